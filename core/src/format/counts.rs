//! The counts a file's header and precision record hold about the build: what was stored, what
//! was dropped, how far vertices moved. The build side measures them; the format owns their
//! shape, so writing a file needs nothing from the build side.

use crate::geometry::Displacement;

/// Counts over one chunk; they add up over chunks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ChunkStats {
    pub triangles: u64,
    pub dropped_triangles: u64,
    /// Distinct mesh vertices referenced by the chunk's strips (after welding, and for grid
    /// vertices after merging those that snap to one grid point).
    pub input_vertices: u64,
    pub stored_vertices: u64,
    pub hierarchy_vertices: u64,
    pub max_strip_length: u64,
    /// Input vertex → stored position; empty for f32 vertices, which do not move.
    pub quantization: Displacement,
    /// Largest angle, in degrees, between an input normal and its stored code; 0 without
    /// normals.
    pub normal_error_degrees: f64,
}

impl ChunkStats {
    pub fn add(&mut self, other: &ChunkStats) {
        self.triangles += other.triangles;
        self.dropped_triangles += other.dropped_triangles;
        self.input_vertices += other.input_vertices;
        self.stored_vertices += other.stored_vertices;
        self.hierarchy_vertices += other.hierarchy_vertices;
        self.max_strip_length = self.max_strip_length.max(other.max_strip_length);
        self.quantization.add(&other.quantization);
        self.normal_error_degrees = self.normal_error_degrees.max(other.normal_error_degrees);
    }
}

/// What a tolerance weld did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct WeldStats {
    /// 0 when only bit-identical positions were welded.
    pub tolerance: f32,
    /// How far the merged vertices moved (`count` is the number merged into another).
    pub displacement: Displacement,
}

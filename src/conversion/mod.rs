//! Conversion of one mesh chunk into encoded strips: the core API the pipeline runs per chunk.
//!
//! "One mesh chunk in memory → encoded strips with bounds". Converting a mesh that fits in
//! memory is the one-chunk case: [`encode_chunk`], then [`ChunkLayout::new`] (the chunk's top
//! level over the strip bounds and the strip-record [`layout`]), then the file is written
//! ([`convert_mesh`] does the three). The pipeline's stages call the same functions per chunk.

mod in_memory;
pub mod layout;
pub mod pooling;

use std::borrow::Cow;
use std::path::Path;

use rayon::prelude::*;

use crate::closedness::count_edges;
use crate::format::attributes::AttributeSet;
use crate::format::counts::WeldStats;
use crate::format::grid::{Grid, MAX_GRID_BITS};
use crate::format::model::{Closedness, UpAxis};
use crate::format::writer::{FileInfo, WriteError};
use crate::geometry::Aabb;
use crate::mesh::Mesh;
use crate::quantize::quantize_mesh;
use crate::strip_encoding::attributes::split_triangles;
use crate::strip_encoding::{encode_strip, split_strip, AttributeSource, EncodedStrip, Positions};
use crate::strip_windows;
use crate::stripify::{stripify, Stripification, StripifyParams};
use crate::toplevel::TopLevelParams;

pub use crate::format::counts::ChunkStats;
pub use in_memory::write_file;
use in_memory::write_layout;
pub use layout::{ChunkLayout, Pooling};

/// Strip kd-tree leaf size the pipeline uses unless the config sets one; [`BuildParams`] keeps
/// the paper's 2.
///
/// Deviation from the paper (leaf threshold 2): the tracer intersects any subtree of at most
/// [`crate::trace::TraceOptions::subtree_windows`] (8) windows at once, one SIMD block, so the
/// nodes below 8 windows are never visited, yet each costs two stored bound vertices: with
/// two-window leaves a third of the stored vertices are such copies. Eight-window leaves store
/// almost none and trace the same subtrees, in fewer bytes and instructions (docs/BENCHMARKS.md,
/// "Strip leaf size").
pub const PIPELINE_LEAF_WINDOWS: usize = 8;

/// Most triangles per strip in the pipeline's default configuration.
///
/// Deviation from the paper (60): a strip's box in the top-level hierarchy grows with its
/// length, and a ray that enters it tests nearly every window: the strip kd-tree's single
/// split planes cull almost nothing for short AO rays. Shorter strips have tighter boxes; 20
/// keeps files under 20 bytes per triangle, where 16 would not (docs/BENCHMARKS.md, "Strip
/// length").
pub const PIPELINE_MAX_STRIP_LENGTH: usize = 20;

/// Build parameters, with the paper's values as defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildParams {
    pub stripify: StripifyParams,
    /// Strip kd-tree leaf size in windows (paper: 2 triangles).
    pub leaf_windows: usize,
    pub top_level: TopLevelParams,
    /// Bits per axis of the model grid vertices are snapped to; `None` stores f32 copies
    /// (lossless, the default).
    pub grid_bits: Option<u32>,
    /// No effect since format 4, whose 8-wide nodes are compressed for every vertex encoding
    /// (format 2.4's lossless files with grid nodes, [`crate::format::VertexEncoding::F32GridNodes`],
    /// are no longer written); kept so that `[strip] grid_nodes` of older configurations is
    /// still accepted.
    pub grid_nodes: bool,
    /// Which attributes the file stores besides positions (none by default).
    pub attributes: AttributeSet,
}

/// Where the attributes of strips over `mesh` come from; `None` when none is stored.
fn attribute_source(set: AttributeSet, mesh: &Mesh) -> Option<AttributeSource<'_>> {
    set.any().then_some(AttributeSource { mesh, set })
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams {
            stripify: StripifyParams::default(),
            leaf_windows: 2,
            top_level: TopLevelParams::default(),
            grid_bits: None,
            grid_nodes: false,
            attributes: AttributeSet::default(),
        }
    }
}

impl BuildParams {
    /// Checks ranges the format imposes: references are counted in u16 and the leaf size in u8.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=1000).contains(&self.stripify.max_length) {
            return Err(format!(
                "strip max_length {} is outside 1..=1000",
                self.stripify.max_length
            ));
        }
        if !(1..=255).contains(&self.leaf_windows) {
            return Err(format!(
                "strip leaf_windows {} is outside 1..=255",
                self.leaf_windows
            ));
        }
        if self.stripify.sah_bins < 2 {
            return Err(format!(
                "sah_bins {} must be at least 2",
                self.stripify.sah_bins
            ));
        }
        if let Some(bits) = self.grid_bits.filter(|b| !(1..=MAX_GRID_BITS).contains(b)) {
            return Err(format!(
                "vertex grid_bits {bits} is outside 1..={MAX_GRID_BITS}"
            ));
        }
        Ok(())
    }

    /// The grid over a whole model's bounds, when vertices are quantized. Every chunk of the
    /// model must be encoded on this one grid.
    pub fn grid(&self, model_bounds: &Aabb) -> Option<Grid> {
        self.grid_bits.map(|bits| Grid::over(model_bounds, bits))
    }
}

/// The encoded strips of one chunk, in Strip-RT output order, with what the file header needs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EncodedChunk {
    pub strips: Vec<EncodedStrip>,
    pub stats: ChunkStats,
    /// The grid the vertices were snapped to; `None` for f32 vertices.
    pub grid: Option<Grid>,
}

/// Runs Strip-RT and strip encoding over a chunk that is the whole model.
pub fn encode_chunk(mesh: &Mesh, params: &BuildParams) -> EncodedChunk {
    encode_chunk_on(mesh, params, params.grid(&mesh.bounds()).as_ref())
}

/// Runs Strip-RT and strip encoding over one chunk of a model, with vertices on the model's
/// `grid` ([`BuildParams::grid`]) or, without one, as f32 copies.
pub fn encode_chunk_on(mesh: &Mesh, params: &BuildParams, grid: Option<&Grid>) -> EncodedChunk {
    let Some(grid) = grid else {
        let stripification = stripify(mesh, &params.stripify);
        let positions = Positions::F32(&mesh.positions);
        let attributes = attribute_source(params.attributes, mesh);
        return encode_strips(&stripification, positions, params.leaf_windows, attributes);
    };
    let quantized = quantize_mesh(mesh, grid);
    let positions = Positions::Grid {
        points: &quantized.points,
        decoded: &quantized.mesh.positions,
        bits: grid.bits,
    };
    let stripification = stripify(&quantized.mesh, &params.stripify);
    let attributes = attribute_source(params.attributes, &quantized.mesh);
    let mut chunk = encode_strips(&stripification, positions, params.leaf_windows, attributes);
    chunk.stats.quantization = quantized.error;
    chunk.grid = Some(*grid);
    chunk
}

/// Encodes strips from any stripifier (Strip-RT, or another one for comparison) over `mesh`,
/// with f32 vertices and no attributes.
pub fn encode_stripification(
    mesh: &Mesh,
    stripification: &Stripification,
    leaf_windows: usize,
) -> EncodedChunk {
    encode_strips(
        stripification,
        Positions::F32(&mesh.positions),
        leaf_windows,
        None,
    )
}

fn encode_strips(
    stripification: &Stripification,
    positions: Positions,
    leaf_windows: usize,
    attributes: Option<AttributeSource>,
) -> EncodedChunk {
    let encoded: Vec<(EncodedStrip, f64)> = stripification
        .strips
        .par_iter()
        .zip(&stripification.triangles)
        .flat_map_iter(|(references, triangles)| {
            let mut pieces = Vec::new();
            encode_fitting(references, triangles, positions, leaf_windows, &mut pieces);
            pieces
                .into_iter()
                .map(move |(mut strip, references, triangles)| {
                    let normal_error = attributes.map_or(0.0, |source| {
                        let (payload, error) =
                            source.of_strip(references, &strip.vertex_sources, triangles);
                        strip.attributes = payload;
                        error
                    });
                    (strip, normal_error)
                })
        })
        .collect();
    let vertex_count = match positions {
        Positions::F32(points) => points.len(),
        Positions::Grid { points, .. } => points.len(),
    };
    let mut stats = ChunkStats {
        dropped_triangles: stripification.dropped_triangles,
        input_vertices: count_referenced_vertices(&stripification.strips, vertex_count),
        ..ChunkStats::default()
    };
    for (s, normal_error) in &encoded {
        stats.stored_vertices += s.vertex_count as u64;
        stats.hierarchy_vertices += s.hierarchy_copies as u64;
        stats.normal_error_degrees = stats.normal_error_degrees.max(*normal_error);
    }
    for references in &stripification.strips {
        let length = strip_windows::triangles(references).count() as u64;
        stats.triangles += length;
        stats.max_strip_length = stats.max_strip_length.max(length);
    }
    EncodedChunk {
        strips: encoded.into_iter().map(|(strip, _)| strip).collect(),
        stats,
        grid: None,
    }
}

/// An encoded strip with its references and the mesh triangles of its real windows.
type Piece<'s> = (EncodedStrip, &'s [u32], &'s [u32]);

/// Encodes a strip, halving it until every piece fits 1-byte local indices.
fn encode_fitting<'s>(
    references: &'s [u32],
    triangles: &'s [u32],
    positions: Positions,
    leaf_windows: usize,
    pieces: &mut Vec<Piece<'s>>,
) {
    match encode_strip(references, positions, leaf_windows) {
        Ok(encoded) => pieces.push((encoded, references, triangles)),
        Err(_) => {
            let (first, second) = split_strip(references);
            let (first_triangles, second_triangles) = split_triangles(first, triangles);
            encode_fitting(first, first_triangles, positions, leaf_windows, pieces);
            encode_fitting(second, second_triangles, positions, leaf_windows, pieces);
        }
    }
}

fn count_referenced_vertices(strips: &[Vec<u32>], vertex_count: usize) -> u64 {
    let mut referenced = vec![false; vertex_count];
    for &v in strips.iter().flatten() {
        referenced[v as usize] = true;
    }
    referenced.iter().filter(|&&r| r).count() as u64
}

/// Bounds of every strip, in chunk order, for the top-level build.
pub fn strip_bounds(strips: &[EncodedStrip]) -> Vec<Aabb> {
    strips.iter().map(|s| s.bounds).collect()
}

/// Converts a mesh that fits in memory (the one-chunk case) and writes the file at `out`.
/// A coordinate beyond [`crate::geometry::MAX_COORDINATE`] (where the tracer's f32 arithmetic
/// would overflow) is refused with an `InvalidInput` error before anything is written.
pub fn convert_mesh(
    mesh: &Mesh,
    params: &BuildParams,
    out: &Path,
) -> Result<ChunkStats, WriteError> {
    if let Some((vertex, axis, value)) = mesh.out_of_range_coordinate() {
        let detail = format!(
            "vertex {vertex}: coordinate {} = {value:e} is outside the supported range ±{:e}",
            ["x", "y", "z"][axis],
            crate::geometry::MAX_COORDINATE
        );
        return Err(WriteError {
            path: out.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidInput, detail),
        });
    }
    let chunk = encode_chunk(mesh, params);
    let closedness = Some(stored_edges(mesh, params));
    write_chunk_counted(Cow::Owned(chunk), params, closedness, None, out)
}

/// The edge counts of `mesh` as stored: on the grid when vertices are quantized, since snapping
/// can join or part edges.
fn stored_edges(mesh: &Mesh, params: &BuildParams) -> Closedness {
    match params.grid(&mesh.bounds()) {
        Some(grid) => count_edges(&quantize_mesh(mesh, &grid).mesh),
        None => count_edges(mesh),
    }
}

/// Builds the top level over one encoded chunk and writes the file at `out`.
pub fn write_chunk(
    chunk: &EncodedChunk,
    params: &BuildParams,
    out: &Path,
) -> Result<ChunkStats, WriteError> {
    write_chunk_counted(Cow::Borrowed(chunk), params, None, None, out)
}

/// [`write_chunk`] with the whole model's edge counts and its up axis, when known.
pub fn write_chunk_counted(
    chunk: Cow<'_, EncodedChunk>,
    params: &BuildParams,
    closedness: Option<Closedness>,
    up: Option<UpAxis>,
    out: &Path,
) -> Result<ChunkStats, WriteError> {
    // Pooling rewrites the blocks: an owned chunk's in place, a borrowed one's in a copy.
    let (chunk, layout) = match Pooling::of(params, chunk.grid.as_ref()) {
        Some(pooling) => {
            let mut chunk = chunk.into_owned();
            let layout = ChunkLayout::pooled(&mut chunk.strips, &params.top_level, pooling);
            (Cow::Owned(chunk), layout)
        }
        None => {
            let layout = ChunkLayout::new(&chunk.strips, &params.top_level);
            (chunk, layout)
        }
    };
    let layout = layout.map_err(|source| WriteError {
        path: out.to_path_buf(),
        source,
    })?;
    let pooled = layout.pooled_vertices.is_some();
    let mut stats = chunk.stats;
    stats.stored_vertices = layout.pooled_vertices.unwrap_or(stats.stored_vertices);
    let info = FileInfo {
        stats,
        leaf_windows: params.leaf_windows,
        max_strip_length: params.stripify.max_length,
        bounds: layout.bounds,
        grid: chunk.grid,
        weld: WeldStats::default(),
        attributes: params.attributes,
        closedness,
        up,
        pooled,
    };
    write_layout(out, &info, &layout, &chunk.strips)?;
    Ok(chunk.stats)
}

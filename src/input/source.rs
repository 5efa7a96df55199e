//! The passes the chunker reads a mesh in, whatever its format: a binary PLY through
//! windows of its file, every other input from a mesh already in memory.

use super::{AttributeRequest, InputError, PlyStream, VertexAttributes};
use crate::geometry::Point;
use crate::mesh::Mesh;

/// A mesh read in passes, so that a model larger than memory can be partitioned: positions in
/// windows, triangles in input order, and positions and attributes of chosen vertices.
pub trait MeshSource: Sync {
    fn vertex_count(&self) -> u64;
    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError>;
    /// Visits every triangle in input order as `visit(face_id, triangle)`: the input face it
    /// comes from (a polygon's fan triangles share it).
    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError>;
    /// Positions of `sorted_ids` (strictly ascending), in that order.
    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError>;
    /// The attributes the source was opened with, of `sorted_ids` (strictly ascending), in that
    /// order.
    fn attributes_of(&self, sorted_ids: &[u32]) -> Result<VertexAttributes, InputError>;
}

/// A binary PLY read through windows of `window_bytes`.
pub(crate) struct WindowedPly {
    pub(crate) stream: PlyStream,
    pub(crate) request: AttributeRequest,
    pub(crate) window_bytes: usize,
}

impl MeshSource for WindowedPly {
    fn vertex_count(&self) -> u64 {
        self.stream.vertex_count()
    }

    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        self.stream
            .for_each_position_window(self.window_bytes, visit)
    }

    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        self.stream.for_each_triangle(self.window_bytes, visit)
    }

    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError> {
        self.stream.positions_of(sorted_ids, self.window_bytes)
    }

    fn attributes_of(&self, sorted_ids: &[u32]) -> Result<VertexAttributes, InputError> {
        self.stream
            .attributes_of(sorted_ids, self.window_bytes, self.request)
    }
}

/// A mesh already in memory (inputs that cannot be streamed, such as ASCII PLY and OBJ).
impl MeshSource for Mesh {
    fn vertex_count(&self) -> u64 {
        self.positions.len() as u64
    }

    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        visit(0, &self.positions);
        Ok(())
    }

    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        for (index, &triangle) in self.triangles.iter().enumerate() {
            visit(self.face_id(index).into(), triangle);
        }
        Ok(())
    }

    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError> {
        Ok(pick(&self.positions, sorted_ids))
    }

    fn attributes_of(&self, sorted_ids: &[u32]) -> Result<VertexAttributes, InputError> {
        Ok(VertexAttributes {
            normals: self.normals.as_ref().map(|n| pick(n, sorted_ids)),
            colors: self.colors.as_ref().map(|c| pick(c, sorted_ids)),
        })
    }
}

pub(crate) fn pick<T: Copy>(values: &[T], ids: &[u32]) -> Vec<T> {
    ids.iter().map(|&v| values[v as usize]).collect()
}

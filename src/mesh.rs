//! The in-memory indexed triangle mesh: one chunk of a model.

use crate::geometry::{Aabb, Point};

/// An indexed triangle mesh. Triangles refer to `positions` by index and keep their input winding.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Point>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.positions)
    }

    /// The first coordinate that is not finite or lies beyond
    /// [`crate::geometry::MAX_COORDINATE`], as `(vertex, axis, value)`. The readers reject such
    /// inputs; meshes built in code are checked by [`crate::conversion::convert_mesh`].
    pub fn out_of_range_coordinate(&self) -> Option<(usize, usize, f32)> {
        self.positions.iter().enumerate().find_map(|(vertex, p)| {
            (0..3)
                .find(|&axis| {
                    !p[axis].is_finite() || p[axis].abs() > crate::geometry::MAX_COORDINATE
                })
                .map(|axis| (vertex, axis, p[axis]))
        })
    }

    pub fn triangle_points(&self, triangle: &[u32; 3]) -> [Point; 3] {
        triangle.map(|v| self.positions[v as usize])
    }
}

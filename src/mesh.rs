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

    pub fn triangle_points(&self, triangle: &[u32; 3]) -> [Point; 3] {
        triangle.map(|v| self.positions[v as usize])
    }
}

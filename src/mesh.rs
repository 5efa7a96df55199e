//! The in-memory indexed triangle mesh: one chunk of a model.

use crate::geometry::{Aabb, Point};

/// An indexed triangle mesh. Triangles refer to `positions` by index and keep their input winding.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Point>,
    pub triangles: Vec<[u32; 3]>,
    /// For each triangle, the index of the input face it comes from: PLY `face` element order,
    /// OBJ `f` statement order across groups; a polygon's fan triangles share their polygon's.
    /// `None` where triangle `i` is face `i`: meshes made in code and PLY files of triangles
    /// only. Pipeline chunks carry their triangles' global input face ids when `[attributes]
    /// face_ids` asks for them, and `None` otherwise.
    pub face_ids: Option<Vec<u32>>,
    /// Per-vertex normals, parallel to `positions`, as read (not necessarily unit length);
    /// `None` when the input has none or they were not asked for.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Per-vertex RGBA8 colours, parallel to `positions` (alpha 255 when the input has none);
    /// `None` when the input has none or they were not asked for.
    pub colors: Option<Vec<[u8; 4]>>,
}

impl Mesh {
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.positions)
    }

    /// The first coordinate that is not finite or lies beyond
    /// [`crate::geometry::MAX_COORDINATE`], as `(vertex, axis, value)`. The readers reject such
    /// inputs; meshes built in code are checked by [`crate::conversion::convert_mesh`].
    pub(crate) fn out_of_range_coordinate(&self) -> Option<(usize, usize, f32)> {
        self.positions.iter().enumerate().find_map(|(vertex, p)| {
            (0..3)
                .find(|&axis| {
                    !p[axis].is_finite() || p[axis].abs() > crate::geometry::MAX_COORDINATE
                })
                .map(|axis| (vertex, axis, p[axis]))
        })
    }

    /// The input face triangle `triangle` comes from.
    pub fn face_id(&self, triangle: usize) -> u32 {
        match &self.face_ids {
            Some(ids) => ids[triangle],
            None => triangle as u32,
        }
    }

    pub fn triangle_points(&self, triangle: &[u32; 3]) -> [Point; 3] {
        triangle.map(|v| self.positions[v as usize])
    }
}

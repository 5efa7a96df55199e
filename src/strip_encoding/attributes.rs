//! The attribute payload of one encoded strip: what the file's attribute sections hold for it
//! (format 2.5), in the strip's own orders, so that the small references that index its stored
//! vertices index their normals and colours too (the paper's section 7 asks for exactly this:
//! attributes stored compactly, per strip, beside the vertices).

pub(crate) use crate::format::attribute_sections::StripAttributes;
use crate::format::attributes::{
    angle_degrees, decode_normal, encode_normal, AttributeSet, NormalEncoding,
};
use crate::mesh::Mesh;

/// What to store, and where it comes from.
#[derive(Clone, Copy, Debug)]
pub(crate) struct AttributeSource<'a> {
    /// The mesh the strips index (the quantized one for grid vertices).
    pub(crate) mesh: &'a Mesh,
    pub(crate) set: AttributeSet,
}

impl AttributeSource<'_> {
    /// The payload of a strip with `references` (mesh vertices, swaps included) whose stored
    /// vertices copy mesh vertices `vertex_sources` and whose real windows are mesh triangles
    /// `triangles`, with the largest angle between an input normal and its stored code, in
    /// degrees.
    ///
    /// A mesh without normals or colours where they are asked for stores `+z` and opaque white:
    /// the pipeline refuses such inputs before converting, so this only serves meshes made in
    /// code.
    pub(crate) fn of_strip(
        &self,
        references: &[u32],
        vertex_sources: &[u32],
        triangles: &[u32],
    ) -> (StripAttributes, f64) {
        let mut attributes = StripAttributes::default();
        if self.set.face_ids {
            attributes.face_ids = self.window_face_ids(references, triangles);
        }
        let mut normal_error: f64 = 0.0;
        if self.set.normals != NormalEncoding::None {
            let input = |v: u32| match &self.mesh.normals {
                Some(normals) => normals[v as usize],
                None => [0.0, 0.0, 1.0],
            };
            attributes.normals = vertex_sources
                .iter()
                .map(|&v| {
                    let code = encode_normal(input(v), self.set.normals);
                    normal_error = normal_error.max(self.error(input(v), code));
                    code
                })
                .collect();
        }
        if self.set.colors {
            attributes.colors = vertex_sources
                .iter()
                .map(|&v| {
                    self.mesh
                        .colors
                        .as_ref()
                        .map_or([255; 4], |c| c[v as usize])
                })
                .collect();
        }
        (attributes, normal_error)
    }

    /// The angle between an input normal and what its code decodes to; 0 for a zero or
    /// non-finite input, which has no direction to keep.
    fn error(&self, input: [f32; 3], code: [i16; 2]) -> f64 {
        let length = input.iter().map(|c| c * c).sum::<f32>().sqrt();
        if !(length.is_finite() && length > 0.0) {
            return 0.0;
        }
        angle_degrees(
            input.map(|c| c / length),
            decode_normal(code, self.set.normals),
        )
    }

    /// The face id of every window: a real window's triangle's, a swap repeating the window
    /// before it (the first triangle's at the strip start).
    fn window_face_ids(&self, references: &[u32], triangles: &[u32]) -> Vec<u32> {
        let face = |t: u32| self.mesh.face_id(t as usize);
        let mut real = triangles.iter().map(|&t| face(t));
        let mut previous = triangles.first().map_or(0, |&t| face(t));
        (0..crate::strip_windows::window_count(references.len()))
            .map(|k| {
                if crate::strip_windows::window_triangle(references, k).is_some() {
                    previous = real.next().unwrap_or(previous);
                }
                previous
            })
            .collect()
    }
}

/// Splits a strip's per-triangle face ids as [`super::split_strip`] splits its references:
/// the first half keeps the real windows before the cut.
pub(crate) fn split_triangles<'t>(
    first_half: &[u32],
    triangles: &'t [u32],
) -> (&'t [u32], &'t [u32]) {
    triangles.split_at(crate::strip_windows::triangles(first_half).count())
}

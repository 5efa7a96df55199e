//! What a hit carries beyond its distance and geometric normal: the input face id, the
//! interpolated stored normal and colour (format 2.5). They are read on request, for the final
//! hit only, so rays that do not ask pay nothing: traversal never touches attribute sections.

use super::ray::Hit;
use crate::format::reader::ReducemFile;
use crate::geometry::Point;
use crate::strip_windows::window_corners;

/// A hit's attributes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitAttributes {
    /// The input face the hit triangle comes from; `None` without face ids.
    pub face_id: Option<u32>,
    /// The stored vertex normals interpolated at the hit and normalized; the geometric normal
    /// without normals (or where they cancel out).
    pub shading_normal: Point,
    /// The stored vertex colours interpolated at the hit, rounded; `None` without colours.
    pub color: Option<[u8; 4]>,
}

/// The attributes of `hit`, a hit of a ray traced in `file`.
pub fn hit_attributes(file: &ReducemFile, hit: &Hit) -> HitAttributes {
    HitAttributes {
        face_id: file.face_id(hit.strip as usize, hit.window as usize),
        ..surface_attributes(file, hit)
    }
}

/// The per-vertex attributes of `hit` (shading normal and colour) without its face id, for
/// callers that shade and need no id: reading a face id is most of a full lookup's cost.
pub fn surface_attributes(file: &ReducemFile, hit: &Hit) -> HitAttributes {
    let (strip, window) = (hit.strip as usize, hit.window as usize);
    let mut attributes = HitAttributes {
        face_id: None,
        shading_normal: hit.normal,
        color: None,
    };
    let Some(vertices) = file.vertex_attributes(strip) else {
        return attributes;
    };
    let view = file.strip(strip);
    if window >= view.window_count() {
        return attributes;
    }
    let mut references = [0u8; 3];
    view.references.read_into(window, &mut references);
    let Some(corners) = window_corners(references.map(usize::from), window) else {
        return attributes;
    };
    let weights = [1.0 - hit.u - hit.v, hit.u, hit.v];
    if let Some(normals) = corners
        .iter()
        .map(|&c| vertices.normal(c))
        .collect::<Option<Vec<_>>>()
    {
        attributes.shading_normal = interpolated_normal(&normals, weights).unwrap_or(hit.normal);
    }
    if let Some(colors) = corners
        .iter()
        .map(|&c| vertices.color(c))
        .collect::<Option<Vec<_>>>()
    {
        attributes.color = Some(interpolated_color(&colors, weights));
    }
    attributes
}

fn interpolated_normal(normals: &[[f32; 3]], weights: [f32; 3]) -> Option<Point> {
    let sum: [f32; 3] =
        std::array::from_fn(|axis| (0..3).map(|c| weights[c] * normals[c][axis]).sum());
    let length = sum.iter().map(|c| c * c).sum::<f32>().sqrt();
    (length.is_normal()).then(|| sum.map(|c| c / length))
}

fn interpolated_color(colors: &[[u8; 4]], weights: [f32; 3]) -> [u8; 4] {
    std::array::from_fn(|channel| {
        let value: f32 = (0..3).map(|c| weights[c] * colors[c][channel] as f32).sum();
        value.round().clamp(0.0, 255.0) as u8
    })
}

//! The tracer's query and answer: a ray and its closest hit. A leaf of the tracer's modules, so
//! traversal ([`super::prepared`], [`super::packet`]) and the ray files use them without
//! importing from the tracer's root; re-exported there as `trace::Ray` and `trace::Hit`.

use bytemuck::{Pod, Zeroable};

use crate::geometry::Point;

/// A ray `origin + t * direction` for `t` in `[tmin, tmax]`; `tmin >= 0`, direction non-zero
/// (need not be unit length: `t` is in units of the direction).
///
/// `#[repr(C)]` in the field order of a ray file's record, so that on a little-endian machine a
/// mapped ray file is read as rays in place ([`super::ray_file::RayFile`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Ray {
    pub origin: Point,
    pub direction: Point,
    pub tmin: f32,
    pub tmax: f32,
}

const _: () = assert!(std::mem::size_of::<Ray>() == 32);

/// The closest intersection of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// Barycentric weights of the triangle's second and third corners in input winding: the hit
    /// point is `(1 - u - v) * v0 + u * v1 + v * v2`.
    pub u: f32,
    pub v: f32,
    /// Unit geometric normal `normalize((v1 - v0) × (v2 - v0))` in input winding.
    pub normal: Point,
    /// File position of the strip.
    pub strip: u32,
    /// Window of the strip (its triangle is decoded by [`crate::strip_windows::window_triangle`]).
    pub window: u16,
}

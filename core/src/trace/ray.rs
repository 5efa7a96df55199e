//! The tracer's query and answer: a ray and its closest hit. A leaf of the tracer's modules, so
//! traversal ([`super::prepared`], [`super::packet`]) and the ray files use them without
//! importing from the tracer's root; re-exported there as `trace::Ray` and `trace::Hit`.

use crate::geometry::Point;

/// A ray `origin + t * direction` for `t` in `[tmin, tmax]`; `tmin >= 0`, direction non-zero
/// (need not be unit length: `t` is in units of the direction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Point,
    pub direction: Point,
    pub tmin: f32,
    pub tmax: f32,
}

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

//! A ray prepared for traversal, and the conservative slab arithmetic every bounds test uses.
//!
//! Robustness follows Ize, "Robust BVH Ray Traversal" (JCGT 2013): a plane distance
//! `(plane - origin) * (1 / d)` carries at most three roundings, so scaling every *far* distance
//! by [`FAR_INFLATION`] (a little more than `1 + 2γ₃`) makes the computed interval contain the
//! exact one; near distances are left as computed. A bounds test may thus visit a node it need
//! not, but never skips one the exact ray enters.
//!
//! Zero direction components: `1 / ±0` is `±inf`, so a plane distance is `±inf` (the ray never
//! crosses the plane, it is entirely on one side) or NaN when the origin lies exactly on the
//! plane (`0 * inf`). A ray in a bounding plane is inside the closed slab, so a NaN must never
//! narrow an interval: every clip starts from a non-NaN value and goes through [`max_not_nan`] /
//! [`min_not_nan`], which keep that value when the other operand is NaN.

use super::watertight::RaySpace;
use super::Ray;
use crate::geometry::Point;

/// `1 + 2^-20`: above `1 + 2γ₃ ≈ 1 + 3.6e-7` with room for the rounding of the product itself.
pub const FAR_INFLATION: f32 = 1.0 + 1.0 / 1_048_576.0;

/// A ray with what every node and triangle test needs precomputed.
#[derive(Clone, Copy, Debug)]
pub struct PreparedRay {
    pub origin: Point,
    pub reciprocal: Point,
    /// Per axis, whether the direction points down that axis (`-0.0` counts as negative, so the
    /// near/far order on an axis the ray does not move along is still well defined).
    pub negative: [bool; 3],
    pub space: RaySpace,
    pub tmin: f32,
    pub tmax: f32,
}

impl PreparedRay {
    pub fn new(ray: &Ray) -> PreparedRay {
        PreparedRay {
            origin: ray.origin,
            reciprocal: ray.direction.map(|d| 1.0 / d),
            negative: ray.direction.map(|d| d.is_sign_negative()),
            space: RaySpace::new(ray.origin, ray.direction),
            tmin: ray.tmin,
            tmax: ray.tmax,
        }
    }

    /// Parameter at which the ray crosses the plane `coordinate[axis] = plane` (±inf or NaN when
    /// the ray is parallel to it; see the module documentation).
    #[inline(always)]
    pub fn plane_distance(&self, axis: usize, plane: f32) -> f32 {
        (plane - self.origin[axis]) * self.reciprocal[axis]
    }

    /// The part of `[t_near, t_far]` inside the box, conservatively, or `None`.
    #[inline(always)]
    pub fn clip_box(
        &self,
        min: &Point,
        max: &Point,
        t_near: f32,
        t_far: f32,
    ) -> Option<(f32, f32)> {
        let [x, y, z] = [0, 1, 2].map(|axis| self.slab(axis, min[axis], max[axis]));
        let near = max_not_nan(max_not_nan(max_not_nan(t_near, x.0), y.0), z.0);
        let far = min_not_nan(min_not_nan(min_not_nan(t_far, x.1), y.1), z.1);
        (near <= far).then_some((near, far))
    }

    /// Entry and (inflated) exit distance of the slab `min <= coordinate[axis] <= max`. Both
    /// planes are computed and then picked by the direction's sign, which is branch-free.
    #[inline(always)]
    fn slab(&self, axis: usize, min: f32, max: f32) -> (f32, f32) {
        let to_min = self.plane_distance(axis, min);
        let to_max = self.plane_distance(axis, max);
        if self.negative[axis] {
            (to_max, to_min * FAR_INFLATION)
        } else {
            (to_min, to_max * FAR_INFLATION)
        }
    }
}

/// `a.max(b)` for a non-NaN `a`: `a` when `b` is NaN, like `f32::max`, but one instruction
/// instead of `f32::max`'s NaN fix-up of both operands.
#[inline(always)]
pub fn max_not_nan(a: f32, b: f32) -> f32 {
    if b > a {
        b
    } else {
        a
    }
}

/// `a.min(b)` for a non-NaN `a`; see [`max_not_nan`].
#[inline(always)]
pub fn min_not_nan(a: f32, b: f32) -> f32 {
    if b < a {
        b
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(origin: Point, direction: Point) -> PreparedRay {
        PreparedRay::new(&Ray {
            origin,
            direction,
            tmin: 0.0,
            tmax: f32::INFINITY,
        })
    }

    #[test]
    fn ray_in_a_face_plane_is_inside_for_both_zero_signs() {
        let (min, max) = ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
        for zero in [0.0f32, -0.0] {
            for origin in [[-1.0, 0.0, 0.5], [-1.0, 1.0, 0.5], [-1.0, 0.5, 1.0]] {
                let r = ray(origin, [1.0, zero, zero]);
                assert!(r.clip_box(&min, &max, 0.0, f32::INFINITY).is_some());
            }
        }
    }

    #[test]
    fn parallel_ray_outside_the_slab_misses() {
        let r = ray([-1.0, 2.0, 0.5], [1.0, 0.0, -0.0]);
        assert_eq!(r.clip_box(&[0.0; 3], &[1.0; 3], 0.0, f32::INFINITY), None);
    }

    #[test]
    fn flat_box_is_hit() {
        let r = ray([0.5, 0.5, 3.0], [0.1, 0.0, -1.0]);
        let hit = r.clip_box(&[0.0, 0.0, 1.0], &[1.0, 1.0, 1.0], 0.0, f32::INFINITY);
        assert!(hit.is_some());
    }
}

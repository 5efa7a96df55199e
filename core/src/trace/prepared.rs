//! A ray prepared for traversal, and the conservative slab arithmetic every bounds test uses.
//!
//! Robustness follows Ize, "Robust BVH Ray Traversal" (JCGT 2013): a plane distance
//! `(plane - origin) * (1 / d)` carries at most three roundings, so scaling every *exit* distance
//! by [`FAR_INFLATION`] (a little more than `1 + 2γ₃`) makes the computed interval contain the
//! exact one; entry distances are left as computed. A bounds test may thus visit a node it need
//! not, but never skips one the exact ray enters.
//!
//! Zero direction components: `1 / ±0` is `±inf`, so a plane distance is `±inf` (the ray never
//! crosses the plane, it is entirely on one side) or NaN when the origin lies exactly on the
//! plane (`0 * inf`). A ray in a bounding plane is inside the closed slab, so a NaN must never
//! narrow an interval: every clip starts from a non-NaN value and goes through [`max_not_nan`] /
//! [`min_not_nan`], which keep that value when the other operand is NaN.
//!
//! Tiny non-zero components: for subnormal `|d|` below about `2.9e-39`, `1 / d` overflows to
//! `±inf` although the ray does cross every plane it moves towards, at a finite parameter when
//! the origin is within about `|d| * f32::MAX` of the plane. Exit
//! distances keep the infinite reciprocal, entry distances use it clamped to `±f32::MAX`; see
//! [`PreparedRay::new`] for why both stay conservative.
//!
//! The top level tests four child boxes at once ([`WideRay::clip_boxes`]) and packets eight rays
//! at once: both run this arithmetic lanewise, operation for operation, with the lanewise
//! [`max_not_nan_x4`] family in place of [`max_not_nan`].
use wide::{f32x4, f32x8};

use super::ray::Ray;
use super::watertight::RaySpace;
use crate::geometry::Point;

/// `1 + 2^-20`: above `1 + 2γ₃ ≈ 1 + 3.6e-7` with room for the rounding of the product itself.
pub const FAR_INFLATION: f32 = 1.0 + 1.0 / 1_048_576.0;

/// A ray with what every node and triangle test needs precomputed.
#[derive(Clone, Copy, Debug)]
pub struct PreparedRay {
    pub origin: Point,
    /// `1 / d` per axis, for exit distances.
    pub exit_reciprocal: Point,
    /// `1 / d` per axis clamped to `±f32::MAX` when `d` is non-zero, for entry distances.
    pub entry_reciprocal: Point,
    /// Per axis, whether the direction points down that axis (`-0.0` counts as negative, so the
    /// near/far order on an axis the ray does not move along is still well defined).
    pub negative: [bool; 3],
    pub space: RaySpace,
    pub tmin: f32,
    pub tmax: f32,
}

impl PreparedRay {
    /// Why the two reciprocals keep every bounds test conservative when `1 / d` overflows for a
    /// non-zero `d` (the exact reciprocal then exceeds `f32::MAX` in magnitude):
    /// * An exit distance `(p - o) * ±inf` is `+inf` when the exact exit is positive (above it),
    ///   `-inf` when it is negative (the ray left the slab before `t = 0 <= tmin`, so the slab
    ///   is rightly empty), and NaN when it is zero, which never narrows an interval.
    /// * An entry distance `(p - o) * ±f32::MAX` has the exact distance's sign and, rounding
    ///   being monotone, is at most what `(p - o)` times the exact reciprocal would round to:
    ///   positive entries are underestimated (the node is entered early, which only costs
    ///   time) and negative ones stay below `tmin >= 0`, where they do not clip.
    ///
    /// A zero component keeps `1 / ±0 = ±inf` for both, as described in the module
    /// documentation: clamping it would turn "never enters" into a huge finite entry.
    pub fn new(ray: &Ray) -> PreparedRay {
        let exit_reciprocal = ray.direction.map(|d| 1.0 / d);
        let entry_reciprocal = std::array::from_fn(|axis| {
            let r = exit_reciprocal[axis];
            if ray.direction[axis] == 0.0 {
                r
            } else {
                r.clamp(-f32::MAX, f32::MAX)
            }
        });
        PreparedRay {
            origin: ray.origin,
            exit_reciprocal,
            entry_reciprocal,
            negative: ray.direction.map(|d| d.is_sign_negative()),
            space: RaySpace::new(ray.origin, ray.direction),
            tmin: ray.tmin,
            tmax: ray.tmax,
        }
    }

    /// Parameter at which the ray enters the half-space beyond the plane
    /// `coordinate[axis] = plane`, rounded as computed (±inf or NaN when the ray is parallel
    /// to it; see the module documentation).
    #[inline(always)]
    pub fn entry_distance(&self, axis: usize, plane: f32) -> f32 {
        (plane - self.origin[axis]) * self.entry_reciprocal[axis]
    }

    /// Parameter at which the ray leaves the half-space before the plane
    /// `coordinate[axis] = plane`, inflated by [`FAR_INFLATION`] so that it is never below the
    /// exact one.
    #[inline(always)]
    pub fn exit_distance(&self, axis: usize, plane: f32) -> f32 {
        (plane - self.origin[axis]) * self.exit_reciprocal[axis] * FAR_INFLATION
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
        // Three plain calls rather than `[0, 1, 2].map(..)`, which the compiler left as an
        // out-of-line `array::try_map` in the hottest loop.
        let x = self.slab(0, min[0], max[0]);
        let y = self.slab(1, min[1], max[1]);
        let z = self.slab(2, min[2], max[2]);
        let near = max_not_nan(max_not_nan(max_not_nan(t_near, x.0), y.0), z.0);
        let far = min_not_nan(min_not_nan(min_not_nan(t_far, x.1), y.1), z.1);
        (near <= far).then_some((near, far))
    }

    /// Entry and (inflated) exit distance of the slab `min <= coordinate[axis] <= max`: the
    /// planes are picked by the direction's sign, then both distances computed.
    #[inline(always)]
    fn slab(&self, axis: usize, min: f32, max: f32) -> (f32, f32) {
        let (entry, exit) = if self.negative[axis] {
            (max, min)
        } else {
            (min, max)
        };
        (
            self.entry_distance(axis, entry),
            self.exit_distance(axis, exit),
        )
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

/// The ray in four lanes, to clip it against a top-level node's four child boxes at once.
#[derive(Clone, Copy, Debug)]
pub struct WideRay {
    origin: [f32x4; 3],
    entry_reciprocal: [f32x4; 3],
    exit_reciprocal: [f32x4; 3],
    pub negative: [bool; 3],
}

impl WideRay {
    pub fn new(ray: &PreparedRay) -> WideRay {
        let splat = |v: &Point| [f32x4::splat(v[0]), f32x4::splat(v[1]), f32x4::splat(v[2])];
        WideRay {
            origin: splat(&ray.origin),
            entry_reciprocal: splat(&ray.entry_reciprocal),
            exit_reciprocal: splat(&ray.exit_reciprocal),
            negative: ray.negative,
        }
    }

    /// [`PreparedRay::clip_box`] for four boxes stored axis by axis (`min[axis][box]`), the same
    /// operations in the same order per lane: per box the entry and exit distance, and the bit
    /// mask of the boxes entered.
    #[inline(always)]
    pub fn clip_boxes(
        &self,
        min: &[[f32; 4]; 3],
        max: &[[f32; 4]; 3],
        t_near: f32,
        t_far: f32,
    ) -> (f32x4, f32x4, u32) {
        let mut interval = (f32x4::splat(t_near), f32x4::splat(t_far));
        for axis in 0..3 {
            let (entry, exit) = if self.negative[axis] {
                (max[axis], min[axis])
            } else {
                (min[axis], max[axis])
            };
            let planes = (f32x4::from(entry), f32x4::from(exit));
            interval = self.clip_axis(axis, planes, interval);
        }
        let (near, far) = interval;
        (near, far, near.simd_le(far).to_bitmask())
    }

    /// One axis of [`WideRay::clip_boxes`]: the intervals `(near, far)` narrowed to the slabs
    /// between the boxes' `entry` and `exit` planes on `axis`.
    #[inline(always)]
    pub fn clip_axis(
        &self,
        axis: usize,
        (entry, exit): (f32x4, f32x4),
        (near, far): (f32x4, f32x4),
    ) -> (f32x4, f32x4) {
        let entry = (entry - self.origin[axis]) * self.entry_reciprocal[axis];
        let exit =
            (exit - self.origin[axis]) * self.exit_reciprocal[axis] * f32x4::splat(FAR_INFLATION);
        (max_not_nan_x4(near, entry), min_not_nan_x4(far, exit))
    }
}

/// Lanewise [`max_not_nan`]: `b` where `b > a`, else `a` (also where `b` is NaN, and `a` on a
/// tie of `+0.0` and `-0.0`).
#[inline(always)]
pub fn max_not_nan_x4(a: f32x4, b: f32x4) -> f32x4 {
    // With SSE `fast_max` is MAXPS, which returns its first operand where it is greater and the
    // second otherwise: exactly `max_not_nan` with the operands swapped, in one instruction.
    // (`f32x4::max` adds a NaN test and a blend.)
    if cfg!(target_feature = "sse") {
        b.fast_max(a)
    } else {
        b.simd_gt(a).select(b, a)
    }
}

/// Lanewise [`min_not_nan`]; see [`max_not_nan_x4`] (MINPS likewise returns its second operand
/// unless the first is smaller).
#[inline(always)]
pub fn min_not_nan_x4(a: f32x4, b: f32x4) -> f32x4 {
    if cfg!(target_feature = "sse") {
        b.fast_min(a)
    } else {
        b.simd_lt(a).select(b, a)
    }
}

/// [`max_not_nan_x4`] for eight lanes (two MAXPS, or one VMAXPS with AVX, same semantics).
#[inline(always)]
pub fn max_not_nan_x8(a: f32x8, b: f32x8) -> f32x8 {
    if cfg!(target_feature = "sse") {
        b.fast_max(a)
    } else {
        b.simd_gt(a).select(b, a)
    }
}

/// [`min_not_nan_x4`] for eight lanes.
#[inline(always)]
pub fn min_not_nan_x8(a: f32x8, b: f32x8) -> f32x8 {
    if cfg!(target_feature = "sse") {
        b.fast_min(a)
    } else {
        b.simd_lt(a).select(b, a)
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
    fn subnormal_direction_enters_the_slab_it_crosses() {
        // The ray crosses x = 0 at t = 0.33 although 1 / 2.68e-43 overflows.
        let r = ray([-8.8e-44, 0.5, 0.5], [2.68e-43, 0.0, 0.5]);
        let (near, far) = r
            .clip_box(&[0.0; 3], &[1.0; 3], 0.0, f32::INFINITY)
            .expect("entered");
        assert!(near <= 0.33 && far >= 1.0, "{near} {far}");
        // Going away from the slab it is still missed.
        let away = ray([-8.8e-44, 0.5, 0.5], [-2.68e-43, 0.0, 0.5]);
        assert_eq!(
            away.clip_box(&[0.0; 3], &[1.0; 3], 0.0, f32::INFINITY),
            None
        );
    }

    /// Operands where a careless max/min differs from the scalar rule: NaN on either side, ties
    /// of `+0.0` and `-0.0`, infinities.
    const AWKWARD: [f32; 8] = [
        f32::NAN,
        0.0,
        -0.0,
        1.0,
        -1.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::MIN_POSITIVE,
    ];

    #[test]
    fn lanewise_min_max_are_the_scalar_rules_bit_for_bit() {
        for a in AWKWARD.into_iter().filter(|a| !a.is_nan()) {
            for b in AWKWARD {
                let lanes = |r: f32x4| r.to_array()[0].to_bits();
                let (va, vb) = (f32x4::splat(a), f32x4::splat(b));
                assert_eq!(lanes(max_not_nan_x4(va, vb)), max_not_nan(a, b).to_bits());
                assert_eq!(lanes(min_not_nan_x4(va, vb)), min_not_nan(a, b).to_bits());
                let (wa, wb) = (f32x8::splat(a), f32x8::splat(b));
                let lane7 = |r: f32x8| r.to_array()[7].to_bits();
                assert_eq!(lane7(max_not_nan_x8(wa, wb)), max_not_nan(a, b).to_bits());
                assert_eq!(lane7(min_not_nan_x8(wa, wb)), min_not_nan(a, b).to_bits());
            }
        }
    }

    /// Four boxes at once give each box's scalar interval bit for bit, for ±0 and subnormal
    /// direction components and rays lying in a box face.
    #[test]
    fn clip_boxes_is_clip_box_per_lane() {
        let boxes: [(Point, Point); 4] = [
            ([0.0; 3], [1.0; 3]),
            ([-1.0, 0.0, 0.5], [0.0, 0.0, 2.0]),
            ([2.0, -3.0, -1.0], [2.5, 3.0, 1.0]),
            ([0.5; 3], [0.5; 3]),
        ];
        let mut min = [[0.0; 4]; 3];
        let mut max = [[0.0; 4]; 3];
        for (slot, (lo, hi)) in boxes.iter().enumerate() {
            for axis in 0..3 {
                min[axis][slot] = lo[axis];
                max[axis][slot] = hi[axis];
            }
        }
        let directions = [
            [1.0, 0.0, -0.0],
            [-0.0, -1.0, 0.0],
            [2.68e-43, 0.0, 0.5],
            [-2.68e-43, -0.0, -0.5],
            [0.3, -0.7, 0.2],
        ];
        let origins = [
            [-1.0, 0.0, 0.5],
            [0.0, 0.0, 1.0],
            [0.5, 0.5, 0.5],
            [-8.8e-44, 0.5, 0.5],
        ];
        for direction in directions {
            for origin in origins {
                let r = ray(origin, direction);
                let (near, far, mask) = WideRay::new(&r).clip_boxes(&min, &max, 0.0, 1e30);
                for (slot, (lo, hi)) in boxes.iter().enumerate() {
                    let scalar = r.clip_box(lo, hi, 0.0, 1e30);
                    let lane = (mask >> slot & 1 == 1)
                        .then(|| (near.to_array()[slot], far.to_array()[slot]));
                    assert_eq!(
                        lane.map(|(n, f)| (n.to_bits(), f.to_bits())),
                        scalar.map(|(n, f)| (n.to_bits(), f.to_bits())),
                        "box {slot}, origin {origin:?}, direction {direction:?}"
                    );
                }
            }
        }
    }

    /// The empty slot (`min = +inf`, `max = -inf`) is missed for every direction sign,
    /// including ±0 and subnormal components.
    #[test]
    fn empty_slots_are_missed_by_every_ray() {
        let min = [[f32::INFINITY; 4]; 3];
        let max = [[f32::NEG_INFINITY; 4]; 3];
        let components = [1.0, -1.0, 0.0, -0.0, 1e-45, -1e-45, 3e38, -3e38];
        for x in components {
            for y in components {
                for z in components {
                    if [x, y, z] == [0.0; 3] {
                        continue;
                    }
                    let r = ray([0.25, -1e11, 1e11], [x, y, z]);
                    let (_, _, mask) = WideRay::new(&r).clip_boxes(&min, &max, 0.0, f32::INFINITY);
                    assert_eq!(mask, 0, "direction {:?}", [x, y, z]);
                }
            }
        }
    }

    #[test]
    fn flat_box_is_hit() {
        let r = ray([0.5, 0.5, 3.0], [0.1, 0.0, -1.0]);
        let hit = r.clip_box(&[0.0, 0.0, 1.0], &[1.0, 1.0, 1.0], 0.0, f32::INFINITY);
        assert!(hit.is_some());
    }
}

//! The packet's box tests in 256-bit lanes. `wide`'s `f32x8` is two SSE registers in a crate
//! compiled for SSE2, even inside a function compiled for AVX2; here each step is one `vsubps`,
//! `vmulps`, `vmaxps` or `vminps` on eight lanes, in the portable kernel's order.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use wide::f32x8;

use crate::trace::kernel::ChildBoxes;
use crate::trace::lanes::Lanes;
use crate::trace::prepared::FAR_INFLATION;

/// `TraceKernel::clip_slot`: per axis the entry distance `(entry - origin) * entry_reciprocal`
/// and the inflated exit distance `(exit - origin) * exit_reciprocal * FAR_INFLATION`, folded
/// into the interval by `max_not_nan_x8` and `min_not_nan_x8` (`vmaxps(entry, near)` and
/// `vminps(exit, far)` keep the interval's value where the distance is NaN, as `maxps` and
/// `minps` do there).
#[target_feature(enable = "avx2,bmi2")]
#[inline]
pub(super) fn clip_slot(
    lanes: &Lanes,
    planes: &Avx2Planes,
    slot: usize,
    t_far: f32x8,
) -> (f32x8, f32x8, u32) {
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let inflation = _mm256_set1_ps(FAR_INFLATION);
    let pick = _mm256_set1_epi32(slot as i32);
    let mut near = wide(lanes.tmin);
    let mut far = wide(t_far);
    for axis in 0..3 {
        let entry = _mm256_permutevar8x32_ps(planes.entry[axis], pick);
        let exit = _mm256_permutevar8x32_ps(planes.exit[axis], pick);
        let origin = wide(lanes.origin[axis]);
        let entry = _mm256_mul_ps(
            _mm256_sub_ps(entry, origin),
            wide(lanes.entry_reciprocal[axis]),
        );
        let exit = _mm256_mul_ps(
            _mm256_mul_ps(
                _mm256_sub_ps(exit, origin),
                wide(lanes.exit_reciprocal[axis]),
            ),
            inflation,
        );
        near = _mm256_max_ps(entry, near);
        far = _mm256_min_ps(exit, far);
    }
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    (bytemuck::cast(near), bytemuck::cast(far), mask)
}

/// `TraceKernel::lanes_at_most`: one `vcmpps` (`LE_OQ`, as `cmpleps`) on eight lanes, where
/// `wide` compares two halves.
#[target_feature(enable = "avx2,bmi2")]
#[inline]
pub(super) fn lanes_at_most(a: f32x8, b: f32x8) -> u32 {
    let (a, b): (__m256, __m256) = (bytemuck::cast(a), bytemuck::cast(b));
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(a, b)) as u32
}

/// A node's child box planes for [`clip_slot`]: per axis the eight slots' entry and exit
/// planes (a four-wide node's four in both 128-bit halves), so that one permute (`vpermps`)
/// spreads a slot's plane over all eight lanes.
pub(in crate::trace) struct Avx2Planes {
    pub(super) entry: [__m256; 3],
    pub(super) exit: [__m256; 3],
}

/// `TraceKernel::planes`: the minima or maxima of each axis picked by the direction's sign
/// with one `vblendvps` each (by `Lanes::negative_masks`), instead of a branch per slot.
#[target_feature(enable = "avx2,bmi2")]
#[inline]
pub(super) fn planes(lanes: &Lanes, (min, max): &ChildBoxes) -> Avx2Planes {
    // Axis by axis, not through `array::map`, whose closure stayed a call.
    let axis = |axis: usize| {
        axis_planes(
            bytemuck::cast(min[axis]),
            bytemuck::cast(max[axis]),
            bytemuck::cast(lanes.negative_masks[axis]),
        )
    };
    let ((entry_x, exit_x), (entry_y, exit_y), (entry_z, exit_z)) = (axis(0), axis(1), axis(2));
    Avx2Planes {
        entry: [entry_x, entry_y, entry_z],
        exit: [exit_x, exit_y, exit_z],
    }
}

/// The entry and exit planes of one axis, each in both halves: `min` and `max` swapped where
/// `negative` is set.
#[target_feature(enable = "avx2,bmi2")]
#[inline]
fn axis_planes(min: __m128, max: __m128, negative: __m128) -> (__m256, __m256) {
    let entry = _mm_blendv_ps(min, max, negative);
    let exit = _mm_blendv_ps(max, min, negative);
    (_mm256_set_m128(entry, entry), _mm256_set_m128(exit, exit))
}

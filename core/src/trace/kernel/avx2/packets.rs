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
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn clip_slot(
    lanes: &Lanes,
    planes: &Avx2Planes,
    slot: usize,
    t_far: f32x8,
) -> (f32x8, f32x8, u32) {
    clip_lanes(lanes, &slot_planes(planes, slot), t_far)
}

/// `TraceKernel::clip_slot_mixed`: [`clip_slot`] with a lane's entry and exit planes swapped
/// on the axes where its direction sign is not lane 0's, by which the planes were picked.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn clip_slot_mixed(
    lanes: &Lanes,
    mixed: &Avx2Mixed,
    planes: &Avx2Planes,
    slot: usize,
    t_far: f32x8,
) -> (f32x8, f32x8, u32) {
    let picked = slot_planes(planes, slot);
    let swapped = std::array::from_fn(|axis| {
        let (entry, exit) = picked[axis];
        let flip = mixed.flip[axis];
        (
            _mm256_blendv_ps(entry, exit, flip),
            _mm256_blendv_ps(exit, entry, flip),
        )
    });
    clip_lanes(lanes, &swapped, t_far)
}

/// `TraceKernel::clip_slot_pair`: [`clip_slot_mixed`] for both halves of a sixteen-ray
/// packet whose halves' origins are equal lane for lane, each plane's difference from the
/// origin computed once for both halves. The difference is taken before the flips' blends:
/// a blend only picks per lane, so each lane subtracts its origin from the plane it clips by,
/// as after the blend.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn clip_slot_pair(
    lanes: [&Lanes; 2],
    mixed: [&Avx2Mixed; 2],
    planes: &Avx2Planes,
    slot: usize,
    t_far: [f32x8; 2],
) -> [(f32x8, f32x8, u32); 2] {
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let picked = slot_planes(planes, slot);
    let mut differences = picked;
    for (axis, (entry, exit)) in differences.iter_mut().enumerate() {
        let origin = wide(lanes[0].origin[axis]);
        (*entry, *exit) = (_mm256_sub_ps(*entry, origin), _mm256_sub_ps(*exit, origin));
    }
    [
        clip_differences(lanes[0], mixed[0], &differences, t_far[0]),
        clip_differences(lanes[1], mixed[1], &differences, t_far[1]),
    ]
}

/// [`clip_lanes`] from the planes' differences from the lanes' origins, each lane's entry and
/// exit swapped by its flips. Kept apart from `clip_lanes` so that the eight-lane walk's code
/// is not reordered.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn clip_differences(
    lanes: &Lanes,
    mixed: &Avx2Mixed,
    differences: &[(__m256, __m256); 3],
    t_far: f32x8,
) -> (f32x8, f32x8, u32) {
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let inflation = _mm256_set1_ps(FAR_INFLATION);
    let mut near = wide(lanes.tmin);
    let mut far = wide(t_far);
    for (axis, &(entry, exit)) in differences.iter().enumerate() {
        let flip = mixed.flip[axis];
        let (entry, exit) = (
            _mm256_blendv_ps(entry, exit, flip),
            _mm256_blendv_ps(exit, entry, flip),
        );
        let entry = _mm256_mul_ps(entry, wide(lanes.entry_reciprocal[axis]));
        let exit = _mm256_mul_ps(
            _mm256_mul_ps(exit, wide(lanes.exit_reciprocal[axis])),
            inflation,
        );
        near = _mm256_max_ps(entry, near);
        far = _mm256_min_ps(exit, far);
    }
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    (bytemuck::cast(near), bytemuck::cast(far), mask)
}

/// Slot `slot`'s entry and exit planes per axis, in every lane.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn slot_planes(planes: &Avx2Planes, slot: usize) -> [(__m256, __m256); 3] {
    let pick = _mm256_set1_epi32(slot as i32);
    std::array::from_fn(|axis| {
        (
            _mm256_permutevar8x32_ps(planes.entry[axis], pick),
            _mm256_permutevar8x32_ps(planes.exit[axis], pick),
        )
    })
}

/// The lanes' interval in the box whose entry and exit planes are `planes` (per axis, each in
/// the lanes that cross it) within `[tmin, t_far]`, and the mask of the lanes entering it.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn clip_lanes(lanes: &Lanes, planes: &[(__m256, __m256); 3], t_far: f32x8) -> (f32x8, f32x8, u32) {
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let inflation = _mm256_set1_ps(FAR_INFLATION);
    let mut near = wide(lanes.tmin);
    let mut far = wide(t_far);
    for (axis, &(entry, exit)) in planes.iter().enumerate() {
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
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
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
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
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
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn axis_planes(min: __m128, max: __m128, negative: __m128) -> (__m256, __m256) {
    let entry = _mm_blendv_ps(min, max, negative);
    let exit = _mm_blendv_ps(max, min, negative);
    (_mm256_set_m128(entry, entry), _mm256_set_m128(exit, exit))
}

/// The packet's rays bounded together, for [`frustum_slots`]: per axis the origin that gives a
/// plane's smallest entry distance over the lanes and the one that gives its largest exit
/// distance, and the lanes' least and greatest reciprocal; the least `tmin`. `None` when a
/// lane's reciprocal is infinite or zero or its origin not finite, where the bounds below
/// would not hold.
pub(in crate::trace) struct Avx2Frustum(Option<FrustumBounds>);

struct FrustumBounds {
    entry_origin: [__m256; 3],
    exit_origin: [__m256; 3],
    reciprocal_low: [__m256; 3],
    reciprocal_high: [__m256; 3],
    tmin: __m256,
}

/// The least lane of `v` in every lane.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn least(v: __m256) -> __m256 {
    let v = _mm256_min_ps(v, _mm256_permute2f128_ps::<1>(v, v));
    let v = _mm256_min_ps(v, _mm256_shuffle_ps::<0b01_00_11_10>(v, v));
    _mm256_min_ps(v, _mm256_shuffle_ps::<0b10_11_00_01>(v, v))
}

/// The greatest lane of `v` in every lane.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn greatest(v: __m256) -> __m256 {
    let v = _mm256_max_ps(v, _mm256_permute2f128_ps::<1>(v, v));
    let v = _mm256_max_ps(v, _mm256_shuffle_ps::<0b01_00_11_10>(v, v));
    _mm256_max_ps(v, _mm256_shuffle_ps::<0b10_11_00_01>(v, v))
}

/// `TraceKernel::frustum`: the bounds over the lanes of `packet_mask` (lane 0 among them);
/// the other lanes take lane 0's values, so that they widen nothing.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn frustum(lanes: &Lanes, packet_mask: u32) -> Avx2Frustum {
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let in_packet = _mm256_castsi256_ps(_mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32(packet_mask as i32), bits),
        bits,
    ));
    let packet = |v: f32x8| {
        let v = wide(v);
        let first = _mm256_permutevar8x32_ps(v, _mm256_setzero_si256());
        _mm256_blendv_ps(first, v, in_packet)
    };
    let magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    let mut finite = 0xFF;
    let mut bounds = FrustumBounds {
        entry_origin: [_mm256_setzero_ps(); 3],
        exit_origin: [_mm256_setzero_ps(); 3],
        reciprocal_low: [_mm256_setzero_ps(); 3],
        reciprocal_high: [_mm256_setzero_ps(); 3],
        // A lane whose `tmin` is NaN enters nothing: `+inf` leaves it out.
        tmin: least(_mm256_min_ps(
            packet(lanes.tmin),
            _mm256_set1_ps(f32::INFINITY),
        )),
    };
    for axis in 0..3 {
        let reciprocal = packet(lanes.exit_reciprocal[axis]);
        let size = _mm256_and_ps(reciprocal, magnitude);
        let usable = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_LT_OQ>(size, _mm256_set1_ps(f32::INFINITY)),
            _mm256_cmp_ps::<_CMP_GT_OQ>(size, _mm256_setzero_ps()),
        );
        let origin = packet(lanes.origin[axis]);
        let finite_origin = _mm256_cmp_ps::<_CMP_LT_OQ>(
            _mm256_and_ps(origin, magnitude),
            _mm256_set1_ps(f32::INFINITY),
        );
        finite &= _mm256_movemask_ps(_mm256_and_ps(usable, finite_origin));
        let (low, high) = (least(origin), greatest(origin));
        // A positive direction enters a plane first from the greatest origin and leaves it
        // last from the least; a negative one the other way round.
        let negative = lanes.signs[axis] & 1 != 0;
        (bounds.entry_origin[axis], bounds.exit_origin[axis]) = match negative {
            true => (low, high),
            false => (high, low),
        };
        bounds.reciprocal_low[axis] = least(reciprocal);
        bounds.reciprocal_high[axis] = greatest(reciprocal);
    }
    Avx2Frustum((finite == 0xFF).then_some(bounds))
}

/// `TraceKernel::frustum_slots`: the slots of `planes` that some lane of the frustum may enter
/// up to `reach`. Per axis a lane's entry distance `(entry - o) * r` is at least the least of
/// `(entry - o') * r_low` and `(entry - o') * r_high` with `o'` the frustum's entry origin
/// (each rounded operation is monotone in each operand, and `r` has one sign), and its exit
/// distance at most the greatest such product from the exit origin, inflated as the lanes'
/// are; a NaN bound keeps the interval's value, as in [`clip_slot`], so it culls nothing. A
/// slot is left out only where the least entry is beyond the greatest exit: no lane enters it.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn frustum_slots(frustum: &Avx2Frustum, planes: &Avx2Planes, reach: f32) -> u32 {
    let Some(bounds) = &frustum.0 else {
        return 0xFF;
    };
    let inflation = _mm256_set1_ps(FAR_INFLATION);
    let mut near = bounds.tmin;
    let mut far = _mm256_set1_ps(reach);
    for axis in 0..3 {
        let (low, high) = (bounds.reciprocal_low[axis], bounds.reciprocal_high[axis]);
        // The lesser of `d * low` and `d * high` is `d * low` where `d`'s sign bit is clear and
        // `d * high` where it is set (rounding is monotone; at a zero `d` both products are
        // zeros of one sign, at a NaN both NaN): one blend on `d`'s sign and one product.
        let entry = _mm256_sub_ps(planes.entry[axis], bounds.entry_origin[axis]);
        let entry = _mm256_mul_ps(entry, _mm256_blendv_ps(low, high, entry));
        let exit = _mm256_sub_ps(planes.exit[axis], bounds.exit_origin[axis]);
        let exit = _mm256_mul_ps(exit, _mm256_blendv_ps(high, low, exit));
        near = _mm256_max_ps(entry, near);
        far = _mm256_min_ps(_mm256_mul_ps(exit, inflation), far);
    }
    let missed = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(near, far)) as u32;
    !missed & 0xFF
}

/// An occlusion packet whose lanes' direction signs may differ ([`TraceKernel::Mixed`]).
///
/// [`TraceKernel::Mixed`]: crate::trace::kernel::TraceKernel::Mixed
pub(in crate::trace) struct Avx2Mixed {
    /// Per axis all ones in the lanes whose direction sign is not lane 0's.
    pub(super) flip: [__m256; 3],
    /// Per axis all ones where lane 0's direction is negative: its entry planes are maxima.
    negative: [__m256; 3],
    /// Per axis the least and greatest coordinate of the lanes' segments, padded; `None` when
    /// a lane's segment is not finite, and nothing is culled.
    segments: Option<([__m256; 3], [__m256; 3])>,
}

/// Lanes whose bit is set in `bits`, as all-ones lanes.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn lanes_of_bits(bits: u32) -> __m256 {
    let each = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32(bits as i32), each),
        each,
    ))
}

/// `TraceKernel::mixed`: the flips, and the box of the segments `o + t d`, `t` in
/// `[tmin, limit]`, over the lanes of `packet_mask` (the others take lane 0's values). A lane's
/// displacement `t d` is taken as `t / r` with `r` its exit reciprocal, and the box padded by
/// `2^-12` of each lane's coordinates' magnitudes, far above the relative error of the clips'
/// distances (a few units in 2^-24, with `FAR_INFLATION` 2^-20): a plane beyond the padded box
/// gives every lane an entry distance beyond its bound or an exit distance below its `tmin`.
/// Segments are bounded only where every lane has a finite origin, `limit` and nonzero finite
/// reciprocals and a `tmin` of at least zero (the exit argument needs `near >= 0` there).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn mixed(lanes: &Lanes, packet_mask: u32, limit: f32x8) -> Avx2Mixed {
    mixed_against(lanes, packet_mask, limit, &lanes.signs)
}

/// `TraceKernel::mixed_against`: [`mixed`] with the flips and lane 0's signs taken from
/// `first_signs` (a packet's `Lanes::signs`, whose lane 0 picked the planes).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn mixed_against(
    lanes: &Lanes,
    packet_mask: u32,
    limit: f32x8,
    first_signs: &[u32; 3],
) -> Avx2Mixed {
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let in_packet = lanes_of_bits(packet_mask);
    let packet = |v: __m256| {
        let first = _mm256_permutevar8x32_ps(v, _mm256_setzero_si256());
        _mm256_blendv_ps(first, v, in_packet)
    };
    let magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    let abs = |v: __m256| _mm256_and_ps(v, magnitude);
    let infinity = _mm256_set1_ps(f32::INFINITY);
    let finite = |v: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(abs(v), infinity);
    let tmin = packet(wide(lanes.tmin));
    let limit = packet(wide(limit));
    let mut usable = _mm256_and_ps(
        _mm256_and_ps(finite(tmin), finite(limit)),
        _mm256_cmp_ps::<_CMP_GE_OQ>(tmin, _mm256_setzero_ps()),
    );
    let pad = _mm256_set1_ps(1.0 / 4096.0);
    let mut low = [_mm256_setzero_ps(); 3];
    let mut high = [_mm256_setzero_ps(); 3];
    for axis in 0..3 {
        let origin = packet(wide(lanes.origin[axis]));
        let reciprocal = packet(wide(lanes.exit_reciprocal[axis]));
        usable = _mm256_and_ps(usable, _mm256_and_ps(finite(origin), finite(reciprocal)));
        usable = _mm256_and_ps(
            usable,
            _mm256_cmp_ps::<_CMP_GT_OQ>(abs(reciprocal), _mm256_setzero_ps()),
        );
        let start = _mm256_div_ps(tmin, reciprocal);
        let end = _mm256_div_ps(limit, reciprocal);
        let margin = _mm256_mul_ps(
            _mm256_add_ps(abs(origin), _mm256_add_ps(abs(start), abs(end))),
            pad,
        );
        let margin = _mm256_add_ps(margin, _mm256_set1_ps(f32::MIN_POSITIVE));
        let lowest = _mm256_sub_ps(_mm256_add_ps(origin, _mm256_min_ps(start, end)), margin);
        let highest = _mm256_add_ps(_mm256_add_ps(origin, _mm256_max_ps(start, end)), margin);
        low[axis] = least(lowest);
        high[axis] = greatest(highest);
    }
    let signs = |axis: usize| lanes.signs[axis];
    let first = |axis: usize| 0u32.wrapping_sub(first_signs[axis] & 1);
    Avx2Mixed {
        flip: std::array::from_fn(|axis| lanes_of_bits((signs(axis) ^ first(axis)) & 0xFF)),
        negative: std::array::from_fn(|axis| lanes_of_bits(first(axis))),
        segments: (_mm256_movemask_ps(usable) == 0xFF).then_some((low, high)),
    }
}

/// `TraceKernel::mixed_slots`: per axis a slot's box (its minimum and maximum, lane 0's entry
/// and exit planes picked back by lane 0's signs) against the segments' box; a NaN plane
/// compares false and culls nothing.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn mixed_slots(mixed: &Avx2Mixed, planes: &Avx2Planes) -> u32 {
    let Some((low, high)) = &mixed.segments else {
        return 0xFF;
    };
    let mut missed = _mm256_setzero_ps();
    for axis in 0..3 {
        let negative = mixed.negative[axis];
        let min = _mm256_blendv_ps(planes.entry[axis], planes.exit[axis], negative);
        let max = _mm256_blendv_ps(planes.exit[axis], planes.entry[axis], negative);
        let below = _mm256_cmp_ps::<_CMP_LT_OQ>(max, low[axis]);
        let above = _mm256_cmp_ps::<_CMP_GT_OQ>(min, high[axis]);
        missed = _mm256_or_ps(missed, _mm256_or_ps(below, above));
    }
    !(_mm256_movemask_ps(missed) as u32) & 0xFF
}

/// `TraceKernel::mixed_slots_pair`: [`mixed_slots`] of both halves of a sixteen-ray packet,
/// whose `negative` are both the first half's lane 0's: each slot's box picked back once.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn mixed_slots_pair(mixed: [&Avx2Mixed; 2], planes: &Avx2Planes) -> [u32; 2] {
    let boxes: [(__m256, __m256); 3] = std::array::from_fn(|axis| {
        let negative = mixed[0].negative[axis];
        (
            _mm256_blendv_ps(planes.entry[axis], planes.exit[axis], negative),
            _mm256_blendv_ps(planes.exit[axis], planes.entry[axis], negative),
        )
    });
    [
        slots_meeting(mixed[0], &boxes),
        slots_meeting(mixed[1], &boxes),
    ]
}

/// The slots whose box (per axis its minimum and maximum) meets the box of `mixed`'s
/// segments, as [`mixed_slots`] finds them.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn slots_meeting(mixed: &Avx2Mixed, boxes: &[(__m256, __m256); 3]) -> u32 {
    let Some((low, high)) = &mixed.segments else {
        return 0xFF;
    };
    let mut missed = _mm256_setzero_ps();
    for (axis, &(min, max)) in boxes.iter().enumerate() {
        let below = _mm256_cmp_ps::<_CMP_LT_OQ>(max, low[axis]);
        let above = _mm256_cmp_ps::<_CMP_GT_OQ>(min, high[axis]);
        missed = _mm256_or_ps(missed, _mm256_or_ps(below, above));
    }
    !(_mm256_movemask_ps(missed) as u32) & 0xFF
}

/// `TraceKernel::plane_order_keys`: `order_keys`' operations in its order on eight lanes, each
/// centre the sum of a slot's entry and exit planes.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn plane_order_keys(planes: &Avx2Planes, negative: &[bool; 3]) -> [f32; 8] {
    let centres = std::array::from_fn(|axis| _mm256_add_ps(planes.entry[axis], planes.exit[axis]));
    super::wide_nodes::keys_of_centres(&centres, negative)
}

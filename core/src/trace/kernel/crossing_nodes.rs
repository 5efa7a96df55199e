//! The crossing walk's test of a format 4 node's eight child boxes (`query::crossing_walk`):
//! each box decoded as the format does, grown by the walk's margin and clipped by the slab
//! test, all eight in one 256-bit register with AVX2. Every lane runs the operations of the
//! walk's four-box test in its order (no fused multiply-add), so the mask is the same bits
//! whichever kernel runs.

#![allow(unsafe_code)]

#[cfg(target_arch = "x86_64")]
use crate::format::WideNode;

/// A ray as the crossing walk's box test needs it: the slab test's precomputed planes and the
/// grown interval. Only the AVX2 test reads it (so other architectures leave it unread).
#[derive(Clone, Copy, Debug)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) struct WidenedRay {
    pub origin: [f32; 3],
    pub entry_reciprocal: [f32; 3],
    pub exit_reciprocal: [f32; 3],
    pub negative: [bool; 3],
    pub t_near: f32,
    pub t_far: f32,
    /// Relative growth of a box: times the sum of its distances to the origin on all axes.
    pub margin: f32,
    /// The slab test's inflation of exit distances.
    pub far_inflation: f32,
}

/// The eight-box test in one AVX2 register: `QueryKernel::entered_wide` of the AVX2 kernel.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn entered_wide_avx2(ray: &WidenedRay, node: &WideNode) -> u32 {
    use std::arch::x86_64::*;

    // Codes widened to f32 (exact), times the power-of-two scale (exact), plus the origin:
    // `WideNode::decode`, one rounding. Each axis's frame is broadcast once for both planes,
    // which the compiler does not always see for itself.
    let origin: [__m256; 3] = std::array::from_fn(|axis| _mm256_set1_ps(node.origin[axis]));
    let scale: [__m256; 3] = std::array::from_fn(|axis| _mm256_set1_ps(node.scale(axis)));
    let decode = |codes: &[u8; 8], axis: usize| {
        let codes = _mm_set_epi64x(0, i64::from_le_bytes(*codes));
        let codes = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(codes));
        _mm256_add_ps(origin[axis], _mm256_mul_ps(codes, scale[axis]))
    };
    let magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    let abs = |x: __m256| _mm256_and_ps(x, magnitude);
    let low: [__m256; 3] = std::array::from_fn(|axis| {
        _mm256_sub_ps(
            decode(&node.min[axis], axis),
            _mm256_set1_ps(ray.origin[axis]),
        )
    });
    let high: [__m256; 3] = std::array::from_fn(|axis| {
        _mm256_sub_ps(
            decode(&node.max[axis], axis),
            _mm256_set1_ps(ray.origin[axis]),
        )
    });
    let reach = |axis: usize| _mm256_add_ps(abs(low[axis]), abs(high[axis]));
    let reach = _mm256_add_ps(_mm256_add_ps(reach(0), reach(1)), reach(2));
    let widen = _mm256_mul_ps(reach, _mm256_set1_ps(ray.margin));
    let mut near = _mm256_set1_ps(ray.t_near);
    let mut far = _mm256_set1_ps(ray.t_far);
    for axis in 0..3 {
        let (low, high) = (
            _mm256_sub_ps(low[axis], widen),
            _mm256_add_ps(high[axis], widen),
        );
        let (entry, exit) = match ray.negative[axis] {
            true => (high, low),
            false => (low, high),
        };
        let entry = _mm256_mul_ps(entry, _mm256_set1_ps(ray.entry_reciprocal[axis]));
        let exit = _mm256_mul_ps(
            _mm256_mul_ps(exit, _mm256_set1_ps(ray.exit_reciprocal[axis])),
            _mm256_set1_ps(ray.far_inflation),
        );
        // MAXPS and MINPS return their second operand unless the first is beyond it: the
        // four-box test's `max_not_nan_x4` and `min_not_nan_x4`, NaN included.
        near = _mm256_max_ps(entry, near);
        far = _mm256_min_ps(exit, far);
    }
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32
}

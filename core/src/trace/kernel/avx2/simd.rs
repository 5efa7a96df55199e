//! Small AVX2 operations the blocks and the packet strips share.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use crate::trace::kernel::BLOCK;

/// `watertight::candidate_lanes` lanewise: the weights' sign bits compared by `vxorps`, their
/// product compared with zero unordered (`vcmpeq_uqps`, true also for NaN).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn candidate_lanes(w: &[__m256; 3]) -> u32 {
    let signs_differ = _mm256_or_ps(_mm256_xor_ps(w[0], w[1]), _mm256_xor_ps(w[1], w[2]));
    let product = _mm256_mul_ps(_mm256_mul_ps(w[0], w[1]), w[2]);
    let zero_or_nan = _mm256_cmp_ps::<_CMP_EQ_UQ>(product, _mm256_setzero_ps());
    let differ = _mm256_movemask_ps(signs_differ) as u32;
    let zero = _mm256_movemask_ps(zero_or_nan) as u32;
    (!differ | zero) & 0xFF
}

/// [`in_range_lanes`] with a range per lane.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn in_range_lanes_between(
    w: &[__m256; 3],
    z: &[__m256; 3],
    tmin: __m256,
    tmax: __m256,
) -> u32 {
    let zero = _mm256_setzero_ps();
    let det = _mm256_add_ps(_mm256_add_ps(w[0], w[1]), w[2]);
    let scaled = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(w[0], z[0]), _mm256_mul_ps(w[1], z[1])),
        _mm256_mul_ps(w[2], z[2]),
    );
    let t = _mm256_div_ps(scaled, det);
    let in_range = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_LE_OQ>(tmin, t),
        _mm256_cmp_ps::<_CMP_LE_OQ>(t, tmax),
    );
    let on_edge = _mm256_or_ps(
        _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_EQ_OQ>(w[0], zero),
            _mm256_cmp_ps::<_CMP_EQ_OQ>(w[1], zero),
        ),
        _mm256_cmp_ps::<_CMP_EQ_OQ>(w[2], zero),
    );
    _mm256_movemask_ps(_mm256_or_ps(in_range, on_edge)) as u32
}

/// Vertex `index` of the flattened f32 vertices as `[x, y, z, any]`. A strip has at least
/// three vertices, so four floats can always be read: the last vertex is read one float early
/// and moved down. An index past the vertices (only in a corrupt file, which opening rejects)
/// reads the last four floats rather than out of bounds.
///
/// The load is unchecked: with the start clamped to `flat.len() - 4` the four floats are in
/// bounds whatever the index, and a checked slice costs a few instructions per vertex.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn load_vertex(flat: &[f32], index: usize) -> __m128 {
    assert!(flat.len() >= 4, "a strip has at least three vertices");
    let start = (3 * index).min(flat.len() - 4);
    // SAFETY: `start + 4 <= flat.len()` (clamped just above), so the unaligned load reads four
    // f32 (16 bytes) inside `flat`; SSE is enabled.
    let four = unsafe { _mm_loadu_ps(flat.as_ptr().add(start)) };
    if start == 3 * index {
        four
    } else {
        _mm_permute_ps::<0b00_11_10_01>(four)
    }
}

/// The eight lanes of `value` (a block's windows, or a packet's rays).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn lanes(value: __m256) -> [f32; BLOCK] {
    let mut lanes = [0.0; BLOCK];
    // SAFETY: `lanes` is eight f32 (32 bytes), what the unaligned store writes; AVX is enabled.
    unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), value) };
    lanes
}

/// `watertight::edge_lanes`, lanewise the same operations: `q.x * p.y - q.y * p.x`.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn edge(p: &[__m256; 2], q: &[__m256; 2]) -> __m256 {
    _mm256_sub_ps(_mm256_mul_ps(q[0], p[1]), _mm256_mul_ps(q[1], p[0]))
}

/// `values` as eight lanes.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn load(values: &[f32; BLOCK]) -> __m256 {
    // SAFETY: `values` is eight f32 (32 bytes), what the unaligned load reads; AVX is enabled.
    unsafe { _mm256_loadu_ps(values.as_ptr()) }
}

//! The crossing walk's test of a format 4 node's eight child boxes (`query::crossing_walk`):
//! each box decoded as the format does, grown by the walk's margin and clipped by the slab
//! test, all eight in one 256-bit register with AVX2. Every lane runs the operations of the
//! walk's four-box test in its order (no fused multiply-add), so the mask is the same bits
//! whichever kernel runs.

#![allow(unsafe_code)]

use super::Kernel;
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

/// How a walk tests a wide node's eight child boxes: the children whose grown box the ray may
/// meet as a bit mask (bit `k`: slot `k`), or `None` where the kernel has no eight-lane
/// registers and the walk tests four boxes at a time. Chosen once per walk by [`compiled`].
pub(crate) trait WideBoxes {
    fn entered(ray: &WidenedRay, node: &WideNode) -> Option<u32>;
}

/// Four boxes at a time, by the walk's own test.
struct FourLanes;

impl WideBoxes for FourLanes {
    #[inline(always)]
    fn entered(_: &WidenedRay, _: &WideNode) -> Option<u32> {
        None
    }
}

/// All eight in one AVX2 register; only [`compiled`] names it, once the CPU was found to run
/// AVX2.
#[cfg(target_arch = "x86_64")]
struct EightLanes;

#[cfg(target_arch = "x86_64")]
impl WideBoxes for EightLanes {
    #[inline(always)]
    fn entered(ray: &WidenedRay, node: &WideNode) -> Option<u32> {
        // SAFETY: `EightLanes` runs only inside `compiled_for_avx2`, called once AVX2 was
        // detected.
        Some(unsafe { entered_wide_avx2(ray, node) })
    }
}

/// A crossing walk generic over its wide-node test, for [`compiled`].
pub(crate) trait NodeWalk {
    type Output;

    fn run<B: WideBoxes>(self) -> Self::Output;
}

/// `walk` with its node tests chosen once: on AVX2 the whole walk is compiled for AVX2, so
/// that the eight-box test is inlined into its loop with the ray's planes loaded once, not
/// called (and the CPU asked) at every node. The masks are the same bits on every path.
#[inline(always)]
pub(crate) fn compiled<W: NodeWalk>(kernel: Kernel, walk: W) -> W::Output {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU runs AVX2 and BMI2, just checked.
        Kernel::Avx2 if super::detect::avx2() => unsafe { compiled_for_avx2(walk) },
        _ => walk.run::<FourLanes>(),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi2")]
#[inline(never)]
fn compiled_for_avx2<W: NodeWalk>(walk: W) -> W::Output {
    walk.run::<EightLanes>()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn entered_wide_avx2(ray: &WidenedRay, node: &WideNode) -> u32 {
    use std::arch::x86_64::*;

    // Codes widened to f32 (exact), times the power-of-two scale (exact), plus the origin:
    // `WideNode::decode`, one rounding.
    let decode = |codes: &[u8; 8], axis: usize| {
        let codes = _mm_set_epi64x(0, i64::from_le_bytes(*codes));
        let codes = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(codes));
        let origin = _mm256_set1_ps(node.origin[axis]);
        _mm256_add_ps(
            origin,
            _mm256_mul_ps(codes, _mm256_set1_ps(node.scale(axis))),
        )
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

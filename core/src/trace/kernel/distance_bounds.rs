//! Lower bounds of the squared distance from a point to several boxes at once, for the
//! closest-point walk: the child boxes of a top-level node, and the boxes of the windows of a
//! strip block. Every lane runs the same f64 operations in the same order whichever kernel runs
//! (AVX2 only widens the lanes; no fused multiply-add), so the bounds are bit-identical across
//! kernels and architectures. The walk reaches them through `QueryKernel` (`query_kernel`).
//!
//! Exactness: a bound is computed in f64 and then lowered by [`BOUND_SHRINK`], so it is never
//! above the true distance from the point to the box, hence to any triangle in it.

#![allow(unsafe_code)]

use super::BLOCK;
#[cfg(target_arch = "x86_64")]
use crate::format::vertices::VertexAccess;
use crate::format::TOP_WIDTH;
#[cfg(target_arch = "x86_64")]
use crate::geometry::Point;

/// The factor that lowers a box's squared distance below its f64 rounding: a subtraction, three
/// squares and two sums, each rounded by at most 2^-53 relative, stay within 2^-50.
pub(crate) const BOUND_SHRINK: f64 = 1.0 - 1.0 / (1u64 << 48) as f64;

/// Boxes by axis and lane: `[axis][lane]`.
pub(crate) type LaneBoxes<const N: usize> = [[f32; N]; 3];

/// The vertices of a block of [`BLOCK`] windows by axis (`[axis][vertex]`), window `k` having
/// vertices `k`, `k + 1` and `k + 2`.
pub(crate) type BlockCorners = [[f32; BLOCK + 2]; 3];

/// A lower bound of the squared distance from `query` to the box `min..max`, never above the
/// true one. A NaN plane (only in a corrupt box) counts as no gap.
#[inline(always)]
pub(crate) fn box_bound(query: &[f64; 3], min: &[f32; 3], max: &[f32; 3]) -> f64 {
    let gaps: [f64; 3] = std::array::from_fn(|axis| {
        let below = f64::from(min[axis]) - query[axis];
        let above = query[axis] - f64::from(max[axis]);
        gap(below, above)
    });
    squared_bound(gaps)
}

/// The gap on one axis from the signed distances below the box's minimum and above its
/// maximum: comparisons that vectorize (`f64::max` does not), and a NaN side counts as none.
#[inline(always)]
fn gap(below: f64, above: f64) -> f64 {
    let below = if below > 0.0 { below } else { 0.0 };
    let above = if above > 0.0 { above } else { 0.0 };
    if below > above {
        below
    } else {
        above
    }
}

#[inline(always)]
fn squared_bound([x, y, z]: [f64; 3]) -> f64 {
    (x * x + y * y + z * z) * BOUND_SHRINK
}

#[inline(always)]
pub(super) fn child_lanes(
    query: &[f64; 3],
    min: &LaneBoxes<TOP_WIDTH>,
    max: &LaneBoxes<TOP_WIDTH>,
) -> [f64; TOP_WIDTH] {
    std::array::from_fn(|lane| box_bound(query, &min.map(|a| a[lane]), &max.map(|a| a[lane])))
}

/// Each vertex's offset from the query once, then per window the smallest and largest of its
/// three corners' offsets: the same values as offsetting the window box's planes, since rounding
/// is monotonic.
#[inline(always)]
pub(super) fn window_lanes(query: &[f64; 3], corners: &BlockCorners) -> [f64; BLOCK] {
    let offsets: [[f64; BLOCK + 2]; 3] =
        std::array::from_fn(|axis| corners[axis].map(|x| f64::from(x) - query[axis]));
    let lesser = |a: f64, b: f64| if a < b { a } else { b };
    let greater = |a: f64, b: f64| if a > b { a } else { b };
    let gaps: [[f64; BLOCK]; 3] = std::array::from_fn(|axis| {
        let o = &offsets[axis];
        std::array::from_fn(|lane| {
            let low = lesser(lesser(o[lane], o[lane + 1]), o[lane + 2]);
            let high = greater(greater(o[lane], o[lane + 1]), o[lane + 2]);
            gap(low, -high)
        })
    });
    std::array::from_fn(|lane| squared_bound([gaps[0][lane], gaps[1][lane], gaps[2][lane]]))
}

/// [`child_lanes`] in AVX2: the four slots in one register, the same operations lane by lane
/// (`max_pd(a, b)` is `if a > b { a } else { b }`, `min_pd` likewise with `<`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn child_bounds_avx2(
    query: &[f64; 3],
    min: &LaneBoxes<TOP_WIDTH>,
    max: &LaneBoxes<TOP_WIDTH>,
) -> [f64; TOP_WIDTH] {
    use std::arch::x86_64::*;
    let gaps: [__m256d; 3] = std::array::from_fn(|axis| {
        let q = _mm256_set1_pd(query[axis]);
        // SAFETY: each row holds four f32, the width of the load.
        let (low, high) = unsafe {
            (
                _mm_loadu_ps(min[axis].as_ptr()),
                _mm_loadu_ps(max[axis].as_ptr()),
            )
        };
        let below = _mm256_sub_pd(_mm256_cvtps_pd(low), q);
        let above = _mm256_sub_pd(q, _mm256_cvtps_pd(high));
        gap_avx2(below, above)
    });
    squared_bound_avx2(gaps)
}

/// [`window_lanes`] in AVX2: windows 0-3 and 4-7 in a register each, a corner's offsets read
/// as the vertices shifted by 0, 1 and 2 positions.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn window_bounds_avx2(query: &[f64; 3], corners: &BlockCorners) -> [f64; BLOCK] {
    use std::arch::x86_64::*;
    let half = |first: usize| {
        let gaps: [__m256d; 3] = std::array::from_fn(|axis| {
            let q = _mm256_set1_pd(query[axis]);
            let offset = |shift: usize| {
                let row = &corners[axis][first + shift..first + shift + 4];
                // SAFETY: the slice holds four f32, the width of the load.
                let vertices = unsafe { _mm_loadu_ps(row.as_ptr()) };
                _mm256_sub_pd(_mm256_cvtps_pd(vertices), q)
            };
            let (a, b, c) = (offset(0), offset(1), offset(2));
            let low = _mm256_min_pd(_mm256_min_pd(a, b), c);
            let high = _mm256_max_pd(_mm256_max_pd(a, b), c);
            gap_avx2(low, _mm256_xor_pd(high, _mm256_set1_pd(-0.0)))
        });
        squared_bound_avx2(gaps)
    };
    let (low, high) = (half(0), half(4));
    std::array::from_fn(|lane| if lane < 4 { low[lane] } else { high[lane - 4] })
}

/// [`window_lanes`] in AVX2 of a lossless block read from the strip's vertices by its
/// `references`: each vertex's offset as one register (x, y, z, 0), a window's minima and maxima
/// across three of them, four windows' gaps transposed into axes; the same operations lane by
/// lane. Rows gathered on the stack would be read back by loads wider than their stores, which
/// stall.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn vertex_window_bounds_avx2(
    query: &[f64; 3],
    vertices: &[Point],
    references: &[u8; BLOCK + 2],
) -> [f64; BLOCK] {
    use std::arch::x86_64::*;
    let q = _mm256_setr_pd(query[0], query[1], query[2], 0.0);
    let offsets: [__m256d; BLOCK + 2] = std::array::from_fn(|k| {
        let [x, y, z] = vertices.point(references[k] as usize);
        _mm256_sub_pd(_mm256_cvtps_pd(_mm_setr_ps(x, y, z, 0.0)), q)
    });
    let gaps: [__m256d; BLOCK] = std::array::from_fn(|window| {
        let (a, b, c) = (offsets[window], offsets[window + 1], offsets[window + 2]);
        let low = _mm256_min_pd(_mm256_min_pd(a, b), c);
        let high = _mm256_max_pd(_mm256_max_pd(a, b), c);
        gap_avx2(low, _mm256_xor_pd(high, _mm256_set1_pd(-0.0)))
    });
    let half = |first: usize| {
        let [g0, g1, g2, g3] = [0, 1, 2, 3].map(|k| gaps[first + k]);
        // (x0, x1, z0, z1) and (y0, y1, _, _), then the halves of two such pairs joined.
        let (xz01, y01) = (_mm256_unpacklo_pd(g0, g1), _mm256_unpackhi_pd(g0, g1));
        let (xz23, y23) = (_mm256_unpacklo_pd(g2, g3), _mm256_unpackhi_pd(g2, g3));
        squared_bound_avx2([
            _mm256_permute2f128_pd::<0x20>(xz01, xz23),
            _mm256_permute2f128_pd::<0x20>(y01, y23),
            _mm256_permute2f128_pd::<0x31>(xz01, xz23),
        ])
    };
    let (low, high) = (half(0), half(4));
    std::array::from_fn(|lane| if lane < 4 { low[lane] } else { high[lane - 4] })
}

/// [`gap`] lane by lane.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn gap_avx2(
    below: std::arch::x86_64::__m256d,
    above: std::arch::x86_64::__m256d,
) -> std::arch::x86_64::__m256d {
    use std::arch::x86_64::*;
    let zero = _mm256_setzero_pd();
    _mm256_max_pd(_mm256_max_pd(below, zero), _mm256_max_pd(above, zero))
}

/// [`squared_bound`] lane by lane.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn squared_bound_avx2([x, y, z]: [std::arch::x86_64::__m256d; 3]) -> [f64; 4] {
    use std::arch::x86_64::*;
    let sum = _mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(x, x), _mm256_mul_pd(y, y)),
        _mm256_mul_pd(z, z),
    );
    let bound = _mm256_mul_pd(sum, _mm256_set1_pd(BOUND_SHRINK));
    let mut lanes = [0.0; 4];
    // SAFETY: `lanes` holds four f64, the width of the store.
    unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), bound) };
    lanes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;
    use crate::trace::kernel::query_kernel::{dispatch_query, QueryKernel, QueryWalk};
    use crate::trace::kernel::Kernel;

    #[test]
    fn box_bounds_are_zero_inside_and_below_the_distance_outside() {
        let (min, max) = ([0.0, 0.0, 0.0], [1.0, 2.0, 3.0]);
        assert_eq!(box_bound(&[0.5, 1.0, 1.0], &min, &max), 0.0);
        let bound = box_bound(&[4.0, -4.0, 3.0], &min, &max);
        assert!(bound < 25.0 && bound > 25.0 * (1.0 - 1e-14));
        let nan = [f32::NAN; 3];
        assert_eq!(box_bound(&[9.0, 9.0, 9.0], &nan, &nan), 0.0);
        assert_eq!(
            box_bound(&[9.0, 0.0, 0.0], &nan, &[1.0, 0.0, 0.0]),
            64.0 * BOUND_SHRINK
        );
    }

    /// Lane values from a small generator, with NaN planes and inverted boxes among them.
    fn value(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        match *seed >> 60 {
            0 => f32::NAN,
            _ => ((*seed >> 33) as i32 % 2000) as f32 / 7.0 - 140.0,
        }
    }

    /// Both bounds of one block on `kernel`, through [`dispatch_query`] as the search runs them.
    struct Bounds<'a> {
        query: &'a [f64; 3],
        boxes: (&'a LaneBoxes<TOP_WIDTH>, &'a LaneBoxes<TOP_WIDTH>),
        corners: &'a BlockCorners,
    }

    impl QueryWalk for Bounds<'_> {
        type Output = ([f64; TOP_WIDTH], [f64; BLOCK]);

        fn run<Q: QueryKernel>(self) -> Self::Output {
            let (min, max) = self.boxes;
            let windows = Q::window_bounds(self.query, self.corners);
            // The same corners as a strip's vertices, referenced in order.
            let vertices: [Point; BLOCK + 2] =
                std::array::from_fn(|k| self.corners.map(|axis| axis[k]));
            let references = std::array::from_fn(|k| k as u8);
            let from_vertices = Q::vertex_window_bounds(self.query, &vertices, &references);
            assert!(windows
                .iter()
                .zip(from_vertices)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
            (Q::child_bounds(self.query, min, max), windows)
        }
    }

    #[test]
    fn every_kernel_bounds_each_lane_as_the_single_box_rule() {
        let mut seed = 5;
        for _ in 0..500 {
            let query = [0; 3].map(|_| f64::from(value(&mut seed)) * 1.3);
            let min: LaneBoxes<TOP_WIDTH> =
                [[0.0; TOP_WIDTH]; 3].map(|a| a.map(|_| value(&mut seed)));
            let max: LaneBoxes<TOP_WIDTH> =
                [[0.0; TOP_WIDTH]; 3].map(|a| a.map(|_| value(&mut seed)));
            let corners: BlockCorners = [[0.0; BLOCK + 2]; 3].map(|a| a.map(|_| value(&mut seed)));
            let on = |kernel: Kernel| {
                let boxes = (&min, &max);
                dispatch_query(
                    kernel,
                    Bounds {
                        query: &query,
                        boxes,
                        corners: &corners,
                    },
                )
            };
            let (children, windows) = on(Kernel::Sse2);
            for (slot, bound) in children.iter().enumerate() {
                let expected = box_bound(&query, &min.map(|a| a[slot]), &max.map(|a| a[slot]));
                assert_eq!(bound.to_bits(), expected.to_bits());
            }
            for (lane, bound) in windows.iter().enumerate() {
                let coordinates = |axis: usize| &corners[axis][lane..lane + 3];
                if (0..3).any(|axis| coordinates(axis).iter().any(|x| x.is_nan())) {
                    continue;
                }
                let low = std::array::from_fn(|axis| {
                    coordinates(axis)
                        .iter()
                        .copied()
                        .fold(f32::INFINITY, f32::min)
                });
                let high = std::array::from_fn(|axis| {
                    coordinates(axis)
                        .iter()
                        .copied()
                        .fold(f32::NEG_INFINITY, f32::max)
                });
                assert_eq!(bound.to_bits(), box_bound(&query, &low, &high).to_bits());
            }
            for kernel in Kernel::supported() {
                let same =
                    |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
                let (kernel_children, kernel_windows) = on(kernel);
                assert!(same(&kernel_children, &children));
                assert!(same(&kernel_windows, &windows));
            }
        }
    }
}

//! The exact closest points of four triangles to one point at once, for the closest-point search:
//! [`closest_on_triangle`](crate::query::triangle_distance::closest_on_triangle)'s Voronoi-region
//! rule with every region's weights computed in every lane and the first region that holds picked
//! by masks, so that no lane branches.
//!
//! Each lane runs the scalar function's f64 operations in its order (no fused multiply-add; the
//! regions' comparisons are the same ordered comparisons), so a lane's distance, weights and
//! point are the scalar function's bits. A lane whose face-region weights come out of range
//! (a sliver or a triangle without area) is left to the scalar function, which then picks the
//! nearest edge; that case is rare.

#![allow(unsafe_code)]

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

use wide::f64x4;

use crate::query::triangle_distance::TrianglePoint;

/// Triangles tested at once.
pub(crate) const TRIANGLE_LANES: usize = 4;

/// Up to [`TRIANGLE_LANES`] triangles' corners widened to f64: `[corner][axis][lane]`.
pub(crate) type CornerLanes = [[[f64; TRIANGLE_LANES]; 3]; 3];

/// Each lane's closest point, as [`TrianglePoint`]'s fields by lane, and the lanes the region
/// masks decided (bit `k`: lane `k`); the others are the scalar function's to answer.
pub(crate) struct LanePoints {
    pub distance_squared: [f64; TRIANGLE_LANES],
    pub u: [f64; TRIANGLE_LANES],
    pub v: [f64; TRIANGLE_LANES],
    pub point: [[f64; TRIANGLE_LANES]; 3],
    pub decided: u32,
}

impl LanePoints {
    /// Lane `lane`'s closest point (a decided lane).
    #[inline(always)]
    pub(crate) fn lane(&self, lane: usize) -> TrianglePoint {
        TrianglePoint {
            distance_squared: self.distance_squared[lane],
            u: self.u[lane],
            v: self.v[lane],
            point: [
                self.point[0][lane],
                self.point[1][lane],
                self.point[2][lane],
            ],
        }
    }
}

/// Four f64 lanes: `wide`'s on the portable kernel, 256-bit registers on AVX2. Comparisons
/// give all-ones lanes where they hold.
pub(crate) trait F64Lanes:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
{
    fn splat(x: f64) -> Self;
    fn load(lanes: &[f64; TRIANGLE_LANES]) -> Self;
    fn store(self) -> [f64; TRIANGLE_LANES];
    fn le(self, other: Self) -> Self;
    fn ge(self, other: Self) -> Self;
    fn lt(self, other: Self) -> Self;
    fn gt(self, other: Self) -> Self;
    /// `if_true` in the lanes where `self` is all ones, else `if_false`.
    fn select(self, if_true: Self, if_false: Self) -> Self;
    fn bitmask(self) -> u32;
}

impl F64Lanes for f64x4 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        f64x4::splat(x)
    }
    #[inline(always)]
    fn load(lanes: &[f64; TRIANGLE_LANES]) -> Self {
        f64x4::from(*lanes)
    }
    #[inline(always)]
    fn store(self) -> [f64; TRIANGLE_LANES] {
        self.to_array()
    }
    #[inline(always)]
    fn le(self, other: Self) -> Self {
        self.simd_le(other)
    }
    #[inline(always)]
    fn ge(self, other: Self) -> Self {
        self.simd_ge(other)
    }
    #[inline(always)]
    fn lt(self, other: Self) -> Self {
        self.simd_lt(other)
    }
    #[inline(always)]
    fn gt(self, other: Self) -> Self {
        self.simd_gt(other)
    }
    #[inline(always)]
    fn select(self, if_true: Self, if_false: Self) -> Self {
        self.bitselect(if_true, if_false)
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        self.to_bitmask()
    }
}

/// The closest point of each lane's triangle to `p`, in lanes `L`.
#[inline(always)]
pub(crate) fn closest_on_triangles<L: F64Lanes>(p: &[f64; 3], corners: &CornerLanes) -> LanePoints {
    let p = [L::splat(p[0]), L::splat(p[1]), L::splat(p[2])];
    let corner = |k: usize| {
        [
            L::load(&corners[k][0]),
            L::load(&corners[k][1]),
            L::load(&corners[k][2]),
        ]
    };
    let (a, b, c) = (corner(0), corner(1), corner(2));
    let (ab, ac) = (sub(&b, &a), sub(&c, &a));
    let (u, v, decided) = region_weights(&p, &a, &b, &c, &ab, &ac);
    let on = |axis: usize| a[axis] + u * ab[axis] + v * ac[axis];
    let point = [on(0), on(1), on(2)];
    let offset = sub(&p, &point);
    LanePoints {
        distance_squared: dot(&offset, &offset).store(),
        u: u.store(),
        v: v.store(),
        point: [point[0].store(), point[1].store(), point[2].store()],
        decided: decided.bitmask(),
    }
}

/// The weights `(u, v)` of the first Voronoi region that holds the point, in the scalar rule's
/// order (vertices a, b, c, edges ab, ac, bc, then the face), and the lanes where one did.
#[inline(always)]
fn region_weights<L: F64Lanes>(
    p: &[L; 3],
    a: &[L; 3],
    b: &[L; 3],
    c: &[L; 3],
    ab: &[L; 3],
    ac: &[L; 3],
) -> (L, L, L) {
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let ap = sub(p, a);
    let (d1, d2) = (dot(ab, &ap), dot(ac, &ap));
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, &bp), dot(ac, &bp));
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, &cp), dot(ac, &cp));
    let at_a = d1.le(zero) & d2.le(zero);
    let at_b = d3.ge(zero) & d4.le(d3);
    let at_c = d6.ge(zero) & d5.le(d6);
    let area_c = d1 * d4 - d3 * d2;
    let on_ab = area_c.le(zero) & d1.ge(zero) & d3.le(zero);
    let area_b = d5 * d2 - d1 * d6;
    let on_ac = area_b.le(zero) & d2.ge(zero) & d6.le(zero);
    let area_a = d3 * d6 - d5 * d4;
    let (towards_c_from_b, towards_b_from_c) = (d4 - d3, d5 - d6);
    let on_bc = area_a.le(zero) & towards_c_from_b.ge(zero) & towards_b_from_c.ge(zero);
    let total = area_a + area_b + area_c;
    let (face_u, face_v) = (area_b / total, area_c / total);
    let on_face = face_u.ge(zero) & face_v.ge(zero) & (face_u + face_v).le(one);
    let bc_w = ratio(towards_c_from_b, towards_c_from_b + towards_b_from_c);
    // From the face back to vertex a, so that the first region of the scalar order wins.
    let mut u = on_bc.select(one - bc_w, face_u);
    let mut v = on_bc.select(bc_w, face_v);
    v = on_ac.select(ratio(d2, d2 - d6), v);
    u = on_ac.select(zero, u);
    u = on_ab.select(ratio(d1, d1 - d3), u);
    v = on_ab.select(zero, v);
    u = at_c.select(zero, u);
    v = at_c.select(one, v);
    u = at_b.select(one, u);
    v = at_b.select(zero, v);
    u = at_a.select(zero, u);
    v = at_a.select(zero, v);
    let decided = at_a | at_b | at_c | on_ab | on_ac | on_bc | on_face;
    (u, v, decided)
}

/// The scalar rule's `ratio` in each lane: `numerator / denominator` clamped to `[0, 1]` (a
/// NaN quotient stays NaN, as `f64::clamp` keeps it), 0 where the denominator is not positive.
#[inline(always)]
fn ratio<L: F64Lanes>(numerator: L, denominator: L) -> L {
    let (zero, one) = (L::splat(0.0), L::splat(1.0));
    let quotient = numerator / denominator;
    let quotient = quotient.lt(zero).select(zero, quotient);
    let quotient = quotient.gt(one).select(one, quotient);
    denominator.gt(zero).select(quotient, zero)
}

#[inline(always)]
fn sub<L: F64Lanes>(x: &[L; 3], y: &[L; 3]) -> [L; 3] {
    [x[0] - y[0], x[1] - y[1], x[2] - y[2]]
}

#[inline(always)]
fn dot<L: F64Lanes>(x: &[L; 3], y: &[L; 3]) -> L {
    x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
}

/// [`F64Lanes`] in a 256-bit register; made only inside the AVX2 kernel's compiled walk.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Sub};

    use super::{closest_on_triangles, CornerLanes, F64Lanes, LanePoints, TRIANGLE_LANES};

    #[derive(Clone, Copy)]
    pub(crate) struct Avx2Lanes(__m256d);

    /// [`closest_on_triangles`] in 256-bit registers.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn closest_on_triangles_avx2(p: &[f64; 3], corners: &CornerLanes) -> LanePoints {
        closest_on_triangles::<Avx2Lanes>(p, corners)
    }

    // SAFETY (every intrinsic below): these lanes exist only in the AVX2 kernel's walk, which
    // runs once the CPU was found to have AVX2 (`kernel::dispatch`).
    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for Avx2Lanes {
                type Output = Avx2Lanes;
                #[inline(always)]
                fn $method(self, other: Avx2Lanes) -> Avx2Lanes {
                    // SAFETY: see above.
                    Avx2Lanes(unsafe { $intrinsic(self.0, other.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_pd);
    binary!(Sub, sub, _mm256_sub_pd);
    binary!(Mul, mul, _mm256_mul_pd);
    binary!(Div, div, _mm256_div_pd);
    binary!(BitAnd, bitand, _mm256_and_pd);
    binary!(BitOr, bitor, _mm256_or_pd);

    impl Avx2Lanes {
        #[inline(always)]
        fn compare<const PREDICATE: i32>(self, other: Avx2Lanes) -> Avx2Lanes {
            // SAFETY: see above.
            Avx2Lanes(unsafe { _mm256_cmp_pd::<PREDICATE>(self.0, other.0) })
        }
    }

    impl F64Lanes for Avx2Lanes {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            // SAFETY: see above.
            Avx2Lanes(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        fn load(lanes: &[f64; TRIANGLE_LANES]) -> Self {
            // SAFETY: see above; `lanes` holds four f64, the width of the load.
            Avx2Lanes(unsafe { _mm256_loadu_pd(lanes.as_ptr()) })
        }
        #[inline(always)]
        fn store(self) -> [f64; TRIANGLE_LANES] {
            let mut lanes = [0.0; TRIANGLE_LANES];
            // SAFETY: see above; `lanes` holds four f64, the width of the store.
            unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), self.0) };
            lanes
        }
        // Ordered, non-signalling: false with a NaN, as the scalar rule's comparisons.
        #[inline(always)]
        fn le(self, other: Self) -> Self {
            self.compare::<_CMP_LE_OQ>(other)
        }
        #[inline(always)]
        fn ge(self, other: Self) -> Self {
            self.compare::<_CMP_GE_OQ>(other)
        }
        #[inline(always)]
        fn lt(self, other: Self) -> Self {
            self.compare::<_CMP_LT_OQ>(other)
        }
        #[inline(always)]
        fn gt(self, other: Self) -> Self {
            self.compare::<_CMP_GT_OQ>(other)
        }
        #[inline(always)]
        fn select(self, if_true: Self, if_false: Self) -> Self {
            // SAFETY: see above.
            Avx2Lanes(unsafe { _mm256_blendv_pd(if_false.0, if_true.0, self.0) })
        }
        #[inline(always)]
        fn bitmask(self) -> u32 {
            // SAFETY: see above.
            unsafe { _mm256_movemask_pd(self.0) as u32 }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::query::triangle_distance::closest_on_triangle;
    use crate::trace::kernel::query_kernel::{dispatch_query, QueryKernel, QueryWalk};
    use crate::trace::kernel::Kernel;

    /// Values from a small generator: mostly spread coordinates, some repeated so that
    /// triangles degenerate (shared corners, collinear corners).
    fn value(seed: &mut u64) -> f32 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        match *seed >> 60 {
            0 => 1.0,
            1 => 0.0,
            _ => ((*seed >> 33) as i32 % 4000) as f32 / 37.0 - 50.0,
        }
    }

    trait Bits {
        fn to_bits_array(&self) -> [u64; 6];
    }

    impl Bits for TrianglePoint {
        fn to_bits_array(&self) -> [u64; 6] {
            let [x, y, z] = self.point;
            [self.distance_squared, self.u, self.v, x, y, z].map(f64::to_bits)
        }
    }

    /// One batch on a kernel, through [`dispatch_query`] as the search runs it.
    struct Lanes<'a> {
        p: &'a [f64; 3],
        corners: &'a CornerLanes,
    }

    impl QueryWalk for Lanes<'_> {
        type Output = LanePoints;

        fn run<Q: QueryKernel>(self) -> LanePoints {
            Q::closest_on_triangles(self.p, self.corners)
        }
    }

    #[test]
    fn every_lane_is_the_scalar_rule() {
        let mut seed = 11;
        for round in 0..20_000 {
            let query: [f32; 3] = std::array::from_fn(|_| value(&mut seed));
            let mut triangles = [[[0.0f32; 3]; 3]; TRIANGLE_LANES];
            for triangle in triangles.iter_mut() {
                *triangle = std::array::from_fn(|_| std::array::from_fn(|_| value(&mut seed)));
                if round % 7 == 0 {
                    // Collinear corners: no area, the nearest edge answers.
                    triangle[2] =
                        std::array::from_fn(|axis| 2.0 * triangle[1][axis] - triangle[0][axis]);
                }
            }
            let corners: CornerLanes = std::array::from_fn(|k| {
                std::array::from_fn(|axis| {
                    std::array::from_fn(|lane| f64::from(triangles[lane][k][axis]))
                })
            });
            let wide = query.map(f64::from);
            let found = closest_on_triangles::<f64x4>(&wide, &corners);
            for kernel in Kernel::supported() {
                let on_kernel = dispatch_query(
                    kernel,
                    Lanes {
                        p: &wide,
                        corners: &corners,
                    },
                );
                assert_eq!(on_kernel.decided, found.decided);
                for lane in 0..TRIANGLE_LANES {
                    let same = |t: &TrianglePoint| t.to_bits_array();
                    if found.decided >> lane & 1 != 0 {
                        assert_eq!(same(&on_kernel.lane(lane)), same(&found.lane(lane)));
                    }
                }
            }
            for (lane, triangle) in triangles.iter().enumerate() {
                let expected = closest_on_triangle(&query, triangle);
                let bits = |t: &TrianglePoint| t.to_bits_array();
                if found.decided >> lane & 1 != 0 {
                    assert_eq!(bits(&found.lane(lane)), bits(&expected));
                }
            }
        }
    }
}

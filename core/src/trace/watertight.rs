//! Watertight ray/triangle intersection (Woop, Benthin and Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2013), split so that a triangle strip can share work between windows.
//!
//! Every vertex is first moved into *ray space*: translated to the ray origin, sheared so that
//! the ray runs along +z, and the z axis scaled by `1 / d[kz]` ([`RaySpace::transform`]). In ray
//! space the ray is the z axis and a triangle is hit when the origin lies inside its 2D
//! projection, which the three 2D edge functions decide. The transform of a vertex depends only
//! on the ray and the vertex, and the edge function of `(p, q)` is bit-exactly the negation of
//! that of `(q, p)` (`a*b - c*d` and `c*d - a*b` round to negated values), so two triangles that
//! share an edge, in one strip or in two strips holding bit-identical vertex copies, agree on
//! which side of it the ray passes: no ray slips through a shared edge or vertex.
//!
//! Design choices:
//! * The test is split into [`RaySpace::transform`], [`edge`] and [`resolve`] so the strip
//!   intersector can run the transform and the edges of eight windows in SIMD lanes, reading
//!   each strip vertex once per block (paper 3.2: "testing rays against all the edges that are
//!   directly defined by the triangle strip"), and finish only the rare candidate windows in
//!   scalar code. [`intersect_triangle`] composes the same pieces for one triangle; it is the
//!   brute-force reference of the tests.
//! * Corner weights are passed in *strip order*; the facing of the triangle does not matter
//!   because both facings are accepted, and sums are formed so that a triangle gives bit-identical
//!   `t` whichever of its two windings is used (see [`resolve`]).
//! * When an edge function is exactly zero (the ray passes through an edge or a vertex at f32
//!   resolution) all three are recomputed in f64, where the products of f32 values are exact, so
//!   the sign is the exact sign; the paper's fallback.
//! * A zero determinant (the ray lies in the triangle's plane, or the triangle has zero area)
//!   never hits.
//! * A zero `t` is always `+0.0`. Negation is exact except at zero: an exactly cancelling sum is
//!   `+0.0` in both windings, and dividing it by the determinant, whose sign the winding sets,
//!   would give `+0.0` for one winding and `-0.0` for the other (a ray starting on a vertex).

use wide::f32x8;

use crate::geometry::Point;

/// A ray's precomputed shear into ray space.
#[derive(Clone, Copy, Debug)]
pub struct RaySpace {
    origin: Point,
    /// Ray-space x, y and z axes as model axes: `kz` is the dominant direction component, and
    /// `kx`, `ky` are swapped when it is negative so that the handedness is kept.
    axes: [usize; 3],
    shear_x: f32,
    shear_y: f32,
    scale_z: f32,
}

/// A vertex in ray space: `x`, `y` are its offsets from the ray in the sheared plane, `z` its
/// distance along the ray in units of the ray's parameter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayPoint {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

/// A triangle hit: the ray parameter and the weights of the three corners in the order given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub weights: [f32; 3],
}

impl RaySpace {
    pub fn new(origin: Point, direction: Point) -> RaySpace {
        let magnitude = direction.map(f32::abs);
        let kz = if magnitude[0] >= magnitude[1] && magnitude[0] >= magnitude[2] {
            0
        } else if magnitude[1] >= magnitude[2] {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if direction[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        RaySpace {
            origin,
            axes: [kx, ky, kz],
            shear_x: direction[kx] / direction[kz],
            shear_y: direction[ky] / direction[kz],
            scale_z: 1.0 / direction[kz],
        }
    }

    /// The ray space whose fields [`RaySpace::new`] computed elsewhere (eight at once for a
    /// packet's lanes): `axes` as [`RaySpace::axes`], the shears as [`RaySpace::shears`].
    pub(super) fn from_parts(
        origin: Point,
        axes: [usize; 3],
        [shear_x, shear_y]: [f32; 2],
        scale_z: f32,
    ) -> RaySpace {
        RaySpace {
            origin,
            axes,
            shear_x,
            shear_y,
            scale_z,
        }
    }

    /// Ray-space x, y and z axes as model axes (one of six permutations).
    #[inline(always)]
    pub fn axes(&self) -> [usize; 3] {
        self.axes
    }

    /// The model-space vertex `p` in ray space.
    #[inline(always)]
    pub fn transform(&self, p: &Point) -> RayPoint {
        let [kx, ky, kz] = self.axes;
        self.transform_on(p, kx, ky, kz)
    }

    /// [`RaySpace::transform`] for a ray whose [`RaySpace::axes`] are `[KX, KY, KZ]`. The same
    /// arithmetic, but with the axes known at compile time the components are plain loads
    /// instead of indexing by a runtime axis, which matters in the strip intersector's loop.
    #[inline(always)]
    pub fn transform_as<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        p: &Point,
    ) -> RayPoint {
        debug_assert_eq!(self.axes, [KX, KY, KZ]);
        self.transform_on(p, KX, KY, KZ)
    }

    #[inline(always)]
    fn transform_on(&self, p: &Point, kx: usize, ky: usize, kz: usize) -> RayPoint {
        let a = [
            p[0] - self.origin[0],
            p[1] - self.origin[1],
            p[2] - self.origin[2],
        ];
        RayPoint {
            x: a[kx] - self.shear_x * a[kz],
            y: a[ky] - self.shear_y * a[kz],
            z: self.scale_z * a[kz],
        }
    }
}

/// The ray-space x and y of eight points in structure-of-arrays form, lane `i` being what
/// [`RaySpace::transform`] gives for the `i`-th model point. The depth z is left out: only the
/// edge functions run on all lanes, and the rare candidate lanes get their depth from
/// [`RaySpace::depth_as`].
#[derive(Clone, Copy, Debug)]
pub struct RayPoints {
    pub x: f32x8,
    pub y: f32x8,
}

impl RayPoints {
    /// Lane `lane` as a single point of depth `z`.
    #[inline(always)]
    pub fn point(&self, lane: usize, z: f32) -> RayPoint {
        RayPoint {
            x: self.x.as_array()[lane],
            y: self.y.as_array()[lane],
            z,
        }
    }
}

impl RaySpace {
    /// [`RaySpace::transform_as`] of eight points at once, x and y only, given their
    /// coordinates on the ray-space axes `[KX, KY, KZ]` (`along_x[i]` is point `i`'s model
    /// coordinate `KX`). The same operations in the same order, lanewise, so every lane is
    /// bit-identical to the scalar transform (IEEE multiplication and subtraction, no fused
    /// multiply-add).
    #[inline(always)]
    pub fn transform_lanes<const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        along_x: f32x8,
        along_y: f32x8,
        along_z: f32x8,
    ) -> RayPoints {
        debug_assert_eq!(self.axes, [KX, KY, KZ]);
        let ax = along_x - f32x8::splat(self.origin[KX]);
        let ay = along_y - f32x8::splat(self.origin[KY]);
        let az = along_z - f32x8::splat(self.origin[KZ]);
        RayPoints {
            x: ax - f32x8::splat(self.shear_x) * az,
            y: ay - f32x8::splat(self.shear_y) * az,
        }
    }

    /// The ray origin's coordinates on the ray-space axes `[KX, KY, KZ]`, for kernels that run
    /// [`RaySpace::transform_lanes`] in other registers.
    #[inline(always)]
    pub fn origin_on<const KX: usize, const KY: usize, const KZ: usize>(&self) -> [f32; 3] {
        debug_assert_eq!(self.axes, [KX, KY, KZ]);
        [self.origin[KX], self.origin[KY], self.origin[KZ]]
    }

    /// The shear factors of ray-space x and y, for the same kernels.
    #[inline(always)]
    pub fn shears(&self) -> (f32, f32) {
        (self.shear_x, self.shear_y)
    }

    /// The factor of ray-space z, for the kernels.
    #[inline(always)]
    pub fn scale_z(&self) -> f32 {
        self.scale_z
    }

    /// The ray-space z of a point whose model coordinate on axis `KZ` is `along_z`: the same
    /// operations as [`RaySpace::transform_as`], so the same bits.
    #[inline(always)]
    pub fn depth_as<const KZ: usize>(&self, along_z: f32) -> f32 {
        debug_assert_eq!(self.axes[2], KZ);
        self.scale_z * (along_z - self.origin[KZ])
    }
}

/// [`edge`] lanewise, bit-identical per lane.
#[inline(always)]
pub fn edge_lanes(p: &RayPoints, q: &RayPoints) -> f32x8 {
    q.x * p.y - q.y * p.x
}

/// Lanes whose three edge weights could make a hit: all of one sign (their sign bits agree), or
/// one exactly zero (which [`resolve`] settles in f64), found as a product that is zero or NaN
/// (a zero times an infinity). Every lane [`resolve`] accepts is among them. So are some it
/// rejects, which cost a test but change no answer: a product that underflows, a NaN or
/// infinite weight. Sign bits and one product take fewer operations than the weights' minimum
/// and maximum and three compares with zero.
#[inline(always)]
pub fn candidate_lanes(w: [f32x8; 3]) -> u32 {
    let signs_differ = (w[0] ^ w[1]) | (w[1] ^ w[2]);
    let product = w[0] * w[1] * w[2];
    let zero_or_nan = product.simd_eq(f32x8::ZERO) | product.simd_ne(product);
    (!signs_differ.to_bitmask() | zero_or_nan.to_bitmask()) & 0xFF
}

/// Edge function of the directed edge `p → q`: positive when the ray passes on one side,
/// negative on the other, zero on the edge. `edge(q, p)` is exactly `-edge(p, q)`.
#[inline(always)]
pub fn edge(p: &RayPoint, q: &RayPoint) -> f32 {
    q.x * p.y - q.y * p.x
}

/// [`edge`] in f64: the two products of f32 values are exact, so the sign is exact.
#[inline]
fn exact_edge(p: &RayPoint, q: &RayPoint) -> f64 {
    q.x as f64 * p.y as f64 - q.y as f64 * p.x as f64
}

/// Finishes the test of the triangle with ray-space corners `c` given its edge weights
/// `w[i] = edge(c[i+1], c[i+2])` (indices mod 3, the weight of corner `i`). Accepts both
/// facings. Returns the hit if its parameter lies in `[tmin, tmax]`.
///
/// The sums are formed as `(w0 + w1) + w2`; a triangle passed with its first two corners swapped
/// (the other winding, as odd strip windows are) gives negated weights in swapped order, and
/// addition commutes, so `t` is bit-identical either way, zero aside (see the module
/// documentation).
#[inline(always)]
pub fn resolve(c: &[RayPoint; 3], w: [f32; 3], tmin: f32, tmax: f32) -> Option<TriangleHit> {
    if w[0] == 0.0 || w[1] == 0.0 || w[2] == 0.0 {
        return resolve_exact(c, tmin, tmax);
    }
    let any_negative = w[0] < 0.0 || w[1] < 0.0 || w[2] < 0.0;
    let any_positive = w[0] > 0.0 || w[1] > 0.0 || w[2] > 0.0;
    if any_negative && any_positive {
        return None;
    }
    let det = w[0] + w[1] + w[2];
    // `+ 0.0` turns `-0.0` into `+0.0` and changes nothing else; see the module documentation.
    let t = (w[0] * c[0].z + w[1] * c[1].z + w[2] * c[2].z) / det + 0.0;
    in_range(t, tmin, tmax).then(|| TriangleHit {
        t,
        weights: w.map(|x| x / det),
    })
}

/// The f64 fallback of [`resolve`] when an f32 edge function was zero.
#[cold]
fn resolve_exact(c: &[RayPoint; 3], tmin: f32, tmax: f32) -> Option<TriangleHit> {
    let w = [
        exact_edge(&c[1], &c[2]),
        exact_edge(&c[2], &c[0]),
        exact_edge(&c[0], &c[1]),
    ];
    let any_negative = w[0] < 0.0 || w[1] < 0.0 || w[2] < 0.0;
    let any_positive = w[0] > 0.0 || w[1] > 0.0 || w[2] > 0.0;
    let det = w[0] + w[1] + w[2];
    if (any_negative && any_positive) || det == 0.0 {
        return None;
    }
    let z = c.map(|p| p.z as f64);
    let t = ((w[0] * z[0] + w[1] * z[1] + w[2] * z[2]) / det) as f32 + 0.0;
    in_range(t, tmin, tmax).then(|| TriangleHit {
        t,
        weights: w.map(|x| (x / det) as f32),
    })
}

#[inline(always)]
fn in_range(t: f32, tmin: f32, tmax: f32) -> bool {
    tmin <= t && t <= tmax
}

/// The whole watertight test of one triangle: the brute-force reference the strip intersector
/// agrees with bit for bit.
pub fn intersect_triangle(
    space: &RaySpace,
    triangle: &[Point; 3],
    tmin: f32,
    tmax: f32,
) -> Option<TriangleHit> {
    let c = triangle.map(|p| space.transform(&p));
    let w = [edge(&c[1], &c[2]), edge(&c[2], &c[0]), edge(&c[0], &c[1])];
    resolve(&c, w, tmin, tmax)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRIANGLE: [Point; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

    #[test]
    fn hits_both_facings_with_barycentrics() {
        for direction in [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]] {
            let origin = [0.25, 0.5, -direction[2] * 2.0];
            let space = RaySpace::new(origin, direction);
            let hit = intersect_triangle(&space, &TRIANGLE, 0.0, f32::INFINITY).expect("hit");
            assert_eq!(hit.t, 2.0);
            assert_eq!(hit.weights, [0.25, 0.25, 0.5]);
        }
    }

    #[test]
    fn reversed_winding_gives_identical_t() {
        let space = RaySpace::new([0.3, 0.2, 5.0], [0.013, -0.021, -1.0]);
        let triangle = [[0.0, 0.0, 0.1], [1.0, 0.0, 0.7], [0.0, 1.0, -0.3]];
        let reversed = [triangle[1], triangle[0], triangle[2]];
        let a = intersect_triangle(&space, &triangle, 0.0, f32::INFINITY).expect("hit");
        let b = intersect_triangle(&space, &reversed, 0.0, f32::INFINITY).expect("hit");
        assert_eq!(a.t.to_bits(), b.t.to_bits());
    }

    #[test]
    fn zero_t_is_positive_in_both_windings() {
        let triangle = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.2], [0.0, 1.0, 0.4]];
        let reversed = [triangle[1], triangle[0], triangle[2]];
        let mut hits = 0;
        for corner in 0..3 {
            for direction in [[0.3, 0.2, -1.0], [-0.3, 0.2, 1.0], [1.0, -0.1, 0.05]] {
                let space = RaySpace::new(triangle[corner], direction);
                for t in [triangle, reversed] {
                    if let Some(hit) = intersect_triangle(&space, &t, 0.0, f32::INFINITY) {
                        assert_eq!(hit.t.to_bits(), 0.0f32.to_bits(), "{corner} {direction:?}");
                        hits += 1;
                    }
                }
            }
        }
        assert_eq!(hits, 18);
    }

    #[test]
    fn shared_edge_is_hit_by_one_side() {
        let quad = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let first = [quad[0], quad[1], quad[2]];
        let second = [quad[0], quad[2], quad[3]];
        for i in 0..=64 {
            let s = i as f32 / 64.0;
            let space = RaySpace::new([s, s, 1.0], [0.0, 0.0, -1.0]);
            let hits = [first, second]
                .iter()
                .filter(|t| intersect_triangle(&space, t, 0.0, f32::INFINITY).is_some())
                .count();
            assert!(hits >= 1, "ray through the diagonal at {s} slipped through");
        }
    }

    #[test]
    fn degenerate_triangle_and_parallel_ray_never_hit() {
        let space = RaySpace::new([0.2, 0.2, 1.0], [0.0, 0.0, -1.0]);
        let line = [[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [2.0, 2.0, 0.0]];
        assert_eq!(intersect_triangle(&space, &line, 0.0, f32::INFINITY), None);
        let grazing = RaySpace::new([-1.0, 0.2, 0.0], [1.0, 0.0, 0.0]);
        assert_eq!(
            intersect_triangle(&grazing, &TRIANGLE, 0.0, f32::INFINITY),
            None
        );
    }
}

//! The closest point of a triangle to a point: Ericson, "Real-Time Collision Detection" (2005),
//! section 5.1.5, which classifies the point into the triangle's Voronoi regions (three
//! vertices, three edges, the face) with dot products alone.
//!
//! Everything is computed in f64 from the stored f32 corners: a difference of two f32 values is
//! exact in f64 for coordinates of similar magnitude, so the closest point and its distance
//! carry an error of about 1e-16 of the coordinates, far below the f32 answer's resolution.
//! The answer is always a convex combination of the corners (barycentrics in `[0, 1]`, summing
//! to at most 1): where rounding makes the face region's weights inconsistent (slivers) or the
//! triangle has no area, the closest of the three edges' points answers instead.

use crate::geometry::Point;

type Vector = [f64; 3];

/// The closest point of a triangle: squared distance and barycentric weights of the second and
/// third corner (`u`, `v`), so that the point is `a + u (b - a) + v (c - a)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePoint {
    pub distance_squared: f64,
    pub u: f64,
    pub v: f64,
    /// The point itself, in f64 (round to f32 for output).
    pub point: Vector,
}

/// The closest point of triangle `[a, b, c]` to `p`.
pub fn closest_on_triangle(p: &Point, corners: &[Point; 3]) -> TrianglePoint {
    let p = widen(p);
    let [a, b, c] = corners.map(|corner| widen(&corner));
    let (u, v) = region_weights(&p, &a, &b, &c).unwrap_or_else(|| nearest_edge(&p, &a, &b, &c));
    let (ab, ac) = (sub(&b, &a), sub(&c, &a));
    let point: Vector = std::array::from_fn(|axis| a[axis] + u * ab[axis] + v * ac[axis]);
    let offset = sub(&p, &point);
    TrianglePoint {
        distance_squared: dot(&offset, &offset),
        u,
        v,
        point,
    }
}

/// The weights `(u, v)` of the closest point by Voronoi region; `None` when the face region's
/// weights come out of range (rounding on a sliver, or no area).
fn region_weights(p: &Vector, a: &Vector, b: &Vector, c: &Vector) -> Option<(f64, f64)> {
    let (ab, ac) = (sub(b, a), sub(c, a));
    let ap = sub(p, a);
    let (d1, d2) = (dot(&ab, &ap), dot(&ac, &ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return Some((0.0, 0.0));
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(&ab, &bp), dot(&ac, &bp));
    if d3 >= 0.0 && d4 <= d3 {
        return Some((1.0, 0.0));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(&ab, &cp), dot(&ac, &cp));
    if d6 >= 0.0 && d5 <= d6 {
        return Some((0.0, 1.0));
    }
    // Twice the signed areas of the sub-triangles opposite c, b and a, scaled by the
    // triangle's: their signs say which edge's region holds the point.
    let area_c = d1 * d4 - d3 * d2;
    if area_c <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return Some((ratio(d1, d1 - d3), 0.0));
    }
    let area_b = d5 * d2 - d1 * d6;
    if area_b <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return Some((0.0, ratio(d2, d2 - d6)));
    }
    let area_a = d3 * d6 - d5 * d4;
    let (towards_c_from_b, towards_b_from_c) = (d4 - d3, d5 - d6);
    if area_a <= 0.0 && towards_c_from_b >= 0.0 && towards_b_from_c >= 0.0 {
        let w = ratio(towards_c_from_b, towards_c_from_b + towards_b_from_c);
        return Some((1.0 - w, w));
    }
    let total = area_a + area_b + area_c;
    let (u, v) = (area_b / total, area_c / total);
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some((u, v))
}

/// The closest of the three edges' closest points, as weights.
fn nearest_edge(p: &Vector, a: &Vector, b: &Vector, c: &Vector) -> (f64, f64) {
    let on_ab = segment_parameter(p, a, b);
    let on_ac = segment_parameter(p, a, c);
    let on_bc = segment_parameter(p, b, c);
    let candidates = [(on_ab, 0.0), (0.0, on_ac), (1.0 - on_bc, on_bc)];
    let distance = |(u, v): (f64, f64)| {
        let point: Vector =
            std::array::from_fn(|axis| a[axis] + u * (b[axis] - a[axis]) + v * (c[axis] - a[axis]));
        let offset = sub(p, &point);
        dot(&offset, &offset)
    };
    candidates
        .into_iter()
        .min_by(|x, y| distance(*x).total_cmp(&distance(*y)))
        .unwrap_or((0.0, 0.0))
}

/// The parameter in `[0, 1]` of the point of segment `x y` closest to `p` (0 for a point
/// segment).
fn segment_parameter(p: &Vector, x: &Vector, y: &Vector) -> f64 {
    let direction = sub(y, x);
    ratio(dot(&sub(p, x), &direction), dot(&direction, &direction))
}

/// `numerator / denominator` clamped to `[0, 1]`; 0 when the denominator is not positive
/// (a zero-length edge, where every parameter names the same point).
fn ratio(numerator: f64, denominator: f64) -> f64 {
    if denominator > 0.0 {
        (numerator / denominator).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

fn widen(p: &Point) -> Vector {
    p.map(f64::from)
}

fn sub(x: &Vector, y: &Vector) -> Vector {
    std::array::from_fn(|axis| x[axis] - y[axis])
}

fn dot(x: &Vector, y: &Vector) -> f64 {
    x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRIANGLE: [Point; 3] = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 2.0, 0.0]];

    fn closest(p: Point) -> (f64, f64, f64) {
        let found = closest_on_triangle(&p, &TRIANGLE);
        (found.distance_squared, found.u, found.v)
    }

    #[test]
    fn each_region_answers_its_feature() {
        assert_eq!(closest([-1.0, -1.0, 0.0]), (2.0, 0.0, 0.0));
        assert_eq!(closest([6.0, -1.0, 0.0]), (5.0, 1.0, 0.0));
        assert_eq!(closest([0.0, 5.0, 3.0]), (18.0, 0.0, 1.0));
        assert_eq!(closest([1.0, -3.0, 0.0]), (9.0, 0.25, 0.0));
        assert_eq!(closest([-2.0, 1.0, 0.0]), (4.0, 0.0, 0.5));
        assert_eq!(closest([1.0, 0.5, -7.0]), (49.0, 0.25, 0.25));
        // Beyond the long edge from (4, 0) to (0, 2): its closest point is (2, 1), halfway.
        let (d2, u, v) = closest([3.0, 3.0, 0.0]);
        assert_eq!((u, v), (0.5, 0.5));
        assert!((d2 - 5.0).abs() < 1e-12);
    }

    #[test]
    fn corners_are_at_distance_zero_with_exact_weights() {
        for (corner, weights) in TRIANGLE.iter().zip([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]) {
            let found = closest_on_triangle(corner, &TRIANGLE);
            assert_eq!(
                (found.distance_squared, found.u, found.v),
                (0.0, weights.0, weights.1)
            );
            assert_eq!(found.point, corner.map(f64::from));
        }
    }

    #[test]
    fn triangles_without_area_answer_their_nearest_edge() {
        let collinear = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        let found = closest_on_triangle(&[2.0, 1.0, 0.0], &collinear);
        assert!((found.distance_squared - 1.0).abs() < 1e-12);
        assert!((found.point[0] - 2.0).abs() < 1e-12 && found.point[1..] == [0.0, 0.0]);
        let point = [[5.0, 5.0, 5.0]; 3];
        let found = closest_on_triangle(&[5.0, 5.0, 7.0], &point);
        assert_eq!((found.distance_squared, found.u, found.v), (4.0, 0.0, 0.0));
    }
}

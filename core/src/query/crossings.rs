//! Every crossing of a ray with the surface: counted ([`count_crossings`]) or listed
//! ([`all_hits`]), for inside/outside tests and for users who need more than the first hit.
//!
//! **The tie rule.** A ray through an edge or a vertex must be counted on exactly one triangle,
//! or the parity of a closed mesh's crossings is wrong. Each triangle is tested in the
//! tracer's ray space ([`RaySpace`], Woop et al. 2013): its corners are moved so that the ray
//! is the z axis, and the ray crosses it when the origin lies strictly inside its projection,
//! which the signs of the three edge functions decide. The transform of a vertex depends only on
//! the ray and the vertex, so every triangle sharing a vertex sees the same projected point.
//! An edge function that is exactly zero (the ray meets the edge's line) takes the sign it
//! would have if the ray were moved by `(ε, ε²)` in ray-space x and y, ε infinitely small:
//! the sign of `q.y - p.y` for the directed edge `p → q`, or when that is zero, of `p.x - q.x`
//! (simulation of simplicity). The rule is antisymmetric in `p` and `q`, so the two triangles
//! of an edge decide it in opposite ways, and it moves the ray, not a triangle, so around a
//! vertex exactly one triangle of a closed fan contains it: the count is that of a ray in
//! general position, whatever strip holds a triangle. A triangle whose projection has zero
//! area (the ray lies in its plane, or it is degenerate) contains no moved ray and crosses
//! nothing. The f32 edge functions are used when none is zero: rounding keeps their signs or
//! makes them zero, so they decide as the exact ones would.

use rayon::prelude::*;

use super::child_box::ChildBox;
use super::FaceIds;
use crate::format::block_boxes::BOX_WINDOWS;
use crate::format::reader::{ReducemFile, StripView, TopNodes};
use crate::format::vertices::{StripVertices, VertexAccess};
use crate::format::{TopSlot, TOP_WIDTH};
use crate::geometry::Point;
use crate::strip_windows::window_corners;
use crate::trace::watertight::{edge, resolve, RayPoint, RaySpace, TriangleHit};
use crate::trace::Ray;

/// The face id of a crossing whose triangle has none (a corrupt stored id).
pub const NO_FACE: u32 = u32::MAX;

/// One crossing of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    pub t: f32,
    /// The input face id, or the triangle's row in `decode` order ([`FaceIds`]).
    pub face_id: u32,
    /// Barycentric weights of the triangle's second and third corners in input winding.
    pub u: f32,
    pub v: f32,
}

/// The crossings of many rays: ray `i`'s are `hits[splits[i] as usize..splits[i + 1] as usize]`,
/// `t` ascending, ties by face id.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AllHits {
    /// `rays + 1` offsets into `hits`, starting at 0.
    pub splits: Vec<u32>,
    pub hits: Vec<RayHit>,
}

/// The number of crossings of every ray in `[tmin, tmax]`, in parallel (rayon's current pool).
pub fn count_crossings(file: &ReducemFile, rays: &[Ray]) -> Vec<u32> {
    rays.par_iter()
        .map(|ray| {
            let mut count = 0u32;
            for_each_crossing(file, ray, |_, _, _| count += 1);
            count
        })
        .collect()
}

/// Every crossing of every ray in `[tmin, tmax]`, in parallel (rayon's current pool).
pub fn all_hits(file: &ReducemFile, rays: &[Ray], face_ids: &FaceIds) -> AllHits {
    let per_ray: Vec<Vec<RayHit>> = rays
        .par_iter()
        .map(|ray| ray_hits(file, ray, face_ids))
        .collect();
    let mut splits = Vec::with_capacity(rays.len() + 1);
    splits.push(0u32);
    let mut hits = Vec::with_capacity(per_ray.iter().map(Vec::len).sum());
    for ray_hits in per_ray {
        hits.extend(ray_hits);
        splits.push(u32::try_from(hits.len()).unwrap_or(u32::MAX));
    }
    AllHits { splits, hits }
}

/// The crossings of one ray, `t` ascending, ties by face id.
pub fn ray_hits(file: &ReducemFile, ray: &Ray, face_ids: &FaceIds) -> Vec<RayHit> {
    let mut hits = Vec::new();
    for_each_crossing(file, ray, |strip, window, hit| {
        hits.push(RayHit {
            t: hit.t,
            face_id: face_ids.id(file, strip, window).unwrap_or(NO_FACE),
            u: hit.weights[1],
            v: hit.weights[2],
        })
    });
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.face_id.cmp(&b.face_id)));
    hits
}

/// Calls `each(strip, window, hit)` for every crossing of `ray` in `[tmin, tmax]`, in no
/// particular order, the hit's weights those of the triangle's corners in input winding. An
/// invalid ray (not finite, zero direction, `tmin` negative or above `tmax`) crosses nothing,
/// as ray files answer it with `--invalid-rays miss`. On a
/// lazily opened file a corrupt node or strip reached is skipped and kept for
/// [`ReducemFile::defect`], as in tracing.
pub fn for_each_crossing(
    file: &ReducemFile,
    ray: &Ray,
    mut each: impl FnMut(u32, u16, TriangleHit),
) {
    if !valid(ray) {
        return;
    }
    let walk = Walk::new(ray);
    match file.top_nodes() {
        TopNodes::F32(nodes) => walk.run(file, nodes, &(), &mut each),
        TopNodes::Grid(nodes, grid) => walk.run(file, nodes, &grid, &mut each),
    }
}

fn valid(ray: &Ray) -> bool {
    let finite = |p: &Point| p.iter().all(|x| x.is_finite());
    finite(&ray.origin)
        && finite(&ray.direction)
        && ray.direction != [0.0; 3]
        && ray.tmin >= 0.0
        && ray.tmin <= ray.tmax
}

/// The crossing of `triangle` (corners in input winding) by the ray of `space` in
/// `[tmin, tmax]` under the tie rule of this module.
pub fn crossing(
    space: &RaySpace,
    triangle: &[Point; 3],
    tmin: f32,
    tmax: f32,
) -> Option<TriangleHit> {
    let c = triangle.map(|p| space.transform(&p));
    let w = [edge(&c[1], &c[2]), edge(&c[2], &c[0]), edge(&c[0], &c[1])];
    if w.contains(&0.0) {
        return crossing_on_edge(&c, tmin, tmax);
    }
    resolve(&c, w, tmin, tmax)
}

/// [`crossing`] when an f32 edge function is zero: exact edge functions in f64, a zero one
/// replaced by the sign of the moved ray.
#[cold]
fn crossing_on_edge(c: &[RayPoint; 3], tmin: f32, tmax: f32) -> Option<TriangleHit> {
    let edges = [(1, 2), (2, 0), (0, 1)];
    let w = edges.map(|(p, q)| exact_edge(&c[p], &c[q]));
    let signs = [0, 1, 2].map(|i| tie_sign(w[i], &c[edges[i].0], &c[edges[i].1]));
    if signs[0] == 0 || signs[0] != signs[1] || signs[1] != signs[2] {
        return None;
    }
    // All three of one sign after the move: the exact determinant is non-zero with that sign.
    let det = w[0] + w[1] + w[2];
    let z = c.map(|p| f64::from(p.z));
    let t = ((w[0] * z[0] + w[1] * z[1] + w[2] * z[2]) / det) as f32 + 0.0;
    (tmin <= t && t <= tmax).then(|| TriangleHit {
        t,
        weights: w.map(|x| (x / det) as f32),
    })
}

/// The edge function of `p → q` in f64: the products of f32 values are exact, so its sign is.
fn exact_edge(p: &RayPoint, q: &RayPoint) -> f64 {
    f64::from(q.x) * f64::from(p.y) - f64::from(q.y) * f64::from(p.x)
}

/// The sign of the edge function `w` of `p → q` for the ray moved by `(ε, ε²)`: `w`'s own sign
/// when it is not zero, else that of `q.y - p.y`, else of `p.x - q.x`; 0 only for an edge
/// of zero length in projection.
fn tie_sign(w: f64, p: &RayPoint, q: &RayPoint) -> i8 {
    let sign = |a: f32, b: f32| match a.partial_cmp(&b) {
        Some(std::cmp::Ordering::Greater) => 1,
        Some(std::cmp::Ordering::Less) => -1,
        _ => 0,
    };
    match w.partial_cmp(&0.0) {
        Some(std::cmp::Ordering::Greater) => 1,
        Some(std::cmp::Ordering::Less) => -1,
        _ => match sign(q.y, p.y) {
            0 => sign(p.x, q.x),
            s => s,
        },
    }
}

/// One ray's walk over the top-level hierarchy: a box is entered when the ray may meet it.
struct Walk {
    ray: Ray,
    space: RaySpace,
}

impl Walk {
    fn new(ray: &Ray) -> Walk {
        Walk {
            ray: *ray,
            space: RaySpace::new(ray.origin, ray.direction),
        }
    }

    fn run<N: ChildBox>(
        &self,
        file: &ReducemFile,
        nodes: &[N],
        grid: &N::Grid,
        each: &mut impl FnMut(u32, u16, TriangleHit),
    ) {
        if nodes.is_empty() {
            return;
        }
        let mut stack = vec![0u32];
        let mut visits = file.node_visits();
        while let Some(index) = stack.pop() {
            // A file changed in place after its validation may link nodes in circles.
            visits = match visits.checked_sub(1) {
                Some(left) => left,
                None => return,
            };
            let Some(node) = file.top_node(nodes, index as usize) else {
                continue;
            };
            for slot in 0..TOP_WIDTH {
                let (min, max) = node.child_box(slot, grid);
                match node.slot(slot) {
                    TopSlot::Internal(child) if self.may_meet(&min, &max) => stack.push(child),
                    TopSlot::Leaf { first, count } if self.may_meet(&min, &max) => {
                        for strip in file.leaf_strips(first, count) {
                            self.strip(file, strip, each);
                        }
                    }
                    _ => {}
                }
            }
        }
    }

    /// Tests every window of strip `strip`.
    fn strip(&self, file: &ReducemFile, strip: u32, each: &mut impl FnMut(u32, u16, TriangleHit)) {
        let view = file.strip(strip as usize);
        match view.vertices {
            StripVertices::F32(vertices) => self.windows(vertices, &view, strip, each),
            StripVertices::Grid(vertices) => self.windows(vertices, &view, strip, each),
        }
    }

    /// Tests the windows of strip `strip` in the blocks whose box the ray may meet (every
    /// window when the strip stores no block boxes).
    fn windows<V: VertexAccess>(
        &self,
        vertices: V,
        view: &StripView,
        strip: u32,
        each: &mut impl FnMut(u32, u16, TriangleHit),
    ) {
        let windows = view.window_count();
        let frame = match view.boxes.is_empty() {
            true => None,
            false => view.boxes.frame(vertices.point(0)),
        };
        let Some(frame) = frame else {
            return self.window_range(vertices, view, strip, 0..windows, each);
        };
        for block in 0..view.boxes.count() {
            let Some((min, max)) = view.boxes.decode(&frame, block) else {
                break;
            };
            if self.may_meet(&min, &max) {
                let first = block * BOX_WINDOWS;
                let range = first..(first + BOX_WINDOWS).min(windows);
                self.window_range(vertices, view, strip, range, each);
            }
        }
    }

    /// Tests the windows `range` of strip `strip`.
    fn window_range<V: VertexAccess>(
        &self,
        vertices: V,
        view: &StripView,
        strip: u32,
        range: std::ops::Range<usize>,
        each: &mut impl FnMut(u32, u16, TriangleHit),
    ) {
        let mut corners = [0u8; 3];
        for window in range {
            view.references.read_into(window, &mut corners);
            let Some(triangle) = window_corners(corners, window) else {
                continue;
            };
            let triangle = triangle.map(|r| vertices.point(r as usize));
            if let Some(hit) = crossing(&self.space, &triangle, self.ray.tmin, self.ray.tmax) {
                each(strip, window as u16, hit);
            }
        }
    }

    /// Whether the ray may meet the box `min..max` within `[tmin, tmax]`: a slab test in f64 on
    /// the box widened by a relative margin, so that no box holding a triangle the rounded
    /// ray-space test accepts is skipped. A NaN plane (only in a corrupt box) is entered.
    fn may_meet(&self, min: &Point, max: &Point) -> bool {
        let (mut near, mut far) = (f64::from(self.ray.tmin), f64::from(self.ray.tmax));
        let margin = 1e-5;
        near -= near.abs() * margin;
        far += far.abs() * margin;
        for axis in 0..3 {
            let origin = f64::from(self.ray.origin[axis]);
            let (low, high) = (f64::from(min[axis]), f64::from(max[axis]));
            let widen = ((low - origin).abs() + (high - origin).abs() + (high - low)) * margin;
            let (low, high) = (low - widen, high + widen);
            let direction = f64::from(self.ray.direction[axis]);
            if direction == 0.0 {
                if origin < low || origin > high {
                    return false;
                }
                continue;
            }
            let (a, b) = ((low - origin) / direction, (high - origin) / direction);
            near = near.max(a.min(b));
            far = far.min(a.max(b));
            if near > far {
                return false;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square split on its diagonal, both windings, and a fan of four around its centre.
    #[test]
    fn rays_through_shared_edges_and_vertices_cross_once() {
        let quad = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        let centre = [0.5, 0.5, 0.0];
        let fan: Vec<[Point; 3]> = (0..4)
            .map(|i| [centre, quad[i], quad[(i + 1) % 4]])
            .collect();
        for i in 0..=16 {
            for j in 0..=16 {
                let (x, y) = (i as f32 / 16.0, j as f32 / 16.0);
                if x == 0.0 || y == 0.0 || x == 1.0 || y == 1.0 {
                    continue;
                }
                for direction in [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]] {
                    let space = RaySpace::new([x, y, -direction[2]], direction);
                    let count = fan
                        .iter()
                        .filter(|t| crossing(&space, t, 0.0, f32::INFINITY).is_some())
                        .count();
                    assert_eq!(count, 1, "ray at ({x}, {y}) {direction:?}");
                }
            }
        }
    }

    #[test]
    fn ray_in_the_plane_crosses_nothing() {
        let triangle = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let space = RaySpace::new([-1.0, 0.2, 0.0], [1.0, 0.0, 0.0]);
        assert_eq!(crossing(&space, &triangle, 0.0, f32::INFINITY), None);
    }
}

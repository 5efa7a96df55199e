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

use super::crossing_packet::CrossingPacket;
pub use super::crossing_packet::PACKET_RAYS;
use super::crossing_stream::CrossingStream;
use super::crossing_walk::CrossingWalk;
use super::FaceIds;
use crate::format::reader::ReducemFile;
use crate::geometry::Point;
use crate::trace::kernel::query_prefetch::QuerySections;
use crate::trace::kernel::Kernel;
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

/// Rays per rayon task of [`count_crossings`] (one interleaved stream of walks) and of
/// [`all_hits`] (one hit list, not one per ray).
const RAYS_PER_TASK: usize = 1024;

/// The number of crossings of every ray in `[tmin, tmax]`, in parallel (rayon's current pool).
pub fn count_crossings(file: &ReducemFile, rays: &[Ray]) -> Vec<u32> {
    count_crossings_on(file, rays, Kernel::configured())
}

/// [`count_crossings`] on `kernel`.
pub fn count_crossings_on(file: &ReducemFile, rays: &[Ray], kernel: Kernel) -> Vec<u32> {
    let sections = QuerySections::new(file);
    let mut counts = vec![0u32; rays.len()];
    counts
        .par_chunks_mut(RAYS_PER_TASK)
        .zip(rays.par_chunks(RAYS_PER_TASK))
        .for_each(|(counts, rays)| {
            let stream = CrossingStream::new(rays, kernel, valid);
            stream.run(file, &sections, &mut |ray, _, window, corners| {
                if settle_window(window, corners, &rays[ray]).is_some() {
                    counts[ray] += 1;
                }
            });
        });
    counts
}

/// Every crossing of every ray in `[tmin, tmax]`, in parallel (rayon's current pool).
pub fn all_hits(file: &ReducemFile, rays: &[Ray], face_ids: &FaceIds) -> AllHits {
    all_hits_on(file, rays, face_ids, Kernel::configured())
}

/// [`all_hits`] on `kernel`.
pub fn all_hits_on(
    file: &ReducemFile,
    rays: &[Ray],
    face_ids: &FaceIds,
    kernel: Kernel,
) -> AllHits {
    let sections = QuerySections::new(file);
    let per_task: Vec<(Vec<usize>, Vec<RayHit>)> = rays
        .par_chunks(RAYS_PER_TASK)
        .map(|rays| task_hits((file, &sections), rays, face_ids, kernel))
        .collect();
    let mut splits = Vec::with_capacity(rays.len() + 1);
    splits.push(0u32);
    let mut hits = Vec::with_capacity(per_task.iter().map(|(_, h)| h.len()).sum());
    for (counts, task_hits) in per_task {
        let mut end = hits.len();
        for count in counts {
            end += count;
            splits.push(u32::try_from(end).unwrap_or(u32::MAX));
        }
        hits.extend(task_hits);
    }
    AllHits { splits, hits }
}

/// The crossing counts and the crossings of `rays` (one task's), walked as one interleaved
/// stream like [`count_crossings_on`]'s: the hits come in any order and are sorted by ray, then
/// `t`, then face id, as [`push_ray_hits`] sorts one ray's.
fn task_hits(
    (file, sections): (&ReducemFile, &QuerySections),
    rays: &[Ray],
    face_ids: &FaceIds,
    kernel: Kernel,
) -> (Vec<usize>, Vec<RayHit>) {
    let mut found: Vec<(u32, RayHit)> = Vec::new();
    let stream = CrossingStream::new(rays, kernel, valid);
    stream.run(file, sections, &mut |ray, strip, window, corners| {
        if let Some(hit) = settle_window(window, corners, &rays[ray]) {
            let hit = RayHit {
                t: hit.t,
                face_id: face_ids.id(file, strip, window as u16).unwrap_or(NO_FACE),
                u: hit.weights[1],
                v: hit.weights[2],
            };
            found.push((ray as u32, hit));
        }
    });
    found.sort_unstable_by(|(ray_a, a), (ray_b, b)| {
        (ray_a.cmp(ray_b))
            .then(a.t.total_cmp(&b.t))
            .then(a.face_id.cmp(&b.face_id))
    });
    let mut counts = vec![0; rays.len()];
    for (ray, _) in &found {
        counts[*ray as usize] += 1;
    }
    (counts, found.into_iter().map(|(_, hit)| hit).collect())
}

/// The crossings of one ray, `t` ascending, ties by face id.
pub fn ray_hits(file: &ReducemFile, ray: &Ray, face_ids: &FaceIds) -> Vec<RayHit> {
    let mut hits = Vec::new();
    let sections = QuerySections::new(file);
    push_ray_hits(
        (file, &sections),
        ray,
        face_ids,
        Kernel::configured(),
        &mut hits,
    );
    hits
}

/// Appends the crossings of `ray` to `hits`, `t` ascending, ties by face id.
fn push_ray_hits(
    (file, sections): (&ReducemFile, &QuerySections),
    ray: &Ray,
    face_ids: &FaceIds,
    kernel: Kernel,
    hits: &mut Vec<RayHit>,
) {
    let before = hits.len();
    crossings_in(file, sections, ray, kernel, |strip, window, hit| {
        hits.push(RayHit {
            t: hit.t,
            face_id: face_ids.id(file, strip, window).unwrap_or(NO_FACE),
            u: hit.weights[1],
            v: hit.weights[2],
        })
    });
    hits[before..].sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.face_id.cmp(&b.face_id)));
}

/// Calls `each(strip, window, hit)` for every crossing of `ray` in `[tmin, tmax]`, in no
/// particular order, the hit's weights those of the triangle's corners in input winding. An
/// invalid ray (not finite, zero direction, `tmin` negative or above `tmax`) crosses nothing,
/// as ray files answer it with `--invalid-rays miss`. On a
/// lazily opened file a corrupt node or strip reached is skipped and kept for
/// [`ReducemFile::defect`], as in tracing.
pub fn for_each_crossing(file: &ReducemFile, ray: &Ray, each: impl FnMut(u32, u16, TriangleHit)) {
    for_each_crossing_on(file, ray, Kernel::configured(), each)
}

/// [`for_each_crossing`] on `kernel`: the kernel finds the windows that may cross in its lanes,
/// and each of them is settled by [`crossing`]'s rule on bit-identical ray-space corners.
pub fn for_each_crossing_on(
    file: &ReducemFile,
    ray: &Ray,
    kernel: Kernel,
    each: impl FnMut(u32, u16, TriangleHit),
) {
    crossings_in(file, &QuerySections::new(file), ray, kernel, each)
}

/// [`for_each_crossing_on`] with `file`'s sections looked up once for a batch of rays.
fn crossings_in(
    file: &ReducemFile,
    sections: &QuerySections,
    ray: &Ray,
    kernel: Kernel,
    mut each: impl FnMut(u32, u16, TriangleHit),
) {
    if !valid(ray) {
        return;
    }
    CrossingWalk::new(ray, kernel).run(file, sections, &mut |strip, window, corners| {
        if let Some(hit) = settle_window(window, corners, ray) {
            each(strip, window as u16, hit);
        }
    });
}

/// [`for_each_crossing_on`] of up to [`PACKET_RAYS`] rays walked together (worth it when they
/// are coherent): `each(k, strip, window, hit)` for every crossing of `rays[k]`, the same
/// crossings as `rays[k]` alone finds, in another order.
pub fn for_each_crossing_of_packet(
    file: &ReducemFile,
    rays: &[Ray],
    kernel: Kernel,
    mut each: impl FnMut(usize, u32, u16, TriangleHit),
) {
    CrossingPacket::new(rays, kernel, valid).run(file, &mut |lane, strip, window, corners| {
        if let Some(hit) = settle_window(window, corners, &rays[lane]) {
            each(lane, strip, window as u16, hit);
        }
    });
}

/// The crossing of `ray` with candidate `window` whose ray-space corners in strip order are
/// `corners`.
#[inline(always)]
fn settle_window(window: usize, corners: [RayPoint; 3], ray: &Ray) -> Option<TriangleHit> {
    // Odd windows are wound the other way (`strip_windows::window_corners`).
    let c = match window % 2 {
        0 => corners,
        _ => [corners[1], corners[0], corners[2]],
    };
    settle(&c, ray.tmin, ray.tmax)
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
    settle(&triangle.map(|p| space.transform(&p)), tmin, tmax)
}

/// [`crossing`] of the triangle whose ray-space corners (in input winding) are `c`.
#[inline(always)]
fn settle(c: &[RayPoint; 3], tmin: f32, tmax: f32) -> Option<TriangleHit> {
    let w = [edge(&c[1], &c[2]), edge(&c[2], &c[0]), edge(&c[0], &c[1])];
    if w.contains(&0.0) {
        return crossing_on_edge(c, tmin, tmax);
    }
    resolve(c, w, tmin, tmax)
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

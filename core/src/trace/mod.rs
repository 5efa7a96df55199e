//! Ray tracing straight from a mapped ReduceM file (paper 3.2, "Traversal and intersection").
//!
//! Two-level traversal: the global hierarchy over strips (`top`, or `packet` for coherent
//! rays), then each strip's implicit kd-tree with watertight intersection of its windows
//! (`strip`, [`watertight`]). The walks are generic over a [`kernel`], which holds everything
//! specific to an instruction set and is chosen once per ray or packet. Nothing is copied out of the mapping: nodes, strip records,
//! vertices and references are read in place, so resident memory is whatever the rays touch.
//!
//! Guarantees:
//! * Watertight: a ray through a shared edge or vertex of a closed mesh always hits (see
//!   [`watertight`]); bounds tests are conservative under rounding (see [`prepared`]), also
//!   for subnormal direction components.
//! * Closed interval: a hit is reported when its `t` lies in `[tmin, tmax]`, ends included, e.g.
//!   with `tmin = tmax` at the hit (traversal culls a little beyond `tmax`, see
//!   `Closest::reach`). A zero `t` is `+0.0`.
//! * Deterministic: the closest hit is the smallest `(t, strip, window)` among the hits, so the
//!   result does not depend on visiting order, packet width or thread count. Packets run the
//!   same per-ray arithmetic as single rays and give bit-identical hits.
//!
//! This module is read side only: it uses `format`, `geometry` and `strip_windows`, nothing
//! from the build side or the pipeline.

mod attributes;
mod closest;
pub mod kernel;
mod lanes;
mod occlusion16;
mod packet;
pub mod prepared;
mod ray;
pub mod ray_file;
mod ray_order;
mod strip;
mod top;
pub mod watertight;

use arrayvec::ArrayVec;
use rayon::prelude::*;

use crate::format::reader::ReducemFile;
use crate::geometry::Point;
pub use attributes::{hit_attributes, surface_attributes, HitAttributes};
use closest::Closest;
use kernel::prefetch::StripSections;
pub use kernel::{Kernel, KernelError, KERNEL_VARIABLE};
use lanes::PACKET_WIDTH;
use prepared::PreparedRay;
use strip::StripQuery;
use top::RayWalk;

pub use ray::{Hit, Ray};
pub use ray_order::coherent_order;

/// Tuning of the traversal. Results do not depend on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceOptions {
    /// Intervals of at most this many windows are intersected at once instead of descending
    /// further (the paper's "external parameter"); the file's leaf size applies when larger.
    pub subtree_windows: usize,
    /// Trace batches as packets of eight rays at the top level.
    pub packets: bool,
    /// The SIMD kernel (by default the fastest this CPU runs; see [`Kernel::from_env`]).
    pub kernel: Kernel,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            subtree_windows: 8,
            packets: true,
            kernel: Kernel::detect(),
        }
    }
}

/// Rays handed to one rayon task: enough to amortize scheduling and for the octant grouping
/// of `Tracer::trace_by_octant` to fill packets whose lanes meet in the same strips (ambient
/// occlusion rays come 16 per hit point over a hemisphere); few enough to balance.
pub const BATCH_RAYS: usize = 4096;

/// Traces rays against one mapped file.
pub struct Tracer<'f> {
    file: &'f ReducemFile,
    options: TraceOptions,
    strips: StripSections<'f>,
}

impl<'f> Tracer<'f> {
    pub fn new(file: &'f ReducemFile, options: TraceOptions) -> Tracer<'f> {
        let strips = StripSections::new(file);
        Tracer {
            file,
            options,
            strips,
        }
    }

    pub fn file(&self) -> &'f ReducemFile {
        self.file
    }

    /// What the walks prefetch strips from.
    fn strip_sections(&self) -> &StripSections<'f> {
        &self.strips
    }

    pub fn options(&self) -> &TraceOptions {
        &self.options
    }

    /// The closest hit in `[tmin, tmax]`, if any.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let prepared = PreparedRay::new(ray);
        let mut closest = Closest::none(ray.tmax);
        self.trace_ray(&prepared, false, &mut closest);
        self.finish(&closest)
    }

    /// Whether anything is hit in `[tmin, tmax]`; stops at the first hit found.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let prepared = PreparedRay::new(ray);
        let mut closest = Closest::none(ray.tmax);
        self.trace_ray(&prepared, true, &mut closest)
    }

    /// The single-ray walk on the options' kernel; true when `any_hit` found a hit.
    fn trace_ray(&self, ray: &PreparedRay, any_hit: bool, closest: &mut Closest) -> bool {
        let walk = RayWalk {
            tracer: self,
            query: &self.query(ray, any_hit),
            closest,
        };
        kernel::dispatch(self.options.kernel, walk)
    }

    /// [`Tracer::intersect`] for every ray, in parallel; packets when the options say so.
    pub fn intersect_batch(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        rays.par_chunks(BATCH_RAYS)
            .flat_map_iter(|chunk| self.intersect_chunk(chunk))
            .collect()
    }

    /// [`Tracer::occluded`] for every ray, in parallel; packets when the options say so.
    pub fn occluded_batch(&self, rays: &[Ray]) -> Vec<bool> {
        rays.par_chunks(BATCH_RAYS)
            .flat_map_iter(|chunk| self.occluded_chunk(chunk))
            .collect()
    }

    /// [`Tracer::intersect`] over consecutive rays on the calling thread.
    pub fn intersect_chunk(&self, rays: &[Ray]) -> Vec<Option<Hit>> {
        let mut hits = vec![None; rays.len()];
        self.intersect_each(rays, |index, hit| hits[index] = hit);
        hits
    }

    /// [`Tracer::intersect_chunk`] handing ray `i`'s closest hit to `each(i, hit)`, in no
    /// particular order of `i`, rather than collecting them.
    pub fn intersect_each(&self, rays: &[Ray], mut each: impl FnMut(usize, Option<Hit>)) {
        if !self.options.packets {
            for (index, ray) in rays.iter().enumerate() {
                each(index, self.intersect(ray));
            }
            return;
        }
        self.trace_by_octant(rays, false, |index, closest| {
            each(index, self.finish(closest))
        });
    }

    /// [`Tracer::intersect_each`] for rays that come in runs of one octant as long as a packet
    /// (a camera's rays in tile order): cut into packets in their order without counting the
    /// runs first. Any rays give the same answers; others only cost more.
    pub fn intersect_each_in_order(&self, rays: &[Ray], mut each: impl FnMut(usize, Option<Hit>)) {
        if !self.options.packets {
            return self.intersect_each(rays, each);
        }
        self.trace_packets(rays, None, false, |index, closest| {
            each(index, self.finish(closest))
        });
    }

    /// [`Tracer::occluded`] over consecutive rays on the calling thread.
    pub fn occluded_chunk(&self, rays: &[Ray]) -> Vec<bool> {
        if !self.options.packets {
            return rays.iter().map(|ray| self.occluded(ray)).collect();
        }
        let mut occluded = vec![false; rays.len()];
        self.trace_by_octant(rays, true, |index, closest| {
            occluded[index] = closest.found()
        });
        occluded
    }

    /// Traces `rays` as packets of rays that share their direction signs, and gives ray `i`'s
    /// result to `answer(i, closest)`. Rays already in runs of one octant (camera rays) are cut
    /// into packets in their order; others (a hit point's ambient-occlusion rays, spread over a
    /// hemisphere) are first grouped by octant, stably, so that they still form packets. The
    /// answers are those of single rays (packets are bit-identical to them) whatever the grouping.
    fn trace_by_octant(&self, rays: &[Ray], any_hit: bool, answer: impl FnMut(usize, &Closest)) {
        // Occlusion packets of a kernel that mixes direction signs take the rays in their order:
        // a hit point's sixteen ambient-occlusion rays share their origin, where a packet of
        // one octant holds the rays of two or three hit points.
        if any_hit && self.options.kernel.mixes_occlusion_signs() {
            return occlusion16::trace_occlusion(self, rays, answer);
        }
        self.trace_packets(rays, octant_order(rays), any_hit, answer);
    }

    /// Traces `rays` as packets of eight in `order` (indices into `rays`; theirs when `None`),
    /// and gives ray `i`'s result to `answer(i, closest)`.
    fn trace_packets(
        &self,
        rays: &[Ray],
        order: Option<Vec<u32>>,
        any_hit: bool,
        mut answer: impl FnMut(usize, &Closest),
    ) {
        let ray_at = |k: usize| order.as_ref().map_or(k, |order| order[k] as usize);
        let mut gathered = ArrayVec::<Ray, { PACKET_WIDTH }>::new();
        let mut found = [Closest::none(f32::NEG_INFINITY); PACKET_WIDTH];
        for start in (0..rays.len()).step_by(PACKET_WIDTH) {
            let end = (start + PACKET_WIDTH).min(rays.len());
            let group = if order.is_some() {
                gathered.clear();
                // Pushed one by one: `extend` stayed an out-of-line call per packet.
                for k in start..end {
                    gathered.push(rays[ray_at(k)]);
                }
                &gathered[..]
            } else {
                &rays[start..end]
            };
            packet::trace_packet(self, group, any_hit, &mut found);
            for (k, closest) in (start..end).zip(&found) {
                answer(ray_at(k), closest);
            }
        }
    }

    fn query<'a>(&'a self, ray: &'a PreparedRay, any_hit: bool) -> StripQuery<'a> {
        StripQuery {
            ray,
            leaf_windows: self.file.leaf_windows(),
            subtree_windows: self.options.subtree_windows,
            any_hit,
        }
    }

    /// Turns the traversal's closest hit into a [`Hit`] in the triangle's input winding.
    fn finish(&self, closest: &Closest) -> Option<Hit> {
        if !closest.found() {
            return None;
        }
        let [w0, w1, w2] = closest.weights;
        let [c0, c1, c2] = closest.corners;
        // Odd windows list their first two corners in the opposite order of the input winding
        // (as `StripView::window_points` does).
        let (u, v, corners) = if closest.window.is_multiple_of(2) {
            (w1, w2, [c0, c1, c2])
        } else {
            (w0, w2, [c1, c0, c2])
        };
        Some(Hit {
            t: closest.t,
            u,
            v,
            normal: unit_normal(&corners),
            strip: closest.strip,
            window: closest.window,
        })
    }
}

/// The indices of `rays` grouped by the octant of their direction (its three sign bits), each
/// group in the rays' order (a counting sort over the eight octants); `None` when the rays
/// already come in runs of one octant as long as a packet on average, which then form packets
/// as they are.
fn octant_order(rays: &[Ray]) -> Option<Vec<u32>> {
    // The runs are counted without storing the octants, which camera rays do not need, and
    // only until they are too many (checked every 64 rays, not in the loop); grouped rays then
    // find their octants again.
    let most_runs = rays.len() / PACKET_WIDTH;
    let mut previous = rays.first().map_or(0, octant);
    let mut runs = 1;
    for chunk in rays.chunks(64) {
        for ray in chunk {
            let octant = octant(ray);
            runs += usize::from(octant != previous);
            previous = octant;
        }
        if runs > most_runs {
            break;
        }
    }
    if runs <= most_runs {
        return None;
    }
    let octants: Vec<u8> = rays.iter().map(octant).collect();
    let mut starts = [0usize; 9];
    for &octant in &octants {
        starts[usize::from(octant) + 1] += 1;
    }
    for i in 1..starts.len() {
        starts[i] += starts[i - 1];
    }
    let mut order = vec![0u32; rays.len()];
    for (index, &octant) in octants.iter().enumerate() {
        let slot = &mut starts[usize::from(octant)];
        order[*slot] = index as u32;
        *slot += 1;
    }
    Some(order)
}

/// The octant of `ray`'s direction: its three sign bits.
#[inline(always)]
fn octant(ray: &Ray) -> u8 {
    let [x, y, z] = ray.direction.map(f32::to_bits);
    (x >> 31 | (y >> 31) << 1 | (z >> 31) << 2) as u8
}

/// `normalize((v1 - v0) × (v2 - v0))`, in f64 so that slivers with tiny edges keep a direction.
pub fn unit_normal(corners: &[Point; 3]) -> Point {
    let [a, b, c] = corners.map(|p| p.map(f64::from));
    let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    if length == 0.0 {
        return [0.0; 3];
    }
    n.map(|x| (x / length) as f32)
}

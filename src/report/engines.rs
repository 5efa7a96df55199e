//! The ray tracers under comparison behind one interface, and their speed on a [`RaySet`].
//!
//! Each engine counts hits (primary) and occluded rays (AO) so that the report can show that the
//! engines answered the same queries, not only how fast.

use rayon::prelude::*;

use super::workload::{median_timed, RaySet};
use crate::baseline::TriangleBvh;
use crate::trace::{Ray, Tracer};

/// Rays handed to one rayon task: eight 8-ray packets of one 8×8 tile.
const CHUNK: usize = 64;

pub trait Engine: Sync {
    /// How many of `rays` hit something (closest-hit queries).
    fn count_hits(&self, rays: &[Ray]) -> usize;
    /// How many of `rays` are occluded (any-hit queries).
    fn count_occluded(&self, rays: &[Ray]) -> usize;
}

/// ReduceM: primary rays as packets when the options say so, AO rays one by one as the
/// renderer traces them.
pub struct ReduceM<'f>(pub Tracer<'f>);

impl Engine for ReduceM<'_> {
    fn count_hits(&self, rays: &[Ray]) -> usize {
        self.0.intersect_chunk(rays).iter().flatten().count()
    }
    fn count_occluded(&self, rays: &[Ray]) -> usize {
        rays.iter().filter(|ray| self.0.occluded(ray)).count()
    }
}

/// The in-project SAH BVH over indexed triangles, single rays.
pub struct Baseline<'b>(pub &'b TriangleBvh);

impl Engine for Baseline<'_> {
    fn count_hits(&self, rays: &[Ray]) -> usize {
        rays.iter()
            .filter(|r| self.0.intersect(r).is_some())
            .count()
    }
    fn count_occluded(&self, rays: &[Ray]) -> usize {
        rays.iter().filter(|r| self.0.occluded(r)).count()
    }
}

/// Median speed of one engine on one ray set, with what it answered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Speed {
    pub primary_mrays: f64,
    pub ao_mrays: f64,
    pub primary_hits: usize,
    pub ao_occluded: usize,
}

/// Traces both ray sets `runs` times on all cores.
pub fn measure(engine: &dyn Engine, rays: &RaySet, runs: usize) -> Speed {
    let (primary_seconds, primary_hits) = median_timed(runs, || {
        rays.primary
            .par_chunks(CHUNK)
            .map(|chunk| engine.count_hits(chunk))
            .sum::<usize>()
    });
    let (ao_seconds, ao_occluded) = median_timed(runs, || {
        rays.ambient_occlusion
            .par_chunks(CHUNK)
            .map(|chunk| engine.count_occluded(chunk))
            .sum::<usize>()
    });
    Speed {
        primary_mrays: mrays(rays.primary.len(), primary_seconds),
        ao_mrays: mrays(rays.ambient_occlusion.len(), ao_seconds),
        primary_hits,
        ao_occluded,
    }
}

fn mrays(rays: usize, seconds: f64) -> f64 {
    rays as f64 / seconds.max(1e-9) / 1e6
}

//! The ray tracers under comparison behind one interface, and their speed on a [`RaySet`].
//!
//! Each engine counts hits (primary) and occluded rays (AO) so that the report can show that the
//! engines answered the same queries, not only how fast.

use std::time::Instant;

use rayon::prelude::*;

use super::workload::RaySet;
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

/// Traces both ray sets on all cores: the median over `runs` runs, each repeating the set until
/// at least `min_seconds` have passed (short runs are at the mercy of the scheduler).
pub fn measure(engine: &dyn Engine, rays: &RaySet, runs: usize, min_seconds: f64) -> Speed {
    let (primary_mrays, primary_hits) = median_rate(&rays.primary, runs, min_seconds, |chunk| {
        engine.count_hits(chunk)
    });
    let (ao_mrays, ao_occluded) =
        median_rate(&rays.ambient_occlusion, runs, min_seconds, |chunk| {
            engine.count_occluded(chunk)
        });
    Speed {
        primary_mrays,
        ao_mrays,
        primary_hits,
        ao_occluded,
    }
}

/// Median Mrays/s of `trace` over `rays`, and what one pass over them answered.
fn median_rate(
    rays: &[Ray],
    runs: usize,
    min_seconds: f64,
    trace: impl Fn(&[Ray]) -> usize + Sync,
) -> (f64, usize) {
    let pass = || rays.par_chunks(CHUNK).map(&trace).sum::<usize>();
    let mut answer = 0;
    let mut rates: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let started = Instant::now();
            let mut passes = 0;
            while passes == 0 || started.elapsed().as_secs_f64() < min_seconds {
                answer = pass();
                passes += 1;
            }
            let seconds = started.elapsed().as_secs_f64().max(1e-9);
            (rays.len() * passes) as f64 / seconds / 1e6
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    (rates[rates.len() / 2], answer)
}

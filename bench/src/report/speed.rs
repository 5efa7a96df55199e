//! The speed of the engines under comparison ([`crate::workload::engines`]) on a [`RaySet`],
//! with what they answered.

use std::time::Instant;

use rayon::prelude::*;

use crate::workload::engines::Engine;
use crate::workload::RaySet;
use reducem::trace::Ray;

/// Rays handed to one rayon task, for every engine: as many as ReduceM's batch calls hand out,
/// so that it groups them into packets as a user's batch would
/// (`bench/examples/bench_trace.rs` says what 64-ray tasks cost it; Embree, one ray at a time,
/// is indifferent).
const CHUNK: usize = reducem::trace::BATCH_RAYS;

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

//! The ray tracers under comparison behind one interface.
//!
//! Each engine counts hits (primary rays) and occluded rays (AO rays), so that a benchmark shows
//! that the engines answered the same queries, not only how fast.

use crate::baseline::TriangleBvh;
use reducem::trace::{Ray, Tracer};

#[cfg(feature = "embree")]
pub use super::embree_engine::{embree_ray, triangle_geometry, Embree};

pub trait Engine: Sync {
    /// How many of `rays` hit something (closest-hit queries).
    fn count_hits(&self, rays: &[Ray]) -> usize;
    /// How many of `rays` are occluded (any-hit queries).
    fn count_occluded(&self, rays: &[Ray]) -> usize;
}

/// ReduceM: rays as batches, as the renderer and `reducem query` trace them (in packets when
/// the options say so; AO rays grouped by octant first).
pub struct ReduceM<'f>(pub Tracer<'f>);

impl Engine for ReduceM<'_> {
    fn count_hits(&self, rays: &[Ray]) -> usize {
        // Counted as they are found, as Embree's are: no vector of hits per task.
        let mut hits = 0;
        self.0
            .intersect_each(rays, |_, hit| hits += usize::from(hit.is_some()));
        hits
    }
    fn count_occluded(&self, rays: &[Ray]) -> usize {
        self.0.occluded_chunk(rays).iter().filter(|&&o| o).count()
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

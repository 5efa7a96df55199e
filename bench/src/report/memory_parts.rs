//! Bytes of a representation by part: what the memory table measures for ReduceM and its
//! peers (the baseline, the paper's layout, Embree), in a module of its own so that the peers'
//! measurements and the table depend on it rather than on each other.

/// Bytes of one representation by part; the parts sum to the total.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryParts {
    pub vertices: u64,
    /// Triangle data: strips and strip hierarchies for ReduceM, triangles for the others.
    pub triangles: u64,
    /// The hierarchy over everything: ReduceM's top level, a BVH's tree.
    pub hierarchy: u64,
    /// File header and section padding; Embree's allocations beyond its buffers.
    pub other: u64,
}

impl MemoryParts {
    pub fn total(&self) -> u64 {
        self.vertices + self.triangles + self.hierarchy + self.other
    }
}

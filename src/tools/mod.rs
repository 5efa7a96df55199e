//! Tools around the paper's algorithms, kept apart so the crate root reads as the paper:
//! synthetic meshes ([`gen`]), the benchmark baseline BVH ([`baseline`]), the shared measuring
//! harness ([`workload`]) and the trade-offs report ([`report`], feature `report`). Nothing in
//! the conversion or the read side depends on them.

pub mod baseline;
pub mod gen;
#[cfg(feature = "report")]
pub mod report;
pub mod workload;

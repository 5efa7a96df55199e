//! What ReduceM is measured against and with, kept out of the `reducem` library: the benchmark
//! baseline BVH ([`baseline`]), the measuring harness the benchmarks and the report share
//! ([`workload`], with Embree behind the `embree` feature) and the trade-offs report ([`report`],
//! feature `report`, run by the `reducem-bench report` command).

#![deny(unsafe_code)]

pub mod baseline;
#[cfg(feature = "report")]
pub mod report;
pub mod workload;

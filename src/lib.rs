//! ReduceM: compact, memory-mappable ray tracing of massive triangle meshes.
//!
//! Implements Lauterbach, Yoon, Tang and Manocha, "ReduceM: Interactive and Memory Efficient Ray
//! Tracing of Large Models" (EGSR 2008). `docs/ARCHITECTURE.md` maps the paper's concepts to modules.
//!
//! Build side: [`input`] reads meshes, [`stripify`] is Strip-RT (paper 4.1), [`strip_encoding`]
//! builds the per-strip implicit kd-trees (paper 3.2), [`toplevel`] the global hierarchy,
//! [`conversion`] ties them together per chunk and lays the strips out for [`format::writer`], which
//! writes the file. Read side: the crate `reducem-core`, re-exported here as
//! [`format`](mod@format) (with [`format::reader`], which maps and validates a file), [`trace`],
//! [`geometry`], [`strip_windows`], [`mapping`] and [`atomic`]; it depends on nothing from the
//! build side.
//!
//! The tools around the algorithms live in crates of their own: `reducem-gen` (the synthetic
//! meshes of `pipeline gen` and of the tests) and `reducem-bench` (the baseline BVH, the
//! benchmark workloads, Embree and the trade-offs report).

#![deny(unsafe_code)]

pub mod chunking;
pub mod cli;
pub mod closedness;
pub mod conversion;
pub mod decode;
pub mod exit_code;
pub mod format;
pub mod input;
pub mod inspect;
pub mod mesh;
pub mod output;
pub mod quantize;
pub mod render;
pub mod splitmix;
pub mod strip_encoding;
pub mod stripify;
pub mod toplevel;

pub use reducem_core::{atomic, geometry, mapping, query, strip_windows, trace};

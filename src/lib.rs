//! ReduceM: compact, memory-mappable ray tracing of massive triangle meshes.
//!
//! Implements Lauterbach, Yoon, Tang and Manocha, "ReduceM: Interactive and Memory Efficient Ray
//! Tracing of Large Models" (EGSR 2008). `docs/ARCHITECTURE.md` maps the paper's concepts to modules.
//!
//! Build side: [`input`] reads meshes, [`stripify`] is Strip-RT (paper 4.1), [`encode`] builds the
//! per-strip implicit kd-trees (paper 3.2), [`toplevel`] the global hierarchy, [`build`] ties them
//! together per chunk and [`format::writer`] writes the file. Read side: [`format::reader`] maps
//! and validates a file; it depends on nothing from the build side.

pub mod atomic;
pub mod baseline;
pub mod build;
pub mod chunking;
pub mod decode;
pub mod encode;
pub mod exit_code;
pub mod format;
pub mod gen;
pub mod geometry;
pub mod input;
pub mod inspect;
pub mod mapping;
pub mod mesh;
pub mod quantize;
pub mod render;
#[cfg(feature = "report")]
pub mod report;
pub mod splitmix;
pub mod strip;
pub mod stripify;
pub mod toplevel;
pub mod trace;
pub mod workload;

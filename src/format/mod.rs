//! The ReduceM file format: the read side's records, reader and validation from
//! [`reducem_core::format`], re-exported here, plus the streaming [`writer`], which belongs to
//! the build side.

pub use reducem_core::format::*;

pub mod attribute_sections;
pub mod writer;

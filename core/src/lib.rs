//! The read side of ReduceM (Lauterbach et al., EGSR 2008): a file is mapped, validated once at
//! open and traced in place, paging in only what rays reach.
//!
//! [`format`](mod@format) holds the on-disk records, the counts a header holds, and the reader with its
//! validation; [`mapping`] the one memory mapping; [`geometry`] and [`strip_windows`] the shared
//! conventions (boxes, strip windows); [`trace`] the tracer and its ray files; [`query`] the
//! queries beyond a ray's closest hit (closest points); [`triangle_index`]
//! the file-order position of a stored triangle; [`atomic`] the temporary-and-rename write the
//! ray files use; [`signals`] how a process ends on a signal (its temporaries removed, a
//! truncated mapped file named). Nothing here knows how a file is built: the `reducem` crate holds the build
//! side and re-exports this crate under its own paths.

#![deny(unsafe_code)]

pub mod atomic;
pub mod format;
pub mod geometry;
pub mod mapping;
pub mod query;
pub mod signals;
pub mod strip_windows;
pub mod trace;
pub mod triangle_index;

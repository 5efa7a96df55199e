//! The ReduceM file format, version 3 (and version 2, which it reads): on-disk records and
//! layout constants.
//!
//! `docs/FORMAT.md` is the specification; this module is its code form. A file is a 4096-byte
//! header page (magic, version, endianness marker, counts, a section table with offsets, lengths
//! and checksums, and a header checksum) followed by page-aligned sections. Every record here is
//! `#[repr(C)]`, little-endian, `Pod`, and has its size asserted at compile time, so the reader
//! views the mapping in place with no pointer fix-up.

pub mod attributes;
pub mod block_boxes;
pub mod counts;
mod defect;
pub mod face_ids;
pub mod grid;
pub mod implicit_tree;
pub mod model;
pub mod pool;
pub mod quantized;
pub mod reader;
pub mod references;
pub mod vertices;

mod grid_node;
mod header;
mod node_record;
mod precision;
mod section;
mod strip_record;
mod top_node;
mod vertex_encoding;
mod wide_node;

pub use defect::Defect;
pub use grid_node::*;
pub use header::*;
pub use node_record::*;
pub use precision::*;
pub use section::*;
pub use strip_record::*;
pub use top_node::*;
pub use vertex_encoding::*;
pub use wide_node::*;

/// First eight bytes of every ReduceM file.
pub const MAGIC: [u8; 8] = *b"REDUCEM\0";
/// Incremented on any incompatible layout change; readers reject majors they do not know.
/// Version 2 replaced version 1's binary top-level nodes (32 bytes) with 4-wide ones
/// ([`TopNode`]); version 3 added per-block boxes to strip blocks ([`block_boxes`]) and packs
/// the references of every vertex encoding; version 4 replaced the top-level nodes with 8-wide
/// compressed ones ([`WideNode`]). Writers write version 4.
pub const VERSION_MAJOR: u16 = 4;
/// Incremented on compatible additions; readers accept any minor of a major they read.
/// Lossless and `vertex_encoding` 3 files are written as 4.0.
pub const VERSION_MINOR: u16 = 0;
/// The minor of format 4 that added pooled grid files (`vertex_encoding` 5, [`pool`]), the one
/// pooled files are written as.
pub const POOLED_MINOR: u16 = 1;
/// The oldest major this reader reads (version 2 files are read as before).
pub const OLDEST_READ_MAJOR: u16 = 2;
/// Version 2's minors: minor 1 added the [`PrecisionRecord`] and the grid vertex encoding,
/// minor 2 grid top-level nodes ([`GridNode`], `vertex_encoding` 2), minor 3 packed references
/// in grid files (`vertex_encoding` 3), minor 4 grid top-level nodes in lossless files
/// (`vertex_encoding` 4), minor 5 attributes. Version 2 writers wrote the lowest minor that had
/// what the file used ([`VertexEncoding::minor`]).
pub const VERSION_2_LAST_MINOR: u16 = 5;
/// Written as a little-endian u32; a reader on a big-endian host sees `0x0403_0201`.
pub const ENDIAN_MARKER: u32 = 0x0102_0304;
/// Sections start at multiples of this, so each can be mapped and paged on its own.
pub const SECTION_ALIGN: u64 = 4096;
/// Bytes reserved for the header; the first section starts here.
pub const HEADER_PAGE: u64 = SECTION_ALIGN;
/// Deepest top-level node a valid file may have (root at depth 0); bounds the traversal stack.
pub const MAX_TOP_DEPTH: usize = 128;
/// The most vertices one strip can address with 1-byte local indices (paper 3.2).
pub const MAX_STRIP_VERTICES: usize = 256;

/// Rounds a byte count up to the next multiple of `align`.
pub fn align_up(value: u64, align: u64) -> u64 {
    value.div_ceil(align) * align
}

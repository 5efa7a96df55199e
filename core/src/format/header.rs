//! The file header at byte 0 of the header page.

use bytemuck::{Pod, Zeroable};

#[cfg(doc)]
use super::VertexEncoding;
use super::{attributes, SectionEntry, SECTION_COUNT};

/// The file header at byte 0. 208 bytes; the rest of the first 4096-byte page is zero.
///
/// | bytes | field |
/// |---|---|
/// | 0..8 | `magic` = `REDUCEM\0` |
/// | 8..10 | `version_major`, 10..12 `version_minor` |
/// | 12..16 | `endian_marker` = 0x01020304 |
/// | 16..20 | `header_bytes` = 208 |
/// | 20..24 | `vertex_encoding` ([`VertexEncoding`]): 0 f32, 1 to 3 grid, 4 f32 with grid nodes, 5 pooled grid |
/// | 24..28 | `leaf_windows`: strip kd-tree leaf size in windows (1..=255) |
/// | 28..32 | `max_strip_length` used by the build (informational) |
/// | 32..40 | `triangle_count`: real (non-swap) triangles |
/// | 40..48 | `strip_count` |
/// | 48..56 | `stored_vertex_count`: vertices stored over all strips |
/// | 56..64 | `input_vertex_count`: distinct vertices of the input after welding |
/// | 64..72 | `dropped_triangle_count`: degenerate input triangles not stored |
/// | 72..80 | `hierarchy_vertex_count`: stored copies that exist only to encode split bounds |
/// | 80..92 | `bounds_min` f32×3, 92..104 `bounds_max` f32×3 |
/// | 104..200 | section table: 3 × [`SectionEntry`] |
/// | 200..208 | `header_checksum`: XXH3-64 of bytes 0..200 |
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct Header {
    pub magic: [u8; 8],
    pub version_major: u16,
    pub version_minor: u16,
    pub endian_marker: u32,
    pub header_bytes: u32,
    pub vertex_encoding: u32,
    pub leaf_windows: u32,
    pub max_strip_length: u32,
    pub triangle_count: u64,
    pub strip_count: u64,
    pub stored_vertex_count: u64,
    pub input_vertex_count: u64,
    pub dropped_triangle_count: u64,
    pub hierarchy_vertex_count: u64,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub sections: [SectionEntry; SECTION_COUNT],
    pub header_checksum: u64,
}
const _: () = assert!(std::mem::size_of::<Header>() == 208);

impl Header {
    /// Whether the file has the precision record (since 2.1).
    pub fn has_precision_record(&self) -> bool {
        self.version_major > 2 || self.version_minor >= 1
    }

    /// Whether the file has the attribute record (since 2.5).
    pub fn has_attribute_record(&self) -> bool {
        self.version_major > 2 || self.version_minor >= attributes::ATTRIBUTES_MINOR
    }

    /// Whether strip blocks carry per-block boxes and packed references (since 3.0).
    pub fn has_block_boxes(&self) -> bool {
        self.version_major >= 3
    }
}

/// Byte length of the header prefix covered by `header_checksum`.
pub const HEADER_CHECKSUMMED_BYTES: usize = 200;

//! The strip record: where a strip's block is and its sizes.

#[cfg(doc)]
use super::quantized;
use bytemuck::{Pod, Zeroable};

/// Where a strip's block lives in the strip-data section. 8 bytes.
///
/// | bytes | field |
/// |---|---|
/// | 0..4 | `data_word`: block offset in the strip-data section, in 4-byte words |
/// | 4..6 | `vertex_count`: stored vertices (3..=256) |
/// | 6..8 | `reference_count`: 1-byte vertex references (≥ 3) |
///
/// A block is `vertex_count` vertices (12 bytes each, or packed grid offsets: see
/// [`quantized`]), then the split axes of the strip's kd-tree at 2 bits per node (4 per byte,
/// node `i` in bits `2*(i%4)..`), then `reference_count` references, padded with zeros to a
/// multiple of 4 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct StripRecord {
    pub data_word: u32,
    pub vertex_count: u16,
    pub reference_count: u16,
}
const _: () = assert!(std::mem::size_of::<StripRecord>() == 8);

/// Bytes of packed 2-bit split axes for `nodes` kd-tree nodes.
pub fn axis_bytes(nodes: usize) -> usize {
    nodes.div_ceil(4)
}

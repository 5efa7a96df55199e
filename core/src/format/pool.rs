//! Shared vertex pools of grid files (format 4.1, `vertex_encoding` 5).
//!
//! Consecutive strips (file order) form a group whose distinct grid points are stored once, in a
//! pool after the group's strip parts: 2.27 stored copies of each grid point in per-strip blocks
//! fell to about 1.3, the largest part of a 20-bit grid file.
//!
//! A strip's part, at its record's `data_word`:
//!
//! | bytes | field |
//! |---|---|
//! | 0..2 | `pool_words`: u16, 4-byte words from the part's start to its group's pool (≥ 1) |
//! | 2 | `base`: the pool point that is the strip's vertex 0 |
//! | 3.. | the references as in `vertex_encoding` 3, at the width of the record's `vertex_count` |
//! | then | the block boxes, as in `vertex_encoding` 3, anchored at the strip's vertex 0 |
//!
//! padded with zeros to 4 bytes. No split axes: a strip of more than eight windows has block
//! boxes, which the tracer walks instead of the kd-tree, so pooled files need leaves of at least
//! eight windows. The pool: a byte `points - 1`, then the axis words and offsets of the
//! pool's points as a `vertex_encoding` 3 block stores a strip's vertices
//! ([`super::quantized`]), then [`POOL_TAIL_BYTES`] zero bytes, padded to 4 bytes. A strip's
//! vertex `i` is pool point `base + i` (`base + vertex_count` at most the pool's points), so
//! the strip's view decodes its vertices with the one decode expression of encoding 3.

use super::quantized::{vertex_part_bytes, AxisWord, AxisWordLayout};

/// Bytes before a part's references: the pool distance and the base.
pub const PART_HEADER_BYTES: usize = 3;
/// Zero bytes after a pool's offsets: a vertex's offsets are read four bytes at a time.
pub const POOL_TAIL_BYTES: usize = 3;
/// The farthest a pool lies from one of its strips' parts.
pub const MAX_POOL_DISTANCE: usize = u16::MAX as usize * 4;
/// Bytes before a pool's axis words: its point count less one.
pub const POOL_COUNT_BYTES: usize = 1;
/// The most points a pool holds: strips address their vertices with one-byte references.
pub const MAX_POOL_POINTS: usize = 256;
/// The longest pool of a grid of at most 24 bits, padded.
pub const MAX_POOL_BYTES: usize =
    (POOL_COUNT_BYTES + (3 * 29 + MAX_POOL_POINTS * 72) / 8 + 1) + POOL_TAIL_BYTES + 3;

/// The two fields at the start of a strip's part.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartHeader {
    /// Bytes from the part's start to its pool.
    pub pool_distance: usize,
    pub base: usize,
}

impl PartHeader {
    /// The header at the start of `part`, or `None` when it is shorter.
    #[inline(always)]
    pub fn read(part: &[u8]) -> Option<PartHeader> {
        let &[low, high, base] = part.first_chunk::<PART_HEADER_BYTES>()?;
        Some(PartHeader {
            pool_distance: u16::from_le_bytes([low, high]) as usize * 4,
            base: base as usize,
        })
    }

    /// The header's bytes; `pool_distance` a multiple of 4 up to [`MAX_POOL_DISTANCE`].
    pub fn bytes(&self) -> [u8; PART_HEADER_BYTES] {
        let [low, high] = ((self.pool_distance / 4) as u16).to_le_bytes();
        [low, high, self.base as u8]
    }
}

/// Points of the pool whose count byte is `byte`.
#[inline(always)]
pub fn pool_points(byte: u8) -> usize {
    byte as usize + 1
}

/// Bytes of a pool of `points` points with axis words `axes`, padded to 4.
pub fn pool_bytes(points: usize, axes: &[AxisWord; 3], layout: AxisWordLayout) -> usize {
    (POOL_COUNT_BYTES + vertex_part_bytes(points, axes, layout) + POOL_TAIL_BYTES)
        .next_multiple_of(4)
}

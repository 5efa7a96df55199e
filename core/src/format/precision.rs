//! The precision record after the header: the grid and how far positions moved.

use bytemuck::{Pod, Zeroable};

use super::grid;
#[cfg(doc)]
use super::{GridNode, Header};

/// Where the [`PrecisionRecord`] starts in the header page: right after the [`Header`].
pub const PRECISION_OFFSET: usize = 208;

/// How positions were stored and how far they moved from the input. 80 bytes at byte 208 of
/// the header page, since format 2.1; a 2.0 file has zeros there (lossless, nothing moved), and
/// 2.0 readers ignore it, so they still read lossless 2.1 files (and reject grid files through
/// `vertex_encoding`).
///
/// | bytes | field |
/// |---|---|
/// | 208..212 | `grid_bits`: bits per axis of the grid (1..=24); 0 for f32 vertices |
/// | 212..216 | `node_shift`: the [`GridNode`] boxes' cell is `grid_cell * 2^node_shift` (vertex encodings 2 and 3); zero otherwise |
/// | 216..228 | `grid_origin` f32×3: the position of grid point (0, 0, 0); with vertex encoding 4, of the node grid's |
/// | 228..232 | `grid_cell` f32: grid step on every axis, a power of two; with vertex encoding 4 the node grid's step; 0 for other f32 files |
/// | 232..240 | `error_max` f64: largest distance from an input vertex (after welding) to its stored position |
/// | 240..248 | `error_rms` f64: root mean square of the same distances |
/// | 248..252 | `weld_tolerance` f32: input vertices closer than this were merged; 0 = bit-identical only |
/// | 252..256 | reserved, zero |
/// | 256..264 | `welded_vertex_count`: input vertices merged into another by the tolerance |
/// | 264..272 | `weld_displacement_max` f64: largest distance a welded vertex moved |
/// | 272..280 | `weld_displacement_rms` f64: root mean square over the welded vertices |
/// | 280..288 | `checksum`: XXH3-64 of bytes 208..280 |
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct PrecisionRecord {
    pub grid_bits: u32,
    pub node_shift: u32,
    pub grid_origin: [f32; 3],
    pub grid_cell: f32,
    pub error_max: f64,
    pub error_rms: f64,
    pub weld_tolerance: f32,
    pub reserved2: u32,
    pub welded_vertex_count: u64,
    pub weld_displacement_max: f64,
    pub weld_displacement_rms: f64,
    pub checksum: u64,
}
const _: () = assert!(std::mem::size_of::<PrecisionRecord>() == 80);

/// Byte length of the precision record prefix covered by its `checksum`.
pub const PRECISION_CHECKSUMMED_BYTES: usize = 72;

impl PrecisionRecord {
    /// The record with its checksum set.
    pub fn sealed(mut self) -> PrecisionRecord {
        self.checksum = self.computed_checksum();
        self
    }

    pub fn computed_checksum(&self) -> u64 {
        xxhash_rust::xxh3::xxh3_64(&bytemuck::bytes_of(self)[..PRECISION_CHECKSUMMED_BYTES])
    }

    /// The grid of a grid-encoded file.
    pub fn grid(&self) -> grid::Grid {
        grid::Grid {
            bits: self.grid_bits,
            origin: self.grid_origin,
            cell: self.grid_cell,
        }
    }
}

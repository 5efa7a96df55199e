//! The strip-record layout: where each strip's block lands in the strip-data section, as the
//! 4-byte word offsets [`StripRecord`]s hold. The in-memory writer and the pipeline's stages
//! (one chunk's records, then each chunk's place in the final file) all count through
//! [`DataWords`], so an offset beyond what a record can hold is an error, never a wrap.

use std::io;

use super::pooling::{pool_blocks, pools_vertices};
use super::{strip_bounds, BuildParams};
use crate::format::grid::Grid;
use crate::format::{StripRecord, VERSION_MAJOR};
use crate::geometry::Aabb;
use crate::strip_encoding::EncodedStrip;
use crate::toplevel::{self, TopLevel, TopLevelParams};

/// A chunk laid out for a file: its own top level, and its strips' records in that top level's
/// leaf order with chunk-local data words.
#[derive(Clone, Debug)]
pub struct ChunkLayout {
    pub top: TopLevel,
    pub records: Vec<StripRecord>,
    /// Union of the strip bounds.
    pub bounds: Aabb,
    /// Bytes of the chunk's strip blocks, a multiple of 4.
    pub data_bytes: u64,
    /// The pools' points when the strips' grid vertices were pooled, which the header then
    /// counts as stored; `None` otherwise.
    pub pooled_vertices: Option<u64>,
}

/// What pooling a chunk's grid vertices needs ([`pools_vertices`]).
#[derive(Clone, Copy, Debug)]
pub struct Pooling {
    pub grid: Grid,
    pub leaf_windows: usize,
}

impl Pooling {
    /// The pooling of a file built with `params` on `grid`, if it pools.
    pub fn of(params: &BuildParams, grid: Option<&Grid>) -> Option<Pooling> {
        let pools = pools_vertices(grid, params.attributes, params.leaf_windows);
        grid.filter(|_| pools).map(|&grid| Pooling {
            grid,
            leaf_windows: params.leaf_windows,
        })
    }
}

impl ChunkLayout {
    /// Builds the top level over `strips` and lays their blocks out in its leaf order. A node
    /// no record holds ([`toplevel::NodeError`], an internal error) fails as `Other`.
    pub fn new(strips: &[EncodedStrip], params: &TopLevelParams) -> io::Result<ChunkLayout> {
        let bounds = strip_bounds(strips);
        let top = toplevel::build(&bounds, params).map_err(io::Error::other)?;
        ChunkLayout::place(strips, top, &bounds, None)
    }

    /// [`ChunkLayout::new`] for a chunk whose grid vertices are pooled: the blocks of `strips`
    /// are rewritten as pooled parts ([`pool_blocks`]) once the top level has fixed their order.
    pub fn pooled(
        strips: &mut [EncodedStrip],
        params: &TopLevelParams,
        pooling: Pooling,
    ) -> io::Result<ChunkLayout> {
        let bounds = strip_bounds(strips);
        let params = TopLevelParams {
            traversal_cost: toplevel::POOLED_TRAVERSAL_COST,
            ..params.clone()
        };
        let top = toplevel::build(&bounds, &params).map_err(io::Error::other)?;
        let grid = &pooling.grid;
        let stored = pool_blocks(strips, &top.strip_order, grid, pooling.leaf_windows);
        ChunkLayout::place(strips, top, &bounds, Some(stored))
    }

    fn place(
        strips: &[EncodedStrip],
        top: TopLevel,
        bounds: &[Aabb],
        pooled_vertices: Option<u64>,
    ) -> io::Result<ChunkLayout> {
        let mut words = DataWords::default();
        let records = strip_records(&top.strip_order, strips, &mut words)?;
        Ok(ChunkLayout {
            top,
            records,
            bounds: bounds.iter().fold(Aabb::EMPTY, |a, b| a.union(b)),
            data_bytes: words.bytes(),
            pooled_vertices,
        })
    }

    /// The chunk's strips in file order.
    pub fn strips<'a>(
        &'a self,
        strips: &'a [EncodedStrip],
    ) -> impl Iterator<Item = &'a EncodedStrip> {
        self.top.strip_order.iter().map(|&s| &strips[s as usize])
    }
}

/// The records of `strips` taken in `order`, their blocks placed one after another from where
/// `words` stands.
pub fn strip_records(
    order: &[u32],
    strips: &[EncodedStrip],
    words: &mut DataWords,
) -> io::Result<Vec<StripRecord>> {
    order
        .iter()
        .map(|&s| {
            let strip = &strips[s as usize];
            Ok(StripRecord {
                data_word: words.place(strip.block.len() as u64)?,
                vertex_count: strip.vertex_count,
                reference_count: strip.reference_count,
            })
        })
        .collect()
}

/// Shifts chunk-local records to a chunk placed at `base` words into the strip data.
pub fn rebase_records(records: &mut [StripRecord], base: u32) -> io::Result<()> {
    for record in records {
        record.data_word = record
            .data_word
            .checked_add(base)
            .ok_or_else(data_too_large)?;
    }
    Ok(())
}

/// A running count of 4-byte words of strip data. Blocks are padded to 4 bytes, so offsets are
/// counted in words.
#[derive(Clone, Copy, Debug, Default)]
pub struct DataWords {
    next: u64,
}

impl DataWords {
    /// The word offset of `bytes` (one block, or a chunk's blocks) placed next; then moves past
    /// them. Fails when the offset does not fit a record's `u32`.
    pub fn place(&mut self, bytes: u64) -> io::Result<u32> {
        let word = u32::try_from(self.next).map_err(|_| data_too_large())?;
        self.next += bytes / 4;
        Ok(word)
    }

    /// Bytes placed so far.
    pub fn bytes(&self) -> u64 {
        self.next * 4
    }
}

fn data_too_large() -> io::Error {
    io::Error::new(
        io::ErrorKind::FileTooLarge,
        format!("strip data exceeds 16 GiB: too large for format version {VERSION_MAJOR}"),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_beyond_a_record_are_errors() {
        let mut words = DataWords::default();
        assert_eq!(words.place(16).unwrap(), 0);
        assert_eq!(words.place(u32::MAX as u64 * 4 - 16).unwrap(), 4);
        assert_eq!(words.bytes(), u32::MAX as u64 * 4);
        assert_eq!(words.place(4).unwrap(), u32::MAX);
        assert!(words.place(4).is_err());
        let mut records = [StripRecord {
            data_word: u32::MAX - 1,
            vertex_count: 3,
            reference_count: 3,
        }];
        assert!(rebase_records(&mut records, 1).is_ok());
        assert!(rebase_records(&mut records, 1).is_err());
    }
}

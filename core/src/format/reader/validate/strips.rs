//! Strip record and strip block checks: counts, bounds, split axes, references, block boxes.

use std::ops::Range;

use crate::format::block_boxes::{BlockBoxes, EXPONENTS};
use crate::format::grid::Grid;
use crate::format::pool::{
    pool_bytes, pool_points, PartHeader, MAX_POOL_BYTES, MAX_POOL_DISTANCE, PART_HEADER_BYTES,
    POOL_COUNT_BYTES,
};
use crate::format::quantized::{vertex_part_bytes, AxisWord, AxisWordLayout};
use crate::format::reader::{
    try_view_block, view_block, FormatError, PartTable, ReducemFile, StripView, VertexLayout,
};
use crate::format::references::References;
use crate::format::{
    axis_bytes, Defect, FilePart, SectionKind, StripRecord, F32_VERTEX_BYTES, MAX_STRIP_VERTICES,
};

pub(super) const RECORD_BYTES: u64 = std::mem::size_of::<StripRecord>() as u64;

/// The error for a defect in strip `index`: in its block, or at its record when the defect has
/// no data offset.
pub(super) fn strip_error(
    opened: &ReducemFile,
    index: usize,
    (offset, defect, detail): StripDefect,
) -> FormatError {
    let (kind, offset) = match offset {
        Some(at) => (SectionKind::StripData, at),
        None => (SectionKind::StripRecords, index as u64 * RECORD_BYTES),
    };
    opened.invalid(
        FilePart::Section(kind),
        opened.section_offset(kind) + offset,
        defect,
        format!("strip {index}: {detail}"),
    )
}

/// A defect in a strip: the data-section offset where it is (if known), its kind and what is
/// wrong.
pub(super) type StripDefect = (Option<u64>, Defect, String);

/// What a strip block's length depends on besides its record.
pub(super) struct BlockShape<'a> {
    /// The file's node counts and part lengths by reference count.
    pub(super) parts: &'a PartTable,
    pub(super) layout: VertexLayout,
}

impl BlockShape<'_> {
    /// The kd-tree's internal node count of a record whose counts pass [`BlockShape::nodes`],
    /// else `None`: inlined into a first view, where the sound case needs no message.
    #[inline(always)]
    fn sound_nodes(&self, record: &StripRecord) -> Option<usize> {
        let vertices = record.vertex_count as usize;
        let references = record.reference_count as usize;
        if !(3..=MAX_STRIP_VERTICES).contains(&vertices) || references < 3 {
            return None;
        }
        let nodes = self.parts.nodes(references);
        (2 * nodes <= vertices).then_some(nodes)
    }

    /// Checks a record's counts and returns its kd-tree's internal node count.
    pub(super) fn nodes(&self, record: &StripRecord) -> Result<usize, StripDefect> {
        if let Some(nodes) = self.sound_nodes(record) {
            return Ok(nodes);
        }
        let vertices = record.vertex_count as usize;
        let references = record.reference_count as usize;
        if !(3..=MAX_STRIP_VERTICES).contains(&vertices) || references < 3 {
            return Err((
                None,
                Defect::OutOfRange,
                format!("{vertices} vertices and {references} references"),
            ));
        }
        let nodes = self.parts.nodes(references);
        let detail = format!(
            "{nodes} kd-tree nodes need {} bound vertices, it has {vertices}",
            2 * nodes
        );
        Err((None, Defect::CountMismatch, detail))
    }

    /// Bytes of the block with vertices of `vertex_bytes`.
    pub(super) fn length(&self, record: &StripRecord, nodes: usize, vertex_bytes: usize) -> u64 {
        let count = record.reference_count as usize;
        let references = self
            .layout
            .reference_bytes(count, record.vertex_count as usize);
        let (_, boxes) = self.parts.lengths(count);
        (vertex_bytes + axis_bytes(nodes) + references + boxes) as u64
    }

    /// A byte range of the strip-data section that holds the record's block: exact for f32
    /// vertices; for grid vertices, whose length the block's own axis words give, the longest
    /// the block could be, cut at the section end.
    pub(super) fn extent(
        &self,
        record: &StripRecord,
        data_len: u64,
    ) -> Result<Range<u64>, StripDefect> {
        let nodes = self.nodes(record)?;
        let count = record.vertex_count as usize;
        let longest = match self.layout {
            VertexLayout::F32 { .. } => self.length(record, nodes, count * F32_VERTEX_BYTES),
            VertexLayout::Grid { grid, packed, .. } => {
                let words_layout = VertexLayout::axis_words(&grid, packed);
                let widest = [AxisWord {
                    anchor: 0,
                    width: grid.bits,
                }; 3];
                let vertex_bytes = vertex_part_bytes(count, &widest, words_layout);
                self.length(record, nodes, vertex_bytes)
            }
            VertexLayout::Pooled { .. } => {
                let part = self.length(record, nodes, PART_HEADER_BYTES);
                part + (MAX_POOL_DISTANCE + MAX_POOL_BYTES) as u64
            }
        };
        let start = self.reaches(record, nodes, data_len)?;
        Ok(start..(start + longest).min(data_len))
    }

    /// The block's start in the section, once its shortest possible length (its exact length
    /// for f32 vertices, its axis words for grid vertices) is known to fit the section.
    pub(super) fn reaches(
        &self,
        record: &StripRecord,
        nodes: usize,
        data_len: u64,
    ) -> Result<u64, StripDefect> {
        let shortest = match self.layout {
            VertexLayout::F32 { .. } => {
                let vertex_bytes = record.vertex_count as usize * F32_VERTEX_BYTES;
                self.length(record, nodes, vertex_bytes)
            }
            VertexLayout::Grid { grid, packed, .. } => {
                let words_layout = VertexLayout::axis_words(&grid, packed);
                self.length(record, nodes, words_layout.bits().div_ceil(8))
            }
            VertexLayout::Pooled { .. } => self.length(record, nodes, PART_HEADER_BYTES),
        };
        let start = record.data_word as u64 * 4;
        if start + shortest > data_len {
            return Err(past_the_end(start, shortest, data_len));
        }
        Ok(start)
    }

    /// Validates a strip's block inside `window` (which starts at `window_start` in the
    /// section, and holds the block's [`BlockShape::extent`]); returns its real-triangle count.
    pub(super) fn check(
        &self,
        window: &[u8],
        window_start: u64,
        record: &StripRecord,
        data_len: u64,
    ) -> Result<u64, StripDefect> {
        let nodes = self.nodes(record)?;
        let start = record.data_word as u64 * 4;
        let available = &window[(start - window_start) as usize..];
        let block = self.block(available, (start, data_len), record, nodes)?;
        let triangles = count_triangles(&block.view.references, block.view.vertices.len())
            .map_err(|(position, reference)| block.reference_defect(position, reference))?;
        block.check_axes_and_boxes(nodes)?;
        Ok(triangles)
    }

    /// Validates the record's block in `data` (the whole strip-data section) as
    /// [`BlockShape::check`] does but for the triangle count, and returns its view: what a
    /// strip's first view needs, in one pass over the block.
    ///
    /// References are checked a load of them at a time ([`References::first_at_least`]), and
    /// the view is the one traversal then gets. A sound block of f32 or grid vertices is viewed
    /// once, straight from the section ([`BlockShape::sound_view`]); any other takes the checks
    /// that name its defect.
    pub(super) fn checked_view<'a>(
        &self,
        data: &'a [u8],
        record: &StripRecord,
    ) -> Result<StripView<'a>, StripDefect> {
        if let Some(view) = self.sound_view(data, record) {
            return Ok(view);
        }
        self.view_or_defect(data, record)
    }

    /// The view of a block in `data` (the strip-data section) that passes every check of
    /// [`BlockShape::view_or_defect`], viewed in place as a valid strip is: the block's
    /// bounds are those of its view's slices, so its length is not computed apart. `None` for
    /// a pooled block (whose pool is checked apart) or a defect.
    #[inline(always)]
    pub(super) fn sound_view<'a>(
        &self,
        data: &'a [u8],
        record: &StripRecord,
    ) -> Option<StripView<'a>> {
        // Axis words first: a view of words wider than the grid would shift past 32 bits.
        if matches!(self.layout, VertexLayout::Pooled { .. })
            || !self.sound_axis_words(data, record)
        {
            return None;
        }
        let nodes = self.sound_nodes(record)?;
        let parts = self.parts.lengths(record.reference_count as usize);
        let view = try_view_block(data, record, parts, &self.layout)?;
        let sound = view.references.all_below(view.vertices.len())
            && no_axis_3(view.axes, nodes)
            && sound_exponents(&view.boxes);
        sound.then_some(view)
    }

    /// Whether the axis words of a grid block that fits `data` fit the grid (true for f32
    /// vertices).
    #[inline(always)]
    fn sound_axis_words(&self, data: &[u8], record: &StripRecord) -> bool {
        let VertexLayout::Grid { grid, packed, .. } = self.layout else {
            return true;
        };
        let block = data
            .get(record.data_word as usize * 4..)
            .unwrap_or_default();
        let words = VertexLayout::axis_words(&grid, packed).read(block);
        words.iter().all(|word| word.fits(grid.bits))
    }

    /// [`BlockShape::checked_view`] with every check apart, each naming its defect.
    #[inline(never)]
    fn view_or_defect<'a>(
        &self,
        data: &'a [u8],
        record: &StripRecord,
    ) -> Result<StripView<'a>, StripDefect> {
        let nodes = self.nodes(record)?;
        let data_len = data.len() as u64;
        let start = self.reaches(record, nodes, data_len)?;
        let block = self.block(&data[start as usize..], (start, data_len), record, nodes)?;
        let vertices = block.view.vertices.len();
        if let Some(position) = block.view.references.first_at_least(vertices) {
            let reference = block.view.references.get(position);
            return Err(block.reference_defect(position, reference));
        }
        block.check_axes_and_boxes(nodes)?;
        Ok(block.view)
    }

    /// The view of the block at the start of `available` (from section offset `start` to at
    /// least the block's shortest length, and to the end of the block or of the section of
    /// `data_len` bytes), its axis words checked and its length against the section's end.
    pub(super) fn block<'a>(
        &self,
        available: &'a [u8],
        (start, data_len): (u64, u64),
        record: &StripRecord,
        nodes: usize,
    ) -> Result<CheckedBlock<'a>, StripDefect> {
        if let VertexLayout::Pooled { grid } = self.layout {
            return self.pooled_block(available, (start, data_len), record, &grid);
        }
        let vertex_bytes = match self.layout {
            VertexLayout::F32 { .. } => record.vertex_count as usize * F32_VERTEX_BYTES,
            VertexLayout::Grid { grid, packed, .. } => {
                let words_layout = VertexLayout::axis_words(&grid, packed);
                let words = words_layout.read(available);
                for (axis, word) in words.iter().enumerate() {
                    let at = (axis * words_layout.bits() / 3 / 8) as u64;
                    word.check(grid.bits)
                        .map_err(|detail| (Some(start + at), Defect::OutOfRange, detail))?;
                }
                vertex_part_bytes(record.vertex_count as usize, &words, words_layout)
            }
            VertexLayout::Pooled { .. } => PART_HEADER_BYTES,
        };
        let length = self.length(record, nodes, vertex_bytes);
        let Some(block) = available.get(..length as usize) else {
            return Err(past_the_end(start, length, data_len));
        };
        let local = StripRecord {
            data_word: 0,
            ..*record
        };
        let parts = self.parts.lengths(record.reference_count as usize);
        let view = view_block(block, &local, parts, &self.layout);
        Ok(CheckedBlock {
            view,
            end: start + length,
        })
    }
}

impl BlockShape<'_> {
    /// [`BlockShape::block`] of a pooled strip ([`crate::format::pool`]): its part, then its
    /// pool, after the part and inside `available`, with axis words inside the grid and room
    /// for the strip's vertices from its base.
    fn pooled_block<'a>(
        &self,
        available: &'a [u8],
        (start, data_len): (u64, u64),
        record: &StripRecord,
        grid: &Grid,
    ) -> Result<CheckedBlock<'a>, StripDefect> {
        let part_bytes = self.length(record, 0, PART_HEADER_BYTES);
        let part = available
            .get(..part_bytes as usize)
            .ok_or_else(|| past_the_end(start, part_bytes, data_len))?;
        let header = PartHeader::read(part).ok_or_else(|| past_the_end(start, 3, data_len))?;
        if (header.pool_distance as u64) < part_bytes {
            let detail = format!(
                "pool {} bytes on overlaps the part of {part_bytes} bytes",
                header.pool_distance
            );
            return Err((Some(start), Defect::OutOfRange, detail));
        }
        let pool_at = start + header.pool_distance as u64;
        let words_layout = AxisWordLayout::Packed {
            grid_bits: grid.bits,
        };
        let head_bytes = POOL_COUNT_BYTES + words_layout.bits().div_ceil(8);
        let pool = available
            .get(header.pool_distance..)
            .filter(|pool| pool.len() >= head_bytes)
            .ok_or_else(|| past_the_end(pool_at, head_bytes as u64, data_len))?;
        let points = pool_points(pool[0]);
        let words = words_layout.read(&pool[POOL_COUNT_BYTES..]);
        for (axis, word) in words.iter().enumerate() {
            let at = (POOL_COUNT_BYTES + axis * words_layout.bits() / 3 / 8) as u64;
            word.check(grid.bits)
                .map_err(|detail| (Some(pool_at + at), Defect::OutOfRange, detail))?;
        }
        let pool_length = pool_bytes(points, &words, words_layout);
        if pool.len() < pool_length {
            return Err(past_the_end(pool_at, pool_length as u64, data_len));
        }
        let vertices = record.vertex_count as usize;
        if header.base + vertices > points {
            let detail = format!(
                "base {} and {vertices} vertices pass the pool's {points} points",
                header.base
            );
            return Err((Some(start + 2), Defect::OutOfRange, detail));
        }
        let local = StripRecord {
            data_word: 0,
            ..*record
        };
        let parts = self.parts.lengths(record.reference_count as usize);
        let view = view_block(available, &local, parts, &self.layout);
        Ok(CheckedBlock {
            view,
            end: start + part_bytes,
        })
    }
}

/// A block whose bounds were checked, viewed in place, and where it ends in the section.
pub(super) struct CheckedBlock<'a> {
    pub(super) view: StripView<'a>,
    pub(super) end: u64,
}

impl CheckedBlock<'_> {
    /// The defect of reference `position`, which is `reference`, naming no vertex.
    pub(super) fn reference_defect(&self, position: usize, reference: u8) -> StripDefect {
        let view = &self.view;
        let vertices = view.vertices.len();
        let area_start =
            self.end - (view.boxes.stored_bytes() + view.references.stored_bytes()) as u64;
        let offset = area_start + view.references.byte_of(position) as u64;
        let detail =
            format!("reference {position} is {reference} out of range ({vertices} vertices)");
        (Some(offset), Defect::OutOfRange, detail)
    }

    /// Checks the `nodes` split axes (each 0, 1 or 2) and the box exponents.
    pub(super) fn check_axes_and_boxes(&self, nodes: usize) -> Result<(), StripDefect> {
        let view = &self.view;
        let boxes_start = self.end - view.boxes.stored_bytes() as u64;
        let references_start = boxes_start - view.references.stored_bytes() as u64;
        if let Some(node) = first_axis_3(view.axes, nodes) {
            let axes_start = references_start - view.axes.len() as u64;
            let detail = format!("node {node} has split axis 3");
            return Err((Some(axes_start), Defect::BadEncoding, detail));
        }
        let exponents = stored_exponents(&view.boxes);
        if let Some(axis) = (0..3).find(|&axis| !EXPONENTS.contains(&exponents[axis])) {
            let detail = format!(
                "block box exponent {} on axis {axis} outside {EXPONENTS:?}",
                exponents[axis]
            );
            return Err((Some(boxes_start + axis as u64), Defect::OutOfRange, detail));
        }
        Ok(())
    }
}

/// The box exponents of a block, or valid stand-ins for a block without boxes.
fn stored_exponents(boxes: &BlockBoxes) -> [u8; 3] {
    boxes.exponents().unwrap_or([*EXPONENTS.start(); 3])
}

/// Whether every box exponent of a block is in range.
#[inline(always)]
fn sound_exponents(boxes: &BlockBoxes) -> bool {
    stored_exponents(boxes)
        .iter()
        .all(|exponent| EXPONENTS.contains(exponent))
}

/// The first of the `nodes` split axes stored in `axes` (2 bits each) that is 3, four per byte.
pub(super) fn first_axis_3(axes: &[u8], nodes: usize) -> Option<usize> {
    axes.iter().enumerate().find_map(|(byte, &pairs)| {
        let in_use = nodes.saturating_sub(4 * byte).min(4);
        let threes = pairs & (pairs >> 1) & 0x55 & ((1u16 << (2 * in_use)) - 1) as u8;
        (threes != 0).then(|| 4 * byte + threes.trailing_zeros() as usize / 2)
    })
}

/// Whether none of the `nodes` split axes in `axes` (their [`axis_bytes`], as a view has them)
/// is 3: [`first_axis_3`] deciding only, inlined into a strip's first view, only the last
/// byte's unused pairs masked off.
#[inline(always)]
fn no_axis_3(axes: &[u8], nodes: usize) -> bool {
    let Some((&last, full)) = axes.split_last() else {
        return true;
    };
    let threes = |pairs: u8| pairs & (pairs >> 1) & 0x55;
    let in_last = nodes.saturating_sub(4 * full.len()).min(4);
    let used = ((1u16 << (2 * in_last)) - 1) as u8;
    let found = full.iter().fold(0, |found, &pairs| found | threes(pairs));
    found | (threes(last) & used) == 0
}

pub(super) fn past_the_end(start: u64, length: u64, data_len: u64) -> StripDefect {
    let detail = format!("block of {length} bytes runs past the section end {data_len}");
    (Some(start), Defect::Truncated, detail)
}

/// The count of real triangles among the references, or the first reference naming no vertex
/// (`>= vertices`) with its position. Read in chunks into a stack buffer, consecutive chunks
/// sharing two references so that each window is counted once: a vector per strip was 2% of a
/// 1M-ray query on the 1M scan.
pub(super) fn count_triangles(
    references: &References,
    vertices: usize,
) -> Result<u64, (usize, u8)> {
    const CHUNK: usize = 64;
    let mut chunk = [0u8; CHUNK];
    let mut triangles = 0;
    let mut first = 0;
    loop {
        let part = &mut chunk[..CHUNK.min(references.len() - first)];
        references.read_into(first, part);
        if let Some(k) = part.iter().position(|&r| r as usize >= vertices) {
            return Err((first + k, part[k]));
        }
        triangles += crate::strip_windows::triangles(part).count() as u64;
        if first + part.len() >= references.len() {
            return Ok(triangles);
        }
        first += CHUNK - 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::references::pack;

    /// The deciding check of split axes agrees with the search that names the node, for axes
    /// of one to three words, a 3 at each place, in use or not.
    #[test]
    fn axis_checks_agree() {
        for nodes in [1usize, 3, 4, 5, 31, 32, 33, 64, 70, 95] {
            let bytes = nodes.div_ceil(4);
            for place in 0..4 * bytes {
                let mut axes = vec![0b10_01_00_10u8 & 0x66; bytes];
                axes[place / 4] |= 3 << (2 * (place % 4));
                let found = first_axis_3(&axes, nodes);
                assert_eq!(found, (place < nodes).then_some(place), "{nodes} {place}");
                assert_eq!(no_axis_3(&axes, nodes), found.is_none(), "{nodes} {place}");
            }
        }
    }

    /// Chunked counting agrees with counting the whole strip at once, across chunk borders,
    /// and finds the first reference out of range.
    #[test]
    fn triangles_are_counted_once_across_chunks() {
        for count in [3usize, 4, 63, 64, 65, 66, 127, 128, 200, 301] {
            // Every fifth window a swap (a repeated reference), the rest distinct.
            let references: Vec<u8> = (0..count)
                .map(|k| {
                    if k % 5 == 4 {
                        ((k - 2) % 97) as u8
                    } else {
                        (k % 97) as u8
                    }
                })
                .collect();
            let expected = crate::strip_windows::triangles(&references).count() as u64;
            let bytes = pack(&references, 97);
            let view = References::packed(&bytes, count, 97);
            assert_eq!(
                count_triangles(&view, 97),
                Ok(expected),
                "{count} references"
            );
            let bad = count - 1;
            let limit = usize::from(references[bad]);
            let first_bad = references.iter().position(|&r| usize::from(r) >= limit);
            let found = count_triangles(&view, limit).err().map(|(k, _)| k);
            assert_eq!(found, first_bad, "{count} references, {limit} vertices");
        }
    }
}

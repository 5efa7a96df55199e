//! Validation of a file: header and section table first ([`Checker`]), then either every
//! top-level node, strip record and block through bounded windows of the file ([`Windows`]), or
//! one strip or node at a time on first use ([`check_strip`], [`check_node`]), so that every
//! view in [`super`] stays in bounds.

use std::fs::File;
use std::mem::size_of;
use std::ops::Range;
use std::path::Path;

use memmap2::Mmap;
use rayon::prelude::*;

use super::super::block_boxes::EXPONENTS;
use super::super::grid::{Grid, NodeGrid, MAX_GRID_BITS};
use super::super::quantized::{vertex_part_bytes, AxisWord};
use super::super::references::References;
use super::super::{
    axis_bytes, GridNode, Header, NodeLimits, NodeRecord, PrecisionRecord, SectionKind,
    StripRecord, TopNode, TopSlot, VertexEncoding, ENDIAN_MARKER, F32_VERTEX_BYTES,
    HEADER_CHECKSUMMED_BYTES, HEADER_PAGE, MAGIC, MAX_STRIP_VERTICES, MAX_TOP_DEPTH,
    OLDEST_READ_MAJOR, PRECISION_CHECKSUMMED_BYTES, PRECISION_OFFSET, SECTION_ALIGN, TOP_WIDTH,
    VERSION_MAJOR,
};
use super::lazy::{LazyChecks, Passed};
use super::{
    section_slot, view_block, FormatError, PartTable, ReducemFile, StripView, Validation,
    VertexLayout, EAGER_VALIDATION_BYTES,
};
use crate::mapping::{map_file, map_range};

/// Maps and validates the file at `path` as `validation` says, or by its size when `None`
/// ([`ReducemFile::open`]).
pub(super) fn open(
    path: &Path,
    validation: Option<Validation>,
) -> Result<ReducemFile, FormatError> {
    let io_error = |source| FormatError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io_error)?;
    let file_len = file.metadata().map_err(io_error)?.len();
    let head = match file_len >= HEADER_PAGE {
        true => Some(map_range(&file, 0, HEADER_PAGE as usize).map_err(io_error)?),
        false => None,
    };
    let checker = Checker {
        path,
        head: head.as_deref().unwrap_or_default(),
        file_len,
    };
    let header = checker.header()?;
    let precision = checker.precision(&header)?;
    let (layout, node_grid) = checker.layout(&header, &precision)?;
    let sections = checker.sections(&header, node_bytes(node_grid.is_some()))?;
    let core_end = sections[section_slot(SectionKind::StripData)].end as u64;
    let attributes = super::attributes::read_record(checker.head, &header, core_end, file_len)
        .map_err(|(offset, detail)| checker.invalid("header", offset, detail))?;
    let model = crate::format::model::read_record(checker.head, &header)
        .map_err(|(offset, detail)| checker.invalid("header", offset, detail))?;
    let map = map_file(&file).map_err(io_error)?;
    if map.len() as u64 != file_len {
        let detail = "the file changed size while it was being opened".to_string();
        return Err(checker.invalid("file", 0, detail));
    }
    let validation = validation.unwrap_or(match file_len <= EAGER_VALIDATION_BYTES {
        true => Validation::Full,
        false => Validation::Lazy,
    });
    let checks = match validation {
        Validation::Full => LazyChecks::new(Passed::all(), Passed::all()),
        Validation::Lazy => {
            let node_section = &sections[section_slot(SectionKind::TopNodes)];
            let nodes = node_section.len() as u64 / node_bytes(node_grid.is_some());
            LazyChecks::new(Passed::none_of(header.strip_count), Passed::none_of(nodes))
        }
    };
    let opened = ReducemFile {
        path: path.to_path_buf(),
        file,
        map,
        header,
        precision,
        layout,
        node_grid,
        sections,
        attributes,
        model,
        checks,
        parts: PartTable::new(header.leaf_windows as usize, layout.boxes()),
    };
    let windows = Windows { opened: &opened };
    windows.check_strip_count()?;
    if validation == Validation::Full {
        windows.validate_strips()?;
        windows.validate_nodes()?;
        opened.validate_attributes()?;
    }
    Ok(opened)
}

/// Validates every strip and node of an opened file ([`ReducemFile::validate_all`]).
pub(super) fn validate_all(opened: &ReducemFile) -> Result<(), FormatError> {
    let windows = Windows { opened };
    windows.validate_strips()?;
    windows.validate_nodes()?;
    opened.validate_attributes()
}

/// Validates node `index` of a lazily opened file alone ([`TreeCheck::check`] without the
/// bookkeeping across nodes).
pub(super) fn check_node(opened: &ReducemFile, index: usize) -> Result<(), FormatError> {
    match opened.node_grid {
        None => check_node_of::<TopNode>(opened, index),
        Some(_) => check_node_of::<GridNode>(opened, index),
    }
}

/// [`NodeRecord::passes_alone`] first; [`TreeCheck::check`], slot by slot, only to word the
/// defect of a node that fails it.
fn check_node_of<N: NodeRecord>(opened: &ReducemFile, index: usize) -> Result<(), FormatError> {
    let nodes: &[N] = bytemuck::cast_slice(opened.section_bytes(SectionKind::TopNodes));
    let limits = NodeLimits {
        nodes: nodes.len(),
        strips: opened.header.strip_count,
        empty_root: index == 0 && opened.header.strip_count == 0,
    };
    if nodes
        .get(index)
        .is_some_and(|node| node.passes_alone(index, limits))
    {
        return Ok(());
    }
    let mut tree = TreeCheck::alone(opened, nodes.len(), size_of::<N>() as u64);
    match nodes.get(index) {
        Some(node) => tree.check(index, node),
        None => {
            let detail = format!("node {index} outside 0..{}", nodes.len());
            Err(tree.fail(0, 0, detail))
        }
    }
}

/// Validates strip `index` of a lazily opened file in the mapping, as [`Windows::validate_strips`]
/// does but for the triangle count (its record, its block's bounds, reference indices, split
/// axes and box exponents), and returns its view.
///
/// The defect is boxed: a result as large as the view and the error side by side cost a copy
/// through `memcpy` and more moves of the view on every first view (33 instructions of 648,
/// callgrind, 1M primary rays on the 1M scan).
pub(super) fn check_strip(
    opened: &ReducemFile,
    index: usize,
) -> Result<StripView<'_>, Box<FormatError>> {
    let Some(record) = opened.strip_records().get(index) else {
        let strips = opened.strip_count();
        let detail = format!("strip {index} outside 0..{strips}");
        return Err(Box::new(opened.invalid(
            "strip_records",
            opened.section_offset(SectionKind::StripRecords),
            detail,
        )));
    };
    let shape = BlockShape {
        parts: &opened.parts,
        layout: opened.layout,
    };
    shape
        .checked_view(opened.section_bytes(SectionKind::StripData), record)
        .map_err(|defect| Box::new(strip_error(opened, index, defect)))
}

/// Bytes of the file mapped at a time while validating.
pub const VALIDATION_WINDOW: usize = 64 << 20;

/// Validation of the sections through bounded windows of the file.
struct Windows<'a> {
    opened: &'a ReducemFile,
}

impl Windows<'_> {
    fn map(&self, offset: u64, length: usize) -> Result<Mmap, FormatError> {
        map_range(&self.opened.file, offset, length).map_err(|source| FormatError::Io {
            path: self.opened.path.clone(),
            source,
        })
    }

    fn section(&self, kind: SectionKind) -> Range<u64> {
        let range = &self.opened.sections[section_slot(kind)];
        range.start as u64..range.end as u64
    }

    /// Checks that the record section holds as many records as the header says strips.
    fn check_strip_count(&self) -> Result<(), FormatError> {
        let opened = self.opened;
        let records = self.section(SectionKind::StripRecords);
        let count = (records.end - records.start) / RECORD_BYTES;
        if count != opened.header.strip_count {
            return Err(opened.invalid(
                "strip_records",
                records.start,
                format!(
                    "{count} records, header says {} strips",
                    opened.header.strip_count
                ),
            ));
        }
        Ok(())
    }

    /// Checks every strip record, its block bounds, reference indices and split axes, and that
    /// the real triangles add up to the header's count.
    fn validate_strips(&self) -> Result<(), FormatError> {
        let opened = self.opened;
        let records = self.section(SectionKind::StripRecords);
        let count = opened.header.strip_count;
        let batch = (VALIDATION_WINDOW as u64 / RECORD_BYTES).max(1);
        let mut triangles = 0;
        for first in (0..count).step_by(batch as usize) {
            let length = batch.min(count - first) * RECORD_BYTES;
            let window = self.map(records.start + first * RECORD_BYTES, length as usize)?;
            let records: &[StripRecord] = bytemuck::try_cast_slice(&window)
                .map_err(|_| opened.invalid("strip_records", records.start, "misaligned".into()))?;
            triangles += self.validate_record_batch(first as usize, records)?;
        }
        if triangles != opened.header.triangle_count {
            return Err(opened.invalid(
                "header",
                32,
                format!(
                    "{triangles} triangles in strips, header says {}",
                    opened.header.triangle_count
                ),
            ));
        }
        Ok(())
    }

    /// Validates consecutive records, mapping their blocks in spans of at most one window.
    fn validate_record_batch(
        &self,
        first: usize,
        records: &[StripRecord],
    ) -> Result<u64, FormatError> {
        let data = self.section(SectionKind::StripData);
        let data_len = data.end - data.start;
        let shape = BlockShape {
            parts: &self.opened.parts,
            layout: self.opened.layout,
        };
        let mut triangles = 0;
        let mut start = 0;
        while start < records.len() {
            let mut span = shape
                .extent(&records[start], data_len)
                .map_err(|defect| strip_error(self.opened, first + start, defect))?;
            let mut end = start + 1;
            while let Some(next) = records.get(end) {
                let Ok(block) = shape.extent(next, data_len) else {
                    break;
                };
                let joined = span.start.min(block.start)..span.end.max(block.end);
                if joined.end - joined.start > VALIDATION_WINDOW as u64 {
                    break;
                }
                span = joined;
                end += 1;
            }
            let window = self.map(data.start + span.start, (span.end - span.start) as usize)?;
            triangles += records[start..end]
                .par_iter()
                .enumerate()
                .map(|(i, record)| {
                    shape
                        .check(&window, span.start, record, data_len)
                        .map_err(|defect| strip_error(self.opened, first + start + i, defect))
                })
                .try_reduce(|| 0u64, |a, b| Ok(a + b))?;
            start = end;
        }
        Ok(triangles)
    }

    /// Checks that the nodes form one tree in preorder within the depth limit, with every slot
    /// well formed and leaf strip ranges inside the record array; every node but the root has
    /// exactly one parent, before it in the array, so traversal terminates and indexes nothing
    /// out of bounds.
    fn validate_nodes(&self) -> Result<(), FormatError> {
        match self.opened.node_grid {
            None => self.validate_nodes_of::<TopNode>(),
            Some(_) => self.validate_nodes_of::<GridNode>(),
        }
    }

    fn validate_nodes_of<N: NodeRecord>(&self) -> Result<(), FormatError> {
        let section = self.section(SectionKind::TopNodes);
        let node_bytes = size_of::<N>() as u64;
        let count = ((section.end - section.start) / node_bytes) as usize;
        let mut tree = TreeCheck {
            opened: self.opened,
            node_bytes,
            nodes: count,
            depth: vec![u8::MAX; count],
            leaf_strips: 0,
        };
        tree.depth[0] = 0;
        let batch = (VALIDATION_WINDOW as u64 / node_bytes).max(1) as usize;
        for first in (0..count).step_by(batch) {
            let length = batch.min(count - first) as u64 * node_bytes;
            let window = self.map(section.start + first as u64 * node_bytes, length as usize)?;
            let nodes: &[N] = bytemuck::try_cast_slice(&window).map_err(|_| {
                self.opened
                    .invalid("top_nodes", section.start, "misaligned".into())
            })?;
            for (i, node) in nodes.iter().enumerate() {
                tree.check(first + i, node)?;
            }
        }
        tree.finish()
    }
}

const RECORD_BYTES: u64 = std::mem::size_of::<StripRecord>() as u64;

/// The error for a defect in strip `index`: at the record when the defect has no data offset.
fn strip_error(opened: &ReducemFile, index: usize, (offset, detail): StripDefect) -> FormatError {
    let offset = offset.map_or(
        opened.section_offset(SectionKind::StripRecords) + index as u64 * RECORD_BYTES,
        |o| opened.section_offset(SectionKind::StripData) + o,
    );
    opened.invalid("strip_data", offset, format!("strip {index}: {detail}"))
}

/// Bytes of one top-level node record: [`GridNode`] with a node grid, else [`TopNode`].
fn node_bytes(grid_nodes: bool) -> u64 {
    match grid_nodes {
        true => size_of::<GridNode>() as u64,
        false => size_of::<TopNode>() as u64,
    }
}

/// The node checks of [`Windows::validate_nodes`], with its one-parent, depth and strip-count
/// bookkeeping, or of [`check_node`] without it.
struct TreeCheck<'a> {
    opened: &'a ReducemFile,
    node_bytes: u64,
    nodes: usize,
    /// Each node's depth, `u8::MAX` before its parent is seen; empty when checking a node
    /// alone.
    depth: Vec<u8>,
    /// Strips over all leaves so far.
    leaf_strips: u64,
}

impl TreeCheck<'_> {
    /// The checks of one node that need no other node, among `nodes` nodes of `node_bytes`.
    fn alone(opened: &ReducemFile, nodes: usize, node_bytes: u64) -> TreeCheck<'_> {
        TreeCheck {
            opened,
            node_bytes,
            nodes,
            depth: Vec::new(),
            leaf_strips: 0,
        }
    }

    fn fail(&self, index: usize, field: u64, detail: String) -> FormatError {
        self.opened.invalid(
            "top_nodes",
            self.opened.section_offset(SectionKind::TopNodes)
                + index as u64 * self.node_bytes
                + field,
            format!("node {index}: {detail}"),
        )
    }

    fn check<N: NodeRecord>(&mut self, index: usize, node: &N) -> Result<(), FormatError> {
        if self.depth.get(index) == Some(&u8::MAX) {
            return Err(self.fail(index, 0, "has no parent".into()));
        }
        let occupied = node.occupied();
        let empty_model = index == 0 && self.opened.header.strip_count == 0;
        if occupied == 0 && !empty_model {
            return Err(self.fail(index, N::KIND_FIELD, "has no children".into()));
        }
        for slot in 0..TOP_WIDTH {
            self.check_slot(index, node, slot, slot >= occupied)?;
        }
        Ok(())
    }

    fn check_slot<N: NodeRecord>(
        &mut self,
        index: usize,
        node: &N,
        slot: usize,
        empty: bool,
    ) -> Result<(), FormatError> {
        let child_field = N::CHILD_FIELD + N::LINK_STRIDE * slot as u64;
        let kind_field = N::KIND_FIELD + N::LINK_STRIDE * slot as u64;
        if empty {
            if !node.is_exactly_empty(slot) {
                let detail = format!(
                    "slot {slot} follows an empty slot but is not the exact empty slot ({})",
                    N::EMPTY_SLOT
                );
                return Err(self.fail(index, kind_field, detail));
            }
            return Ok(());
        }
        if let Some((axis, field)) = node.inverted_axis(slot) {
            let detail = format!("slot {slot}: box minimum above its maximum on axis {axis}");
            return Err(self.fail(index, field, detail));
        }
        match node.slot(slot) {
            TopSlot::Internal(child) => self.adopt(index, slot, child as usize, child_field),
            TopSlot::Leaf { first, count } => {
                let strips = self.opened.header.strip_count;
                let end = first as u64 + count as u64;
                if end > strips {
                    let detail = format!("slot {slot}: strips {first}..{end} outside 0..{strips}");
                    return Err(self.fail(index, child_field, detail));
                }
                self.leaf_strips += count as u64;
                Ok(())
            }
            TopSlot::Invalid(kind) => Err(self.fail(
                index,
                kind_field,
                format!("slot {slot}: kind {kind:#x} is neither internal nor a strip count"),
            )),
            TopSlot::Empty => unreachable!("occupied slots come before the first empty one"),
        }
    }

    /// Records node `child` as the child of node `index` in `slot`.
    fn adopt(
        &mut self,
        index: usize,
        slot: usize,
        child: usize,
        field: u64,
    ) -> Result<(), FormatError> {
        let nodes = self.nodes;
        if child <= index || child >= nodes {
            let detail = format!("slot {slot}: child {child} outside {}..{nodes}", index + 1);
            return Err(self.fail(index, field, detail));
        }
        if self.depth.is_empty() {
            return Ok(());
        }
        let child_depth = self.depth[index] + 1;
        if child_depth as usize > MAX_TOP_DEPTH {
            return Err(self.fail(index, field, format!("deeper than {MAX_TOP_DEPTH} levels")));
        }
        if self.depth[child] != u8::MAX {
            let detail = format!("slot {slot}: child {child} has a second parent");
            return Err(self.fail(index, field, detail));
        }
        self.depth[child] = child_depth;
        Ok(())
    }

    /// The leaves must hold as many strips as the file has: every strip is reachable.
    fn finish(&self) -> Result<(), FormatError> {
        let strips = self.opened.header.strip_count;
        if self.leaf_strips != strips {
            let detail = format!(
                "leaves hold {} strips, the file has {strips}",
                self.leaf_strips
            );
            return Err(self.fail(0, 0, detail));
        }
        Ok(())
    }
}

/// A defect in a strip: the data-section offset where it is (if known) and what is wrong.
type StripDefect = (Option<u64>, String);

/// What a strip block's length depends on besides its record.
struct BlockShape<'a> {
    /// The file's node counts and part lengths by reference count.
    parts: &'a PartTable,
    layout: VertexLayout,
}

impl BlockShape<'_> {
    /// Checks a record's counts and returns its kd-tree's internal node count.
    fn nodes(&self, record: &StripRecord) -> Result<usize, StripDefect> {
        let vertices = record.vertex_count as usize;
        let references = record.reference_count as usize;
        if !(3..=MAX_STRIP_VERTICES).contains(&vertices) || references < 3 {
            return Err((
                None,
                format!("{vertices} vertices and {references} references"),
            ));
        }
        let nodes = self.parts.nodes(references);
        if 2 * nodes > vertices {
            let detail = format!(
                "{nodes} kd-tree nodes need {} bound vertices, it has {vertices}",
                2 * nodes
            );
            return Err((None, detail));
        }
        Ok(nodes)
    }

    /// Bytes of the block with vertices of `vertex_bytes`.
    fn length(&self, record: &StripRecord, nodes: usize, vertex_bytes: usize) -> u64 {
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
    fn extent(&self, record: &StripRecord, data_len: u64) -> Result<Range<u64>, StripDefect> {
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
        };
        let start = self.reaches(record, nodes, data_len)?;
        Ok(start..(start + longest).min(data_len))
    }

    /// The block's start in the section, once its shortest possible length (its exact length
    /// for f32 vertices, its axis words for grid vertices) is known to fit the section.
    fn reaches(
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
        };
        let start = record.data_word as u64 * 4;
        if start + shortest > data_len {
            return Err(past_the_end(start, shortest, data_len));
        }
        Ok(start)
    }

    /// Validates a strip's block inside `window` (which starts at `window_start` in the
    /// section, and holds the block's [`BlockShape::extent`]); returns its real-triangle count.
    fn check(
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
    /// the view is the one traversal then gets: at 1,388 instructions per first view before
    /// (callgrind, 1M primary rays on the 1M scan, 41,583 first views), the triangle count
    /// and the block's second view were a third of it.
    fn checked_view<'a>(
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
    fn block<'a>(
        &self,
        available: &'a [u8],
        (start, data_len): (u64, u64),
        record: &StripRecord,
        nodes: usize,
    ) -> Result<CheckedBlock<'a>, StripDefect> {
        let vertex_bytes = match self.layout {
            VertexLayout::F32 { .. } => record.vertex_count as usize * F32_VERTEX_BYTES,
            VertexLayout::Grid { grid, packed, .. } => {
                let words_layout = VertexLayout::axis_words(&grid, packed);
                let words = words_layout.read(available);
                for (axis, word) in words.iter().enumerate() {
                    let at = (axis * words_layout.bits() / 3 / 8) as u64;
                    word.check(grid.bits)
                        .map_err(|detail| (Some(start + at), detail))?;
                }
                vertex_part_bytes(record.vertex_count as usize, &words, words_layout)
            }
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

/// A block whose bounds were checked, viewed in place, and where it ends in the section.
struct CheckedBlock<'a> {
    view: StripView<'a>,
    end: u64,
}

impl CheckedBlock<'_> {
    /// The defect of reference `position`, which is `reference`, naming no vertex.
    fn reference_defect(&self, position: usize, reference: u8) -> StripDefect {
        let view = &self.view;
        let vertices = view.vertices.len();
        let area_start =
            self.end - (view.boxes.stored_bytes() + view.references.stored_bytes()) as u64;
        let offset = area_start + view.references.byte_of(position) as u64;
        let detail =
            format!("reference {position} is {reference} out of range ({vertices} vertices)");
        (Some(offset), detail)
    }

    /// Checks the `nodes` split axes (each 0, 1 or 2) and the box exponents.
    fn check_axes_and_boxes(&self, nodes: usize) -> Result<(), StripDefect> {
        let view = &self.view;
        let boxes_start = self.end - view.boxes.stored_bytes() as u64;
        let references_start = boxes_start - view.references.stored_bytes() as u64;
        if let Some(node) = first_axis_3(view.axes, nodes) {
            let axes_start = references_start - view.axes.len() as u64;
            return Err((Some(axes_start), format!("node {node} has split axis 3")));
        }
        let exponents = view
            .boxes
            .exponents()
            .unwrap_or([EXPONENTS.start().to_owned(); 3]);
        if let Some(axis) = (0..3).find(|&axis| !EXPONENTS.contains(&exponents[axis])) {
            let detail = format!(
                "block box exponent {} on axis {axis} outside {EXPONENTS:?}",
                exponents[axis]
            );
            return Err((Some(boxes_start + axis as u64), detail));
        }
        Ok(())
    }
}

/// The first of the `nodes` split axes stored in `axes` (2 bits each) that is 3, four per byte.
fn first_axis_3(axes: &[u8], nodes: usize) -> Option<usize> {
    axes.iter().enumerate().find_map(|(byte, &pairs)| {
        let in_use = nodes.saturating_sub(4 * byte).min(4);
        let threes = pairs & (pairs >> 1) & 0x55 & ((1u16 << (2 * in_use)) - 1) as u8;
        (threes != 0).then(|| 4 * byte + threes.trailing_zeros() as usize / 2)
    })
}

fn past_the_end(start: u64, length: u64, data_len: u64) -> StripDefect {
    let detail = format!("block of {length} bytes runs past the section end {data_len}");
    (Some(start), detail)
}

/// The count of real triangles among the references, or the first reference naming no vertex
/// (`>= vertices`) with its position. Read in chunks into a stack buffer, consecutive chunks
/// sharing two references so that each window is counted once: a vector per strip was 2% of a
/// 1M-ray query on the 1M scan.
fn count_triangles(references: &References, vertices: usize) -> Result<u64, (usize, u8)> {
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

/// Header and section-table checks, before anything else is trusted.
struct Checker<'a> {
    path: &'a Path,
    /// The first page of the file (all of it when shorter).
    head: &'a [u8],
    file_len: u64,
}

impl Checker<'_> {
    fn invalid(&self, section: &'static str, offset: u64, detail: String) -> FormatError {
        FormatError::Invalid {
            path: self.path.to_path_buf(),
            section,
            offset,
            detail,
        }
    }

    fn header(&self) -> Result<Header, FormatError> {
        if self.file_len < HEADER_PAGE {
            let detail = format!(
                "file is {} bytes, the header page alone is {HEADER_PAGE}",
                self.file_len
            );
            return Err(self.invalid("header", 0, detail));
        }
        let header: Header = bytemuck::pod_read_unaligned(&self.head[..size_of::<Header>()]);
        if header.magic != MAGIC {
            return Err(self.invalid("header", 0, "not a ReduceM file (bad magic)".into()));
        }
        if header.endian_marker != ENDIAN_MARKER {
            let detail = format!(
                "endianness marker {:#010x}: written on or read on a big-endian host",
                header.endian_marker
            );
            return Err(self.invalid("header", 12, detail));
        }
        if !(OLDEST_READ_MAJOR..=VERSION_MAJOR).contains(&header.version_major) {
            let advice = if header.version_major < OLDEST_READ_MAJOR {
                "an older format (version 1 had binary top-level nodes): convert the mesh again"
            } else {
                "a newer format: use a newer reducem"
            };
            let detail = format!(
                "format version {}.{}, this reader reads {OLDEST_READ_MAJOR}.x to \
                 {VERSION_MAJOR}.x; {advice}",
                header.version_major, header.version_minor
            );
            return Err(self.invalid("header", 8, detail));
        }
        let checksum = xxhash_rust::xxh3::xxh3_64(&self.head[..HEADER_CHECKSUMMED_BYTES]);
        if checksum != header.header_checksum || header.header_bytes as usize != size_of::<Header>()
        {
            return Err(self.invalid(
                "header",
                HEADER_CHECKSUMMED_BYTES as u64,
                "header checksum mismatch".into(),
            ));
        }
        if !(1..=255).contains(&header.leaf_windows) {
            return Err(self.invalid(
                "header",
                24,
                format!("leaf size {} outside 1..=255", header.leaf_windows),
            ));
        }
        Ok(header)
    }

    /// The precision record of a format 2.1 file, checksum checked; zeros for 2.0.
    fn precision(&self, header: &Header) -> Result<PrecisionRecord, FormatError> {
        if !header.has_precision_record() {
            return Ok(PrecisionRecord::default());
        }
        let bytes = &self.head[PRECISION_OFFSET..PRECISION_OFFSET + size_of::<PrecisionRecord>()];
        let record: PrecisionRecord = bytemuck::pod_read_unaligned(bytes);
        if record.computed_checksum() != record.checksum {
            return Err(self.invalid(
                "header",
                (PRECISION_OFFSET + PRECISION_CHECKSUMMED_BYTES) as u64,
                "precision record checksum mismatch".into(),
            ));
        }
        Ok(record)
    }

    /// The vertex layout the header and precision record describe, checked: a grid has 1 to 24
    /// bits, a power-of-two cell and finite corners, so that every grid point decodes to a
    /// finite position; f32 vertices have no grid.
    fn layout(
        &self,
        header: &Header,
        precision: &PrecisionRecord,
    ) -> Result<(VertexLayout, Option<NodeGrid>), FormatError> {
        let at = |field: usize| (PRECISION_OFFSET + field) as u64;
        let Some(encoding) = VertexEncoding::from_u32(header.vertex_encoding) else {
            return Err(self.invalid(
                "header",
                20,
                format!("unknown vertex encoding {}", header.vertex_encoding),
            ));
        };
        if header.version_major == 2 && header.version_minor < encoding.minor() {
            let detail = format!(
                "vertex encoding {} needs format 2.{} or later",
                header.vertex_encoding,
                encoding.minor()
            );
            return Err(self.invalid("header", 20, detail));
        }
        let boxes = header.has_block_boxes();
        if boxes && matches!(encoding, VertexEncoding::Grid | VertexEncoding::GridNodes) {
            let detail = format!(
                "vertex encoding {} (unpacked grid blocks) is not part of format 3",
                header.vertex_encoding
            );
            return Err(self.invalid("header", 20, detail));
        }
        if !encoding.has_grid_nodes() && precision.node_shift != 0 {
            let detail = format!(
                "node shift {} without grid top-level nodes",
                precision.node_shift
            );
            return Err(self.invalid("header", at(4), detail));
        }
        match encoding {
            VertexEncoding::F32 if precision.grid_bits != 0 => Err(self.invalid(
                "header",
                at(0),
                format!("f32 vertices with a {}-bit grid", precision.grid_bits),
            )),
            VertexEncoding::F32 => Ok((VertexLayout::F32 { boxes }, None)),
            VertexEncoding::F32GridNodes => Ok((
                VertexLayout::F32 { boxes },
                Some(self.lossless_node_grid(precision)?),
            )),
            _ => {
                let grid = precision.grid();
                if !(1..=MAX_GRID_BITS).contains(&grid.bits) {
                    let detail = format!("grid of {} bits outside 1..={MAX_GRID_BITS}", grid.bits);
                    return Err(self.invalid("header", at(0), detail));
                }
                if !is_power_of_two(grid.cell) {
                    let detail = format!("grid cell {} is not a power of two", grid.cell);
                    return Err(self.invalid("header", at(20), detail));
                }
                let far = grid.far_corner();
                if !grid.origin.iter().chain(&far).all(|c| c.is_finite()) {
                    let detail = format!(
                        "grid from {:?} in steps of {} is not finite",
                        grid.origin, grid.cell
                    );
                    return Err(self.invalid("header", at(8), detail));
                }
                let node_grid = if encoding.has_grid_nodes() {
                    let shift = precision.node_shift;
                    let node_grid = NodeGrid::new(&grid, shift).ok_or_else(|| {
                        let detail =
                            format!("node grid of cell {} * 2^{shift} is not finite", grid.cell);
                        self.invalid("header", at(4), detail)
                    })?;
                    Some(node_grid)
                } else {
                    None
                };
                let packed = encoding == VertexEncoding::GridPackedReferences;
                let layout = VertexLayout::Grid {
                    grid,
                    packed,
                    boxes,
                };
                Ok((layout, node_grid))
            }
        }
    }

    /// The node grid of a lossless file with grid nodes (vertex encoding 4): its origin and
    /// cell in the precision record's grid fields, checked as a grid's, with no vertex grid
    /// (`grid_bits` 0) and no shift.
    fn lossless_node_grid(&self, precision: &PrecisionRecord) -> Result<NodeGrid, FormatError> {
        let at = |field: usize| (PRECISION_OFFSET + field) as u64;
        if precision.grid_bits != 0 {
            let detail = format!("f32 vertices with a {}-bit grid", precision.grid_bits);
            return Err(self.invalid("header", at(0), detail));
        }
        if precision.node_shift != 0 {
            let detail = format!("node shift {} in a lossless file", precision.node_shift);
            return Err(self.invalid("header", at(4), detail));
        }
        let base = Grid {
            bits: 0,
            origin: precision.grid_origin,
            cell: precision.grid_cell,
        };
        if !is_power_of_two(base.cell) {
            let detail = format!("node grid cell {} is not a power of two", base.cell);
            return Err(self.invalid("header", at(20), detail));
        }
        NodeGrid::new(&base, 0)
            .filter(|node| node.origin.iter().all(|c| c.is_finite()))
            .ok_or_else(|| {
                let detail = format!(
                    "node grid from {:?} in steps of {} is not finite",
                    base.origin, base.cell
                );
                self.invalid("header", at(8), detail)
            })
    }

    /// The section ranges, checked; `node_bytes` is the top-level node record's size.
    fn sections(&self, header: &Header, node_bytes: u64) -> Result<[Range<usize>; 3], FormatError> {
        let mut previous_end = HEADER_PAGE;
        let mut ranges = [0..0, 0..0, 0..0];
        for (slot, kind) in SectionKind::ALL.into_iter().enumerate() {
            let entry = &header.sections[slot];
            let table_offset = 104 + slot as u64 * 32;
            let end = entry.offset.saturating_add(entry.length);
            let record = match kind {
                SectionKind::TopNodes => node_bytes,
                SectionKind::StripRecords => RECORD_BYTES,
                SectionKind::StripData => 4,
            };
            let detail = if entry.kind != kind as u32 {
                Some(format!(
                    "section {slot} has kind {}, expected {}",
                    entry.kind, kind as u32
                ))
            } else if !entry.offset.is_multiple_of(SECTION_ALIGN) || entry.offset < previous_end {
                Some(format!(
                    "{} offset {} is unaligned or overlaps",
                    kind.name(),
                    entry.offset
                ))
            } else if end > self.file_len {
                Some(format!(
                    "{} ends at {end}, past the file end {}",
                    kind.name(),
                    self.file_len
                ))
            } else if !entry.length.is_multiple_of(record)
                || (kind == SectionKind::TopNodes && entry.length == 0)
            {
                Some(format!(
                    "{} length {} is not a positive multiple of {record}",
                    kind.name(),
                    entry.length
                ))
            } else {
                None
            };
            if let Some(detail) = detail {
                return Err(self.invalid("section table", table_offset, detail));
            }
            ranges[slot] = entry.offset as usize..end as usize;
            previous_end = end;
        }
        Ok(ranges)
    }
}

/// Whether `cell` is a positive normal power of two (grid cells are, so that `q * cell` is
/// exact).
fn is_power_of_two(cell: f32) -> bool {
    cell.is_normal() && cell > 0.0 && cell.to_bits() & 0x007f_ffff == 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::references::pack;

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

//! Validation of a file: header and section table first ([`Checker`]), then either every
//! top-level node, strip record and block through bounded windows of the file ([`Windows`]), or
//! one strip or node at a time on first use ([`check_strip`], [`check_node`]), so that every
//! view in [`super`] stays in bounds.

mod header;
mod nodes;
mod strips;

use std::fs::File;
use std::mem::size_of;
use std::ops::Range;
use std::path::Path;

use memmap2::Mmap;
use rayon::prelude::*;

use super::super::{
    Defect, FilePart, GridNode, NodeLimits, NodeRecord, SectionKind, StripRecord, TopNode,
    WideNode, HEADER_PAGE,
};
use super::lazy::{LazyChecks, Passed};
use super::{
    section_slot, FormatError, NodeLayout, PartTable, ReducemFile, StripView, Validation,
    EAGER_VALIDATION_BYTES, NO_TREE,
};
use crate::mapping::{advise_default_reads, map_file, map_range};
use header::Checker;
use nodes::{node_bytes, TreeCheck};
use strips::{strip_error, BlockShape, RECORD_BYTES};

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
    let (layout, nodes) = checker.layout(&header, &precision)?;
    let sections = checker.sections(&header, node_bytes(&nodes))?;
    let core_end = sections[section_slot(SectionKind::StripData)].end as u64;
    let attributes = super::attributes::read_record(checker.head, &header, core_end, file_len)
        .map_err(|(offset, defect, detail)| {
            checker.invalid(FilePart::Header, offset, defect, detail)
        })?;
    let model = crate::format::model::read_record(checker.head, &header).map_err(
        |(offset, defect, detail)| checker.invalid(FilePart::Header, offset, defect, detail),
    )?;
    let map = map_file(&file).map_err(io_error)?;
    if map.len() as u64 != file_len {
        let detail = "the file changed size while it was being opened".to_string();
        return Err(checker.invalid(FilePart::File, 0, Defect::ChangedWhileMapped, detail));
    }
    advise_default_reads(&map);
    let validation = validation.unwrap_or(match file_len <= EAGER_VALIDATION_BYTES {
        true => Validation::Full,
        false => Validation::Lazy,
    });
    let checks = match validation {
        Validation::Full => LazyChecks::new(Passed::all(), Passed::all()),
        Validation::Lazy => {
            let node_section = &sections[section_slot(SectionKind::TopNodes)];
            let node_count = node_section.len() as u64 / node_bytes(&nodes);
            LazyChecks::new(
                Passed::none_of(header.strip_count),
                Passed::none_of(node_count),
            )
        }
    };
    let opened = ReducemFile {
        path: path.to_path_buf(),
        file,
        map,
        header,
        precision,
        layout,
        nodes,
        sections,
        attributes,
        model,
        checks,
        parts: match layout.kd_trees() {
            true => PartTable::new(header.leaf_windows as usize, layout.boxes()),
            false => PartTable::new(NO_TREE, true),
        },
        scattered: Default::default(),
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
    match opened.nodes {
        NodeLayout::F32 => check_node_of::<TopNode>(opened, index),
        NodeLayout::Grid(_) => check_node_of::<GridNode>(opened, index),
        NodeLayout::Wide => check_node_of::<WideNode>(opened, index),
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
            Err(tree.fail(0, 0, Defect::OutOfRange, detail))
        }
    }
}

/// The view of strip `index` of a lazily opened file when it passes every check of
/// [`check_strip`], else `None` (also for a pooled strip, left to [`check_strip`]): the
/// checks decide without naming a defect, so that a sound strip's first view costs little more
/// than a view.
#[inline(always)]
pub(super) fn sound_strip(opened: &ReducemFile, index: usize) -> Option<StripView<'_>> {
    let record = opened.record(index)?;
    let shape = BlockShape {
        parts: &opened.parts,
        layout: opened.layout,
    };
    shape.sound_view(opened.section_bytes(SectionKind::StripData), &record)
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
            FilePart::Section(SectionKind::StripRecords),
            opened.section_offset(SectionKind::StripRecords),
            Defect::OutOfRange,
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
                FilePart::Section(SectionKind::StripRecords),
                records.start,
                Defect::CountMismatch,
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
            let records: &[StripRecord] = bytemuck::try_cast_slice(&window).map_err(|_| {
                opened.invalid(
                    FilePart::Section(SectionKind::StripRecords),
                    records.start,
                    Defect::Misaligned,
                    "misaligned".into(),
                )
            })?;
            triangles += self.validate_record_batch(first as usize, records)?;
        }
        if triangles != opened.header.triangle_count {
            return Err(opened.invalid(
                FilePart::Header,
                32,
                Defect::CountMismatch,
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
        match self.opened.nodes {
            NodeLayout::F32 => self.validate_nodes_of::<TopNode>(),
            NodeLayout::Grid(_) => self.validate_nodes_of::<GridNode>(),
            NodeLayout::Wide => self.validate_nodes_of::<WideNode>(),
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
                self.opened.invalid(
                    FilePart::Section(SectionKind::TopNodes),
                    section.start,
                    Defect::Misaligned,
                    "misaligned".into(),
                )
            })?;
            for (i, node) in nodes.iter().enumerate() {
                tree.check(first + i, node)?;
            }
        }
        tree.finish()
    }
}

//! Opens a ReduceM file by mapping it and validating it once.
//!
//! Opening is cheap (one linear pass over records, references and nodes, no copy of the
//! geometry) and strict: every offset, count, index and child link is checked, and a short or
//! inconsistent file is an error, never a default. After a successful open, traversal can index
//! the mapping without further checks and cannot read out of bounds, even on a crafted file.
//! Checksums are verified only on request ([`ReducemFile::verify_checksums`]), since hashing
//! pages in the whole file.
//!
//! This module is the read side: it depends on the format definitions only, never on the build
//! side, the pipeline, PLY input, progress or channel code.

use std::fs::File;
use std::ops::Range;
use std::path::{Path, PathBuf};

use memmap2::Mmap;
use rayon::prelude::*;

use super::implicit_tree::internal_nodes;
use super::{
    axis_bytes, Header, SectionKind, StripRecord, TopNode, TopSlot, VertexEncoding, ENDIAN_MARKER,
    HEADER_CHECKSUMMED_BYTES, HEADER_PAGE, MAGIC, MAX_STRIP_VERTICES, MAX_TOP_DEPTH, SECTION_ALIGN,
    TOP_WIDTH, VERSION_MAJOR,
};
use crate::geometry::Point;
use crate::mapping::{map_file, map_range};

/// Why a file could not be opened, with the file and the byte offset of the defect.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: {section} at byte {offset}: {detail}", path.display())]
    Invalid {
        path: PathBuf,
        section: &'static str,
        offset: u64,
        detail: String,
    },
}

/// A mapped, validated ReduceM file.
pub struct ReducemFile {
    path: PathBuf,
    map: Mmap,
    header: Header,
    sections: [Range<usize>; 3],
}

/// One strip's block, viewed in place.
#[derive(Clone, Copy, Debug)]
pub struct StripView<'a> {
    pub vertices: &'a [Point],
    /// Split axes, 2 bits per internal node.
    pub axes: &'a [u8],
    /// 1-byte references into `vertices`, swaps included.
    pub references: &'a [u8],
}

impl StripView<'_> {
    pub fn window_count(&self) -> usize {
        self.references.len() - 2
    }

    /// Split axis of internal node `node`.
    #[inline]
    pub fn axis(&self, node: usize) -> usize {
        ((self.axes[node / 4] >> (2 * (node % 4))) & 3) as usize
    }

    /// Corners of window `k` in input winding, or `None` for a swap.
    #[inline]
    pub fn window_points(&self, k: usize) -> Option<[Point; 3]> {
        crate::strip::window_triangle(self.references, k)
            .map(|t| t.map(|r| self.vertices[r as usize]))
    }
}

impl ReducemFile {
    /// Validates the file at `path` and maps it.
    ///
    /// Validation reads the file through bounded windows ([`VALIDATION_WINDOW`]) that are
    /// unmapped as it goes, and traversal gets a fresh mapping of the same (never modified in
    /// place) file: opening a 6 GB model costs tens of megabytes of resident memory, and the
    /// resident set after a frame is only the pages rays really reached.
    pub fn open(path: &Path) -> Result<ReducemFile, FormatError> {
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
        let sections = checker.sections(&header)?;
        let map = map_file(&file).map_err(io_error)?;
        if map.len() as u64 != file_len {
            let detail = "the file changed size while it was being opened".to_string();
            return Err(checker.invalid("file", 0, detail));
        }
        let opened = ReducemFile {
            path: path.to_path_buf(),
            map,
            header,
            sections,
        };
        let windows = Windows {
            file: &file,
            opened: &opened,
        };
        windows.validate_strips()?;
        windows.validate_nodes()?;
        Ok(opened)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn header(&self) -> &Header {
        &self.header
    }

    pub fn file_bytes(&self) -> u64 {
        self.map.len() as u64
    }

    /// Strip kd-tree leaf size in windows.
    pub fn leaf_windows(&self) -> usize {
        self.header.leaf_windows as usize
    }

    pub fn section_bytes(&self, kind: SectionKind) -> &[u8] {
        &self.map[self.sections[section_slot(kind)].clone()]
    }

    pub fn top_nodes(&self) -> &[TopNode] {
        bytemuck::cast_slice(self.section_bytes(SectionKind::TopNodes))
    }

    pub fn strip_records(&self) -> &[StripRecord] {
        bytemuck::cast_slice(self.section_bytes(SectionKind::StripRecords))
    }

    pub fn strip_count(&self) -> usize {
        self.strip_records().len()
    }

    /// The strip at file position `index` (`index < strip_count()`).
    #[inline]
    pub fn strip(&self, index: usize) -> StripView<'_> {
        strip_view(
            self.section_bytes(SectionKind::StripData),
            &self.strip_records()[index],
            self.leaf_windows(),
        )
    }

    /// Hashes every section and compares with the header's checksums.
    pub fn verify_checksums(&self) -> Result<(), FormatError> {
        for (slot, kind) in SectionKind::ALL.into_iter().enumerate() {
            let entry = &self.header.sections[slot];
            let actual = xxhash_rust::xxh3::xxh3_64(self.section_bytes(kind));
            if actual != entry.checksum {
                return Err(self.invalid(
                    kind.name(),
                    entry.offset,
                    format!(
                        "checksum {actual:#018x} does not match the header's {:#018x}",
                        entry.checksum
                    ),
                ));
            }
        }
        Ok(())
    }

    fn invalid(&self, section: &'static str, offset: u64, detail: String) -> FormatError {
        FormatError::Invalid {
            path: self.path.clone(),
            section,
            offset,
            detail,
        }
    }

    fn section_offset(&self, kind: SectionKind) -> u64 {
        self.header.sections[section_slot(kind)].offset
    }
}

/// Bytes of the file mapped at a time while validating.
pub const VALIDATION_WINDOW: usize = 64 << 20;

/// Validation of the sections through bounded windows of the file.
struct Windows<'a> {
    file: &'a File,
    opened: &'a ReducemFile,
}

impl Windows<'_> {
    fn map(&self, offset: u64, length: usize) -> Result<Mmap, FormatError> {
        map_range(self.file, offset, length).map_err(|source| FormatError::Io {
            path: self.opened.path.clone(),
            source,
        })
    }

    fn section(&self, kind: SectionKind) -> Range<u64> {
        let range = &self.opened.sections[section_slot(kind)];
        range.start as u64..range.end as u64
    }

    /// Checks every strip record, its block bounds, reference indices and split axes, and that
    /// the real triangles add up to the header's count.
    fn validate_strips(&self) -> Result<(), FormatError> {
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
        let leaf = self.opened.leaf_windows();
        let mut triangles = 0;
        let mut start = 0;
        while start < records.len() {
            let mut span = block_range(&records[start], leaf, data.end - data.start)
                .map_err(|defect| self.strip_error(first + start, defect))?;
            let mut end = start + 1;
            while let Some(next) = records.get(end) {
                let Ok(block) = block_range(next, leaf, data.end - data.start) else {
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
                    check_block(&window, span.start, record, leaf)
                        .map_err(|defect| self.strip_error(first + start + i, defect))
                })
                .try_reduce(|| 0u64, |a, b| Ok(a + b))?;
            start = end;
        }
        Ok(triangles)
    }

    fn strip_error(&self, index: usize, (offset, detail): StripDefect) -> FormatError {
        let opened = self.opened;
        let offset = offset.map_or(
            opened.section_offset(SectionKind::StripRecords) + index as u64 * RECORD_BYTES,
            |o| opened.section_offset(SectionKind::StripData) + o,
        );
        opened.invalid("strip_data", offset, format!("strip {index}: {detail}"))
    }

    /// Checks that the nodes form one tree in preorder within the depth limit, with every slot
    /// well formed and leaf strip ranges inside the record array; every node but the root has
    /// exactly one parent, before it in the array, so traversal terminates and indexes nothing
    /// out of bounds.
    fn validate_nodes(&self) -> Result<(), FormatError> {
        let section = self.section(SectionKind::TopNodes);
        let count = ((section.end - section.start) / NODE_BYTES) as usize;
        let mut tree = TreeCheck {
            opened: self.opened,
            depth: vec![u8::MAX; count],
            leaf_strips: 0,
        };
        tree.depth[0] = 0;
        let batch = (VALIDATION_WINDOW as u64 / NODE_BYTES).max(1) as usize;
        for first in (0..count).step_by(batch) {
            let length = batch.min(count - first) as u64 * NODE_BYTES;
            let window = self.map(section.start + first as u64 * NODE_BYTES, length as usize)?;
            let nodes: &[TopNode] = bytemuck::try_cast_slice(&window).map_err(|_| {
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
const NODE_BYTES: u64 = std::mem::size_of::<TopNode>() as u64;

/// The one-parent, depth and strip-count bookkeeping of [`Windows::validate_nodes`].
struct TreeCheck<'a> {
    opened: &'a ReducemFile,
    depth: Vec<u8>,
    /// Strips over all leaves so far.
    leaf_strips: u64,
}

/// Byte offsets of a slot's fields within a [`TopNode`].
const CHILD_FIELD: u64 = 96;
const KIND_FIELD: u64 = 112;

impl TreeCheck<'_> {
    fn fail(&self, index: usize, field: u64, detail: String) -> FormatError {
        self.opened.invalid(
            "top_nodes",
            self.opened.section_offset(SectionKind::TopNodes) + index as u64 * NODE_BYTES + field,
            format!("node {index}: {detail}"),
        )
    }

    fn check(&mut self, index: usize, node: &TopNode) -> Result<(), FormatError> {
        if self.depth[index] == u8::MAX {
            return Err(self.fail(index, 0, "has no parent".into()));
        }
        let occupied = node.occupied();
        let empty_model = index == 0 && self.opened.header.strip_count == 0;
        if occupied == 0 && !empty_model {
            return Err(self.fail(index, KIND_FIELD, "has no children".into()));
        }
        for slot in 0..TOP_WIDTH {
            self.check_slot(index, node, slot, slot >= occupied)?;
        }
        Ok(())
    }

    fn check_slot(
        &mut self,
        index: usize,
        node: &TopNode,
        slot: usize,
        empty: bool,
    ) -> Result<(), FormatError> {
        let child_field = CHILD_FIELD + 4 * slot as u64;
        let kind_field = KIND_FIELD + 4 * slot as u64;
        if empty {
            if !node.is_exactly_empty(slot) {
                let detail = format!(
                    "slot {slot} follows an empty slot but is not the exact empty slot \
                     (min +inf, max -inf, child 0, kind 0)"
                );
                return Err(self.fail(index, kind_field, detail));
            }
            return Ok(());
        }
        match node.slot(slot) {
            TopSlot::Internal(child) => self.adopt(index, slot, child as usize),
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
            TopSlot::Invalid(_) | TopSlot::Empty => Err(self.fail(
                index,
                kind_field,
                format!(
                    "slot {slot}: kind {:#x} is neither internal nor a strip count",
                    node.kind[slot]
                ),
            )),
        }
    }

    /// Records node `child` as the child of node `index` in `slot`.
    fn adopt(&mut self, index: usize, slot: usize, child: usize) -> Result<(), FormatError> {
        let field = CHILD_FIELD + 4 * slot as u64;
        let nodes = self.depth.len();
        if child <= index || child >= nodes {
            let detail = format!("slot {slot}: child {child} outside {}..{nodes}", index + 1);
            return Err(self.fail(index, field, detail));
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

fn section_slot(kind: SectionKind) -> usize {
    kind as usize - 1
}

/// Views a strip's block; the record has been validated by [`check_strip`].
#[inline]
pub(crate) fn strip_view<'a>(
    data: &'a [u8],
    record: &StripRecord,
    leaf_windows: usize,
) -> StripView<'a> {
    let start = record.data_word as usize * 4;
    let vertex_end = start + record.vertex_count as usize * VertexEncoding::F32.bytes_per_vertex();
    let windows = record.reference_count as usize - 2;
    let axes_end = vertex_end + axis_bytes(internal_nodes(windows, leaf_windows));
    StripView {
        vertices: bytemuck::cast_slice(&data[start..vertex_end]),
        axes: &data[vertex_end..axes_end],
        references: &data[axes_end..axes_end + record.reference_count as usize],
    }
}

/// A defect in a strip: the data-section offset where it is (if known) and what is wrong.
type StripDefect = (Option<u64>, String);

/// Checks a record's counts and returns its block's byte range within the strip-data section.
fn block_range(
    record: &StripRecord,
    leaf_windows: usize,
    data_len: u64,
) -> Result<Range<u64>, StripDefect> {
    let vertices = record.vertex_count as usize;
    let references = record.reference_count as usize;
    if !(3..=MAX_STRIP_VERTICES).contains(&vertices) || references < 3 {
        return Err((
            None,
            format!("{vertices} vertices and {references} references"),
        ));
    }
    let nodes = internal_nodes(references - 2, leaf_windows);
    if 2 * nodes > vertices {
        let detail = format!(
            "{nodes} kd-tree nodes need {} bound vertices, it has {vertices}",
            2 * nodes
        );
        return Err((None, detail));
    }
    let start = record.data_word as u64 * 4;
    let length =
        (vertices * VertexEncoding::F32.bytes_per_vertex() + axis_bytes(nodes) + references) as u64;
    if start + length > data_len {
        let detail = format!("block of {length} bytes runs past the section end {data_len}");
        return Err((Some(start), detail));
    }
    Ok(start..start + length)
}

/// Validates a strip's block inside `window` (which starts at `window_start` in the section,
/// and holds the block: see [`block_range`]); returns its real-triangle count.
fn check_block(
    window: &[u8],
    window_start: u64,
    record: &StripRecord,
    leaf_windows: usize,
) -> Result<u64, StripDefect> {
    let vertices = record.vertex_count as usize;
    let block = block_range(record, leaf_windows, u64::MAX)?;
    let local = StripRecord {
        data_word: 0,
        ..*record
    };
    let bytes = &window[(block.start - window_start) as usize..(block.end - window_start) as usize];
    let view = strip_view(bytes, &local, leaf_windows);
    if let Some(position) = view.references.iter().position(|&r| r as usize >= vertices) {
        let offset = block.end - view.references.len() as u64 + position as u64;
        let detail = format!(
            "reference {} out of range ({vertices} vertices)",
            view.references[position]
        );
        return Err((Some(offset), detail));
    }
    let nodes = internal_nodes(view.window_count(), leaf_windows);
    if let Some(node) = (0..nodes).find(|&n| view.axis(n) > 2) {
        return Err((Some(block.start), format!("node {node} has split axis 3")));
    }
    Ok(crate::strip::triangles(view.references).count() as u64)
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
        let header: Header =
            bytemuck::pod_read_unaligned(&self.head[..std::mem::size_of::<Header>()]);
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
        if header.version_major != VERSION_MAJOR {
            let advice = if header.version_major < VERSION_MAJOR {
                "an older format (version 1 had binary top-level nodes): convert the mesh again"
            } else {
                "a newer format: use a newer reducem"
            };
            let detail = format!(
                "format version {}.{}, this reader reads {VERSION_MAJOR}.x; {advice}",
                header.version_major, header.version_minor
            );
            return Err(self.invalid("header", 8, detail));
        }
        let checksum = xxhash_rust::xxh3::xxh3_64(&self.head[..HEADER_CHECKSUMMED_BYTES]);
        if checksum != header.header_checksum
            || header.header_bytes as usize != std::mem::size_of::<Header>()
        {
            return Err(self.invalid(
                "header",
                HEADER_CHECKSUMMED_BYTES as u64,
                "header checksum mismatch".into(),
            ));
        }
        if VertexEncoding::from_u32(header.vertex_encoding).is_none() {
            return Err(self.invalid(
                "header",
                20,
                format!("unknown vertex encoding {}", header.vertex_encoding),
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

    fn sections(&self, header: &Header) -> Result<[Range<usize>; 3], FormatError> {
        let mut previous_end = HEADER_PAGE;
        let mut ranges = [0..0, 0..0, 0..0];
        for (slot, kind) in SectionKind::ALL.into_iter().enumerate() {
            let entry = &header.sections[slot];
            let table_offset = 104 + slot as u64 * 32;
            let end = entry.offset.saturating_add(entry.length);
            let record = record_size(kind);
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

fn record_size(kind: SectionKind) -> u64 {
    match kind {
        SectionKind::TopNodes => std::mem::size_of::<TopNode>() as u64,
        SectionKind::StripRecords => std::mem::size_of::<StripRecord>() as u64,
        SectionKind::StripData => 4,
    }
}

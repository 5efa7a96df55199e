//! Opens a ReduceM file by mapping it, validates it, and views it in place.
//!
//! Validation is strict: every offset, count, index and child link is checked
//! (`reader/validate.rs`), and a short or inconsistent file is an error, never a default. It
//! happens in one of two ways ([`Validation`]):
//! * in full at open: one linear pass over records, references and nodes;
//! * lazily, for a model larger than [`EAGER_VALIDATION_BYTES`]: opening checks the header and
//!   the section table, and each strip and top-level node is checked the first time traversal
//!   uses it (`reader/lazy.rs`), so that opening does not read the whole model before the first
//!   ray. A strip found corrupt then reads as a strip without triangles, a node as one every
//!   ray misses, and the defect is kept ([`ReducemFile::defect`]) for the caller to report.
//!
//! Either way, traversal can index the mapping through the views here ([`ReducemFile::strip`],
//! [`ReducemFile::top_nodes`] through [`ReducemFile::top_node`]) and cannot read out of bounds
//! or loop, even on a crafted file. Checksums
//! are verified only on request ([`ReducemFile::verify_checksums`]), since hashing pages in the
//! whole file.
//!
//! This module is the read side: it depends on the format definitions only, never on the build
//! side, the pipeline, PLY input, progress or channel code.

mod attributes;
mod lazy;
mod validate;

use std::fs::File;
use std::mem::size_of;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use memmap2::Mmap;

use super::attributes::AttributeSection;
use super::block_boxes::{self, BlockBoxes};
use super::grid::{Grid, NodeGrid};
use super::implicit_tree::internal_nodes;
use super::pool::{pool_points, PartHeader, PART_HEADER_BYTES, POOL_COUNT_BYTES};
use super::quantized::{vertex_part_bytes, AxisWordLayout, GridVertices};
use super::references::{packed_bytes, packed_width, References, MIN_PACKED_BYTES};
use super::vertices::StripVertices;
use super::{
    axis_bytes, Defect, FilePart, GridNode, Header, PrecisionRecord, SectionKind, StripRecord,
    TopNode, WideNode, F32_VERTEX_BYTES,
};
use crate::geometry::Point;
use attributes::AttributeSections;
use lazy::LazyChecks;

pub use attributes::VertexAttributes;
pub use validate::VALIDATION_WINDOW;

/// Files up to this size are validated in full when opened by [`ReducemFile::open`]: it costs
/// about a millisecond at most, and a corrupt small model is then rejected at open.
pub const EAGER_VALIDATION_BYTES: u64 = 1 << 20;

/// A batch of fewer rays than one per this many bytes of the file reads it as scattered pages
/// ([`ReducemFile::advise_batch`]): between the measured crossover of 10,000 to 100,000 rays on
/// a 5.5 GiB file.
pub const SCATTERED_BATCH_BYTES_PER_RAY: u64 = 256 << 10;

/// When the strips of a file are validated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Validation {
    /// Every strip and node at open, and the triangle count against the header: the open
    /// fails on any structural defect. What `reducem inspect` and the pipeline's final check
    /// use.
    Full,
    /// The header and the section table at open; each strip and top-level node the first time
    /// traversal uses it. Opening costs the same for any model size.
    Lazy,
}

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
        section: FilePart,
        offset: u64,
        /// What is wrong, for callers that act on the kind; `detail` words it with the values.
        defect: Defect,
        detail: String,
    },
}

impl FormatError {
    /// The kind of defect of an invalid file; `None` for an I/O error.
    pub fn defect(&self) -> Option<Defect> {
        match self {
            FormatError::Invalid { defect, .. } => Some(*defect),
            FormatError::Io { .. } => None,
        }
    }
}

/// A mapped, validated ReduceM file.
pub struct ReducemFile {
    path: PathBuf,
    /// Kept open for [`ReducemFile::validate_all`], which maps the file in bounded windows.
    file: File,
    map: Mmap,
    header: Header,
    precision: PrecisionRecord,
    layout: VertexLayout,
    /// The record of the top-level nodes.
    nodes: NodeLayout,
    sections: [Range<usize>; 3],
    attributes: AttributeSections,
    /// The model record (since 3.1).
    model: Option<super::model::ModelRecord>,
    checks: LazyChecks,
    /// The lengths of blocks' split axes and boxes by reference count, for views.
    parts: PartTable,
    /// Whether [`ReducemFile::advise_batch`] asked for scattered reads, which a scoped
    /// [`ReducemFile::with_scattered_reads`] then leaves in place.
    scattered: AtomicBool,
}

/// The record of a file's top-level nodes: by its version and vertex encoding.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeLayout {
    /// [`TopNode`]s (format 2 and 3, f32 nodes).
    F32,
    /// [`GridNode`]s on this node grid (format 2 and 3, grid nodes).
    Grid(NodeGrid),
    /// [`WideNode`]s (format 4).
    Wide,
}

/// The top-level nodes of a file, in the record its version and vertex encoding imply.
#[derive(Clone, Copy, Debug)]
pub enum TopNodes<'a> {
    F32(&'a [TopNode]),
    Grid(&'a [GridNode], NodeGrid),
    Wide(&'a [WideNode]),
}

impl TopNodes<'_> {
    pub fn len(&self) -> usize {
        match self {
            TopNodes::F32(nodes) => nodes.len(),
            TopNodes::Grid(nodes, _) => nodes.len(),
            TopNodes::Wide(nodes) => nodes.len(),
        }
    }

    /// Never true for an opened file, whose root always exists.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// How a file's strip blocks store vertices and references: what viewing a block needs besides
/// the block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VertexLayout {
    /// f32 vertices. With `boxes` (format 3) the references are packed and strips carry block
    /// boxes ([`super::block_boxes`]); before, one byte per reference and no boxes.
    F32 { boxes: bool },
    /// Grid vertices. `packed` since format 2.3: axis words at the grid's bits
    /// ([`AxisWordLayout::Packed`]) and references at the strip's ([`super::references`]);
    /// before, u32 axis words and one byte per reference. `boxes` since format 3.0 (always
    /// with `packed`).
    Grid {
        grid: Grid,
        packed: bool,
        boxes: bool,
    },
    /// Grid vertices in pools shared by consecutive strips (format 4.1, [`super::pool`]): packed
    /// axis words and references, block boxes, no split axes.
    Pooled { grid: Grid },
}

impl From<Option<Grid>> for VertexLayout {
    /// The layout the writer gives vertices on `grid` (or f32 ones without): format 3.
    fn from(grid: Option<Grid>) -> VertexLayout {
        grid.map_or(VertexLayout::F32 { boxes: true }, |grid| {
            VertexLayout::Grid {
                grid,
                packed: true,
                boxes: true,
            }
        })
    }
}

impl VertexLayout {
    /// How the axis words of a grid block are stored.
    fn axis_words(grid: &Grid, packed: bool) -> AxisWordLayout {
        match packed {
            true => AxisWordLayout::Packed {
                grid_bits: grid.bits,
            },
            false => AxisWordLayout::Words,
        }
    }

    /// Whether strips carry block boxes (format 3).
    pub fn boxes(&self) -> bool {
        match *self {
            VertexLayout::F32 { boxes } | VertexLayout::Grid { boxes, .. } => boxes,
            VertexLayout::Pooled { .. } => true,
        }
    }

    /// Whether references are packed at the strip's bits.
    fn packed_references(&self) -> bool {
        match *self {
            VertexLayout::F32 { boxes } => boxes,
            VertexLayout::Grid { packed, .. } => packed,
            VertexLayout::Pooled { .. } => true,
        }
    }

    /// Whether blocks store their strip kd-tree's split axes (all but pooled files).
    pub fn kd_trees(&self) -> bool {
        !matches!(self, VertexLayout::Pooled { .. })
    }

    /// Bytes of a block's `count` references with `vertices` vertices.
    fn reference_bytes(&self, count: usize, vertices: usize) -> usize {
        match self.packed_references() {
            true => packed_bytes(count, vertices),
            false => count,
        }
    }
}

/// A pooled strip's place in the vertex pool it shares with its neighbours
/// ([`super::pool`]).
#[derive(Clone, Copy, Debug)]
pub struct PoolPlace<'a> {
    /// The pool's byte offset in the strip-data section: equal for the strips sharing it.
    pub offset: usize,
    /// The pool point that is the strip's vertex 0.
    pub base: usize,
    /// Every point of the pool.
    pub points: StripVertices<'a>,
}

/// One strip's block, viewed in place.
#[derive(Clone, Copy, Debug)]
pub struct StripView<'a> {
    pub vertices: StripVertices<'a>,
    /// Split axes, 2 bits per internal node.
    pub axes: &'a [u8],
    /// References into `vertices`, swaps included.
    pub references: References<'a>,
    /// One box per eight windows (format 3, strips of more than eight windows); empty
    /// otherwise.
    pub boxes: BlockBoxes<'a>,
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
        let mut corners = [0u8; 3];
        self.references.read_into(k, &mut corners);
        crate::strip_windows::window_corners(corners, k)
            .map(|t| t.map(|r| self.vertices.point(r as usize)))
    }

    /// The real triangles' references in strip order and input winding.
    pub fn triangles(&self) -> Vec<[u8; 3]> {
        crate::strip_windows::triangles(&self.references.to_vec()).collect()
    }
}

impl ReducemFile {
    /// Maps the file at `path` and validates it: in full when it is at most
    /// [`EAGER_VALIDATION_BYTES`], else lazily ([`Validation::Lazy`]), so that opening a large
    /// model costs the same as a small one.
    pub fn open(path: &Path) -> Result<ReducemFile, FormatError> {
        validate::open(path, None)
    }

    /// Maps the file at `path` and validates it as `validation` says.
    ///
    /// Validation reads the file through bounded windows ([`VALIDATION_WINDOW`]) that are
    /// unmapped as it goes, and traversal gets a fresh mapping of the same (never modified in
    /// place) file: validating a 6 GB model costs tens of megabytes of resident memory, and the
    /// resident set after a frame is only the pages rays really reached.
    pub fn open_with(path: &Path, validation: Validation) -> Result<ReducemFile, FormatError> {
        validate::open(path, Some(validation))
    }

    /// Tells the kernel how a batch of `rays` rays will read the file: scattered pages, each
    /// page fault reading its page alone, when the batch is small for the file (fewer than one
    /// ray per [`SCATTERED_BATCH_BYTES_PER_RAY`]) or when the file is larger than the memory
    /// available ([`crate::mapping::available_memory_bytes`]); otherwise the default
    /// read-around, which streams the many pages a large batch needs faster than page-by-page
    /// faults.
    ///
    /// Small batches, measured on the 300M-triangle scan (5.5 GiB, 8 MiB read-ahead, page cache
    /// cold, `reducem query --occluded` of spread AO rays): 1 ray 0.25–0.57 s by default, 0.03 s
    /// advised; 1,000 rays 4.9–6.0 s against 0.7–0.8 s; 10,000 rays 6.1–6.7 s against 4.8–5.2 s;
    /// 100,000 rays 5.8–7.8 s against 18–21 s. Advising the nodes "will need" (reading them all
    /// ahead) gained nothing measurable.
    ///
    /// Files larger than memory: the read-around window (8 MiB on the test machine's disk)
    /// evicts the pages the rays keep returning to, so every frame reads the file again. On the
    /// 500M-triangle scan (9.22 GiB) with 3 GiB available (`MODEL=scan500m.rdm BUDGETS=3
    /// SIZES=1024 scripts/bench_outofcore.sh`, 1024², 4 AO rays per pixel, 2 threads), a warm
    /// AO frame read 5.4 GiB and traced 0.23 Mrays/s by default, 0 bytes and 0.98 Mrays/s
    /// advised (1.01 in core); a warm primary frame 0.27 against 0.91 Mrays/s (1.57 in core).
    /// The price is the first frame from a cold cache: page-by-page faults traced it at 0.036
    /// instead of 0.17 Mrays/s (AO); later frames, and later processes while the pages stay
    /// cached, gain. (An earlier measurement on a loaded machine found the opposite with a
    /// 4 GiB budget on the 5.5 GiB 300M scan, 73% of the file: a warm primary frame 11.5 s
    /// advised against 6.3 s; not measured again since.)
    pub fn advise_batch(&self, rays: usize) {
        let small_batch =
            (rays as u64).saturating_mul(SCATTERED_BATCH_BYTES_PER_RAY) < self.file_bytes();
        let larger_than_memory = crate::mapping::available_memory_bytes()
            .is_some_and(|available| self.file_bytes() > available);
        if small_batch || larger_than_memory {
            crate::mapping::advise_scattered_reads(&self.map);
            self.scattered.store(true, Ordering::Relaxed);
        }
    }

    /// Runs `read`, which reads the file about `reads` times at scattered places, with page
    /// faults reading their page alone when so few reads are small for the file (as
    /// [`ReducemFile::advise_batch`] decides), then restores the read-around for what follows.
    /// Framing a cold 300M-triangle file samples 4,096 strips spread over it: with an 8 MiB
    /// read-around each sample pulls its window in, and the samples read the whole file.
    pub fn with_scattered_reads<T>(&self, reads: usize, read: impl FnOnce() -> T) -> T {
        let small =
            (reads as u64).saturating_mul(SCATTERED_BATCH_BYTES_PER_RAY) < self.file_bytes();
        if !small || self.scattered.load(Ordering::Relaxed) {
            return read();
        }
        crate::mapping::advise_scattered_reads(&self.map);
        let result = read();
        if !self.scattered.load(Ordering::Relaxed) {
            crate::mapping::advise_default_reads(&self.map);
        }
        result
    }

    /// Node `index` of `nodes`, this file's [`ReducemFile::top_nodes`], when it may be
    /// traversed: on a lazily opened file, the node's first visit validates it (the checks that
    /// need no other node: slots, child links after it and inside the array, leaf strip ranges
    /// inside the record array); a corrupt node is `None`, which traversal takes as a miss, and
    /// the defect is kept for [`ReducemFile::defect`].
    #[inline(always)]
    pub fn top_node<'n, N>(&self, nodes: &'n [N], index: usize) -> Option<&'n N> {
        if !self.checks.nodes.get(index) && !self.node_on_first_visit(index) {
            return None;
        }
        nodes.get(index)
    }

    /// Validates node `index`; whether it passed. Out of line: it runs once per node.
    #[inline(never)]
    fn node_on_first_visit(&self, index: usize) -> bool {
        match validate::check_node(self, index) {
            Ok(()) => {
                self.checks.nodes.set(index);
                true
            }
            Err(defect) => {
                self.checks.keep(defect);
                false
            }
        }
    }

    /// Validates every strip and node, and the triangle count against the header, as
    /// [`Validation::Full`] does at open: for a lazily opened file, what `reducem inspect
    /// --verify` checks.
    pub fn validate_all(&self) -> Result<(), FormatError> {
        validate::validate_all(self)
    }

    /// The first defect met in a strip or top-level node viewed since a lazy open, if any: such
    /// a strip read as having no triangles, such a node as missed, so results that reached it
    /// are incomplete and must not be reported as complete. Always `None` after a full
    /// validation.
    pub fn defect(&self) -> Option<FormatError> {
        self.checks.first_defect(&self.path)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The model record; `None` before format 3.1.
    pub fn model(&self) -> Option<&super::model::ModelRecord> {
        self.model.as_ref()
    }

    /// The precision record (zeros for a format 2.0 file: lossless, nothing welded).
    pub fn precision(&self) -> &PrecisionRecord {
        &self.precision
    }

    pub fn vertex_layout(&self) -> &VertexLayout {
        &self.layout
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

    pub fn top_nodes(&self) -> TopNodes<'_> {
        let bytes = self.section_bytes(SectionKind::TopNodes);
        match self.nodes {
            NodeLayout::F32 => TopNodes::F32(bytemuck::cast_slice(bytes)),
            NodeLayout::Grid(grid) => TopNodes::Grid(bytemuck::cast_slice(bytes), grid),
            NodeLayout::Wide => TopNodes::Wide(bytemuck::cast_slice(bytes)),
        }
    }

    pub fn strip_records(&self) -> &[StripRecord] {
        bytemuck::cast_slice(self.section_bytes(SectionKind::StripRecords))
    }

    pub fn strip_count(&self) -> usize {
        self.strip_records().len()
    }

    /// The points of a pooled grid file's pools, each pool counted once, read from the strips'
    /// parts in file order (a pool's strips are consecutive); `None` for other files. What
    /// `reducem inspect` reports as stored: 4.1 files written before the header counted the
    /// pools' points count the vertices of the strips' views there. A part or pool outside the
    /// strip data counts nothing.
    pub fn pool_points(&self) -> Option<u64> {
        if !matches!(self.layout, VertexLayout::Pooled { .. }) {
            return None;
        }
        let data = self.section_bytes(SectionKind::StripData);
        let mut previous = None;
        let mut points = 0;
        for record in self.strip_records() {
            let part = record.data_word as usize * 4;
            let Some(header) = data.get(part..).and_then(PartHeader::read) else {
                continue;
            };
            let offset = part + header.pool_distance;
            if previous != Some(offset) {
                points += data
                    .get(offset)
                    .map_or(0, |&count| pool_points(count) as u64);
                previous = Some(offset);
            }
        }
        Some(points)
    }

    /// Strip `index`'s place in its vertex pool, in pooled grid files and once the strip has
    /// passed validation (after [`ReducemFile::strip`]); `None` otherwise.
    pub fn pool(&self, index: usize) -> Option<PoolPlace<'_>> {
        let VertexLayout::Pooled { grid } = self.layout else {
            return None;
        };
        if !self.checks.strips.get(index) {
            return None;
        }
        let data = self.section_bytes(SectionKind::StripData);
        let part = self.strip_records().get(index)?.data_word as usize * 4;
        let header = PartHeader::read(data.get(part..)?)?;
        let offset = part + header.pool_distance;
        let pool = data.get(offset..)?;
        let count = pool_points(*pool.first()?);
        let pool = pool.get(POOL_COUNT_BYTES..)?;
        let words_layout = AxisWordLayout::Packed {
            grid_bits: grid.bits,
        };
        let words = words_layout.read(pool);
        let points =
            GridVertices::new(pool, (&words, words_layout), 0, &grid).starting_at(0, count);
        Some(PoolPlace {
            offset,
            base: header.base,
            points: StripVertices::Grid(points),
        })
    }

    /// The strips of a leaf whose slot holds `first` and `count`, within the file's strips: a
    /// slot changed in place after its validation cannot send a walk through billions of
    /// strips.
    #[inline(always)]
    pub fn leaf_strips(&self, first: u32, count: u32) -> std::ops::Range<u32> {
        let end = first.saturating_add(count).min(self.strip_count() as u32);
        first.min(end)..end
    }

    /// How many nodes a walk of one ray (or packet) may visit: each node at most once in a
    /// valid file; a walk that reaches this was sent round in circles by a file changed in
    /// place after its validation, and stops.
    #[inline(always)]
    pub fn node_visits(&self) -> usize {
        self.top_nodes().len()
    }

    /// The strip at file position `index` (`index < strip_count()`).
    ///
    /// On a lazily opened file, the strip's first view validates it; a corrupt strip reads as
    /// one without triangles, and the defect is kept for [`ReducemFile::defect`].
    #[inline]
    pub fn strip(&self, index: usize) -> StripView<'_> {
        if !self.checks.strips.get(index) {
            return self.strip_on_first_view(index);
        }
        self.strip_in_place(index)
    }

    /// [`ReducemFile::strip`] inlined into its caller (a first view stays out of line), for the
    /// packet walk, which views a strip per leaf strip: a call would save registers and copy
    /// the view out. `strip` is left to the compiler for its other callers.
    #[inline(always)]
    pub fn strip_inlined(&self, index: usize) -> StripView<'_> {
        if !self.checks.strips.get(index) {
            return self.strip_on_first_view(index);
        }
        self.strip_in_place(index)
    }

    /// Validates strip `index` and views it, or the stand-in without triangles when it is
    /// corrupt. Out of line: it runs once per strip. A sound strip takes checks that only
    /// decide ([`validate::sound_strip`]); the others are checked again to word the defect.
    #[inline(never)]
    fn strip_on_first_view(&self, index: usize) -> StripView<'_> {
        match validate::sound_strip(self, index) {
            Some(view) => {
                self.checks.strips.set(index);
                view
            }
            None => self.strip_with_defect(index),
        }
    }

    /// [`ReducemFile::strip_on_first_view`] of a strip the sound path did not pass: corrupt, or
    /// pooled (whose pool is checked here).
    #[inline(never)]
    fn strip_with_defect(&self, index: usize) -> StripView<'_> {
        match validate::check_strip(self, index) {
            Ok(view) => {
                self.checks.strips.set(index);
                view
            }
            Err(defect) => {
                self.checks.keep(*defect);
                lazy::no_triangles()
            }
        }
    }

    /// Strip `index`'s record, read from the mapping at its offset; `None` past the records.
    ///
    /// The record is read once and checked again before use: a file changed in place after
    /// its validation reads as strips without triangles, never as a panic.
    #[inline(always)]
    fn record(&self, index: usize) -> Option<StripRecord> {
        let records = &self.sections[section_slot(SectionKind::StripRecords)];
        let at = records.start + index * size_of::<StripRecord>();
        match self.map.get(at..at + 8) {
            Some(bytes) if at + 8 <= records.end => Some(bytemuck::pod_read_unaligned(bytes)),
            _ => None,
        }
    }

    /// The view of a strip known to be valid.
    ///
    /// The record is read from the mapping at its offset, and the block viewed in the mapping
    /// from the strip-data section's start: the sections lie inside the mapping (checked at
    /// open) and a valid block inside its section, so the view is the same as through the
    /// sections' slices, whose bounds and alignment checks, and those of the record slice, cost
    /// 10 of a view's 146 instructions (callgrind, 1M primary rays on the 1M scan).
    #[inline(always)]
    fn strip_in_place(&self, index: usize) -> StripView<'_> {
        let Some(record) = self.record(index) else {
            return lazy::no_triangles();
        };
        let data = &self.map[self.sections[section_slot(SectionKind::StripData)].start..];
        let parts = self.parts.lengths(record.reference_count as usize);
        view_block(data, &record, parts, &self.layout)
    }

    /// Hashes every section and compares with the header's checksums.
    pub fn verify_checksums(&self) -> Result<(), FormatError> {
        let core = SectionKind::ALL
            .into_iter()
            .enumerate()
            .map(|(slot, kind)| {
                (
                    FilePart::Section(kind),
                    &self.header.sections[slot],
                    self.section_bytes(kind),
                )
            });
        let set = self.attributes();
        let attributes = AttributeSection::ALL
            .into_iter()
            .filter(|&kind| set.has(kind))
            .map(|kind| {
                let entry = &self.attributes.record.sections[kind.slot()];
                (FilePart::Attribute(kind), entry, self.attribute_bytes(kind))
            });
        for (name, entry, bytes) in core.chain(attributes) {
            let actual = xxhash_rust::xxh3::xxh3_64(bytes);
            if actual != entry.checksum {
                return Err(self.invalid(
                    name,
                    entry.offset,
                    Defect::ChecksumMismatch,
                    format!(
                        "checksum {actual:#018x} does not match the header's {:#018x}",
                        entry.checksum
                    ),
                ));
            }
        }
        Ok(())
    }

    fn invalid(
        &self,
        section: FilePart,
        offset: u64,
        defect: Defect,
        detail: String,
    ) -> FormatError {
        FormatError::Invalid {
            path: self.path.clone(),
            section,
            offset,
            defect,
            detail,
        }
    }

    fn section_offset(&self, kind: SectionKind) -> u64 {
        self.header.sections[section_slot(kind)].offset
    }
}

fn section_slot(kind: SectionKind) -> usize {
    kind as usize - 1
}

/// Views a strip's block. The record must be one an opened [`ReducemFile`] holds (validated at
/// open or on first view by `BlockShape` in `reader/validate.rs`) or describe a block the build
/// side just encoded; any other record may panic on a slice bound.
///
/// An opened file views its strips through [`view_block`] with its [`PartTable`]; this computes
/// the part lengths instead.
#[inline]
pub fn strip_view<'a>(
    data: &'a [u8],
    record: &StripRecord,
    leaf_windows: usize,
    layout: &VertexLayout,
) -> StripView<'a> {
    let count = record.reference_count as usize;
    let parts = match layout.kd_trees() {
        true => part_lengths(count, leaf_windows, layout.boxes()),
        false => part_lengths(count, NO_TREE, true),
    };
    view_block(data, record, parts, layout)
}

/// The leaf size that gives every strip a single leaf: how the part lengths of blocks without
/// kd-trees (pooled files) are computed.
pub(super) const NO_TREE: usize = usize::MAX;

/// Internal kd-tree nodes of a block with `count` references (none with [`NO_TREE`]).
#[inline(always)]
fn tree_nodes(count: usize, leaf_windows: usize) -> usize {
    match leaf_windows {
        NO_TREE => 0,
        _ => internal_nodes(count - 2, leaf_windows),
    }
}

/// Bytes of the split axes and of the block boxes of a block with `count` references.
#[inline(always)]
fn part_lengths(count: usize, leaf_windows: usize, boxes: bool) -> (usize, usize) {
    let axes = axis_bytes(tree_nodes(count, leaf_windows));
    match boxes {
        true => (axes, block_boxes::area_bytes(count - 2)),
        false => (axes, 0),
    }
}

/// A block's kd-tree node count and [`part_lengths`] for the reference counts of nearly every
/// strip, computed at open: looking them up rather than computing them (a division by the leaf
/// size or a shift, two roundings, a branch on the box area) took a view from 136 to 113
/// instructions (callgrind, 1M primary rays on the 1M scan).
#[derive(Clone, Debug)]
pub(super) struct PartTable {
    leaf_windows: usize,
    boxes: bool,
    /// Internal kd-tree nodes, split-axis bytes and box bytes for each reference count below
    /// [`PART_TABLE_COUNTS`] (zeros below 3, which no valid record has): at most 253, 64 and
    /// 99.
    entries: [[u8; 3]; PART_TABLE_COUNTS],
}

/// Reference counts [`PartTable`] holds: strips of up to 256 references, the most a strip of
/// [`super::MAX_STRIP_VERTICES`] vertices has without swaps.
const PART_TABLE_COUNTS: usize = 257;

impl PartTable {
    pub(super) fn new(leaf_windows: usize, boxes: bool) -> PartTable {
        let entries = std::array::from_fn(|count| match count {
            0..3 => [0; 3],
            _ => {
                let nodes = tree_nodes(count, leaf_windows);
                let (axes, box_bytes) = part_lengths(count, leaf_windows, boxes);
                [nodes as u8, axes as u8, box_bytes as u8]
            }
        });
        PartTable {
            leaf_windows,
            boxes,
            entries,
        }
    }

    /// Internal kd-tree nodes of a block of `count` references (at least 3).
    #[inline(always)]
    pub(super) fn nodes(&self, count: usize) -> usize {
        match self.entries.get(count) {
            Some(&[nodes, _, _]) => nodes as usize,
            None => tree_nodes(count, self.leaf_windows),
        }
    }

    /// [`part_lengths`] of a block of `count` references (at least 3).
    #[inline(always)]
    pub(super) fn lengths(&self, count: usize) -> (usize, usize) {
        match self.entries.get(count) {
            Some(&[_, axes, boxes]) => (axes as usize, boxes as usize),
            None => part_lengths(count, self.leaf_windows, self.boxes),
        }
    }
}

/// Views `record`'s block, whose split axes and boxes take `parts` bytes ([`part_lengths`]).
///
/// One branch on the layout, each arm computing its block's parts with the layout's variant
/// known: this runs for every strip a ray (or packet) enters, and with the layout matched again
/// for each part a lossless format 3 view cost 190 instructions, 153 then (callgrind, strips'
/// first views by 100k primary rays on the 1M scan). The block is sliced once from its start
/// and split into its parts, each length computed once (the reference width was computed
/// twice): 166 to 146 instructions per view (1M primary rays on the 1M scan).
#[inline(always)]
pub(super) fn view_block<'a>(
    data: &'a [u8],
    record: &StripRecord,
    parts: (usize, usize),
    layout: &VertexLayout,
) -> StripView<'a> {
    try_view_block(data, record, parts, layout).unwrap_or_else(lazy::no_triangles)
}

/// [`view_block`], or `None` when the block does not fit `data` or has fewer than three
/// references: only a record changed after its validation (or never validated) gets there.
#[inline(always)]
pub(super) fn try_view_block<'a>(
    data: &'a [u8],
    record: &StripRecord,
    parts: (usize, usize),
    layout: &VertexLayout,
) -> Option<StripView<'a>> {
    if record.reference_count < 3 {
        return None;
    }
    let block = data.get(record.data_word as usize * 4..)?;
    let count = record.vertex_count as usize;
    match *layout {
        VertexLayout::F32 { boxes } => {
            let parts = BlockParts::new(record, parts, &VertexLayout::F32 { boxes });
            let (vertices, after) = block.split_at_checked(count * F32_VERTEX_BYTES)?;
            // Cast as whole vertices, whose length needs no check that it divides.
            let (vertices, _) = vertices.as_chunks::<F32_VERTEX_BYTES>();
            let vertices: &[Point] = bytemuck::cast_slice(vertices);
            parts.view(after, StripVertices::F32(vertices))
        }
        VertexLayout::Grid {
            grid,
            packed,
            boxes,
        } => {
            let words_layout = VertexLayout::axis_words(&grid, packed);
            let words = words_layout.read(block);
            let vertex_bytes = vertex_part_bytes(count, &words, words_layout);
            let layout = VertexLayout::Grid {
                grid,
                packed,
                boxes,
            };
            let parts = BlockParts::new(record, parts, &layout);
            let block = block.get(..vertex_bytes + parts.bytes())?;
            let vertices = GridVertices::new(block, (&words, words_layout), count, &grid);
            parts.view(block.get(vertex_bytes..)?, StripVertices::Grid(vertices))
        }
        VertexLayout::Pooled { grid } => {
            let header = PartHeader::read(block)?;
            let parts = BlockParts::new(record, parts, &VertexLayout::Pooled { grid });
            let part = block.get(PART_HEADER_BYTES..PART_HEADER_BYTES + parts.bytes())?;
            // The pool follows the part: the vertices are read from the pool's axis words on.
            let pool = block.get(header.pool_distance + POOL_COUNT_BYTES..)?;
            let words_layout = AxisWordLayout::Packed {
                grid_bits: grid.bits,
            };
            let words = words_layout.read(pool);
            let vertices = GridVertices::new(pool, (&words, words_layout), 0, &grid)
                .starting_at(header.base, count);
            parts.view(part, StripVertices::Grid(vertices))
        }
    }
}

/// The lengths of the parts after a block's vertices: split axes, then references, then block
/// boxes.
struct BlockParts {
    axes: usize,
    references: usize,
    boxes: usize,
    count: usize,
    /// Bits per reference: 8 for one byte each.
    width: u32,
    /// References packed at `width` bits (else one byte each).
    packed: bool,
}

impl BlockParts {
    /// The parts of `record`'s block, whose split axes and boxes take `(axes, boxes)` bytes;
    /// `layout` is best a value the caller built, whose variant the compiler then knows.
    #[inline(always)]
    fn new(
        record: &StripRecord,
        (axes, boxes): (usize, usize),
        layout: &VertexLayout,
    ) -> BlockParts {
        let count = record.reference_count as usize;
        let packed = layout.packed_references();
        let width = match packed {
            true => packed_width(record.vertex_count as usize),
            false => 8,
        };
        BlockParts {
            axes,
            references: match packed {
                true => (count * width as usize).div_ceil(8).max(MIN_PACKED_BYTES),
                false => count,
            },
            boxes,
            count,
            width,
            packed,
        }
    }

    /// Bytes of the parts.
    #[inline(always)]
    fn bytes(&self) -> usize {
        self.axes + self.references + self.boxes
    }

    /// The view of the parts at the start of `after_vertices`, the block's bytes after its
    /// vertices (and possibly more).
    #[inline(always)]
    fn view<'a>(
        &self,
        after_vertices: &'a [u8],
        vertices: StripVertices<'a>,
    ) -> Option<StripView<'a>> {
        let (axes, after_axes) = after_vertices.split_at_checked(self.axes)?;
        let after_axes = after_axes.get(..self.references + self.boxes)?;
        let (stored, boxes) = after_axes.split_at_checked(self.references)?;
        let references = match self.packed {
            true => References::packed_at(after_axes, self.references, self.count, self.width),
            false => References::bytes(stored),
        };
        Some(StripView {
            vertices,
            axes,
            references,
            boxes: BlockBoxes::new(boxes),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table a file's views read gives the lengths the validation checked, for every leaf
    /// size and reference count, inside the table and past it.
    #[test]
    fn part_table_agrees_with_computed_lengths() {
        for leaf_windows in 1..=255 {
            for boxes in [false, true] {
                let table = PartTable::new(leaf_windows, boxes);
                for count in 3..PART_TABLE_COUNTS + 40 {
                    let case = format!("leaf {leaf_windows}, boxes {boxes}, {count} references");
                    let computed = part_lengths(count, leaf_windows, boxes);
                    assert_eq!(table.lengths(count), computed, "{case}");
                    let nodes = internal_nodes(count - 2, leaf_windows);
                    assert_eq!(table.nodes(count), nodes, "{case}");
                }
            }
        }
    }
}

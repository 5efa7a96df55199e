//! Writes a ReduceM file: sections first, header last, through [`crate::atomic`], so a crash or
//! a full disk leaves any earlier file at the destination untouched.
//!
//! The sections come from a [`SectionSource`]: the build side's in-memory model, or the
//! pipeline's strip chunks. This module knows the records only, nothing of how they were built.

use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use xxhash_rust::xxh3::Xxh3;

use super::attribute_sections::{AttributeVisit, AttributeWriter};
use super::attributes::{
    AttributeRecord, AttributeSection, AttributeSet, ATTRIBUTE_RECORD_OFFSET, GROUP_STRIPS,
};
use super::counts::{ChunkStats, WeldStats};
use super::grid::Grid;
use super::model::{Closedness, ModelRecord, UpAxis, MODEL_OFFSET};
use super::{
    align_up, Header, PrecisionRecord, SectionEntry, SectionKind, VertexEncoding, WideNode,
    ENDIAN_MARKER, HEADER_CHECKSUMMED_BYTES, HEADER_PAGE, MAGIC, POOLED_MINOR, PRECISION_OFFSET,
    SECTION_ALIGN, SECTION_COUNT, VERSION_MAJOR, VERSION_MINOR,
};
use crate::atomic::{write_atomically, WholeRuns};
use crate::geometry::Aabb;

/// What the header records about the build besides the sections.
#[derive(Clone, Debug, PartialEq)]
pub struct FileInfo {
    pub stats: ChunkStats,
    pub leaf_windows: usize,
    pub max_strip_length: usize,
    pub bounds: Aabb,
    /// The grid the vertices were snapped to; `None` for lossless f32 vertices.
    pub grid: Option<Grid>,
    pub weld: WeldStats,
    /// The attributes stored besides positions (format 2.5 when any).
    pub attributes: AttributeSet,
    /// Edge counts over the whole mesh, when the build counted them (model record, 3.1).
    pub closedness: Option<Closedness>,
    /// The up-axis hint of the model record.
    pub up: Option<UpAxis>,
    /// Whether the strip blocks are pooled grid parts (`vertex_encoding` 5, format 4.1): grid
    /// files without attributes and with leaves of at least 8 windows.
    pub pooled: bool,
}

impl FileInfo {
    /// Lossless (0), pooled grid vertices (5) or packed grid vertices (3); the top-level nodes
    /// are [`WideNode`]s in all.
    fn vertex_encoding(&self) -> VertexEncoding {
        match self.grid {
            Some(_) if self.pooled => VertexEncoding::GridPooled,
            Some(_) => VertexEncoding::GridPackedReferences,
            None => VertexEncoding::F32,
        }
    }
}

/// Writes top-level nodes in the file's record.
pub fn write_nodes(out: &mut dyn Write, nodes: &[WideNode]) -> io::Result<()> {
    out.write_all(bytemuck::cast_slice(nodes))
}

/// A failed write, naming the file.
#[derive(Debug, thiserror::Error)]
#[error("writing {}: {source}", path.display())]
pub struct WriteError {
    pub path: PathBuf,
    #[source]
    pub source: io::Error,
}

/// Produces the sections' bytes in file order; the writer aligns, hashes and places them.
pub trait SectionSource {
    fn strip_count(&self) -> u64;
    fn write_section(&mut self, kind: SectionKind, out: &mut dyn Write) -> io::Result<()>;
    /// Hands every strip's attribute payload to `visit`, in file order; called once per
    /// attribute section when [`FileInfo::attributes`] stores any.
    fn visit_attributes(&mut self, visit: &mut AttributeVisit) -> io::Result<()>;
}

/// Writes a ReduceM file whose sections come from `source`, atomically.
pub fn write_streaming(
    path: &Path,
    info: &FileInfo,
    source: &mut impl SectionSource,
) -> Result<(), WriteError> {
    write_atomically(path, |out| write_sections(out, info, source)).map_err(|source| WriteError {
        path: path.to_path_buf(),
        source,
    })
}

fn write_sections(
    file: &mut BufWriter<File>,
    info: &FileInfo,
    source: &mut impl SectionSource,
) -> io::Result<()> {
    let mut runs = WholeRuns(&mut *file);
    let mut out = SectionWriter::new(&mut runs);
    out.pad_to(HEADER_PAGE)?;
    let mut entries = [SectionEntry::default(); SECTION_COUNT];
    for (entry, kind) in entries.iter_mut().zip(SectionKind::ALL) {
        *entry = out.section(kind as u32, |w| source.write_section(kind, w))?;
    }
    let attribute_record = write_attribute_sections(&mut out, info, source)?;
    let header = header(info, source.strip_count(), entries);
    file.seek(SeekFrom::Start(0))?;
    file.write_all(bytemuck::bytes_of(&header))?;
    file.seek(SeekFrom::Start(PRECISION_OFFSET as u64))?;
    file.write_all(bytemuck::bytes_of(&precision(info)))?;
    file.seek(SeekFrom::Start(ATTRIBUTE_RECORD_OFFSET as u64))?;
    file.write_all(bytemuck::bytes_of(&attribute_record))?;
    file.seek(SeekFrom::Start(MODEL_OFFSET as u64))?;
    let model = ModelRecord::new(info.closedness, info.up);
    file.write_all(bytemuck::bytes_of(&model))?;
    Ok(())
}

/// Writes the attribute sections after `strip_data`, and returns their record (format 3 files
/// always have one; with no attributes its flags and sections are zero).
fn write_attribute_sections<W: Write>(
    out: &mut SectionWriter<W>,
    info: &FileInfo,
    source: &mut impl SectionSource,
) -> io::Result<AttributeRecord> {
    let set = info.attributes;
    if !set.any() {
        return Ok(AttributeRecord::default().sealed());
    }
    let mut writer = AttributeWriter::new(set);
    let mut record = AttributeRecord {
        flags: AttributeRecord::flags_of(&set),
        normal_encoding: set.normals as u32,
        group_strips: GROUP_STRIPS as u32,
        normal_error_max_degrees: info.stats.normal_error_degrees,
        ..AttributeRecord::default()
    };
    for kind in AttributeSection::ALL.into_iter().filter(|&k| set.has(k)) {
        record.sections[kind.slot()] = out.section(kind as u32, |w| {
            writer.write(kind, &mut |visit| source.visit_attributes(visit), w)
        })?;
    }
    Ok(record.sealed())
}

fn precision(info: &FileInfo) -> PrecisionRecord {
    // No node grid since format 4: each wide node has its own frame, so `node_shift` is 0.
    let (grid_bits, grid_origin, grid_cell) = match info.grid {
        Some(grid) => (grid.bits, grid.origin, grid.cell),
        None => (0, [0.0; 3], 0.0),
    };
    let error = &info.stats.quantization;
    let weld = &info.weld.displacement;
    PrecisionRecord {
        grid_bits,
        grid_origin,
        grid_cell,
        error_max: error.max,
        error_rms: error.rms(),
        weld_tolerance: info.weld.tolerance,
        welded_vertex_count: weld.count,
        weld_displacement_max: weld.max,
        weld_displacement_rms: weld.rms(),
        ..PrecisionRecord::default()
    }
    .sealed()
}

fn header(info: &FileInfo, strip_count: u64, sections: [SectionEntry; SECTION_COUNT]) -> Header {
    let encoding = info.vertex_encoding();
    let mut header = Header {
        magic: MAGIC,
        // Format 4: block boxes in every strip block and wide nodes, whatever the encoding.
        version_major: VERSION_MAJOR,
        version_minor: match encoding {
            VertexEncoding::GridPooled => POOLED_MINOR,
            _ => VERSION_MINOR,
        },
        endian_marker: ENDIAN_MARKER,
        header_bytes: std::mem::size_of::<Header>() as u32,
        vertex_encoding: encoding as u32,
        leaf_windows: info.leaf_windows as u32,
        max_strip_length: info.max_strip_length as u32,
        triangle_count: info.stats.triangles,
        strip_count,
        stored_vertex_count: info.stats.stored_vertices,
        input_vertex_count: info.stats.input_vertices,
        dropped_triangle_count: info.stats.dropped_triangles,
        hierarchy_vertex_count: info.stats.hierarchy_vertices,
        bounds_min: info.bounds.min,
        bounds_max: info.bounds.max,
        sections,
        header_checksum: 0,
    };
    header.header_checksum =
        xxhash_rust::xxh3::xxh3_64(&bytemuck::bytes_of(&header)[..HEADER_CHECKSUMMED_BYTES]);
    header
}

/// Sequential writer that aligns sections and hashes them as they pass.
struct SectionWriter<'a, W: Write> {
    out: &'a mut W,
    position: u64,
}

impl<'a, W: Write> SectionWriter<'a, W> {
    fn new(out: &'a mut W) -> SectionWriter<'a, W> {
        SectionWriter { out, position: 0 }
    }

    fn pad_to(&mut self, offset: u64) -> io::Result<()> {
        let zeros = vec![0u8; (offset - self.position) as usize];
        self.out.write_all(&zeros)?;
        self.position = offset;
        Ok(())
    }

    fn section(
        &mut self,
        kind: u32,
        body: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    ) -> io::Result<SectionEntry> {
        self.pad_to(align_up(self.position, SECTION_ALIGN))?;
        let offset = self.position;
        let mut hashing = HashingWriter {
            out: &mut *self.out,
            hasher: Xxh3::new(),
            written: 0,
        };
        body(&mut hashing)?;
        let (length, checksum) = (hashing.written, hashing.hasher.digest());
        self.position += length;
        Ok(SectionEntry {
            kind,
            reserved: 0,
            offset,
            length,
            checksum,
        })
    }
}

struct HashingWriter<'a, W: Write> {
    out: &'a mut W,
    hasher: Xxh3,
    written: u64,
}

impl<W: Write> Write for HashingWriter<'_, W> {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let n = self.out.write(bytes)?;
        self.hasher.update(&bytes[..n]);
        self.written += n as u64;
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

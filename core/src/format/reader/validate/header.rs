//! Header, precision record and section-table checks, before anything else is trusted.

use std::mem::{offset_of, size_of};
use std::ops::Range;
use std::path::Path;

use super::strips::RECORD_BYTES;
use crate::format::block_boxes::BOX_WINDOWS;
use crate::format::grid::{Grid, NodeGrid, MAX_GRID_BITS};
use crate::format::reader::{FormatError, NodeLayout, VertexLayout};
use crate::format::{
    Defect, FilePart, Header, PrecisionRecord, SectionEntry, SectionKind, VertexEncoding,
    ENDIAN_MARKER, HEADER_CHECKSUMMED_BYTES, HEADER_PAGE, MAGIC, OLDEST_READ_MAJOR,
    PRECISION_OFFSET, SECTION_ALIGN, VERSION_MAJOR,
};

/// Header and section-table checks, before anything else is trusted.
pub(super) struct Checker<'a> {
    pub(super) path: &'a Path,
    /// The first page of the file (all of it when shorter).
    pub(super) head: &'a [u8],
    pub(super) file_len: u64,
}

impl Checker<'_> {
    pub(super) fn invalid(
        &self,
        section: FilePart,
        offset: u64,
        defect: Defect,
        detail: String,
    ) -> FormatError {
        FormatError::Invalid {
            path: self.path.to_path_buf(),
            section,
            offset,
            defect,
            detail,
        }
    }

    pub(super) fn header(&self) -> Result<Header, FormatError> {
        if self.file_len < HEADER_PAGE {
            let detail = format!(
                "file is {} bytes, the header page alone is {HEADER_PAGE}",
                self.file_len
            );
            return Err(self.invalid(FilePart::Header, 0, Defect::Truncated, detail));
        }
        let header: Header = bytemuck::pod_read_unaligned(&self.head[..size_of::<Header>()]);
        if header.magic != MAGIC {
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, magic) as u64,
                Defect::BadMagic,
                "not a ReduceM file (bad magic)".into(),
            ));
        }
        if header.endian_marker != ENDIAN_MARKER {
            let detail = format!(
                "endianness marker {:#010x}: written on or read on a big-endian host",
                header.endian_marker
            );
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, endian_marker) as u64,
                Defect::BadEndianMarker,
                detail,
            ));
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
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, version_major) as u64,
                Defect::UnsupportedVersion,
                detail,
            ));
        }
        let checksum = xxhash_rust::xxh3::xxh3_64(&self.head[..HEADER_CHECKSUMMED_BYTES]);
        if checksum != header.header_checksum || header.header_bytes as usize != size_of::<Header>()
        {
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, header_checksum) as u64,
                Defect::ChecksumMismatch,
                "header checksum mismatch".into(),
            ));
        }
        if !(1..=255).contains(&header.leaf_windows) {
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, leaf_windows) as u64,
                Defect::OutOfRange,
                format!("leaf size {} outside 1..=255", header.leaf_windows),
            ));
        }
        Ok(header)
    }

    /// The precision record of a format 2.1 file, checksum checked; zeros for 2.0.
    pub(super) fn precision(&self, header: &Header) -> Result<PrecisionRecord, FormatError> {
        if !header.has_precision_record() {
            return Ok(PrecisionRecord::default());
        }
        let bytes = &self.head[PRECISION_OFFSET..PRECISION_OFFSET + size_of::<PrecisionRecord>()];
        let record: PrecisionRecord = bytemuck::pod_read_unaligned(bytes);
        if record.computed_checksum() != record.checksum {
            return Err(self.invalid(
                FilePart::Header,
                (PRECISION_OFFSET + offset_of!(PrecisionRecord, checksum)) as u64,
                Defect::ChecksumMismatch,
                "precision record checksum mismatch".into(),
            ));
        }
        Ok(record)
    }

    /// The vertex layout and the node record the header and precision record describe,
    /// checked: see [`Checker::vertex_layout`]; format 4 has [`WideNode`](crate::format::WideNode)s
    /// with f32 or packed grid vertices and no node grid.
    pub(super) fn layout(
        &self,
        header: &Header,
        precision: &PrecisionRecord,
    ) -> Result<(VertexLayout, NodeLayout), FormatError> {
        let wide = header.version_major >= 4;
        if wide {
            self.check_format_4_encoding(header, precision)?;
        }
        let (vertices, node_grid) = self.vertex_layout(header, precision)?;
        let nodes = match (wide, node_grid) {
            (true, _) => NodeLayout::Wide,
            (false, Some(grid)) => NodeLayout::Grid(grid),
            (false, None) => NodeLayout::F32,
        };
        Ok((vertices, nodes))
    }

    /// Format 4 stores vertices as f32 or as a packed grid, and its nodes need no node grid.
    fn check_format_4_encoding(
        &self,
        header: &Header,
        precision: &PrecisionRecord,
    ) -> Result<(), FormatError> {
        let encoding = VertexEncoding::from_u32(header.vertex_encoding);
        let pooled = encoding == Some(VertexEncoding::GridPooled)
            && header.version_minor >= VertexEncoding::GridPooled.minor();
        if !pooled
            && !matches!(
                encoding,
                Some(VertexEncoding::F32 | VertexEncoding::GridPackedReferences)
            )
        {
            let detail = format!(
                "vertex encoding {} is not part of format 4",
                header.vertex_encoding
            );
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, vertex_encoding) as u64,
                Defect::BadEncoding,
                detail,
            ));
        }
        if precision.node_shift != 0 {
            let detail = format!("node shift {} in format 4", precision.node_shift);
            return Err(self.invalid(
                FilePart::Header,
                (PRECISION_OFFSET + offset_of!(PrecisionRecord, node_shift)) as u64,
                Defect::Contradiction,
                detail,
            ));
        }
        Ok(())
    }

    /// The vertex layout the header and precision record describe, checked: a grid has 1 to 24
    /// bits, a power-of-two cell and finite corners, so that every grid point decodes to a
    /// finite position; f32 vertices have no grid. With it the grid of format 2 and 3's grid
    /// nodes, if the encoding has them.
    fn vertex_layout(
        &self,
        header: &Header,
        precision: &PrecisionRecord,
    ) -> Result<(VertexLayout, Option<NodeGrid>), FormatError> {
        let at = |field: usize| (PRECISION_OFFSET + field) as u64;
        let Some(encoding) = VertexEncoding::from_u32(header.vertex_encoding) else {
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, vertex_encoding) as u64,
                Defect::BadEncoding,
                format!("unknown vertex encoding {}", header.vertex_encoding),
            ));
        };
        if header.version_major == 2 && header.version_minor < encoding.minor() {
            let detail = format!(
                "vertex encoding {} needs format 2.{} or later",
                header.vertex_encoding,
                encoding.minor()
            );
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, vertex_encoding) as u64,
                Defect::BadEncoding,
                detail,
            ));
        }
        let boxes = header.has_block_boxes();
        if encoding == VertexEncoding::GridPooled {
            self.check_pooled(header)?;
        }
        if boxes && matches!(encoding, VertexEncoding::Grid | VertexEncoding::GridNodes) {
            let detail = format!(
                "vertex encoding {} (unpacked grid blocks) is not part of format 3",
                header.vertex_encoding
            );
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, vertex_encoding) as u64,
                Defect::BadEncoding,
                detail,
            ));
        }
        if !encoding.has_grid_nodes() && precision.node_shift != 0 {
            let detail = format!(
                "node shift {} without grid top-level nodes",
                precision.node_shift
            );
            return Err(self.invalid(
                FilePart::Header,
                at(offset_of!(PrecisionRecord, node_shift)),
                Defect::Contradiction,
                detail,
            ));
        }
        match encoding {
            VertexEncoding::F32 if precision.grid_bits != 0 => Err(self.invalid(
                FilePart::Header,
                at(offset_of!(PrecisionRecord, grid_bits)),
                Defect::Contradiction,
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
                    return Err(self.invalid(
                        FilePart::Header,
                        at(offset_of!(PrecisionRecord, grid_bits)),
                        Defect::OutOfRange,
                        detail,
                    ));
                }
                if !is_power_of_two(grid.cell) {
                    let detail = format!("grid cell {} is not a power of two", grid.cell);
                    return Err(self.invalid(
                        FilePart::Header,
                        at(offset_of!(PrecisionRecord, grid_cell)),
                        Defect::NotPowerOfTwo,
                        detail,
                    ));
                }
                let far = grid.far_corner();
                if !grid.origin.iter().chain(&far).all(|c| c.is_finite()) {
                    let detail = format!(
                        "grid from {:?} in steps of {} is not finite",
                        grid.origin, grid.cell
                    );
                    return Err(self.invalid(
                        FilePart::Header,
                        at(offset_of!(PrecisionRecord, grid_origin)),
                        Defect::NonFinite,
                        detail,
                    ));
                }
                let node_grid = if encoding.has_grid_nodes() {
                    let shift = precision.node_shift;
                    let node_grid = NodeGrid::new(&grid, shift).ok_or_else(|| {
                        let detail =
                            format!("node grid of cell {} * 2^{shift} is not finite", grid.cell);
                        self.invalid(
                            FilePart::Header,
                            at(offset_of!(PrecisionRecord, node_shift)),
                            Defect::NonFinite,
                            detail,
                        )
                    })?;
                    Some(node_grid)
                } else {
                    None
                };
                let packed = encoding == VertexEncoding::GridPackedReferences;
                let layout = match encoding {
                    VertexEncoding::GridPooled => VertexLayout::Pooled { grid },
                    _ => VertexLayout::Grid {
                        grid,
                        packed,
                        boxes,
                    },
                };
                Ok((layout, node_grid))
            }
        }
    }

    /// Pooled grid files (format 4.1) have no strip kd-trees: every strip the tracer would
    /// descend by its kd-tree must have block boxes, so leaves hold at least a box's windows.
    fn check_pooled(&self, header: &Header) -> Result<(), FormatError> {
        if header.version_major < 4 {
            let detail = format!(
                "vertex encoding {} needs format 4.1 or later",
                header.vertex_encoding
            );
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, vertex_encoding) as u64,
                Defect::BadEncoding,
                detail,
            ));
        }
        if (header.leaf_windows as usize) < BOX_WINDOWS {
            let detail = format!(
                "pooled grid vertices with leaves of {} windows, fewer than {BOX_WINDOWS}",
                header.leaf_windows
            );
            return Err(self.invalid(
                FilePart::Header,
                offset_of!(Header, leaf_windows) as u64,
                Defect::Contradiction,
                detail,
            ));
        }
        Ok(())
    }

    /// The node grid of a lossless file with grid nodes (vertex encoding 4): its origin and
    /// cell in the precision record's grid fields, checked as a grid's, with no vertex grid
    /// (`grid_bits` 0) and no shift.
    pub(super) fn lossless_node_grid(
        &self,
        precision: &PrecisionRecord,
    ) -> Result<NodeGrid, FormatError> {
        let at = |field: usize| (PRECISION_OFFSET + field) as u64;
        if precision.grid_bits != 0 {
            let detail = format!("f32 vertices with a {}-bit grid", precision.grid_bits);
            return Err(self.invalid(
                FilePart::Header,
                at(offset_of!(PrecisionRecord, grid_bits)),
                Defect::Contradiction,
                detail,
            ));
        }
        if precision.node_shift != 0 {
            let detail = format!("node shift {} in a lossless file", precision.node_shift);
            return Err(self.invalid(
                FilePart::Header,
                at(offset_of!(PrecisionRecord, node_shift)),
                Defect::Contradiction,
                detail,
            ));
        }
        let base = Grid {
            bits: 0,
            origin: precision.grid_origin,
            cell: precision.grid_cell,
        };
        if !is_power_of_two(base.cell) {
            let detail = format!("node grid cell {} is not a power of two", base.cell);
            return Err(self.invalid(
                FilePart::Header,
                at(offset_of!(PrecisionRecord, grid_cell)),
                Defect::NotPowerOfTwo,
                detail,
            ));
        }
        NodeGrid::new(&base, 0)
            .filter(|node| node.origin.iter().all(|c| c.is_finite()))
            .ok_or_else(|| {
                let detail = format!(
                    "node grid from {:?} in steps of {} is not finite",
                    base.origin, base.cell
                );
                self.invalid(
                    FilePart::Header,
                    at(offset_of!(PrecisionRecord, grid_origin)),
                    Defect::NonFinite,
                    detail,
                )
            })
    }

    /// The section ranges, checked; `node_bytes` is the top-level node record's size.
    pub(super) fn sections(
        &self,
        header: &Header,
        node_bytes: u64,
    ) -> Result<[Range<usize>; 3], FormatError> {
        let mut previous_end = HEADER_PAGE;
        let mut ranges = [0..0, 0..0, 0..0];
        for (slot, kind) in SectionKind::ALL.into_iter().enumerate() {
            let entry = &header.sections[slot];
            let table_offset =
                (offset_of!(Header, sections) + slot * size_of::<SectionEntry>()) as u64;
            let end = entry.offset.saturating_add(entry.length);
            let record = match kind {
                SectionKind::TopNodes => node_bytes,
                SectionKind::StripRecords => RECORD_BYTES,
                SectionKind::StripData => 4,
            };
            let unaligned_or_overlaps = || {
                format!(
                    "{} offset {} is unaligned or overlaps",
                    kind.name(),
                    entry.offset
                )
            };
            let defect = if entry.kind != kind as u32 {
                Some((
                    Defect::BadEncoding,
                    format!(
                        "section {slot} has kind {}, expected {}",
                        entry.kind, kind as u32
                    ),
                ))
            } else if !entry.offset.is_multiple_of(SECTION_ALIGN) {
                Some((Defect::Misaligned, unaligned_or_overlaps()))
            } else if entry.offset < previous_end {
                Some((Defect::Overlap, unaligned_or_overlaps()))
            } else if end > self.file_len {
                Some((
                    Defect::Truncated,
                    format!(
                        "{} ends at {end}, past the file end {}",
                        kind.name(),
                        self.file_len
                    ),
                ))
            } else if !entry.length.is_multiple_of(record)
                || (kind == SectionKind::TopNodes && entry.length == 0)
            {
                Some((
                    Defect::OutOfRange,
                    format!(
                        "{} length {} is not a positive multiple of {record}",
                        kind.name(),
                        entry.length
                    ),
                ))
            } else {
                None
            };
            if let Some((defect, detail)) = defect {
                return Err(self.invalid(FilePart::SectionTable, table_offset, defect, detail));
            }
            ranges[slot] = entry.offset as usize..end as usize;
            previous_end = end;
        }
        Ok(ranges)
    }
}

/// Whether `cell` is a positive normal power of two (grid cells are, so that `q * cell` is
/// exact).
pub(super) fn is_power_of_two(cell: f32) -> bool {
    cell.is_normal() && cell > 0.0 && cell.to_bits() & 0x007f_ffff == 0
}

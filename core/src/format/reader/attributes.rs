//! The attribute sections of a format 2.5 file: checked at open (the record, the section
//! table), looked up per hit, and validated in full with the strips (every face id entry
//! decodes and ends where the next group starts; the vertex groups count the strips' stored
//! vertices exactly).
//!
//! A lookup on a lazily opened file checks what it reads as it reads it; a defect makes it
//! answer `None` and is kept for [`ReducemFile::defect`], as a corrupt strip is.

use std::ops::Range;

use super::{FormatError, ReducemFile};
use crate::format::attributes::{
    decode_normal, read_normal, AttributeRecord, AttributeSection, AttributeSet, FaceIdGroup,
    NormalEncoding, ATTRIBUTE_CHECKSUMMED_BYTES, ATTRIBUTE_RECORD_OFFSET, FLAG_COLORS,
    FLAG_FACE_IDS, FLAG_NORMALS, GROUP_STRIPS,
};
use crate::format::face_ids::{self, BitStream, FaceIdDefect};
use crate::format::{Defect, FilePart};
use crate::format::{Header, SectionEntry, SECTION_ALIGN};

/// A file's attribute record and section ranges (all empty for files before 2.5).
#[derive(Clone, Debug, Default)]
pub(super) struct AttributeSections {
    pub(super) set: AttributeSet,
    pub(super) record: AttributeRecord,
    ranges: [Range<usize>; 5],
}

/// The per-vertex attributes of one strip, in its stored order.
#[derive(Clone, Copy, Debug)]
pub struct VertexAttributes<'a> {
    normals: &'a [u8],
    encoding: NormalEncoding,
    colors: &'a [u8],
}

impl VertexAttributes<'_> {
    /// The unit normal of stored vertex `vertex`, when the file has normals.
    pub fn normal(&self, vertex: usize) -> Option<[f32; 3]> {
        let bytes = self.encoding.bytes();
        let code = self.normals.get(vertex * bytes..(vertex + 1) * bytes)?;
        (bytes > 0).then(|| decode_normal(read_normal(code, self.encoding), self.encoding))
    }

    /// The RGBA8 colour of stored vertex `vertex`, when the file has colours.
    pub fn color(&self, vertex: usize) -> Option<[u8; 4]> {
        let bytes = self.colors.get(vertex * 4..vertex * 4 + 4)?;
        Some([bytes[0], bytes[1], bytes[2], bytes[3]])
    }
}

/// Reads and checks the attribute record of the header page `head` of a file of `file_len`
/// bytes whose last core section ends at `core_end`. Errors are `(offset, kind, detail)` in the
/// header.
pub(super) fn read_record(
    head: &[u8],
    header: &Header,
    core_end: u64,
    file_len: u64,
) -> Result<AttributeSections, (u64, Defect, String)> {
    if !header.has_attribute_record() {
        return Ok(AttributeSections::default());
    }
    let at = |field: usize| (ATTRIBUTE_RECORD_OFFSET + field) as u64;
    let bytes =
        &head[ATTRIBUTE_RECORD_OFFSET..ATTRIBUTE_RECORD_OFFSET + size_of::<AttributeRecord>()];
    let record: AttributeRecord = bytemuck::pod_read_unaligned(bytes);
    if record.computed_checksum() != record.checksum {
        let detail = "attribute record checksum mismatch".to_string();
        return Err((
            at(ATTRIBUTE_CHECKSUMMED_BYTES),
            Defect::ChecksumMismatch,
            detail,
        ));
    }
    if record.flags & !(FLAG_FACE_IDS | FLAG_NORMALS | FLAG_COLORS) != 0 {
        return Err((
            at(0),
            Defect::BadEncoding,
            format!("unknown attribute flags {:#x}", record.flags),
        ));
    }
    let encoding = NormalEncoding::from_u32(record.normal_encoding);
    let has_normals = record.flags & FLAG_NORMALS != 0;
    if encoding.is_none_or(|e| (e != NormalEncoding::None) != has_normals) {
        let detail = format!(
            "normal encoding {} does not match the normals flag",
            record.normal_encoding
        );
        return Err((at(4), Defect::Contradiction, detail));
    }
    let set = record.set();
    let group_strips = if set.any() { GROUP_STRIPS as u32 } else { 0 };
    if record.group_strips != group_strips {
        let detail = format!(
            "{} strips per group, expected {group_strips}",
            record.group_strips
        );
        return Err((at(8), Defect::OutOfRange, detail));
    }
    let groups = header.strip_count.div_ceil(GROUP_STRIPS as u64);
    let mut previous_end = core_end;
    let mut ranges: [Range<usize>; 5] = Default::default();
    for kind in AttributeSection::ALL {
        let entry = &record.sections[kind.slot()];
        let table_offset = at(24 + kind.slot() * 32);
        if !set.has(kind) {
            if *entry != SectionEntry::default() {
                return Err((
                    table_offset,
                    Defect::Contradiction,
                    format!("{} entry of an absent attribute is not zero", kind.name()),
                ));
            }
            continue;
        }
        check_entry(kind, entry, &set, groups, previous_end, file_len)
            .map_err(|(defect, detail)| (table_offset, defect, detail))?;
        let end = entry.offset + entry.length;
        ranges[kind.slot()] = entry.offset as usize..end as usize;
        previous_end = end;
    }
    let per_vertex = |kind: AttributeSection, bytes: usize| {
        set.has(kind).then(|| ranges[kind.slot()].len() / bytes)
    };
    let normals = per_vertex(AttributeSection::Normals, set.normals.bytes().max(1));
    let colors = per_vertex(AttributeSection::Colors, 4);
    if let (Some(normals), Some(colors)) = (normals, colors) {
        if normals != colors {
            let detail = format!("{normals} normals but {colors} colours");
            let at_colors = at(24 + AttributeSection::Colors.slot() * 32 + 16);
            return Err((at_colors, Defect::CountMismatch, detail));
        }
    }
    Ok(AttributeSections {
        set,
        record,
        ranges,
    })
}

fn check_entry(
    kind: AttributeSection,
    entry: &SectionEntry,
    set: &AttributeSet,
    groups: u64,
    previous_end: u64,
    file_len: u64,
) -> Result<(), (Defect, String)> {
    let name = kind.name();
    let end = entry.offset.saturating_add(entry.length);
    if entry.kind != kind as u32 {
        let detail = format!(
            "section {name} has kind {}, expected {}",
            entry.kind, kind as u32
        );
        return Err((Defect::BadEncoding, detail));
    }
    let unaligned_or_overlaps =
        || format!("{name} offset {} is unaligned or overlaps", entry.offset);
    if !entry.offset.is_multiple_of(SECTION_ALIGN) {
        return Err((Defect::Misaligned, unaligned_or_overlaps()));
    }
    if entry.offset < previous_end {
        return Err((Defect::Overlap, unaligned_or_overlaps()));
    }
    if end > file_len {
        let detail = format!("{name} ends at {end}, past the file end {file_len}");
        return Err((Defect::Truncated, detail));
    }
    let length_ok = match kind {
        AttributeSection::FaceIds => true,
        AttributeSection::FaceIdGroups => entry.length == groups * size_of::<FaceIdGroup>() as u64,
        AttributeSection::VertexGroups => entry.length == groups * 8,
        AttributeSection::Normals => entry.length.is_multiple_of(set.normals.bytes() as u64),
        AttributeSection::Colors => entry.length.is_multiple_of(4),
    };
    match length_ok {
        true => Ok(()),
        false => Err((
            Defect::OutOfRange,
            format!(
                "{name} length {} does not fit {groups} groups or its records",
                entry.length
            ),
        )),
    }
}

impl ReducemFile {
    /// The attributes this file stores besides positions.
    pub fn attributes(&self) -> AttributeSet {
        self.attributes.set
    }

    /// The attribute record (zeros before format 2.5).
    pub fn attribute_record(&self) -> &AttributeRecord {
        &self.attributes.record
    }

    /// The bytes of attribute section `kind` (empty when absent).
    pub fn attribute_bytes(&self, kind: AttributeSection) -> &[u8] {
        &self.map[self.attributes.ranges[kind.slot()].clone()]
    }

    fn attribute_offset(&self, kind: AttributeSection) -> u64 {
        self.attributes.ranges[kind.slot()].start as u64
    }

    /// The input face id of `window` of strip `strip`; `None` when the file has no face ids, or
    /// when the entry is corrupt (the defect is kept for [`ReducemFile::defect`]).
    pub fn face_id(&self, strip: usize, window: usize) -> Option<u32> {
        if !self.attributes.set.face_ids {
            return None;
        }
        self.face_id_checked(strip, window)
            .map_err(|defect| self.keep_attribute_defect(AttributeSection::FaceIds, defect))
            .ok()
    }

    fn face_id_checked(&self, strip: usize, window: usize) -> Result<u32, FaceIdDefect> {
        let groups: &[FaceIdGroup] =
            bytemuck::cast_slice(self.attribute_bytes(AttributeSection::FaceIdGroups));
        let group = groups
            .get(strip / GROUP_STRIPS)
            .ok_or_else(|| (0, Defect::OutOfRange, format!("strip {strip} has no group")))?;
        let stream = BitStream::new(self.attribute_bytes(AttributeSection::FaceIds));
        let records = self.strip_records();
        face_ids::face_id(&stream, group, strip, window, |s| {
            records
                .get(s)
                .map_or(0, |r| r.reference_count as u64)
                .saturating_sub(2)
        })
    }

    /// The per-vertex attributes of strip `strip`; `None` when the file has none, or when the
    /// strip's are out of place (the defect is kept).
    pub fn vertex_attributes(&self, strip: usize) -> Option<VertexAttributes<'_>> {
        let set = self.attributes.set;
        if !set.per_vertex() {
            return None;
        }
        let range = self
            .strip_vertex_range(strip)
            .map_err(|defect| self.keep_attribute_defect(AttributeSection::VertexGroups, defect))
            .ok()?;
        let slice = |kind: AttributeSection, bytes: usize| {
            let section = self.attribute_bytes(kind);
            section.get(range.start * bytes..range.end * bytes)
        };
        let normals = slice(AttributeSection::Normals, set.normals.bytes());
        let colors = slice(AttributeSection::Colors, if set.colors { 4 } else { 0 });
        match (normals, colors) {
            (Some(normals), Some(colors)) => Some(VertexAttributes {
                normals,
                encoding: set.normals,
                colors,
            }),
            _ => {
                let detail = format!("strip {strip}'s vertices {range:?} pass the section end");
                let defect = (0, Defect::Truncated, detail);
                self.keep_attribute_defect(AttributeSection::VertexGroups, defect);
                None
            }
        }
    }

    /// The stored vertices of strip `strip` in the order of all strips' stored vertices.
    fn strip_vertex_range(&self, strip: usize) -> Result<Range<usize>, FaceIdDefect> {
        let groups = self.attribute_bytes(AttributeSection::VertexGroups);
        let group = strip / GROUP_STRIPS;
        let first = groups
            .get(group * 8..group * 8 + 8)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default()))
            .ok_or_else(|| {
                let detail = format!("strip {strip} has no vertex group");
                (0, Defect::OutOfRange, detail)
            })?;
        let records = self.strip_records();
        let count = |s: usize| records.get(s).map_or(0, |r| r.vertex_count as u64);
        let start = first + (group * GROUP_STRIPS..strip).map(count).sum::<u64>();
        let start = usize::try_from(start).map_err(|_| {
            let detail = "vertex group beyond memory".to_string();
            (group as u64 * 64, Defect::OutOfRange, detail)
        })?;
        Ok(start..start + count(strip) as usize)
    }

    /// Keeps a defect found at bit (for `face_ids`) or byte `at` of attribute section `kind`.
    fn keep_attribute_defect(&self, kind: AttributeSection, (at, defect, detail): FaceIdDefect) {
        let offset = match kind {
            AttributeSection::FaceIds => at / 8,
            _ => at,
        };
        self.checks.keep(FormatError::Invalid {
            path: self.path.clone(),
            section: FilePart::Attribute(kind),
            offset: self.attribute_offset(kind) + offset,
            defect,
            detail,
        });
    }

    /// Decodes every face id entry and checks the vertex groups against the strip records,
    /// as a full validation does.
    pub(super) fn validate_attributes(&self) -> Result<(), FormatError> {
        self.validate_face_ids()?;
        self.validate_vertex_groups()
    }

    fn validate_face_ids(&self) -> Result<(), FormatError> {
        if !self.attributes.set.face_ids {
            return Ok(());
        }
        let groups: &[FaceIdGroup] =
            bytemuck::cast_slice(self.attribute_bytes(AttributeSection::FaceIdGroups));
        let stream = BitStream::new(self.attribute_bytes(AttributeSection::FaceIds));
        let records = self.strip_records();
        let invalid = |kind: AttributeSection, at: u64, defect: Defect, detail: String| {
            FormatError::Invalid {
                path: self.path.clone(),
                section: FilePart::Attribute(kind),
                offset: self.attribute_offset(kind) + at,
                defect,
                detail,
            }
        };
        let mut expected_start = 0;
        for (index, (group, strips)) in groups.iter().zip(records.chunks(GROUP_STRIPS)).enumerate()
        {
            if group.bit_offset != expected_start {
                let detail = format!(
                    "group {index} starts at bit {}, the previous group ends at bit {expected_start}",
                    group.bit_offset
                );
                return Err(invalid(
                    AttributeSection::FaceIdGroups,
                    index as u64 * 16,
                    Defect::CountMismatch,
                    detail,
                ));
            }
            let windows: Vec<u64> = strips
                .iter()
                .map(|r| (r.reference_count as u64).saturating_sub(2))
                .collect();
            expected_start = face_ids::decode_group(&stream, group, &windows, &mut |_, _| {})
                .map_err(|(at, defect, detail)| {
                    invalid(AttributeSection::FaceIds, at / 8, defect, detail)
                })?;
        }
        if expected_start.div_ceil(8) != stream.bits() / 8 {
            let detail = format!(
                "the entries end at bit {expected_start}, the section is {} bytes",
                stream.bits() / 8
            );
            return Err(invalid(
                AttributeSection::FaceIds,
                expected_start / 8,
                Defect::CountMismatch,
                detail,
            ));
        }
        Ok(())
    }

    fn validate_vertex_groups(&self) -> Result<(), FormatError> {
        if !self.attributes.set.per_vertex() {
            return Ok(());
        }
        let groups = self.attribute_bytes(AttributeSection::VertexGroups);
        let mut expected = 0u64;
        for (index, strips) in self.strip_records().chunks(GROUP_STRIPS).enumerate() {
            let first = u64::from_le_bytes(
                groups[index * 8..index * 8 + 8]
                    .try_into()
                    .unwrap_or_default(),
            );
            if first != expected {
                let detail = format!("group {index} starts at vertex {first}, expected {expected}");
                return Err(FormatError::Invalid {
                    path: self.path.clone(),
                    section: FilePart::Attribute(AttributeSection::VertexGroups),
                    offset: self.attribute_offset(AttributeSection::VertexGroups)
                        + index as u64 * 8,
                    defect: Defect::CountMismatch,
                    detail,
                });
            }
            expected += strips.iter().map(|r| r.vertex_count as u64).sum::<u64>();
        }
        let set = self.attributes.set;
        let (kind, bytes) = match set.normals {
            NormalEncoding::None => (AttributeSection::Colors, 4),
            encoding => (AttributeSection::Normals, encoding.bytes()),
        };
        let stored = self.attribute_bytes(kind).len() / bytes;
        if stored as u64 != expected {
            let detail = format!("{stored} vertices stored, the strips have {expected}");
            return Err(FormatError::Invalid {
                path: self.path.clone(),
                section: FilePart::Attribute(kind),
                offset: self.attribute_offset(kind),
                defect: Defect::CountMismatch,
                detail,
            });
        }
        Ok(())
    }
}

//! The section table: which sections a file has and where each one is.

#[cfg(doc)]
use super::{StripRecord, TopNode};
use bytemuck::{Pod, Zeroable};

use super::attributes::AttributeSection;

/// The sections of a version-2 file, in file order. The discriminant is the on-disk kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum SectionKind {
    /// [`TopNode`] array: the global hierarchy over strips, depth-first.
    TopNodes = 1,
    /// [`StripRecord`] array: where each strip's block starts and its sizes.
    StripRecords = 2,
    /// Strip blocks: vertices, packed split axes, vertex references (packed since 3.0), block
    /// boxes (since 3.0).
    StripData = 3,
}

impl SectionKind {
    pub const ALL: [SectionKind; 3] = [
        SectionKind::TopNodes,
        SectionKind::StripRecords,
        SectionKind::StripData,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SectionKind::TopNodes => "top_nodes",
            SectionKind::StripRecords => "strip_records",
            SectionKind::StripData => "strip_data",
        }
    }
}

/// One entry of the header's section table. 32 bytes.
///
/// | bytes | field |
/// |---|---|
/// | 0..4 | `kind` ([`SectionKind`]) |
/// | 4..8 | reserved, zero |
/// | 8..16 | `offset` from file start, multiple of 4096 |
/// | 16..24 | `length` in bytes |
/// | 24..32 | `checksum`: XXH3-64 of the section bytes |
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct SectionEntry {
    pub kind: u32,
    pub reserved: u32,
    pub offset: u64,
    pub length: u64,
    pub checksum: u64,
}
const _: () = assert!(std::mem::size_of::<SectionEntry>() == 32);

/// Number of entries in the section table.
pub const SECTION_COUNT: usize = SectionKind::ALL.len();

/// Where in a file a defect is: the file as a whole, a record of the header page, or a section.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilePart {
    /// The file as a whole (its length).
    File,
    /// The header, precision and attribute records of the header page.
    Header,
    /// The header's section table.
    SectionTable,
    Section(SectionKind),
    Attribute(AttributeSection),
}

impl std::fmt::Display for FilePart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            FilePart::File => "file",
            FilePart::Header => "header",
            FilePart::SectionTable => "section table",
            FilePart::Section(kind) => kind.name(),
            FilePart::Attribute(kind) => kind.name(),
        })
    }
}

//! The model record (since 3.1): what the conversion learnt about the whole mesh that a reader
//! cannot cheaply find again, stored in the header page after the attribute record. Whether
//! the mesh is closed decides whether inside/outside is exact (one ray's parity) or a vote;
//! the up axis tells a viewer how to stand the model.
//!
//! | bytes | field |
//! |---|---|
//! | 480..488 | `boundary_edges` u64: edges used by exactly one triangle |
//! | 488..496 | `nonmanifold_edges` u64: edges used by more than two triangles, or by two in the same direction |
//! | 496..500 | `up_axis` u32: 0 unknown, 1 +y, 2 +z |
//! | 500..504 | `flags` u32: bit 0 the edge counts are known; other bits 0 |
//! | 504..512 | `checksum`: XXH3-64 of bytes 480..504 |

use bytemuck::{Pod, Zeroable};

use super::reader::ReducemFile;
use super::{Defect, Header};

/// The first minor of format 3 with the model record.
pub const MODEL_MINOR: u16 = 1;

/// Where the record starts in the header page: after the attribute record.
pub const MODEL_OFFSET: usize = 480;

/// Byte length of the record's prefix covered by its checksum.
pub const MODEL_CHECKSUMMED_BYTES: usize = 24;

/// [`ModelRecord::flags`] bit: the edge counts were made by the conversion.
pub const EDGES_COUNTED: u32 = 1;

/// The model record as stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct ModelRecord {
    pub boundary_edges: u64,
    pub nonmanifold_edges: u64,
    pub up_axis: u32,
    pub flags: u32,
    pub checksum: u64,
}
const _: () = assert!(std::mem::size_of::<ModelRecord>() == 32);

/// Edge counts over the whole mesh, from the conversion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Closedness {
    /// Edges used by exactly one triangle.
    pub boundary_edges: u64,
    /// Edges used by more than two triangles, or by two that run them the same way (opposite
    /// windings, so no consistent outside).
    pub nonmanifold_edges: u64,
}

impl Closedness {
    /// Every edge has exactly two triangles that run it in opposite directions.
    pub fn closed(&self) -> bool {
        self.boundary_edges == 0 && self.nonmanifold_edges == 0
    }
}

/// The model's up direction, a hint for viewers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpAxis {
    Y,
    Z,
}

impl UpAxis {
    /// The stored code: 1 for y, 2 for z.
    pub fn code(self) -> u32 {
        match self {
            UpAxis::Y => 1,
            UpAxis::Z => 2,
        }
    }

    /// The axis of stored code `code`; `None` for 0 (unknown).
    pub fn from_code(code: u32) -> Option<UpAxis> {
        match code {
            1 => Some(UpAxis::Y),
            2 => Some(UpAxis::Z),
            _ => None,
        }
    }

    /// `"y"` or `"z"`, as configs and `inspect --json` spell it.
    pub fn name(self) -> &'static str {
        match self {
            UpAxis::Y => "y",
            UpAxis::Z => "z",
        }
    }

    /// The axis a config names (`"y"` or `"z"`).
    pub fn parse(name: &str) -> Option<UpAxis> {
        match name {
            "y" => Some(UpAxis::Y),
            "z" => Some(UpAxis::Z),
            _ => None,
        }
    }
}

impl ModelRecord {
    /// The record a writer stores: `closedness` when it counted edges, with its checksum set.
    pub fn new(closedness: Option<Closedness>, up: Option<UpAxis>) -> ModelRecord {
        let counts = closedness.unwrap_or_default();
        let mut record = ModelRecord {
            boundary_edges: counts.boundary_edges,
            nonmanifold_edges: counts.nonmanifold_edges,
            up_axis: up.map_or(0, UpAxis::code),
            flags: match closedness {
                Some(_) => EDGES_COUNTED,
                None => 0,
            },
            checksum: 0,
        };
        record.checksum = record.computed_checksum();
        record
    }

    pub fn computed_checksum(&self) -> u64 {
        xxhash_rust::xxh3::xxh3_64(&bytemuck::bytes_of(self)[..MODEL_CHECKSUMMED_BYTES])
    }

    pub fn closedness(&self) -> Option<Closedness> {
        (self.flags & EDGES_COUNTED != 0).then_some(Closedness {
            boundary_edges: self.boundary_edges,
            nonmanifold_edges: self.nonmanifold_edges,
        })
    }

    pub fn up(&self) -> Option<UpAxis> {
        UpAxis::from_code(self.up_axis)
    }
}

/// Whether a file of this header has the record (3.1 and later).
pub fn has_model_record(header: &Header) -> bool {
    header.version_major > 3 || (header.version_major == 3 && header.version_minor >= MODEL_MINOR)
}

/// The model record of the header page `head`, checked: `None` for files before 3.1; an error
/// `(byte offset, kind, detail)` for a checksum mismatch, unknown flags or an unknown up axis.
pub fn read_record(
    head: &[u8],
    header: &Header,
) -> Result<Option<ModelRecord>, (u64, Defect, String)> {
    if !has_model_record(header) {
        return Ok(None);
    }
    let end = MODEL_OFFSET + size_of::<ModelRecord>();
    let Some(bytes) = head.get(MODEL_OFFSET..end) else {
        return Err((
            MODEL_OFFSET as u64,
            Defect::Truncated,
            "header page too short for the model record".into(),
        ));
    };
    let record: ModelRecord = bytemuck::pod_read_unaligned(bytes);
    let at = |field: usize| (MODEL_OFFSET + field) as u64;
    if record.computed_checksum() != record.checksum {
        let detail = "model record checksum mismatch".to_string();
        return Err((
            at(MODEL_CHECKSUMMED_BYTES),
            Defect::ChecksumMismatch,
            detail,
        ));
    }
    if record.up_axis > 2 {
        let detail = format!("unknown up axis {}", record.up_axis);
        return Err((at(16), Defect::BadEncoding, detail));
    }
    if record.flags & !EDGES_COUNTED != 0 {
        let detail = format!("unknown model flags {:#x}", record.flags);
        return Err((at(20), Defect::BadEncoding, detail));
    }
    if record.flags & EDGES_COUNTED == 0 && (record.boundary_edges | record.nonmanifold_edges) != 0
    {
        let detail = "edge counts without the counted flag".into();
        return Err((at(0), Defect::Contradiction, detail));
    }
    Ok(Some(record))
}

impl ReducemFile {
    /// The conversion's edge counts; `None` for files written before they were stored (3.0 and
    /// older) or by a writer that did not count them.
    pub fn closedness(&self) -> Option<Closedness> {
        self.model().and_then(|record| record.closedness())
    }

    /// Whether the mesh is known to be closed: false when [`ReducemFile::closedness`] is unknown.
    pub fn closed(&self) -> bool {
        self.closedness().is_some_and(|counts| counts.closed())
    }

    /// The up axis the conversion was told or chose; `None` when unknown.
    pub fn up_axis(&self) -> Option<UpAxis> {
        self.model().and_then(|record| record.up())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(minor: u16) -> Header {
        Header {
            version_major: 3,
            version_minor: minor,
            ..Header::default()
        }
    }

    fn page(record: &ModelRecord) -> Vec<u8> {
        let mut head = vec![0u8; 4096];
        head[MODEL_OFFSET..MODEL_OFFSET + 32].copy_from_slice(bytemuck::bytes_of(record));
        head
    }

    #[test]
    fn records_round_trip_and_older_files_have_none() {
        let counts = Closedness {
            boundary_edges: 7,
            nonmanifold_edges: 2,
        };
        let record = ModelRecord::new(Some(counts), Some(UpAxis::Z));
        let read = read_record(&page(&record), &header(1)).unwrap().unwrap();
        assert_eq!(read.closedness(), Some(counts));
        assert_eq!(read.up(), Some(UpAxis::Z));
        assert_eq!(read_record(&page(&record), &header(0)), Ok(None));
    }

    #[test]
    fn corrupt_records_name_the_byte() {
        let mut record = ModelRecord::new(None, Some(UpAxis::Y));
        record.boundary_edges = 1;
        let error = read_record(&page(&record), &header(1)).unwrap_err();
        assert_eq!((error.0, error.1), (504, Defect::ChecksumMismatch));
        let mut record = ModelRecord::new(None, None);
        record.up_axis = 3;
        record.checksum = record.computed_checksum();
        let error = read_record(&page(&record), &header(1)).unwrap_err();
        assert_eq!((error.0, error.1), (496, Defect::BadEncoding));
    }
}

//! A crafted defect in each record kind is reported in its part of the file at the byte of
//! the field that was changed, computed here from the record layout, with its kind.

mod common;

use std::mem::{offset_of, size_of};

use common::{fixture_bytes, temp_path, torus};
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::{FormatError, ReducemFile};
use reducem::format::{
    Defect, FilePart, Header, PrecisionRecord, SectionEntry, SectionKind, StripRecord, TopNode,
    WideNode, HEADER_CHECKSUMMED_BYTES, PRECISION_OFFSET,
};

fn file_bytes(name: &str, params: &BuildParams) -> Vec<u8> {
    let path = temp_path(name);
    convert_mesh(&torus(24, 12), params, &path).expect("convert");
    std::fs::read(&path).expect("read back")
}

/// The part, absolute offset and kind the opener reports for `bytes`.
fn defect_site(name: &str, bytes: &[u8]) -> (FilePart, u64, Defect) {
    let path = temp_path(name);
    std::fs::write(&path, bytes).expect("write");
    let error = ReducemFile::open(&path).err().expect("defect rejected");
    site_of(&error)
}

fn site_of(error: &FormatError) -> (FilePart, u64, Defect) {
    match *error {
        FormatError::Invalid {
            section,
            offset,
            defect,
            ..
        } => {
            assert_eq!(error.defect(), Some(defect));
            (section, offset, defect)
        }
        ref other => panic!("not a format defect: {other}"),
    }
}

fn header(bytes: &[u8]) -> Header {
    bytemuck::pod_read_unaligned(&bytes[..size_of::<Header>()])
}

/// `bytes` with the header replaced by `header`, its checksum recomputed.
fn with_header(bytes: &[u8], mut header: Header) -> Vec<u8> {
    let mut changed = bytes.to_vec();
    changed[..size_of::<Header>()].copy_from_slice(bytemuck::bytes_of(&header));
    header.header_checksum = xxhash_rust::xxh3::xxh3_64(&changed[..HEADER_CHECKSUMMED_BYTES]);
    changed[..size_of::<Header>()].copy_from_slice(bytemuck::bytes_of(&header));
    changed
}

fn section_offset(bytes: &[u8], kind: SectionKind) -> usize {
    header(bytes).sections[kind as usize - 1].offset as usize
}

#[test]
fn header_defects_are_reported_at_their_field() {
    let bytes = file_bytes("site-header.rdm", &BuildParams::default());
    let mut flipped = bytes.clone();
    flipped[offset_of!(Header, endian_marker)] ^= 0xff;
    let at = offset_of!(Header, endian_marker) as u64;
    assert_eq!(
        defect_site("endian.rdm", &flipped),
        (FilePart::Header, at, Defect::BadEndianMarker)
    );

    let mut flipped = bytes.clone();
    flipped[offset_of!(Header, magic)] ^= 0xff;
    let at = offset_of!(Header, magic) as u64;
    assert_eq!(
        defect_site("magic.rdm", &flipped),
        (FilePart::Header, at, Defect::BadMagic)
    );

    let mut bad = header(&bytes);
    bad.version_major = 99;
    let at = offset_of!(Header, version_major) as u64;
    assert_eq!(
        defect_site("version.rdm", &with_header(&bytes, bad)),
        (FilePart::Header, at, Defect::UnsupportedVersion)
    );

    let mut flipped = bytes.clone();
    flipped[offset_of!(Header, triangle_count)] ^= 1;
    let at = offset_of!(Header, header_checksum) as u64;
    assert_eq!(
        defect_site("header-checksum.rdm", &flipped),
        (FilePart::Header, at, Defect::ChecksumMismatch)
    );

    assert_eq!(
        defect_site("short.rdm", &bytes[..100]),
        (FilePart::Header, 0, Defect::Truncated)
    );

    let mut bad = header(&bytes);
    bad.leaf_windows = 0;
    let at = offset_of!(Header, leaf_windows) as u64;
    assert_eq!(
        defect_site("leaf.rdm", &with_header(&bytes, bad)),
        (FilePart::Header, at, Defect::OutOfRange)
    );
}

#[test]
fn precision_defect_is_reported_at_its_field() {
    let params = BuildParams {
        grid_bits: Some(16),
        ..BuildParams::default()
    };
    let bytes = file_bytes("site-precision.rdm", &params);
    let range = PRECISION_OFFSET..PRECISION_OFFSET + size_of::<PrecisionRecord>();
    let record: PrecisionRecord = bytemuck::pod_read_unaligned(&bytes[range.clone()]);
    let mut tripled = record;
    tripled.grid_cell *= 3.0;
    let mut changed = bytes.clone();
    changed[range.clone()].copy_from_slice(bytemuck::bytes_of(&tripled.sealed()));
    let at = (PRECISION_OFFSET + offset_of!(PrecisionRecord, grid_cell)) as u64;
    assert_eq!(
        defect_site("cell.rdm", &changed),
        (FilePart::Header, at, Defect::NotPowerOfTwo)
    );

    let mut infinite = record;
    infinite.grid_origin[0] = f32::INFINITY;
    let mut changed = bytes.clone();
    changed[range].copy_from_slice(bytemuck::bytes_of(&infinite.sealed()));
    let at = (PRECISION_OFFSET + offset_of!(PrecisionRecord, grid_origin)) as u64;
    assert_eq!(
        defect_site("origin.rdm", &changed),
        (FilePart::Header, at, Defect::NonFinite)
    );
}

#[test]
fn lossless_file_with_a_vertex_grid_is_a_contradiction() {
    let bytes = file_bytes("site-contradiction.rdm", &BuildParams::default());
    let range = PRECISION_OFFSET..PRECISION_OFFSET + size_of::<PrecisionRecord>();
    let mut record: PrecisionRecord = bytemuck::pod_read_unaligned(&bytes[range.clone()]);
    record.grid_bits = 16;
    let mut changed = bytes.clone();
    changed[range].copy_from_slice(bytemuck::bytes_of(&record.sealed()));
    let at = (PRECISION_OFFSET + offset_of!(PrecisionRecord, grid_bits)) as u64;
    assert_eq!(
        defect_site("f32-grid.rdm", &changed),
        (FilePart::Header, at, Defect::Contradiction)
    );
}

#[test]
fn triangle_count_disagreeing_with_the_strips_is_a_count_mismatch() {
    let bytes = file_bytes("site-count.rdm", &BuildParams::default());
    let mut bad = header(&bytes);
    bad.triangle_count += 1;
    let at = offset_of!(Header, triangle_count) as u64;
    assert_eq!(
        defect_site("count.rdm", &with_header(&bytes, bad)),
        (FilePart::Header, at, Defect::CountMismatch)
    );
}

#[test]
fn section_table_defect_is_reported_at_its_entry() {
    let bytes = file_bytes("site-table.rdm", &BuildParams::default());
    let slot = SectionKind::StripRecords as usize - 1;
    let at = offset_of!(Header, sections) + slot * size_of::<SectionEntry>();
    let site = |defect| (FilePart::SectionTable, at as u64, defect);

    let mut bad = header(&bytes);
    bad.sections[slot].offset += 1;
    let unaligned = with_header(&bytes, bad);
    assert_eq!(
        defect_site("table.rdm", &unaligned),
        site(Defect::Misaligned)
    );

    let mut bad = header(&bytes);
    bad.sections[slot].offset = bad.sections[slot - 1].offset;
    let overlapping = with_header(&bytes, bad);
    assert_eq!(
        defect_site("overlap.rdm", &overlapping),
        site(Defect::Overlap)
    );

    let cut = &bytes[..section_offset(&bytes, SectionKind::StripRecords) + 1];
    assert_eq!(defect_site("cut.rdm", cut), site(Defect::Truncated));
}

/// A link of tag 0 with an index (neither empty nor a link) in a format 4 node, and a kind
/// with the internal bit and a count in a format 3.1 one.
#[test]
fn top_node_defect_is_reported_at_its_slot() {
    let wide = file_bytes("site-node.rdm", &BuildParams::default());
    let old = fixture_bytes("tests/fixtures", "torus-format-3.1.rdm");
    for (name, bytes, field, word) in [
        ("node-4.0.rdm", wide, offset_of!(WideNode, link), 5u32),
        ("node-3.1.rdm", old, offset_of!(TopNode, kind), 0x8000_0001),
    ] {
        let at = section_offset(&bytes, SectionKind::TopNodes) + field;
        let mut changed = bytes.clone();
        changed[at..at + 4].copy_from_slice(&word.to_le_bytes());
        assert_eq!(
            defect_site(name, &changed),
            (
                FilePart::Section(SectionKind::TopNodes),
                at as u64,
                Defect::BadEncoding
            ),
            "{name}"
        );
    }
}

#[test]
fn strip_record_defect_is_reported_at_its_record() {
    let bytes = file_bytes("site-record.rdm", &BuildParams::default());
    let strip = 1;
    let record =
        section_offset(&bytes, SectionKind::StripRecords) + strip * size_of::<StripRecord>();
    let at = record + offset_of!(StripRecord, vertex_count);
    let mut changed = bytes.clone();
    changed[at..at + 2].copy_from_slice(&2u16.to_le_bytes());
    assert_eq!(
        defect_site("record.rdm", &changed),
        (
            FilePart::Section(SectionKind::StripRecords),
            record as u64,
            Defect::OutOfRange
        )
    );
}

#[test]
fn section_checksum_defect_is_reported_at_its_section() {
    let bytes = file_bytes("site-checksum.rdm", &BuildParams::default());
    let data = section_offset(&bytes, SectionKind::StripData);
    let mut changed = bytes.clone();
    // The lowest mantissa byte of the first vertex: the structure stays valid.
    changed[data] ^= 1;
    let path = temp_path("checksum.rdm");
    std::fs::write(&path, &changed).expect("write");
    let opened = ReducemFile::open(&path).expect("structure intact");
    let error = opened.verify_checksums().expect_err("checksum differs");
    assert_eq!(
        site_of(&error),
        (
            FilePart::Section(SectionKind::StripData),
            data as u64,
            Defect::ChecksumMismatch
        )
    );
}

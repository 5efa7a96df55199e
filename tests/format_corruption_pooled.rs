//! Crafted pooled grid files (format 4.1, `vertex_encoding` 5): a strip's pool distance, base
//! or references, or its pool's count or axis words, are rejected naming the strip and the
//! byte, at open and on a lazy first view (which then reads the strip as one without
//! triangles), never read out of bounds; the header needs format 4.1 and leaves of at least
//! eight windows.

mod common;

use common::{temp_path, torus};
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::{ReducemFile, Validation};
use reducem::format::{SectionKind, StripRecord, VertexEncoding};

/// A torus on a 16-bit grid, pooled, converted at `name` (tests run in parallel).
fn pooled_bytes(name: &str) -> Vec<u8> {
    let params = BuildParams {
        grid_bits: Some(16),
        leaf_windows: 8,
        ..BuildParams::default()
    };
    let path = temp_path(name);
    convert_mesh(&torus(24, 12), &params, &path).expect("convert");
    let bytes = std::fs::read(&path).expect("read back");
    let encoding = u32::from_le_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!(encoding, VertexEncoding::GridPooled as u32);
    bytes
}

fn section_range(bytes: &[u8], kind: SectionKind) -> (usize, usize) {
    let entry = 104 + (kind as usize - 1) * 32;
    let field = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    (field(entry + 8), field(entry + 16))
}

fn record(bytes: &[u8], index: usize) -> StripRecord {
    let at = section_range(bytes, SectionKind::StripRecords).0 + 8 * index;
    bytemuck::pod_read_unaligned(&bytes[at..at + 8])
}

/// File offset of strip `index`'s part.
fn part_at(bytes: &[u8], index: usize) -> usize {
    section_range(bytes, SectionKind::StripData).0 + 4 * record(bytes, index).data_word as usize
}

/// File offset of strip `index`'s pool.
fn pool_at(bytes: &[u8], index: usize) -> usize {
    let part = part_at(bytes, index);
    part + 4 * u16::from_le_bytes([bytes[part], bytes[part + 1]]) as usize
}

fn edited(bytes: &[u8], at: usize, new: &[u8]) -> Vec<u8> {
    let mut edited = bytes.to_vec();
    edited[at..at + new.len()].copy_from_slice(new);
    edited
}

fn open_error(name: &str, bytes: &[u8]) -> String {
    let path = temp_path(name);
    std::fs::write(&path, bytes).expect("write");
    ReducemFile::open_with(&path, Validation::Full)
        .err()
        .unwrap_or_else(|| panic!("{name} opened"))
        .to_string()
}

/// The defect a lazy open reports once strip `index` is viewed: the view has no triangles.
fn lazy_defect(name: &str, bytes: &[u8], index: usize) -> String {
    let path = temp_path(name);
    std::fs::write(&path, bytes).expect("write");
    let file = ReducemFile::open_with(&path, Validation::Lazy).expect("opens lazily");
    assert!(file.defect().is_none());
    let view = file.strip(index);
    assert!(
        view.triangles().is_empty(),
        "{name}: strip {index} kept triangles"
    );
    file.defect()
        .unwrap_or_else(|| panic!("{name}: no defect"))
        .to_string()
}

fn assert_rejected(name: &str, bytes: &[u8], index: usize, wanted: &str, byte: usize) {
    let strip = format!("strip {index}:");
    let at = format!("at byte {byte}:");
    for message in [open_error(name, bytes), lazy_defect(name, bytes, index)] {
        assert!(
            message.contains(&strip) && message.contains(wanted) && message.contains(&at),
            "{name}: {message}"
        );
    }
}

#[test]
fn the_pooled_source_is_valid() {
    let bytes = pooled_bytes("source-1.rdm");
    let path = temp_path("pooled-valid.rdm");
    std::fs::write(&path, &bytes).expect("write");
    let file = ReducemFile::open_with(&path, Validation::Full).expect("valid");
    file.verify_checksums().expect("checksums");
    assert!(file.strip_count() > 4);
}

#[test]
fn crafted_pool_distances_are_rejected_naming_strip_and_byte() {
    let bytes = pooled_bytes("source-2.rdm");
    let part = part_at(&bytes, 1);
    let overlapping = edited(&bytes, part, &0u16.to_le_bytes());
    assert_rejected("overlap.rdm", &overlapping, 1, "overlaps the part", part);
    let far = edited(&bytes, part, &u16::MAX.to_le_bytes());
    let message = open_error("far.rdm", &far);
    assert!(
        message.contains("strip 1:") && message.contains("past the section end"),
        "{message}"
    );
    lazy_defect("far.rdm", &far, 1);
}

#[test]
fn crafted_bases_and_pool_counts_are_rejected() {
    let bytes = pooled_bytes("source-3.rdm");
    let part = part_at(&bytes, 0);
    let base = edited(&bytes, part + 2, &[255]);
    assert_rejected("base.rdm", &base, 0, "pass the pool's", part + 2);
    let pool = pool_at(&bytes, 0);
    let count = edited(&bytes, pool, &[1]);
    assert_rejected("count.rdm", &count, 0, "pass the pool's 2 points", part + 2);
}

#[test]
fn crafted_pool_axis_words_are_rejected_naming_the_byte() {
    let bytes = pooled_bytes("source-4.rdm");
    let pool = pool_at(&bytes, 0);
    // The x word: 16 anchor bits then 5 width bits, from the byte after the count.
    let mut head = u32::from_le_bytes(bytes[pool + 1..pool + 5].try_into().unwrap());
    head = (head & !(0x1f << 16)) | (17 << 16);
    let wide = edited(&bytes, pool + 1, &head.to_le_bytes());
    assert_rejected("wide.rdm", &wide, 0, "offset width 17", pool + 1);
}

#[test]
fn crafted_references_are_rejected_naming_the_byte() {
    let bytes = pooled_bytes("source-5.rdm");
    let strip = record(&bytes, 0);
    assert!(strip.vertex_count < 128, "references narrower than a byte");
    let part = part_at(&bytes, 0);
    // All bits of the first reference byte set: reference 0 is the width's largest value.
    let crafted = edited(&bytes, part + 3, &[0xff]);
    assert_rejected("reference.rdm", &crafted, 0, "out of range", part + 3);
}

#[test]
fn pooled_headers_need_format_4_1_and_leaves_of_eight_windows() {
    let bytes = pooled_bytes("source-6.rdm");
    let reseal = |mut bytes: Vec<u8>| {
        let checksum = xxhash_rust::xxh3::xxh3_64(&bytes[..200]);
        bytes[200..208].copy_from_slice(&checksum.to_le_bytes());
        bytes
    };
    let minor_0 = reseal(edited(&bytes, 10, &0u16.to_le_bytes()));
    let message = open_error("minor-0.rdm", &minor_0);
    assert!(message.contains("is not part of format 4"), "{message}");
    let leaf_at = std::mem::offset_of!(reducem::format::Header, leaf_windows);
    let short = reseal(edited(&bytes, leaf_at, &4u32.to_le_bytes()));
    let message = open_error("short-leaves.rdm", &short);
    assert!(
        message.contains("fewer than 8") && message.contains(&format!("at byte {leaf_at}")),
        "{message}"
    );
}

//! The opener rejects truncated, bit-flipped and crafted files with an error and never panics;
//! whatever it accepts decodes without panicking.

mod common;

use common::{temp_path, torus};
use reducem::build::{convert_mesh, BuildParams};
use reducem::decode;
use reducem::format::reader::{FormatError, ReducemFile};
use reducem::format::{SectionKind, HEADER_PAGE};

fn valid_file_bytes(name: &str) -> Vec<u8> {
    let path = temp_path(name);
    convert_mesh(&torus(24, 12), &BuildParams::default(), &path).expect("convert");
    std::fs::read(&path).expect("read back")
}

fn open_bytes(name: &str, bytes: &[u8]) -> Result<ReducemFile, FormatError> {
    let path = temp_path(name);
    std::fs::write(&path, bytes).expect("write");
    ReducemFile::open(&path)
}

fn section_range(bytes: &[u8], kind: SectionKind) -> (usize, usize) {
    let entry = 104 + (kind as usize - 1) * 32;
    let field = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    (field(entry + 8), field(entry + 16))
}

fn section_offset(bytes: &[u8], kind: SectionKind) -> usize {
    section_range(bytes, kind).0
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = valid_file_bytes("truncate-source.rdm");
    let step = (bytes.len() / 300).max(1);
    for length in (0..bytes.len()).step_by(step).chain([bytes.len() - 1]) {
        assert!(
            open_bytes("truncated.rdm", &bytes[..length]).is_err(),
            "length {length} of {} opened",
            bytes.len()
        );
    }
}

#[test]
fn every_bit_flip_fails_verification_and_never_panics() {
    let bytes = valid_file_bytes("flip-source.rdm");
    let mut accepted_structurally = 0;
    let in_section = |p: usize| {
        SectionKind::ALL.iter().any(|&kind| {
            let (offset, length) = section_range(&bytes, kind);
            (offset..offset + length).contains(&p)
        })
    };
    // Zero padding between sections carries no meaning and no checksum.
    let positions: Vec<usize> = (0..208)
        .chain(
            (HEADER_PAGE as usize..bytes.len())
                .step_by(7)
                .filter(|&p| in_section(p)),
        )
        .collect();
    for &position in &positions {
        let mut corrupted = bytes.clone();
        corrupted[position] ^= 1 << (position % 8);
        if let Ok(file) = open_bytes("flipped.rdm", &corrupted) {
            accepted_structurally += 1;
            assert_eq!(
                decode::triangles(&file).count() as u64,
                file.header().triangle_count
            );
            assert!(
                file.verify_checksums().is_err(),
                "flip at {position} passed the checksums"
            );
        }
    }
    assert!(
        accepted_structurally > 0,
        "no flip reached the checksum stage"
    );
}

#[test]
fn header_errors_name_the_byte() {
    let bytes = valid_file_bytes("header-source.rdm");
    let mut bad_magic = bytes.clone();
    bad_magic[0] = b'X';
    let message = open_bytes("magic.rdm", &bad_magic)
        .err()
        .expect("bad magic")
        .to_string();
    assert!(
        message.contains("magic.rdm") && message.contains("at byte 0") && message.contains("magic"),
        "{message}"
    );

    let mut big_endian = bytes.clone();
    big_endian[12..16].copy_from_slice(&0x0102_0304u32.to_be_bytes());
    let message = open_bytes("endian.rdm", &big_endian)
        .err()
        .expect("endianness")
        .to_string();
    assert!(
        message.contains("at byte 12") && message.contains("big-endian"),
        "{message}"
    );
}

#[test]
fn crafted_node_and_record_links_are_rejected() {
    let bytes = valid_file_bytes("crafted-source.rdm");
    let nodes = section_offset(&bytes, SectionKind::TopNodes);
    // The root's right child pointing at itself would loop forever.
    let mut self_loop = bytes.clone();
    self_loop[nodes + 24..nodes + 28].copy_from_slice(&0u32.to_le_bytes());
    let message = open_bytes("loop.rdm", &self_loop)
        .err()
        .expect("self loop")
        .to_string();
    assert!(
        message.contains("top_nodes") && message.contains("node 0"),
        "{message}"
    );

    // A strip block pointing past the section end.
    let records = section_offset(&bytes, SectionKind::StripRecords);
    let mut far_block = bytes.clone();
    far_block[records..records + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let message = open_bytes("far.rdm", &far_block)
        .err()
        .expect("far block")
        .to_string();
    assert!(
        message.contains("strip 0") && message.contains("past the section end"),
        "{message}"
    );

    // A reference beyond the strip's vertices.
    let data = section_offset(&bytes, SectionKind::StripData);
    let vertex_count =
        u16::from_le_bytes(bytes[records + 4..records + 6].try_into().unwrap()) as usize;
    let reference_count =
        u16::from_le_bytes(bytes[records + 6..records + 8].try_into().unwrap()) as usize;
    let nodes_in_strip = reducem::format::implicit_tree::internal_nodes(reference_count - 2, 2);
    let first_reference = data + vertex_count * 12 + reducem::format::axis_bytes(nodes_in_strip);
    let mut bad_reference = bytes.clone();
    bad_reference[first_reference] = 255;
    let message = open_bytes("reference.rdm", &bad_reference)
        .err()
        .expect("bad reference")
        .to_string();
    assert!(
        message.contains("reference 255 out of range")
            && message.contains(&format!("at byte {first_reference}")),
        "{message}"
    );
}

//! The opener rejects truncated, bit-flipped and crafted files with an error and never panics;
//! whatever it accepts decodes without panicking. Lossless and grid (quantized) files alike.

mod common;

use common::{temp_path, torus};
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::decode;
use reducem::format::reader::{FormatError, ReducemFile};
use reducem::format::{Defect, PrecisionRecord, SectionKind, HEADER_PAGE, PRECISION_OFFSET};

fn valid_file_bytes(name: &str) -> Vec<u8> {
    file_bytes(name, &BuildParams::default())
}

/// A lossless torus with 64-byte grid top-level nodes (format 2.4).
fn grid_node_file_bytes(name: &str) -> Vec<u8> {
    let params = BuildParams {
        grid_nodes: true,
        ..BuildParams::default()
    };
    file_bytes(name, &params)
}

/// A torus with vertices on a 16-bit grid.
fn grid_file_bytes(name: &str) -> Vec<u8> {
    let params = BuildParams {
        grid_bits: Some(16),
        ..BuildParams::default()
    };
    file_bytes(name, &params)
}

fn file_bytes(name: &str, params: &BuildParams) -> Vec<u8> {
    let path = temp_path(name);
    convert_mesh(&torus(24, 12), params, &path).expect("convert");
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
    assert_truncations_fail(&valid_file_bytes("truncate-source.rdm"));
    assert_truncations_fail(&grid_file_bytes("truncate-grid-source.rdm"));
}

fn assert_truncations_fail(bytes: &[u8]) {
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
    assert_bit_flips_caught(&valid_file_bytes("flip-source.rdm"));
    assert_bit_flips_caught(&grid_file_bytes("flip-grid-source.rdm"));
}

fn assert_bit_flips_caught(bytes: &[u8]) {
    let mut accepted_structurally = 0;
    let in_section = |p: usize| {
        SectionKind::ALL.iter().any(|&kind| {
            let (offset, length) = section_range(bytes, kind);
            (offset..offset + length).contains(&p)
        })
    };
    // Zero padding between sections carries no meaning and no checksum.
    let positions: Vec<usize> = (0..PRECISION_OFFSET + size_of::<PrecisionRecord>())
        .chain(
            (HEADER_PAGE as usize..bytes.len())
                .step_by(7)
                .filter(|&p| in_section(p)),
        )
        .collect();
    for &position in &positions {
        let mut corrupted = bytes.to_vec();
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

/// Byte offsets within a 128-byte top-level node (see `docs/FORMAT.md`).
const NODE_BYTES: usize = 128;
const MIN_FIELD: usize = 0;
const CHILD_FIELD: usize = 96;
const KIND_FIELD: usize = 112;

fn node_word(bytes: &[u8], node: usize, field: usize) -> u32 {
    let at = section_offset(bytes, SectionKind::TopNodes) + node * NODE_BYTES + field;
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

/// A copy of `bytes` with one 4-byte word of node `node` replaced; returns it and the word's
/// file offset.
fn with_node_word(bytes: &[u8], node: usize, field: usize, value: u32) -> (Vec<u8>, usize) {
    let at = section_offset(bytes, SectionKind::TopNodes) + node * NODE_BYTES + field;
    let mut changed = bytes.to_vec();
    changed[at..at + 4].copy_from_slice(&value.to_le_bytes());
    (changed, at)
}

/// The first (node, slot) whose kind satisfies `wanted`, in file order.
fn find_slot(bytes: &[u8], wanted: impl Fn(u32) -> bool) -> (usize, usize) {
    let nodes = section_range(bytes, SectionKind::TopNodes).1 / NODE_BYTES;
    (0..nodes)
        .flat_map(|node| (0..4).map(move |slot| (node, slot)))
        .find(|&(node, slot)| wanted(node_word(bytes, node, KIND_FIELD + 4 * slot)))
        .expect("a slot of the wanted kind")
}

fn rejection(name: &str, bytes: &[u8]) -> String {
    open_bytes(name, bytes)
        .err()
        .unwrap_or_else(|| panic!("{name} opened"))
        .to_string()
}

/// The kind of defect the opener reports for `bytes`.
fn rejection_kind(name: &str, bytes: &[u8]) -> Option<Defect> {
    open_bytes(name, bytes)
        .err()
        .unwrap_or_else(|| panic!("{name} opened"))
        .defect()
}

#[test]
fn crafted_node_links_are_rejected_naming_node_and_byte() {
    const INTERNAL: u32 = 1 << 31;
    let bytes = valid_file_bytes("crafted-nodes-source.rdm");
    let (node, slot) = find_slot(&bytes, |kind| kind == INTERNAL);
    let child_field = CHILD_FIELD + 4 * slot;
    let named = |message: &str, at: usize| {
        message.contains("top_nodes")
            && message.contains(&format!("node {node}:"))
            && message.contains(&format!("at byte {at}"))
    };

    // A child pointing at its own node would loop forever.
    let (self_loop, at) = with_node_word(&bytes, node, child_field, node as u32);
    let message = rejection("loop.rdm", &self_loop);
    assert!(
        named(&message, at) && message.contains("outside"),
        "{message}"
    );
    assert_eq!(
        rejection_kind("loop.rdm", &self_loop),
        Some(Defect::OutOfRange)
    );

    // A child beyond the node array.
    let (far, at) = with_node_word(&bytes, node, child_field, u32::MAX);
    let message = rejection("far-child.rdm", &far);
    assert!(
        named(&message, at) && message.contains("outside"),
        "{message}"
    );

    // Two slots with the same child: a DAG, whose traversal could repeat work exponentially.
    let (other, other_slot) = (0..section_range(&bytes, SectionKind::TopNodes).1 / NODE_BYTES)
        .find_map(|n| {
            let internal: Vec<usize> = (0..4)
                .filter(|&s| node_word(&bytes, n, KIND_FIELD + 4 * s) == INTERNAL)
                .collect();
            (internal.len() >= 2).then(|| (n, internal[1]))
        })
        .expect("a node with two internal children");
    let first_internal = (0..4)
        .find(|&s| node_word(&bytes, other, KIND_FIELD + 4 * s) == INTERNAL)
        .unwrap();
    let sibling = node_word(&bytes, other, CHILD_FIELD + 4 * first_internal);
    let (shared, at) = with_node_word(&bytes, other, CHILD_FIELD + 4 * other_slot, sibling);
    let message = rejection("shared.rdm", &shared);
    assert!(
        message.contains(&format!("node {other}:"))
            && message.contains(&format!("at byte {at}"))
            && message.contains("second parent"),
        "{message}"
    );
    assert_eq!(rejection_kind("shared.rdm", &shared), Some(Defect::BadTree));

    // A kind with the internal bit and a count.
    let (bad_kind, at) = with_node_word(&bytes, node, KIND_FIELD + 4 * slot, INTERNAL | 3);
    let message = rejection("kind.rdm", &bad_kind);
    assert!(
        named(&message, at) && message.contains("neither internal nor a strip count"),
        "{message}"
    );
    assert_eq!(
        rejection_kind("kind.rdm", &bad_kind),
        Some(Defect::BadEncoding)
    );
}

#[test]
fn crafted_leaves_and_empty_slots_are_rejected() {
    const INTERNAL: u32 = 1 << 31;
    let bytes = valid_file_bytes("crafted-leaves-source.rdm");
    let strips = u64::from_le_bytes(bytes[40..48].try_into().unwrap()) as u32;

    // A leaf running past the strip records.
    let (node, slot) = find_slot(&bytes, |kind| kind != 0 && kind != INTERNAL);
    let (long_leaf, _) = with_node_word(&bytes, node, KIND_FIELD + 4 * slot, strips + 1);
    let message = rejection("long-leaf.rdm", &long_leaf);
    assert!(
        message.contains(&format!("node {node}:"))
            && message.contains(&format!("outside 0..{strips}")),
        "{message}"
    );

    // A leaf covering fewer strips than before: some strip is unreachable.
    let kind = node_word(&bytes, node, KIND_FIELD + 4 * slot);
    if kind > 1 {
        let (short_leaf, _) = with_node_word(&bytes, node, KIND_FIELD + 4 * slot, kind - 1);
        let message = rejection("short-leaf.rdm", &short_leaf);
        assert!(message.contains("leaves hold"), "{message}");
        assert_eq!(
            rejection_kind("short-leaf.rdm", &short_leaf),
            Some(Defect::CountMismatch)
        );
    }

    // An empty slot whose box is not exactly the empty box: a ray could enter it.
    let (node, slot) = find_slot(&bytes, |kind| kind == 0);
    let (loose_empty, _) = with_node_word(&bytes, node, MIN_FIELD + 4 * slot, 0);
    let kind_at =
        section_offset(&bytes, SectionKind::TopNodes) + node * NODE_BYTES + KIND_FIELD + 4 * slot;
    let message = rejection("loose-empty.rdm", &loose_empty);
    assert!(
        message.contains(&format!("node {node}:"))
            && message.contains(&format!("at byte {kind_at}"))
            && message.contains("exact empty slot"),
        "{message}"
    );
    assert_eq!(
        rejection_kind("loose-empty.rdm", &loose_empty),
        Some(Defect::BadEncoding)
    );

    // An occupied slot after an empty one.
    let (root_gap, _) = with_node_word(&bytes, 0, KIND_FIELD, 0);
    let message = rejection("gap.rdm", &root_gap);
    assert!(message.contains("node 0:"), "{message}");
}

#[test]
fn version_1_files_are_rejected_with_advice() {
    let mut old = valid_file_bytes("version-source.rdm");
    old[8..10].copy_from_slice(&1u16.to_le_bytes());
    old[10..12].copy_from_slice(&0u16.to_le_bytes());
    let message = rejection("version1.rdm", &old);
    assert!(
        message.contains("at byte 8")
            && message.contains("format version 1.0")
            && message.contains("convert the mesh again"),
        "{message}"
    );
}

#[test]
fn crafted_record_links_are_rejected() {
    let bytes = valid_file_bytes("crafted-source.rdm");
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
    assert_eq!(
        rejection_kind("far.rdm", &far_block),
        Some(Defect::Truncated)
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
    // References are packed at the bits the strip's vertex count needs (format 3): all ones
    // is the largest reference that width holds, past the vertices unless they are a power of
    // two.
    assert!(!vertex_count.is_power_of_two());
    bad_reference[first_reference] = 255;
    let message = open_bytes("reference.rdm", &bad_reference)
        .err()
        .expect("bad reference")
        .to_string();
    let width = reducem::format::references::packed_width(vertex_count);
    assert!(
        message.contains(&format!("reference 0 is {} out of range", (1 << width) - 1))
            && message.contains(&format!("at byte {first_reference}")),
        "{message}"
    );
    assert_eq!(
        rejection_kind("reference.rdm", &bad_reference),
        Some(Defect::OutOfRange)
    );
}

/// A block box exponent outside 1..=254 (a scale that is zero, subnormal or not finite) is
/// rejected naming the strip and the byte; box codes need no check.
#[test]
fn crafted_block_box_exponents_are_rejected() {
    use reducem::format::block_boxes::area_bytes;
    let bytes = valid_file_bytes("crafted-boxes-source.rdm");
    let records = section_offset(&bytes, SectionKind::StripRecords);
    let data = section_offset(&bytes, SectionKind::StripData);
    let strips = section_range(&bytes, SectionKind::StripRecords).1 / 8;
    let record = |s: usize| {
        let at = records + 8 * s;
        let field = |o: usize| u16::from_le_bytes(bytes[at + o..at + o + 2].try_into().unwrap());
        let word = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        (word * 4, field(4) as usize, field(6) as usize)
    };
    let strip = (0..strips)
        .find(|&s| area_bytes(record(s).2 - 2) > 0)
        .expect("a strip with boxes");
    let (start, vertices, references) = record(strip);
    let nodes = reducem::format::implicit_tree::internal_nodes(references - 2, 2);
    let area = data
        + start
        + vertices * 12
        + reducem::format::axis_bytes(nodes)
        + reducem::format::references::packed_bytes(references, vertices);
    for (axis, exponent) in [(0, 0u8), (2, 255)] {
        let mut crafted = bytes.clone();
        crafted[area + axis] = exponent;
        let message = open_error("box-exponent.rdm", &crafted);
        assert!(
            message.contains(&format!("strip {strip}"))
                && message.contains(&format!("at byte {}", area + axis))
                && message.contains(&format!("exponent {exponent} on axis {axis}")),
            "{message}"
        );
    }
    let mut codes = bytes.clone();
    codes[area + 3] ^= 0xff;
    assert!(open_bytes("box-codes.rdm", &codes).is_ok());
}

/// `bytes` with the precision record changed by `edit` and its checksum recomputed.
fn with_precision(bytes: &[u8], edit: impl FnOnce(&mut PrecisionRecord)) -> Vec<u8> {
    let range = PRECISION_OFFSET..PRECISION_OFFSET + size_of::<PrecisionRecord>();
    let mut record: PrecisionRecord = bytemuck::pod_read_unaligned(&bytes[range.clone()]);
    edit(&mut record);
    let mut edited = bytes.to_vec();
    edited[range].copy_from_slice(bytemuck::bytes_of(&record.sealed()));
    edited
}

/// `bytes` with the header claiming format version `major.minor`, its checksum resealed.
fn claiming_version(bytes: &[u8], major: u16, minor: u16) -> Vec<u8> {
    let mut claimed = bytes.to_vec();
    claimed[8..10].copy_from_slice(&major.to_le_bytes());
    claimed[10..12].copy_from_slice(&minor.to_le_bytes());
    let checksum = xxhash_rust::xxh3::xxh3_64(&claimed[..200]);
    claimed[200..208].copy_from_slice(&checksum.to_le_bytes());
    claimed
}

fn open_error(name: &str, bytes: &[u8]) -> String {
    open_bytes(name, bytes)
        .err()
        .unwrap_or_else(|| panic!("{name} opened"))
        .to_string()
}

#[test]
fn crafted_grid_headers_are_rejected_naming_the_byte() {
    let bytes = grid_file_bytes("crafted-grid-header-source.rdm");
    let fine = with_precision(&bytes, |r| r.grid_bits = 25);
    let message = open_error("bits.rdm", &fine);
    assert!(
        message.contains("at byte 208") && message.contains("25 bits"),
        "{message}"
    );
    let uneven = with_precision(&bytes, |r| r.grid_cell = 3.0);
    let message = open_error("cell.rdm", &uneven);
    assert!(
        message.contains("at byte 228") && message.contains("power of two"),
        "{message}"
    );
    // Finite origin and cell, but the far grid points overflow.
    let endless = with_precision(&bytes, |r| {
        r.grid_origin[1] = f32::MAX;
        r.grid_cell = 2f32.powi(110);
    });
    let message = open_error("origin.rdm", &endless);
    assert!(
        message.contains("at byte 216") && message.contains("not finite"),
        "{message}"
    );
    let mut unsealed = bytes.clone();
    unsealed[PRECISION_OFFSET + 24] ^= 1;
    let message = open_error("unsealed.rdm", &unsealed);
    assert!(
        message.contains("at byte 280") && message.contains("precision record checksum"),
        "{message}"
    );
    let lossless = valid_file_bytes("crafted-f32-source.rdm");
    let claimed = with_precision(&lossless, |r| r.grid_bits = 16);
    let message = open_error("claimed.rdm", &claimed);
    assert!(
        message.contains("at byte 208") && message.contains("f32 vertices"),
        "{message}"
    );
}

/// `bytes` with the packed axis word of `axis` (16 anchor bits and 5 width bits per axis on a
/// 16-bit grid) of the block at `block` set to `(anchor, width)`.
fn with_axis_word(bytes: &[u8], block: usize, axis: u32, anchor: u32, width: u32) -> Vec<u8> {
    let mut edited = bytes.to_vec();
    let head = &mut edited[block..block + 16];
    let mut stream = u128::from_le_bytes(head.try_into().unwrap());
    stream &= !(((1u128 << 21) - 1) << (21 * axis));
    stream |= ((anchor | width << 16) as u128) << (21 * axis);
    head.copy_from_slice(&stream.to_le_bytes());
    edited
}

#[test]
fn crafted_grid_blocks_are_rejected_naming_strip_and_byte() {
    let bytes = grid_file_bytes("crafted-grid-block-source.rdm");
    // Record 0's block starts the strip-data section.
    let block = section_offset(&bytes, SectionKind::StripData);
    let wide = with_axis_word(&bytes, block, 0, 0, 17);
    let message = open_error("wide.rdm", &wide);
    assert!(
        message.contains("strip 0")
            && message.contains("offset width 17 exceeds the grid's 16 bits")
            && message.contains(&format!("at byte {block}")),
        "{message}"
    );
    // The y word starts at bit 21, in the block's third byte.
    let off_grid = with_axis_word(&bytes, block, 1, 65_535, 4);
    let message = open_error("off-grid.rdm", &off_grid);
    assert!(
        message.contains("strip 0")
            && message.contains("leaves the 16-bit grid")
            && message.contains(&format!("at byte {}", block + 2)),
        "{message}"
    );
    // Offsets this wide make the block run past the end of the last strip's data.
    let records = section_range(&bytes, SectionKind::StripRecords);
    let last_record = records.0 + records.1 - 8;
    let last_word = u32::from_le_bytes(bytes[last_record..last_record + 4].try_into().unwrap());
    let last_block = block + 4 * last_word as usize;
    let long = (0..3).fold(bytes.clone(), |edited, axis| {
        with_axis_word(&edited, last_block, axis, 0, 16)
    });
    let message = open_error("long.rdm", &long);
    assert!(message.contains("past the section end"), "{message}");
}

/// Byte offsets within a 64-byte grid top-level node (see `docs/FORMAT.md`).
const GRID_NODE_BYTES: usize = 64;
const GRID_MAX_FIELD: usize = 24;
const GRID_LINK_FIELD: usize = 48;
const GRID_INTERNAL: u32 = 15 << 28;

fn grid_node_at(bytes: &[u8], node: usize, field: usize) -> usize {
    section_offset(bytes, SectionKind::TopNodes) + node * GRID_NODE_BYTES + field
}

fn grid_link(bytes: &[u8], node: usize, slot: usize) -> u32 {
    let at = grid_node_at(bytes, node, GRID_LINK_FIELD + 4 * slot);
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

#[test]
fn crafted_grid_nodes_are_rejected_naming_node_and_byte() {
    let bytes = grid_file_bytes("crafted-grid-nodes-source.rdm");
    let nodes = section_range(&bytes, SectionKind::TopNodes).1 / GRID_NODE_BYTES;
    let slots = || (0..nodes).flat_map(|node| (0..4).map(move |slot| (node, slot)));
    let with_link = |node: usize, slot: usize, link: u32| {
        let at = grid_node_at(&bytes, node, GRID_LINK_FIELD + 4 * slot);
        let mut changed = bytes.clone();
        changed[at..at + 4].copy_from_slice(&link.to_le_bytes());
        (changed, at)
    };
    let (node, slot) = slots()
        .find(|&(n, s)| grid_link(&bytes, n, s) >> 28 == 15)
        .expect("an internal slot");
    let named = |message: &str, at: usize| {
        message.contains("top_nodes")
            && message.contains(&format!("node {node}:"))
            && message.contains(&format!("at byte {at}"))
    };

    // A child pointing at its own node would loop forever.
    let (self_loop, at) = with_link(node, slot, GRID_INTERNAL | node as u32);
    let message = rejection("grid-loop.rdm", &self_loop);
    assert!(
        named(&message, at) && message.contains("outside"),
        "{message}"
    );

    // Tag 0 with an index: neither empty nor a link.
    let (untagged, at) = with_link(node, slot, 5);
    let message = rejection("grid-untagged.rdm", &untagged);
    assert!(
        named(&message, at) && message.contains("neither internal nor a strip count"),
        "{message}"
    );

    // A leaf running past the strip records.
    let strips = u64::from_le_bytes(bytes[40..48].try_into().unwrap()) as u32;
    let (leaf_node, leaf_slot) = slots()
        .find(|&(n, s)| (1..15).contains(&(grid_link(&bytes, n, s) >> 28)))
        .expect("a leaf slot");
    let (long_leaf, _) = with_link(leaf_node, leaf_slot, 14 << 28 | strips);
    let message = rejection("grid-long-leaf.rdm", &long_leaf);
    assert!(
        message.contains(&format!("outside 0..{strips}")),
        "{message}"
    );

    // A box whose maximum is below its minimum, named at the minimum's byte.
    let min_at = grid_node_at(&bytes, node, 8 + 2 * slot);
    let max_at = grid_node_at(&bytes, node, GRID_MAX_FIELD + 8 + 2 * slot);
    let mut inverted = bytes.clone();
    inverted[min_at..min_at + 2].copy_from_slice(&2u16.to_le_bytes());
    inverted[max_at..max_at + 2].copy_from_slice(&1u16.to_le_bytes());
    let message = rejection("grid-inverted.rdm", &inverted);
    assert!(
        named(&message, min_at) && message.contains("minimum above its maximum on axis 1"),
        "{message}"
    );

    // An empty slot with a box: it must be all zero bytes.
    let (empty_node, empty_slot) = slots()
        .find(|&(n, s)| grid_link(&bytes, n, s) == 0)
        .expect("an empty slot");
    let mut boxed_empty = bytes.clone();
    boxed_empty[grid_node_at(&bytes, empty_node, GRID_MAX_FIELD + 2 * empty_slot)] = 1;
    let message = rejection("grid-boxed-empty.rdm", &boxed_empty);
    let link_at = grid_node_at(&bytes, empty_node, GRID_LINK_FIELD + 4 * empty_slot);
    assert!(
        message.contains(&format!("node {empty_node}:"))
            && message.contains(&format!("at byte {link_at}"))
            && message.contains("all zero bytes"),
        "{message}"
    );
}

/// A 2.2 reader rejects packed references through `vertex_encoding` 3 (unknown to it); this
/// reader rejects that encoding in a file claiming 2.2, the unpacked grid encodings 1 and 2 in
/// a 3.0 file, and a node shift on an encoding without grid nodes.
#[test]
fn grid_encodings_need_their_format_minor_and_a_finite_node_grid() {
    let bytes = grid_file_bytes("grid-nodes-version-source.rdm");
    assert_eq!(&bytes[8..12], &[3, 0, 1, 0]);
    assert_eq!(&bytes[20..24], &3u32.to_le_bytes());
    let message = open_error("grid-nodes-2.2.rdm", &claiming_version(&bytes, 2, 2));
    assert!(
        message.contains("at byte 20") && message.contains("needs format 2.3"),
        "{message}"
    );
    for encoding in [1u32, 2] {
        let mut unpacked = bytes.clone();
        unpacked[20..24].copy_from_slice(&encoding.to_le_bytes());
        let message = open_error("grid-3.0-unpacked.rdm", &claiming_version(&unpacked, 3, 0));
        assert!(
            message.contains("at byte 20") && message.contains("not part of format 3"),
            "{message}"
        );
    }
    let overflowing = with_precision(&bytes, |r| r.node_shift = 200);
    let message = open_error("node-shift.rdm", &overflowing);
    assert!(
        message.contains("at byte 212") && message.contains("node grid"),
        "{message}"
    );
    let lossless = valid_file_bytes("node-shift-f32-source.rdm");
    let shifted = with_precision(&lossless, |r| r.node_shift = 1);
    let message = open_error("node-shift-f32.rdm", &shifted);
    assert!(
        message.contains("at byte 212") && message.contains("without grid top-level nodes"),
        "{message}"
    );
}

/// A lossless file with grid nodes (vertex encoding 4) keeps its node grid in the precision
/// record's grid fields: a vertex grid, a shift, a cell that is not a power of two or a claim
/// of an older minor are each rejected, naming the byte.
#[test]
fn lossless_grid_nodes_need_format_2_4_and_a_well_formed_node_grid() {
    let bytes = grid_node_file_bytes("lossless-grid-nodes-source.rdm");
    assert_eq!(&bytes[8..12], &[3, 0, 1, 0]);
    assert_eq!(&bytes[20..24], &4u32.to_le_bytes());
    let message = open_error(
        "lossless-grid-nodes-2.3.rdm",
        &claiming_version(&bytes, 2, 3),
    );
    assert!(
        message.contains("at byte 20") && message.contains("needs format 2.4"),
        "{message}"
    );
    type Case = (&'static str, fn(&mut PrecisionRecord), u64, &'static str);
    let cases: [Case; 3] = [
        (
            "bits",
            |r| r.grid_bits = 16,
            208,
            "f32 vertices with a 16-bit grid",
        ),
        (
            "shift",
            |r| r.node_shift = 1,
            212,
            "node shift 1 in a lossless file",
        ),
        ("cell", |r| r.grid_cell *= 1.5, 228, "is not a power of two"),
    ];
    for (name, change, byte, expected) in cases {
        let crafted = with_precision(&bytes, change);
        let message = open_error(&format!("lossless-grid-nodes-{name}.rdm"), &crafted);
        assert!(
            message.contains(&format!("at byte {byte}")) && message.contains(expected),
            "{name}: {message}"
        );
    }
}

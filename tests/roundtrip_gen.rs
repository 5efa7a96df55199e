//! decode(convert(mesh)) on every generator kind, read back through the PLY reader: the exact
//! multiset of non-degenerate input triangles (coordinates and winding) comes back.

mod common;

use common::{canonical_sorted, expected_triangles, temp_path};
use reducem::conversion::{convert_mesh, encode_chunk, strip_bounds, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::input::read_mesh;
use reducem::{decode, strip_encoding, toplevel};
use reducem_gen::{generate, Kind};

fn round_trip(kind: Kind, triangles: u64, params: &BuildParams) {
    let name = format!("{kind:?}-{triangles}-{}", params.leaf_windows);
    let ply = temp_path(&format!("{name}.ply"));
    generate(kind, triangles, 7, &ply).expect("generate");
    let mesh = read_mesh(&ply).expect("read");
    let chunk = encode_chunk(&mesh, params);
    for (i, strip) in chunk.strips.iter().enumerate() {
        strip_encoding::validate(strip, params.leaf_windows, &chunk.grid.into())
            .unwrap_or_else(|e| panic!("{name}: strip {i}: {e}"));
    }
    let bounds = strip_bounds(&chunk.strips);
    toplevel::build(&bounds, &params.top_level)
        .expect("top level")
        .validate(&bounds)
        .unwrap_or_else(|e| panic!("{name}: top level: {e}"));

    let out = temp_path(&format!("{name}.rdm"));
    convert_mesh(&mesh, params, &out).expect("convert");
    let file = ReducemFile::open(&out).expect("open");
    assert_eq!(
        canonical_sorted(decode::triangles(&file)),
        expected_triangles(&mesh),
        "{name}: decoded triangles differ from the input"
    );
}

#[test]
fn every_generator_kind_round_trips() {
    for kind in Kind::ALL {
        round_trip(kind, 20_000, &BuildParams::default());
    }
}

#[test]
fn other_leaf_sizes_and_strip_lengths_round_trip() {
    for (leaf, max_length) in [(1, 4), (3, 60), (4, 128), (8, 200)] {
        let mut params = BuildParams {
            leaf_windows: leaf,
            ..BuildParams::default()
        };
        params.stripify.max_length = max_length;
        round_trip(Kind::Scan, 8_000, &params);
        round_trip(Kind::Cad, 8_000, &params);
    }
}

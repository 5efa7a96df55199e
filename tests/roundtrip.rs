//! decode(convert(mesh)) equals the mesh's non-degenerate triangles, exactly, on hand-made nasty
//! meshes; every strip hierarchy and the top level validate after each build.

mod common;

use common::{canonical_sorted, expected_triangles, grid, temp_path, torus};
use reducem::conversion::{convert_mesh, encode_chunk, strip_bounds, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::mesh::Mesh;
use reducem::{decode, strip_encoding, toplevel};

fn assert_round_trip(name: &str, mesh: &Mesh, params: &BuildParams) {
    let chunk = encode_chunk(mesh, params);
    for (i, strip) in chunk.strips.iter().enumerate() {
        strip_encoding::validate(strip, params.leaf_windows, &chunk.grid.into())
            .unwrap_or_else(|e| panic!("{name}: strip {i}: {e}"));
    }
    let bounds = strip_bounds(&chunk.strips);
    let top = toplevel::build(&bounds, &params.top_level).expect("top level");
    top.validate(&bounds)
        .unwrap_or_else(|e| panic!("{name}: top level: {e}"));

    let path = temp_path(&format!("{name}.rdm"));
    let stats = convert_mesh(mesh, params, &path).expect("convert");
    let file = ReducemFile::open(&path).expect("open");
    file.verify_checksums().expect("checksums");
    let expected = expected_triangles(mesh);
    assert_eq!(
        canonical_sorted(decode::triangles(&file)),
        expected,
        "{name}: decoded triangles differ"
    );
    assert_eq!(stats.triangles, expected.len() as u64);
    assert_eq!(
        stats.dropped_triangles,
        (mesh.triangles.len() - expected.len()) as u64
    );
}

#[test]
fn grid_round_trips_for_several_leaf_sizes_and_lengths() {
    let mesh = grid(40, 30);
    for (leaf, max_length) in [(1, 60), (2, 60), (3, 17), (8, 128), (2, 1)] {
        let mut params = BuildParams {
            leaf_windows: leaf,
            ..BuildParams::default()
        };
        params.stripify.max_length = max_length;
        assert_round_trip(&format!("grid-{leaf}-{max_length}"), &mesh, &params);
    }
}

#[test]
fn closed_torus_round_trips() {
    assert_round_trip("torus", &torus(64, 24), &BuildParams::default());
}

#[test]
fn nasty_mesh_round_trips() {
    let mut mesh = grid(6, 6);
    let n = mesh.positions.len() as u32;
    // Non-manifold: three more triangles on the edge (0, 1).
    mesh.positions
        .extend([[0.5, -1.0, 1.0], [0.5, -1.0, -1.0], [0.5, 1.0, 2.0]]);
    mesh.triangles
        .extend([[0, 1, n], [1, 0, n + 1], [0, 1, n + 2]]);
    // Opposite winding to its neighbour, a duplicate, an isolated triangle.
    mesh.triangles.push(mesh.triangles[10]);
    let flipped = mesh.triangles[20];
    mesh.triangles[20] = [flipped[0], flipped[2], flipped[1]];
    mesh.positions
        .extend([[10.0, 10.0, 10.0], [11.0, 10.0, 10.0], [10.0, 11.0, 10.0]]);
    mesh.triangles.push([n + 3, n + 4, n + 5]);
    // A hole, a repeated-index triangle and a collinear one.
    mesh.triangles.remove(30);
    mesh.triangles.push([3, 3, 4]);
    mesh.positions.push([0.5, 0.0, 0.0]);
    mesh.triangles.push([0, n + 6, 1]);
    assert_round_trip("nasty", &mesh, &BuildParams::default());
}

#[test]
fn unwelded_soup_round_trips() {
    let grid = grid(10, 10);
    let mut soup = Mesh::default();
    for t in &grid.triangles {
        let base = soup.positions.len() as u32;
        soup.positions.extend(grid.triangle_points(t));
        soup.triangles.push([base, base + 1, base + 2]);
    }
    assert_round_trip("soup", &soup, &BuildParams::default());
}

#[test]
fn empty_mesh_round_trips() {
    assert_round_trip("empty", &Mesh::default(), &BuildParams::default());
}

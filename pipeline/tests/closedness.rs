//! The model record through the staged job: the edge counts of a model converted in any
//! number of chunks equal a brute-force count over the input (and the in-memory path's), so a
//! closed model converted in many chunks is closed and answers inside/outside exactly as one
//! converted whole; `[input] up` is stored (y by default for PLY) and an unknown axis is refused.

mod common;

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use reducem::closedness::count_edges;
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::model::{Closedness, UpAxis};
use reducem::format::reader::ReducemFile;
use reducem::input::read_mesh;
use reducem::mesh::Mesh;
use reducem::query::occupancy;
use reducem::stripify::adjacency::is_dropped;
use reducem_gen::{generate, Kind};

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("pipeline-closedness-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Runs the job on `input` with `max_triangles` per chunk and `extra` input keys.
fn staged(dir: &Path, input: &Path, max_triangles: u64, extra: &str) -> ReducemFile {
    let out = dir.join(format!("out-{max_triangles}{}.rdm", extra.len()));
    let config = dir.join("job.toml");
    let body = format!(
        "[input]\npath = {input:?}\n{extra}\n[output]\npath = {out:?}\n\n[chunk]\nmax_triangles = {max_triangles}\n"
    );
    fs::write(&config, body).expect("config");
    let run = common::pipeline(&["run", config.to_str().unwrap(), "--log-format", "plain"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    ReducemFile::open(&out).expect("open")
}

#[test]
fn every_chunk_count_stores_the_in_memory_edge_counts() {
    let dir = temp_dir("chunks");
    for kind in [Kind::Sphere, Kind::Terrain, Kind::Cad] {
        let input = dir.join(format!("{}.ply", kind.name()));
        generate(kind, 4_000, 3, &input).expect("generate");
        let in_memory = dir.join("memory.rdm");
        convert_mesh(
            &read_mesh(&input).expect("read"),
            &BuildParams::default(),
            &in_memory,
        )
        .expect("convert");
        let expected = ReducemFile::open(&in_memory).expect("open").closedness();
        assert!(expected.is_some());
        let one = staged(&dir, &input, 1_000_000, "");
        assert_eq!(one.closedness(), expected, "{}", kind.name());
        assert_eq!(one.up_axis(), Some(UpAxis::Y));
        for max_triangles in [2_001, 300, 40] {
            let several = staged(&dir, &input, max_triangles, "");
            let counts = several.closedness();
            assert_eq!(counts, expected, "{} in {max_triangles}", kind.name());
        }
    }
    let sphere = dir.join("sphere.ply");
    assert!(staged(&dir, &sphere, 1_000_000, "").closed());
    let z_up = staged(&dir, &sphere, 1_000_000, "up = \"z\"");
    assert_eq!(z_up.up_axis(), Some(UpAxis::Z));
    let _ = fs::remove_dir_all(&dir);
}

/// The edge counts of `mesh` by the definition, one map entry per edge: boundary when used
/// once, non-manifold when used more than twice or twice the same way. Triangles Strip-RT
/// drops (two equal corners, no area) are not stored, so not counted.
fn brute_force(mesh: &Mesh) -> Closedness {
    let mut uses: HashMap<([u32; 3], [u32; 3]), (u32, u32)> = HashMap::new();
    for triangle in mesh.triangles.iter().filter(|t| !is_dropped(mesh, t)) {
        let corners = triangle.map(|v| mesh.positions[v as usize].map(f32::to_bits));
        for i in 0..3 {
            let (from, to) = (corners[i], corners[(i + 1) % 3]);
            let entry = uses.entry((from.min(to), from.max(to))).or_default();
            match from < to {
                true => entry.0 += 1,
                false => entry.1 += 1,
            }
        }
    }
    let mut counts = Closedness::default();
    for &(forward, backward) in uses.values() {
        match (forward, backward) {
            (1, 0) | (0, 1) => counts.boundary_edges += 1,
            (1, 1) => {}
            _ => counts.nonmanifold_edges += 1,
        }
    }
    counts
}

fn write_ascii_ply(mesh: &Mesh, path: &Path) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    for p in &mesh.positions {
        text += &format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]);
    }
    for t in &mesh.triangles {
        text += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    fs::write(path, text).expect("write ply");
}

/// A generated sphere, and beside it: the sphere with one triangle flipped, and two spheres
/// sharing one edge (the second the first's point reflection through the edge's midpoint, the
/// edge's ends set exactly): that edge has four uses.
fn sphere_variants(dir: &Path) -> Vec<(&'static str, Mesh)> {
    let path = dir.join("base.ply");
    generate(Kind::Sphere, 3_000, 5, &path).expect("generate");
    let sphere = read_mesh(&path).expect("read");
    let mut flipped = sphere.clone();
    flipped.triangles[17].swap(1, 2);
    let mut joined = sphere.clone();
    let [a, b, _] = sphere.triangles[0];
    let [pa, pb] = [a, b].map(|v| sphere.positions[v as usize]);
    let mut copy: Vec<[f32; 3]> = (sphere.positions.iter())
        .map(|p| [0, 1, 2].map(|i| pa[i] + pb[i] - p[i]))
        .collect();
    (copy[a as usize], copy[b as usize]) = (pb, pa);
    let base = sphere.positions.len() as u32;
    joined.positions.extend(copy);
    joined
        .triangles
        .extend(sphere.triangles.iter().map(|t| t.map(|v| v + base)));
    vec![("sphere", sphere), ("flipped", flipped), ("joined", joined)]
}

#[test]
fn closed_open_and_nonmanifold_meshes_count_as_a_brute_force_in_any_number_of_chunks() {
    let dir = temp_dir("brute");
    for (name, mesh) in sphere_variants(&dir) {
        let input = dir.join(format!("{name}.ply"));
        write_ascii_ply(&mesh, &input);
        let expected = brute_force(&read_mesh(&input).expect("read"));
        match name {
            "sphere" => assert!(expected.closed()),
            "flipped" => assert_eq!(expected.nonmanifold_edges, 3),
            _ => assert_eq!(expected.nonmanifold_edges, 1),
        }
        let triangles = mesh.triangles.len() as u64;
        for max_triangles in [triangles, triangles / 2 + 1, 50] {
            let file = staged(&dir, &input, max_triangles, "");
            let found = file.closedness();
            assert_eq!(found, Some(expected), "{name} in {max_triangles}");
            assert_eq!(file.closed(), expected.closed(), "{name}");
        }
    }
    let terrain = dir.join("terrain.ply");
    generate(Kind::Terrain, 3_000, 5, &terrain).expect("generate");
    let expected = brute_force(&read_mesh(&terrain).expect("read"));
    assert!(expected.boundary_edges > 0);
    for max_triangles in [1_000_000, 1_501, 50] {
        let found = staged(&dir, &terrain, max_triangles, "").closedness();
        assert_eq!(found, Some(expected), "terrain in {max_triangles}");
    }
    let _ = fs::remove_dir_all(&dir);
}

/// The meshes of the fuzz corpus that read as meshes: a cube, pyramids, spheres, a tetrahedron,
/// creased and coloured parts.
fn fuzz_meshes() -> Vec<PathBuf> {
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus");
    let mut paths: Vec<PathBuf> = ["ply", "obj", "stl", "gltf"]
        .iter()
        .flat_map(|format| fs::read_dir(corpus.join(format)).expect("corpus"))
        .map(|entry| entry.expect("corpus entry").path())
        .filter(|path| read_mesh(path).is_ok())
        .collect();
    paths.sort();
    paths
}

#[test]
fn every_generated_kind_and_fuzz_mesh_counts_as_a_brute_force_in_one_chunk_and_many() {
    let dir = temp_dir("kinds");
    let mut inputs = fuzz_meshes();
    assert!(inputs.len() >= 10, "{inputs:?}");
    for kind in Kind::ALL {
        let input = dir.join(format!("{}.ply", kind.name()));
        generate(kind, 3_000, 7, &input).expect("generate");
        inputs.push(input);
    }
    for input in &inputs {
        let mesh = read_mesh(input).expect("read");
        let expected = brute_force(&mesh);
        assert_eq!(count_edges(&mesh), expected, "{}", input.display());
        for max_triangles in [1_000_000, 50] {
            let found = staged(&dir, input, max_triangles, "").closedness();
            let name = input.display();
            assert_eq!(found, Some(expected), "{name} in {max_triangles}");
        }
    }
    let _ = fs::remove_dir_all(&dir);
}

/// `mesh` with unshared vertices, each corner's copy moved by a few ulps and given a normal:
/// a tolerance weld joins the copies again.
fn write_jittered_ply_with_normals(mesh: &Mesh, path: &Path) {
    let mut text = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.triangles.len() * 3,
        mesh.triangles.len()
    );
    for (index, t) in mesh.triangles.iter().enumerate() {
        for (corner, &v) in t.iter().enumerate() {
            let jitter = ((index + corner) % 5) as u32;
            let p = mesh.positions[v as usize].map(|c| f32::from_bits(c.to_bits() + jitter));
            text += &format!("{:?} {:?} {:?} 0 0 1\n", p[0], p[1], p[2]);
        }
    }
    for index in 0..mesh.triangles.len() {
        let first = index * 3;
        text += &format!("3 {} {} {}\n", first, first + 1, first + 2);
    }
    fs::write(path, text).expect("write ply");
}

#[test]
fn a_tolerance_weld_with_normals_closes_a_split_sphere_in_many_chunks() {
    let dir = temp_dir("snapped");
    let base = dir.join("base.ply");
    generate(Kind::Sphere, 2_000, 5, &base).expect("generate");
    let input = dir.join("split.ply");
    write_jittered_ply_with_normals(&read_mesh(&base).expect("read"), &input);
    let keys = "\n[vertices]\nweld_tolerance = 1e-5\n\n[attributes]\nnormals = \"oct16\"\n";
    for max_triangles in [1_000_000, 40] {
        let file = staged(&dir, &input, max_triangles, keys);
        assert_eq!(
            file.closedness(),
            Some(Closedness::default()),
            "{max_triangles}"
        );
    }
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn grid_files_in_many_chunks_count_as_in_one() {
    let dir = temp_dir("grid");
    let input = dir.join("scan.ply");
    generate(Kind::Scan, 6_000, 2, &input).expect("generate");
    // A coarse grid snaps vertices together across chunk borders.
    for bits in [20, 7] {
        let grid = format!("\n[vertices]\nencoding = \"grid\"\ngrid_bits = {bits}\n");
        let one = staged(&dir, &input, 1_000_000, &grid).closedness();
        let many = staged(&dir, &input, 64, &grid).closedness();
        assert_eq!(many, one, "{bits} bits");
        assert!(one.is_some());
    }
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn a_closed_model_in_many_chunks_answers_inside_as_in_one() {
    let dir = temp_dir("inside");
    let input = dir.join("scan.ply");
    generate(Kind::Scan, 5_000, 4, &input).expect("generate");
    let one = staged(&dir, &input, 1_000_000, "");
    let many = staged(&dir, &input, 60, "");
    assert!(one.closed() && many.closed());
    let (min, max) = (one.header().bounds_min, one.header().bounds_max);
    let mut random = reducem::splitmix::SplitMix64::new(9);
    let points: Vec<[f32; 3]> = (0..2_000)
        .map(|_| {
            [0, 1, 2].map(|axis| {
                let t = (random.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
                min[axis] + t * (max[axis] - min[axis])
            })
        })
        .collect();
    let whole = occupancy(&one, &points, 5);
    let chunked = occupancy(&many, &points, 5);
    assert!(whole.exact && chunked.exact);
    assert_eq!(chunked.inside, whole.inside);
    assert!(whole.inside.iter().any(|&inside| inside));
    assert!(whole.inside.iter().any(|&inside| !inside));
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn an_unknown_up_axis_is_refused() {
    let dir = temp_dir("up");
    let config = dir.join("job.toml");
    fs::write(
        &config,
        "[input]\npath = \"in.ply\"\nup = \"x\"\n\n[output]\npath = \"out.rdm\"\n",
    )
    .expect("config");
    let run = common::pipeline(&["run", config.to_str().unwrap(), "--log-format", "plain"]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("up") && stderr.contains("job.toml"),
        "{stderr}"
    );
}

//! Chunked reading keeps attributes: every triangle of every chunk carries its global input face
//! id, and every vertex its exact normal and colour, compared with reading the file whole.
//! Inputs: a binary PLY (streamed through small windows) and an OBJ (read whole), both with
//! quads whose normals change from face to face, so positions repeat with different normals.

use std::path::{Path, PathBuf};

use reducem::chunking::{self, local_mesh, vertices_of, MeshSource};
use reducem::input::{read_mesh_with, weld_identical_positions, AttributeRequest};
use reducem::mesh::Mesh;

const SIDE: u32 = 9;
const ALL: AttributeRequest = AttributeRequest {
    normals: true,
    colors: true,
};

struct TempFile(PathBuf);

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn temp_file(name: &str, bytes: &[u8]) -> TempFile {
    let path = std::env::temp_dir().join(format!(
        "reducem-chunked-attributes-{}-{name}",
        std::process::id()
    ));
    std::fs::write(&path, bytes).expect("write fixture");
    TempFile(path)
}

fn grid_point(i: u32, j: u32) -> [f32; 3] {
    [i as f32, j as f32, ((i * j) % 3) as f32 * 0.25]
}

/// Alternating normals: every edge between two quads is a crease.
fn face_normal(i: u32, j: u32) -> [f32; 3] {
    if (i + j).is_multiple_of(2) {
        [0.0, 0.0, 1.0]
    } else {
        [0.0, 0.6, 0.8]
    }
}

fn quad_corners(i: u32, j: u32) -> [(u32, u32); 4] {
    [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
}

/// Quads with their own four vertex copies each (per-face normals), colours by position.
fn binary_ply() -> Vec<u8> {
    let faces = SIDE * SIDE;
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
         property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         property uchar alpha\nelement face {faces}\nproperty list uchar int vertex_indices\n\
         end_header\n",
        4 * faces
    )
    .into_bytes();
    for (i, j) in quads() {
        for (ci, cj) in quad_corners(i, j) {
            for value in grid_point(ci, cj).into_iter().chain(face_normal(i, j)) {
                bytes.extend_from_slice(&value.to_le_bytes());
            }
            bytes.extend_from_slice(&[ci as u8 * 20, cj as u8 * 20, 7, 200]);
        }
    }
    for face in 0..faces {
        bytes.push(4);
        for corner in 0..4 {
            bytes.extend_from_slice(&((4 * face + corner) as i32).to_le_bytes());
        }
    }
    bytes
}

/// The same surface as OBJ: shared positions with colours, two `vn`, corners `v//vn`.
fn obj() -> String {
    let mut text = String::new();
    for j in 0..=SIDE {
        for i in 0..=SIDE {
            let [x, y, z] = grid_point(i, j);
            let (r, g) = (i as f32 * 20.0 / 255.0, j as f32 * 20.0 / 255.0);
            text += &format!("v {x} {y} {z} {r} {g} 0.5\n");
        }
    }
    text += "vn 0 0 1\nvn 0 0.6 0.8\n";
    for (i, j) in quads() {
        let normal = if (i + j).is_multiple_of(2) { 1 } else { 2 };
        text += "f";
        for (ci, cj) in quad_corners(i, j) {
            text += &format!(" {}//{normal}", cj * (SIDE + 1) + ci + 1);
        }
        text += "\n";
    }
    text
}

fn quads() -> impl Iterator<Item = (u32, u32)> {
    (0..SIDE).flat_map(|j| (0..SIDE).map(move |i| (i, j)))
}

/// A triangle as comparable values: its face and each corner's position, normal and colour.
type Record = (u32, [([u32; 3], [u32; 3], [u8; 4]); 3]);

fn records(mesh: &Mesh) -> Vec<Record> {
    let normals = mesh.normals.as_ref().expect("normals");
    let colors = mesh.colors.as_ref().expect("colours");
    (0..mesh.triangles.len())
        .map(|t| {
            let corners = mesh.triangles[t].map(|v| {
                let v = v as usize;
                (
                    mesh.positions[v].map(f32::to_bits),
                    normals[v].map(f32::to_bits),
                    colors[v],
                )
            });
            (mesh.face_id(t), corners)
        })
        .collect()
}

/// The chunk meshes of `path`, as the pipeline's chunk stage makes them.
fn chunks(path: &Path, tolerance: f32, max_triangles: u64) -> Vec<Mesh> {
    let source = chunking::open_source(path, ALL, 256).expect("open");
    let (source, _) = chunking::weld_source(source, tolerance, ALL).expect("weld");
    let partition = chunking::partition(&*source, max_triangles).expect("partition");
    let mut per_chunk = vec![(Vec::new(), Vec::new()); partition.plan.chunk_count()];
    chunking::distribute(&*source, &partition, &mut |chunk, face, triangle| {
        per_chunk[chunk as usize].0.push(triangle);
        per_chunk[chunk as usize].1.push(face as u32);
    })
    .expect("distribute");
    per_chunk
        .into_iter()
        .map(|(triangles, faces)| {
            let source: &dyn MeshSource = &*source;
            let mesh = local_mesh(&triangles, Some(faces), |ids| vertices_of(source, ids));
            weld_identical_positions(mesh.expect("vertices"))
        })
        .collect()
}

fn assert_chunks_match_whole_read(name: &str, bytes: &[u8]) {
    let file = temp_file(name, bytes);
    let whole = read_mesh_with(&file.0, ALL).expect("read whole");
    assert_eq!(whole.triangles.len() as u32, 2 * SIDE * SIDE);
    let mut expected = records(&whole);
    expected.sort();
    for tolerance in [0.0, 1e-4] {
        let chunks = chunks(&file.0, tolerance, 20);
        assert!(chunks.len() > 4, "{name}: {} chunks", chunks.len());
        let mut found: Vec<Record> = chunks.iter().flat_map(records).collect();
        found.sort();
        assert_eq!(found, expected, "{name}, tolerance {tolerance}");
        // Each face's two triangles, and creases kept: a chunk holds a vertex per
        // (position, normal) pair, never fewer.
        for chunk in &chunks {
            let mut pairs: Vec<_> = records(chunk)
                .iter()
                .flat_map(|(_, corners)| corners.map(|(p, n, _)| (p, n)))
                .collect();
            pairs.sort();
            pairs.dedup();
            assert_eq!(chunk.positions.len(), pairs.len(), "{name}");
        }
    }
}

#[test]
fn streamed_ply_chunks_keep_global_face_ids_and_exact_attributes() {
    assert_chunks_match_whole_read("grid.ply", &binary_ply());
}

#[test]
fn obj_chunks_keep_global_face_ids_and_exact_attributes() {
    assert_chunks_match_whole_read("grid.obj", obj().as_bytes());
}

#[test]
fn face_ids_of_the_whole_read_are_the_input_faces() {
    // Quad q (row-major) is face q, fanned into triangles 2q and 2q + 1.
    for (name, bytes) in [("ids.ply", binary_ply()), ("ids.obj", obj().into_bytes())] {
        let file = temp_file(name, &bytes);
        let whole = read_mesh_with(&file.0, ALL).expect("read");
        let ids: Vec<u32> = (0..whole.triangles.len())
            .map(|t| whole.face_id(t))
            .collect();
        let expected: Vec<u32> = (0..SIDE * SIDE).flat_map(|q| [q, q]).collect();
        assert_eq!(ids, expected, "{name}");
    }
}

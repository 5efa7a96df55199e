//! The generated part of the seed corpus: binary inputs that are easier to write than to keep
//! by hand (ReduceM files, ray files, binary PLY in both byte orders). The text seeds (ASCII
//! PLY, OBJ) are written by hand in `fuzz/corpus/`. Regenerate after a format change with
//! `cargo run -p reducem-fuzz --release -- seed fuzz/corpus`; the seeds of older formats
//! (`reducem/*-format-2.x.rdm` and `reducem/*-format-3.1.rdm`, written by the writers of those
//! versions) are kept by hand, so that the reader of every version this one reads stays fuzzed
//! and the tests of the older read paths have files to read.

use std::path::Path;

use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::attributes::{AttributeSet, NormalEncoding};
use reducem::mesh::Mesh;
use reducem::trace::ray_file::encode_rays;
use reducem::trace::Ray;

use crate::targets::octahedron_sphere;

/// Writes every generated seed under `corpus/<target>/`.
pub fn write_seeds(corpus: &Path) -> std::io::Result<()> {
    let reducem = corpus.join("reducem");
    std::fs::create_dir_all(&reducem)?;
    convert_mesh(
        &octahedron_sphere(2),
        &BuildParams::default(),
        &reducem.join("sphere.rdm"),
    )
    .map_err(std::io::Error::other)?;
    let leaf_of_one = BuildParams {
        leaf_windows: 1,
        ..BuildParams::default()
    };
    convert_mesh(
        &octahedron_sphere(1),
        &leaf_of_one,
        &reducem.join("leaf1.rdm"),
    )
    .map_err(std::io::Error::other)?;
    let grid_nodes = BuildParams {
        grid_nodes: true,
        ..BuildParams::default()
    };
    convert_mesh(
        &octahedron_sphere(2),
        &grid_nodes,
        &reducem.join("sphere-grid-nodes.rdm"),
    )
    .map_err(std::io::Error::other)?;
    convert_mesh(
        &Mesh::default(),
        &BuildParams::default(),
        &reducem.join("empty.rdm"),
    )
    .map_err(std::io::Error::other)?;
    let quantized = BuildParams {
        grid_bits: Some(12),
        ..BuildParams::default()
    };
    convert_mesh(&octahedron_sphere(2), &quantized, &reducem.join("grid.rdm"))
        .map_err(std::io::Error::other)?;
    // Leaves of eight windows make the grid file pooled (format 4.1, `vertex_encoding` 5).
    let pooled = BuildParams {
        leaf_windows: 8,
        ..quantized
    };
    convert_mesh(
        &octahedron_sphere(3),
        &pooled,
        &reducem.join("grid-pooled.rdm"),
    )
    .map_err(std::io::Error::other)?;
    let attributes = BuildParams {
        attributes: AttributeSet {
            face_ids: true,
            normals: NormalEncoding::Oct16,
            colors: true,
        },
        ..BuildParams::default()
    };
    convert_mesh(
        &with_attributes(octahedron_sphere(2)),
        &attributes,
        &reducem.join("attributes.rdm"),
    )
    .map_err(std::io::Error::other)?;

    let rays = corpus.join("rays");
    std::fs::create_dir_all(&rays)?;
    std::fs::write(rays.join("probe.rays"), encode_rays(&probe_rays()))?;

    let ply = corpus.join("ply");
    std::fs::create_dir_all(&ply)?;
    let mesh = octahedron_sphere(1);
    std::fs::write(ply.join("sphere-le.ply"), binary_ply(&mesh, false))?;
    std::fs::write(ply.join("sphere-be.ply"), binary_ply(&mesh, true))?;
    Ok(())
}

/// `mesh` with its positions as normals (the unit sphere's) and a colour per vertex.
fn with_attributes(mut mesh: Mesh) -> Mesh {
    mesh.normals = Some(mesh.positions.clone());
    mesh.colors = Some(
        (0..mesh.positions.len())
            .map(|v| [v as u8, (v * 7) as u8, (v * 13) as u8, 255])
            .collect(),
    );
    mesh
}

/// Rays on the unit sphere's hard spots: axis rays with ±0 components through vertices, a ray
/// along an edge, a ray from inside, and a degenerate `tmin = tmax` interval.
fn probe_rays() -> Vec<Ray> {
    let ray = |origin, direction, tmin, tmax| Ray {
        origin,
        direction,
        tmin,
        tmax,
    };
    vec![
        ray([0.0, 0.0, 5.0], [0.0, -0.0, -1.0], 0.0, f32::INFINITY),
        ray([-0.0, 0.0, -5.0], [-0.0, 0.0, 1.0], 0.0, f32::INFINITY),
        ray([5.0, 0.0, 0.0], [-1.0, 0.0, 0.0], 4.0, 4.0),
        ray([2.0, -1.0, 0.0], [-1.0, 1.0, 0.0], 0.0, 100.0),
        ray([0.1, 0.2, 0.3], [1.0, 1.0, 1.0], 0.0, f32::INFINITY),
        ray([0.0, 0.0, 0.0], [1e-30, 1.0, 1e30], 1e-3, f32::MAX),
    ]
}

/// A binary PLY of `mesh` with a colour property to skip and one quad face to fan.
fn binary_ply(mesh: &Mesh, big_endian: bool) -> Vec<u8> {
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut bytes = format!(
        "ply\nformat {format} 1.0\ncomment fuzz seed\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\nproperty uchar red\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len() + 1
    )
    .into_bytes();
    // Little-endian bytes of a 4-byte value, reversed for a big-endian body.
    let word = |little: [u8; 4]| {
        if big_endian {
            u32::from_le_bytes(little).to_be_bytes()
        } else {
            little
        }
    };
    for p in &mesh.positions {
        for x in p {
            bytes.extend(word(x.to_le_bytes()));
        }
        bytes.push(200);
    }
    let faces = mesh
        .triangles
        .iter()
        .map(|t| t.to_vec())
        .chain([vec![0, 2, 1, 3]]);
    for face in faces {
        bytes.push(face.len() as u8);
        for index in face {
            bytes.extend(word((index as i32).to_le_bytes()));
        }
    }
    bytes
}

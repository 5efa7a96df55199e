//! Which welding of vertices with attributes keeps strips longer: vertices at one position
//! with different normals kept apart (what `reducem::input` does), or joined with the first
//! one's normal winning.
//!
//! `cargo run --release --example attribute_weld -- [triangles] [kind]` (default 200000 cad)
//!
//! The generated mesh is written as OBJ twice: faceted (one `vn` per face, so every edge is a
//! crease) and smoothed (each corner's normal averages the faces around its vertex whose
//! normals lie within 30° of its own face's, so only hard edges split vertices: how CAD
//! exporters write normals). Each is read with normals, welded both ways, stripified with
//! the paper's parameters and the pipeline's (`max_length` 60 and 20), and the average strip
//! length printed.

use std::fmt::Write as _;
use std::path::Path;

use reducem::conversion::PIPELINE_MAX_STRIP_LENGTH;
use reducem::geometry::Point;
use reducem::input::{read_mesh, read_obj_with, weld_identical_positions, AttributeRequest};
use reducem::mesh::Mesh;
use reducem::stripify::{stripify, StripifyParams};
use reducem_gen::Kind;

const CREASE_DEGREES: f32 = 30.0;

fn main() {
    let mut args = std::env::args().skip(1);
    let triangles: u64 = args
        .next()
        .map_or(200_000, |t| t.parse().expect("triangles"));
    let kind: Kind = args
        .next()
        .map_or(Kind::Cad, |k| k.parse().expect("gen kind"));
    let dir = std::env::temp_dir();
    let ply = dir.join(format!("attribute_weld_{}_{triangles}.ply", kind.name()));
    reducem_gen::generate(kind, triangles, 1, &ply).expect("generate");
    let mesh = read_mesh(&ply).expect("read generated mesh");
    println!(
        "{} mesh: {} triangles, {} welded vertices",
        kind.name(),
        mesh.triangles.len(),
        mesh.positions.len()
    );
    for (label, smooth) in [("faceted", false), ("smoothed within 30°", true)] {
        let obj = dir.join(format!("attribute_weld_{}.obj", std::process::id()));
        std::fs::write(&obj, obj_with_normals(&mesh, smooth)).expect("write OBJ");
        report(label, &obj);
        std::fs::remove_file(&obj).expect("remove OBJ");
    }
}

fn report(label: &str, obj: &Path) {
    let request = AttributeRequest {
        normals: true,
        colors: false,
    };
    let read = read_obj_with(obj, request).expect("read OBJ");
    let apart = weld_identical_positions(read.clone());
    let first_wins = weld_identical_positions(Mesh {
        normals: None,
        ..read
    });
    for (name, mesh) in [("stay apart", &apart), ("first wins", &first_wins)] {
        let mut line = format!("{label:>20}, {name}: {:>7} vertices", mesh.positions.len());
        for max_length in [60, PIPELINE_MAX_STRIP_LENGTH] {
            let params = StripifyParams {
                max_length,
                ..StripifyParams::default()
            };
            let strips = stripify(mesh, &params);
            let average = strips.average_strip_length();
            write!(
                line,
                ", average strip length {average:.2} (max {max_length})"
            )
            .unwrap();
        }
        println!("{line}");
    }
}

/// `mesh` as OBJ text whose face corners name normals: each face's own, or smoothed over the
/// faces around the corner's vertex within [`CREASE_DEGREES`].
fn obj_with_normals(mesh: &Mesh, smooth: bool) -> String {
    let face_normals: Vec<Point> = mesh
        .triangles
        .iter()
        .map(|t| unit(face_normal(mesh.triangle_points(t))))
        .collect();
    let mut faces_of_vertex = vec![Vec::new(); mesh.positions.len()];
    for (face, triangle) in mesh.triangles.iter().enumerate() {
        for &v in triangle {
            faces_of_vertex[v as usize].push(face);
        }
    }
    let cos_crease = CREASE_DEGREES.to_radians().cos();
    let mut text = String::new();
    for p in &mesh.positions {
        writeln!(text, "v {} {} {}", p[0], p[1], p[2]).unwrap();
    }
    let mut normal_count = 0;
    for (face, triangle) in mesh.triangles.iter().enumerate() {
        let own = face_normals[face];
        let corner_normals = triangle.map(|v| {
            if !smooth {
                return own;
            }
            let mut sum = [0.0f32; 3];
            for &other in &faces_of_vertex[v as usize] {
                if dot(face_normals[other], own) >= cos_crease {
                    sum = [0, 1, 2].map(|a| sum[a] + face_normals[other][a]);
                }
            }
            unit(sum)
        });
        let mut indices = [0; 3];
        for (corner, normal) in corner_normals.iter().enumerate() {
            writeln!(text, "vn {} {} {}", normal[0], normal[1], normal[2]).unwrap();
            normal_count += 1;
            indices[corner] = normal_count;
        }
        let [a, b, c] = triangle.map(|v| v + 1);
        let [na, nb, nc] = indices;
        writeln!(text, "f {a}//{na} {b}//{nb} {c}//{nc}").unwrap();
    }
    text
}

fn face_normal([a, b, c]: [Point; 3]) -> Point {
    let (u, v) = (
        [0, 1, 2].map(|i| b[i] - a[i]),
        [0, 1, 2].map(|i| c[i] - a[i]),
    );
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

fn dot(a: Point, b: Point) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `v` scaled to unit length; a zero vector (a degenerate face) stays zero.
fn unit(v: Point) -> Point {
    let length = dot(v, v).sqrt();
    if length > 0.0 {
        v.map(|c| c / length)
    } else {
        v
    }
}

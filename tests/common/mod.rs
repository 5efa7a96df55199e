//! Mesh builders and comparison helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

use reducem::geometry::{is_degenerate, Point};
use reducem::mesh::Mesh;

/// A fresh path in the system temp dir, unique per test and process.
pub fn temp_path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reducem-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir.join(name)
}

/// A `w` × `h` quad grid in the z = f(x, y) plane, two triangles per quad, consistent winding.
pub fn grid(w: u32, h: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for y in 0..=h {
        for x in 0..=w {
            let z = ((x * 7 + y * 13) % 5) as f32 * 0.1;
            mesh.positions.push([x as f32, y as f32, z]);
        }
    }
    let id = |x: u32, y: u32| y * (w + 1) + x;
    for y in 0..h {
        for x in 0..w {
            mesh.triangles
                .push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
            mesh.triangles
                .push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
        }
    }
    mesh
}

/// A closed torus with `n` × `m` quads: every edge shared by two consistently wound triangles.
pub fn torus(n: u32, m: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for i in 0..n {
        for j in 0..m {
            let (u, v) = (
                i as f32 / n as f32 * std::f32::consts::TAU,
                j as f32 / m as f32 * std::f32::consts::TAU,
            );
            let r = 3.0 + v.cos();
            mesh.positions.push([r * u.cos(), r * u.sin(), v.sin()]);
        }
    }
    let id = |i: u32, j: u32| (i % n) * m + (j % m);
    for i in 0..n {
        for j in 0..m {
            mesh.triangles
                .push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            mesh.triangles
                .push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    mesh
}

/// Corner positions rotated so the lexicographically smallest bit pattern comes first: equal
/// for two triangles exactly when they have the same corners in the same winding.
pub fn canonical(t: [Point; 3]) -> [[u32; 3]; 3] {
    let bits = t.map(|p| p.map(f32::to_bits));
    let first = (0..3).min_by_key(|&i| bits[i]).unwrap_or(0);
    [0, 1, 2].map(|k| bits[(first + k) % 3])
}

/// The sorted canonical multiset of a mesh's non-degenerate triangles.
pub fn expected_triangles(mesh: &Mesh) -> Vec<[[u32; 3]; 3]> {
    let mut all: Vec<_> = mesh
        .triangles
        .iter()
        .map(|t| mesh.triangle_points(t))
        .filter(|[a, b, c]| !is_degenerate(a, b, c))
        .map(canonical)
        .collect();
    all.sort_unstable();
    all
}

/// The sorted canonical multiset of decoded triangles.
pub fn canonical_sorted(triangles: impl Iterator<Item = [Point; 3]>) -> Vec<[[u32; 3]; 3]> {
    let mut all: Vec<_> = triangles.map(canonical).collect();
    all.sort_unstable();
    all
}

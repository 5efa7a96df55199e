//! Test-only reader for the generators' own PLY output and the mesh checks
//! the tests share (validity, manifoldness, winding, volume, components).
//!
//! The reader accepts exactly the header the writer produces, so any drift in
//! the format fails loudly instead of being tolerated.

use std::collections::HashMap;
use std::path::Path;

use super::{generate, GenSummary, Kind};

pub struct Mesh {
    pub comment: String,
    pub positions: Vec<[f32; 3]>,
    pub faces: Vec<[u32; 3]>,
}

/// Generates `kind` into a temporary directory, reads it back and runs the
/// checks every kind must pass.
pub fn generated(kind: Kind, triangles: u64, seed: u64) -> (GenSummary, Mesh) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.ply");
    let summary = generate(kind, triangles, seed, &path).unwrap();
    let mesh = Mesh::read(&path);
    assert_eq!(mesh.positions.len() as u64, summary.vertices);
    assert_eq!(mesh.faces.len() as u64, summary.triangles);
    let name = format!("kind={kind}");
    assert!(mesh.comment.contains(&name) && mesh.comment.contains(&format!("seed={seed}")));
    mesh.assert_indices_in_range();
    mesh.assert_no_degenerate_triangles();
    (summary, mesh)
}

fn take_line<'a>(bytes: &mut &'a [u8]) -> &'a str {
    let end = bytes.iter().position(|&b| b == b'\n').expect("header line");
    let line = std::str::from_utf8(&bytes[..end]).unwrap();
    *bytes = &bytes[end + 1..];
    line
}

fn expect_count(line: &str, prefix: &str) -> usize {
    line.strip_prefix(prefix)
        .unwrap_or_else(|| panic!("expected `{prefix}...`, got `{line}`"))
        .parse()
        .unwrap()
}

fn le_u32(bytes: &[u8]) -> u32 {
    u32::from_le_bytes(bytes.try_into().unwrap())
}

impl Mesh {
    pub fn read(path: &Path) -> Mesh {
        let data = std::fs::read(path).unwrap();
        let mut rest = &data[..];
        assert_eq!(take_line(&mut rest), "ply");
        assert_eq!(take_line(&mut rest), "format binary_little_endian 1.0");
        let comment = take_line(&mut rest)
            .strip_prefix("comment ")
            .unwrap()
            .to_string();
        let vertices = expect_count(take_line(&mut rest), "element vertex ");
        for axis in ["x", "y", "z"] {
            assert_eq!(take_line(&mut rest), format!("property float {axis}"));
        }
        let faces = expect_count(take_line(&mut rest), "element face ");
        assert_eq!(
            take_line(&mut rest),
            "property list uchar int vertex_indices"
        );
        assert_eq!(take_line(&mut rest), "end_header");
        assert_eq!(
            rest.len(),
            vertices * 12 + faces * 13,
            "body size disagrees with header"
        );
        let (vertex_bytes, face_bytes) = rest.split_at(vertices * 12);
        let positions = vertex_bytes
            .chunks_exact(12)
            .map(|r| [0, 4, 8].map(|o| f32::from_bits(le_u32(&r[o..o + 4]))))
            .collect();
        let faces = face_bytes
            .chunks_exact(13)
            .map(|r| {
                assert_eq!(r[0], 3, "non-triangle face");
                [1, 5, 9].map(|o| le_u32(&r[o..o + 4]))
            })
            .collect();
        Mesh {
            comment,
            positions,
            faces,
        }
    }

    fn corner(&self, index: u32) -> [f64; 3] {
        self.positions[index as usize].map(f64::from)
    }

    pub fn area(&self, face: [u32; 3]) -> f64 {
        let [a, b, c] = face.map(|i| self.corner(i));
        let (u, v) = (sub(b, a), sub(c, a));
        0.5 * norm(cross(u, v))
    }

    pub fn assert_indices_in_range(&self) {
        let limit = self.positions.len() as u32;
        assert!(
            self.faces.iter().flatten().all(|&i| i < limit),
            "index out of range"
        );
    }

    pub fn assert_no_degenerate_triangles(&self) {
        for &face in &self.faces {
            let [a, b, c] = face;
            assert!(a != b && b != c && a != c, "repeated vertex in {face:?}");
            assert!(self.area(face) > 0.0, "zero-area triangle {face:?}");
        }
    }

    /// Uses of each undirected edge: (traversals low->high, high->low).
    fn edge_uses(&self) -> HashMap<(u32, u32), (u32, u32)> {
        let mut uses: HashMap<(u32, u32), (u32, u32)> = HashMap::new();
        for face in &self.faces {
            for k in 0..3 {
                let (from, to) = (face[k], face[(k + 1) % 3]);
                let entry = uses.entry((from.min(to), from.max(to))).or_default();
                if from < to {
                    entry.0 += 1;
                } else {
                    entry.1 += 1;
                }
            }
        }
        uses
    }

    /// Every edge is used once in each direction: closed, manifold along
    /// edges, and consistently wound.
    pub fn assert_closed_consistent_manifold(&self) {
        for (edge, uses) in self.edge_uses() {
            assert_eq!(uses, (1, 1), "edge {edge:?} used {uses:?}");
        }
    }

    /// Every edge is used at most once in each direction; returns how many
    /// edges are boundary (used once).
    pub fn assert_consistent_manifold_with_boundary(&self) -> usize {
        let uses = self.edge_uses();
        for (edge, &(forward, backward)) in &uses {
            assert!(
                forward <= 1 && backward <= 1,
                "edge {edge:?} used {forward}+{backward}"
            );
        }
        uses.values().filter(|&&(f, b)| f + b == 1).count()
    }

    /// Volume by the divergence theorem; positive when normals face outward.
    pub fn signed_volume(&self) -> f64 {
        self.faces
            .iter()
            .map(|face| {
                let [a, b, c] = face.map(|i| self.corner(i));
                dot(a, cross(b, c)) / 6.0
            })
            .sum()
    }

    /// Connected components of the triangles, joined through shared vertices.
    pub fn components(&self) -> usize {
        let mut parent: Vec<u32> = (0..self.positions.len() as u32).collect();
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                parent[i as usize] = parent[parent[i as usize] as usize];
                i = parent[i as usize];
            }
            i
        }
        for &[a, b, c] in &self.faces {
            for other in [b, c] {
                let (ra, ro) = (root(&mut parent, a), root(&mut parent, other));
                parent[ra as usize] = ro;
            }
        }
        let mut roots: Vec<u32> = self.faces.iter().map(|f| root(&mut parent, f[0])).collect();
        roots.sort_unstable();
        roots.dedup();
        roots.len()
    }

    /// Merges vertices whose positions are bit-identical.
    pub fn welded(&self) -> Mesh {
        let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
        let mut positions = Vec::new();
        let remap: Vec<u32> = self
            .positions
            .iter()
            .map(|p| {
                *ids.entry(p.map(f32::to_bits)).or_insert_with(|| {
                    positions.push(*p);
                    positions.len() as u32 - 1
                })
            })
            .collect();
        let faces = self
            .faces
            .iter()
            .map(|f| f.map(|i| remap[i as usize]))
            .collect();
        Mesh {
            comment: self.comment.clone(),
            positions,
            faces,
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

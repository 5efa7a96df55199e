//! `sphere`: a closed, watertight icosphere: each of the 20 icosahedron
//! faces is subdivided into `k^2` triangles and every vertex is projected to
//! the unit sphere.
//!
//! Streaming needs a global numbering in which every shared vertex is written
//! once and can be found again from any face touching it:
//! - ids `0..12`: the icosahedron corners;
//! - then `k - 1` ids per icosahedron edge, numbered from the edge's lower
//!   corner id to its higher one, so both faces on an edge agree;
//! - then each face's `(k-1)(k-2)/2` interior lattice points, face by face,
//!   row by row.
//!
//! A face `(A, B, C)` has lattice points `(i, j)` at `A + i/k (B-A) + j/k (C-A)`
//! with `i + j <= k`; `lattice_id` maps any of them (corner, edge or interior)
//! to its global id, so faces stream independently in rows of the lattice.
//! The icosahedron faces are oriented outward at construction, and lattice
//! triangles keep their face's orientation, so the whole sphere faces out.
//!
//! The seed only turns the whole sphere by a pseudo-random rotation: the
//! construction has no other freedom, and a different seed must still give
//! different geometry.
//!
//! Triangle count: `20 k^2` with `k = max(1, round(sqrt(N / 20)))`; vertex
//! count `10 k^2 + 2`.

use super::noise::Rng;
use super::{GenSummary, Generator, TRIANGLES_PER_CHUNK};

type Vec3 = [f64; 3];

const CORNERS: usize = 12;
const EDGES: usize = 30;
const FACES: usize = 20;

pub struct Icosphere {
    /// Subdivisions per icosahedron edge.
    k: u32,
    corners: [Vec3; CORNERS],
    /// Corner ids, counter-clockwise seen from outside.
    faces: Vec<[u32; 3]>,
    /// Corner id pairs `(low, high)`, sorted: the position is the edge index.
    edges: Vec<(u32, u32)>,
    /// Lattice rows of face interiors per vertex-writing chunk.
    interior_rows_per_chunk: u32,
    /// Lattice strips (rows of triangles) per face-writing chunk.
    strips_per_chunk: u32,
}

fn lerp(a: Vec3, b: Vec3, t: f64) -> Vec3 {
    [0, 1, 2].map(|axis| a[axis] + (b[axis] - a[axis]) * t)
}

fn on_unit_sphere(p: Vec3) -> [f32; 3] {
    let length = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    p.map(|c| (c / length) as f32)
}

/// The regular icosahedron: corners are the cyclic permutations of
/// `(0, ±1, ±φ)`; faces are the corner triples at the minimal edge length.
fn icosahedron(seed: u64) -> ([Vec3; CORNERS], Vec<[u32; 3]>) {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut corners = [[0.0; 3]; CORNERS];
    for (index, corner) in corners.iter_mut().enumerate() {
        let (rotation, signs) = (index / 4, index % 4);
        let base = [
            0.0,
            if signs & 1 == 0 { 1.0 } else { -1.0 },
            if signs & 2 == 0 { phi } else { -phi },
        ];
        *corner = [0, 1, 2].map(|axis| base[(axis + 3 - rotation) % 3]);
    }
    let corners = corners.map(|corner| rotate(corner, seed));
    let adjacent = |a: usize, b: usize| {
        let d: f64 = (0..3)
            .map(|axis| (corners[a][axis] - corners[b][axis]).powi(2))
            .sum();
        (d - 4.0).abs() < 1e-6
    };
    let mut faces = Vec::with_capacity(FACES);
    for a in 0..CORNERS {
        for b in a + 1..CORNERS {
            for c in b + 1..CORNERS {
                if adjacent(a, b) && adjacent(b, c) && adjacent(a, c) {
                    faces.push(outward([a, b, c].map(|i| i as u32), &corners));
                }
            }
        }
    }
    (corners, faces)
}

/// Turns `p` by Euler angles drawn from `seed` (about x, then y, then z).
fn rotate(p: Vec3, seed: u64) -> Vec3 {
    let mut rng = Rng::new(seed, 0);
    let mut p = p;
    for axis in 0..3 {
        let (sin, cos) = rng.range(0.0, std::f64::consts::TAU).sin_cos();
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        (p[a], p[b]) = (cos * p[a] - sin * p[b], sin * p[a] + cos * p[b]);
    }
    p
}

/// Reorders a face so its normal points away from the centre.
fn outward(face: [u32; 3], corners: &[Vec3; CORNERS]) -> [u32; 3] {
    let [a, b, c] = face.map(|i| corners[i as usize]);
    let (u, v) = (
        [0, 1, 2].map(|i| b[i] - a[i]),
        [0, 1, 2].map(|i| c[i] - a[i]),
    );
    let normal = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let facing: f64 = (0..3).map(|i| normal[i] * (a[i] + b[i] + c[i])).sum();
    if facing > 0.0 {
        face
    } else {
        [face[0], face[2], face[1]]
    }
}

impl Icosphere {
    pub fn new(triangles: u64, seed: u64) -> Self {
        let k = ((triangles as f64 / 20.0).sqrt().round() as u32).max(1);
        let (corners, faces) = icosahedron(seed);
        let mut edges: Vec<(u32, u32)> = faces
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
            .map(|(p, q)| (p.min(q), p.max(q)))
            .collect();
        edges.sort_unstable();
        edges.dedup();
        assert_eq!((faces.len(), edges.len()), (FACES, EDGES));
        let triangles_per_strip = 2 * k as u64;
        let strips_per_chunk = (TRIANGLES_PER_CHUNK / triangles_per_strip).max(1) as u32;
        Icosphere {
            k,
            corners,
            faces,
            edges,
            interior_rows_per_chunk: 2 * strips_per_chunk,
            strips_per_chunk,
        }
    }

    fn interior_per_face(&self) -> u64 {
        let k = self.k as u64;
        if k < 3 {
            0
        } else {
            (k - 1) * (k - 2) / 2
        }
    }

    fn first_interior_id(&self) -> u64 {
        (CORNERS + EDGES * (self.k as usize - 1)) as u64
    }

    fn edge_point_id(&self, from: u32, to: u32, steps_from_start: u32) -> u32 {
        let (low, high) = (from.min(to), from.max(to));
        let edge = self
            .edges
            .binary_search(&(low, high))
            .expect("icosahedron edge");
        let steps_from_low = if from == low {
            steps_from_start
        } else {
            self.k - steps_from_start
        };
        (CORNERS as u32) + edge as u32 * (self.k - 1) + steps_from_low - 1
    }

    /// Global id of lattice point `(i, j)` of `face`.
    fn lattice_id(&self, face: usize, i: u32, j: u32) -> u32 {
        let [a, b, c] = self.faces[face];
        let k = self.k;
        match (i, j) {
            (0, 0) => a,
            (_, 0) if i == k => b,
            (0, _) if j == k => c,
            (_, 0) => self.edge_point_id(a, b, i),
            (0, _) => self.edge_point_id(a, c, j),
            _ if i + j == k => self.edge_point_id(b, c, j),
            _ => {
                // Interior rows j = 1.. hold i = 1..=k-1-j.
                let rows_before = (j - 1) as u64;
                let row_start = rows_before * (k as u64 - 1) - rows_before * (rows_before + 1) / 2;
                let offset = self.first_interior_id() + face as u64 * self.interior_per_face();
                (offset + row_start + (i - 1) as u64) as u32
            }
        }
    }

    fn lattice_position(&self, face: usize, i: u32, j: u32) -> [f32; 3] {
        let [a, b, c] = self.faces[face].map(|id| self.corners[id as usize]);
        let (s, t) = (i as f64 / self.k as f64, j as f64 / self.k as f64);
        let along_ab = lerp(a, b, s);
        on_unit_sphere([0, 1, 2].map(|axis| along_ab[axis] + (c[axis] - a[axis]) * t))
    }

    fn interior_chunks_per_face(&self) -> u32 {
        self.k
            .saturating_sub(2)
            .div_ceil(self.interior_rows_per_chunk)
    }

    fn face_chunks_per_face(&self) -> u32 {
        self.k.div_ceil(self.strips_per_chunk)
    }
}

impl Generator for Icosphere {
    fn summary(&self) -> GenSummary {
        let k = self.k as u64;
        GenSummary {
            vertices: 10 * k * k + 2,
            triangles: 20 * k * k,
        }
    }

    /// Chunk 0 holds corners and edge points, then each face's interior
    /// rows in blocks, matching the id order.
    fn vertex_chunk(&self, chunk: usize, out: &mut Vec<[f32; 3]>) {
        if chunk == 0 {
            self.corners
                .iter()
                .for_each(|&c| out.push(on_unit_sphere(c)));
            for &(low, high) in &self.edges {
                let (a, b) = (self.corners[low as usize], self.corners[high as usize]);
                for step in 1..self.k {
                    out.push(on_unit_sphere(lerp(a, b, step as f64 / self.k as f64)));
                }
            }
            return;
        }
        let per_face = self.interior_chunks_per_face() as usize;
        let (face, block) = ((chunk - 1) / per_face, ((chunk - 1) % per_face) as u32);
        let first_row = 1 + block * self.interior_rows_per_chunk;
        let rows = first_row..(first_row + self.interior_rows_per_chunk).min(self.k - 1);
        for j in rows {
            for i in 1..self.k - j {
                out.push(self.lattice_position(face, i, j));
            }
        }
    }

    fn vertex_chunks(&self) -> usize {
        1 + FACES * self.interior_chunks_per_face() as usize
    }

    fn face_chunks(&self) -> usize {
        FACES * self.face_chunks_per_face() as usize
    }

    /// Strip `j` lies between lattice rows `j` and `j + 1`: upward triangles
    /// `(i,j) (i+1,j) (i,j+1)` and downward ones `(i+1,j) (i+1,j+1) (i,j+1)`,
    /// both with the face's orientation.
    fn face_chunk(&self, chunk: usize, out: &mut Vec<[u32; 3]>) {
        let per_face = self.face_chunks_per_face() as usize;
        let (face, block) = (chunk / per_face, (chunk % per_face) as u32);
        let first_strip = block * self.strips_per_chunk;
        let id = |i, j| self.lattice_id(face, i, j);
        for j in first_strip..(first_strip + self.strips_per_chunk).min(self.k) {
            let width = self.k - j;
            for i in 0..width {
                out.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                if i + 1 < width {
                    out.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_mesh::generated;
    use super::super::Kind;

    #[test]
    fn sphere_is_closed_consistent_and_outward_for_every_small_k() {
        for (requested, k) in [(1, 1u64), (80, 2), (180, 3), (20_000, 32)] {
            let (summary, mesh) = generated(Kind::Sphere, requested, 5);
            assert_eq!(summary.triangles, 20 * k * k);
            assert_eq!(summary.vertices, 10 * k * k + 2);
            mesh.assert_closed_consistent_manifold();
            assert!(mesh.signed_volume() > 0.0);
            assert!(mesh.positions.iter().all(|p| {
                let r2: f32 = p.iter().map(|c| c * c).sum();
                (r2 - 1.0).abs() < 1e-5
            }));
        }
    }
}

//! `terrain`: an open heightfield over the unit square with fractal noise
//! heights, like a digital elevation model.
//!
//! Vertex `(i, j)` (x index `i`, y index `j`) is numbered `j * (side + 1) + i`,
//! so vertices and faces both stream row by row. Quads are split along the
//! same diagonal everywhere and wound counter-clockwise seen from above, so
//! the surface is a consistently oriented disc whose only boundary is the
//! square's rim.
//!
//! Triangle count: `2 * side^2` with `side = max(1, round(sqrt(N / 2)))`,
//! within about `2 * sqrt(2N)` of N.

use super::noise::{Fbm2, Fbm2Row};
use super::{Chunking, GenSummary, Generator, TRIANGLES_PER_CHUNK};

/// Relief relative to the unit square: hilly rather than flat.
const HEIGHT_SCALE: f64 = 0.25;
const NOISE_CELLS: [i64; 2] = [4, 4];
const NOISE_OCTAVES: u32 = 9;

pub struct Heightfield {
    /// Quads per side.
    side: u32,
    noise: Fbm2,
}

impl Heightfield {
    pub fn for_triangles(triangles: u64, seed: u64) -> Self {
        // The noise's first coordinate runs along y (one row per y), second along x.
        Heightfield {
            side: ((triangles as f64 / 2.0).sqrt().round() as u32).max(1),
            noise: Fbm2::new(seed, NOISE_CELLS, NOISE_OCTAVES),
        }
    }

    fn vertices_per_row(&self) -> u32 {
        self.side + 1
    }

    fn row_heights(&self, j: u32) -> Fbm2Row {
        self.noise.row(j as f64 / self.side as f64)
    }

    fn position(&self, heights: &Fbm2Row, i: u32, j: u32) -> [f32; 3] {
        let (x, y) = (i as f64 / self.side as f64, j as f64 / self.side as f64);
        let z = HEIGHT_SCALE * heights.at(x);
        [x as f32, y as f32, z as f32]
    }

    fn row_triangles(&self, j: u32, out: &mut Vec<[u32; 3]>) {
        let id = |i: u32, j: u32| j * self.vertices_per_row() + i;
        for i in 0..self.side {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            out.push([a, b, c]);
            out.push([a, c, d]);
        }
    }

    fn vertex_rows(&self) -> Chunking {
        let rows = self.vertices_per_row() as u64;
        Chunking::by_work(rows, 2 * self.side as u64, TRIANGLES_PER_CHUNK)
    }

    fn quad_rows(&self) -> Chunking {
        let side = self.side as u64;
        Chunking::by_work(side, 2 * side, TRIANGLES_PER_CHUNK)
    }
}

impl Generator for Heightfield {
    fn summary(&self) -> GenSummary {
        let vertex_rows = self.vertices_per_row() as u64;
        GenSummary {
            vertices: vertex_rows * vertex_rows,
            triangles: 2 * self.side as u64 * self.side as u64,
        }
    }

    fn vertex_chunks(&self) -> usize {
        self.vertex_rows().count()
    }

    fn vertex_chunk(&self, chunk: usize, out: &mut Vec<[f32; 3]>) {
        for j in self.vertex_rows().range(chunk) {
            let heights = self.row_heights(j as u32);
            out.extend((0..self.vertices_per_row()).map(|i| self.position(&heights, i, j as u32)));
        }
    }

    fn face_chunks(&self) -> usize {
        self.quad_rows().count()
    }

    fn face_chunk(&self, chunk: usize, out: &mut Vec<[u32; 3]>) {
        self.quad_rows()
            .range(chunk)
            .for_each(|j| self.row_triangles(j as u32, out));
    }

    /// Vertex `j * (side + 1) + i` is `(i, j)`; the ids of one row share its noise row.
    fn positions_of(&self, sorted_ids: &[u32]) -> Option<Vec<[f32; 3]>> {
        let per_row = self.vertices_per_row();
        let mut positions = Vec::with_capacity(sorted_ids.len());
        for ids in sorted_ids.chunk_by(|a, b| a / per_row == b / per_row) {
            let j = ids[0] / per_row;
            let heights = self.row_heights(j);
            positions.extend(
                ids.iter()
                    .map(|id| self.position(&heights, id % per_row, j)),
            );
        }
        Some(positions)
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_mesh::generated;
    use super::super::Kind;

    #[test]
    fn terrain_is_an_upward_consistent_disc() {
        let (summary, mesh) = generated(Kind::Terrain, 10_000, 4);
        assert_eq!(summary.triangles, 2 * 71 * 71);
        let boundary_edges = mesh.assert_consistent_manifold_with_boundary();
        assert_eq!(boundary_edges, 4 * 71);
        assert_eq!(mesh.components(), 1);
        let heights: Vec<f32> = mesh.positions.iter().map(|p| p[2]).collect();
        let relief = heights.iter().cloned().fold(f32::MIN, f32::max)
            - heights.iter().cloned().fold(f32::MAX, f32::min);
        assert!(relief > 0.05, "relief {relief}");
        for face in &mesh.faces {
            let [a, b, c] = face.map(|i| mesh.positions[i as usize]);
            let normal_z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            assert!(normal_z > 0.0, "triangle {face:?} faces down");
        }
    }
}

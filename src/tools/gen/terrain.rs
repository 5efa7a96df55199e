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

use anyhow::Result;

use super::noise::Fbm2;
use super::ply::{FaceBuf, PlyWriter, Target, VertexBuf};
use super::{Chunking, GenSummary, TRIANGLES_PER_CHUNK};

/// Relief relative to the unit square: hilly rather than flat.
const HEIGHT_SCALE: f64 = 0.25;
const NOISE_CELLS: [i64; 2] = [4, 4];
const NOISE_OCTAVES: u32 = 9;

struct Heightfield {
    /// Quads per side.
    side: u32,
    noise: Fbm2,
}

impl Heightfield {
    fn vertices_per_row(&self) -> u32 {
        self.side + 1
    }

    fn row_positions(&self, j: u32, out: &mut VertexBuf) {
        let y = j as f64 / self.side as f64;
        let heights = self.noise.row(y);
        for i in 0..self.vertices_per_row() {
            let x = i as f64 / self.side as f64;
            let z = HEIGHT_SCALE * heights.at(x);
            out.push([x as f32, y as f32, z as f32]);
        }
    }

    fn row_triangles(&self, j: u32, out: &mut FaceBuf) {
        let id = |i: u32, j: u32| j * self.vertices_per_row() + i;
        for i in 0..self.side {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            out.push([a, b, c]);
            out.push([a, c, d]);
        }
    }
}

pub fn generate(triangles: u64, seed: u64, target: &Target) -> Result<GenSummary> {
    let side = ((triangles as f64 / 2.0).sqrt().round() as u32).max(1);
    // The noise's first coordinate runs along y (one row per y), second along x.
    let field = Heightfield {
        side,
        noise: Fbm2::new(seed, NOISE_CELLS, NOISE_OCTAVES),
    };
    let vertex_rows = (side + 1) as u64;
    let declared = GenSummary {
        vertices: vertex_rows * vertex_rows,
        triangles: 2 * side as u64 * side as u64,
    };
    let mut writer = PlyWriter::create(target, declared)?;
    let rows = Chunking::by_work(vertex_rows, 2 * side as u64, TRIANGLES_PER_CHUNK);
    writer.write_vertices(rows.count(), |chunk, out| {
        rows.range(chunk)
            .for_each(|j| field.row_positions(j as u32, out));
    })?;
    let quad_rows = Chunking::by_work(side as u64, 2 * side as u64, TRIANGLES_PER_CHUNK);
    writer.write_faces(quad_rows.count(), |chunk, out| {
        quad_rows
            .range(chunk)
            .for_each(|j| field.row_triangles(j as u32, out));
    })?;
    writer.finish()
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

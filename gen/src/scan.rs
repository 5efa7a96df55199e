//! `scan`: a closed, watertight, manifold surface that looks like a scanned
//! statue: a torus whose tube radius is displaced by fractal noise.
//!
//! A torus is a periodic grid in (u around the main axis, v around the tube),
//! so it closes without seams, poles or special cases: vertex `(i, j)` is
//! numbered `i * columns + j` and every quad connects to its wrapped
//! neighbours. The noise is periodic on the same square, so the displaced
//! surface is continuous across the wrap too. The displacement stays well
//! below the tube radius, so the surface never collapses onto the tube axis.
//!
//! Triangle count: `2 * rows * columns` with `columns = max(3, round(sqrt(N/6)))`
//! and `rows = max(3, round(N / (2 * columns)))`, i.e. about three times as
//! many rows around the long way (matching the torus proportions); this is
//! within about `columns` triangles of N, and at least 18.
//!
//! Winding: each quad `(i,j) (i+1,j) (i+1,j+1) (i,j+1)` is split into
//! `(a,b,c)` and `(a,c,d)`, counter-clockwise seen from outside, so the
//! normals point away from the tube.

use std::f64::consts::TAU;

use super::noise::{Fbm2, Fbm2Row};
use super::{Chunking, GenSummary, Generator, TRIANGLES_PER_CHUNK};

const MAJOR_RADIUS: f64 = 1.0;
const TUBE_RADIUS: f64 = 0.35;
/// Peak displacement; below `TUBE_RADIUS` so the tube never pinches shut.
const DISPLACEMENT: f64 = 0.1;
/// The coarsest noise has this many bumps around each direction (the long
/// way has about three times the circumference).
const NOISE_CELLS: [i64; 2] = [9, 3];
/// Octaves reach bumps of about a thousandth of the long circumference.
const NOISE_OCTAVES: u32 = 7;

/// The two triangles of a grid quad as (row, column) offsets from its
/// first corner, counter-clockwise seen from outside.
pub const QUAD_TRIANGLES: [[(u32, u32); 3]; 2] =
    [[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]];

/// The shared part of one grid row's vertices.
pub struct ScanRow {
    sin_u: f64,
    cos_u: f64,
    noise: Fbm2Row,
}

/// The displaced torus, sampled on a `rows x columns` periodic grid.
pub struct ScanSurface {
    pub rows: u32,
    pub columns: u32,
    noise: Fbm2,
    /// `(cos v, sin v)` of each column, shared by every row.
    tube_directions: Vec<(f64, f64)>,
}

impl ScanSurface {
    pub fn for_triangles(triangles: u64, seed: u64) -> Self {
        let columns = ((triangles as f64 / 6.0).sqrt().round() as u32).max(3);
        let rows = ((triangles as f64 / (2.0 * columns as f64)).round() as u32).max(3);
        let tube_directions = (0..columns)
            .map(|j| (TAU * j as f64 / columns as f64).sin_cos())
            .map(|(sin, cos)| (cos, sin))
            .collect();
        ScanSurface {
            rows,
            columns,
            noise: Fbm2::new(seed, NOISE_CELLS, NOISE_OCTAVES),
            tube_directions,
        }
    }

    pub fn triangles(&self) -> u64 {
        2 * self.vertices()
    }

    pub fn vertices(&self) -> u64 {
        self.rows as u64 * self.columns as u64
    }

    /// What every vertex of grid row `row` shares: its angle around the main axis and its
    /// noise.
    pub fn row(&self, row: u32) -> ScanRow {
        let u = row as f64 / self.rows as f64;
        let (sin_u, cos_u) = (TAU * u).sin_cos();
        ScanRow {
            sin_u,
            cos_u,
            noise: self.noise.row(u),
        }
    }

    /// The position of vertex `(row, column)` given its row's [`ScanRow`].
    pub fn position(&self, row: &ScanRow, column: u32) -> [f32; 3] {
        let (cos_v, sin_v) = self.tube_directions[column as usize];
        let v = column as f64 / self.columns as f64;
        let tube = TUBE_RADIUS + DISPLACEMENT * row.noise.at(v);
        let radial = MAJOR_RADIUS + tube * cos_v;
        [
            (radial * row.cos_u) as f32,
            (radial * row.sin_u) as f32,
            (tube * sin_v) as f32,
        ]
    }

    /// Positions of grid row `row`, in column order, appended to `out`.
    pub fn row_positions(&self, row: u32, out: &mut Vec<[f32; 3]>) {
        let frame = self.row(row);
        out.extend((0..self.columns).map(|column| self.position(&frame, column)));
    }

    /// Chunks of whole grid rows: a vertex chunk and a face chunk cover the same rows.
    fn row_chunks(&self) -> Chunking {
        Chunking::by_work(
            self.rows as u64,
            2 * self.columns as u64,
            TRIANGLES_PER_CHUNK,
        )
    }

    /// Vertex ids of the triangles of quad `(row, column)`, wrapping around.
    pub fn quad_triangles(&self, row: u32, column: u32) -> [[u32; 3]; 2] {
        QUAD_TRIANGLES.map(|corners| {
            corners.map(|(d_row, d_column)| {
                let i = (row + d_row) % self.rows;
                let j = (column + d_column) % self.columns;
                i * self.columns + j
            })
        })
    }
}

impl Generator for ScanSurface {
    fn summary(&self) -> GenSummary {
        GenSummary {
            vertices: self.vertices(),
            triangles: self.triangles(),
        }
    }

    fn vertex_chunks(&self) -> usize {
        self.row_chunks().count()
    }

    fn vertex_chunk(&self, chunk: usize, out: &mut Vec<[f32; 3]>) {
        for row in self.row_chunks().range(chunk) {
            self.row_positions(row as u32, out);
        }
    }

    fn face_chunks(&self) -> usize {
        self.row_chunks().count()
    }

    fn face_chunk(&self, chunk: usize, out: &mut Vec<[u32; 3]>) {
        for row in self.row_chunks().range(chunk) {
            for column in 0..self.columns {
                out.extend(self.quad_triangles(row as u32, column));
            }
        }
    }

    /// Vertex `i * columns + j` is `(i, j)`; the ids of one row share one [`ScanRow`].
    fn positions_of(&self, sorted_ids: &[u32]) -> Option<Vec<[f32; 3]>> {
        let mut positions = Vec::with_capacity(sorted_ids.len());
        for ids in sorted_ids.chunk_by(|a, b| a / self.columns == b / self.columns) {
            let row = self.row(ids[0] / self.columns);
            positions.extend(ids.iter().map(|id| self.position(&row, id % self.columns)));
        }
        Some(positions)
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_mesh::{generated, Mesh};
    use super::super::Kind;

    #[test]
    fn scan_is_closed_consistently_wound_and_outward() {
        let (summary, mesh) = generated(Kind::Scan, 12_000, 11);
        assert!(summary.triangles.abs_diff(12_000) < 100, "{summary:?}");
        mesh.assert_closed_consistent_manifold();
        assert!(mesh.signed_volume() > 0.0);
        assert_eq!(mesh.components(), 1);
    }

    #[test]
    fn scan_surface_is_displaced() {
        let (_, mesh): (_, Mesh) = generated(Kind::Scan, 5_000, 3);
        let tube_radii: Vec<f64> = mesh
            .positions
            .iter()
            .map(|p| {
                let radial = (p[0] as f64).hypot(p[1] as f64) - super::MAJOR_RADIUS;
                radial.hypot(p[2] as f64)
            })
            .collect();
        let spread = tube_radii.iter().cloned().fold(f64::MIN, f64::max)
            - tube_radii.iter().cloned().fold(f64::MAX, f64::min);
        assert!(spread > 0.02, "tube radius spread {spread}");
    }
}

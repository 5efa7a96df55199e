//! `soup`: unindexed triangles, as produced by exporters that write every
//! triangle with its own three vertices (STL-like).
//!
//! The geometry is the `scan` surface, so welding bit-identical positions
//! recovers one closed, consistently wound torus: every copy of a grid vertex
//! is computed by the same function from the same grid coordinates, hence
//! bit-identical. Triangle `t` owns vertices `3t, 3t+1, 3t+2`, in the same
//! order as `scan`'s faces.
//!
//! Triangle count: the same rule as `scan`; the vertex count is three times it.

use super::scan::{ScanRow, ScanSurface, QUAD_TRIANGLES};
use super::{Chunking, GenSummary, Generator, TRIANGLES_PER_CHUNK};

/// The `scan` surface with every triangle's corners written apart.
pub struct Soup {
    surface: ScanSurface,
}

impl Soup {
    pub fn for_triangles(triangles: u64, seed: u64) -> Self {
        Soup {
            surface: ScanSurface::for_triangles(triangles, seed),
        }
    }

    /// Vertex chunks cover whole rows of quads.
    fn row_chunks(&self) -> Chunking {
        let columns = self.surface.columns as u64;
        Chunking::by_work(self.surface.rows as u64, 2 * columns, TRIANGLES_PER_CHUNK)
    }

    fn triangle_chunks(&self) -> Chunking {
        Chunking::by_work(self.surface.triangles(), 1, TRIANGLES_PER_CHUNK)
    }

    /// The grid vertex `(row, column)` that soup vertex `id` copies.
    fn grid_vertex(&self, id: u32) -> (u32, u32) {
        let (triangle, corner) = (id / 3, id % 3);
        let columns = self.surface.columns;
        let (row, in_row) = (triangle / (2 * columns), triangle % (2 * columns));
        let (column, half) = (in_row / 2, in_row % 2);
        let (d_row, d_column) = QUAD_TRIANGLES[half as usize][corner as usize];
        (
            (row + d_row) % self.surface.rows,
            (column + d_column) % columns,
        )
    }
}

impl Generator for Soup {
    fn summary(&self) -> GenSummary {
        GenSummary {
            vertices: 3 * self.surface.triangles(),
            triangles: self.surface.triangles(),
        }
    }

    fn vertex_chunks(&self) -> usize {
        self.row_chunks().count()
    }

    fn vertex_chunk(&self, chunk: usize, out: &mut Vec<[f32; 3]>) {
        let surface = &self.surface;
        let columns = surface.columns as usize;
        // Two consecutive grid rows, the second wrapping to row 0 at the end.
        let mut band = Vec::with_capacity(2 * columns);
        for row in self.row_chunks().range(chunk) {
            band.clear();
            surface.row_positions(row as u32, &mut band);
            surface.row_positions((row as u32 + 1) % surface.rows, &mut band);
            for column in 0..columns {
                for corners in QUAD_TRIANGLES {
                    for (d_row, d_column) in corners {
                        let wrapped_column = (column + d_column as usize) % columns;
                        out.push(band[d_row as usize * columns + wrapped_column]);
                    }
                }
            }
        }
    }

    fn face_chunks(&self) -> usize {
        self.triangle_chunks().count()
    }

    fn face_chunk(&self, chunk: usize, out: &mut Vec<[u32; 3]>) {
        for triangle in self.triangle_chunks().range(chunk) {
            let first = 3 * triangle as u32;
            out.push([first, first + 1, first + 2]);
        }
    }

    /// Ascending ids visit grid rows in runs of two (a quad row and the next), so the last
    /// two rows' shared parts are kept.
    fn positions_of(&self, sorted_ids: &[u32]) -> Option<Vec<[f32; 3]>> {
        let mut recent: Vec<(u32, ScanRow)> = Vec::with_capacity(2);
        let positions = sorted_ids
            .iter()
            .map(|&id| {
                let (row, column) = self.grid_vertex(id);
                let index = match recent.iter().position(|(r, _)| *r == row) {
                    Some(index) => index,
                    None => {
                        if recent.len() == 2 {
                            recent.remove(0);
                        }
                        recent.push((row, self.surface.row(row)));
                        recent.len() - 1
                    }
                };
                self.surface.position(&recent[index].1, column)
            })
            .collect();
        Some(positions)
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_mesh::generated;
    use super::super::Kind;

    #[test]
    fn soup_welds_into_the_closed_scan_surface() {
        let (summary, soup) = generated(Kind::Soup, 6_000, 21);
        assert_eq!(summary.vertices, 3 * summary.triangles);
        assert_eq!(soup.components(), summary.triangles as usize);
        let welded = soup.welded();
        welded.assert_closed_consistent_manifold();
        assert_eq!(welded.components(), 1);
        let (_, scan) = generated(Kind::Scan, 6_000, 21);
        assert_eq!(welded.positions.len(), scan.positions.len());
        assert!(welded.signed_volume() > 0.0);
    }
}

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

use anyhow::Result;

use super::ply::{PlyWriter, Target};
use super::scan::{ScanSurface, QUAD_TRIANGLES};
use super::{Chunking, GenSummary, TRIANGLES_PER_CHUNK};

pub fn generate(triangles: u64, seed: u64, target: &Target) -> Result<GenSummary> {
    let surface = ScanSurface::for_triangles(triangles, seed);
    let declared = GenSummary {
        vertices: 3 * surface.triangles(),
        triangles: surface.triangles(),
    };
    let columns = surface.columns as usize;
    let rows = Chunking::by_work(surface.rows as u64, 2 * columns as u64, TRIANGLES_PER_CHUNK);
    let mut writer = PlyWriter::create(target, declared)?;
    writer.write_vertices(rows.count(), |chunk, out| {
        // Two consecutive grid rows, the second wrapping to row 0 at the end.
        let mut band = Vec::with_capacity(2 * columns);
        for row in rows.range(chunk) {
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
    })?;
    let triangle_chunks = Chunking::by_work(declared.triangles, 1, TRIANGLES_PER_CHUNK);
    writer.write_faces(triangle_chunks.count(), |chunk, out| {
        for triangle in triangle_chunks.range(chunk) {
            let first = 3 * triangle as u32;
            out.push([first, first + 1, first + 2]);
        }
    })?;
    writer.finish()
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

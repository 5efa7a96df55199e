//! Snapping a chunk's vertices to the model's grid before stripification.
//!
//! Every vertex becomes its nearest grid point ([`Grid::quantize`]) and is from then on the
//! decoded position of that point ([`Grid::decode`]): Strip-RT, the strip kd-trees and the top
//! level all work on what the reader will decode, so bounds are exact on it. Vertices that land
//! on one grid point are welded (as bit-identical input vertices are, so vertices with
//! different normals or colours stay apart on their common point), which keeps the strips
//! connected across them; triangles that collapse are dropped by Strip-RT's adjacency step like
//! any degenerate input triangle.
//!
//! The error of each input vertex (the distance to its decoded grid point) is measured here, in
//! vertex order, so the sums are the same for any thread count.

use rayon::prelude::*;

use crate::format::grid::Grid;
use crate::geometry::{distance, Displacement, Point};
use crate::input::weld_identical_positions_kept;
use crate::mesh::Mesh;

/// A chunk on the grid: positions are decoded grid points, `points[v]` is vertex `v`'s grid
/// point.
#[derive(Clone, Debug, PartialEq)]
pub struct QuantizedMesh {
    pub mesh: Mesh,
    pub points: Vec<[u32; 3]>,
    /// Input vertex → decoded position, over every vertex of the input mesh.
    pub error: Displacement,
}

/// Snaps `mesh` to `grid`, welds coincident grid points and measures the error.
pub fn quantize_mesh(mesh: &Mesh, grid: &Grid) -> QuantizedMesh {
    let points: Vec<[u32; 3]> = mesh
        .positions
        .par_iter()
        .map(|p| grid.quantize(p))
        .collect();
    let decoded: Vec<Point> = points.par_iter().map(|q| grid.decode(q)).collect();
    let mut error = Displacement::default();
    for (input, stored) in mesh.positions.iter().zip(&decoded) {
        error.record(distance(input, stored));
    }
    let snapped = Mesh {
        positions: decoded,
        triangles: mesh.triangles.clone(),
        face_ids: mesh.face_ids.clone(),
        normals: mesh.normals.clone(),
        colors: mesh.colors.clone(),
    };
    let (welded, kept) = weld_identical_positions_kept(snapped);
    QuantizedMesh {
        points: kept.iter().map(|&v| points[v as usize]).collect(),
        mesh: welded,
        error,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;

    #[test]
    fn vertices_on_one_grid_point_merge_and_the_error_is_measured() {
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.001, 0.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [3, 2, 1]],
            face_ids: None,
            normals: None,
            colors: None,
        };
        let grid = Grid::over(
            &Aabb {
                min: [0.0; 3],
                max: [1.0; 3],
            },
            4,
        );
        let quantized = quantize_mesh(&mesh, &grid);
        assert_eq!(quantized.mesh.positions.len(), 3);
        assert_eq!(quantized.mesh.triangles, vec![[0, 1, 2], [0, 2, 1]]);
        assert_eq!(quantized.points, vec![[0, 0, 0], [8, 0, 0], [0, 8, 0]]);
        assert_eq!(quantized.error.count, 4);
        assert!((quantized.error.max - 0.001).abs() < 1e-9);
    }

    #[test]
    fn vertices_on_one_grid_point_with_other_colours_stay_apart() {
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.001, 0.0, 0.0],
                [0.0, 0.001, 0.0],
            ],
            triangles: vec![[0, 1, 2], [3, 2, 1], [4, 1, 2]],
            face_ids: Some(vec![0, 1, 1]),
            normals: None,
            colors: Some(vec![
                [1, 1, 1, 255],
                [2, 2, 2, 255],
                [3, 3, 3, 255],
                [1, 1, 1, 255],
                [9, 9, 9, 255],
            ]),
        };
        let grid = Grid::over(
            &Aabb {
                min: [0.0; 3],
                max: [1.0; 3],
            },
            4,
        );
        let quantized = quantize_mesh(&mesh, &grid);
        // Vertex 3 joins vertex 0 (same point, same colour); vertex 4 lands on vertex 0's point
        // too but keeps its colour.
        assert_eq!(
            quantized.mesh.triangles,
            vec![[0, 1, 2], [0, 2, 1], [3, 1, 2]]
        );
        assert_eq!(quantized.mesh.positions[3], quantized.mesh.positions[0]);
        assert_eq!(quantized.points[3], quantized.points[0]);
        assert_eq!(
            quantized.mesh.colors,
            Some(vec![
                [1, 1, 1, 255],
                [2, 2, 2, 255],
                [3, 3, 3, 255],
                [9, 9, 9, 255]
            ])
        );
        assert_eq!(quantized.mesh.face_ids, Some(vec![0, 1, 1]));
    }
}

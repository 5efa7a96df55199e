//! Welding within a distance tolerance: a vertex closer than the tolerance to an earlier kept
//! vertex is merged into it.
//!
//! For inputs whose shared vertices were perturbed (parts exported separately, the paper's
//! Boeing 777): bit-exact welding ([`super::weld_identical_positions`]) leaves such copies apart,
//! adjacency then sees boundaries where the surface continues, and strips end there. Merging
//! them recovers the connectivity and with it longer strips.
//!
//! Greedy clustering over a uniform hash grid (spatial hashing): vertices are visited in input
//! order; each joins the nearest kept vertex within the tolerance (the lowest index among equally
//! near ones), or else is kept itself. Kept vertices never move and every other vertex moves at
//! most the tolerance, so clusters cannot chain across the model; the result depends on the
//! positions and their order only, not on the thread count. Grid cells are twice the tolerance
//! wide, so the tolerance ball of a vertex meets at most two cells per axis: eight lookups.
//!
//! Vertices with normals or colours move to their cluster's kept position but stay apart
//! from vertices with other attributes there (see [`super::weld`] for why): the exact weld
//! that follows the move joins only vertices whose attributes match.
//!
//! The clustering needs every position of the model, so the pipeline runs it over the whole
//! input before the chunk partition, and a vertex shared by two chunks merges the same way in
//! both.

use std::collections::HashMap;

use crate::format::counts::WeldStats;
use crate::geometry::{distance, Point};
use crate::mesh::Mesh;

/// For every vertex, the kept vertex it merges into (itself when kept).
pub(crate) fn tolerance_representatives(
    positions: &[Point],
    tolerance: f32,
) -> (Vec<u32>, WeldStats) {
    let mut stats = WeldStats {
        tolerance,
        ..WeldStats::default()
    };
    let mut representative: Vec<u32> = (0..positions.len() as u32).collect();
    if tolerance.is_nan() || tolerance <= 0.0 {
        return (representative, stats);
    }
    let mut kept = KeptVertices::new(positions, tolerance);
    for (index, point) in positions.iter().enumerate() {
        match kept.nearest(point) {
            Some((found, moved)) => {
                representative[index] = found;
                stats.displacement.record(moved);
            }
            None => kept.insert(index as u32),
        }
    }
    (representative, stats)
}

/// Merges vertices within `tolerance` (bit-identical ones included), remapping triangles and
/// dropping the merged vertices; kept vertices keep their order.
pub fn weld_within_tolerance(mesh: Mesh, tolerance: f32) -> (Mesh, WeldStats) {
    let (representative, stats) = tolerance_representatives(&mesh.positions, tolerance);
    if mesh.normals.is_some() || mesh.colors.is_some() {
        return (snap_and_weld(mesh, &representative), stats);
    }
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| representative[v as usize]))
        .collect();
    let remapped = Mesh {
        positions: mesh.positions,
        triangles,
        face_ids: mesh.face_ids,
        normals: None,
        colors: None,
    };
    (compact(remapped, &representative), stats)
}

/// Moves every vertex to its representative's position, then joins bit-identical vertices
/// with equal attributes.
fn snap_and_weld(mut mesh: Mesh, representative: &[u32]) -> Mesh {
    mesh.positions = representative
        .iter()
        .map(|&kept| mesh.positions[kept as usize])
        .collect();
    super::weld_identical_positions(mesh)
}

/// Drops the merged vertices, keeping the order of the kept ones.
fn compact(mesh: Mesh, representative: &[u32]) -> Mesh {
    let mut new_index = vec![u32::MAX; mesh.positions.len()];
    let mut positions = Vec::new();
    for (index, point) in mesh.positions.iter().enumerate() {
        if representative[index] == index as u32 {
            new_index[index] = positions.len() as u32;
            positions.push(*point);
        }
    }
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| new_index[v as usize]))
        .collect();
    // Meshes with attributes take `snap_and_weld` instead.
    Mesh {
        positions,
        triangles,
        face_ids: mesh.face_ids,
        normals: None,
        colors: None,
    }
}

/// Kept vertices bucketed by grid cell, each cell a linked list through `next`.
struct KeptVertices<'a> {
    positions: &'a [Point],
    tolerance: f64,
    /// Reciprocal of the cell width (twice the tolerance).
    scale: f64,
    first: HashMap<[i64; 3], u32>,
    next: Vec<u32>,
}

const END: u32 = u32::MAX;

impl<'a> KeptVertices<'a> {
    fn new(positions: &'a [Point], tolerance: f32) -> Self {
        KeptVertices {
            positions,
            tolerance: tolerance as f64,
            scale: 0.5 / tolerance as f64,
            first: HashMap::new(),
            next: vec![END; positions.len()],
        }
    }

    fn cell(&self, p: &Point) -> [i64; 3] {
        p.map(|c| (c as f64 * self.scale).floor() as i64)
    }

    fn insert(&mut self, index: u32) {
        let cell = self.cell(&self.positions[index as usize]);
        let head = self.first.entry(cell).or_insert(END);
        self.next[index as usize] = *head;
        *head = index;
    }

    /// The nearest kept vertex within the tolerance, and its distance.
    fn nearest(&self, p: &Point) -> Option<(u32, f64)> {
        let scaled = p.map(|c| c as f64 * self.scale);
        // The tolerance is half a cell: the ball reaches the neighbour on the side of the
        // cell's centre that the point is on, and no further.
        let side = scaled.map(|s| if s - s.floor() < 0.5 { -1 } else { 1 });
        let cell = scaled.map(|s| s.floor() as i64);
        let mut best: Option<(u32, f64)> = None;
        for corner in 0..8 {
            let neighbour: [i64; 3] = std::array::from_fn(|a| {
                cell[a].saturating_add(((corner >> a) & 1) as i64 * side[a])
            });
            let mut at = self.first.get(&neighbour).copied().unwrap_or(END);
            while at != END {
                let d = distance(p, &self.positions[at as usize]);
                let closer = best.is_none_or(|(b, bd)| d < bd || (d == bd && at < b));
                if d <= self.tolerance && closer {
                    best = Some((at, d));
                }
                at = self.next[at as usize];
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perturbed_copies_merge_into_the_first_and_far_ones_stay() {
        let positions = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0004, -0.0003, 0.0],
            [1.0, 0.0, 0.0009],
            [0.002, 0.0, 0.0],
        ];
        let (representative, stats) = tolerance_representatives(&positions, 0.001);
        assert_eq!(representative, vec![0, 1, 0, 1, 4]);
        assert_eq!(stats.displacement.count, 2);
        assert!((stats.displacement.max - 0.0009).abs() < 1e-9);
    }

    #[test]
    fn clusters_do_not_chain() {
        // Each point is within the tolerance of the previous one, but only the first two of
        // the kept vertex.
        let positions: Vec<Point> = (0..6).map(|i| [i as f32 * 0.6, 0.0, 0.0]).collect();
        let (representative, _) = tolerance_representatives(&positions, 1.0);
        assert_eq!(representative, vec![0, 0, 2, 2, 4, 4]);
    }

    #[test]
    fn neighbours_across_cell_borders_are_found() {
        // Cells are 2 wide: 1.99 and 2.01 sit in different cells.
        let positions = [[1.99, -0.01, 3.99], [2.01, 0.01, 4.01]];
        let (representative, _) = tolerance_representatives(&positions, 1.0);
        assert_eq!(representative, vec![0, 0]);
    }

    #[test]
    fn zero_tolerance_keeps_everything() {
        let positions = [[0.0; 3], [0.0; 3]];
        let (representative, stats) = tolerance_representatives(&positions, 0.0);
        assert_eq!(representative, vec![0, 1]);
        assert_eq!(stats.displacement.count, 0);
    }

    #[test]
    fn welding_a_mesh_reconnects_its_triangles() {
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1e-6, 0.0],
                [1.0, 1.0, 0.0],
                [-1e-6, 1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [3, 4, 5]],
            face_ids: None,
            normals: None,
            colors: None,
        };
        let (welded, stats) = weld_within_tolerance(mesh, 1e-5);
        assert_eq!(welded.positions.len(), 4);
        assert_eq!(welded.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        assert_eq!(stats.displacement.count, 2);
    }

    #[test]
    fn vertices_with_other_attributes_move_but_stay_apart() {
        // Vertex 3 is a perturbed copy of vertex 1 with the same normal: it merges. Vertex 5 is
        // one of vertex 2 with another normal: it moves onto vertex 2 but stays its own vertex.
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1e-6, 0.0],
                [1.0, 1.0, 0.0],
                [-1e-6, 1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [3, 4, 5]],
            face_ids: Some(vec![4, 9]),
            normals: Some(vec![
                [0.0, 0.0, 1.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, 1.0],
                [1.0, 0.0, 0.0],
            ]),
            colors: None,
        };
        let (welded, stats) = weld_within_tolerance(mesh, 1e-5);
        assert_eq!(stats.displacement.count, 2);
        assert_eq!(welded.triangles, vec![[0, 1, 2], [1, 3, 4]]);
        assert_eq!(welded.positions[4], [0.0, 1.0, 0.0]);
        assert_eq!(welded.positions[4], welded.positions[2]);
        assert_eq!(welded.normals.as_ref().unwrap()[4], [1.0, 0.0, 0.0]);
        assert_eq!(welded.normals.as_ref().unwrap()[2], [0.0, 0.0, 1.0]);
        assert_eq!(welded.face_ids, Some(vec![4, 9]));
    }
}

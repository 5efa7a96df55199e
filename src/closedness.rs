//! Closedness of a whole mesh for the model record: edges used by exactly one stored triangle
//! (boundary) and edges used by more than two, or by two running it the same way
//! (non-manifold). Inside/outside is the exact parity of one ray only when both are zero.
//!
//! Edges are keyed by the bits of their two end positions, not by vertex indices: the tracer
//! and the crossing tie rule see positions, so two triangles meeting at equal coordinates share
//! the edge whatever their indices. Triangles Strip-RT drops (repeated index or no area) are not
//! stored and not counted.

use rayon::prelude::*;

use crate::format::model::{Closedness, UpAxis};
use crate::mesh::Mesh;
use crate::stripify::adjacency::is_dropped;

/// A position by its bits, ordered lexicographically.
type PositionKey = [u32; 3];

/// One use of an edge: its ends in key order, and whether the triangle runs it from the first
/// to the second.
type EdgeUse = (PositionKey, PositionKey, bool);

/// The edge counts of `mesh`'s stored triangles.
pub fn count_edges(mesh: &Mesh) -> Closedness {
    let mut uses: Vec<EdgeUse> = mesh
        .triangles
        .par_iter()
        .filter(|triangle| !is_dropped(mesh, triangle))
        .flat_map_iter(|triangle| {
            let keys = mesh.triangle_points(triangle).map(|p| p.map(f32::to_bits));
            (0..3).map(move |i| edge_use(keys[i], keys[(i + 1) % 3]))
        })
        .collect();
    uses.par_sort_unstable();
    let mut counts = Closedness::default();
    for group in uses.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)) {
        match group {
            [_] => counts.boundary_edges += 1,
            [a, b] if a.2 != b.2 => {}
            _ => counts.nonmanifold_edges += 1,
        }
    }
    counts
}

fn edge_use(from: PositionKey, to: PositionKey) -> EdgeUse {
    match from < to {
        true => (from, to, true),
        false => (to, from, false),
    }
}

/// The up axis of a model read from `path` when the configuration names none: its format's
/// (z for STL, whose CAD and printing sources stand on the xy plane, else y); y when the
/// format cannot be told, so the reading stage reports that instead.
pub fn default_up(path: &std::path::Path) -> UpAxis {
    crate::input::detect(path).map_or(UpAxis::Y, |detected| detected.format.default_up())
}

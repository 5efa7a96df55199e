//! Strip-RT step 1, adjacency computation (paper 4.1, "Adjacency computation").
//!
//! Triangles that repeat a vertex index or have zero area ([`is_degenerate`]) are dropped first:
//! they add nothing to a ray tracer and would only create ambiguous edges. The kept triangles are
//! renumbered densely ("local" indices, in input order) so that the later steps can use compact
//! per-triangle arrays.
//!
//! Edges are matched by sorting `(undirected edge key, edge slot)` pairs rather than through a
//! hash map: the sort is deterministic, parallel, and has a predictable memory footprint
//! (16 bytes per edge slot, released before partitioning starts).
//!
//! Two triangles become neighbours across an edge only when it is a manifold edge (exactly two
//! kept triangles use it) that they traverse in opposite directions. Deviation from the paper,
//! which does not discuss orientation: requiring consistent winding lets the strip output keep
//! every triangle's input winding without any per-triangle flags, and non-manifold or
//! inconsistently wound edges simply become strip boundaries. Two triangles over the same three
//! vertices with opposite winding (a two-sided sliver) are legitimate neighbours by this rule.

use rayon::prelude::*;

use crate::geometry::is_degenerate;
use crate::mesh::Mesh;

/// Marks an edge slot without a neighbour.
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// Kept triangles and their edge neighbours.
#[derive(Clone, Debug, Default)]
pub struct Adjacency {
    /// Mesh triangle index of each kept (local) triangle, in input order.
    pub kept: Vec<u32>,
    /// For each local triangle, the local neighbour across edge `i = (v_i, v_{i+1 mod 3})`,
    /// or [`NO_NEIGHBOUR`].
    pub neighbours: Vec<[u32; 3]>,
    /// Number of mesh triangles dropped as degenerate.
    pub dropped_triangles: u64,
}

/// One directed use of an undirected edge: `key` identifies the edge, `slot` is
/// `local triangle * 3 + edge`.
type EdgeUse = (u64, u64);

impl Adjacency {
    /// Drops degenerate triangles and links consistently wound manifold neighbours.
    ///
    /// Precondition: fewer than `u32::MAX` kept triangles (local indices are `u32`, and
    /// `u32::MAX` is the "no neighbour" marker); chunks of a massive model are far smaller.
    pub fn build(mesh: &Mesh) -> Adjacency {
        let kept = kept_triangles(mesh);
        assert!(
            kept.len() < u32::MAX as usize,
            "a stripification chunk must hold fewer than 2^32 - 1 triangles"
        );
        let dropped_triangles = (mesh.triangles.len() - kept.len()) as u64;
        let mut edge_uses = edge_uses(mesh, &kept);
        edge_uses.par_sort_unstable();
        let neighbours = link_manifold_edges(mesh, &kept, &edge_uses);
        Adjacency {
            kept,
            neighbours,
            dropped_triangles,
        }
    }
}

fn kept_triangles(mesh: &Mesh) -> Vec<u32> {
    mesh.triangles
        .par_iter()
        .enumerate()
        .filter(|(_, triangle)| !is_dropped(mesh, triangle))
        .map(|(index, _)| index as u32)
        .collect()
}

/// True for triangles Strip-RT drops: a repeated vertex index, or zero area.
pub fn is_dropped(mesh: &Mesh, triangle: &[u32; 3]) -> bool {
    let [a, b, c] = *triangle;
    if a == b || b == c || a == c {
        return true;
    }
    let [pa, pb, pc] = mesh.triangle_points(triangle);
    is_degenerate(&pa, &pb, &pc)
}

fn edge_key(a: u32, b: u32) -> u64 {
    let (low, high) = if a < b { (a, b) } else { (b, a) };
    ((low as u64) << 32) | high as u64
}

fn edge_vertices(triangle: &[u32; 3], edge: usize) -> (u32, u32) {
    (triangle[edge], triangle[(edge + 1) % 3])
}

fn edge_uses(mesh: &Mesh, kept: &[u32]) -> Vec<EdgeUse> {
    let mut uses = vec![(0, 0); kept.len() * 3];
    uses.par_chunks_mut(3)
        .zip(kept.par_iter())
        .enumerate()
        .for_each(|(local, (slots, &mesh_index))| {
            let triangle = &mesh.triangles[mesh_index as usize];
            for (edge, slot) in slots.iter_mut().enumerate() {
                let (a, b) = edge_vertices(triangle, edge);
                *slot = (edge_key(a, b), (local * 3 + edge) as u64);
            }
        });
    uses
}

/// Walks the sorted edge uses group by group and links the two triangles of every manifold,
/// oppositely traversed edge.
fn link_manifold_edges(mesh: &Mesh, kept: &[u32], sorted_uses: &[EdgeUse]) -> Vec<[u32; 3]> {
    let mut neighbours = vec![[NO_NEIGHBOUR; 3]; kept.len()];
    for group in sorted_uses.chunk_by(|x, y| x.0 == y.0) {
        if let [(_, first), (_, second)] = group {
            let (first, second) = (*first as usize, *second as usize);
            if traverses_forward(mesh, kept, first) != traverses_forward(mesh, kept, second) {
                neighbours[first / 3][first % 3] = (second / 3) as u32;
                neighbours[second / 3][second % 3] = (first / 3) as u32;
            }
        }
    }
    neighbours
}

/// Whether the edge slot runs from the smaller to the larger vertex index; two uses of one
/// edge are oppositely wound exactly when this differs.
fn traverses_forward(mesh: &Mesh, kept: &[u32], slot: usize) -> bool {
    let triangle = &mesh.triangles[kept[slot / 3] as usize];
    let (a, b) = edge_vertices(triangle, slot % 3);
    a < b
}

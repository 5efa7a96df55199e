//! Strip-RT step 1, adjacency computation (paper 4.1, "Adjacency computation").
//!
//! Triangles that repeat a vertex index or have zero area ([`is_degenerate`]) are dropped first:
//! they add nothing to a ray tracer and would only create ambiguous edges. The kept triangles are
//! renumbered densely ("local" indices, in input order) so that the later steps can use compact
//! per-triangle arrays.
//!
//! Edges are matched with a counting sort of edge uses by their lower vertex index, then a tiny
//! sort inside each vertex's bucket, rather than through a hash map or a global sort: it is
//! O(n), deterministic, and needs 8 bytes per edge use plus 4 per vertex, released before
//! partitioning starts. It runs single-threaded; at well under 100 ns per triangle it is not the
//! bottleneck.
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

/// Largest number of kept triangles per call: edge slots (`triangle * 3 + edge`) are `u32`.
pub(crate) const MAX_TRIANGLES: usize = (u32::MAX / 3) as usize;

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

impl Adjacency {
    /// Drops degenerate triangles and links consistently wound manifold neighbours.
    ///
    /// Precondition: at most [`MAX_TRIANGLES`] kept triangles; chunks of a massive model are far
    /// smaller.
    pub fn build(mesh: &Mesh) -> Adjacency {
        let kept = kept_triangles(mesh);
        assert!(
            kept.len() <= MAX_TRIANGLES,
            "a stripification chunk must hold at most {MAX_TRIANGLES} triangles"
        );
        let dropped_triangles = (mesh.triangles.len() - kept.len()) as u64;
        let neighbours = link_manifold_edges(mesh, &kept);
        Adjacency {
            kept,
            neighbours,
            dropped_triangles,
        }
    }

    /// Index `i` of the edge `(v_i, v_{i+1})` of `triangle` shared with its neighbour `other`.
    /// Only the two triangles of a two-sided sliver share more than one edge; they form a
    /// component of their own, so the first match is as good as any.
    pub(crate) fn edge_towards(&self, triangle: u32, other: u32) -> usize {
        self.neighbours[triangle as usize]
            .iter()
            .position(|&n| n == other)
            .expect("path links always join adjacent triangles")
    }

    /// The turn of a path that enters `triangle` from `from` and leaves toward `to`: the exit
    /// edge index minus the entry edge index, mod 3, in the triangle's input winding. It is
    /// [`TURN_TO_NEXT_EDGE`] or 2 (through the edge before the entry edge); reversing the path
    /// swaps the two.
    pub(crate) fn turn(&self, from: u32, triangle: u32, to: u32) -> u8 {
        let entry = self.edge_towards(triangle, from);
        let exit = self.edge_towards(triangle, to);
        ((exit + 3 - entry) % 3) as u8
    }
}

/// A turn that leaves through the edge after the entry edge in input winding.
pub(crate) const TURN_TO_NEXT_EDGE: u8 = 1;

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

fn edge_vertices(triangle: &[u32; 3], edge: usize) -> (u32, u32) {
    (triangle[edge], triangle[(edge + 1) % 3])
}

/// One use of an undirected edge, filed under its lower vertex: `high` is the other vertex,
/// `slot` is `local triangle * 3 + edge`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
struct EdgeUse {
    high: u32,
    slot: u32,
}

/// All edge uses, grouped by lower vertex with a counting sort: `uses[bucket_end[v - 1]..
/// bucket_end[v]]` are the uses whose lower vertex is `v`. The scatter visits slots in
/// increasing order, so every bucket is already ordered by slot.
struct EdgeBuckets {
    uses: Vec<EdgeUse>,
    bucket_end: Vec<u32>,
}

impl EdgeBuckets {
    fn build(mesh: &Mesh, kept: &[u32]) -> EdgeBuckets {
        let mut bucket_end = vec![0u32; mesh.positions.len() + 1];
        let low_vertices = || {
            kept.iter().flat_map(|&t| {
                let triangle = mesh.triangles[t as usize];
                (0..3).map(move |edge| {
                    let (a, b) = edge_vertices(&triangle, edge);
                    (a.min(b), a.max(b))
                })
            })
        };
        for (low, _) in low_vertices() {
            bucket_end[low as usize + 1] += 1;
        }
        for v in 1..bucket_end.len() {
            bucket_end[v] += bucket_end[v - 1];
        }
        let mut uses = vec![EdgeUse::default(); kept.len() * 3];
        for (slot, (low, high)) in low_vertices().enumerate() {
            let cursor = &mut bucket_end[low as usize];
            uses[*cursor as usize] = EdgeUse {
                high,
                slot: slot as u32,
            };
            *cursor += 1;
        }
        // Each cursor now sits at its bucket's end; the trailing entry is unused.
        bucket_end.pop();
        EdgeBuckets { uses, bucket_end }
    }

    fn buckets_mut(&mut self) -> impl Iterator<Item = &mut [EdgeUse]> {
        let mut rest = self.uses.as_mut_slice();
        let mut start = 0;
        self.bucket_end.iter().map(move |&end| {
            let (bucket, tail) = std::mem::take(&mut rest).split_at_mut((end - start) as usize);
            rest = tail;
            start = end;
            bucket
        })
    }
}

/// Groups the uses of each undirected edge and links the two triangles of every manifold,
/// oppositely traversed edge.
fn link_manifold_edges(mesh: &Mesh, kept: &[u32]) -> Vec<[u32; 3]> {
    let mut neighbours = vec![[NO_NEIGHBOUR; 3]; kept.len()];
    let mut buckets = EdgeBuckets::build(mesh, kept);
    for bucket in buckets.buckets_mut() {
        // Buckets are tiny (about the vertex valence), and ordering by `(high, slot)` keeps
        // the grouping deterministic.
        bucket.sort_unstable();
        for group in bucket.chunk_by(|x, y| x.high == y.high) {
            if let [first, second] = group {
                let (first, second) = (first.slot as usize, second.slot as usize);
                if traverses_forward(mesh, kept, first) != traverses_forward(mesh, kept, second) {
                    neighbours[first / 3][first % 3] = (second / 3) as u32;
                    neighbours[second / 3][second % 3] = (first / 3) as u32;
                }
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

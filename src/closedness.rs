//! Closedness of a whole mesh for the model record: edges used by exactly one stored triangle
//! (boundary) and edges used by more than two, or by two running it the same way
//! (non-manifold). Inside/outside is the exact parity of one ray only when both are zero.
//!
//! Edges are keyed by the bits of their two end positions, not by vertex indices: the tracer
//! and the crossing tie rule see positions, so two triangles meeting at equal coordinates share
//! the edge whatever their indices. Triangles Strip-RT drops (repeated index or no area) are not
//! stored and not counted.

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;

use crate::format::grid::Grid;
use crate::format::model::{Closedness, UpAxis};
use crate::geometry::Point;
use crate::mesh::Mesh;
use crate::stripify::adjacency::is_dropped;

/// A position by its bits, ordered lexicographically.
pub type PositionKey = [u32; 3];

/// One use of an edge: its ends as the smallest vertex of their position, in index order, and
/// whether the triangle runs it from the first to the second (12 bytes, where positions would
/// take 28).
type EdgeUse = (u32, u32, bool);

/// The edge counts of `mesh`'s stored triangles.
pub fn count_edges(mesh: &Mesh) -> Closedness {
    count_chunk_edges(mesh, |_| false).0
}

/// The uses of one edge within one chunk of a model converted in several: its ends in key
/// order and how many triangles run it each way. Chunks write these for the edges they cannot
/// close alone, and [`count_border_edges`] adds up every chunk's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Pod, Zeroable)]
#[repr(C)]
pub struct BorderEdge {
    pub first: PositionKey,
    pub second: PositionKey,
    /// Triangles running the edge from `first` to `second`.
    pub forward: u32,
    pub backward: u32,
}

impl BorderEdge {
    fn ends(&self) -> (PositionKey, PositionKey) {
        (self.first, self.second)
    }
}

/// The edge counts of one chunk's stored triangles over the edges it holds every use of, and,
/// sorted, the edges whose both ends are `shared` (positions other chunks may use too, so
/// their uses may continue there).
pub fn count_chunk_edges(
    mesh: &Mesh,
    shared: impl Fn(&PositionKey) -> bool,
) -> (Closedness, Vec<BorderEdge>) {
    let key = |vertex: u32| mesh.positions[vertex as usize].map(f32::to_bits);
    let same_position = first_vertex_of_position(mesh);
    let mut uses: Vec<EdgeUse> = Vec::with_capacity(mesh.triangles.len() * 3);
    for triangle in mesh.triangles.iter().filter(|t| !is_dropped(mesh, t)) {
        let corners = triangle.map(|v| same_position[v as usize]);
        uses.extend((0..3).map(|i| edge_use(corners[i], corners[(i + 1) % 3])));
    }
    uses.par_sort_unstable();
    let mut counts = Closedness::default();
    let mut border = Vec::new();
    for group in uses.chunk_by(|a, b| (a.0, a.1) == (b.0, b.1)) {
        let forward = group.iter().filter(|u| u.2).count() as u32;
        let backward = group.len() as u32 - forward;
        let (low, high) = (key(group[0].0), key(group[0].1));
        match shared(&low) && shared(&high) {
            true if low < high => border.push(BorderEdge {
                first: low,
                second: high,
                forward,
                backward,
            }),
            true => border.push(BorderEdge {
                first: high,
                second: low,
                forward: backward,
                backward: forward,
            }),
            false => tally(&mut counts, forward, backward),
        }
    }
    border.sort_unstable();
    (counts, border)
}

/// For each vertex, the smallest vertex at bit-identical coordinates: edges are edges of
/// positions, and a chunk may keep two vertices on one position apart (different attributes).
fn first_vertex_of_position(mesh: &Mesh) -> Vec<u32> {
    let key = |vertex: u32| mesh.positions[vertex as usize].map(f32::to_bits);
    let mut order: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    order.par_sort_unstable_by_key(|&vertex| (key(vertex), vertex));
    let mut first = vec![0u32; mesh.positions.len()];
    for group in order.chunk_by(|&a, &b| key(a) == key(b)) {
        group
            .iter()
            .for_each(|&vertex| first[vertex as usize] = group[0]);
    }
    first
}

/// The counts of the edges in `sorted` (every chunk's border edges, in key order), each edge's
/// uses summed over the chunks that hold some.
pub fn count_border_edges(sorted: &[BorderEdge]) -> Closedness {
    let mut counts = Closedness::default();
    for group in sorted.chunk_by(|a, b| a.ends() == b.ends()) {
        let forward: u64 = group.iter().map(|e| u64::from(e.forward)).sum();
        let backward: u64 = group.iter().map(|e| u64::from(e.backward)).sum();
        tally(&mut counts, forward, backward);
    }
    counts
}

/// Counts an edge used `forward` times one way and `backward` times the other: boundary when
/// used once, non-manifold unless used exactly once each way.
fn tally(counts: &mut Closedness, forward: impl Into<u64>, backward: impl Into<u64>) {
    match (forward.into(), backward.into()) {
        (1, 0) | (0, 1) => counts.boundary_edges += 1,
        (1, 1) => {}
        _ => counts.nonmanifold_edges += 1,
    }
}

fn edge_use(from: u32, to: u32) -> EdgeUse {
    match from < to {
        true => (from, to, true),
        false => (to, from, false),
    }
}

/// The key of `position` as stored: its grid point decoded, when the model has a grid.
pub fn stored_key(position: &Point, grid: Option<&Grid>) -> PositionKey {
    let stored = grid.map_or(*position, |grid| grid.decode(&grid.quantize(position)));
    stored.map(f32::to_bits)
}

/// A set of positions that may hold false members but never misses one: one bit per hash
/// bucket, two buckets per vertex of the model, so few unshared positions are taken for shared
/// ones.
pub struct SharedPositions {
    bits: Vec<u64>,
    mask: u64,
}

impl SharedPositions {
    pub fn new(vertex_count: u64) -> SharedPositions {
        let buckets = (vertex_count.saturating_mul(2))
            .next_power_of_two()
            .max(1 << 12);
        SharedPositions {
            bits: vec![0; (buckets / 64) as usize],
            mask: buckets - 1,
        }
    }

    /// The set of every position.
    pub fn everything() -> SharedPositions {
        SharedPositions {
            bits: vec![u64::MAX],
            mask: 63,
        }
    }

    pub fn insert(&mut self, key: &PositionKey) {
        let bucket = self.bucket(key);
        self.bits[(bucket / 64) as usize] |= 1 << (bucket % 64);
    }

    pub fn contains(&self, key: &PositionKey) -> bool {
        let bucket = self.bucket(key);
        self.bits[(bucket / 64) as usize] & (1 << (bucket % 64)) != 0
    }

    fn bucket(&self, key: &PositionKey) -> u64 {
        let packed = key.iter().fold(0u64, |hash, &word| {
            crate::splitmix::mix(hash ^ u64::from(word))
        });
        packed & self.mask
    }
}

/// The up axis of a model read from `path` when the configuration names none: its format's
/// (z for STL, whose CAD and printing sources stand on the xy plane, else y); y when the
/// format cannot be told, so the reading stage reports that instead.
pub fn default_up(path: &std::path::Path) -> UpAxis {
    crate::input::detect(path).map_or(UpAxis::Y, |detected| detected.format.default_up())
}

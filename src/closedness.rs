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
use crate::splitmix::hash_words;
use crate::stripify::adjacency::is_dropped;

/// A position by its bits, ordered lexicographically.
pub type PositionKey = [u32; 3];

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
    let mut uses = EdgeUses::of(mesh, &first_vertex_of_position(mesh));
    let mut counts = Closedness::default();
    let mut border = Vec::new();
    for (low, bucket) in uses.buckets_mut().filter(|(_, bucket)| !bucket.is_empty()) {
        // A bucket holds about a vertex's valence of uses.
        bucket.sort_unstable();
        let low = key(low);
        // Asked once a vertex: most positions are not shared, and then none of their edges is.
        let low_shared = shared(&low);
        for group in bucket.chunk_by(|a, b| a >> 1 == b >> 1) {
            let forward = group.iter().filter(|&&u| u & 1 == 1).count() as u32;
            let backward = group.len() as u32 - forward;
            let high = key((group[0] >> 1) as u32);
            match low_shared && shared(&high) {
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
    }
    border.sort_unstable();
    (counts, border)
}

/// Every use of an edge by a stored triangle, its ends taken as the smallest vertex of their
/// position, filed under its lower end by a counting sort: linear, where sorting the uses was
/// most of the cost. A use is `(higher end << 1) | forward` (8 bytes), `forward` when the
/// triangle runs the edge from its lower to its higher end.
struct EdgeUses {
    uses: Vec<u64>,
    /// `uses[bucket_end[v - 1]..bucket_end[v]]` are the uses whose lower end is `v`.
    bucket_end: Vec<usize>,
}

impl EdgeUses {
    fn of(mesh: &Mesh, same_position: &[u32]) -> EdgeUses {
        let edges: Vec<[u32; 2]> = (mesh.triangles.par_iter())
            .filter(|t| !is_dropped(mesh, t))
            .flat_map_iter(|t| {
                let [a, b, c] = t.map(|v| same_position[v as usize]);
                [[a, b], [b, c], [c, a]]
            })
            .collect();
        let mut bucket_end = vec![0usize; mesh.positions.len() + 1];
        for &[from, to] in &edges {
            bucket_end[from.min(to) as usize + 1] += 1;
        }
        for v in 1..bucket_end.len() {
            bucket_end[v] += bucket_end[v - 1];
        }
        let mut uses = vec![0u64; edges.len()];
        for &[from, to] in &edges {
            let cursor = &mut bucket_end[from.min(to) as usize];
            uses[*cursor] = (u64::from(from.max(to)) << 1) | u64::from(from < to);
            *cursor += 1;
        }
        // Each cursor now sits at its bucket's end; the trailing entry is unused.
        bucket_end.pop();
        EdgeUses { uses, bucket_end }
    }

    /// Each vertex with the uses filed under it.
    fn buckets_mut(&mut self) -> impl Iterator<Item = (u32, &mut [u64])> {
        let mut rest = self.uses.as_mut_slice();
        let mut start = 0;
        self.bucket_end
            .iter()
            .enumerate()
            .map(move |(vertex, &end)| {
                let (bucket, tail) = std::mem::take(&mut rest).split_at_mut(end - start);
                rest = tail;
                start = end;
                (vertex as u32, bucket)
            })
    }
}

/// For each vertex, the smallest vertex at bit-identical coordinates: edges are edges of
/// positions, and a chunk may keep two vertices on one position apart (different attributes).
/// Found with an open-addressing table of vertices filled in index order, so the first one
/// holding a position is the smallest.
fn first_vertex_of_position(mesh: &Mesh) -> Vec<u32> {
    const EMPTY: u32 = u32::MAX;
    let key = |vertex: u32| mesh.positions[vertex as usize].map(f32::to_bits);
    let mask = (mesh.positions.len() * 2).next_power_of_two() - 1;
    let mut slots = vec![EMPTY; mask + 1];
    (0..mesh.positions.len() as u32)
        .map(|vertex| {
            let position = key(vertex);
            let mut slot = hash_words(&position) as usize & mask;
            loop {
                match slots[slot] {
                    EMPTY => {
                        slots[slot] = vertex;
                        return vertex;
                    }
                    held if key(held) == position => return held,
                    _ => slot = (slot + 1) & mask,
                }
            }
        })
        .collect()
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
        hash_words(key) & self.mask
    }
}

/// The up axis of a model read from `path` when the configuration names none: its format's
/// (z for STL, whose CAD and printing sources stand on the xy plane, else y); y when the
/// format cannot be told, so the reading stage reports that instead.
pub fn default_up(path: &std::path::Path) -> UpAxis {
    crate::input::detect(path).map_or(UpAxis::Y, |detected| detected.format.default_up())
}

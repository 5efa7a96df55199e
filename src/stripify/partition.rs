//! Strip-RT step 2, partitioning (paper 4.1, "Partitioning").
//!
//! A binned-SAH object hierarchy (BVH-like) is built top-down over the kept triangles, down to
//! one triangle per leaf, exactly as the paper describes; the ordering step only needs each
//! node's parent and depth plus the triangle → leaf map (the paper's "inverse mapping").
//!
//! Design choices:
//! - Node ids do not depend on construction order, so the top levels can be built in parallel
//!   with `rayon::join` and the result is still identical for any thread count. The leaves are
//!   the triangles in their final partitioned order: leaf at position `p` is node
//!   `n - 1 + p`. Every internal node splits a contiguous range of positions at some `mid`, and
//!   every `mid` in `1..n` is used by exactly one node, so the internal node gets id `mid - 1`.
//!   The ids of a subtree then form contiguous ranges too, which lets the recursion hand out
//!   disjoint `&mut` slices to parallel tasks.
//! - Splits use `sah_bins` bins over the centroid bounds and the classic cost
//!   `area(left) * count(left) + area(right) * count(right)`. Child centroid bounds are
//!   gathered in the bins rather than in a separate scan. Nodes with fewer triangles than bins
//!   use one bin per triangle: more bins than triangles rarely find a better split, and the many
//!   tiny nodes near the leaves would otherwise dominate the build time.
//! - Deviation from the paper ("the best split ... using the SAH"): only the longest axis of
//!   the centroid bounds is binned, a common trade-off in fast SAH builders. It costs a third
//!   of all-axes binning, and this step dominates the stripification time because the
//!   hierarchy goes down to single triangles (about 2n nodes). Strip lengths do not suffer
//!   (docs/BENCHMARKS.md, "SAH binning axis").
//! - When SAH cannot separate the triangles (all centroids equal, or non-finite coordinates),
//!   the node is split at the median along the longest centroid axis.
//! - Deviation from the paper: from depth [`MAX_SAH_DEPTH`] on, every split is a median split.
//!   SAH alone can peel off one triangle per level on adversarial inputs; the guard bounds the
//!   depth by `MAX_SAH_DEPTH + log2(n)`, which keeps the ordering step's ancestor walks and the
//!   recursion's stack depth logarithmic. It only matters for pathological triangle
//!   distributions.

use rayon::prelude::*;

use crate::geometry::Aabb;
use crate::mesh::Mesh;

/// Marks the root's missing parent.
pub(crate) const NO_NODE: u32 = u32::MAX;

/// Depth from which SAH is no longer trusted to make progress; see the module docs.
pub const MAX_SAH_DEPTH: u32 = 64;

/// Ranges at least this large are split into parallel tasks; smaller ones are not worth the
/// scheduling overhead.
const PARALLEL_MIN_TRIANGLES: usize = 16 * 1024;

/// Parent and depth of one hierarchy node.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct NodeLinks {
    pub parent: u32,
    pub depth: u32,
}

/// The SAH object hierarchy over the kept (local) triangles, down to single triangles: what
/// Strip-RT orders by. Named a tree to keep it apart from the top-level hierarchy over strips
/// (`toplevel`) and the pipeline's hierarchy stage.
#[derive(Clone, Debug, Default)]
pub struct TriangleTree {
    /// Per node id; internal nodes are `0..n-1`, leaves `n-1..2n-1` (see the module docs).
    nodes: Vec<NodeLinks>,
    /// Leaf node of each local triangle.
    leaf_of_triangle: Vec<u32>,
}

/// A triangle's bounds, moved around during partitioning so that the binning passes read
/// contiguous memory. Aligned to 32 bytes (from 28): the partition swaps these constantly,
/// and odd-sized overlapping copies stall store forwarding.
#[derive(Clone, Copy, Debug)]
#[repr(align(16))]
struct TriangleRef {
    bounds: Aabb,
    triangle: u32,
}

impl TriangleRef {
    fn centroid(&self, axis: usize) -> f32 {
        self.bounds.centroid(axis)
    }

    fn centroid_point(&self) -> [f32; 3] {
        [0, 1, 2].map(|axis| self.centroid(axis))
    }
}

/// Triangles whose centroids fall into one bin: their bounds (for the SAH cost), their
/// centroids' bounds (handed to the children, which saves a scan per node) and their count.
#[derive(Clone, Copy, Debug)]
struct Bin {
    bounds: Aabb,
    centroid_bounds: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin {
    bounds: Aabb::EMPTY,
    centroid_bounds: Aabb::EMPTY,
    count: 0,
};

/// Per-task scratch memory, reused across the nodes one task builds.
#[derive(Default)]
struct SplitScratch {
    bins: Vec<Bin>,
    right_costs: Vec<f64>,
}

impl TriangleTree {
    /// Builds the hierarchy over `kept` mesh triangles (local triangle `i` is mesh triangle
    /// `kept[i]`). `sah_bins` below 2 is treated as 2.
    pub fn build(mesh: &Mesh, kept: &[u32], sah_bins: usize) -> TriangleTree {
        let n = kept.len();
        if n == 0 {
            return TriangleTree::default();
        }
        let mut refs: Vec<TriangleRef> = kept
            .par_iter()
            .enumerate()
            .map(|(local, &mesh_index)| TriangleRef {
                bounds: Aabb::from_points(
                    &mesh.triangle_points(&mesh.triangles[mesh_index as usize]),
                ),
                triangle: local as u32,
            })
            .collect();
        let mut nodes = vec![NodeLinks::default(); 2 * n - 1];
        let (internal, leaves) = nodes.split_at_mut(n - 1);
        let root = NodeLinks {
            parent: NO_NODE,
            depth: 0,
        };
        let centroid_bounds = centroid_bounds_of(&refs);
        let subtree = Subtree {
            refs: &mut refs,
            internal,
            leaves,
            offset: 0,
            centroid_bounds,
        };
        build_subtree(sah_bins.max(2), subtree, root, &mut SplitScratch::default());

        let mut leaf_of_triangle = vec![NO_NODE; n];
        for (position, r) in refs.iter().enumerate() {
            leaf_of_triangle[r.triangle as usize] = (n - 1 + position) as u32;
        }
        TriangleTree {
            nodes,
            leaf_of_triangle,
        }
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    pub(crate) fn leaf_of(&self, triangle: u32) -> u32 {
        self.leaf_of_triangle[triangle as usize]
    }

    pub(crate) fn parent(&self, node: u32) -> u32 {
        self.nodes[node as usize].parent
    }

    pub(crate) fn depth(&self, node: u32) -> u32 {
        self.nodes[node as usize].depth
    }

    /// Deepest node that is an ancestor of (or equal to) both `a` and `b`. Walks parent links,
    /// so it costs the depth of the two nodes below their common ancestor.
    pub(crate) fn lowest_common_ancestor(&self, mut a: u32, mut b: u32) -> u32 {
        while self.depth(a) > self.depth(b) {
            a = self.parent(a);
        }
        while self.depth(b) > self.depth(a) {
            b = self.parent(b);
        }
        while a != b {
            a = self.parent(a);
            b = self.parent(b);
        }
        a
    }

    /// Checks the structural invariants: every triangle sits in exactly one leaf, exactly one
    /// root at depth 0, every other node one deeper than its parent, internal nodes have two
    /// children and leaves none.
    pub fn validate(&self) -> Result<(), String> {
        let n = self.leaf_of_triangle.len();
        let expected_nodes = if n == 0 { 0 } else { 2 * n - 1 };
        if self.nodes.len() != expected_nodes {
            return Err(format!("{} nodes for {n} triangles", self.nodes.len()));
        }
        self.validate_leaf_map()?;
        self.validate_links()
    }

    fn validate_leaf_map(&self) -> Result<(), String> {
        let first_leaf = self.leaf_of_triangle.len().saturating_sub(1);
        let mut leaf_taken = vec![false; self.leaf_of_triangle.len()];
        for (triangle, &leaf) in self.leaf_of_triangle.iter().enumerate() {
            let position = (leaf as usize).checked_sub(first_leaf);
            let taken = position.and_then(|p| leaf_taken.get_mut(p));
            match taken {
                Some(taken) if !*taken => *taken = true,
                _ => {
                    return Err(format!(
                        "triangle {triangle} maps to bad or shared leaf {leaf}"
                    ))
                }
            }
        }
        Ok(())
    }

    fn validate_links(&self) -> Result<(), String> {
        let first_leaf = self.leaf_of_triangle.len().saturating_sub(1);
        let mut child_counts = vec![0u32; self.nodes.len()];
        let mut roots = 0;
        for (node, links) in self.nodes.iter().enumerate() {
            if links.parent == NO_NODE {
                roots += 1;
                if links.depth != 0 {
                    return Err(format!("root {node} has depth {}", links.depth));
                }
                continue;
            }
            let parent = self
                .nodes
                .get(links.parent as usize)
                .ok_or(format!("node {node}: bad parent"))?;
            if links.depth != parent.depth + 1 || links.parent as usize >= first_leaf {
                return Err(format!(
                    "node {node} at depth {} under {:?}",
                    links.depth, parent
                ));
            }
            child_counts[links.parent as usize] += 1;
        }
        if !self.nodes.is_empty() && roots != 1 {
            return Err(format!("{roots} roots"));
        }
        for (node, &count) in child_counts.iter().enumerate() {
            let expected = if node < first_leaf { 2 } else { 0 };
            if count != expected {
                return Err(format!(
                    "node {node} has {count} children, expected {expected}"
                ));
            }
        }
        Ok(())
    }
}

/// The part of the hierarchy one recursive call builds: `refs` are its triangles, whose leaves
/// start at position `offset`; `internal` and `leaves` are exactly its node slots (internal ids
/// `offset..offset + len - 1`, leaf positions `offset..offset + len`).
struct Subtree<'a> {
    refs: &'a mut [TriangleRef],
    internal: &'a mut [NodeLinks],
    leaves: &'a mut [NodeLinks],
    offset: usize,
    centroid_bounds: Aabb,
}

/// Builds `subtree`, whose root has the parent and depth given by `links`.
fn build_subtree(sah_bins: usize, subtree: Subtree, links: NodeLinks, scratch: &mut SplitScratch) {
    let Subtree {
        refs,
        internal,
        leaves,
        offset,
        centroid_bounds,
    } = subtree;
    if refs.len() == 1 {
        leaves[0] = links;
        return;
    }
    let parallel = refs.len() >= PARALLEL_MIN_TRIANGLES;
    let split = partition_node(sah_bins, refs, &centroid_bounds, links.depth, scratch);
    let mid = split.left_count;
    let (left_internal, own_and_right) = internal.split_at_mut(mid - 1);
    let (own, right_internal) = own_and_right.split_at_mut(1);
    own[0] = links;
    let child_links = NodeLinks {
        parent: (offset + mid - 1) as u32,
        depth: links.depth + 1,
    };
    let (left_refs, right_refs) = refs.split_at_mut(mid);
    let (left_leaves, right_leaves) = leaves.split_at_mut(mid);
    let left = Subtree {
        refs: left_refs,
        internal: left_internal,
        leaves: left_leaves,
        offset,
        centroid_bounds: split.left_centroid_bounds,
    };
    let right = Subtree {
        refs: right_refs,
        internal: right_internal,
        leaves: right_leaves,
        offset: offset + mid,
        centroid_bounds: split.right_centroid_bounds,
    };
    if parallel {
        rayon::join(
            || build_subtree(sah_bins, left, child_links, scratch),
            || build_subtree(sah_bins, right, child_links, &mut SplitScratch::default()),
        );
    } else {
        build_subtree(sah_bins, left, child_links, scratch);
        build_subtree(sah_bins, right, child_links, scratch);
    }
}

/// The outcome of splitting one node: `refs[..left_count]` go left, the rest right.
struct NodeSplit {
    left_count: usize,
    left_centroid_bounds: Aabb,
    right_centroid_bounds: Aabb,
}

/// Reorders `refs` into a non-empty left and a non-empty right part.
fn partition_node(
    sah_bins: usize,
    refs: &mut [TriangleRef],
    centroid_bounds: &Aabb,
    depth: u32,
    scratch: &mut SplitScratch,
) -> NodeSplit {
    if let [left, right] = refs {
        // The only possible split; about a third of all nodes, so worth skipping the binning.
        return NodeSplit {
            left_count: 1,
            left_centroid_bounds: centroid_bounds_of(std::slice::from_ref(left)),
            right_centroid_bounds: centroid_bounds_of(std::slice::from_ref(right)),
        };
    }
    let axis = centroid_bounds.longest_axis();
    if depth < MAX_SAH_DEPTH {
        let bins = sah_bins.min(refs.len());
        if let Some(split) = best_sah_split(refs, centroid_bounds, axis, bins, scratch) {
            let left_count = partition_in_place(refs, |r| split.goes_left(r));
            let (left_bins, right_bins) = scratch.bins.split_at(split.first_right_bin);
            return NodeSplit {
                left_count,
                left_centroid_bounds: union_of_centroid_bounds(left_bins),
                right_centroid_bounds: union_of_centroid_bounds(right_bins),
            };
        }
    }
    median_split(refs, axis)
}

fn centroid_bounds_of(refs: &[TriangleRef]) -> Aabb {
    let mut bounds = Aabb::EMPTY;
    for r in refs {
        bounds.grow_point(&r.centroid_point());
    }
    bounds
}

/// A bin boundary on one axis: triangles whose centroid falls into a bin below `first_right_bin`
/// go left.
#[derive(Clone, Copy, Debug)]
struct SahSplit {
    axis: usize,
    binning: Binning,
    first_right_bin: usize,
}

impl SahSplit {
    fn goes_left(&self, r: &TriangleRef) -> bool {
        self.binning.bin(r.centroid(self.axis)) < self.first_right_bin
    }
}

/// Maps centroids on one axis to bins. The same instance is used for binning and for the final
/// partition, so both agree bit for bit.
#[derive(Clone, Copy, Debug)]
struct Binning {
    min: f32,
    scale: f32,
    bins: usize,
}

impl Binning {
    fn bin(&self, centroid: f32) -> usize {
        // `as usize` saturates (NaN → 0), so non-finite input cannot index out of range.
        (((centroid - self.min) * self.scale) as usize).min(self.bins - 1)
    }
}

/// Finds the cheapest SAH split along `axis`, or `None` when the centroids cannot be separated
/// there (zero or non-finite extent). Ties keep the lowest boundary.
fn best_sah_split(
    refs: &[TriangleRef],
    centroid_bounds: &Aabb,
    axis: usize,
    bins: usize,
    scratch: &mut SplitScratch,
) -> Option<SahSplit> {
    let extent = centroid_bounds.extent(axis);
    if !(extent > 0.0 && extent.is_finite()) {
        return None;
    }
    let binning = Binning {
        min: centroid_bounds.min[axis],
        scale: bins as f32 / extent,
        bins,
    };
    fill_bins(refs, axis, &binning, scratch);
    let first_right_bin = cheapest_boundary(scratch)?;
    Some(SahSplit {
        axis,
        binning,
        first_right_bin,
    })
}

fn fill_bins(refs: &[TriangleRef], axis: usize, binning: &Binning, scratch: &mut SplitScratch) {
    scratch.bins.clear();
    scratch.bins.resize(binning.bins, EMPTY_BIN);
    for r in refs {
        let bin = &mut scratch.bins[binning.bin(r.centroid(axis))];
        grow_by_range(&mut bin.bounds, &r.bounds.min, &r.bounds.max);
        let centroid = r.centroid_point();
        grow_by_range(&mut bin.centroid_bounds, &centroid, &centroid);
        bin.count += 1;
    }
}

/// Grows `bounds` to include the box `min..max`. Same result as [`Aabb::grow`] (a NaN input
/// coordinate is ignored, and `bounds` never holds NaN), but written as plain comparisons so it
/// compiles to bare min/max instructions; this is the innermost loop of the whole build.
fn grow_by_range(bounds: &mut Aabb, min: &[f32; 3], max: &[f32; 3]) {
    for axis in 0..3 {
        if min[axis] < bounds.min[axis] {
            bounds.min[axis] = min[axis];
        }
        if max[axis] > bounds.max[axis] {
            bounds.max[axis] = max[axis];
        }
    }
}

fn union_of_centroid_bounds(bins: &[Bin]) -> Aabb {
    bins.iter().fold(Aabb::EMPTY, |bounds, bin| {
        bounds.union(&bin.centroid_bounds)
    })
}

/// Sweeps the filled bins from both sides and returns the cheapest boundary that leaves
/// triangles on both sides, by the cost `area(left) * count(left) + area(right) * count(right)`.
fn cheapest_boundary(scratch: &mut SplitScratch) -> Option<usize> {
    let bins = &scratch.bins;
    let right_costs = &mut scratch.right_costs;
    right_costs.clear();
    right_costs.resize(bins.len(), f64::INFINITY);
    let (mut right_bounds, mut right_count) = (Aabb::EMPTY, 0u32);
    for boundary in (1..bins.len()).rev() {
        right_bounds.grow(&bins[boundary].bounds);
        right_count += bins[boundary].count;
        if right_count > 0 {
            right_costs[boundary] = right_bounds.surface_area() * right_count as f64;
        }
    }
    let (mut left_bounds, mut left_count) = (Aabb::EMPTY, 0u32);
    let mut best: Option<(f64, usize)> = None;
    for boundary in 1..bins.len() {
        left_bounds.grow(&bins[boundary - 1].bounds);
        left_count += bins[boundary - 1].count;
        if left_count == 0 || right_costs[boundary].is_infinite() {
            continue;
        }
        let cost = left_bounds.surface_area() * left_count as f64 + right_costs[boundary];
        if best.is_none_or(|(best_cost, _)| cost < best_cost) {
            best = Some((cost, boundary));
        }
    }
    best.map(|(_, boundary)| boundary)
}

/// Moves the elements satisfying `goes_left` to the front and returns their count.
///
/// Branch-free Lomuto scheme: every element is swapped to the boundary and the boundary only
/// advances for left elements (swapping a right element with itself or with another right
/// element is harmless). Near the top of the tree the predicate is close to random in input
/// order, and a data-dependent branch there would mispredict half of the time. Deterministic
/// for a given input order, which is all the build needs.
fn partition_in_place(refs: &mut [TriangleRef], goes_left: impl Fn(&TriangleRef) -> bool) -> usize {
    let mut left_count = 0;
    for i in 0..refs.len() {
        let left = goes_left(&refs[i]);
        refs.swap(left_count, i);
        left_count += left as usize;
    }
    left_count
}

/// Splits into halves by centroid along `axis`; `select_nth_unstable_by` is deterministic.
fn median_split(refs: &mut [TriangleRef], axis: usize) -> NodeSplit {
    let mid = refs.len() / 2;
    refs.select_nth_unstable_by(mid, |a, b| a.centroid(axis).total_cmp(&b.centroid(axis)));
    NodeSplit {
        left_count: mid,
        left_centroid_bounds: centroid_bounds_of(&refs[..mid]),
        right_centroid_bounds: centroid_bounds_of(&refs[mid..]),
    }
}

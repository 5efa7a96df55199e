//! The global hierarchy over strips (paper 3.2: "one global high-level hierarchy whose leaf nodes
//! contain the strip hierarchies").
//!
//! Built in two steps: a binned-SAH binary bounding volume hierarchy over strip bounds, then
//! collapsed into 4-wide nodes ([`TopNode`]). A wide node rooted at a binary node takes its two
//! children as slots and may open internal slots (replace one by its two children) up to four;
//! which ones each wide node opens is chosen bottom-up by dynamic programming so that the wide
//! nodes' total surface area, the SAH's expected number of node visits, is least (as in Ylitie
//! et al. 2017, with the binary tree's leaves kept). Compared with the greedy top-down collapse
//! (open the largest child until four), this fills the nodes near the leaves, where most of
//! them are: 12% fewer nodes on a 1M-triangle scan, at the same tracing speed. Opening a slot
//! in place keeps the leaves in the binary tree's order, so the strip numbering is the binary
//! tree's.
//!
//! Deviation from the paper: binary BVH → 4-wide for SIMD box tests and fewer bytes. A ray
//! tests four boxes with one set of vector operations per node fetch, and the top level takes
//! one 128-byte node per about 2.4 leaves instead of two 32-byte nodes per leaf (2.57 instead
//! of 3.11 bytes per triangle on a 1M-triangle scan).
//!
//! Nodes are emitted depth-first (a node's first internal child right after it) and the strips
//! are renumbered in leaf order, so the strips of a subtree are contiguous in the strip-data
//! section and a subtree's nodes are contiguous in the node section: a ray that stays in one
//! region of the model pages in few pages of either.

use crate::format::{TopNode, TopSlot, INTERNAL_CHILD, MAX_TOP_DEPTH, TOP_WIDTH};
use crate::geometry::Aabb;

/// Build parameters of the top-level hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct TopLevelParams {
    /// SAH bins per axis.
    pub bins: usize,
    /// Most strips in one leaf; the SAH may stop earlier.
    pub max_leaf_strips: usize,
    /// Cost of one node traversal relative to testing one strip, for the SAH termination.
    pub traversal_cost: f64,
}

impl Default for TopLevelParams {
    fn default() -> Self {
        TopLevelParams {
            bins: 16,
            max_leaf_strips: 4,
            traversal_cost: 0.5,
        }
    }
}

/// The built hierarchy: nodes in file order and, for each file strip position, the input strip.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TopLevel {
    pub nodes: Vec<TopNode>,
    pub strip_order: Vec<u32>,
}

/// Builds the hierarchy over `bounds` (one box per strip).
pub fn build(bounds: &[Aabb], params: &TopLevelParams) -> TopLevel {
    let (binary, strip_order) = build_binary(bounds, params);
    let mut nodes = NodeArray(Vec::with_capacity(binary.len() / 3 + 1));
    if binary.is_empty() {
        nodes.0.push(TopNode::EMPTY);
    } else {
        emit(&Collapse::new(&binary), 0, &mut nodes);
    }
    TopLevel {
        nodes: nodes.0,
        strip_order,
    }
}

/// A node of the binary SAH hierarchy, before it is collapsed into wide nodes.
#[derive(Clone, Copy, Debug)]
struct BinaryNode {
    bounds: Aabb,
    kind: BinaryKind,
}

#[derive(Clone, Copy, Debug)]
enum BinaryKind {
    /// Strips `first .. first + count` in leaf order.
    Leaf {
        first: u32,
        count: u32,
    },
    Internal {
        left: usize,
        right: usize,
    },
}

/// The binary hierarchy in preorder (empty without strips) and the strips in leaf order.
fn build_binary(bounds: &[Aabb], params: &TopLevelParams) -> (Vec<BinaryNode>, Vec<u32>) {
    let mut builder = Builder {
        bounds,
        params,
        centroids: bounds
            .iter()
            .map(|b| [0, 1, 2].map(|a| b.centroid(a)))
            .collect(),
        nodes: Vec::with_capacity(bounds.len().max(1) * 2 / params.max_leaf_strips.max(1) + 1),
    };
    let mut order: Vec<u32> = (0..bounds.len() as u32).collect();
    if !order.is_empty() {
        builder.subtree(&mut order, 0, 0);
    }
    (builder.nodes, order)
}

struct Builder<'a> {
    bounds: &'a [Aabb],
    params: &'a TopLevelParams,
    centroids: Vec<[f32; 3]>,
    nodes: Vec<BinaryNode>,
}

/// Below this depth splits are SAH; deeper ones are median splits, which bound the depth at
/// `SAH_DEPTH_LIMIT + log2(strips)`, well inside the reader's [`crate::format::MAX_TOP_DEPTH`].
const SAH_DEPTH_LIMIT: usize = 48;
/// `Split::bin` value of a median split.
const MEDIAN_SPLIT: usize = usize::MAX;

struct Split {
    axis: usize,
    /// Strips going left: those with a centroid bin below this.
    bin: usize,
    cost: f64,
}

impl Builder<'_> {
    /// Emits the subtree over `strips` (whose file positions start at `first`) in preorder.
    fn subtree(&mut self, strips: &mut [u32], first: usize, depth: usize) {
        let bounds = strips
            .iter()
            .fold(Aabb::EMPTY, |b, &s| b.union(&self.bounds[s as usize]));
        let node_index = self.nodes.len();
        let split = if depth < SAH_DEPTH_LIMIT {
            self.best_split(strips, &bounds)
        } else {
            self.median_split(strips)
        };
        let leaf_cost = strips.len() as f64;
        let must_split = strips.len() > self.params.max_leaf_strips;
        let split = split.filter(|s| must_split || s.cost < leaf_cost);
        let leaf = BinaryKind::Leaf {
            first: first as u32,
            count: strips.len() as u32,
        };
        self.nodes.push(BinaryNode { bounds, kind: leaf });
        let Some(left_count) = split.as_ref().map(|s| self.partition(strips, s)) else {
            return;
        };
        let (left, right) = strips.split_at_mut(left_count);
        self.subtree(left, first, depth + 1);
        let right_index = self.nodes.len();
        self.subtree(right, first + left_count, depth + 1);
        self.nodes[node_index].kind = BinaryKind::Internal {
            left: node_index + 1,
            right: right_index,
        };
    }

    /// The cheapest binned SAH split, or a median split when all centroids share a bin.
    fn best_split(&self, strips: &[u32], bounds: &Aabb) -> Option<Split> {
        if strips.len() < 2 {
            return None;
        }
        let centroid_bounds =
            Aabb::from_points(strips.iter().map(|&s| &self.centroids[s as usize]));
        let best = (0..3)
            .filter(|&axis| centroid_bounds.extent(axis) > 0.0)
            .filter_map(|axis| self.best_split_on_axis(strips, axis, &centroid_bounds, bounds))
            .min_by(|a, b| a.cost.total_cmp(&b.cost));
        best.or_else(|| self.median_split(strips))
    }

    fn median_split(&self, strips: &[u32]) -> Option<Split> {
        let centroid_bounds =
            Aabb::from_points(strips.iter().map(|&s| &self.centroids[s as usize]));
        (strips.len() >= 2).then(|| Split {
            axis: centroid_bounds.longest_axis(),
            bin: MEDIAN_SPLIT,
            cost: f64::INFINITY,
        })
    }

    fn best_split_on_axis(
        &self,
        strips: &[u32],
        axis: usize,
        centroids: &Aabb,
        bounds: &Aabb,
    ) -> Option<Split> {
        let bins = self.params.bins.max(2);
        let mut bin_bounds = vec![Aabb::EMPTY; bins];
        let mut bin_counts = vec![0usize; bins];
        for &s in strips {
            let bin = self.bin_of(s, axis, centroids, bins);
            bin_bounds[bin].grow(&self.bounds[s as usize]);
            bin_counts[bin] += 1;
        }
        let mut right_area = vec![0.0; bins];
        let mut right_count = vec![0usize; bins];
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for bin in (1..bins).rev() {
            acc.grow(&bin_bounds[bin]);
            count += bin_counts[bin];
            right_area[bin] = acc.surface_area();
            right_count[bin] = count;
        }
        let parent_area = bounds.surface_area().max(f64::MIN_POSITIVE);
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        let mut best: Option<Split> = None;
        for bin in 1..bins {
            acc.grow(&bin_bounds[bin - 1]);
            count += bin_counts[bin - 1];
            if count == 0 || right_count[bin] == 0 {
                continue;
            }
            let cost = self.params.traversal_cost
                + (acc.surface_area() * count as f64 + right_area[bin] * right_count[bin] as f64)
                    / parent_area;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(Split { axis, bin, cost });
            }
        }
        best
    }

    fn bin_of(&self, strip: u32, axis: usize, centroids: &Aabb, bins: usize) -> usize {
        let scale = bins as f32 / centroids.extent(axis);
        let offset = self.centroids[strip as usize][axis] - centroids.min[axis];
        ((offset * scale) as usize).min(bins - 1)
    }

    /// Reorders `strips` so the left side comes first and returns its length.
    fn partition(&self, strips: &mut [u32], split: &Split) -> usize {
        if split.bin == MEDIAN_SPLIT {
            return self.median_partition(strips, split.axis);
        }
        let centroids = Aabb::from_points(strips.iter().map(|&s| &self.centroids[s as usize]));
        let bins = self.params.bins.max(2);
        let mut left = 0;
        for i in 0..strips.len() {
            if self.bin_of(strips[i], split.axis, &centroids, bins) < split.bin {
                strips.swap(i, left);
                left += 1;
            }
        }
        left
    }

    /// Splits at the median centroid, ties broken by strip id, so that equal centroids still
    /// separate deterministically.
    fn median_partition(&self, strips: &mut [u32], axis: usize) -> usize {
        let mid = strips.len() / 2;
        strips.select_nth_unstable_by(mid, |&a, &b| {
            let (ca, cb) = (
                self.centroids[a as usize][axis],
                self.centroids[b as usize][axis],
            );
            ca.total_cmp(&cb).then(a.cmp(&b))
        });
        mid
    }
}

/// The slots of a wide node: binary node indices, in leaf order.
#[derive(Clone, Copy, Debug)]
struct Frontier {
    nodes: [usize; TOP_WIDTH],
    len: usize,
}

impl Frontier {
    fn slots(&self) -> &[usize] {
        &self.nodes[..self.len]
    }

    /// The frontier with `self.nodes[i]` replaced by its two children, in place.
    fn open(&self, i: usize, children: [usize; 2]) -> Frontier {
        let mut opened = Frontier {
            nodes: [0; TOP_WIDTH],
            len: self.len + 1,
        };
        opened.nodes[..i].copy_from_slice(&self.nodes[..i]);
        opened.nodes[i..i + 2].copy_from_slice(&children);
        opened.nodes[i + 2..opened.len].copy_from_slice(&self.nodes[i + 1..self.len]);
        opened
    }
}

/// How the binary tree is cut into wide nodes: for each binary internal node, the least total
/// surface area of the wide nodes under it when it roots one (the SAH's expected number of node
/// visits, up to a constant), computed bottom-up.
struct Collapse<'a> {
    tree: &'a [BinaryNode],
    cost: Vec<f64>,
}

impl Collapse<'_> {
    fn new(tree: &[BinaryNode]) -> Collapse<'_> {
        let mut collapse = Collapse {
            tree,
            cost: vec![0.0; tree.len()],
        };
        // Preorder puts children after their parent: reverse order is bottom-up.
        for index in (0..tree.len()).rev() {
            if let BinaryKind::Internal { .. } = tree[index].kind {
                collapse.cost[index] =
                    tree[index].bounds.surface_area() + collapse.frontier(index).0;
            }
        }
        collapse
    }

    /// The slots of the wide node rooted at binary node `index` with their cost: its two
    /// children, with internal ones opened (up to [`TOP_WIDTH`] slots) wherever that lowers the
    /// total. A binary leaf (only ever the root) stands alone.
    fn frontier(&self, index: usize) -> (f64, Frontier) {
        let start = match self.tree[index].kind {
            BinaryKind::Internal { left, right } => Frontier {
                nodes: [left, right, 0, 0],
                len: 2,
            },
            BinaryKind::Leaf { .. } => Frontier {
                nodes: [index, 0, 0, 0],
                len: 1,
            },
        };
        let mut best = (f64::INFINITY, start);
        self.cheapest(start, &mut best);
        best
    }

    /// Tries `frontier` and every way of opening more of its internal slots.
    fn cheapest(&self, frontier: Frontier, best: &mut (f64, Frontier)) {
        let cost: f64 = frontier.slots().iter().map(|&c| self.cost[c]).sum();
        // Strictly lower only: of equal totals the one found first, with fewer slots opened.
        if cost < best.0 {
            *best = (cost, frontier);
        }
        if frontier.len == TOP_WIDTH {
            return;
        }
        for (i, &c) in frontier.slots().iter().enumerate() {
            if let BinaryKind::Internal { left, right } = self.tree[c].kind {
                self.cheapest(frontier.open(i, [left, right]), best);
            }
        }
    }
}

/// Where collapsed wide nodes go: the node array of one hierarchy, or the splice's item list.
trait WideOut {
    /// Reserves the next node; returns its file index and a handle for [`WideOut::complete`].
    fn open(&mut self) -> (u32, usize);
    fn complete(&mut self, handle: usize, node: TopNode);
    /// The `(child, kind)` a binary leaf's slot holds, emitting what the slot points at.
    fn leaf(&mut self, first: u32, count: u32) -> (u32, u32);
}

/// Emits the wide node standing for binary node `index`, then its subtree, in preorder;
/// returns its file index.
fn emit(collapse: &Collapse, index: usize, out: &mut impl WideOut) -> u32 {
    let tree = collapse.tree;
    let (file_index, handle) = out.open();
    let mut node = TopNode::EMPTY;
    for (slot, &child) in collapse.frontier(index).1.slots().iter().enumerate() {
        let (link, kind) = match tree[child].kind {
            BinaryKind::Leaf { first, count } => out.leaf(first, count),
            BinaryKind::Internal { .. } => (emit(collapse, child, out), INTERNAL_CHILD),
        };
        let bounds = &tree[child].bounds;
        node.set(slot, &bounds.min, &bounds.max, link, kind);
    }
    out.complete(handle, node);
    file_index
}

/// The nodes of one hierarchy; leaves hold their strip ranges.
struct NodeArray(Vec<TopNode>);

impl WideOut for NodeArray {
    fn open(&mut self) -> (u32, usize) {
        self.0.push(TopNode::EMPTY);
        ((self.0.len() - 1) as u32, self.0.len() - 1)
    }

    fn complete(&mut self, handle: usize, node: TopNode) {
        self.0[handle] = node;
    }

    fn leaf(&mut self, first: u32, count: u32) -> (u32, u32) {
        (first, count)
    }
}

impl TopLevel {
    /// Checks the structure: nodes in preorder within [`MAX_TOP_DEPTH`], occupied slots first
    /// and empty ones exact, every strip in exactly one leaf with leaves in strip order, every
    /// slot's box containing its child's slot boxes or its strips' bounds.
    pub fn validate(&self, bounds: &[Aabb]) -> Result<(), String> {
        let mut walk = ValidateWalk {
            top: self,
            bounds,
            visited: 0,
            next_strip: 0,
        };
        walk.node(0, None, 0)?;
        if walk.visited != self.nodes.len() {
            return Err(format!(
                "{} nodes, {} reachable",
                self.nodes.len(),
                walk.visited
            ));
        }
        if walk.next_strip != bounds.len() || self.strip_order.len() != bounds.len() {
            return Err(format!(
                "leaves cover {} strips of {}",
                walk.next_strip,
                bounds.len()
            ));
        }
        let mut seen = vec![false; bounds.len()];
        for &strip in &self.strip_order {
            if std::mem::replace(&mut seen[strip as usize], true) {
                return Err(format!("strip {strip} is in two leaves"));
            }
        }
        Ok(())
    }
}

/// The preorder walk of [`TopLevel::validate`].
struct ValidateWalk<'a> {
    top: &'a TopLevel,
    bounds: &'a [Aabb],
    visited: usize,
    next_strip: usize,
}

impl ValidateWalk<'_> {
    /// Checks node `index`, whose parent's slot box is `parent_box` (none for the root).
    fn node(&mut self, index: usize, parent_box: Option<Aabb>, depth: usize) -> Result<(), String> {
        let node = self
            .top
            .nodes
            .get(index)
            .ok_or(format!("node {index} out of range"))?;
        if index != self.visited || depth > MAX_TOP_DEPTH {
            return Err(format!("node {index} is out of preorder or too deep"));
        }
        self.visited += 1;
        let occupied = node.occupied();
        if let Some(slot) = (occupied..TOP_WIDTH).find(|&slot| !node.is_exactly_empty(slot)) {
            return Err(format!("node {index} slot {slot} is not exactly empty"));
        }
        for slot in 0..occupied {
            let (min, max) = node.slot_box(slot);
            let slot_box = Aabb { min, max };
            if parent_box.is_some_and(|parent| !parent.contains_box(&slot_box)) {
                return Err(format!(
                    "node {index} slot {slot} is outside its parent's box"
                ));
            }
            match node.slot(slot) {
                TopSlot::Internal(child) => self.node(child as usize, Some(slot_box), depth + 1)?,
                TopSlot::Leaf { first, count } => self.leaf(index, &slot_box, first, count)?,
                other => return Err(format!("node {index} slot {slot} holds {other:?}")),
            }
        }
        Ok(())
    }

    fn leaf(
        &mut self,
        index: usize,
        slot_box: &Aabb,
        first: u32,
        count: u32,
    ) -> Result<(), String> {
        if first as usize != self.next_strip {
            return Err(format!(
                "node {index}: leaf at strip {first}, expected {}",
                self.next_strip
            ));
        }
        for position in first as usize..(first + count) as usize {
            let strip = *self
                .top
                .strip_order
                .get(position)
                .ok_or("leaf strip out of range")? as usize;
            let strip_box = self.bounds.get(strip).ok_or("strip id out of range")?;
            if !slot_box.contains_box(strip_box) {
                return Err(format!("node {index} does not contain strip {strip}"));
            }
        }
        self.next_strip += count as usize;
        Ok(())
    }
}

/// One chunk's finished hierarchy, as the splice sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Subtree {
    /// The union of the chunk's strip bounds: the box of the upper slot pointing at its root.
    pub bounds: Aabb,
    pub node_count: u32,
    pub strip_count: u32,
}

/// One step of the spliced hierarchy in final preorder: an upper node over chunks, or a whole
/// chunk subtree whose nodes and strips are renumbered from the given bases.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpliceItem {
    Node(TopNode),
    Subtree {
        index: usize,
        node_base: u32,
        strip_base: u32,
    },
}

/// Joins per-chunk hierarchies under an upper SAH hierarchy over their root boxes (paper 4.2:
/// chunks stripified separately, "with a merge operation at the end").
///
/// Each chunk's nodes and strips stay contiguous, so the final file can be written by streaming
/// chunk after chunk, and a subtree's nodes and strips sit together in the file. The upper
/// hierarchy is built like the per-chunk ones with one chunk per leaf and collapsed the same
/// way, except that a leaf becomes an internal slot pointing at the chunk's root. A single chunk
/// needs no upper node: its root is the file's. Chunks without strips are left out.
pub fn splice(subtrees: &[Subtree], params: &TopLevelParams) -> Vec<SpliceItem> {
    let used: Vec<usize> = (0..subtrees.len())
        .filter(|&i| subtrees[i].strip_count > 0)
        .collect();
    let bounds: Vec<Aabb> = used.iter().map(|&i| subtrees[i].bounds).collect();
    let upper_params = TopLevelParams {
        max_leaf_strips: 1,
        ..params.clone()
    };
    let (upper, chunk_order) = build_binary(&bounds, &upper_params);
    let mut out = SpliceOut {
        chunk_order: chunk_order.iter().map(|&c| used[c as usize]).collect(),
        subtrees,
        items: Vec::new(),
        next_node: 0,
        next_strip: 0,
    };
    match upper.len() {
        0 => out.items.push(SpliceItem::Node(TopNode::EMPTY)),
        1 => {
            out.leaf(0, 1);
        }
        _ => {
            emit(&Collapse::new(&upper), 0, &mut out);
        }
    }
    out.items
}

/// The splice's item list; an upper leaf is one chunk, placed whole.
struct SpliceOut<'a> {
    /// Chunk index at each upper leaf position.
    chunk_order: Vec<usize>,
    subtrees: &'a [Subtree],
    items: Vec<SpliceItem>,
    next_node: u32,
    next_strip: u32,
}

impl WideOut for SpliceOut<'_> {
    fn open(&mut self) -> (u32, usize) {
        self.items.push(SpliceItem::Node(TopNode::EMPTY));
        self.next_node += 1;
        (self.next_node - 1, self.items.len() - 1)
    }

    fn complete(&mut self, handle: usize, node: TopNode) {
        self.items[handle] = SpliceItem::Node(node);
    }

    fn leaf(&mut self, first: u32, _count: u32) -> (u32, u32) {
        let index = self.chunk_order[first as usize];
        let root = self.next_node;
        self.items.push(SpliceItem::Subtree {
            index,
            node_base: root,
            strip_base: self.next_strip,
        });
        self.next_node += self.subtrees[index].node_count;
        self.next_strip += self.subtrees[index].strip_count;
        (root, INTERNAL_CHILD)
    }
}

/// A chunk node renumbered into the final file: node links and strip ranges shift by the bases.
pub fn relocate(node: &TopNode, node_base: u32, strip_base: u32) -> TopNode {
    let mut moved = *node;
    for slot in 0..TOP_WIDTH {
        moved.child[slot] += match node.slot(slot) {
            TopSlot::Internal(_) => node_base,
            TopSlot::Leaf { .. } => strip_base,
            TopSlot::Empty | TopSlot::Invalid(_) => 0,
        };
    }
    moved
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Boxes on a jittered grid, deterministic.
    fn boxes(count: usize) -> Vec<Aabb> {
        (0..count)
            .map(|i| {
                let x = (i % 17) as f32 + (i as f32 * 0.37).sin();
                let y = ((i / 17) % 13) as f32;
                let z = (i / 221) as f32 + (i as f32 * 0.11).cos();
                Aabb {
                    min: [x, y, z],
                    max: [x + 0.8, y + 0.5 + (i % 3) as f32, z + 0.3],
                }
            })
            .collect()
    }

    #[test]
    fn wide_tree_is_valid_and_keeps_the_binary_leaf_order() {
        for count in [0, 1, 2, 3, 5, 64, 1000] {
            let bounds = boxes(count);
            let params = TopLevelParams::default();
            let top = build(&bounds, &params);
            top.validate(&bounds).unwrap();
            assert_eq!(top.strip_order, build_binary(&bounds, &params).1);
        }
    }

    #[test]
    fn collapsing_fills_nodes() {
        let bounds = boxes(1000);
        let params = TopLevelParams::default();
        let binary_internal = build_binary(&bounds, &params)
            .0
            .iter()
            .filter(|n| matches!(n.kind, BinaryKind::Internal { .. }))
            .count();
        let top = build(&bounds, &params);
        // Every wide node absorbs at least one binary internal node, most three.
        assert!(top.nodes.len() * 2 < binary_internal, "{}", top.nodes.len());
    }

    #[test]
    fn empty_and_single_strip_roots() {
        assert_eq!(
            build(&[], &TopLevelParams::default()).nodes,
            [TopNode::EMPTY]
        );
        let one = build(&boxes(1), &TopLevelParams::default());
        assert_eq!(one.nodes.len(), 1);
        assert_eq!(one.nodes[0].slot(0), TopSlot::Leaf { first: 0, count: 1 });
        assert_eq!(one.nodes[0].occupied(), 1);
    }

    #[test]
    fn validate_rejects_broken_trees() {
        let bounds = boxes(200);
        let top = build(&bounds, &TopLevelParams::default());
        let mut loose = top.clone();
        loose.nodes[0].min[0][0] = 1e9;
        assert!(loose.validate(&bounds).is_err());
        let mut unpacked = top.clone();
        unpacked.nodes[1].kind[0] = 0;
        assert!(unpacked.validate(&bounds).is_err());
        let mut duplicated = top;
        duplicated.strip_order[1] = duplicated.strip_order[0];
        assert!(duplicated.validate(&bounds).is_err());
    }

    /// Splicing chunk hierarchies gives a tree whose every chunk root is an internal slot, and
    /// the spliced file nodes validate like one hierarchy.
    #[test]
    fn splice_places_chunks_under_wide_upper_nodes() {
        let all = boxes(900);
        let chunks: Vec<&[Aabb]> = all.chunks(100).collect();
        let built: Vec<TopLevel> = chunks
            .iter()
            .map(|c| build(c, &TopLevelParams::default()))
            .collect();
        let subtrees: Vec<Subtree> = built
            .iter()
            .zip(&chunks)
            .map(|(top, c)| Subtree {
                bounds: c.iter().fold(Aabb::EMPTY, |a, b| a.union(b)),
                node_count: top.nodes.len() as u32,
                strip_count: c.len() as u32,
            })
            .collect();
        let mut spliced = TopLevel::default();
        let mut spliced_bounds = Vec::new();
        for item in splice(&subtrees, &TopLevelParams::default()) {
            match item {
                SpliceItem::Node(node) => spliced.nodes.push(node),
                SpliceItem::Subtree {
                    index,
                    node_base,
                    strip_base,
                } => {
                    assert_eq!(node_base as usize, spliced.nodes.len());
                    assert_eq!(strip_base as usize, spliced.strip_order.len());
                    let chunk = &built[index];
                    spliced.nodes.extend(
                        chunk
                            .nodes
                            .iter()
                            .map(|n| relocate(n, node_base, strip_base)),
                    );
                    for &s in &chunk.strip_order {
                        spliced.strip_order.push(spliced_bounds.len() as u32);
                        spliced_bounds.push(chunks[index][s as usize]);
                    }
                }
            }
        }
        spliced.validate(&spliced_bounds).unwrap();
        // Nine chunks fit under three upper nodes at most.
        let upper = spliced.nodes.len() - built.iter().map(|t| t.nodes.len()).sum::<usize>();
        assert!((1..=4).contains(&upper), "{upper}");
    }

    #[test]
    fn splice_of_one_chunk_is_that_chunk() {
        let subtree = Subtree {
            bounds: boxes(1)[0],
            node_count: 3,
            strip_count: 7,
        };
        let empty = Subtree {
            strip_count: 0,
            ..subtree
        };
        assert_eq!(
            splice(&[empty, subtree], &TopLevelParams::default()),
            [SpliceItem::Subtree {
                index: 1,
                node_base: 0,
                strip_base: 0
            }]
        );
        assert_eq!(
            splice(&[empty], &TopLevelParams::default()),
            [SpliceItem::Node(TopNode::EMPTY)]
        );
    }
}

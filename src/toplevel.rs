//! The global hierarchy over strips (paper 3.2: "one global high-level hierarchy whose leaf nodes
//! contain the strip hierarchies").
//!
//! A binned-SAH bounding volume hierarchy over strip bounds. Nodes are emitted depth-first (left
//! child next to its parent) and the strips are renumbered in leaf order, so the strips of a
//! subtree are contiguous in the strip-data section and a subtree's nodes are contiguous in the
//! node section: a ray that stays in one region of the model pages in few pages of either.

use crate::format::TopNode;
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
    if order.is_empty() {
        builder
            .nodes
            .push(TopNode::leaf(Aabb::EMPTY.min, Aabb::EMPTY.max, 0, 0));
    } else {
        builder.subtree(&mut order, 0, 0);
    }
    TopLevel {
        nodes: builder.nodes,
        strip_order: order,
    }
}

struct Builder<'a> {
    bounds: &'a [Aabb],
    params: &'a TopLevelParams,
    centroids: Vec<[f32; 3]>,
    nodes: Vec<TopNode>,
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
        let Some(left_count) = split.as_ref().map(|s| self.partition(strips, s)) else {
            self.nodes.push(TopNode::leaf(
                bounds.min,
                bounds.max,
                first as u32,
                strips.len() as u32,
            ));
            return;
        };
        let axis = split.map_or(0, |s| s.axis);
        self.nodes
            .push(TopNode::internal(bounds.min, bounds.max, 0, axis));
        let (left, right) = strips.split_at_mut(left_count);
        self.subtree(left, first, depth + 1);
        let right_index = self.nodes.len() as u32;
        self.nodes[node_index].payload = right_index;
        self.subtree(right, first + left_count, depth + 1);
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

impl TopLevel {
    /// Checks the structure: preorder layout, every strip in exactly one leaf, every node's box
    /// containing its children's boxes and its strips' bounds.
    pub fn validate(&self, bounds: &[Aabb]) -> Result<(), String> {
        let mut seen = vec![false; bounds.len()];
        let mut visited = 0;
        self.validate_node(0, bounds, &mut seen, &mut visited)?;
        if visited != self.nodes.len() {
            return Err(format!("{} nodes, {visited} reachable", self.nodes.len()));
        }
        match seen.iter().position(|&s| !s) {
            Some(strip) => Err(format!("strip {strip} is in no leaf")),
            None => Ok(()),
        }
    }

    fn validate_node(
        &self,
        index: usize,
        bounds: &[Aabb],
        seen: &mut [bool],
        visited: &mut usize,
    ) -> Result<(), String> {
        let node = self
            .nodes
            .get(index)
            .ok_or(format!("node {index} out of range"))?;
        *visited += 1;
        let node_box = Aabb {
            min: node.min,
            max: node.max,
        };
        if !node.is_internal() {
            let range = node.payload as usize..(node.payload + node.strip_count()) as usize;
            for position in range {
                let strip = *self
                    .strip_order
                    .get(position)
                    .ok_or("leaf strip out of range")? as usize;
                if std::mem::replace(&mut seen[strip], true) {
                    return Err(format!("strip {strip} is in two leaves"));
                }
                if !node_box.contains_box(&bounds[strip]) {
                    return Err(format!("node {index} does not contain strip {strip}"));
                }
            }
            return Ok(());
        }
        let right = node.payload as usize;
        if right <= index + 1 {
            return Err(format!(
                "node {index}: right child {right} is not after the left child"
            ));
        }
        for child in [index + 1, right] {
            let c = self
                .nodes
                .get(child)
                .ok_or(format!("node {child} out of range"))?;
            if !node_box.contains_box(&Aabb {
                min: c.min,
                max: c.max,
            }) {
                return Err(format!("node {index} does not contain child {child}"));
            }
            self.validate_node(child, bounds, seen, visited)?;
        }
        Ok(())
    }
}

/// One chunk's finished hierarchy, as the splice sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Subtree {
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
/// hierarchy is built like the per-chunk ones with one chunk per leaf. Chunks without strips are
/// left out.
pub fn splice(subtrees: &[Subtree], params: &TopLevelParams) -> Vec<SpliceItem> {
    let used: Vec<usize> = (0..subtrees.len())
        .filter(|&i| subtrees[i].strip_count > 0)
        .collect();
    if used.is_empty() {
        return vec![SpliceItem::Node(TopNode::leaf(
            Aabb::EMPTY.min,
            Aabb::EMPTY.max,
            0,
            0,
        ))];
    }
    let bounds: Vec<Aabb> = used.iter().map(|&i| subtrees[i].bounds).collect();
    let upper_params = TopLevelParams {
        max_leaf_strips: 1,
        ..params.clone()
    };
    let upper = build(&bounds, &upper_params);
    let mut walk = SpliceWalk {
        upper: &upper,
        used: &used,
        subtrees,
        items: Vec::new(),
        next_node: 0,
        next_strip: 0,
    };
    walk.visit(0);
    walk.items
}

struct SpliceWalk<'a> {
    upper: &'a TopLevel,
    used: &'a [usize],
    subtrees: &'a [Subtree],
    items: Vec<SpliceItem>,
    next_node: u32,
    next_strip: u32,
}

impl SpliceWalk<'_> {
    fn visit(&mut self, node: usize) {
        let upper_node = self.upper.nodes[node];
        if !upper_node.is_internal() {
            let index = self.used[self.upper.strip_order[upper_node.payload as usize] as usize];
            self.items.push(SpliceItem::Subtree {
                index,
                node_base: self.next_node,
                strip_base: self.next_strip,
            });
            self.next_node += self.subtrees[index].node_count;
            self.next_strip += self.subtrees[index].strip_count;
            return;
        }
        let position = self.items.len();
        self.items.push(SpliceItem::Node(upper_node));
        self.next_node += 1;
        self.visit(node + 1);
        let right = self.next_node;
        if let SpliceItem::Node(spliced) = &mut self.items[position] {
            spliced.payload = right;
        }
        self.visit(upper_node.payload as usize);
    }
}

/// A chunk node renumbered into the final file: links and strip ranges shift by the bases.
pub fn relocate(node: &TopNode, node_base: u32, strip_base: u32) -> TopNode {
    let mut moved = *node;
    moved.payload += if node.is_internal() {
        node_base
    } else {
        strip_base
    };
    moved
}

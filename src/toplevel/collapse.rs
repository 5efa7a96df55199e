//! Step two: which binary nodes each 4-wide node opens, chosen bottom-up by dynamic programming
//! for the least total surface area (see the module [`super`]).

use super::sah::{BinaryKind, BinaryNode};
use crate::format::TOP_WIDTH;

/// The slots of a wide node: binary node indices, in leaf order.
#[derive(Clone, Copy, Debug)]
pub(super) struct Frontier {
    nodes: [usize; TOP_WIDTH],
    len: usize,
}

impl Frontier {
    pub(super) fn slots(&self) -> &[usize] {
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

/// The slots of a wide node with the least total surface area found for them.
#[derive(Clone, Copy, Debug)]
pub(super) struct CostedFrontier {
    pub(super) cost: f64,
    pub(super) frontier: Frontier,
}

/// How the binary tree is cut into wide nodes: for each binary internal node, the least total
/// surface area of the wide nodes under it when it roots one (the SAH's expected number of node
/// visits, up to a constant), computed bottom-up.
pub(super) struct Collapse<'a> {
    pub(super) tree: &'a [BinaryNode],
    cost: Vec<f64>,
}

impl Collapse<'_> {
    pub(super) fn new(tree: &[BinaryNode]) -> Collapse<'_> {
        let mut collapse = Collapse {
            tree,
            cost: vec![0.0; tree.len()],
        };
        // Preorder puts children after their parent: reverse order is bottom-up.
        for index in (0..tree.len()).rev() {
            if let BinaryKind::Internal { .. } = tree[index].kind {
                collapse.cost[index] =
                    tree[index].bounds.surface_area() + collapse.frontier(index).cost;
            }
        }
        collapse
    }

    /// The slots of the wide node rooted at binary node `index` with their cost: its two
    /// children, with internal ones opened (up to [`TOP_WIDTH`] slots) wherever that lowers the
    /// total. A binary leaf (only ever the root) stands alone.
    pub(super) fn frontier(&self, index: usize) -> CostedFrontier {
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
        let mut best = CostedFrontier {
            cost: f64::INFINITY,
            frontier: start,
        };
        self.cheapest(start, &mut best);
        best
    }

    /// Tries `frontier` and every way of opening more of its internal slots.
    fn cheapest(&self, frontier: Frontier, best: &mut CostedFrontier) {
        let cost: f64 = frontier.slots().iter().map(|&c| self.cost[c]).sum();
        // Strictly lower only: of equal totals the one found first, with fewer slots opened.
        if cost < best.cost {
            *best = CostedFrontier { cost, frontier };
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

//! Step two: which binary nodes each 8-wide node takes as its slots, and which subtrees become
//! leaves, chosen bottom-up by Ylitie et al. 2017's dynamic programme for the least SAH cost
//! (see the module [`super`]).

use super::sah::{BinaryKind, BinaryNode};
use super::TopLevelParams;
use crate::format::WIDE_WIDTH;

/// The least cost of covering one binary node's subtree with at most `i + 1` slots, for each
/// `i`, and how it is reached.
#[derive(Clone, Copy, Debug)]
struct Table {
    cost: [f64; WIDE_WIDTH],
    /// Slots given to the left child at `i + 1` slots; 0 when `i` slots cost no more (and at
    /// one slot, where the node is the slot itself).
    left_slots: [u8; WIDE_WIDTH],
    /// Whether the node as one slot is a leaf over its strips rather than a wide node.
    leaf: bool,
}

/// One slot of a wide node as the collapse chose it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Slot {
    /// The strips `first .. first + count` of binary node `node`'s subtree, tested one by one.
    Leaf { node: usize, first: u32, count: u32 },
    /// A wide node rooted at binary node `node`.
    Wide(usize),
}

/// How the binary tree is cut into wide nodes and leaves. By the SAH, up to a constant, a wide
/// node rooted at a binary node costs its surface area times the cost of a node visit
/// ([`TopLevelParams::traversal_cost`]) plus the cost of its slots, and a leaf costs its surface
/// area times its strip count (a strip test is the unit); a subtree of at most
/// [`TopLevelParams::max_leaf_strips`] strips may be a leaf.
pub(super) struct Collapse<'a> {
    pub(super) tree: &'a [BinaryNode],
    tables: Vec<Table>,
    /// First strip and strip count of each binary node's subtree.
    strips: Vec<(u32, u32)>,
}

impl Collapse<'_> {
    /// The tables of every binary node: O(nodes × [`WIDE_WIDTH`]²).
    pub(super) fn new<'a>(tree: &'a [BinaryNode], params: &TopLevelParams) -> Collapse<'a> {
        let empty = Table {
            cost: [0.0; WIDE_WIDTH],
            left_slots: [0; WIDE_WIDTH],
            leaf: true,
        };
        let mut collapse = Collapse {
            tree,
            tables: vec![empty; tree.len()],
            strips: vec![(0, 0); tree.len()],
        };
        // Preorder puts children after their parent: reverse order is bottom-up.
        for index in (0..tree.len()).rev() {
            let area = tree[index].bounds.surface_area();
            match tree[index].kind {
                BinaryKind::Leaf { first, count } => {
                    collapse.strips[index] = (first, count);
                    collapse.tables[index].cost = [area * count as f64; WIDE_WIDTH];
                }
                BinaryKind::Internal { left, right } => {
                    let (first, left_count) = collapse.strips[left];
                    let count = left_count + collapse.strips[right].1;
                    collapse.strips[index] = (first, count);
                    let leaf_cost = if count as usize <= params.max_leaf_strips {
                        area * count as f64
                    } else {
                        f64::INFINITY
                    };
                    let node_cost = area * params.traversal_cost;
                    collapse.tables[index] = collapse.table(left, right, leaf_cost, node_cost);
                }
            }
        }
        collapse
    }

    fn table(&self, left: usize, right: usize, leaf_cost: f64, node_cost: f64) -> Table {
        let (left, right) = (&self.tables[left], &self.tables[right]);
        let (children, _) = spread(left, right, WIDE_WIDTH);
        let wide_cost = node_cost + children;
        // Strictly lower only: of equal costs, the wide node, whose boxes cull more.
        let leaf = leaf_cost < wide_cost;
        let mut table = Table {
            cost: [leaf_cost.min(wide_cost); WIDE_WIDTH],
            left_slots: [0; WIDE_WIDTH],
            leaf,
        };
        for slots in 2..=WIDE_WIDTH {
            let (cost, left_slots) = spread(left, right, slots);
            // Strictly lower only: of equal costs, the one with fewer slots opened.
            if cost < table.cost[slots - 2] {
                table.cost[slots - 1] = cost;
                table.left_slots[slots - 1] = left_slots as u8;
            } else {
                table.cost[slots - 1] = table.cost[slots - 2];
            }
        }
        table
    }

    /// The least total cost of the subtree of binary node `index` as one slot.
    #[cfg(test)]
    pub(super) fn cost(&self, index: usize) -> f64 {
        self.tables[index].cost[0]
    }

    /// The slots of the wide node rooted at binary node `index`, in leaf order: its children
    /// spread over at most [`WIDE_WIDTH`] slots. A binary leaf (only ever the root) stands
    /// alone.
    pub(super) fn slots(&self, index: usize) -> Vec<Slot> {
        let mut slots = Vec::with_capacity(WIDE_WIDTH);
        match self.tree[index].kind {
            BinaryKind::Internal { left, right } => {
                let (_, left_slots) = spread(&self.tables[left], &self.tables[right], WIDE_WIDTH);
                self.cover(left, left_slots, &mut slots);
                self.cover(right, WIDE_WIDTH - left_slots, &mut slots);
            }
            BinaryKind::Leaf { .. } => slots.push(self.slot(index)),
        }
        slots
    }

    /// Appends the slots covering binary node `index`'s subtree at its least cost with at most
    /// `count` slots.
    fn cover(&self, index: usize, count: usize, slots: &mut Vec<Slot>) {
        let mut count = count;
        let table = &self.tables[index];
        while count > 1 && table.left_slots[count - 1] == 0 {
            count -= 1;
        }
        match self.tree[index].kind {
            BinaryKind::Internal { left, right } if count > 1 => {
                let left_slots = table.left_slots[count - 1] as usize;
                self.cover(left, left_slots, slots);
                self.cover(right, count - left_slots, slots);
            }
            _ => slots.push(self.slot(index)),
        }
    }

    /// Binary node `index` as one slot.
    fn slot(&self, index: usize) -> Slot {
        let (first, count) = self.strips[index];
        if self.tables[index].leaf {
            Slot::Leaf {
                node: index,
                first,
                count,
            }
        } else {
            Slot::Wide(index)
        }
    }
}

/// The least cost of covering two siblings with `slots` slots between them, and the left one's
/// share (the first of equal costs).
fn spread(left: &Table, right: &Table, slots: usize) -> (f64, usize) {
    (1..slots)
        .map(|share| (left.cost[share - 1] + right.cost[slots - share - 1], share))
        .fold((f64::INFINITY, 0), |best, candidate| {
            if candidate.0 < best.0 {
                candidate
            } else {
                best
            }
        })
}

//! Step two: which binary nodes each 8-wide node takes as its slots, chosen bottom-up by
//! Ylitie et al. 2017's dynamic programme for the least total surface area (see the module
//! [`super`]).

use super::sah::{BinaryKind, BinaryNode};
use crate::format::WIDE_WIDTH;

/// The least cost of covering one binary node's subtree with at most `i + 1` slots, for each
/// `i`, and how it is reached.
#[derive(Clone, Copy, Debug)]
struct Table {
    cost: [f64; WIDE_WIDTH],
    /// Slots given to the left child at `i + 1` slots; 0 when `i` slots cost no more (and at
    /// one slot, where the node is the slot itself).
    left_slots: [u8; WIDE_WIDTH],
}

/// How the binary tree is cut into wide nodes. A binary internal node rooting a wide node costs
/// its surface area (the SAH's probability of visiting the wide node, up to a constant) plus
/// the cost of spreading its two children over at most [`WIDE_WIDTH`] slots; a binary leaf
/// costs nothing, since every cut keeps the same leaves.
pub(super) struct Collapse<'a> {
    pub(super) tree: &'a [BinaryNode],
    tables: Vec<Table>,
}

impl Collapse<'_> {
    /// The tables of every binary node: O(nodes × [`WIDE_WIDTH`]²).
    pub(super) fn new(tree: &[BinaryNode]) -> Collapse<'_> {
        let empty = Table {
            cost: [0.0; WIDE_WIDTH],
            left_slots: [0; WIDE_WIDTH],
        };
        let mut collapse = Collapse {
            tree,
            tables: vec![empty; tree.len()],
        };
        // Preorder puts children after their parent: reverse order is bottom-up.
        for index in (0..tree.len()).rev() {
            if let BinaryKind::Internal { left, right } = tree[index].kind {
                collapse.tables[index] = collapse.table(index, left, right);
            }
        }
        collapse
    }

    fn table(&self, index: usize, left: usize, right: usize) -> Table {
        let (left, right) = (&self.tables[left], &self.tables[right]);
        let (children, _) = spread(left, right, WIDE_WIDTH);
        let mut table = Table {
            cost: [self.tree[index].bounds.surface_area() + children; WIDE_WIDTH],
            left_slots: [0; WIDE_WIDTH],
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

    /// The least total cost of the wide nodes under the one rooted at binary node `index`.
    #[cfg(test)]
    pub(super) fn cost(&self, index: usize) -> f64 {
        self.tables[index].cost[0]
    }

    /// The slots of the wide node rooted at binary node `index`, as binary node indices in
    /// leaf order: its children spread over at most [`WIDE_WIDTH`] slots. A binary leaf (only
    /// ever the root) stands alone.
    pub(super) fn slots(&self, index: usize) -> Vec<usize> {
        let mut slots = Vec::with_capacity(WIDE_WIDTH);
        match self.tree[index].kind {
            BinaryKind::Internal { left, right } => {
                let (_, left_slots) = spread(&self.tables[left], &self.tables[right], WIDE_WIDTH);
                self.cover(left, left_slots, &mut slots);
                self.cover(right, WIDE_WIDTH - left_slots, &mut slots);
            }
            BinaryKind::Leaf { .. } => slots.push(index),
        }
        slots
    }

    /// Appends the slots covering binary node `index`'s subtree at its least cost with at most
    /// `count` slots.
    fn cover(&self, index: usize, count: usize, slots: &mut Vec<usize>) {
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
            _ => slots.push(index),
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

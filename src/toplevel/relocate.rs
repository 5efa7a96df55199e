//! Renumbering a chunk's nodes into the spliced file.

use crate::format::{TopNode, TopSlot, TOP_WIDTH};

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

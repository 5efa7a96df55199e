//! Writes collapsed wide nodes in depth-first preorder, into one hierarchy's node array or the
//! splice's item list.

use super::collapse::Collapse;
use super::sah::BinaryKind;
use crate::format::{TopNode, INTERNAL_CHILD};

/// Where collapsed wide nodes go: the node array of one hierarchy, or the splice's item list.
pub(super) trait WideOut {
    /// Reserves the next node; returns its file index and a handle for [`WideOut::complete`].
    fn open(&mut self) -> (u32, usize);
    fn complete(&mut self, handle: usize, node: TopNode);
    /// The `(child, kind)` a binary leaf's slot holds, emitting what the slot points at.
    fn leaf(&mut self, first: u32, count: u32) -> (u32, u32);
}

/// Emits the wide node standing for binary node `index`, then its subtree, in preorder;
/// returns its file index.
pub(super) fn emit(collapse: &Collapse, index: usize, out: &mut impl WideOut) -> u32 {
    let tree = collapse.tree;
    let (file_index, handle) = out.open();
    let mut node = TopNode::EMPTY;
    for (slot, &child) in collapse.frontier(index).frontier.slots().iter().enumerate() {
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
pub(super) struct NodeArray(pub(super) Vec<TopNode>);

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

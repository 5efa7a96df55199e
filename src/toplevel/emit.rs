//! Writes collapsed wide nodes in depth-first preorder, into one hierarchy's node array or the
//! splice's item list.

use super::collapse::{Collapse, Slot};
use super::NodeError;
use crate::format::{TopSlot, WideChild, WideNode};
use crate::geometry::Aabb;

/// Where collapsed wide nodes go: the node array of one hierarchy, or the splice's item list.
pub(super) trait WideOut {
    /// Reserves the next node; returns its file index and a handle for [`WideOut::complete`].
    fn open(&mut self) -> (u32, usize);
    fn complete(&mut self, handle: usize, node: WideNode);
    /// What a binary leaf's slot holds and the box it needs, emitting what the slot points at.
    fn leaf(&mut self, first: u32, count: u32, bounds: &Aabb) -> (TopSlot, Aabb);
}

/// Emits the wide node standing for binary node `index`, then its subtree, in preorder;
/// returns its file index and its decoded box (the union of its slots' decoded boxes).
///
/// A slot pointing at an internal child gets that child's decoded box, not its binary bounds:
/// both are rounded outward, so only this way does a parent's decoded box hold its children's.
pub(super) fn emit(
    collapse: &Collapse,
    index: usize,
    out: &mut impl WideOut,
) -> Result<(u32, Aabb), NodeError> {
    let tree = collapse.tree;
    let (file_index, handle) = out.open();
    let mut children = Vec::new();
    for child in collapse.slots(index) {
        let (slot, bounds) = match child {
            Slot::Leaf { node, first, count } => out.leaf(first, count, &tree[node].bounds),
            Slot::Wide(node) => {
                let (node, bounds) = emit(collapse, node, out)?;
                (TopSlot::Internal(node), bounds)
            }
        };
        children.push(WideChild {
            min: bounds.min,
            max: bounds.max,
            slot,
        });
    }
    let node = WideNode::encode(&children).map_err(|detail| NodeError {
        index: file_index,
        detail,
    })?;
    out.complete(handle, node);
    Ok((file_index, decoded_bounds(&node)))
}

/// The union of the decoded boxes of `node`'s occupied slots.
pub fn decoded_bounds(node: &WideNode) -> Aabb {
    (0..super::occupied(node))
        .map(|slot| {
            let (min, max) = node.slot_box(slot);
            Aabb { min, max }
        })
        .fold(Aabb::EMPTY, |a, b| a.union(&b))
}

/// The nodes of one hierarchy; leaves hold their strip ranges.
pub(super) struct NodeArray(pub(super) Vec<WideNode>);

impl WideOut for NodeArray {
    fn open(&mut self) -> (u32, usize) {
        self.0.push(WideNode::EMPTY);
        ((self.0.len() - 1) as u32, self.0.len() - 1)
    }

    fn complete(&mut self, handle: usize, node: WideNode) {
        self.0[handle] = node;
    }

    fn leaf(&mut self, first: u32, count: u32, bounds: &Aabb) -> (TopSlot, Aabb) {
        (TopSlot::Leaf { first, count }, *bounds)
    }
}

//! Renumbering a chunk's nodes into the spliced file.

use crate::format::{TopSlot, WideNode, GRID_LINK_INDEX, WIDE_WIDTH};

/// A chunk node renumbered into the final file: node links and strip ranges shift by the bases.
/// A shifted index beyond a link's 28 bits is an error naming the slot, never a wrap.
pub fn relocate(node: &WideNode, node_base: u32, strip_base: u32) -> Result<WideNode, String> {
    let mut moved = *node;
    for slot in 0..WIDE_WIDTH {
        let base = match node.slot(slot) {
            TopSlot::Internal(_) => node_base,
            TopSlot::Leaf { .. } => strip_base,
            TopSlot::Empty | TopSlot::Invalid(_) => continue,
        };
        let index = node.link[slot] & GRID_LINK_INDEX;
        let shifted = index
            .checked_add(base)
            .filter(|&shifted| shifted <= GRID_LINK_INDEX)
            .ok_or_else(|| {
                format!("slot {slot}: index {index} + {base} needs more than 28 bits")
            })?;
        moved.link[slot] = node.link[slot] - index + shifted;
    }
    Ok(moved)
}

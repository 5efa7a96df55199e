//! Renumbering a chunk's nodes into the spliced file.

use crate::format::{pack_link, TopSlot, WideNode, WIDE_WIDTH};

/// A chunk node renumbered into the final file: node links and strip ranges shift by the bases.
/// A shifted index beyond a link's 28 bits is an error naming the slot, never a wrap.
pub fn relocate(node: &WideNode, node_base: u32, strip_base: u32) -> Result<WideNode, String> {
    let mut moved = *node;
    for slot in 0..WIDE_WIDTH {
        let shifted = match node.slot(slot) {
            TopSlot::Internal(child) => TopSlot::Internal(shift(slot, child, node_base)?),
            TopSlot::Leaf { first, count } => TopSlot::Leaf {
                first: shift(slot, first, strip_base)?,
                count,
            },
            TopSlot::Empty | TopSlot::Invalid(_) => continue,
        };
        moved.link[slot] = pack_link(slot, shifted)?;
    }
    Ok(moved)
}

fn shift(slot: usize, index: u32, base: u32) -> Result<u32, String> {
    index
        .checked_add(base)
        .ok_or_else(|| format!("slot {slot}: index {index} + {base} overflows"))
}

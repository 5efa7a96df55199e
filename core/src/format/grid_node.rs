//! The 4-wide top-level node of grid files, on the node grid.

use bytemuck::{Pod, Zeroable};

use super::{grid, TopNode, TopSlot, TOP_WIDTH};

/// Bits of a [`GridNode`] link below its tag: the node index or first strip.
pub const GRID_LINK_INDEX_BITS: u32 = 28;
/// Mask of a [`GridNode`] link's index.
pub const GRID_LINK_INDEX: u32 = (1 << GRID_LINK_INDEX_BITS) - 1;
/// [`GridNode`] link tag of an internal child; tags 1 to 14 are leaf strip counts.
pub const GRID_LINK_INTERNAL: u32 = 15;
/// Most strips in one leaf of a [`GridNode`] (the builder's leaves hold at most
/// `TopLevelParams::max_leaf_strips`, 4 by default).
pub const MAX_GRID_LEAF_STRIPS: u32 = GRID_LINK_INTERNAL - 1;

/// A top-level node of a grid file (`vertex_encoding` 2, format 2.2): [`TopNode`]'s boxes on
/// the node grid ([`grid::NodeGrid`]) as u16 and its `child`/`kind` pairs packed in one word.
/// 64 bytes, half a [`TopNode`], in the same tree order.
///
/// | bytes | field |
/// |---|---|
/// | 0..24 | `min[axis][slot]`: u16 × 4 per axis (x at 0, y at 8, z at 16), one lane per child |
/// | 24..48 | `max[axis][slot]`, same layout |
/// | 48..64 | `link[slot]`: bits 28..32 tag, bits 0..28 index: tag 0 → empty slot (the whole word 0); tags 1..=14 → a leaf of that many strips from strip `index`; tag 15 → internal child, node `index` |
///
/// Child `i` covers `node_grid.decode(min[·][i]) ..= node_grid.decode(max[·][i])`, rounded
/// outward from the f32 box when written. An empty slot is all zero bytes (box included):
/// traversal skips it by its link, since no u16 box is missed by every ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct GridNode {
    pub min: [[u16; TOP_WIDTH]; 3],
    pub max: [[u16; TOP_WIDTH]; 3],
    pub link: [u32; TOP_WIDTH],
}
const _: () = assert!(std::mem::size_of::<GridNode>() == 64);

impl GridNode {
    /// `node` with its boxes rounded outward to `grid` and its links packed; an error when a
    /// box lies outside the node grid or a link does not fit.
    pub fn encode(node: &TopNode, grid: &grid::NodeGrid) -> Result<GridNode, String> {
        let mut out = GridNode::zeroed();
        for slot in 0..node.occupied() {
            let (min, max) = node.slot_box(slot);
            for axis in 0..3 {
                let outside = || format!("box {min:?}..{max:?} outside the node grid {grid:?}");
                let low = grid.floor(min[axis], axis).ok_or_else(outside)?;
                let high = grid.ceil(max[axis], axis).ok_or_else(outside)?;
                // Where the cell is below the coordinates' ulp (a small model far from the
                // origin), several points decode to one value, and a flat box's floor may
                // pass its ceiling; both then decode to that value, so the ceiling serves.
                out.min[axis][slot] = low.min(high);
                out.max[axis][slot] = high;
            }
            out.link[slot] = pack_link(slot, node.slot(slot))?;
        }
        Ok(out)
    }
}

/// What a one-word link ([`GridNode`]'s and [`WideNode`](super::WideNode)'s) holds.
pub fn unpack_link(link: u32) -> TopSlot {
    let index = link & GRID_LINK_INDEX;
    match link >> GRID_LINK_INDEX_BITS {
        0 if link == 0 => TopSlot::Empty,
        0 => TopSlot::Invalid(link),
        GRID_LINK_INTERNAL => TopSlot::Internal(index),
        count => TopSlot::Leaf {
            first: index,
            count,
        },
    }
}

/// `link`, the content of `slot`, as a one-word link; an error naming the slot when it is no
/// child or leaf, holds more strips than a tag counts or an index beyond 28 bits.
pub fn pack_link(slot: usize, link: TopSlot) -> Result<u32, String> {
    let (tag, index) = match link {
        TopSlot::Internal(child) => (GRID_LINK_INTERNAL, child),
        TopSlot::Leaf { first, count } if (1..=MAX_GRID_LEAF_STRIPS).contains(&count) => {
            (count, first)
        }
        other => return Err(format!("slot {slot} holds {other:?}: no one-word link")),
    };
    if index > GRID_LINK_INDEX {
        return Err(format!(
            "slot {slot}: index {index} needs more than 28 bits"
        ));
    }
    Ok(tag << GRID_LINK_INDEX_BITS | index)
}

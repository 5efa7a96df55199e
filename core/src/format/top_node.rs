//! The 4-wide f32 top-level node.

use bytemuck::{Pod, Zeroable};

/// Child slots of a [`TopNode`].
pub const TOP_WIDTH: usize = 4;

/// `TopNode::kind` of an internal child; smaller non-zero values are leaf strip counts.
pub const INTERNAL_CHILD: u32 = 1 << 31;

/// A node of the global hierarchy over strips: the boxes and links of up to [`TOP_WIDTH`]
/// children. 128 bytes, depth-first preorder, root at index 0. A node has no box of its own:
/// its parent's slot holds it, and the root's is the whole model (traversal tests the root's
/// children directly).
///
/// | bytes | field |
/// |---|---|
/// | 0..48 | `min[axis][slot]`: f32 × 4 per axis (x at 0, y at 16, z at 32), one lane per child |
/// | 48..96 | `max[axis][slot]`, same layout |
/// | 96..112 | `child[slot]`: internal child → its node index, greater than this node's; leaf → its first strip |
/// | 112..128 | `kind[slot]`: 0 → empty slot; [`INTERNAL_CHILD`] → internal child; otherwise a leaf of that many strips (1..2^31) |
///
/// The boxes are stored axis by axis (structure of arrays) so that one 16-byte load gives one
/// plane of all four children and a ray tests them together. Occupied slots come first; an
/// empty slot is exactly `min = +inf`, `max = -inf` on every axis, `child = 0`, `kind = 0`, a
/// box every ray misses (its entry distance is `+inf` and its exit `-inf` whatever the
/// direction's sign), and as a leaf of zero strips it would hold nothing even if entered.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct TopNode {
    pub min: [[f32; TOP_WIDTH]; 3],
    pub max: [[f32; TOP_WIDTH]; 3],
    pub child: [u32; TOP_WIDTH],
    pub kind: [u32; TOP_WIDTH],
}
const _: () = assert!(std::mem::size_of::<TopNode>() == 128);

/// What one slot of a [`TopNode`] holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TopSlot {
    Empty,
    /// The child node's index.
    Internal(u32),
    /// Strips `first .. first + count` in file order.
    Leaf {
        first: u32,
        count: u32,
    },
    /// A kind above [`INTERNAL_CHILD`]: never written, rejected by the reader.
    Invalid(u32),
}

impl TopNode {
    /// A node with every slot empty: the root of a model without strips.
    pub const EMPTY: TopNode = TopNode {
        min: [[f32::INFINITY; TOP_WIDTH]; 3],
        max: [[f32::NEG_INFINITY; TOP_WIDTH]; 3],
        child: [0; TOP_WIDTH],
        kind: [0; TOP_WIDTH],
    };

    /// Fills `slot` with a child box and its link (`kind` as stored: [`INTERNAL_CHILD`] or a
    /// strip count).
    pub fn set(&mut self, slot: usize, min: &[f32; 3], max: &[f32; 3], child: u32, kind: u32) {
        for axis in 0..3 {
            self.min[axis][slot] = min[axis];
            self.max[axis][slot] = max[axis];
        }
        self.child[slot] = child;
        self.kind[slot] = kind;
    }

    pub fn slot(&self, slot: usize) -> TopSlot {
        match self.kind[slot] {
            0 => TopSlot::Empty,
            INTERNAL_CHILD => TopSlot::Internal(self.child[slot]),
            count if count < INTERNAL_CHILD => TopSlot::Leaf {
                first: self.child[slot],
                count,
            },
            kind => TopSlot::Invalid(kind),
        }
    }

    /// The box of `slot` as (min, max).
    pub fn slot_box(&self, slot: usize) -> ([f32; 3], [f32; 3]) {
        (
            [0, 1, 2].map(|axis| self.min[axis][slot]),
            [0, 1, 2].map(|axis| self.max[axis][slot]),
        )
    }

    /// Occupied slots: those before the first empty one.
    pub fn occupied(&self) -> usize {
        self.kind.iter().take_while(|&&kind| kind != 0).count()
    }

    /// Whether `slot` is bit for bit the empty slot of [`TopNode::EMPTY`].
    pub fn is_exactly_empty(&self, slot: usize) -> bool {
        let empty = &TopNode::EMPTY;
        (0..3).all(|axis| {
            self.min[axis][slot].to_bits() == empty.min[axis][slot].to_bits()
                && self.max[axis][slot].to_bits() == empty.max[axis][slot].to_bits()
        }) && self.child[slot] == 0
            && self.kind[slot] == 0
    }
}

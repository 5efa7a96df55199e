//! The 8-wide compressed top-level node of format 4: child boxes as 8-bit planes in the node's
//! own frame, after Ylitie, Karras and Laine 2017 ("Efficient incoherent ray traversal on GPUs
//! through compressed wide BVHs"), with [`GridNode`](super::GridNode)'s one-word links instead
//! of their per-node bases, so that nodes keep the depth-first preorder of format 3.

use bytemuck::{Pod, Zeroable};

use super::{pack_link, unpack_link, TopSlot, MAX_GRID_LEAF_STRIPS};

/// Child slots of a [`WideNode`].
pub const WIDE_WIDTH: usize = 8;

/// Most strips in one leaf of a [`WideNode`]: the link tags below the internal one.
pub const MAX_WIDE_LEAF_STRIPS: u32 = MAX_GRID_LEAF_STRIPS;

/// Largest plane code.
const TOP_CODE: u8 = u8::MAX;

/// A node of the global hierarchy over strips in format 4: up to [`WIDE_WIDTH`] children,
/// each a box of 8-bit planes in the node's frame and a link. 96 bytes, depth-first preorder,
/// root at index 0; a node has no box of its own (the root's is the whole model).
///
/// | bytes | field |
/// |---|---|
/// | 0..12 | `origin`: f32 × 3, the frame's corner |
/// | 12..15 | `exponent`: u8 × 3, each in 1..=254: the axis's scale is the f32 `2^(e - 127)` (bits `e << 23`) |
/// | 15 | reserved, 0 |
/// | 16..40 | `min[axis][slot]`: u8 × 8 per axis (x at 16, y at 24, z at 32), one lane per child |
/// | 40..64 | `max[axis][slot]`, same layout |
/// | 64..96 | `link[slot]`: u32, bits 28..32 tag, bits 0..28 index, as [`GridNode`](super::GridNode)'s: tag 0 → empty slot (the word 0); tags 1..=14 → a leaf of that many strips from strip `index`; tag 15 → internal child, node `index` |
///
/// Code `q` on axis `a` decodes to the f32 expression `origin[a] + (q as f32) * scale[a]`: an
/// exact product (`q` has 8 bits, the scale is a power of two), then one rounded sum, no fused
/// multiply-add; so decoding is monotone in `q` and the same bits everywhere. Child `i`'s box
/// is its decoded minima to its decoded maxima, rounded outward from the f32 box when written
/// ([`WideNode::encode`] checks each code with that expression): it holds the child's strips.
/// Occupied slots come first; an empty slot is all zero bytes (planes included) and traversal
/// skips it by its link, since no 8-bit box is missed by every ray.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct WideNode {
    pub origin: [f32; 3],
    pub exponent: [u8; 3],
    pub reserved: u8,
    pub min: [[u8; WIDE_WIDTH]; 3],
    pub max: [[u8; WIDE_WIDTH]; 3],
    pub link: [u32; WIDE_WIDTH],
}
const _: () = assert!(std::mem::size_of::<WideNode>() == 96);

/// One occupied child as the builder has it: its f32 box and what it links to
/// ([`TopSlot::Internal`] or [`TopSlot::Leaf`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideChild {
    pub min: [f32; 3],
    pub max: [f32; 3],
    pub slot: TopSlot,
}

impl WideNode {
    /// A node with every slot empty: the root of a model without strips (scale 1 on each axis).
    pub const EMPTY: WideNode = WideNode {
        origin: [0.0; 3],
        exponent: [127; 3],
        reserved: 0,
        min: [[0; WIDE_WIDTH]; 3],
        max: [[0; WIDE_WIDTH]; 3],
        link: [0; WIDE_WIDTH],
    };

    /// The node of `children` (at most [`WIDE_WIDTH`], in slot order): the frame over their
    /// union with the finest scale whose top code reaches its maximum, each box rounded outward
    /// to codes, each link packed. An error names what no node can hold: too many children, a
    /// box that is not finite, a leaf of no or too many strips, an index beyond 28 bits.
    pub fn encode(children: &[WideChild]) -> Result<WideNode, String> {
        if children.len() > WIDE_WIDTH {
            return Err(format!("{} children, at most {WIDE_WIDTH}", children.len()));
        }
        let mut node = WideNode::EMPTY;
        if children.is_empty() {
            return Ok(node);
        }
        for (slot, child) in children.iter().enumerate() {
            let finite = child.min.iter().chain(&child.max).all(|c| c.is_finite());
            if !finite || (0..3).any(|axis| child.min[axis] > child.max[axis]) {
                return Err(format!("slot {slot}: box {:?}..{:?}", child.min, child.max));
            }
            node.link[slot] = pack_link(slot, child.slot)?;
        }
        for axis in 0..3 {
            let low = children
                .iter()
                .map(|c| c.min[axis])
                .fold(f32::MAX, f32::min);
            let high = children
                .iter()
                .map(|c| c.max[axis])
                .fold(f32::MIN, f32::max);
            let frame = AxisFrame::covering(low, high)
                .ok_or_else(|| format!("axis {axis}: no frame covers {low}..{high}"))?;
            node.origin[axis] = frame.origin;
            node.exponent[axis] = frame.exponent;
            for (slot, child) in children.iter().enumerate() {
                let below = frame.floor(child.min[axis]);
                let above = frame.ceil(child.max[axis]);
                // Where the scale is below the ulp of the coordinates several codes decode to
                // one value, and a flat box's floor may pass its ceiling; both then decode to
                // that value, so the ceiling serves for both.
                node.min[axis][slot] = below.min(above);
                node.max[axis][slot] = above;
            }
        }
        Ok(node)
    }

    /// What `slot` holds.
    pub fn slot(&self, slot: usize) -> TopSlot {
        unpack_link(self.link[slot])
    }

    /// The scale of `axis`: `2^(exponent - 127)`.
    #[inline(always)]
    pub fn scale(&self, axis: usize) -> f32 {
        f32::from_bits((self.exponent[axis] as u32) << 23)
    }

    /// Code `q` of `axis` decoded: the format's expression.
    #[inline(always)]
    pub fn decode(&self, axis: usize, q: u8) -> f32 {
        self.origin[axis] + f32::from(q) * self.scale(axis)
    }

    /// The decoded box of `slot` as (min, max).
    pub fn slot_box(&self, slot: usize) -> ([f32; 3], [f32; 3]) {
        (
            [0, 1, 2].map(|axis| self.decode(axis, self.min[axis][slot])),
            [0, 1, 2].map(|axis| self.decode(axis, self.max[axis][slot])),
        )
    }
}

/// One axis of a node's frame while encoding.
struct AxisFrame {
    origin: f32,
    exponent: u8,
}

impl AxisFrame {
    /// The frame from `low` with the smallest exponent whose top code decodes at or above
    /// `high`, if one does (the largest exponent's top code overflows to infinity, so one does
    /// for finite bounds).
    fn covering(low: f32, high: f32) -> Option<AxisFrame> {
        let fits = |exponent: u8| {
            AxisFrame {
                origin: low,
                exponent,
            }
            .decode(TOP_CODE)
                >= high
        };
        // The exponent of the extent over 255 rounded down, then the exact check each way: a
        // step or two, not a search over all 254.
        let estimate = (((high - low) / f32::from(TOP_CODE)).to_bits() >> 23).clamp(1, 254) as u8;
        let mut exponent = estimate;
        while exponent < 254 && !fits(exponent) {
            exponent += 1;
        }
        while exponent > 1 && fits(exponent - 1) {
            exponent -= 1;
        }
        fits(exponent).then_some(AxisFrame {
            origin: low,
            exponent,
        })
    }

    fn decode(&self, q: u8) -> f32 {
        self.origin + f32::from(q) * f32::from_bits((self.exponent as u32) << 23)
    }

    /// The largest code decoding at or below `value` (code 0 decodes to the frame's low end).
    fn floor(&self, value: f32) -> u8 {
        let mut q = self.estimate(value);
        while q > 0 && self.decode(q) > value {
            q -= 1;
        }
        while q < TOP_CODE && self.decode(q + 1) <= value {
            q += 1;
        }
        q
    }

    /// The smallest code decoding at or above `value` (the top code reaches the frame's high
    /// end).
    fn ceil(&self, value: f32) -> u8 {
        let mut q = self.estimate(value);
        while q < TOP_CODE && self.decode(q) < value {
            q += 1;
        }
        while q > 0 && self.decode(q - 1) >= value {
            q -= 1;
        }
        q
    }

    /// A code near `value`, for the exact steps to start from.
    fn estimate(&self, value: f32) -> u8 {
        let scale = f32::from_bits((self.exponent as u32) << 23);
        ((value - self.origin) / scale).clamp(0.0, f32::from(TOP_CODE)) as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::GRID_LINK_INDEX;

    /// A xorshift generator of coordinates of assorted magnitudes.
    struct Coordinates(u64);

    impl Coordinates {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }

        fn coordinate(&mut self, magnitude: f32) -> f32 {
            let unit = (self.next() >> 40) as f32 / (1u64 << 24) as f32;
            (unit - 0.5) * magnitude
        }

        fn child(&mut self, offset: f32, magnitude: f32, extent: f32, slot: TopSlot) -> WideChild {
            let min = [0; 3].map(|_| offset + self.coordinate(magnitude));
            let size = [0; 3].map(|_| self.coordinate(extent).abs());
            WideChild {
                min,
                max: [0, 1, 2].map(|axis| min[axis] + size[axis]),
                slot,
            }
        }
    }

    fn assert_holds(node: &WideNode, children: &[WideChild]) {
        for (slot, child) in children.iter().enumerate() {
            let (min, max) = node.slot_box(slot);
            for axis in 0..3 {
                assert!(min[axis] <= child.min[axis], "{node:?} {child:?} {axis}");
                assert!(max[axis] >= child.max[axis], "{node:?} {child:?} {axis}");
                assert!(min[axis] <= max[axis], "{node:?} {child:?} {axis}");
            }
            assert_eq!(node.slot(slot), child.slot);
        }
        for slot in children.len()..WIDE_WIDTH {
            assert_eq!(node.slot(slot), TopSlot::Empty);
            assert!((0..3).all(|a| node.min[a][slot] == 0 && node.max[a][slot] == 0));
        }
        assert!(node.exponent.iter().all(|e| (1..=254).contains(e)));
    }

    #[test]
    fn decoded_boxes_hold_their_children_at_every_scale() {
        let mut coordinates = Coordinates(0x9e37_79b9_7f4a_7c15);
        let scales = [
            (0.0, 1.0, 0.1),
            (1.0e5, 1.0, 1.0e-3),
            (-3.0e7, 1.0e-2, 1.0e-6),
            (0.0, 1.0e-30, 1.0e-32),
            (0.0, 1.0e30, 1.0e29),
            (0.0, 3.0e38, 1.0e37),
            (12.5, 0.0, 0.0),
        ];
        for (offset, magnitude, extent) in scales {
            for round in 0..2_000 {
                let count = 1 + round % WIDE_WIDTH;
                let children: Vec<WideChild> = (0..count)
                    .map(|slot| {
                        let link = match slot % 2 {
                            0 => TopSlot::Internal(slot as u32 + 1),
                            _ => TopSlot::Leaf {
                                first: 7 * slot as u32,
                                count: 1 + slot as u32 % 4,
                            },
                        };
                        coordinates.child(offset, magnitude, extent, link)
                    })
                    .collect();
                let node = WideNode::encode(&children).unwrap();
                assert_holds(&node, &children);
            }
        }
    }

    #[test]
    fn codes_are_tight_where_the_scale_resolves_them() {
        let child = |min: f32, max: f32| WideChild {
            min: [min; 3],
            max: [max; 3],
            slot: TopSlot::Internal(1),
        };
        let node = WideNode::encode(&[child(0.0, 255.0), child(10.0, 20.0)]).unwrap();
        assert_eq!(node.exponent, [127; 3]);
        assert_eq!((node.min[0][1], node.max[0][1]), (10, 20));
        let node = WideNode::encode(&[child(0.0, 255.0), child(10.5, 19.5)]).unwrap();
        assert_eq!((node.min[1][1], node.max[1][1]), (10, 20));
    }

    #[test]
    fn what_no_node_holds_is_refused() {
        let leaf = |count| WideChild {
            min: [0.0; 3],
            max: [1.0; 3],
            slot: TopSlot::Leaf { first: 0, count },
        };
        assert!(WideNode::encode(&[leaf(1); 9]).is_err());
        assert!(WideNode::encode(&[leaf(0)]).is_err());
        assert!(WideNode::encode(&[leaf(MAX_WIDE_LEAF_STRIPS + 1)]).is_err());
        let mut far = leaf(1);
        far.slot = TopSlot::Internal(GRID_LINK_INDEX + 1);
        assert!(WideNode::encode(&[far]).is_err());
        let mut infinite = leaf(1);
        infinite.max[2] = f32::INFINITY;
        assert!(WideNode::encode(&[infinite]).is_err());
        let mut inverted = leaf(1);
        inverted.min[0] = 2.0;
        assert!(WideNode::encode(&[inverted]).is_err());
        assert_eq!(WideNode::encode(&[]), Ok(WideNode::EMPTY));
    }
}

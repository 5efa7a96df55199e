//! What the top-level node records share: their slots, and the checks of one node alone.

use std::mem::{offset_of, size_of};

use bytemuck::Pod;
use wide::i32x4;

use super::{
    unpack_link, GridNode, TopNode, TopSlot, WideNode, GRID_LINK_INDEX, GRID_LINK_INDEX_BITS,
    GRID_LINK_INTERNAL, INTERNAL_CHILD, TOP_WIDTH, WIDE_WIDTH,
};

/// validates and traversal follows.
pub trait NodeRecord: Pod {
    /// Child slots of the record.
    const WIDTH: usize;
    /// Byte offset of slot 0's link (child or first strip) within the record, for errors.
    const CHILD_FIELD: u64;
    /// Byte offset of slot 0's kind (or whole link), for errors.
    const KIND_FIELD: u64;
    /// Bytes from one slot's link word to the next.
    const LINK_STRIDE: u64 = size_of::<u32>() as u64;
    /// The exact empty slot, for errors.
    const EMPTY_SLOT: &'static str;

    fn slot(&self, slot: usize) -> TopSlot;

    /// Whether `slot` is bit for bit the record's empty slot.
    fn is_exactly_empty(&self, slot: usize) -> bool;

    /// Occupied slots: those before the first empty one.
    fn occupied(&self) -> usize {
        (0..Self::WIDTH)
            .take_while(|&slot| self.slot(slot) != TopSlot::Empty)
            .count()
    }

    /// The first axis on which occupied `slot`'s box has `min > max`, with the byte offset of
    /// that `min` in the record; `None` when the box is well formed (or the record admits any).
    fn inverted_axis(&self, slot: usize) -> Option<(usize, u64)>;

    /// What is wrong with the fields the node's slots share, if anything, with the byte offset
    /// of the field in the record.
    fn frame_defect(&self) -> Option<(u64, String)> {
        None
    }

    /// Whether node `index` passes the checks that need no other node, all slots at once in
    /// plain comparisons: occupied slots first (at least one unless `limits.empty_root`), each
    /// with a well-formed box and an internal child inside `index + 1..limits.nodes` or a leaf
    /// inside `0..limits.strips`; every slot after them exactly empty. The same decision as
    /// the per-slot checks through [`NodeRecord::slot`] that word a defect (but for limits
    /// beyond 32 bits, where it may reject what they accept: see `LinkBounds`), made without
    /// them: those cost about 270 instructions a node on its first visit, 2.6% of a 1M-ray
    /// query on the 10M scan (callgrind).
    fn passes_alone(&self, index: usize, limits: NodeLimits) -> bool;
}

/// What the checks of one top-level node alone compare its links with.
#[derive(Clone, Copy, Debug)]
pub struct NodeLimits {
    /// Nodes in the file.
    pub nodes: usize,
    /// Strips in the file.
    pub strips: u64,
    /// Whether the node may have no children: the root of a model without strips.
    pub empty_root: bool,
}

impl NodeRecord for TopNode {
    const WIDTH: usize = TOP_WIDTH;
    const CHILD_FIELD: u64 = offset_of!(TopNode, child) as u64;
    const KIND_FIELD: u64 = offset_of!(TopNode, kind) as u64;
    const EMPTY_SLOT: &'static str = "min +inf, max -inf, child 0, kind 0";

    fn slot(&self, slot: usize) -> TopSlot {
        TopNode::slot(self, slot)
    }

    fn is_exactly_empty(&self, slot: usize) -> bool {
        TopNode::is_exactly_empty(self, slot)
    }

    fn occupied(&self) -> usize {
        TopNode::occupied(self)
    }

    /// An inverted f32 box is missed by every ray, like the empty slot's: harmless, admitted.
    fn inverted_axis(&self, _slot: usize) -> Option<(usize, u64)> {
        None
    }

    #[inline]
    fn passes_alone(&self, index: usize, limits: NodeLimits) -> bool {
        let words: &[[u32; TOP_WIDTH]; 8] = bytemuck::cast_ref(self);
        let empty: &[[u32; TOP_WIDTH]; 8] = bytemuck::cast_ref(&TopNode::EMPTY);
        let mut differ = [0u32; TOP_WIDTH];
        for (row, empty_row) in words.iter().zip(empty) {
            for lane in 0..TOP_WIDTH {
                differ[lane] |= row[lane] ^ empty_row[lane];
            }
        }
        let kinds = i32x4::new(self.kind.map(|kind| kind as i32));
        let internal = kinds.simd_eq(i32x4::splat(INTERNAL_CHILD as i32));
        let leaf = !kinds.simd_lt(i32x4::ZERO);
        let links = LinkBounds::new(index, limits).passes(self.child, internal, leaf, kinds);
        slots_pass(
            lanes(|slot| self.kind[slot] != 0),
            links,
            lanes(|slot| differ[slot] == 0),
            limits.empty_root,
        )
    }
}

/// [`NodeLimits`] around node `index` in 32-bit lanes, so that a node's slots compare at once:
/// unsigned values with their sign bit flipped, ordered as signed ones. Limits beyond 32 bits
/// (over 4G nodes or strips) are clamped, which only rejects links that
/// [`NodeRecord::slot`]'s checks then accept.
struct LinkBounds {
    /// The node itself: children come after it.
    node: i32x4,
    last_node: i32x4,
    strips: i32x4,
}

impl LinkBounds {
    #[inline(always)]
    fn new(index: usize, limits: NodeLimits) -> LinkBounds {
        let lane = |value: u64| i32x4::splat(flip_sign(value.min(u32::MAX as u64) as u32));
        LinkBounds {
            node: lane(index as u64),
            last_node: lane(limits.nodes.saturating_sub(1) as u64),
            strips: lane(limits.strips),
        }
    }

    /// The slots whose link passes, as bits: an `internal` slot's names a node after this one
    /// inside the array, a `leaf`'s strips `link..link + count` (`count < 2^31`) lie inside the
    /// record array.
    #[inline(always)]
    fn passes(&self, links: [u32; TOP_WIDTH], internal: i32x4, leaf: i32x4, count: i32x4) -> u32 {
        let links = i32x4::new(links.map(flip_sign));
        let child = links.simd_gt(self.node) & !links.simd_gt(self.last_node);
        let end = links + count;
        let strips = !end.simd_lt(links) & !end.simd_gt(self.strips);
        ((internal & child) | (leaf & strips)).to_bitmask()
    }
}

impl LinkBounds {
    /// [`LinkBounds::passes`] of four one-word links (tag and index, as [`GridNode`] packs
    /// them).
    #[inline(always)]
    fn pass_words(&self, words: [u32; 4]) -> u32 {
        let tags = i32x4::new(words.map(|word| (word >> GRID_LINK_INDEX_BITS) as i32));
        let internal = tags.simd_eq(i32x4::splat(GRID_LINK_INTERNAL as i32));
        let leaf = !tags.simd_eq(i32x4::ZERO) & !internal;
        let first = words.map(|word| word & GRID_LINK_INDEX);
        self.passes(first, internal, leaf, tags)
    }
}

/// `value` with its sign bit flipped: unsigned order as signed order.
#[inline(always)]
fn flip_sign(value: u32) -> i32 {
    (value ^ 1 << 31) as i32
}

/// Bit `slot` set where `test(slot)` holds, over a 4-wide node's slots.
#[inline(always)]
fn lanes(test: impl Fn(usize) -> bool) -> u32 {
    lanes_of(TOP_WIDTH, test)
}

/// Bit `slot` set where `test(slot)` holds, over `width` slots.
#[inline(always)]
fn lanes_of(width: usize, test: impl Fn(usize) -> bool) -> u32 {
    (0..width).fold(0, |bits, slot| bits | (test(slot) as u32) << slot)
}

/// [`NodeRecord::passes_alone`] from bit masks over the slots: `occupied` ones form a prefix
/// (non-empty unless `empty_root`), each with passing `links` (box included), and the others
/// are `exactly_empty`.
#[inline(always)]
fn slots_pass(occupied: u32, links: u32, exactly_empty: u32, empty_root: bool) -> bool {
    slots_of_width_pass(TOP_WIDTH, (occupied, links, exactly_empty), empty_root)
}

/// [`slots_pass`] over `width` slots.
#[inline(always)]
fn slots_of_width_pass(
    width: usize,
    (occupied, links, exactly_empty): (u32, u32, u32),
    empty_root: bool,
) -> bool {
    let all = (1 << width) - 1;
    (occupied & (occupied + 1) == 0)
        & ((occupied != 0) | empty_root)
        & (links & occupied == occupied)
        & (exactly_empty | occupied == all)
}

/// The top bit of each byte of a word.
const BYTE_TOPS: u64 = 0x8080_8080_8080_8080;

/// The top bit of each byte of `word` as bits 0 to 7: each lands, through one multiplication,
/// in its own bit of the top byte, no two partial products meeting.
#[inline(always)]
fn byte_tops(word: u64) -> u32 {
    (((word & BYTE_TOPS) >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u32
}

/// The top bit of each byte of `word` that is not zero.
#[inline(always)]
fn nonzero_bytes(word: u64) -> u64 {
    (((word & !BYTE_TOPS) + !BYTE_TOPS) | word) & BYTE_TOPS
}

/// The top bit of each byte of `a` above the same byte of `b`, unsigned: the low seven bits
/// compared by a subtraction that cannot borrow across bytes, the top bits then decide.
#[inline(always)]
fn bytes_above(a: u64, b: u64) -> u64 {
    let low_not_above = (b | BYTE_TOPS) - (a & !BYTE_TOPS);
    ((a & !b) | (!(a ^ b) & !low_not_above)) & BYTE_TOPS
}

/// Whether `slot`'s box is all zero codes in boxes stored lane by lane (`min[axis][slot]`), as
/// [`GridNode`]'s u16 and [`WideNode`]'s u8 codes are.
fn lane_box_is_zero<T: Copy + Default + PartialEq, const W: usize>(
    min: &[[T; W]; 3],
    max: &[[T; W]; 3],
    slot: usize,
) -> bool {
    (0..3).all(|axis| min[axis][slot] == T::default() && max[axis][slot] == T::default())
}

/// The first axis on which `slot`'s lane-stored box is inverted, with the byte offset of its
/// minimum in the node (`min_field`: the offset of the `min` array).
fn lane_box_inverted_axis<T: Copy + PartialOrd, const W: usize>(
    min: &[[T; W]; 3],
    max: &[[T; W]; 3],
    slot: usize,
    min_field: usize,
) -> Option<(usize, u64)> {
    (0..3)
        .find(|&axis| min[axis][slot] > max[axis][slot])
        .map(|axis| {
            (
                axis,
                (min_field + (axis * W + slot) * size_of::<T>()) as u64,
            )
        })
}

impl NodeRecord for GridNode {
    const WIDTH: usize = TOP_WIDTH;
    const CHILD_FIELD: u64 = offset_of!(GridNode, link) as u64;
    const KIND_FIELD: u64 = offset_of!(GridNode, link) as u64;
    const EMPTY_SLOT: &'static str = "all zero bytes";

    fn slot(&self, slot: usize) -> TopSlot {
        unpack_link(self.link[slot])
    }

    fn is_exactly_empty(&self, slot: usize) -> bool {
        lane_box_is_zero(&self.min, &self.max, slot) && self.link[slot] == 0
    }

    /// An inverted u16 box need not be missed (traversal relies on the link to skip empty
    /// slots only), and no writer rounds outward to one: rejected.
    fn inverted_axis(&self, slot: usize) -> Option<(usize, u64)> {
        lane_box_inverted_axis(&self.min, &self.max, slot, offset_of!(GridNode, min))
    }

    #[inline]
    fn passes_alone(&self, index: usize, limits: NodeLimits) -> bool {
        let mut differ = [0u16; TOP_WIDTH];
        let mut inverted = [false; TOP_WIDTH];
        for (min, max) in self.min.iter().zip(&self.max) {
            for lane in 0..TOP_WIDTH {
                differ[lane] |= min[lane] | max[lane];
                inverted[lane] |= min[lane] > max[lane];
            }
        }
        let links =
            LinkBounds::new(index, limits).pass_words(self.link) & !lanes(|slot| inverted[slot]);
        slots_pass(
            lanes(|slot| self.link[slot] != 0),
            links,
            lanes(|slot| (differ[slot] == 0) & (self.link[slot] == 0)),
            limits.empty_root,
        )
    }
}

impl NodeRecord for WideNode {
    const WIDTH: usize = WIDE_WIDTH;
    const CHILD_FIELD: u64 = offset_of!(WideNode, link) as u64;
    const KIND_FIELD: u64 = offset_of!(WideNode, link) as u64;
    const EMPTY_SLOT: &'static str = "all zero bytes";

    fn slot(&self, slot: usize) -> TopSlot {
        WideNode::slot(self, slot)
    }

    fn is_exactly_empty(&self, slot: usize) -> bool {
        lane_box_is_zero(&self.min, &self.max, slot) && self.link[slot] == 0
    }

    /// As [`GridNode`]'s: no writer rounds outward to an inverted box.
    fn inverted_axis(&self, slot: usize) -> Option<(usize, u64)> {
        lane_box_inverted_axis(&self.min, &self.max, slot, offset_of!(WideNode, min))
    }

    /// A finite origin and exponents in 1..=254 decode every code to a finite value or an
    /// infinity of the right sign (never NaN); the reserved byte is zero.
    fn frame_defect(&self) -> Option<(u64, String)> {
        if let Some(axis) = (0..3).find(|&axis| !self.origin[axis].is_finite()) {
            let field = offset_of!(WideNode, origin) + axis * size_of::<f32>();
            let detail = format!("origin {} on axis {axis} is not finite", self.origin[axis]);
            return Some((field as u64, detail));
        }
        if let Some(axis) = (0..3).find(|&axis| !(1..=254).contains(&self.exponent[axis])) {
            let field = offset_of!(WideNode, exponent) + axis;
            let detail = format!(
                "scale exponent {} on axis {axis} outside 1..=254",
                self.exponent[axis]
            );
            return Some((field as u64, detail));
        }
        (self.reserved != 0).then(|| {
            let detail = format!("reserved byte {} is not 0", self.reserved);
            (offset_of!(WideNode, reserved) as u64, detail)
        })
    }

    #[inline]
    fn passes_alone(&self, index: usize, limits: NodeLimits) -> bool {
        let frame = self.origin.iter().all(|c| c.is_finite())
            & self.exponent.iter().all(|e| (1..=254).contains(e))
            & (self.reserved == 0);
        // Eight slots' codes of an axis are one word: the lanes compare as bytes of words.
        let min: [u64; 3] = bytemuck::cast(self.min);
        let max: [u64; 3] = bytemuck::cast(self.max);
        let codes = min.iter().chain(&max).fold(0, |codes, &word| codes | word);
        let inverted = (0..3).fold(0, |inverted, axis| {
            inverted | bytes_above(min[axis], max[axis])
        });
        let bounds = LinkBounds::new(index, limits);
        let [low, high]: [[u32; 4]; 2] = bytemuck::cast(self.link);
        let links = (bounds.pass_words(low) | bounds.pass_words(high) << 4) & !byte_tops(inverted);
        let linked = lanes_of(WIDE_WIDTH, |slot| self.link[slot] != 0);
        let slots = (
            linked,
            links,
            !(byte_tops(nonzero_bytes(codes)) | linked) & 0xff,
        );
        frame & slots_of_width_pass(WIDE_WIDTH, slots, limits.empty_root)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytemuck::Zeroable;

    /// The per-slot checks that word a node's defect (`validate::nodes::TreeCheck::check` on
    /// a node alone), as a verdict.
    fn passes_slot_by_slot<N: NodeRecord>(node: &N, index: usize, limits: NodeLimits) -> bool {
        let occupied = node.occupied();
        if node.frame_defect().is_some() || (occupied == 0 && !limits.empty_root) {
            return false;
        }
        (0..N::WIDTH).all(|slot| {
            if slot >= occupied {
                return node.is_exactly_empty(slot);
            }
            node.inverted_axis(slot).is_none()
                && match node.slot(slot) {
                    TopSlot::Internal(child) => {
                        child as usize > index && (child as usize) < limits.nodes
                    }
                    TopSlot::Leaf { first, count } => first as u64 + count as u64 <= limits.strips,
                    TopSlot::Empty | TopSlot::Invalid(_) => false,
                }
        })
    }

    /// The byte-lane helpers agree with comparing each byte, on words built from edge values.
    #[test]
    fn byte_lanes_agree_with_each_byte() {
        let mut picker = Picker(0x9e37_79b9_7f4a_7c15);
        let edges = [0u8, 1, 2, 0x7f, 0x80, 0x81, 0xfe, 0xff];
        for _ in 0..20_000 {
            let a: [u8; 8] = std::array::from_fn(|_| picker.pick(&edges));
            let b: [u8; 8] = std::array::from_fn(|_| picker.pick(&edges));
            let (wa, wb) = (u64::from_le_bytes(a), u64::from_le_bytes(b));
            let above = lanes_of(8, |lane| a[lane] > b[lane]);
            assert_eq!(byte_tops(bytes_above(wa, wb)), above, "{a:?} {b:?}");
            let nonzero = lanes_of(8, |lane| a[lane] != 0);
            assert_eq!(byte_tops(nonzero_bytes(wa)), nonzero, "{a:?}");
        }
    }

    /// A xorshift generator picking from small sets of edge values.
    struct Picker(u64);

    impl Picker {
        fn pick<T: Copy>(&mut self, values: &[T]) -> T {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            values[(self.0 % values.len() as u64) as usize]
        }
    }

    const INDEX: usize = 5;
    const NODES: usize = 9;
    const STRIPS: u64 = 20;

    /// How many generated nodes passed and failed, after checking that the fast check agrees
    /// with the per-slot checks on each.
    #[derive(Default)]
    struct Verdicts {
        passed: usize,
        failed: usize,
    }

    impl Verdicts {
        fn compare<N: NodeRecord + std::fmt::Debug>(&mut self, node: &N, picker: &mut Picker) {
            let (index, limits) = limits(picker);
            let expected = passes_slot_by_slot(node, index, limits);
            assert_eq!(
                node.passes_alone(index, limits),
                expected,
                "{node:?} {limits:?}"
            );
            match expected {
                true => self.passed += 1,
                false => self.failed += 1,
            }
        }

        /// Both verdicts came up often: the generated nodes exercised the check both ways.
        fn assert_both_seen(&self) {
            let Verdicts { passed, failed } = self;
            assert!(
                *passed > 10_000 && *failed > 10_000,
                "{passed} passed, {failed} failed"
            );
        }
    }

    fn limits(picker: &mut Picker) -> (usize, NodeLimits) {
        let index = picker.pick(&[0, INDEX]);
        let limits = NodeLimits {
            nodes: NODES,
            strips: STRIPS,
            empty_root: picker.pick(&[false, true]),
        };
        (index, limits)
    }

    /// Links around every bound the checks compare with.
    const LINKS: [u32; 10] = [0, 1, 4, 5, 6, 8, 9, 17, 19, 20];

    #[test]
    fn f32_nodes_pass_alone_exactly_when_every_slot_passes() {
        let mut picker = Picker(0x9e37_79b9_7f4a_7c15);
        let kinds = [
            0,
            0,
            1,
            3,
            INTERNAL_CHILD,
            INTERNAL_CHILD,
            INTERNAL_CHILD + 1,
            u32::MAX,
        ];
        let coordinates = [f32::INFINITY, f32::NEG_INFINITY, 0.0, -0.0, 1.0, f32::NAN];
        let mut verdicts = Verdicts::default();
        for round in 0..200_000 {
            let mut node = TopNode::EMPTY;
            let occupied = picker.pick(&[0, 1, 2, 3, 4]);
            for slot in 0..TOP_WIDTH {
                let kind = match slot < occupied {
                    true => picker.pick(&[1, 3, INTERNAL_CHILD]),
                    false => 0,
                };
                let child = picker.pick(&LINKS);
                node.set(slot, &[0.0; 3], &[1.0; 3], child, kind);
                if slot >= occupied && round % 2 == 0 {
                    node.set(slot, &[f32::INFINITY; 3], &[f32::NEG_INFINITY; 3], 0, 0);
                }
            }
            for _ in 0..picker.pick(&[0, 1, 2]) {
                let slot = picker.pick(&[0, 1, 2, 3]);
                let axis = picker.pick(&[0, 1, 2]);
                match picker.pick(&[0, 1, 2, 3]) {
                    0 => node.kind[slot] = picker.pick(&kinds),
                    1 => node.child[slot] = picker.pick(&LINKS),
                    2 => node.min[axis][slot] = picker.pick(&coordinates),
                    _ => node.max[axis][slot] = picker.pick(&coordinates),
                }
            }
            verdicts.compare(&node, &mut picker);
        }
        verdicts.assert_both_seen();
    }

    #[test]
    fn grid_nodes_pass_alone_exactly_when_every_slot_passes() {
        let mut picker = Picker(0x2545_f491_4f6c_dd1d);
        let tags = [0, 1, 3, 14, GRID_LINK_INTERNAL];
        let bounds = [0, 1, 2, u16::MAX];
        let mut verdicts = Verdicts::default();
        for _ in 0..200_000 {
            let mut node = GridNode::zeroed();
            let occupied = picker.pick(&[0, 1, 2, 3, 4]);
            for slot in 0..occupied {
                let tag = picker.pick(&[1, 3, GRID_LINK_INTERNAL]);
                node.link[slot] = tag << GRID_LINK_INDEX_BITS | picker.pick(&LINKS);
                for axis in 0..3 {
                    node.min[axis][slot] = 1;
                    node.max[axis][slot] = 2;
                }
            }
            for _ in 0..picker.pick(&[0, 1, 2]) {
                let slot = picker.pick(&[0, 1, 2, 3]);
                let axis = picker.pick(&[0, 1, 2]);
                match picker.pick(&[0, 1, 2, 3]) {
                    0 => {
                        let tag = picker.pick(&tags);
                        node.link[slot] = tag << GRID_LINK_INDEX_BITS | picker.pick(&LINKS);
                    }
                    1 => node.link[slot] = picker.pick(&[0, u32::MAX, GRID_LINK_INDEX]),
                    2 => node.min[axis][slot] = picker.pick(&bounds),
                    _ => node.max[axis][slot] = picker.pick(&bounds),
                }
            }
            verdicts.compare(&node, &mut picker);
        }
        verdicts.assert_both_seen();
    }

    #[test]
    fn wide_nodes_pass_alone_exactly_when_every_slot_passes() {
        let mut picker = Picker(0x6a09_e667_f3bc_c909);
        let tags = [0, 1, 3, 14, GRID_LINK_INTERNAL];
        let bounds = [0, 1, 2, u8::MAX];
        let mut verdicts = Verdicts::default();
        for _ in 0..200_000 {
            let mut node = WideNode::EMPTY;
            let occupied = picker.pick(&[0, 1, 2, 4, 7, 8]);
            for slot in 0..occupied {
                let tag = picker.pick(&[1, 3, GRID_LINK_INTERNAL]);
                node.link[slot] = tag << GRID_LINK_INDEX_BITS | picker.pick(&LINKS);
                for axis in 0..3 {
                    node.min[axis][slot] = 1;
                    node.max[axis][slot] = 2;
                }
            }
            for _ in 0..picker.pick(&[0, 1, 2]) {
                let slot = picker.pick(&[0, 1, 3, 4, 6, 7]);
                let axis = picker.pick(&[0, 1, 2]);
                match picker.pick(&[0, 1, 2, 3, 4, 5, 6]) {
                    0 => {
                        let tag = picker.pick(&tags);
                        node.link[slot] = tag << GRID_LINK_INDEX_BITS | picker.pick(&LINKS);
                    }
                    1 => node.link[slot] = picker.pick(&[0, u32::MAX, GRID_LINK_INDEX]),
                    2 => node.min[axis][slot] = picker.pick(&bounds),
                    3 => node.max[axis][slot] = picker.pick(&bounds),
                    4 => node.exponent[axis] = picker.pick(&[0, 1, 127, 254, 255]),
                    5 => node.origin[axis] = picker.pick(&[0.0, f32::INFINITY, f32::NAN]),
                    _ => node.reserved = picker.pick(&[0, 0, 1]),
                }
            }
            verdicts.compare(&node, &mut picker);
        }
        verdicts.assert_both_seen();
    }
}

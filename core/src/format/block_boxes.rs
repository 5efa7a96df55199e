//! Per-block bounding boxes of a strip (format 3.0): one box per eight consecutive windows,
//! stored in 4-bit codes on a per-strip power-of-two scale around the strip's first vertex.
//!
//! Why: the strip kd-tree clips a ray on one axis per node, and on the scan surfaces the project
//! measures a short ambient-occlusion ray that enters a strip's top-level box tests nearly every
//! block of it. A full box per block culls about half of them: on 100k AO rays of the 1M-triangle
//! scan, 5.37 blocks tested per ray without boxes, 2.60 with exact boxes, 3.00 with these codes
//! (2.82 with 4-bit codes relative to the strip's own box, which the tracer does not have), all
//! tested where the kd-tree leads; the tracer walks the blocks without the kd-tree and tests
//! 3.19.
//!
//! Deviation from the paper, which culls inside a strip with its kd-tree alone: the boxes cost
//! three bytes per block and three per strip; format 3.0 packs every file's references
//! (`super::references`) to pay for them, so a default lossless file stays below 20 bytes per
//! triangle (the 1M scan: 19.61 before, 19.82 with boxes and packed references).
//!
//! Layout (after the references, only for strips of more than [`BOX_WINDOWS`] windows): three
//! exponent bytes `e[axis]`, then per box `k` (windows `8k .. 8k + 8`) three bytes, one per axis:
//! low nibble the minimum's code, high nibble the maximum's. With anchor `a` the strip's stored
//! vertex 0 as the reader decodes it, a code `q` on `axis` decodes to
//! `a[axis] + ((q - 8) as f32) * 2^(e[axis] - 127)`: the scale is the normal f32 whose biased
//! exponent is `e` (writers use 1..=254), the product is exact, and the sum is rounded once, so
//! decoding is monotone in `q` and the same bits in every reader and kernel. Writers store the
//! largest minimum code that decodes at or below the block's minimum and the smallest maximum
//! code at or above its maximum (decoded positions, for grid files), so every decoded box holds
//! its windows.

use crate::geometry::Point;

/// Windows per box: the tracer's block of eight windows, one SIMD lane each.
pub const BOX_WINDOWS: usize = 8;
/// Bytes of the per-strip exponents, one per axis.
pub const EXPONENT_BYTES: usize = 3;
/// Bytes of one box: per axis, the minimum's code (low nibble) and the maximum's (high nibble).
pub const BOX_BYTES: usize = 3;
/// Codes run `0..=15`; code `CODE_BIAS` decodes to the anchor.
pub const CODE_BIAS: i32 = 8;
/// The largest code.
pub const MAX_CODE: u8 = 15;
/// Valid exponent bytes: those of normal, finite f32 scales.
pub const EXPONENTS: std::ops::RangeInclusive<u8> = 1..=254;

/// Whether a strip of `windows` windows stores boxes: one block needs none, the strip's own box
/// in the top level bounds it.
pub fn has_boxes(windows: usize) -> bool {
    windows > BOX_WINDOWS
}

/// Bytes of the box area of a strip of `windows` windows.
pub fn area_bytes(windows: usize) -> usize {
    if has_boxes(windows) {
        EXPONENT_BYTES + BOX_BYTES * windows.div_ceil(BOX_WINDOWS)
    } else {
        0
    }
}

/// The scale an exponent byte stands for: `2^(exponent - 127)`.
#[inline(always)]
pub fn scale(exponent: u8) -> f32 {
    f32::from_bits(u32::from(exponent) << 23)
}

/// The plane code `code` stands for on an axis with anchor coordinate `anchor` and `scale`.
#[inline(always)]
pub fn decode_plane(anchor: f32, scale: f32, code: u8) -> f32 {
    anchor + (i32::from(code) - CODE_BIAS) as f32 * scale
}

/// A strip's box area, viewed in place: empty for a strip without boxes.
#[derive(Clone, Copy, Debug, Default)]
pub struct BlockBoxes<'a> {
    bytes: &'a [u8],
}

/// The decoding frame of a strip's boxes: its anchor and per-axis scales.
#[derive(Clone, Copy, Debug)]
pub struct BoxFrame {
    pub anchor: Point,
    pub scale: Point,
}

impl<'a> BlockBoxes<'a> {
    /// The area in `bytes` (exactly [`area_bytes`] long).
    pub fn new(bytes: &'a [u8]) -> BlockBoxes<'a> {
        BlockBoxes { bytes }
    }

    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Bytes of the area.
    pub fn stored_bytes(&self) -> usize {
        self.bytes.len()
    }

    /// The area's bytes: the exponents, then the boxes' codes.
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Boxes stored.
    pub fn count(&self) -> usize {
        self.bytes.len().saturating_sub(EXPONENT_BYTES) / BOX_BYTES
    }

    /// The exponent bytes, one per axis (`None` without boxes).
    pub fn exponents(&self) -> Option<[u8; 3]> {
        self.bytes.first_chunk().copied()
    }

    /// The frame of the boxes around `anchor` (the strip's decoded vertex 0), or `None`.
    #[inline(always)]
    pub fn frame(&self, anchor: Point) -> Option<BoxFrame> {
        let exponents = self.exponents()?;
        Some(BoxFrame {
            anchor,
            scale: exponents.map(scale),
        })
    }

    /// The codes of box `index`, or `None` past the last box.
    #[inline(always)]
    pub fn codes(&self, index: usize) -> Option<[u8; BOX_BYTES]> {
        let start = EXPONENT_BYTES + BOX_BYTES * index;
        self.bytes.get(start..)?.first_chunk().copied()
    }

    /// Box `index` (windows `8 index ..`) decoded in `frame`, or `None` past the last box.
    #[inline(always)]
    pub fn decode(&self, frame: &BoxFrame, index: usize) -> Option<(Point, Point)> {
        let start = EXPONENT_BYTES + BOX_BYTES * index;
        let codes: &[u8; BOX_BYTES] = self.bytes.get(start..)?.first_chunk()?;
        let plane =
            |axis: usize, code: u8| decode_plane(frame.anchor[axis], frame.scale[axis], code);
        let min = std::array::from_fn(|axis| plane(axis, codes[axis] & MAX_CODE));
        let max = std::array::from_fn(|axis| plane(axis, codes[axis] >> 4));
        Some((min, max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn area_sizes() {
        assert_eq!(area_bytes(3), 0);
        assert_eq!(area_bytes(8), 0);
        assert_eq!(area_bytes(9), 3 + 6);
        assert_eq!(area_bytes(24), 3 + 9);
    }

    #[test]
    fn planes_decode_around_the_anchor() {
        assert_eq!(scale(127), 1.0);
        assert_eq!(scale(128), 2.0);
        assert_eq!(decode_plane(1.5, 0.25, 8), 1.5);
        assert_eq!(decode_plane(1.5, 0.25, 0), -0.5);
        assert_eq!(decode_plane(1.5, 0.25, 15), 3.25);
        let bytes = [127, 126, 128, 0xF0, 0x98, 0x87];
        let boxes = BlockBoxes::new(&bytes);
        let frame = boxes.frame([0.0, 1.0, -2.0]).expect("boxes");
        let (min, max) = boxes.decode(&frame, 0).expect("box 0");
        assert_eq!(min, [-8.0, 1.0, -2.0 - 2.0]);
        assert_eq!(max, [7.0, 1.5, -2.0]);
        assert!(boxes.decode(&frame, 1).is_none());
        assert!(BlockBoxes::default().frame([0.0; 3]).is_none());
    }
}

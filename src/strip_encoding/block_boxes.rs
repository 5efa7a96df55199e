//! Encodes a strip's block boxes (format 3.0, [`crate::format::block_boxes`]): per axis the
//! smallest power-of-two scale whose sixteen codes around the anchor reach the strip's bounds,
//! then per box the outward-rounded codes of its windows' bounds.
//!
//! Every choice is checked with the reader's own decode expression
//! ([`decode_plane`]), so a decoded box holds its windows bit for bit, whatever the rounding
//! of the sum.

use crate::format::block_boxes::{
    decode_plane, has_boxes, scale, BOX_WINDOWS, EXPONENTS, MAX_CODE,
};
use crate::geometry::{Aabb, Point};

/// The box area of a strip whose references name `positions` (decoded, strip order, swaps
/// included) and whose stored vertex 0 decodes to `anchor`; empty for a strip of one block.
pub(crate) fn encode(positions: &[Point], anchor: Point) -> Vec<u8> {
    let windows = positions.len().saturating_sub(2);
    if !has_boxes(windows) {
        return Vec::new();
    }
    let boxes: Vec<Aabb> = (0..windows)
        .step_by(BOX_WINDOWS)
        .map(|first| {
            let end = (first + BOX_WINDOWS + 2).min(positions.len());
            Aabb::from_points(&positions[first..end])
        })
        .collect();
    let strip = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
    let exponents: [u8; 3] =
        std::array::from_fn(|axis| exponent(anchor[axis], strip.min[axis], strip.max[axis]));
    let mut area = exponents.to_vec();
    for block in &boxes {
        area.extend((0..3).map(|axis| {
            let s = scale(exponents[axis]);
            let min = min_code(anchor[axis], s, block.min[axis]);
            let max = max_code(anchor[axis], s, block.max[axis]);
            min | max << 4
        }));
    }
    area
}

/// The smallest exponent whose codes 0 and 15 decode at or beyond `low` and `high`. The
/// largest one always does: its planes overflow to infinities.
fn exponent(anchor: f32, low: f32, high: f32) -> u8 {
    let reaches = |e: u8| {
        decode_plane(anchor, scale(e), 0) <= low && decode_plane(anchor, scale(e), MAX_CODE) >= high
    };
    // Start a little below the scale the extent asks for, so that rounding cannot skip one.
    let extent = (high - anchor).max(anchor - low).max(0.0);
    let estimate = ((extent / 8.0).to_bits() >> 23) as u8;
    let first = estimate.saturating_sub(2).max(*EXPONENTS.start());
    (first..=*EXPONENTS.end())
        .find(|&e| reaches(e))
        .unwrap_or(*EXPONENTS.end())
}

/// The largest code decoding at or below `value` (code 0 does, by the exponent's choice).
fn min_code(anchor: f32, scale: f32, value: f32) -> u8 {
    (0..=MAX_CODE)
        .rev()
        .find(|&q| decode_plane(anchor, scale, q) <= value)
        .unwrap_or(0)
}

/// The smallest code decoding at or above `value` (code 15 does, by the exponent's choice).
fn max_code(anchor: f32, scale: f32, value: f32) -> u8 {
    (0..=MAX_CODE)
        .find(|&q| decode_plane(anchor, scale, q) >= value)
        .unwrap_or(MAX_CODE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::block_boxes::{area_bytes, BlockBoxes};

    /// Decoded boxes hold their windows' positions, for ordinary, flat, tiny and huge strips.
    #[test]
    fn decoded_boxes_hold_their_windows() {
        let strips: Vec<Vec<Point>> = vec![
            (0..20)
                .map(|k| [k as f32 * 0.1, (k % 2) as f32, 0.5])
                .collect(),
            (0..30)
                .map(|k| [1.0e6 + k as f32, 3.0, -(k as f32)])
                .collect(),
            (0..11).map(|k| [1e-30 * k as f32, 0.0, 0.0]).collect(),
            (0..12)
                .map(|k| [3.0e38 - (k as f32) * 1e37, -3.0e38, 7.0])
                .collect(),
        ];
        for positions in strips {
            for anchor in [positions[0], positions[positions.len() / 2]] {
                let area = encode(&positions, anchor);
                let windows = positions.len() - 2;
                assert_eq!(area.len(), area_bytes(windows));
                let boxes = BlockBoxes::new(&area);
                let frame = boxes.frame(anchor).expect("boxes");
                for first in (0..windows).step_by(BOX_WINDOWS) {
                    let (min, max) = boxes.decode(&frame, first / BOX_WINDOWS).expect("box");
                    for p in &positions[first..(first + BOX_WINDOWS + 2).min(positions.len())] {
                        for axis in 0..3 {
                            assert!(min[axis] <= p[axis] && p[axis] <= max[axis], "{p:?}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn one_block_strips_have_no_boxes() {
        assert!(encode(&[[0.0; 3]; 10], [0.0; 3]).is_empty());
    }
}

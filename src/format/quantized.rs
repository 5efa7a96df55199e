//! The vertices of a quantized strip block: one anchor per axis plus fixed-width offsets, the
//! approach of AMD's Dense Geometry Format (Barczak et al., "DGF: A Dense, Hardware-Friendly
//! Geometry Format for Lossily Compressing Meshlets with Arbitrary Topologies", HPG 2024).
//!
//! A strip is small and spatially compact, so its grid points differ from the strip's minimum
//! corner by far less than the grid's extent: each axis stores only the bits that the strip's
//! extent on that axis needs. Layout at the start of the block (little-endian):
//!
//! ```text
//! 3 axis words (u32: x, y, z)   bits 0..24 anchor a (grid coordinate), bits 24..29 width w
//!                               (0..=24), bits 29..32 zero
//! vertex offsets                vertex_count × (wx + wy + wz) bits in ceil(/ 8) bytes, least
//!                               significant bit first; vertex i's x offset at bits
//!                               [i s, i s + wx), then y, then z (s = wx + wy + wz)
//! ```
//!
//! A vertex's grid coordinate on an axis is `a + offset`. Writers keep `a + 2^w - 1` inside the
//! grid (`< 2^bits`), so a reader checks three words, not every vertex, to know that every grid
//! coordinate is in range.
//!
//! Decoding reads four bytes per axis at the offset's first byte: an offset of at most 24 bits
//! shifted by at most 7 fits. The last such read ends at most three bytes past the offsets, and
//! a block always has at least three reference bytes after them.

use super::grid::{Grid, MAX_GRID_BITS};
use crate::geometry::Point;

/// Bytes of the three axis words at the start of a quantized block.
pub const AXIS_WORDS_BYTES: usize = 12;

const ANCHOR_MASK: u32 = (1 << MAX_GRID_BITS) - 1;
const WIDTH_SHIFT: u32 = 24;

/// One axis of a strip's quantized vertices: the anchor and the offset width in bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AxisWord {
    pub anchor: u32,
    pub width: u32,
}

impl AxisWord {
    pub fn to_u32(self) -> u32 {
        self.anchor | self.width << WIDTH_SHIFT
    }

    pub fn from_u32(word: u32) -> AxisWord {
        AxisWord {
            anchor: word & ANCHOR_MASK,
            width: word >> WIDTH_SHIFT,
        }
    }

    /// The three words at the start of `block` (at least [`AXIS_WORDS_BYTES`] long), unchecked.
    #[inline(always)]
    pub fn read_all(block: &[u8]) -> [AxisWord; 3] {
        let words = &block[..AXIS_WORDS_BYTES];
        let word = |at: usize| {
            AxisWord::from_u32(u32::from_le_bytes([
                words[at],
                words[at + 1],
                words[at + 2],
                words[at + 3],
            ]))
        };
        [word(0), word(4), word(8)]
    }

    /// Whether the word fits the file's grid (see the module documentation).
    pub fn check(&self, grid_bits: u32) -> Result<(), String> {
        if self.width > grid_bits {
            return Err(format!(
                "offset width {} exceeds the grid's {grid_bits} bits",
                self.width
            ));
        }
        let top = self.anchor as u64 + (1u64 << self.width) - 1;
        if top >> grid_bits != 0 {
            return Err(format!(
                "anchor {} plus {}-bit offsets leaves the {grid_bits}-bit grid",
                self.anchor, self.width
            ));
        }
        Ok(())
    }
}

/// Bits of one vertex's offsets.
pub fn vertex_bits(axes: &[AxisWord; 3]) -> usize {
    axes.iter().map(|a| a.width as usize).sum()
}

/// Bytes of the axis words and offsets of `count` vertices.
pub fn vertex_part_bytes(count: usize, axes: &[AxisWord; 3]) -> usize {
    AXIS_WORDS_BYTES + (count * vertex_bits(axes)).div_ceil(8)
}

/// The axis words and packed offsets of `points` on a grid of `grid_bits` bits.
pub fn pack(points: &[[u32; 3]], grid_bits: u32) -> Vec<u8> {
    let axes: [AxisWord; 3] = std::array::from_fn(|a| {
        let min = points.iter().map(|p| p[a]).min().unwrap_or(0);
        let max = points.iter().map(|p| p[a]).max().unwrap_or(0);
        let width = u32::BITS - (max - min).leading_zeros();
        // Lowered when the offsets' full range would pass the grid's last coordinate; the
        // offsets still fit, since max < 2^bits.
        let anchor = min.min((1u32 << grid_bits) - (1u32 << width));
        AxisWord { anchor, width }
    });
    let mut bytes = Vec::with_capacity(vertex_part_bytes(points.len(), &axes));
    for axis in &axes {
        bytes.extend_from_slice(&axis.to_u32().to_le_bytes());
    }
    let mut writer = BitWriter {
        bytes,
        pending: 0,
        pending_bits: 0,
    };
    for p in points {
        for (a, axis) in axes.iter().enumerate() {
            writer.push(p[a] - axis.anchor, axis.width);
        }
    }
    writer.finish()
}

/// Appends values of up to 24 bits, least significant bit first.
struct BitWriter {
    bytes: Vec<u8>,
    pending: u64,
    pending_bits: u32,
}

impl BitWriter {
    fn push(&mut self, value: u32, width: u32) {
        self.pending |= (value as u64) << self.pending_bits;
        self.pending_bits += width;
        while self.pending_bits >= 8 {
            self.bytes.push(self.pending as u8);
            self.pending >>= 8;
            self.pending_bits -= 8;
        }
    }

    fn finish(mut self) -> Vec<u8> {
        if self.pending_bits > 0 {
            self.bytes.push(self.pending as u8);
        }
        self.bytes
    }
}

/// The low `width` bits set.
#[inline(always)]
fn mask(width: u32) -> u32 {
    (1u32 << width) - 1
}

/// Widest vertex read with one eight-byte load: its offsets start at most 7 bits into the load.
const ONE_WORD_BITS: u32 = 64 - 7;

/// A strip's quantized vertices decoded in place from the mapping.
#[derive(Clone, Copy, Debug)]
pub struct GridVertices<'a> {
    /// From the first offset byte to the end of the block (at least three bytes past the
    /// offsets: see the module documentation).
    bytes: &'a [u8],
    anchor: [u32; 3],
    mask: [u32; 3],
    /// Bit of vertex 0's offset on each axis; 0 for zero-width axes, so that their (masked)
    /// read never passes the offsets.
    first_bit: [u32; 3],
    stride: u32,
    count: u32,
    grid: Grid,
}

impl<'a> GridVertices<'a> {
    /// `bytes` starts at the first offset byte and runs to the block's end; `axes` were checked
    /// by [`AxisWord::check`] and the block's length by the reader.
    #[inline]
    pub fn new(bytes: &'a [u8], axes: &[AxisWord; 3], count: usize, grid: &Grid) -> Self {
        let mut first_bit = [0; 3];
        let mut stride = 0;
        for (a, axis) in axes.iter().enumerate() {
            if axis.width > 0 {
                first_bit[a] = stride;
            }
            stride += axis.width;
        }
        GridVertices {
            bytes,
            anchor: [axes[0].anchor, axes[1].anchor, axes[2].anchor],
            mask: [
                mask(axes[0].width),
                mask(axes[1].width),
                mask(axes[2].width),
            ],
            first_bit,
            stride,
            count: count as u32,
            grid: *grid,
        }
    }

    pub fn len(&self) -> usize {
        self.count as usize
    }

    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Grid coordinate of vertex `index` on `axis`.
    #[inline(always)]
    pub fn grid_coordinate(&self, index: usize, axis: usize) -> u32 {
        let bit = index * self.stride as usize + self.first_bit[axis] as usize;
        let at = bit >> 3;
        let bytes = &self.bytes[at..at + 4];
        let word = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        self.anchor[axis] + ((word >> (bit & 7)) & self.mask[axis])
    }

    /// Grid point of vertex `index`. A vertex of at most [`ONE_WORD_BITS`] bits (the common
    /// case: strips are small) is read with one eight-byte load instead of one load per axis.
    #[inline(always)]
    pub fn grid_point(&self, index: usize) -> [u32; 3] {
        if self.stride > ONE_WORD_BITS {
            return [
                self.grid_coordinate(index, 0),
                self.grid_coordinate(index, 1),
                self.grid_coordinate(index, 2),
            ];
        }
        let bit = index * self.stride as usize;
        let at = bit >> 3;
        let word = match self.bytes.get(at..at + 8) {
            Some(bytes) => u64::from_le_bytes(bytes.try_into().unwrap_or_default()),
            None => self.last_word(at),
        } >> (bit & 7);
        let axis = |a: usize| self.anchor[a] + ((word >> self.first_bit[a]) as u32 & self.mask[a]);
        [axis(0), axis(1), axis(2)]
    }

    /// The bytes from `at` to the end of the block, zero-extended to eight.
    #[cold]
    fn last_word(&self, at: usize) -> u64 {
        let mut bytes = [0u8; 8];
        let tail = &self.bytes[at..];
        bytes[..tail.len()].copy_from_slice(tail);
        u64::from_le_bytes(bytes)
    }

    /// Vertex `index`'s coordinate on `axis`, through [`Grid::decode_axis`].
    #[inline(always)]
    pub fn coordinate(&self, index: usize, axis: usize) -> f32 {
        self.grid
            .decode_axis(self.grid_coordinate(index, axis), axis)
    }

    #[inline(always)]
    pub fn point(&self, index: usize) -> Point {
        self.decode(self.grid_point(index))
    }

    #[inline(always)]
    fn decode(&self, q: [u32; 3]) -> Point {
        let grid = &self.grid;
        [
            grid.decode_axis(q[0], 0),
            grid.decode_axis(q[1], 1),
            grid.decode_axis(q[2], 2),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Aabb;

    fn words(bytes: &[u8], bits: u32) -> [AxisWord; 3] {
        let axes = AxisWord::read_all(bytes);
        for axis in &axes {
            axis.check(bits).expect("valid word");
        }
        axes
    }

    fn decoder<'a>(bytes: &'a [u8], count: usize, grid: &Grid) -> GridVertices<'a> {
        let axes = words(bytes, grid.bits);
        GridVertices::new(&bytes[AXIS_WORDS_BYTES..], &axes, count, grid)
    }

    fn unit_grid(bits: u32) -> Grid {
        Grid::over(
            &Aabb {
                min: [0.0; 3],
                max: [1.0; 3],
            },
            bits,
        )
    }

    #[test]
    fn packed_points_read_back_exactly() {
        let grid = unit_grid(20);
        let points: Vec<[u32; 3]> = (0..200u32)
            .map(|i| [1000 + i * 37 % 4096, 77, 500_000 + (i * i) % 300])
            .collect();
        let mut bytes = pack(&points, 20);
        let axes = words(&bytes, 20);
        assert_eq!(axes.map(|a| a.width), [12, 0, 9]);
        assert_eq!(bytes.len(), vertex_part_bytes(points.len(), &axes));
        bytes.extend([0; 3]);
        let vertices = decoder(&bytes, points.len(), &grid);
        for (i, p) in points.iter().enumerate() {
            assert_eq!(vertices.grid_point(i), *p);
            assert_eq!(vertices.point(i), grid.decode(p));
        }
    }

    #[test]
    fn anchors_near_the_grid_end_are_lowered_to_stay_inside() {
        let points = [[1022, 1023, 0], [1023, 1015, 0]];
        let mut bytes = pack(&points, 10);
        let axes = words(&bytes, 10);
        assert_eq!(
            axes[0],
            AxisWord {
                anchor: 1022,
                width: 1
            }
        );
        assert_eq!(
            axes[1],
            AxisWord {
                anchor: 1008,
                width: 4
            }
        );
        bytes.extend([0; 3]);
        let vertices = decoder(&bytes, 2, &unit_grid(10));
        assert_eq!(vertices.grid_point(1), points[1]);
    }

    #[test]
    fn words_outside_the_grid_are_rejected() {
        let check = |anchor, width, bits| AxisWord { anchor, width }.check(bits);
        assert!(check(0, 17, 16).is_err());
        assert!(check(65_535, 1, 16).is_err());
        assert!(check(65_534, 1, 16).is_ok());
        assert!(AxisWord::from_u32(u32::MAX).check(24).is_err());
    }
}

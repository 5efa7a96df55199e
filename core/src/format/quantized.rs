//! The vertices of a quantized strip block: one anchor per axis plus fixed-width offsets, the
//! approach of AMD's Dense Geometry Format (Barczak et al., "DGF: A Dense, Hardware-Friendly
//! Geometry Format for Lossily Compressing Meshlets with Arbitrary Topologies", HPG 2024).
//!
//! A strip is small and spatially compact, so its grid points differ from the strip's minimum
//! corner by far less than the grid's extent: each axis stores only the bits that the strip's
//! extent on that axis needs. The block starts with one little-endian bit stream (bit `b` is
//! bit `b mod 8` of byte `b / 8`): per axis x, y, z an anchor `a` (a grid coordinate) and an
//! offset width `w` (0..=24), then the vertices' offsets, vertex `i`'s x offset at bits
//! `[h + i s, h + i s + wx)`, then y, then z (`s = wx + wy + wz`, `h` the axis words' bits).
//! The axis words are stored as laid out by [`AxisWordLayout`]: since format 2.3 packed at the
//! grid's bits (`h = 3 (grid_bits + 5)`, 75 bits at 20 bits instead of 96), before as three
//! u32 words with the anchor in bits 0..24 and the width in bits 24..29.
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

const ANCHOR_MASK: u32 = (1 << MAX_GRID_BITS) - 1;
const WIDTH_SHIFT: u32 = 24;
/// Bits of a packed axis word's width field.
const WIDTH_BITS: u32 = 5;

/// How a block stores its three axis words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisWordLayout {
    /// Three u32 words, anchor in bits 0..24 and width in bits 24..29 (formats 2.1 and 2.2).
    Words,
    /// Per axis `grid_bits` anchor bits then 5 width bits, the offsets following in the same bit
    /// stream (format 2.3).
    Packed { grid_bits: u32 },
}

impl AxisWordLayout {
    /// Bits of the three axis words, where vertex 0's offsets start.
    pub fn bits(self) -> usize {
        match self {
            AxisWordLayout::Words => 96,
            AxisWordLayout::Packed { grid_bits } => 3 * (grid_bits + WIDTH_BITS) as usize,
        }
    }

    /// The three axis words at the start of `block`, unchecked (see [`AxisWord::check`]); a
    /// block shorter than the words reads as zero-extended.
    #[inline(always)]
    pub fn read(self, block: &[u8]) -> [AxisWord; 3] {
        let stream = match block.get(..16) {
            Some(head) => u128::from_le_bytes(head.try_into().unwrap_or_default()),
            None => zero_extended(block),
        };
        match self {
            AxisWordLayout::Words => {
                std::array::from_fn(|a| AxisWord::from_u32((stream >> (32 * a)) as u32))
            }
            AxisWordLayout::Packed { grid_bits } => std::array::from_fn(|a| {
                let word = (stream >> (a as u32 * (grid_bits + WIDTH_BITS))) as u32;
                AxisWord {
                    anchor: word & ((1 << grid_bits) - 1),
                    width: (word >> grid_bits) & ((1 << WIDTH_BITS) - 1),
                }
            }),
        }
    }
}

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

    /// Whether the word fits the file's grid: [`AxisWord::check`] without the message.
    #[inline(always)]
    pub fn fits(&self, grid_bits: u32) -> bool {
        self.width <= grid_bits && (self.anchor as u64 + (1u64 << self.width) - 1) >> grid_bits == 0
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

/// The first 16 bytes of a block shorter than that, zero-extended.
#[cold]
fn zero_extended(block: &[u8]) -> u128 {
    let mut head = [0u8; 16];
    head[..block.len()].copy_from_slice(block);
    u128::from_le_bytes(head)
}

/// Bits of one vertex's offsets.
pub fn vertex_bits(axes: &[AxisWord; 3]) -> usize {
    axes.iter().map(|a| a.width as usize).sum()
}

/// Bytes of the axis words and offsets of `count` vertices.
pub fn vertex_part_bytes(count: usize, axes: &[AxisWord; 3], layout: AxisWordLayout) -> usize {
    (layout.bits() + count * vertex_bits(axes)).div_ceil(8)
}

/// The axis words and packed offsets of `points` on a grid of `grid_bits` bits.
pub fn pack(points: &[[u32; 3]], grid_bits: u32, layout: AxisWordLayout) -> Vec<u8> {
    let axes: [AxisWord; 3] = std::array::from_fn(|a| {
        let min = points.iter().map(|p| p[a]).min().unwrap_or(0);
        let max = points.iter().map(|p| p[a]).max().unwrap_or(0);
        let width = u32::BITS - (max - min).leading_zeros();
        // Lowered when the offsets' full range would pass the grid's last coordinate; the
        // offsets still fit, since max < 2^bits.
        let anchor = min.min((1u32 << grid_bits) - (1u32 << width));
        AxisWord { anchor, width }
    });
    let mut writer = BitWriter {
        bytes: Vec::with_capacity(vertex_part_bytes(points.len(), &axes, layout)),
        pending: 0,
        pending_bits: 0,
    };
    for axis in &axes {
        match layout {
            AxisWordLayout::Words => writer.push_u32(axis.to_u32()),
            AxisWordLayout::Packed { grid_bits } => {
                writer.push(axis.anchor, grid_bits);
                writer.push(axis.width, WIDTH_BITS);
            }
        }
    }
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
    fn push_u32(&mut self, value: u32) {
        self.push(value & 0xffff, 16);
        self.push(value >> 16, 16);
    }

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
    /// From the block's start to its end (at least three bytes past the offsets: see the module
    /// documentation).
    bytes: &'a [u8],
    /// Bit of vertex 0's offsets: the axis words' bits.
    base_bit: u32,
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
    /// `bytes` is the block, whose axis words (`axes`, laid out as `layout`) were checked by
    /// [`AxisWord::check`] and whose length was checked by the reader.
    #[inline]
    pub fn new(
        bytes: &'a [u8],
        (axes, layout): (&[AxisWord; 3], AxisWordLayout),
        count: usize,
        grid: &Grid,
    ) -> Self {
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
            base_bit: layout.bits() as u32,
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

    /// The `count` vertices from vertex `first` on: a pooled strip's vertices within its pool
    /// ([`super::pool`]), decoded as the pool's own.
    #[inline(always)]
    pub fn starting_at(self, first: usize, count: usize) -> Self {
        GridVertices {
            base_bit: self.base_bit + (first as u32) * self.stride,
            count: count as u32,
            ..self
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
        let bit =
            self.base_bit as usize + index * self.stride as usize + self.first_bit[axis] as usize;
        let at = bit >> 3;
        // Beyond the block only for a file changed after its validation: zeros, not a panic.
        let word = self.bytes.get(at..at + 4).map_or(0, |bytes| {
            u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])
        });
        self.anchor[axis].wrapping_add((word >> (bit & 7)) & self.mask[axis])
    }

    /// Grid point of vertex `index`. A vertex of at most [`ONE_WORD_BITS`] bits (the common
    /// case: strips are small) is read with one eight-byte load instead of one load per axis.
    #[inline(always)]
    pub fn grid_point(&self, index: usize) -> [u32; 3] {
        if self.stride > ONE_WORD_BITS {
            return [0, 1, 2].map(|axis| self.grid_coordinate(index, axis));
        }
        self.grid_point_in_word(index)
    }

    /// The grid points of the first `used` vertices `indices` name, one array per axis, as
    /// [`GridVertices::grid_point`] gives them (later entries are arbitrary grid points);
    /// whether a vertex fits one load is decided once for all of them.
    #[inline(always)]
    pub fn grid_points<const N: usize>(&self, indices: &[u8; N], used: usize) -> [[u32; N]; 3] {
        let mut points = [[0; N]; 3];
        if self.stride > ONE_WORD_BITS {
            for (position, &index) in indices.iter().enumerate().take(used) {
                for (axis, coordinates) in points.iter_mut().enumerate() {
                    coordinates[position] = self.grid_coordinate(index as usize, axis);
                }
            }
            return points;
        }
        // First every vertex's word, then every axis over all words: the axis loops have fixed
        // lengths and uniform shifts, which the compiler unrolls and vectorizes, rather than
        // one long loop body that keeps three axes' fields live.
        let mut words = [0u64; N];
        for (word, &index) in words.iter_mut().zip(indices).take(used) {
            *word = self.vertex_word(index as usize);
        }
        for (axis, coordinates) in points.iter_mut().enumerate() {
            for (coordinate, &word) in coordinates.iter_mut().zip(&words) {
                *coordinate = self.axis_of_word(word, axis);
            }
        }
        points
    }

    /// [`GridVertices::grid_point`] of a vertex of at most [`ONE_WORD_BITS`] bits.
    #[inline(always)]
    fn grid_point_in_word(&self, index: usize) -> [u32; 3] {
        let word = self.vertex_word(index);
        [0, 1, 2].map(|axis| self.axis_of_word(word, axis))
    }

    /// The bits of vertex `index` (of at most [`ONE_WORD_BITS`]), from bit 0.
    #[inline(always)]
    fn vertex_word(&self, index: usize) -> u64 {
        let bit = self.base_bit as usize + index * self.stride as usize;
        let at = bit >> 3;
        let word = match self.bytes.get(at..at + 8) {
            Some(bytes) => u64::from_le_bytes(bytes.try_into().unwrap_or_default()),
            None => self.last_word(at),
        };
        word >> (bit & 7)
    }

    /// Grid coordinate on `axis` of the vertex whose bits are `word`.
    #[inline(always)]
    fn axis_of_word(&self, word: u64, axis: usize) -> u32 {
        self.anchor[axis].wrapping_add((word >> self.first_bit[axis]) as u32 & self.mask[axis])
    }

    /// The bytes from `at` to the end of the block, zero-extended to eight.
    #[cold]
    fn last_word(&self, at: usize) -> u64 {
        let mut bytes = [0u8; 8];
        let tail = self.bytes.get(at..).unwrap_or_default();
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

    fn layouts(bits: u32) -> [AxisWordLayout; 2] {
        [
            AxisWordLayout::Words,
            AxisWordLayout::Packed { grid_bits: bits },
        ]
    }

    fn words(bytes: &[u8], bits: u32, layout: AxisWordLayout) -> [AxisWord; 3] {
        let axes = layout.read(bytes);
        for axis in &axes {
            axis.check(bits).expect("valid word");
        }
        axes
    }

    fn decoder<'a>(
        bytes: &'a [u8],
        count: usize,
        grid: &Grid,
        layout: AxisWordLayout,
    ) -> GridVertices<'a> {
        let axes = words(bytes, grid.bits, layout);
        GridVertices::new(bytes, (&axes, layout), count, grid)
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
        for layout in layouts(20) {
            let mut bytes = pack(&points, 20, layout);
            let axes = words(&bytes, 20, layout);
            assert_eq!(axes.map(|a| a.width), [12, 0, 9]);
            assert_eq!(axes[1].anchor, 77);
            assert_eq!(bytes.len(), vertex_part_bytes(points.len(), &axes, layout));
            bytes.extend([0; 3]);
            let vertices = decoder(&bytes, points.len(), &grid, layout);
            for (i, p) in points.iter().enumerate() {
                assert_eq!(vertices.grid_point(i), *p);
                assert_eq!(vertices.point(i), grid.decode(p));
                assert_eq!(vertices.grid_coordinate(i, 2), p[2]);
            }
        }
    }

    #[test]
    fn packed_axis_words_take_the_grid_bits() {
        let points = [[5, 6, 7], [9, 6, 8]];
        let packed = pack(&points, 20, AxisWordLayout::Packed { grid_bits: 20 });
        let words = pack(&points, 20, AxisWordLayout::Words);
        // 75 bits of axis words and 3 + 0 + 1 offset bits per vertex.
        assert_eq!(packed.len(), 83usize.div_ceil(8));
        assert_eq!(words.len(), 104usize.div_ceil(8));
    }

    #[test]
    fn anchors_near_the_grid_end_are_lowered_to_stay_inside() {
        let points = [[1022, 1023, 0], [1023, 1015, 0]];
        for layout in layouts(10) {
            let mut bytes = pack(&points, 10, layout);
            let axes = words(&bytes, 10, layout);
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
            let vertices = decoder(&bytes, 2, &unit_grid(10), layout);
            assert_eq!(vertices.grid_point(1), points[1]);
        }
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

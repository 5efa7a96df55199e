//! A strip's vertex references as stored: one byte each (the paper's 1-byte local indices), or,
//! in grid files since format 2.3 and in every file since 3.0, packed at the fewest bits that
//! address the strip's vertices.
//!
//! Why pack: a strip stores on average about 20 vertices, so 5 of the 8 bits of a reference
//! address anything; on a 10M-triangle scan at 20 grid bits the references are 1.26 of 8.4
//! bytes per triangle, and packing saves 0.44 of them. Format 2 kept one byte per reference in
//! lossless files, as the paper does; format 3 packs them too (0.51 bytes per triangle on the
//! 1M scan), which pays for its block boxes ([`super::block_boxes`]). Reading a tracer block
//! then costs one load and a shift per reference ([`References::block_stream`]), or one
//! `pdep` for eight of them in the AVX2 kernel.
//!
//! Packed layout: a strip with `v` vertices stores reference `k` in bits
//! `[k w, k w + w)` of its reference bytes, least significant bit first, with
//! `w = `[`packed_width`]`(v)`; the reference bytes are at least [`MIN_PACKED_BYTES`] long
//! (zero-filled), so that the quantized vertex decoder may read past the vertex offsets (see
//! [`super::quantized`]).
//!
//! Deviation from the paper: it stores 1-byte indices; packing is the Dense Geometry Format's
//! per-meshlet index width applied to the strip.

/// Bits of packed references one 8-byte load holds: 64 less a shift of at most 7.
const BITS_PER_LOAD: usize = 57;

/// References of any width (at most 8 bits) one load of [`BITS_PER_LOAD`] bits holds.
const REFERENCES_PER_LOAD: usize = BITS_PER_LOAD / 8;

/// Bytes a packed reference area has at least.
pub const MIN_PACKED_BYTES: usize = 3;

/// Bits of one packed reference of a strip with `vertices` stored vertices: enough for index
/// `vertices - 1`, at least 1; 8 for 256 vertices.
pub fn packed_width(vertices: usize) -> u32 {
    usize::BITS - vertices.saturating_sub(1).max(1).leading_zeros()
}

/// Bytes of `count` references packed for a strip of `vertices` vertices.
pub fn packed_bytes(count: usize, vertices: usize) -> usize {
    (count * packed_width(vertices) as usize)
        .div_ceil(8)
        .max(MIN_PACKED_BYTES)
}

/// Packs `references` (each below `vertices`) into [`packed_bytes`] bytes.
pub fn pack(references: &[u8], vertices: usize) -> Vec<u8> {
    let width = packed_width(vertices) as usize;
    let mut bytes = vec![0u8; packed_bytes(references.len(), vertices)];
    for (k, &reference) in references.iter().enumerate() {
        let bit = k * width;
        let wide = (reference as u16) << (bit % 8);
        bytes[bit / 8] |= wide as u8;
        if let Some(next) = bytes.get_mut(bit / 8 + 1) {
            *next |= (wide >> 8) as u8;
        }
    }
    bytes
}

/// The eight `width`-bit fields at the bottom of `stream` (`width` at most 7), one per byte,
/// least significant first: the upper four fields moved up to bit 32, then in each half the upper
/// two to bit 16, then in each quarter the upper one to bit 8. Each step's mask keeps the fields
/// it moves and drops those a shift brought down from the part above, which at 7 bits a field
/// end below the moved fields' destination.
#[inline(always)]
fn spread_to_bytes(stream: u64, width: usize) -> u64 {
    let quad_mask = (1u64 << (4 * width)) - 1;
    let quads = (stream & quad_mask) | (((stream >> (4 * width)) & quad_mask) << 32);
    let pair_mask = ((1u64 << (2 * width)) - 1) * 0x0000_0001_0000_0001;
    let pairs = (quads & pair_mask) | (((quads >> (2 * width)) & pair_mask) << 16);
    let single_mask = ((1u64 << width) - 1) * 0x0001_0001_0001_0001;
    (pairs & single_mask) | (((pairs >> width) & single_mask) << 8)
}

/// The masks [`References::first_at_least`] compares one load of `width`-bit fields with.
#[derive(Clone, Copy, Debug)]
struct FieldMasks {
    /// Fields one load holds.
    per_load: usize,
    /// The top bit of each field.
    top: u64,
    /// The other bits of each field.
    low: u64,
}

impl FieldMasks {
    const fn of(width: usize) -> FieldMasks {
        let per_load = BITS_PER_LOAD / width;
        let field = (1u64 << width) - 1;
        let ones = ((1u64 << (per_load * width)) - 1) / field;
        let top = ones << (width - 1);
        FieldMasks {
            per_load,
            top,
            low: (ones * field) & !top,
        }
    }
}

/// A limit in every field of one load, its top bits and its other bits apart.
struct FieldLimit {
    masks: FieldMasks,
    top: u64,
    low: u64,
}

impl FieldLimit {
    #[inline(always)]
    fn new(masks: FieldMasks, width: usize, limit: usize) -> FieldLimit {
        let spread = (masks.top >> (width - 1)) * limit as u64;
        FieldLimit {
            masks,
            top: spread & masks.top,
            low: spread & masks.low,
        }
    }
}

/// [`FieldMasks`] by width, for every width a strip record can give (1 to 16; 0 unused).
const FIELD_MASKS: [FieldMasks; 17] = {
    let mut masks = [FieldMasks {
        per_load: 1,
        top: 0,
        low: 0,
    }; 17];
    let mut width = 1;
    while width < masks.len() {
        masks[width] = FieldMasks::of(width);
        width += 1;
    }
    masks
};

/// A strip's references viewed in place.
#[derive(Clone, Copy, Debug)]
pub struct References<'a> {
    /// The references' bytes and, for packed references, whatever of the block follows them
    /// (loads may read it; masks drop it).
    bytes: &'a [u8],
    /// Bytes of the references themselves.
    stored: usize,
    count: usize,
    width: u32,
}

impl<'a> References<'a> {
    /// One reference per byte.
    pub fn bytes(bytes: &'a [u8]) -> References<'a> {
        References {
            bytes,
            stored: bytes.len(),
            count: bytes.len(),
            width: 8,
        }
    }

    /// `count` references packed for a strip of `vertices` vertices in `bytes` (at least
    /// [`packed_bytes`] long).
    pub fn packed(bytes: &'a [u8], count: usize, vertices: usize) -> References<'a> {
        References::packed_before(bytes, bytes.len(), count, vertices)
    }

    /// [`References::packed`] stored in the first `stored` bytes of `bytes`, the rest being
    /// other data of the block that may be read and masked off: a strip's last block then
    /// loads in place rather than through `References::load_tail` (format 3 blocks follow
    /// their references with the block boxes).
    pub fn packed_before(
        bytes: &'a [u8],
        stored: usize,
        count: usize,
        vertices: usize,
    ) -> References<'a> {
        References::packed_at(bytes, stored, count, packed_width(vertices))
    }

    /// [`References::packed_before`] with the width known: [`packed_width`] of the strip's
    /// vertices, which the reader computes anyway for the area's length.
    #[inline(always)]
    pub fn packed_at(bytes: &'a [u8], stored: usize, count: usize, width: u32) -> References<'a> {
        References {
            bytes,
            stored,
            count,
            width,
        }
    }

    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Bytes the references occupy in the block.
    pub fn stored_bytes(&self) -> usize {
        self.stored
    }

    /// Where reference `k` starts in the stored bytes.
    pub fn byte_of(&self, k: usize) -> usize {
        k * self.width as usize / 8
    }

    /// Reference `k` (below [`References::len`]).
    #[inline(always)]
    pub fn get(&self, k: usize) -> u8 {
        let mut one = [0u8];
        self.read_into(k, &mut one);
        one[0]
    }

    /// References `first .. first + out.len()` into `out`. Packed references (at most 7 bits)
    /// are read eight at a time, with one 8-byte load and three word steps that move each of
    /// them into a byte of its own ([`spread_to_bytes`]), rather than a shift, a mask and a
    /// store each.
    #[inline(always)]
    pub fn read_into(&self, first: usize, out: &mut [u8]) {
        if self.width == 8 {
            out.copy_from_slice(&self.bytes[first..first + out.len()]);
            return;
        }
        let width = self.width as usize;
        let (groups, tail) = out.as_chunks_mut::<8>();
        let mut next = first;
        for group in groups {
            *group = spread_to_bytes(self.eight_at(next), width).to_le_bytes();
            next += 8;
        }
        if !tail.is_empty() {
            let bytes = spread_to_bytes(self.eight_at(next), width).to_le_bytes();
            for (slot, byte) in tail.iter_mut().zip(bytes) {
                *slot = byte;
            }
        }
    }

    /// The bit stream from reference `first` on: at least 57 bits, eight references of up to 7
    /// bits.
    #[inline(always)]
    fn eight_at(&self, first: usize) -> u64 {
        let bit = first * self.width as usize;
        self.load(bit / 8) >> (bit % 8)
    }

    /// References `first .. first + N` (`first` below [`References::len`]), positions past the
    /// last reference holding 0, which names a vertex every strip has. One byte per reference
    /// is one fixed-size copy when the block lies inside the stored bytes: a copy of a length
    /// known at compile time is a couple of loads, not a call to `memcpy`.
    #[inline(always)]
    pub fn read_block<const N: usize>(&self, first: usize) -> [u8; N] {
        if self.width == 8 {
            let stored = &self.bytes[..self.stored];
            return match stored.get(first..).and_then(|rest| rest.first_chunk()) {
                Some(&block) => block,
                None => self.read_last_byte_block(first),
            };
        }
        self.read_partial_block(first)
    }

    /// References `first .. first + N` as one little-endian bit stream of
    /// [`References::width`] bits each (those past the last reference zero), when they are
    /// packed and fit one load: a tracer block of ten references up to 5 bits wide, that is of
    /// a strip of at most 32 vertices (nearly all at the pipeline's strip length).
    #[inline(always)]
    pub fn block_stream<const N: usize>(&self, first: usize) -> Option<u64> {
        let width = self.width as usize;
        if width == 8 || N * width > BITS_PER_LOAD {
            return None;
        }
        let bit = first * width;
        let kept = (self.count - first).min(N) * width;
        Some((self.load(bit / 8) >> (bit % 8)) & ((1u64 << kept) - 1))
    }

    /// Bits per reference.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// [`References::read_block`] of one byte per reference at the strip's end: eight
    /// references per load, with no per-reference work and no `memcpy` of a variable length.
    #[inline(always)]
    fn read_last_byte_block<const N: usize>(&self, first: usize) -> [u8; N] {
        let mut block = [0u8; N];
        let available = self.count - first;
        for (chunk, slots) in block.chunks_mut(8).enumerate() {
            let start = chunk * 8;
            let kept = available.saturating_sub(start).min(8) as u32;
            // The bytes past the last reference are other data: masked off (read as vertex 0).
            let word = self.load(first + start) & u64::MAX.checked_shr(64 - 8 * kept).unwrap_or(0);
            slots.copy_from_slice(&word.to_le_bytes()[..slots.len()]);
        }
        block
    }

    /// [`References::read_block`] up to the last reference, through one load per
    /// [`REFERENCES_PER_LOAD`] references whatever their width: for a block of fixed size, a
    /// fixed number of loads and no division by the width.
    #[inline(always)]
    fn read_partial_block<const N: usize>(&self, first: usize) -> [u8; N] {
        let mut block = [0u8; N];
        let available = self.count - first;
        let width = self.width as usize;
        let mask = (1u64 << width) - 1;
        if let Some(stream) = self.block_stream::<N>(first) {
            for (k, slot) in block.iter_mut().enumerate() {
                *slot = ((stream >> (k * width)) & mask) as u8;
            }
            return block;
        }
        for (chunk, slots) in block.chunks_mut(REFERENCES_PER_LOAD).enumerate() {
            let start = chunk * REFERENCES_PER_LOAD;
            let bit = (first + start) * width;
            // Bits past the last reference are padding or other data: masked off so that
            // they read as vertex 0. At most 7 * 8 bits are kept: the shift stays below 64.
            let kept = available.saturating_sub(start).min(REFERENCES_PER_LOAD) * width;
            let stream = (self.load(bit / 8) >> (bit % 8)) & ((1u64 << kept) - 1);
            for (k, slot) in slots.iter_mut().enumerate() {
                *slot = ((stream >> (k * width)) & mask) as u8;
            }
        }
        block
    }

    /// The 8 bytes from `at`, zero-extended past the end.
    #[inline(always)]
    fn load(&self, at: usize) -> u64 {
        match self.bytes.get(at..at + 8) {
            Some(bytes) => u64::from_le_bytes(bytes.try_into().unwrap_or_default()),
            None => self.load_tail(at),
        }
    }

    /// [`References::load`] past the last eight bytes: those shifted down, so that a strip's
    /// last block costs a shift rather than a byte copy. Areas shorter than eight bytes (a few
    /// references) are assembled byte by byte.
    #[inline]
    fn load_tail(&self, at: usize) -> u64 {
        match self.bytes.len().checked_sub(8) {
            Some(start) => {
                let last: [u8; 8] = self.bytes[start..].try_into().unwrap_or_default();
                // `at > start`: the eight bytes from `at` pass the end.
                u64::from_le_bytes(last)
                    .checked_shr(8 * (at - start) as u32)
                    .unwrap_or(0)
            }
            None => self.bytes[at.min(self.bytes.len())..]
                .iter()
                .rev()
                .fold(0, |word, &byte| (word << 8) | byte as u64),
        }
    }

    /// The position of the first reference that is `limit` or more, if any: for a strip of
    /// `limit` vertices, the first that names no vertex.
    ///
    /// A dozen word operations per load of [`BITS_PER_LOAD`] bits (eleven 5-bit references)
    /// rather than a load, a mask and a comparison per reference: this runs on every strip's
    /// first view. Per field of `w` bits, the comparison is split at the field's top bit: with
    /// that bit set in the value and clear in the limit, subtracting the limit's low bits never
    /// borrows across fields, and the difference's top bit says whether the low bits reach the
    /// limit's; the top bits then decide. The masks per width are constants ([`FieldMasks`]):
    /// computed per call, their two divisions and shifts were a third of the search.
    #[inline]
    pub fn first_at_least(&self, limit: usize) -> Option<usize> {
        let width = self.width as usize;
        if limit >> width != 0 {
            return None;
        }
        let masks = FIELD_MASKS
            .get(width)
            .copied()
            .unwrap_or_else(|| FieldMasks::of(width));
        let limit = FieldLimit::new(masks, width, limit);
        let mut first = 0;
        while first < self.count {
            let kept = (self.count - first).min(masks.per_load) * width;
            let found = self.fields_at_least(first, &limit) & ((1u64 << kept) - 1);
            if found != 0 {
                return Some(first + found.trailing_zeros() as usize / width);
            }
            first += masks.per_load;
        }
        None
    }

    /// Whether every reference is below `limit`: [`References::first_at_least`] deciding only,
    /// inlined into a strip's first view. Loads of as many fields as one holds, the last ending
    /// at the last reference (checking again some that an earlier load checked), so that no
    /// load but a lone short one masks off fields past the references: most strips take two
    /// loads and no loop.
    #[inline(always)]
    pub fn all_below(&self, limit: usize) -> bool {
        let width = self.width as usize;
        if limit >> width != 0 {
            return true;
        }
        let Some(&masks) = FIELD_MASKS.get(width) else {
            return self.first_at_least(limit).is_none();
        };
        let limit = FieldLimit::new(masks, width, limit);
        let Some(last) = self.count.checked_sub(masks.per_load) else {
            let kept = (1u64 << (self.count * width)) - 1;
            return self.fields_at_least(0, &limit) & kept == 0;
        };
        let mut found = self.fields_at_least(last, &limit);
        let mut first = 0;
        while first < last {
            found |= self.fields_at_least(first, &limit);
            first += masks.per_load;
        }
        found == 0
    }

    /// The top bit of each field of one load, from reference `first` on, that is `limit`'s or
    /// more (fields past the references included).
    #[inline(always)]
    fn fields_at_least(&self, first: usize, limit: &FieldLimit) -> u64 {
        let FieldMasks { top, low, .. } = limit.masks;
        let bit = first * self.width as usize;
        let stream = self.load(bit / 8) >> (bit % 8);
        let (value_top, value_low) = (stream & top, stream & low);
        let low_reaches = ((value_low | top) - limit.low) & top;
        (value_top & !limit.top) | (!(value_top ^ limit.top) & low_reaches)
    }

    /// How many of the first `windows` windows (at most [`References::len`] less 2) name three
    /// different references, that is are not swaps (`strip_windows::window_corners`).
    ///
    /// Counted on the packed fields a load at a time, without spreading them into bytes: a
    /// load's fields xor-ed with the same load shifted by one and two fields, a field that is
    /// not zero found as in [`References::first_at_least`], the windows counted by one
    /// popcount. The face-row index counts every strip of a file so.
    #[inline]
    pub fn distinct_windows(&self, windows: usize) -> usize {
        let width = self.width as usize;
        let Some(&FieldMasks { per_load, top, low }) = FIELD_MASKS.get(width) else {
            return (0..windows)
                .filter(|&k| {
                    let [a, b, c] = [self.get(k), self.get(k + 1), self.get(k + 2)];
                    a != b && b != c && a != c
                })
                .count();
        };
        // A window needs its two following fields in the same load.
        let windows_per_load = per_load - 2;
        let nonzero = |x: u64| (((x & low) + low) | x) & top;
        let mut real = 0;
        let mut first = 0;
        while first < windows {
            let bit = first * width;
            let a = self.load(bit / 8) >> (bit % 8);
            let (b, c) = (a >> width, a >> (2 * width));
            let kept = (windows - first).min(windows_per_load) * width;
            let distinct = nonzero(a ^ b) & nonzero(b ^ c) & nonzero(a ^ c);
            real += (distinct & ((1u64 << kept) - 1)).count_ones() as usize;
            first += windows_per_load;
        }
        real
    }

    /// Every reference, one byte each.
    pub fn to_vec(&self) -> Vec<u8> {
        let mut all = vec![0; self.count];
        self.read_into(0, &mut all);
        all
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_address_exactly_the_vertices() {
        assert_eq!(packed_width(1), 1);
        assert_eq!(packed_width(2), 1);
        assert_eq!(packed_width(3), 2);
        assert_eq!(packed_width(4), 2);
        assert_eq!(packed_width(5), 3);
        assert_eq!(packed_width(32), 5);
        assert_eq!(packed_width(33), 6);
        assert_eq!(packed_width(256), 8);
    }

    #[test]
    fn packed_references_read_back_for_every_width() {
        for vertices in [3usize, 4, 5, 17, 32, 33, 100, 128, 129, 256] {
            for count in [3usize, 4, 7, 8, 9, 61, 200] {
                let references: Vec<u8> = (0..count)
                    .map(|k| ((k * 7919 + vertices) % vertices) as u8)
                    .collect();
                let bytes = pack(&references, vertices);
                assert_eq!(bytes.len(), packed_bytes(count, vertices));
                let view = References::packed(&bytes, count, vertices);
                assert_eq!(view.to_vec(), references, "{vertices} vertices, {count}");
                assert!((0..count).all(|k| view.get(k) == references[k]));
                let mut tail = [0u8; 3];
                view.read_into(count - 3, &mut tail);
                assert_eq!(tail, references[count - 3..]);
                let block: [u8; 10] = view.read_block(count - 3);
                assert_eq!(block[..3], references[count - 3..]);
                assert_eq!(block[3..], [0; 7]);
            }
        }
    }

    /// `references` packed for `vertices`, then `after` (other data past the area), and the
    /// area's length.
    fn packed_then(references: &[u8], vertices: usize, after: &[u8]) -> (Vec<u8>, usize) {
        let mut bytes = pack(references, vertices);
        let stored = bytes.len();
        bytes.extend_from_slice(after);
        (bytes, stored)
    }

    /// The word-parallel search finds the same reference as a scan, and the range check
    /// decides as it, for every width, limit and position, in packed and byte areas, with
    /// other data after the references.
    #[test]
    fn first_reference_at_least_a_limit_matches_a_scan() {
        for vertices in [
            3usize, 4, 5, 7, 8, 9, 17, 31, 32, 33, 100, 128, 129, 200, 256,
        ] {
            for count in [3usize, 4, 10, 11, 12, 23, 57, 61, 200] {
                let references: Vec<u8> = (0..count)
                    .map(|k| ((k * 7919 + vertices * 31) % vertices) as u8)
                    .collect();
                let (bytes, stored) = packed_then(&references, vertices, &[0xff; 5]);
                let packed = References::packed_before(&bytes, stored, count, vertices);
                let unpacked = References::bytes(&references);
                for limit in 1..=vertices {
                    let scan = references.iter().position(|&r| usize::from(r) >= limit);
                    assert_eq!(
                        packed.first_at_least(limit),
                        scan,
                        "{vertices} {count} {limit}"
                    );
                    assert_eq!(
                        unpacked.first_at_least(limit),
                        scan,
                        "bytes {count} {limit}"
                    );
                    assert_eq!(packed.all_below(limit), scan.is_none(), "{count} {limit}");
                    assert_eq!(unpacked.all_below(limit), scan.is_none(), "{count} {limit}");
                }
            }
        }
    }

    /// The count of windows with three different references is that of a scan, for every
    /// width and for one byte per reference, from few references to more than a load holds.
    #[test]
    fn distinct_windows_match_a_scan_of_the_windows() {
        let mut seed = 7u64;
        for vertices in [2usize, 3, 4, 5, 8, 9, 17, 32, 33, 64, 65, 128, 129, 256] {
            for count in [2usize, 3, 4, 9, 13, 14, 22, 57, 60, 130, 258] {
                let references: Vec<u8> = (0..count)
                    .map(|_| {
                        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                        // Mostly a few small values, so that swaps are common.
                        let value = match seed >> 62 {
                            0 => seed >> 33,
                            _ => seed >> 61,
                        };
                        (value as usize % vertices) as u8
                    })
                    .collect();
                let (bytes, stored) = packed_then(&references, vertices, &[0xff; 5]);
                let packed = References::packed_before(&bytes, stored, count, vertices);
                let unpacked = References::bytes(&references);
                for windows in 0..=count - 2 {
                    let scan = references[..windows + 2]
                        .windows(3)
                        .filter(|c| c[0] != c[1] && c[1] != c[2] && c[0] != c[2])
                        .count();
                    assert_eq!(packed.distinct_windows(windows), scan, "{vertices} {count}");
                    assert_eq!(unpacked.distinct_windows(windows), scan, "bytes {count}");
                }
            }
        }
    }

    /// Reading any run of references from any position gives the packed references, for every
    /// width, with other data after the area.
    #[test]
    fn packed_runs_read_back_from_every_position() {
        for vertices in [3usize, 4, 5, 9, 16, 17, 32, 33, 64, 65, 128, 129, 256] {
            let count = 41;
            let references: Vec<u8> = (0..count)
                .map(|k| ((k * 7919 + vertices * 13) % vertices) as u8)
                .collect();
            let (bytes, stored) = packed_then(&references, vertices, &[0xa5; 6]);
            let view = References::packed_before(&bytes, stored, count, vertices);
            for first in 0..count {
                for length in 0..=count - first {
                    let mut out = vec![0u8; length];
                    view.read_into(first, &mut out);
                    assert_eq!(out, references[first..first + length], "{vertices} {first}");
                }
            }
        }
    }

    #[test]
    fn byte_blocks_read_whole_or_zero_padded() {
        let references: Vec<u8> = (0..12).map(|k| k * 3).collect();
        let view = References::bytes(&references);
        let whole: [u8; 10] = view.read_block(2);
        assert_eq!(whole, references[2..12]);
        let tail: [u8; 10] = view.read_block(5);
        assert_eq!(tail[..7], references[5..]);
        assert_eq!(tail[7..], [0; 3]);
    }

    #[test]
    fn packed_areas_keep_three_bytes_for_the_vertex_decoder() {
        assert_eq!(packed_bytes(3, 3), 3);
        assert_eq!(packed_bytes(24, 256), 24);
        assert_eq!(packed_bytes(25, 3), 7);
    }
}

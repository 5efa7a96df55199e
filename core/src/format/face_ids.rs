//! Reading the `face_ids` section (format 2.5): per strip, one entry of bit-packed ids, one
//! per window, laid out as [`FaceIdGroup`] describes.
//!
//! Why this code: input faces of scanned and generated meshes come in scan-line or slice order,
//! so a strip's triangles form a few runs of consecutive ids (along a row) joined by jumps of a
//! row's length (across rows). A delta from the previous window fits a few bits inside a run,
//! and an offset from the strip's smallest id covers the jumps; a flag per window says which.
//! Measured on 1M-triangle meshes of every `gen` kind converted at the pipeline's strip
//! settings (length 20, 8-window leaves), sections `face_ids` plus `face_id_groups` over the
//! triangle count: 1.11 bytes per triangle on `scan`, 0.95 `cad`, 1.32 `terrain`, 1.26
//! `sphere`, 1.49 `isosurface`; 3.01 on `scan` with its faces numbered in random order (no
//! coherence at all). The same prototype with offsets alone took 1.61 on `scan` (plus groups),
//! with deltas alone 1.41.

use super::attributes::{
    FaceIdGroup, BASE_WIDTH_BITS, DELTA_WIDTH_BITS, GROUP_STRIPS, OFFSET_WIDTH_BITS,
};
use super::Defect;

/// A defect in the stream: the bit where it is, its kind and what is wrong.
pub type FaceIdDefect = (u64, Defect, String);

/// A little-endian bit stream over a byte slice (bit `b` is bit `b mod 8` of byte `b / 8`).
#[derive(Clone, Copy, Debug)]
pub struct BitStream<'a> {
    bytes: &'a [u8],
}

/// Bits a lookup reads at once: a word at any bit offset holds at least 56 bits.
const WORD_BITS: u64 = 56;

impl<'a> BitStream<'a> {
    pub fn new(bytes: &'a [u8]) -> BitStream<'a> {
        BitStream { bytes }
    }

    pub fn bits(&self) -> u64 {
        self.bytes.len() as u64 * 8
    }

    /// The 56 bits from bit `at` (zeros past the end: callers check an entry's extent first).
    #[inline]
    fn word(&self, at: u64) -> u64 {
        let first = (at / 8) as usize;
        let word = match self.bytes.get(first..first + 8) {
            Some(eight) => u64::from_le_bytes(eight.try_into().unwrap_or_default()),
            None => {
                let mut tail = [0u8; 8];
                let start = first.min(self.bytes.len());
                let available = self.bytes.len() - start;
                tail[..available].copy_from_slice(&self.bytes[start..]);
                u64::from_le_bytes(tail)
            }
        };
        word >> (at % 8)
    }

    /// The `width` (at most 56) bits at bit `at`.
    #[inline]
    fn field(&self, at: u64, width: u32) -> u64 {
        self.word(at) & low_bits(width)
    }

    /// Ones among the `count` bits at `at`.
    fn ones(&self, at: u64, count: u64) -> u64 {
        let mut ones = 0;
        let mut done = 0;
        while done < count {
            let width = (count - done).min(WORD_BITS) as u32;
            ones += self.field(at + done, width).count_ones() as u64;
            done += width as u64;
        }
        ones
    }
}

fn low_bits(width: u32) -> u64 {
    (1u64 << width) - 1
}

/// The header of one strip's entry.
#[derive(Clone, Copy, Debug)]
struct EntryHeader {
    smallest: u64,
    offset_width: u32,
    delta_width: u32,
    /// Bit of the first window flag.
    flags: u64,
}

/// Reads the header of the entry at bit `at` (its widths and base fit one 56-bit word).
#[inline(always)]
fn entry_header(stream: &BitStream, at: u64, group_base: u32) -> Result<EntryHeader, FaceIdDefect> {
    let word = stream.word(at);
    let base_width = (word & low_bits(BASE_WIDTH_BITS)) as u32;
    if base_width > 32 {
        let detail = format!("base width {base_width} is above 32");
        return Err((at, Defect::OutOfRange, detail));
    }
    let base_delta = (word >> BASE_WIDTH_BITS) & low_bits(base_width);
    let rest = word >> (BASE_WIDTH_BITS + base_width);
    let offset_width = (rest & low_bits(OFFSET_WIDTH_BITS)) as u32;
    if offset_width > 32 {
        let field = at + (BASE_WIDTH_BITS + base_width) as u64;
        let detail = format!("offset width {offset_width} is above 32");
        return Err((field, Defect::OutOfRange, detail));
    }
    let delta_width = ((rest >> OFFSET_WIDTH_BITS) & low_bits(DELTA_WIDTH_BITS)) as u32;
    let flags = at + (BASE_WIDTH_BITS + base_width + OFFSET_WIDTH_BITS + DELTA_WIDTH_BITS) as u64;
    if flags > stream.bits() {
        let detail = "the entry header passes the section end".into();
        return Err((at, Defect::Truncated, detail));
    }
    Ok(EntryHeader {
        smallest: group_base as u64 + base_delta,
        offset_width,
        delta_width,
        flags,
    })
}

impl EntryHeader {
    /// The bit after the entry of a strip of `windows` windows, checked to lie in the stream.
    #[inline(always)]
    fn end(&self, stream: &BitStream, windows: u64) -> Result<u64, FaceIdDefect> {
        let flags_end = self.flags.saturating_add(windows);
        if flags_end > stream.bits() {
            let detail = "the entry's flags pass the section end".into();
            return Err((self.flags, Defect::Truncated, detail));
        }
        let offsets = stream.ones(self.flags, windows);
        let end = flags_end
            + offsets * self.offset_width as u64
            + (windows - offsets) * self.delta_width as u64;
        match end <= stream.bits() {
            true => Ok(end),
            false => Err((
                self.flags,
                Defect::Truncated,
                "the entry's ids pass the section end".into(),
            )),
        }
    }

    /// Decodes the ids of windows `0..=last` of an entry inside the stream (see
    /// [`EntryHeader::end`]), handing each to `visit`.
    fn decode(
        &self,
        stream: &BitStream,
        windows: u64,
        last: u64,
        mut visit: impl FnMut(u32),
    ) -> Result<(), FaceIdDefect> {
        let mut value_at = self.flags + windows;
        let mut id = self.smallest;
        let mut flags = 0;
        for window in 0..=last {
            if window % WORD_BITS == 0 {
                flags = stream.word(self.flags + window);
            }
            let is_offset = flags & 1 == 1;
            flags >>= 1;
            if window == 0 && !is_offset {
                return Err((
                    self.flags,
                    Defect::BadEncoding,
                    "the first window's flag is not an offset".into(),
                ));
            }
            id = if is_offset {
                let offset = stream.field(value_at, self.offset_width);
                value_at += self.offset_width as u64;
                self.smallest + offset
            } else {
                let zigzag = stream.field(value_at, self.delta_width);
                value_at += self.delta_width as u64;
                let delta = (zigzag >> 1) as i64 ^ -((zigzag & 1) as i64);
                (id as i64).wrapping_add(delta) as u64
            };
            let Ok(id) = u32::try_from(id) else {
                let detail = format!("window {window}'s id {id} is not a u32");
                return Err((value_at, Defect::OutOfRange, detail));
            };
            visit(id);
        }
        Ok(())
    }
}

/// The face id of `window` of `strip`, whose group record is `group`; `windows(s)` gives the
/// window count of strip `s` (from its record).
pub fn face_id(
    stream: &BitStream,
    group: &FaceIdGroup,
    strip: usize,
    window: usize,
    windows: impl Fn(usize) -> u64,
) -> Result<u32, FaceIdDefect> {
    let first = strip - strip % GROUP_STRIPS;
    let mut at = group.bit_offset;
    for before in first..strip {
        at = entry_header(stream, at, group.base)?.end(stream, windows(before))?;
    }
    let header = entry_header(stream, at, group.base)?;
    let count = windows(strip);
    if window as u64 >= count {
        let detail = format!("window {window} of a strip of {count} windows");
        return Err((at, Defect::OutOfRange, detail));
    }
    header.end(stream, count)?;
    let mut found = 0;
    header.decode(stream, count, window as u64, |id| found = id)?;
    Ok(found)
}

/// Decodes every id of the group's strips, in order, each with its strip; the bit after the
/// group's last entry.
pub fn decode_group(
    stream: &BitStream,
    group: &FaceIdGroup,
    strip_windows: &[u64],
    visit: &mut dyn FnMut(usize, u32),
) -> Result<u64, FaceIdDefect> {
    let mut at = group.bit_offset;
    for (strip, &windows) in strip_windows.iter().enumerate() {
        let header = entry_header(stream, at, group.base)?;
        let end = header.end(stream, windows)?;
        if windows > 0 {
            header.decode(stream, windows, windows - 1, |id| visit(strip, id))?;
        }
        at = end;
    }
    Ok(at)
}

//! Reading the `face_ids` section (format 2.5): per strip, one entry of bit-packed ids, one
//! per window, laid out as [`FaceIdGroup`] describes.
//!
//! Why this code: input faces of scanned and generated meshes come in scan-line or slice order,
//! so a strip's triangles form a few runs of consecutive ids (along a row) joined by jumps of a
//! row's length (across rows). A delta from the previous window fits a few bits inside a run,
//! and an offset from the strip's smallest id covers the jumps; a flag per window says which.
//! Measured over 1M-triangle meshes of every `gen` kind at the pipeline's strip settings (length
//! 20, 8-window leaves): 1.03 bytes per triangle on `scan` (1.61 for offsets alone, 1.41 for
//! deltas alone), 0.87 `cad`, 1.22 `terrain`, 1.15 `sphere`, 1.35 `isosurface`, group records
//! included.

use super::attributes::{
    FaceIdGroup, BASE_WIDTH_BITS, DELTA_WIDTH_BITS, GROUP_STRIPS, OFFSET_WIDTH_BITS,
};

/// A defect in the stream: the bit where it is, and what is wrong.
pub type FaceIdDefect = (u64, String);

/// A little-endian bit stream over a byte slice (bit `b` is bit `b mod 8` of byte `b / 8`).
#[derive(Clone, Copy, Debug)]
pub struct BitStream<'a> {
    bytes: &'a [u8],
}

impl<'a> BitStream<'a> {
    pub fn new(bytes: &'a [u8]) -> BitStream<'a> {
        BitStream { bytes }
    }

    pub fn bits(&self) -> u64 {
        self.bytes.len() as u64 * 8
    }

    /// The `width` (at most 32) bits at bit `at`; a defect when they pass the end.
    #[inline]
    pub fn read(&self, at: u64, width: u32) -> Result<u64, FaceIdDefect> {
        if at.saturating_add(width as u64) > self.bits() {
            return Err((at, format!("a {width}-bit field passes the section end")));
        }
        if width == 0 {
            return Ok(0);
        }
        let first = (at / 8) as usize;
        let mut word = [0u8; 8];
        let available = (self.bytes.len() - first).min(8);
        word[..available].copy_from_slice(&self.bytes[first..first + available]);
        let value = u64::from_le_bytes(word) >> (at % 8);
        Ok(value & ((1u64 << width) - 1))
    }

    /// Ones among the `count` bits at `at` (all inside the stream).
    fn ones(&self, at: u64, count: u64) -> Result<u64, FaceIdDefect> {
        let mut ones = 0;
        let mut done = 0;
        while done < count {
            let width = (count - done).min(32) as u32;
            ones += self.read(at + done, width)?.count_ones() as u64;
            done += width as u64;
        }
        Ok(ones)
    }
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

fn entry_header(stream: &BitStream, at: u64, group_base: u32) -> Result<EntryHeader, FaceIdDefect> {
    let base_width = stream.read(at, BASE_WIDTH_BITS)? as u32;
    let after_base_width = at + BASE_WIDTH_BITS as u64;
    let offset_width_at = after_base_width + base_width as u64;
    if base_width > 32 {
        return Err((at, format!("base width {base_width} is above 32")));
    }
    let smallest = group_base as u64 + stream.read(after_base_width, base_width)?;
    let offset_width = stream.read(offset_width_at, OFFSET_WIDTH_BITS)? as u32;
    if offset_width > 32 {
        return Err((
            offset_width_at,
            format!("offset width {offset_width} is above 32"),
        ));
    }
    let delta_width_at = offset_width_at + OFFSET_WIDTH_BITS as u64;
    let delta_width = stream.read(delta_width_at, DELTA_WIDTH_BITS)? as u32;
    Ok(EntryHeader {
        smallest,
        offset_width,
        delta_width,
        flags: delta_width_at + DELTA_WIDTH_BITS as u64,
    })
}

impl EntryHeader {
    /// The bit after the entry of a strip of `windows` windows.
    fn end(&self, stream: &BitStream, windows: u64) -> Result<u64, FaceIdDefect> {
        let offsets = stream.ones(self.flags, windows)?;
        Ok(self.flags
            + windows
            + offsets * self.offset_width as u64
            + (windows - offsets) * self.delta_width as u64)
    }

    /// Decodes the ids of windows `0..=last`, handing each to `visit`.
    fn decode(
        &self,
        stream: &BitStream,
        windows: u64,
        last: u64,
        visit: &mut dyn FnMut(u32),
    ) -> Result<(), FaceIdDefect> {
        let mut value_at = self.flags + windows;
        let mut id = self.smallest;
        for window in 0..=last {
            let flag_at = self.flags + window;
            let is_offset = stream.read(flag_at, 1)? == 1;
            if window == 0 && !is_offset {
                return Err((flag_at, "the first window's flag is not an offset".into()));
            }
            id = if is_offset {
                let offset = stream.read(value_at, self.offset_width)?;
                value_at += self.offset_width as u64;
                self.smallest + offset
            } else {
                let zigzag = stream.read(value_at, self.delta_width)?;
                value_at += self.delta_width as u64;
                let delta = (zigzag >> 1) as i64 ^ -((zigzag & 1) as i64);
                (id as i64).wrapping_add(delta) as u64
            };
            let Ok(id) = u32::try_from(id) else {
                return Err((value_at, format!("window {window}'s id {id} is not a u32")));
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
        return Err((at, format!("window {window} of a strip of {count} windows")));
    }
    let mut found = 0;
    header.decode(stream, count, window as u64, &mut |id| found = id)?;
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
        if windows > 0 {
            header.decode(stream, windows, windows - 1, &mut |id| visit(strip, id))?;
        }
        at = header.end(stream, windows)?;
    }
    Ok(at)
}

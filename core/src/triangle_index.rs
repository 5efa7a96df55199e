//! The position of a stored triangle in file order: strip after strip, window after window,
//! swap windows skipped — the order `reducem decode` writes triangles in, so a hit's
//! `(strip, window)` names a row of the decoded mesh.
//!
//! The file stores no per-strip triangle count (swap windows are only known by reading the
//! references), so [`TriangleIndex::new`] counts each strip's real triangles once, on every
//! core, and keeps the prefix sums: 8 bytes per strip. It pages in every strip's references,
//! which is why it is built on demand rather than at open.
//!
//! Files that store input face ids (format 2.5, [`ReducemFile::face_id`]) answer an
//! input-facing id directly; this index stays the position in the stored order.

use rayon::prelude::*;

use crate::format::reader::{ReducemFile, StripView};

/// The first stored triangle of every strip, in file order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TriangleIndex {
    /// `first[s]`: triangles stored before strip `s`; one more entry holds the total.
    first: Vec<u64>,
}

impl TriangleIndex {
    /// Counts the real triangles of every strip of `file` (in parallel).
    pub fn new(file: &ReducemFile) -> TriangleIndex {
        let counts: Vec<u64> = (0..file.strip_count())
            .into_par_iter()
            .map(|s| {
                let view = file.strip(s);
                real_triangles_before(&view, view.window_count())
            })
            .collect();
        let mut first = Vec::with_capacity(counts.len() + 1);
        let mut total = 0u64;
        first.push(total);
        for count in counts {
            total += count;
            first.push(total);
        }
        TriangleIndex { first }
    }

    /// Stored triangles in the file.
    pub fn total(&self) -> u64 {
        self.first.last().copied().unwrap_or(0)
    }

    /// The position in file order of the triangle of `window` of strip `strip` (a real
    /// triangle, as a hit's strip and window are); `None` when the strip does not exist.
    pub fn position(&self, file: &ReducemFile, strip: u32, window: u16) -> Option<u64> {
        let strip = strip as usize;
        let first = *self.first.get(strip)?;
        if strip >= file.strip_count() {
            return None;
        }
        let view = file.strip(strip);
        let window = (window as usize).min(view.window_count());
        Some(first + real_triangles_before(&view, window))
    }
}

/// Windows whose references are read in one call: unpacking them a window at a time read
/// each reference three times.
const WINDOWS_READ_AT_ONCE: usize = 64;

/// Real (non-swap) windows among the first `windows` windows of a strip.
fn real_triangles_before(view: &StripView, windows: usize) -> u64 {
    let mut references = [0u8; WINDOWS_READ_AT_ONCE + 2];
    let mut real = 0;
    let mut first = 0;
    while first < windows {
        let count = (windows - first).min(WINDOWS_READ_AT_ONCE);
        view.references
            .read_into(first, &mut references[..count + 2]);
        real += real_windows(&references, count);
        first += count;
    }
    real
}

/// Windows counted at once: a window's corners differ in the bytes of three u64 words.
const WORD_WINDOWS: usize = 8;
const LOW_BITS: u64 = 0x7f7f_7f7f_7f7f_7f7f;
const HIGH_BITS: u64 = 0x8080_8080_8080_8080;
const ONE_PER_BYTE: u64 = 0x0101_0101_0101_0101;
// The last word read starts two references past the last window counted at once.
const _: () = assert!(WINDOWS_READ_AT_ONCE.is_multiple_of(WORD_WINDOWS));

/// Windows among the first `count` of `references` whose three corners differ (a swap repeats
/// one, as `strip_windows::window_corners` decides), eight at a time in the bytes of a word
/// without branches, since every strip of the file is counted.
fn real_windows(references: &[u8; WINDOWS_READ_AT_ONCE + 2], count: usize) -> u64 {
    let word = |at: usize| {
        let mut bytes = [0u8; WORD_WINDOWS];
        bytes.copy_from_slice(&references[at..at + WORD_WINDOWS]);
        u64::from_le_bytes(bytes)
    };
    // The high bit of each byte of `x` that is not zero (no carry crosses a byte).
    let nonzero = |x: u64| ((x & LOW_BITS) + LOW_BITS) | x;
    let mut real = 0;
    for first in (0..count.min(WINDOWS_READ_AT_ONCE)).step_by(WORD_WINDOWS) {
        let (a, b, c) = (word(first), word(first + 1), word(first + 2));
        let windows = (count - first).min(WORD_WINDOWS);
        let in_range = HIGH_BITS & (u64::MAX >> (8 * (WORD_WINDOWS - windows)));
        let distinct = nonzero(a ^ b) & nonzero(b ^ c) & nonzero(a ^ c) & in_range;
        // A byte of 0 or 1 per window, summed into the top byte by one product.
        real += (distinct >> 7).wrapping_mul(ONE_PER_BYTE) >> 56;
    }
    real
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::strip_windows::window_corners;

    #[test]
    fn word_count_of_real_windows_is_the_filter_of_window_corners() {
        let mut seed = 7u64;
        for _ in 0..2000 {
            let mut references = [0u8; WINDOWS_READ_AT_ONCE + 2];
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
            let count = 1 + (seed >> 40) as usize % WINDOWS_READ_AT_ONCE;
            for reference in references.iter_mut() {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                *reference = (seed >> 61) as u8;
            }
            let filtered = references[..count + 2]
                .windows(3)
                .filter(|c| window_corners([c[0], c[1], c[2]], 0).is_some())
                .count();
            assert_eq!(real_windows(&references, count), filtered as u64);
        }
    }
}

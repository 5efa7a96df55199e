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

/// Real (non-swap) windows among the first `windows` windows of a strip.
fn real_triangles_before(view: &StripView, windows: usize) -> u64 {
    view.references.distinct_windows(windows) as u64
}

//! `primitive_ids` of hits in O(1): the input face id when the file stores face ids, else the
//! triangle's row in `decode` order. Rows are a strip's first row plus the real (non-swap)
//! windows before the hit's window, which a bit mask per strip counts with one popcount instead
//! of reading the strip's references on every hit.

use rayon::prelude::*;
use reducem_core::format::reader::{ReducemFile, StripView};
use reducem_core::strip_windows::window_corners;

/// `primitive_ids` of a miss, or of a triangle whose id is not known.
pub const NO_PRIMITIVE: u32 = u32::MAX;

/// Windows a strip's mask covers; a longer strip's later windows are counted by reading its
/// references.
const MASKED_WINDOWS: usize = u64::BITS as usize;

/// How a scene names the triangle a query answers with.
pub enum PrimitiveIds {
    /// The file's input face ids.
    Stored,
    /// Rows in `decode` order.
    Rows(Vec<StripRows>),
}

/// One strip's first row and which of its first 64 windows are real triangles.
#[derive(Clone, Copy)]
pub struct StripRows {
    first: u64,
    real: u64,
}

impl PrimitiveIds {
    /// The naming `file` supports; reads every strip's references (in parallel) when it has no
    /// face ids.
    pub fn of(file: &ReducemFile) -> PrimitiveIds {
        if file.attributes().face_ids {
            return PrimitiveIds::Stored;
        }
        let mut strips: Vec<(u64, u64)> = (0..file.strip_count())
            .into_par_iter()
            .map(|s| real_windows(&file.strip(s)))
            .collect();
        let mut rows = 0u64;
        for (count, _) in &mut strips {
            let first = rows;
            rows += *count;
            *count = first;
        }
        let rows = strips
            .into_iter()
            .map(|(first, real)| StripRows { first, real })
            .collect();
        PrimitiveIds::Rows(rows)
    }

    /// The id of `window` of strip `strip`; [`NO_PRIMITIVE`] when it does not fit in a u32 or
    /// its stored id is corrupt (kept for [`ReducemFile::defect`]).
    pub fn id(&self, file: &ReducemFile, strip: u32, window: u16) -> u32 {
        let PrimitiveIds::Rows(rows) = self else {
            return file
                .face_id(strip as usize, window as usize)
                .unwrap_or(NO_PRIMITIVE);
        };
        let Some(strip_rows) = rows.get(strip as usize) else {
            return NO_PRIMITIVE;
        };
        let window = window as usize;
        let masked = window.min(MASKED_WINDOWS);
        let below = match masked {
            MASKED_WINDOWS => u64::MAX,
            _ => (1u64 << masked) - 1,
        };
        let mut row = strip_rows.first + u64::from((strip_rows.real & below).count_ones());
        if window > MASKED_WINDOWS {
            let view = file.strip(strip as usize);
            row += count_real(&view, MASKED_WINDOWS..window.min(view.window_count()));
        }
        u32::try_from(row).unwrap_or(NO_PRIMITIVE)
    }
}

/// A strip's real triangles, and the mask of its first 64 windows that are real.
fn real_windows(view: &StripView) -> (u64, u64) {
    let windows = view.window_count();
    let mut corners = [0u8; 3];
    let mut real = 0u64;
    for k in 0..windows.min(MASKED_WINDOWS) {
        view.references.read_into(k, &mut corners);
        if window_corners(corners, k).is_some() {
            real |= 1 << k;
        }
    }
    let beyond = count_real(view, MASKED_WINDOWS.min(windows)..windows);
    (u64::from(real.count_ones()) + beyond, real)
}

fn count_real(view: &StripView, windows: std::ops::Range<usize>) -> u64 {
    let mut corners = [0u8; 3];
    windows
        .filter(|&k| {
            view.references.read_into(k, &mut corners);
            window_corners(corners, k).is_some()
        })
        .count() as u64
}

//! The closest hit a traversal has found so far, shared by the walks and the kernels.

use super::prepared::FAR_INFLATION;
use crate::format::vertices::VertexAccess;
use crate::geometry::Point;

/// The closest hit so far, with its weights and corners in strip order (`s[k], s[k+1], s[k+2]`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Closest {
    /// Hits are accepted in `[tmin, t]`: `tmax` until one is found, then the closest one's `t`.
    pub t: f32,
    /// `t * FAR_INFLATION`: traversal enters nodes whose entry distance is at most this. A
    /// triangle's `t` is rounded on its own and may lie a few ulps before the computed entry
    /// distance of the boxes around it (say, on a vertex in a box's entry face); culling with
    /// `t` itself would then miss a hit at the very end of the closed interval, e.g. with
    /// `tmin = tmax` at the hit. Exit distances carry the same inflation for the `tmin` end.
    pub reach: f32,
    pub strip: u32,
    pub window: u16,
    pub weights: [f32; 3],
    /// The window's model-space corners, read when the hit is accepted from the vertices the
    /// traversal has at hand, so that finishing the hit (its normal) needs no second view of
    /// the strip.
    pub corners: [Point; 3],
}

impl Closest {
    /// No hit yet: accepts anything up to `tmax`.
    pub fn none(tmax: f32) -> Closest {
        Closest {
            t: tmax,
            reach: tmax * FAR_INFLATION,
            strip: u32::MAX,
            window: u16::MAX,
            weights: [0.0; 3],
            corners: [[0.0; 3]; 3],
        }
    }

    pub fn found(&self) -> bool {
        self.strip != u32::MAX
    }

    /// Keeps `(t, strip, window)` if it is lexicographically smaller than the current hit,
    /// reading its corners (strip references `corners`) from `vertices` only then: a ray may
    /// be offered several hits. Out of line, so that the rare accepted hit does not weigh on
    /// the code of the block loop around it.
    #[inline(never)]
    pub fn offer<V: VertexAccess>(
        &mut self,
        t: f32,
        (strip, window): (u32, u16),
        weights: [f32; 3],
        (vertices, [a, b, c]): (V, [u8; 3]),
    ) {
        if t < self.t || (strip, window) < (self.strip, self.window) {
            *self = Closest {
                t,
                reach: t * FAR_INFLATION,
                strip,
                window,
                weights,
                // Not `map`: its closure stayed a call per corner for grid vertices.
                corners: [
                    vertices.point(a as usize),
                    vertices.point(b as usize),
                    vertices.point(c as usize),
                ],
            };
        }
    }
}

//! Traversal of one strip's implicit kd-tree and intersection of its windows (paper 3.2,
//! "Traversal and intersection"), read in place from the mapping.
//!
//! The traversal is that of a bounding interval hierarchy (the paper: "virtually same as that of
//! s-kd-trees"): a node is an interval `[lo, hi)` of windows and a parameter interval
//! `[t_near, t_far]`. Internal node `i` on axis `a` clips the ray to `coordinate_a <= L` for the
//! left child and `coordinate_a >= R` for the right one, with `L = vertices[2i][a]`,
//! `R = vertices[2i+1][a]`; the two slabs may overlap or leave a gap, so the ray may enter both
//! children, one, or neither. The near child (by the sign of the direction on `a`) is entered
//! first and the far one deferred on a small stack; a deferred node is dropped when the closest
//! hit found since is nearer than its entry.
//!
//! An interval of at most [`TraceOptions::subtree_windows`](super::TraceOptions) windows, or a
//! leaf, is intersected at once (the paper's "external parameter"). The intersector transforms
//! each strip position of the interval to ray space once and evaluates every strip edge once:
//! window `k` uses the short edges `(s[k], s[k+1])`, `(s[k+1], s[k+2])` and the long edge
//! `(s[k], s[k+2])`, and shares its second short edge with window `k + 1`, so a strip costs about
//! two edge functions per triangle instead of three.
//!
//! Determinism: among hits at the same parameter the one with the smallest (strip, window) wins,
//! and culling compares inclusively, so ties resolve the same way whatever the visiting order.

use super::prepared::{PreparedRay, FAR_INFLATION};
use super::watertight::{edge, resolve, RayPoint};
use crate::format::implicit_tree::{is_leaf, right_child, split_point};
use crate::format::reader::StripView;

/// Most windows intersected in one batch; bounds the per-batch stack arrays.
pub const MAX_BATCH_WINDOWS: usize = 32;

/// Deepest strip kd-tree: intervals halve, and a strip has fewer than 2^16 windows.
const STRIP_STACK: usize = 20;

/// The closest hit so far, with its weights in strip order (corners `s[k], s[k+1], s[k+2]`).
#[derive(Clone, Copy, Debug)]
pub struct Closest {
    pub t: f32,
    pub strip: u32,
    pub window: u16,
    pub weights: [f32; 3],
}

impl Closest {
    /// No hit yet: accepts anything up to `tmax`.
    pub fn none(tmax: f32) -> Closest {
        Closest {
            t: tmax,
            strip: u32::MAX,
            window: u16::MAX,
            weights: [0.0; 3],
        }
    }

    pub fn found(&self) -> bool {
        self.strip != u32::MAX
    }

    /// Keeps `(t, strip, window)` if it is lexicographically smaller than the current hit.
    #[inline]
    fn offer(&mut self, t: f32, strip: u32, window: u16, weights: [f32; 3]) {
        if t < self.t || (strip, window) < (self.strip, self.window) {
            *self = Closest {
                t,
                strip,
                window,
                weights,
            };
        }
    }
}

/// `node` if the ray's interval in it is non-empty and not beyond the closest hit.
#[inline(always)]
fn enters(node: Pending, closest_t: f32) -> Option<Pending> {
    (node.t_near <= node.t_far && node.t_near <= closest_t).then_some(node)
}

/// What one strip traversal looks for.
pub struct StripQuery<'a> {
    pub ray: &'a PreparedRay,
    /// The file's strip kd-tree leaf size (it defines the tree's shape).
    pub leaf_windows: usize,
    pub subtree_windows: usize,
    /// Stop at the first hit in range (shadow and occlusion rays).
    pub any_hit: bool,
}

#[derive(Clone, Copy, Default)]
struct Pending {
    node: u32,
    lo: u32,
    hi: u32,
    t_near: f32,
    t_far: f32,
}

impl StripQuery<'_> {
    /// Traverses strip `index` within `[t_near, t_far]`, updating `closest`. Returns true when
    /// `any_hit` is set and a hit was found.
    pub fn trace(
        &self,
        view: &StripView,
        index: u32,
        t_near: f32,
        t_far: f32,
        closest: &mut Closest,
    ) -> bool {
        let mut stack = [Pending::default(); STRIP_STACK];
        let mut depth = 0;
        let mut current = Pending {
            node: 0,
            lo: 0,
            hi: view.window_count() as u32,
            t_near,
            t_far,
        };
        loop {
            let (lo, hi) = (current.lo as usize, current.hi as usize);
            if hi - lo <= self.subtree_windows || is_leaf(lo, hi, self.leaf_windows) {
                if self.intersect(view, index, lo, hi, closest) && self.any_hit {
                    return true;
                }
            } else {
                let (near, far) = self.children(view, &current, closest.t);
                match (near, far) {
                    (Some(near), Some(far)) => {
                        stack[depth] = far;
                        depth += 1;
                        current = near;
                        continue;
                    }
                    (Some(only), None) | (None, Some(only)) => {
                        current = only;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            loop {
                if depth == 0 {
                    return false;
                }
                depth -= 1;
                if stack[depth].t_near <= closest.t {
                    current = stack[depth];
                    break;
                }
            }
        }
    }

    /// The children of an internal node the ray enters, near one first.
    #[inline(always)]
    fn children(
        &self,
        view: &StripView,
        node: &Pending,
        closest_t: f32,
    ) -> (Option<Pending>, Option<Pending>) {
        let (index, lo, hi) = (node.node as usize, node.lo as usize, node.hi as usize);
        let mid = split_point(lo, hi, self.leaf_windows);
        let axis = view.axis(index);
        let ray = self.ray;
        let left_max = ray.plane_distance(axis, view.vertices[2 * index][axis]);
        let right_min = ray.plane_distance(axis, view.vertices[2 * index + 1][axis]);
        let left = Pending {
            node: node.node + 1,
            lo: node.lo,
            hi: mid as u32,
            ..*node
        };
        let right = Pending {
            node: right_child(index, lo, mid, self.leaf_windows) as u32,
            lo: mid as u32,
            hi: node.hi,
            ..*node
        };
        let (near, near_exit, far, far_entry) = if ray.negative[axis] {
            (right, right_min, left, left_max)
        } else {
            (left, left_max, right, right_min)
        };
        let near = Pending {
            t_far: near.t_far.min(near_exit * FAR_INFLATION),
            ..near
        };
        let far = Pending {
            t_near: far.t_near.max(far_entry),
            ..far
        };
        (enters(near, closest_t), enters(far, closest_t))
    }

    /// Intersects windows `[lo, hi)` in batches of at most [`MAX_BATCH_WINDOWS`].
    fn intersect(
        &self,
        view: &StripView,
        index: u32,
        lo: usize,
        hi: usize,
        closest: &mut Closest,
    ) -> bool {
        let mut start = lo;
        while start < hi {
            let end = hi.min(start + MAX_BATCH_WINDOWS);
            if self.intersect_batch(view, index, start, end, closest) && self.any_hit {
                return true;
            }
            start = end;
        }
        false
    }

    /// Transforms positions `lo .. hi + 2` once, then tests each window with the shared edges.
    #[inline(always)]
    fn intersect_batch(
        &self,
        view: &StripView,
        index: u32,
        lo: usize,
        hi: usize,
        closest: &mut Closest,
    ) -> bool {
        let references = &view.references[lo..hi + 2];
        let mut points = [RayPoint::default(); MAX_BATCH_WINDOWS + 2];
        for (point, &reference) in points.iter_mut().zip(references) {
            *point = self.ray.space.transform(&view.vertices[reference as usize]);
        }
        let mut leading_edge = edge(&points[0], &points[1]);
        let mut found = false;
        for k in 0..hi - lo {
            let trailing_edge = edge(&points[k + 1], &points[k + 2]);
            let [a, b, c] = [references[k], references[k + 1], references[k + 2]];
            if a != b && b != c && a != c {
                let corners = [points[k], points[k + 1], points[k + 2]];
                let weights = [
                    trailing_edge,
                    edge(&points[k + 2], &points[k]),
                    leading_edge,
                ];
                if let Some(hit) = resolve(&corners, weights, self.ray.tmin, closest.t) {
                    closest.offer(hit.t, index, (lo + k) as u16, hit.weights);
                    found = true;
                    if self.any_hit {
                        return true;
                    }
                }
            }
            leading_edge = trailing_edge;
        }
        found
    }
}

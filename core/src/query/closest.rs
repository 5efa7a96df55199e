//! The closest point of the surface to a query point: a best-first walk over the top-level
//! hierarchy (nodes and leaves in a heap ordered by the squared distance from the point to
//! their boxes), then the blocks of a leaf's strips nearest first (by their block boxes, or the
//! leaf's box for a strip without them), and in a block entered each window whose own box may
//! beat the best tested exactly ([`closest_on_triangle`]).
//!
//! Exactness: a box's bound is computed in f64 and then lowered by a relative margin larger
//! than its rounding error ([`BOUND_SHRINK`]), so it is never above the true distance from the
//! point to the box, hence to any triangle in it: the walk skips a box only when every triangle
//! in it is truly farther than the best distance found. Boxes are those the file stores (node
//! boxes decoded from the node grid, block boxes from their codes); both bound their decoded
//! triangles by the format's rules.
//!
//! Determinism: among triangles at the same computed distance the smallest `(strip, window)`
//! wins, and a box at exactly the best distance is still entered, so the answer does not depend
//! on the visiting order.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::child_box::ChildBox;
use super::triangle_distance::{closest_on_triangle, TrianglePoint};
use crate::format::block_boxes::BOX_WINDOWS;
use crate::format::reader::{ReducemFile, StripView, TopNodes};
use crate::format::vertices::{StripVertices, VertexAccess};
use crate::format::{TopSlot, INTERNAL_CHILD, TOP_WIDTH};
use crate::geometry::Point;
use crate::strip_windows::window_corners;

/// The factor that lowers a box's squared distance below its f64 rounding: a subtraction, three
/// squares and two sums, each rounded by at most 2^-53 relative, stay within 2^-50.
const BOUND_SHRINK: f64 = 1.0 - 1.0 / (1u64 << 48) as f64;

/// The closest point of the surface to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// The distance from the query point, computed in f64 and rounded to f32.
    pub distance: f32,
    /// The closest point, on the triangle of `(strip, window)` (rounded to f32).
    pub point: Point,
    pub strip: u32,
    pub window: u16,
    /// Barycentric weights of the triangle's second and third corners in input winding:
    /// `point = (1 - u - v) a + u b + v c`.
    pub u: f32,
    pub v: f32,
}

/// Searches one file for closest points, keeping its heap between queries (one per thread).
pub struct ClosestPointSearch<'f> {
    file: &'f ReducemFile,
    pending: BinaryHeap<Reverse<Pending>>,
    spans: Vec<Span<'f>>,
}

/// A query point, and in f64 for the bounds.
struct Query {
    point: Point,
    wide: [f64; 3],
}

/// A node or leaf waiting in the heap: the bits of its box's squared-distance bound (ordered
/// as the f64 they are: a sum of squares is never negative, nor -0.0), then its link as a node
/// slot holds it.
type Pending = (u64, u32, u32);

/// The best triangle so far and the squared distance a triangle must not exceed to beat it.
struct Best {
    limit: f64,
    found: Option<(u32, u16, TrianglePoint)>,
}

impl Best {
    /// Keeps `candidate` when it is nearer, or as near with a smaller `(strip, window)`.
    fn offer(&mut self, strip: u32, window: u16, candidate: TrianglePoint) {
        let distance = candidate.distance_squared;
        let first_key = self.found.is_none_or(|(s, w, _)| (strip, window) < (s, w));
        if distance < self.limit || (distance == self.limit && first_key) {
            self.limit = distance;
            self.found = Some((strip, window, candidate));
        }
    }
}

impl<'f> ClosestPointSearch<'f> {
    pub fn new(file: &'f ReducemFile) -> ClosestPointSearch<'f> {
        ClosestPointSearch {
            file,
            pending: BinaryHeap::new(),
            spans: Vec::new(),
        }
    }

    /// The closest point of the surface to `point` at a distance of at most `max_distance`
    /// (`f32::INFINITY` for no limit); `None` when no triangle lies that near. On a lazily
    /// opened file, a corrupt node or strip reached is skipped and kept for
    /// [`ReducemFile::defect`], as in tracing.
    pub fn closest(&mut self, point: &Point, max_distance: f32) -> Option<ClosestPoint> {
        let max = f64::from(max_distance);
        let mut best = Best {
            limit: max * max,
            found: None,
        };
        match self.file.top_nodes() {
            TopNodes::F32(nodes) => self.walk(nodes, &(), point, &mut best),
            TopNodes::Grid(nodes, grid) => self.walk(nodes, &grid, point, &mut best),
        }
        let (strip, window, found) = best.found?;
        Some(ClosestPoint {
            distance: found.distance_squared.sqrt() as f32,
            point: found.point.map(|x| x as f32),
            strip,
            window,
            u: found.u as f32,
            v: found.v as f32,
        })
    }

    fn walk<N: ChildBox>(&mut self, nodes: &[N], grid: &N::Grid, point: &Point, best: &mut Best) {
        let query = Query {
            point: *point,
            wide: point.map(f64::from),
        };
        self.pending.clear();
        self.pending.push(Reverse((0, 0, INTERNAL_CHILD)));
        while let Some(Reverse((bound, child, kind))) = self.pending.pop() {
            let bound = f64::from_bits(bound);
            if bound > best.limit {
                break;
            }
            if kind != INTERNAL_CHILD {
                self.search_leaf((child, kind), bound, &query, best);
                continue;
            }
            let Some(node) = self.file.top_node(nodes, child as usize) else {
                continue;
            };
            for slot in 0..TOP_WIDTH {
                let link = match node.slot(slot) {
                    TopSlot::Internal(index) => (index, INTERNAL_CHILD),
                    TopSlot::Leaf { first, count } => (first, count),
                    TopSlot::Empty | TopSlot::Invalid(_) => continue,
                };
                let (min, max) = node.child_box(slot, grid);
                let bound = box_bound(&query.wide, &min, &max);
                if bound <= best.limit {
                    self.pending
                        .push(Reverse((bound.to_bits(), link.0, link.1)));
                }
            }
        }
    }
}

/// Windows of one strip that a leaf's search tests together: a block with its box's bound, or
/// a whole strip without block boxes with its leaf's.
#[derive(Clone, Copy)]
struct Span<'f> {
    bound: f64,
    view: StripView<'f>,
    strip: u32,
    windows: (usize, usize),
}

impl<'f> ClosestPointSearch<'f> {
    /// Tests the windows of the leaf's strips (`first .. first + count`, the leaf's box at
    /// `leaf_bound`) that may beat `best`: the blocks of every strip nearest first, so that the
    /// limit shrinks early and farther blocks are skipped.
    fn search_leaf(
        &mut self,
        (first, count): (u32, u32),
        leaf_bound: f64,
        query: &Query,
        best: &mut Best,
    ) {
        self.spans.clear();
        for strip in first..first.saturating_add(count) {
            let view = self.file.strip(strip as usize);
            push_spans(&mut self.spans, view, strip, leaf_bound, query);
        }
        self.spans
            .sort_unstable_by(|a, b| a.bound.total_cmp(&b.bound));
        for span in &self.spans {
            if span.bound > best.limit {
                break;
            }
            // The one branch on the vertex encoding, per span.
            match span.view.vertices {
                StripVertices::F32(vertices) => search_windows(vertices, span, query, best),
                StripVertices::Grid(vertices) => search_windows(vertices, span, query, best),
            }
        }
    }
}

/// The spans of strip `strip`: one per block box when it stores them, else the whole strip at
/// its leaf's bound.
fn push_spans<'f>(
    spans: &mut Vec<Span<'f>>,
    view: StripView<'f>,
    strip: u32,
    leaf_bound: f64,
    query: &Query,
) {
    let windows = view.window_count();
    let frame = match view.boxes.is_empty() {
        true => None,
        false => view.boxes.frame(view.vertices.point(0)),
    };
    let Some(frame) = frame else {
        spans.push(Span {
            bound: leaf_bound,
            view,
            strip,
            windows: (0, windows),
        });
        return;
    };
    for block in 0..view.boxes.count() {
        let Some((min, max)) = view.boxes.decode(&frame, block) else {
            break;
        };
        let first = block * BOX_WINDOWS;
        spans.push(Span {
            bound: box_bound(&query.wide, &min, &max),
            view,
            strip,
            windows: (first, (first + BOX_WINDOWS).min(windows)),
        });
    }
}

/// Tests the span's windows whose own box may beat `best` exactly.
fn search_windows<V: VertexAccess>(vertices: V, span: &Span, query: &Query, best: &mut Best) {
    let mut references = [0u8; 3];
    for window in span.windows.0..span.windows.1 {
        span.view.references.read_into(window, &mut references);
        let Some(corners) = window_corners(references, window) else {
            continue;
        };
        let corners = corners.map(|r| vertices.point(r as usize));
        if triangle_bound(&query.wide, &corners) <= best.limit {
            let found = closest_on_triangle(&query.point, &corners);
            best.offer(span.strip, window as u16, found);
        }
    }
}

/// [`box_bound`] of the triangle's own box: a few comparisons that spare the exact test of
/// most triangles of a block the search enters.
fn triangle_bound(query: &[f64; 3], [a, b, c]: &[Point; 3]) -> f64 {
    let min = std::array::from_fn(|axis| a[axis].min(b[axis]).min(c[axis]));
    let max = std::array::from_fn(|axis| a[axis].max(b[axis]).max(c[axis]));
    box_bound(query, &min, &max)
}

/// A lower bound of the squared distance from `query` to the box `min..max`, never above the
/// true one ([`BOUND_SHRINK`]). A NaN plane (only in a corrupt box) counts as no gap.
fn box_bound(query: &[f64; 3], min: &Point, max: &Point) -> f64 {
    let gap = |axis: usize| {
        let below = f64::from(min[axis]) - query[axis];
        let above = query[axis] - f64::from(max[axis]);
        below.max(above).max(0.0)
    };
    let squared = (0..3).map(|axis| gap(axis) * gap(axis)).sum::<f64>();
    squared * BOUND_SHRINK
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_bounds_are_zero_inside_and_below_the_distance_outside() {
        let (min, max) = ([0.0, 0.0, 0.0], [1.0, 2.0, 3.0]);
        assert_eq!(box_bound(&[0.5, 1.0, 1.0], &min, &max), 0.0);
        let bound = box_bound(&[4.0, -4.0, 3.0], &min, &max);
        assert!(bound < 25.0 && bound > 25.0 * (1.0 - 1e-14));
        let nan = [f32::NAN; 3];
        assert_eq!(box_bound(&[9.0, 9.0, 9.0], &nan, &nan), 0.0);
    }

    #[test]
    fn ties_go_to_the_smallest_strip_and_window() {
        let at = |d: f64| TrianglePoint {
            distance_squared: d,
            u: 0.0,
            v: 0.0,
            point: [0.0; 3],
        };
        let mut best = Best {
            limit: 4.0,
            found: None,
        };
        best.offer(3, 1, at(4.0));
        best.offer(2, 5, at(4.0));
        best.offer(2, 7, at(4.0));
        assert_eq!(best.found.map(|(s, w, _)| (s, w)), Some((2, 5)));
        best.offer(9, 0, at(1.0));
        best.offer(9, 1, at(1.5));
        assert_eq!(best.found.map(|(s, w, _)| (s, w)), Some((9, 0)));
        best.offer(0, 0, at(4.5));
        assert_eq!(best.limit, 1.0);
    }
}

//! The closest point of the surface to a query point: a depth-first walk over the top-level
//! hierarchy (of a node's children that may beat the best, the nearest by the squared distance
//! from the point to their boxes entered first, the others kept on a stack), then the blocks of
//! a leaf's strips nearest first (by their block boxes, or the leaf's box for a strip without
//! them), and in a block entered each window whose own box may beat the best tested exactly
//! ([`closest_on_triangle`]). Box bounds of a node's children and of a block's windows are
//! computed together by the kernel in `distance_bounds`.
//!
//! Exactness: a box's bound is computed in f64 and then lowered by a relative margin larger
//! than its rounding error (`BOUND_SHRINK`), so it is never above the true distance from the
//! point to the box, hence to any triangle in it: the walk skips a box only when every triangle
//! in it is truly farther than the best distance found. Boxes are those the file stores (node
//! boxes decoded from the node grid, block boxes from their codes); both bound their decoded
//! triangles by the format's rules.
//!
//! Determinism: among triangles at the same computed distance the smallest `(strip, window)`
//! wins, and a box at exactly the best distance is still entered, so the answer does not depend
//! on the visiting order.

use arrayvec::ArrayVec;

use super::child_box::ChildBox;
use super::crossing_walk::{block_boxes, box_frame, BOX_LANES};
use super::top_walk::{dispatch_top_walk, QueryNode, TopWalk};
use super::triangle_distance::{closest_on_triangle, TrianglePoint};
use crate::format::block_boxes::BOX_WINDOWS;
use crate::format::reader::{ReducemFile, StripView};
use crate::format::vertices::{StripVertices, VertexAccess};
use crate::format::{TopSlot, INTERNAL_CHILD, TOP_WIDTH, WIDE_WIDTH};
use crate::geometry::Point;
use crate::strip_windows::window_corners;
use crate::trace::kernel::distance_bounds::BlockCorners;
use crate::trace::kernel::query_kernel::QueryKernel;
use crate::trace::kernel::query_prefetch::{ChildPrefetch, QuerySections};
use crate::trace::kernel::triangle_lanes::{CornerLanes, TRIANGLE_LANES};
use crate::trace::kernel::Kernel;

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
    sections: QuerySections<'f>,
    kernel: Kernel,
    pending: Vec<Pending>,
    spans: Vec<Span>,
    views: Vec<StripView<'f>>,
    /// The closest point found for the previous query, a point of the surface: its distance
    /// bounds the next query's (points come in spatial order), so that the first descent
    /// already skips far boxes.
    previous: Option<[f64; 3]>,
}

/// A query point, and in f64 for the bounds.
struct Query {
    point: Point,
    wide: [f64; 3],
}

/// A node or leaf waiting on the stack: its box's squared-distance bound, then its link as a
/// node slot holds it.
type Pending = (f64, (u32, u32));

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
    /// A search on [`Kernel::configured`].
    pub fn new(file: &'f ReducemFile) -> ClosestPointSearch<'f> {
        ClosestPointSearch::with_kernel(file, Kernel::configured())
    }

    /// A search whose box bounds run on `kernel` (every kernel gives the same answers); a
    /// kernel this CPU lacks runs as the portable one.
    pub fn with_kernel(file: &'f ReducemFile, kernel: Kernel) -> ClosestPointSearch<'f> {
        ClosestPointSearch {
            file,
            sections: QuerySections::new(file),
            kernel,
            pending: Vec::new(),
            spans: Vec::new(),
            views: Vec::new(),
            previous: None,
        }
    }

    /// The closest point of the surface to `point` at a distance of at most `max_distance`
    /// (`f32::INFINITY` for no limit); `None` when no triangle lies that near. On a lazily
    /// opened file, a corrupt node or strip reached is skipped and kept for
    /// [`ReducemFile::defect`], as in tracing.
    pub fn closest(&mut self, point: &Point, max_distance: f32) -> Option<ClosestPoint> {
        let max = f64::from(max_distance);
        let mut best = Best {
            limit: (max * max).min(self.previous_bound(point)),
            found: None,
        };
        dispatch_top_walk(
            self.kernel,
            self.file,
            Search {
                search: self,
                point,
                best: &mut best,
            },
        );
        self.previous = best.found.map(|(_, _, found)| found.point);
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

    /// A squared distance at least that of `point`'s closest triangle as computed: the
    /// distance to the previous query's closest point (which lies on a triangle up to f64
    /// rounding), grown far beyond the roundings of both computations; infinite without one.
    fn previous_bound(&self, point: &Point) -> f64 {
        let Some(previous) = self.previous else {
            return f64::INFINITY;
        };
        let wide = point.map(f64::from);
        let squared: f64 = (0..3).map(|k| (wide[k] - previous[k]).powi(2)).sum();
        let scale = (0..3).fold(0.0f64, |m, k| m.max(wide[k].abs()).max(previous[k].abs()));
        let reach = squared.sqrt() * (1.0 + PREVIOUS_MARGIN) + scale * PREVIOUS_MARGIN;
        match reach.is_finite() {
            true => reach * reach,
            false => f64::INFINITY,
        }
    }

    /// Depth-first over the top level, a node's nearest child entered at once and its others
    /// stacked farthest first. Not best-first: the previous point's bound makes the limit tight
    /// from the start, so the order hardly changes what is visited, and a stack costs less than
    /// a heap; the answer does not depend on the order (see the module's notes).
    #[inline(always)]
    fn walk<N: ChildBox, Q: QueryKernel>(
        &mut self,
        nodes: &[N],
        grid: &N::Grid,
        point: &Point,
        best: &mut Best,
    ) {
        let query = Query {
            point: *point,
            wide: point.map(f64::from),
        };
        let prefetch = ChildPrefetch::new(&self.sections, nodes);
        self.pending.clear();
        let mut next = Some((0.0, (0, INTERNAL_CHILD)));
        loop {
            let (bound, (child, kind)) = match next.take() {
                Some(entered) => entered,
                None => match self.pending.pop() {
                    Some(pending) => pending,
                    None => break,
                },
            };
            if bound > best.limit {
                continue;
            }
            if kind != INTERNAL_CHILD {
                self.search_leaf::<Q>((child, kind), bound, &query, best);
                continue;
            }
            if let Some(node) = self.file.top_node(nodes, child as usize) {
                next = self.push_children::<N, Q>(node, grid, &query, best.limit, &prefetch);
            }
        }
    }

    /// Stacks the children of `node` whose bound does not exceed `limit`, the farthest lowest,
    /// but for the nearest, returned with its bound; each is asked for from memory before the
    /// walk reaches it.
    #[inline(always)]
    fn push_children<N: ChildBox, Q: QueryKernel>(
        &mut self,
        node: &N,
        grid: &N::Grid,
        query: &Query,
        limit: f64,
        prefetch: &ChildPrefetch<N>,
    ) -> Option<(f64, (u32, u32))> {
        // A plain array shifted in place: `ArrayVec::insert`'s checks and move cost more than
        // the few comparisons of an insertion among at most eight.
        let mut children: [Pending; WIDE_WIDTH] = [(0.0, (0, 0)); WIDE_WIDTH];
        let mut count = 0;
        let groups = node.child_boxes::<Q>(grid);
        for (group, (min, max)) in groups.as_ref().iter().enumerate() {
            if node.slot(group * TOP_WIDTH) == TopSlot::Empty {
                break;
            }
            let bounds = Q::child_bounds(&query.wide, min, max);
            for (lane, &bound) in bounds.iter().enumerate() {
                let link = match node.slot(group * TOP_WIDTH + lane) {
                    TopSlot::Internal(index) => (index, INTERNAL_CHILD),
                    TopSlot::Leaf { first, count } => (first, count),
                    TopSlot::Empty | TopSlot::Invalid(_) => continue,
                };
                if bound > limit {
                    continue;
                }
                prefetch.child(link);
                // Insertion by falling bound: a node has at most eight children.
                let mut at = count;
                while at > 0 && children[at - 1].0 < bound {
                    children[at] = children[at - 1];
                    at -= 1;
                }
                children[at] = (bound, link);
                count += 1;
            }
        }
        let (nearest, farther) = children[..count].split_last()?;
        self.pending.extend_from_slice(farther);
        Some(*nearest)
    }
}

/// [`ClosestPointSearch::closest`]'s walk of one point, for [`dispatch_top_walk`].
struct Search<'s, 'f> {
    search: &'s mut ClosestPointSearch<'f>,
    point: &'s Point,
    best: &'s mut Best,
}

impl TopWalk for Search<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run<Q: QueryKernel, N: QueryNode>(self, nodes: &[N], grid: &N::Grid) {
        let Search {
            search,
            point,
            best,
        } = self;
        search.walk::<_, Q>(nodes, grid, point, best)
    }
}

/// Relative growth of the previous closest point's distance ([`ClosestPointSearch::closest`]):
/// far above f64 roundings, far below any distance that matters for pruning.
const PREVIOUS_MARGIN: f64 = 1.0 / (1u64 << 30) as f64;

/// Windows of one strip that a leaf's search tests together: a block with its box's bound, or
/// a whole strip without block boxes with its leaf's. Small, for the sort: the strip's view is
/// `view` in the search's views.
#[derive(Clone, Copy)]
struct Span {
    bound: f64,
    strip: u32,
    view: u32,
    windows: (usize, usize),
}

impl<'f> ClosestPointSearch<'f> {
    /// Tests the windows of the leaf's strips (`first .. first + count`, the leaf's box at
    /// `leaf_bound`) that may beat `best`: the blocks of every strip nearest first, so that the
    /// limit shrinks early and farther blocks are skipped.
    #[inline(always)]
    fn search_leaf<Q: QueryKernel>(
        &mut self,
        (first, count): (u32, u32),
        leaf_bound: f64,
        query: &Query,
        best: &mut Best,
    ) {
        self.spans.clear();
        self.views.clear();
        for strip in first..first.saturating_add(count) {
            let view = self.file.strip(strip as usize);
            let at = (strip, self.views.len() as u32);
            push_spans::<Q>(&mut self.spans, &view, at, leaf_bound, query, best.limit);
            self.views.push(view);
        }
        self.spans
            .sort_unstable_by(|a, b| a.bound.total_cmp(&b.bound));
        for span in &self.spans {
            if span.bound > best.limit {
                break;
            }
            let view = &self.views[span.view as usize];
            // The one branch on the vertex encoding, per span.
            match view.vertices {
                StripVertices::F32(vertices) => {
                    search_windows::<_, Q>(vertices, view, span, query, best)
                }
                StripVertices::Grid(vertices) => {
                    search_windows::<_, Q>(vertices, view, span, query, best)
                }
            }
        }
    }
}

/// The spans of strip `strip` (view `view`) that may beat `limit`: one per block box when it stores
/// them (bounded four at a time, each as `distance_bounds::box_bound` bounds it; up to the first
/// box that cannot be read), else the whole strip at its leaf's bound.
#[inline(always)]
fn push_spans<Q: QueryKernel>(
    spans: &mut Vec<Span>,
    strip_view: &StripView,
    (strip, view): (u32, u32),
    leaf_bound: f64,
    query: &Query,
    limit: f64,
) {
    let windows = strip_view.window_count();
    let boxes = &strip_view.boxes;
    let frame = match boxes.is_empty() {
        true => None,
        false => box_frame(strip_view),
    };
    let Some(frame) = frame else {
        spans.push(Span {
            bound: leaf_bound,
            strip,
            view,
            windows: (0, windows),
        });
        return;
    };
    let blocks = boxes.count();
    // Plain loops here and over a span's blocks: a `step_by` range's set-up costs as much as
    // the one or two passes a strip takes.
    let mut first = 0;
    while first < blocks {
        let lanes = (blocks - first).min(BOX_LANES);
        let ((min, max), unreadable) = block_boxes(boxes, &frame, first, lanes);
        let bounds = Q::child_bounds(&query.wide, &min, &max);
        for (lane, &bound) in bounds.iter().enumerate().take(lanes) {
            if unreadable >> lane & 1 != 0 {
                return;
            }
            let first_window = (first + lane) * BOX_WINDOWS;
            if bound <= limit {
                spans.push(Span {
                    bound,
                    strip,
                    view,
                    windows: (first_window, (first_window + BOX_WINDOWS).min(windows)),
                });
            }
        }
        first += BOX_LANES;
    }
}

/// Tests the span's windows whose own box may beat `best` exactly, a block of windows at a
/// time: its references and vertices read once, its windows' box bounds computed together, and
/// its candidates' exact distances four at a time in lanes.
#[inline(always)]
fn search_windows<V: VertexAccess, Q: QueryKernel>(
    vertices: V,
    view: &StripView,
    span: &Span,
    query: &Query,
    best: &mut Best,
) {
    let mut batch = Candidates::new();
    let (mut block, end) = span.windows;
    while block < end {
        let used = (end - block).min(BOX_WINDOWS);
        let references: [u8; BOX_WINDOWS + 2] = view.references.read_block(block);
        let bounds = match vertices.lossless() {
            Some(points) => Q::vertex_window_bounds(&query.wide, points, &references),
            None => {
                let corners: BlockCorners =
                    vertices.gather::<0, 1, 2, { BOX_WINDOWS + 2 }>(&references, used + 2);
                Q::window_bounds(&query.wide, &corners)
            }
        };
        for (lane, &bound) in bounds.iter().enumerate().take(used) {
            if bound > best.limit {
                continue;
            }
            let window = block + lane;
            let stored = [references[lane], references[lane + 1], references[lane + 2]];
            let Some(corners) = window_corners(stored, window) else {
                continue;
            };
            batch.push(window, corners.map(|r| vertices.point(r as usize)));
            if batch.windows.len() == TRIANGLE_LANES {
                batch.offer::<Q>(span.strip, query, best);
            }
        }
        batch.offer::<Q>(span.strip, query, best);
        block += BOX_WINDOWS;
    }
}

/// Windows whose exact distances are computed together, with their corners in lanes.
struct Candidates {
    windows: ArrayVec<usize, TRIANGLE_LANES>,
    corners: CornerLanes,
}

impl Candidates {
    fn new() -> Candidates {
        Candidates {
            windows: ArrayVec::new(),
            corners: [[[0.0; TRIANGLE_LANES]; 3]; 3],
        }
    }

    #[inline(always)]
    fn push(&mut self, window: usize, corners: [Point; 3]) {
        let lane = self.windows.len();
        for (k, corner) in corners.iter().enumerate() {
            for (axis, &x) in corner.iter().enumerate() {
                self.corners[k][axis][lane] = f64::from(x);
            }
        }
        self.windows.push(window);
    }

    /// Offers every window's closest point to `best`, and empties the batch.
    #[inline(always)]
    fn offer<Q: QueryKernel>(&mut self, strip: u32, query: &Query, best: &mut Best) {
        if self.windows.is_empty() {
            return;
        }
        let found = Q::closest_on_triangles(&query.wide, &self.corners);
        for (lane, &window) in self.windows.iter().enumerate() {
            let candidate = match found.decided >> lane & 1 {
                1 if found.distance_squared[lane] > best.limit => continue,
                1 => found.lane(lane),
                _ => self.scalar(lane, query),
            };
            best.offer(strip, window as u16, candidate);
        }
        self.windows.clear();
    }

    /// The scalar rule for a lane the region masks leave undecided.
    #[cold]
    fn scalar(&self, lane: usize, query: &Query) -> TrianglePoint {
        let corner = |k: usize| self.corners[k].map(|axis| axis[lane] as f32);
        closest_on_triangle(&query.point, &[corner(0), corner(1), corner(2)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

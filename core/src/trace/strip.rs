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
//! leaf, is intersected at once (the paper's "external parameter"), eight windows at a time in
//! the kernel's SIMD lanes: window `k` evaluates the short edges `(s[k], s[k+1])`,
//! `(s[k+1], s[k+2])` and the long edge `(s[k], s[k+2])` with no branch on the geometry (a
//! branch skipping the long edge once the short ones separate the ray is mispredicted about
//! half the time), and only the rare windows whose three edges agree finish in the scalar
//! [`resolve`], bit-identical to the single-triangle test.
//!
//! Kernels: the lanes are computed by the walk's [`TraceKernel`] (the portable `wide` lanes, or
//! 256-bit AVX2 lanes), which runs the same IEEE operations per lane, so the kernel never
//! changes a hit.
//!
//! Cost: the traversal is a flat loop over a fixed stack, with nodes numbered in buckets of
//! `leaf_windows` windows (see [`crate::format::implicit_tree`]) so that splitting a node and
//! finding its right child take a shift and an add rather than divisions by the leaf size, and
//! nothing is allocated or zeroed per strip or per window.
//!
//! Block boxes (format 3, [`crate::format::block_boxes`]): a strip that stores a box per
//! block is walked block by block, the boxes tested up to [`BOX_GROUP`] at a time
//! ([`TraceKernel::entered_boxes`]), and its kd-tree is not descended; see
//! `StripQuery::traverse_boxes`.
//!
//! Vertex encodings: the traversal is generic over [`VertexAccess`] and monomorphized per
//! encoding, with one branch per strip on [`StripVertices`]: lossless strips read their f32
//! vertices in place, grid strips decode each vertex in place through the one grid decode
//! expression, so a vertex shared by two strips is bit-identical in both (watertightness).
//!
//! Determinism: among hits at the same parameter the one with the smallest (strip, window) wins,
//! and culling compares inclusively against [`Closest::reach`], a little beyond the closest hit,
//! so ties resolve the same way whatever the visiting order.

use arrayvec::ArrayVec;

use super::closest::Closest;
use super::kernel::{TraceKernel, Walk, BLOCK, BOX_GROUP};
use super::prepared::{max_not_nan, min_not_nan, PreparedRay};
use super::watertight::{resolve, RayPoint};
use crate::format::block_boxes::{BoxFrame, BOX_WINDOWS};
use crate::format::implicit_tree::buckets;
use crate::format::reader::StripView;
use crate::format::vertices::{StripVertices, VertexAccess};

/// Runs the strip walk `StripAxes::<V, KX, KY, KZ>` on the kernel `K` for the query's
/// ray-space axes.
macro_rules! by_axes {
    ($kernel:ty, $query:expr, $vertices:expr, $args:expr) => {
        match $query.ray.space.axes() {
            [1, 2, 0] => {
                <$kernel>::compiled(StripAxes::<V, 1, 2, 0>::new($query, $vertices, $args))
            }
            [2, 1, 0] => {
                <$kernel>::compiled(StripAxes::<V, 2, 1, 0>::new($query, $vertices, $args))
            }
            [2, 0, 1] => {
                <$kernel>::compiled(StripAxes::<V, 2, 0, 1>::new($query, $vertices, $args))
            }
            [0, 2, 1] => {
                <$kernel>::compiled(StripAxes::<V, 0, 2, 1>::new($query, $vertices, $args))
            }
            [0, 1, 2] => {
                <$kernel>::compiled(StripAxes::<V, 0, 1, 2>::new($query, $vertices, $args))
            }
            _ => <$kernel>::compiled(StripAxes::<V, 1, 0, 2>::new($query, $vertices, $args)),
        }
    };
}

/// Most deferred subtrees: one per level of the deepest strip kd-tree (intervals halve, and a
/// strip has fewer than 2^16 windows).
const STRIP_STACK: usize = 20;

/// What one strip traversal looks for.
pub struct StripQuery<'a> {
    pub ray: &'a PreparedRay,
    /// The file's strip kd-tree leaf size (it defines the tree's shape).
    pub leaf_windows: usize,
    pub subtree_windows: usize,
    /// Stop at the first hit in range (shadow and occlusion rays).
    pub any_hit: bool,
}

/// A strip traversal's strip, its file position, the ray's parameter interval and the closest
/// hit so far.
type TraceArgs<'a, 'v> = (&'a StripView<'v>, u32, f32, f32, &'a mut Closest);

/// A subtree of the strip's kd-tree and the ray's parameter interval in it. The subtree covers
/// buckets `[first, end)`, bucket `b` being windows `b * leaf_windows ..` (the last one shorter).
#[derive(Clone, Copy)]
struct Pending {
    node: u32,
    first: u32,
    end: u32,
    t_near: f32,
    t_far: f32,
}

/// The strip walk for a ray whose ray-space axes are `[KX, KY, KZ]`, as the kernel compiles it.
struct StripAxes<'q, 'a, 'v, V, const KX: usize, const KY: usize, const KZ: usize> {
    query: &'q StripQuery<'q>,
    vertices: V,
    args: TraceArgs<'a, 'v>,
}

impl<'q, 'a, 'v, V, const KX: usize, const KY: usize, const KZ: usize>
    StripAxes<'q, 'a, 'v, V, KX, KY, KZ>
{
    #[inline(always)]
    fn new(query: &'q StripQuery<'q>, vertices: V, args: TraceArgs<'a, 'v>) -> Self {
        StripAxes {
            query,
            vertices,
            args,
        }
    }
}

impl<V: VertexAccess, const KX: usize, const KY: usize, const KZ: usize> Walk
    for StripAxes<'_, '_, '_, V, KX, KY, KZ>
{
    type Output = bool;

    #[inline(always)]
    fn run<K: TraceKernel>(self) -> bool {
        self.query
            .traverse::<K, V, KX, KY, KZ>(self.vertices, self.args)
    }
}

impl StripQuery<'_> {
    /// Traverses strip `index` within `[t_near, t_far]` with the kernel `K`, updating
    /// `closest`. Returns true when `any_hit` is set and a hit was found.
    #[inline(always)]
    pub fn trace<K: TraceKernel>(
        &self,
        view: &StripView,
        index: u32,
        t_near: f32,
        t_far: f32,
        closest: &mut Closest,
    ) -> bool {
        // The one branch on the vertex encoding, per strip; below it everything is compiled
        // for the encoding at hand.
        match view.vertices {
            StripVertices::F32(vertices) => {
                self.trace_with::<K, _>(vertices, (view, index, t_near, t_far, closest))
            }
            StripVertices::Grid(vertices) => {
                self.trace_with::<K, _>(vertices, (view, index, t_near, t_far, closest))
            }
        }
    }

    /// [`StripQuery::trace`] with the strip's vertices read through `vertices`: one compiled
    /// walk per ray-space axis order.
    #[inline(always)]
    fn trace_with<K: TraceKernel, V: VertexAccess>(&self, vertices: V, args: TraceArgs) -> bool {
        by_axes!(K, self, vertices, args)
    }

    /// The strip kd-tree traversal with blocks intersected by `K`.
    #[inline(always)]
    fn traverse<
        K: TraceKernel,
        V: VertexAccess,
        const KX: usize,
        const KY: usize,
        const KZ: usize,
    >(
        &self,
        vertices: V,
        (view, index, t_near, t_far, closest): TraceArgs,
    ) -> bool {
        if !view.boxes.is_empty() {
            if let Some(frame) = view.boxes.frame(vertices.point(0)) {
                let args = (view, index, t_near, t_far, closest);
                return self.traverse_boxes::<K, V, KX, KY, KZ>((vertices, &frame), args);
            }
        }
        let windows = view.window_count();
        let leaf = self.leaf_windows;
        let ray = self.ray;
        let mut stack = ArrayVec::<Pending, STRIP_STACK>::new();
        let mut current = Pending {
            node: 0,
            first: 0,
            end: buckets(windows, leaf) as u32,
            t_near,
            t_far,
        };
        loop {
            // Invariant: `current` is entered: `t_near <= t_far` and `t_near <= closest.reach`.
            let (first, end) = (current.first as usize, current.end as usize);
            let lo = first * leaf;
            let hi = (end * leaf).min(windows);
            if end - first == 1 || hi - lo <= self.subtree_windows {
                let found =
                    self.intersect::<K, V, KX, KY, KZ>(vertices, view, index, lo, hi, closest);
                if found && self.any_hit {
                    return true;
                }
            } else {
                // The left child takes the larger half of the buckets (left-balanced tree).
                let mid = first + (end - first).div_ceil(2);
                let node = current.node as usize;
                // Validated axes are at most 2; saying so lets the compiler drop the bounds
                // checks of the indexing below.
                let axis = view.axis(node).min(2);
                let left_max = vertices.coordinate(2 * node, axis);
                let right_min = vertices.coordinate(2 * node + 1, axis);
                let left = Pending {
                    node: current.node + 1,
                    end: mid as u32,
                    ..current
                };
                let right = Pending {
                    node: (node + (mid - first)) as u32,
                    first: mid as u32,
                    ..current
                };
                let (mut near, exit_plane, mut far, entry_plane) = if ray.negative[axis] {
                    (right, right_min, left, left_max)
                } else {
                    (left, left_max, right, right_min)
                };
                near.t_far = min_not_nan(near.t_far, ray.exit_distance(axis, exit_plane));
                far.t_near = max_not_nan(far.t_near, ray.entry_distance(axis, entry_plane));
                let far_entered = far.t_near <= far.t_far && far.t_near <= closest.reach;
                if near.t_near <= near.t_far {
                    if far_entered {
                        stack.push(far);
                    }
                    current = near;
                    continue;
                }
                if far_entered {
                    current = far;
                    continue;
                }
            }
            loop {
                let Some(deferred) = stack.pop() else {
                    return false;
                };
                if deferred.t_near <= closest.reach {
                    current = deferred;
                    break;
                }
            }
        }
    }

    /// The blocks of a strip with block boxes (format 3), each intersected when the ray enters
    /// its box within `[t_near, t_far]`, in strip order; true when `any_hit` is set and a hit
    /// was found.
    ///
    /// Deviation from the paper: such a strip's kd-tree is not traversed. A box per block
    /// culls more than the kd-tree's one plane per node, and a flat loop over a strip's few
    /// blocks costs less than descending it (`docs/BENCHMARKS.md`, "Block boxes").
    ///
    /// The boxes of a group are tested before any of its blocks, against `t_far`, so that a
    /// kernel may test them in one pass; the bound of a hit found meanwhile is applied per
    /// block (`near <= reach`), which enters exactly the blocks that testing each box against
    /// `min(t_far, reach)` in turn entered.
    #[inline(always)]
    fn traverse_boxes<
        K: TraceKernel,
        V: VertexAccess,
        const KX: usize,
        const KY: usize,
        const KZ: usize,
    >(
        &self,
        (vertices, frame): (V, &BoxFrame),
        (view, index, t_near, t_far, closest): TraceArgs,
    ) -> bool {
        let windows = view.window_count();
        let boxes = view.boxes.count().min(windows.div_ceil(BOX_WINDOWS));
        for group in 0..boxes.div_ceil(BOX_GROUP) {
            let entered = K::entered_boxes(self.ray, &view.boxes, frame, group, t_near, t_far);
            let mut mask = entered.mask;
            while mask != 0 {
                let lane = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                // `near <= far` held; a hit found since may have moved the bound nearer
                // (`near` is never NaN: it starts from `t_near` and NaN distances keep it).
                if entered.near[lane] > closest.reach {
                    continue;
                }
                let first = (group * BOX_GROUP + lane) * BOX_WINDOWS;
                let count = BOX_WINDOWS.min(windows - first);
                let block = (vertices, view, first, count);
                // Grid blocks keep one instantiation for both walks (see `intersect_block`).
                let found = match vertices.lossless() {
                    Some(_) => self.intersect_block::<K, V, KX, KY, KZ, 1>(block, index, closest),
                    None => self.intersect_block::<K, V, KX, KY, KZ, 0>(block, index, closest),
                };
                if found && self.any_hit {
                    return true;
                }
            }
        }
        false
    }

    /// Intersects windows `[lo, hi)` in blocks of [`BLOCK`] windows.
    #[inline(always)]
    fn intersect<
        K: TraceKernel,
        V: VertexAccess,
        const KX: usize,
        const KY: usize,
        const KZ: usize,
    >(
        &self,
        vertices: V,
        view: &StripView,
        index: u32,
        lo: usize,
        hi: usize,
        closest: &mut Closest,
    ) -> bool {
        let mut found = false;
        for first in (lo..hi).step_by(BLOCK) {
            let count = BLOCK.min(hi - first);
            let block = (vertices, view, first, count);
            if self.intersect_block::<K, V, KX, KY, KZ, 0>(block, index, closest) {
                found = true;
                if self.any_hit {
                    return true;
                }
            }
        }
        found
    }

    /// `SITE` tells the two walks' calls apart (the kd-tree's 0, the block boxes' 1): each
    /// instantiation of the kernel's block then has one caller and is inlined, even where it
    /// cannot be `inline(always)`, rather than called per block with its result copied.
    ///
    /// Intersects the `count <= BLOCK` windows from `first`, lane `k` being window
    /// `first + k`: the kernel `K` finds the candidate lanes (`BlockEdges`) with no branch on
    /// the geometry, and the rare lanes whose edges all agree go through the scalar
    /// [`resolve`], which sees bit-identical inputs to the single-triangle test.
    #[inline(always)]
    fn intersect_block<
        K: TraceKernel,
        V: VertexAccess,
        const KX: usize,
        const KY: usize,
        const KZ: usize,
        const SITE: usize,
    >(
        &self,
        (vertices, view, first, count): (V, &StripView, usize, usize),
        index: u32,
        closest: &mut Closest,
    ) -> bool {
        let references = K::references(&view.references, first);
        let range = (self.ray.tmin, closest.t);
        let Some(edges) =
            K::edges::<V, KX, KY, KZ, SITE>(&self.ray.space, vertices, &references, count, range)
        else {
            return false;
        };
        let mut candidates = edges.candidates;
        let mut found = false;
        while candidates != 0 {
            let lane = candidates.trailing_zeros() as usize;
            candidates &= candidates - 1;
            if !is_real_window(&references[lane..lane + 3]) {
                continue;
            }
            let c: [RayPoint; 3] = std::array::from_fn(|corner| {
                let along_z = vertices.coordinate(references[lane + corner] as usize, KZ);
                RayPoint {
                    x: edges.x[corner][lane],
                    y: edges.y[corner][lane],
                    z: self.ray.space.depth_as::<KZ>(along_z),
                }
            });
            let w = edges.weights.map(|w| w[lane]);
            if let Some(hit) = resolve(&c, w, self.ray.tmin, closest.t) {
                let corners = std::array::from_fn(|k| references[lane + k]);
                let window = (index, (first + lane) as u16);
                closest.offer(hit.t, window, hit.weights, (vertices, corners));
                found = true;
                if self.any_hit {
                    return true;
                }
            }
        }
        found
    }
}

/// Whether the window with these three corner references is a real triangle rather than a
/// swap. Only candidate lanes are checked: a swap repeats a corner, so one of its edge functions
/// is exactly zero and it would reach [`resolve`], which rejects it (zero determinant), but
/// slowly.
#[inline(always)]
fn is_real_window(corners: &[u8]) -> bool {
    corners[0] != corners[1] && corners[1] != corners[2] && corners[0] != corners[2]
}

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
//! SIMD lanes: the block's references are read as one fixed-size array and its strip positions
//! gathered once; lanes shifted by 0, 1 and 2 positions are the windows' three corners, each
//! moved to ray space (x and y; the depth only for the rare candidate windows), and window `k`
//! evaluates the short edges `(s[k], s[k+1])`, `(s[k+1], s[k+2])` and the long edge
//! `(s[k], s[k+2])`, with no branch on the geometry until a window's three edges agree, which is
//! rare; those windows finish in the scalar [`resolve`], bit-identical to the single-triangle
//! test. A position is transformed, and a short edge
//! evaluated, once per window that uses it (up to three and two times): the same operations on
//! the same inputs give the same bits, and the repeated arithmetic costs fewer instructions than
//! transforming once and shifting the results across lanes through memory, as the block first
//! did. (The SIMD block replaced a scalar loop that skipped the long edge when the short ones
//! already separated the ray: fewer operations, but the skip was a data-dependent branch
//! mispredicted about half the time.)
//!
//! Kernels: the lanes are computed by a [`BlockKernel`], chosen per query
//! ([`super::kernel::Kernel`]): the baseline's `wide` lanes here, or 256-bit AVX2 lanes
//! ([`super::avx2`], which compiles this same traversal for AVX2). Both run the same IEEE
//! operations per lane, so the kernel never changes a hit.
//!
//! Cost: the traversal is a flat loop over a fixed stack, with nodes numbered in buckets of
//! `leaf_windows` windows (see [`crate::format::implicit_tree`]) so that splitting a node and
//! finding its right child take a shift and an add rather than divisions by the leaf size, and
//! nothing is allocated or zeroed per strip or per window.
//!
//! Block boxes (format 3, [`crate::format::block_boxes`]): a strip that stores a box per
//! block is walked block by block, the boxes tested up to [`BOX_GROUP`] at a time
//! ([`BlockKernel::entered_boxes`]: one box after the other in the baseline, all four in one
//! pass with AVX2), and its kd-tree is not descended; see `StripQuery::traverse_boxes`.
//!
//! Vertex encodings: the traversal is generic over [`VertexAccess`] and monomorphized per
//! encoding, with one branch per strip on [`StripVertices`]: lossless strips read their f32
//! vertices as before, grid strips decode each vertex in place through the one grid decode
//! expression, so a vertex shared by two strips is bit-identical in both (watertightness).
//!
//! Determinism: among hits at the same parameter the one with the smallest (strip, window) wins,
//! and culling compares inclusively against [`Closest::reach`], a little beyond the closest hit,
//! so ties resolve the same way whatever the visiting order.

use arrayvec::ArrayVec;

use super::prepared::{
    max_not_nan, max_not_nan_x4, min_not_nan, min_not_nan_x4, PreparedRay, FAR_INFLATION,
};
use wide::{f32x4, f32x8};

use super::kernel::Kernel;
use super::watertight::{candidate_lanes, edge_lanes, resolve, RayPoint, RaySpace};
use crate::format::block_boxes::{
    BlockBoxes, BoxFrame, BOX_BYTES, BOX_WINDOWS, CODE_BIAS, MAX_CODE,
};
use crate::format::implicit_tree::buckets;
use crate::format::reader::StripView;
use crate::format::references::References;
use crate::format::vertices::{StripVertices, VertexAccess};
use crate::geometry::Point;

/// Calls `$entry::<V, KX, KY, KZ>($query, ..)` for the query's ray-space axes.
macro_rules! by_axes {
    ($($entry:ident)::+, $query:expr, $vertices:expr, $args:expr) => {
        match $query.ray.space.axes() {
            [1, 2, 0] => $($entry)::+::<V, 1, 2, 0>($query, $vertices, $args),
            [2, 1, 0] => $($entry)::+::<V, 2, 1, 0>($query, $vertices, $args),
            [2, 0, 1] => $($entry)::+::<V, 2, 0, 1>($query, $vertices, $args),
            [0, 2, 1] => $($entry)::+::<V, 0, 2, 1>($query, $vertices, $args),
            [0, 1, 2] => $($entry)::+::<V, 0, 1, 2>($query, $vertices, $args),
            _ => $($entry)::+::<V, 1, 0, 2>($query, $vertices, $args),
        }
    };
}
#[cfg(target_arch = "x86_64")]
pub(super) use by_axes;

/// Most deferred subtrees: one per level of the deepest strip kd-tree (intervals halve, and a
/// strip has fewer than 2^16 windows).
const STRIP_STACK: usize = 20;

/// The closest hit so far, with its weights and corners in strip order (`s[k], s[k+1], s[k+2]`).
#[derive(Clone, Copy, Debug)]
pub struct Closest {
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
    /// traversal has at hand: finishing the hit (its normal) then needs no second view of the
    /// strip, which cost about 160 instructions per hit.
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
    /// the code of the block loop around it (inlined, it cost more per strip traversed than it
    /// saved).
    #[inline(never)]
    pub(super) fn offer<V: VertexAccess>(
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

/// What one strip traversal looks for.
pub struct StripQuery<'a> {
    pub ray: &'a PreparedRay,
    /// The file's strip kd-tree leaf size (it defines the tree's shape).
    pub leaf_windows: usize,
    pub subtree_windows: usize,
    /// Stop at the first hit in range (shadow and occlusion rays).
    pub any_hit: bool,
    /// The SIMD kernel of the strip blocks; one this CPU lacks runs as the baseline.
    pub kernel: Kernel,
}

/// A strip traversal's strip, its file position, the ray's parameter interval and the closest
/// hit so far.
pub(super) type TraceArgs<'a, 'v> = (&'a StripView<'v>, u32, f32, f32, &'a mut Closest);

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
        // The one branch on the vertex encoding, per strip; below it everything is compiled
        // for the encoding at hand.
        match view.vertices {
            StripVertices::F32(vertices) => {
                self.trace_with(vertices, (view, index, t_near, t_far, closest))
            }
            StripVertices::Grid(vertices) => {
                self.trace_with(vertices, (view, index, t_near, t_far, closest))
            }
        }
    }

    /// [`StripQuery::trace`] with the strip's vertices read through `vertices`, on the query's
    /// kernel.
    #[inline(always)]
    fn trace_with<V: VertexAccess>(&self, vertices: V, args: TraceArgs) -> bool {
        #[cfg(target_arch = "x86_64")]
        let args = match self.kernel {
            Kernel::Avx2 => match super::avx2::trace(self, vertices, args) {
                Ok(found) => return found,
                Err(args) => args,
            },
            Kernel::Sse2 => args,
        };
        by_axes!(Self::trace_as_sse2, self, vertices, args)
    }

    /// [`StripQuery::trace`] for a ray whose ray-space axes are `[KX, KY, KZ]`, baseline
    /// kernel. Never inlined: the twelve instantiations per kernel (six axis orders, two
    /// encodings) are each compiled on their own rather than some into [`StripQuery::trace`],
    /// whose size then swayed how well the others were optimized.
    #[inline(never)]
    fn trace_as_sse2<V: VertexAccess, const KX: usize, const KY: usize, const KZ: usize>(
        &self,
        vertices: V,
        args: TraceArgs,
    ) -> bool {
        self.traverse::<Sse2Blocks, V, KX, KY, KZ>(vertices, args)
    }

    /// The strip kd-tree traversal with blocks intersected by `K`.
    #[inline(always)]
    pub(super) fn traverse<
        K: BlockKernel,
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
    /// culls more than the kd-tree's one plane per node, and a flat loop over the strip's few
    /// blocks (2.4 on average at the pipeline's strip length) costs less than descending it:
    /// measured on 100k AO rays of the 1M scan, 5.37 blocks (35.9 windows) tested per ray with
    /// the kd-tree, 3.19 (23.0) with the boxes; on 100k primary rays 3.05 (20.2) and 1.77
    /// (12.8). Instructions per AO ray 3,545 -> 3,149 with the AVX2 kernel, 4,904 -> 4,537 with
    /// the baseline (callgrind, references packed as format 3 stores them; format 2.1 before).
    ///
    /// The boxes of a group are tested before any of its blocks, against `t_far`; the bound of
    /// a hit found meanwhile is applied per block (`near <= reach`), which enters exactly the
    /// blocks that testing each box against `min(t_far, reach)` in turn entered. With the AVX2
    /// kernel testing a strip's boxes in one pass, 3,151 -> 2,885 instructions per AO ray and
    /// 2,361 -> 2,217 per primary ray (callgrind, 100k rays of the 1M scan, as above).
    #[inline(always)]
    fn traverse_boxes<
        K: BlockKernel,
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
        K: BlockKernel,
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
    /// instantiation of the kernel then has one caller, and the AVX2 block, which is not
    /// `inline(always)` (a `target_feature` function cannot be), is inlined again; with one
    /// instantiation for both it was called per block and its result copied (3,228 -> 3,149
    /// instructions per AO ray, 2,596 -> 2,572 per primary ray, callgrind as in `traverse_boxes`).
    ///
    /// Intersects the `count <= BLOCK` windows from `first`, lane `k` being window
    /// `first + k`: the kernel `K` finds the candidate lanes ([`BlockEdges`]) with no branch on
    /// the geometry, and the rare lanes whose edges all agree go through the scalar
    /// [`resolve`], which sees bit-identical inputs to the single-triangle test.
    #[inline(always)]
    fn intersect_block<
        K: BlockKernel,
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

/// What a kernel computes for a block of windows with candidate lanes (see
/// [`candidate_lanes`]): the candidates (never 0) and every lane's ray-space corners `[corner]`
/// and edge weights `[corner]`, each lane holding what the scalar test computes for its window.
#[derive(Clone, Copy)]
pub struct BlockEdges {
    pub candidates: u32,
    pub x: [[f32; BLOCK]; 3],
    pub y: [[f32; BLOCK]; 3],
    pub weights: [[f32; BLOCK]; 3],
}

/// One way of computing [`BlockEdges`].
pub(super) trait BlockKernel {
    /// The `BLOCK + 2` references of the block from window `first`, as
    /// [`References::read_block`] reads them.
    #[inline(always)]
    fn references(references: &References, first: usize) -> [u8; BLOCK + 2] {
        references.read_block(first)
    }

    /// The block whose `BLOCK + 2` strip references are `references`, or `None` when no lane is
    /// a candidate (the common case: nothing is stored then); lanes past `count` are not
    /// candidates. A kernel may also drop candidates that [`resolve`] would find outside `range`
    /// (`tmin`, the closest hit's `t`) with nonzero weights, computing their `t` as it does.
    /// `SITE` only separates the instantiations of the calling walks (see
    /// `StripQuery::intersect_block`).
    fn edges<
        V: VertexAccess,
        const KX: usize,
        const KY: usize,
        const KZ: usize,
        const SITE: usize,
    >(
        space: &RaySpace,
        vertices: V,
        references: &[u8; BLOCK + 2],
        count: usize,
        range: (f32, f32),
    ) -> Option<BlockEdges>;

    /// The boxes of group `group` (boxes `BOX_GROUP * group ..`) that the ray enters within
    /// `[t_near, t_far]`, with their entry distances: per box what [`BoxTest::interval`]
    /// computes, box after box.
    #[inline(always)]
    fn entered_boxes(
        ray: &PreparedRay,
        boxes: &BlockBoxes,
        frame: &BoxFrame,
        group: usize,
        t_near: f32,
        t_far: f32,
    ) -> EnteredBoxes {
        let test = BoxTest::new(ray, frame);
        let mut entered = EnteredBoxes::default();
        for lane in 0..BOX_GROUP {
            let Some(codes) = boxes.codes(group * BOX_GROUP + lane) else {
                break;
            };
            let (near, far) = test.interval(codes, t_near, t_far);
            entered.near[lane] = near;
            entered.mask |= u32::from(near <= far) << lane;
        }
        entered
    }
}

/// Block boxes tested together ([`BlockKernel::entered_boxes`]): a strip of the pipeline's
/// default length (at most 20 windows) has at most three.
pub const BOX_GROUP: usize = 4;

/// The boxes of a group the ray enters: bit `k` of `mask` for box `k` of the group, whose entry
/// distance is `near[k]`.
#[derive(Clone, Copy, Debug, Default)]
pub struct EnteredBoxes {
    pub mask: u32,
    pub near: [f32; BOX_GROUP],
}

/// The baseline kernel: `wide`'s eight lanes (two SSE2 operations each on x86-64). The block's
/// `BLOCK + 2` positions are gathered once into an array and read as lanes shifted by 0, 1 and
/// 2 positions as the windows' three corners; each corner is moved to ray space (x and y) and
/// each edge evaluated in lanes.
struct Sse2Blocks;

impl BlockKernel for Sse2Blocks {
    #[inline(always)]
    fn edges<
        V: VertexAccess,
        const KX: usize,
        const KY: usize,
        const KZ: usize,
        const SITE: usize,
    >(
        space: &RaySpace,
        vertices: V,
        references: &[u8; BLOCK + 2],
        count: usize,
        _range: (f32, f32),
    ) -> Option<BlockEdges> {
        let model = vertices.gather::<KX, KY, KZ, { BLOCK + 2 }>(references, count + 2);
        // A position is transformed once per corner it is in (up to three times) rather than
        // once and then shifted through memory: the arithmetic is cheaper than storing lanes and
        // reloading them misaligned, and every copy of a vertex has the same bits.
        let corner = |shift: usize| {
            space.transform_lanes::<KX, KY, KZ>(
                lanes_from(&model[0], shift),
                lanes_from(&model[1], shift),
                lanes_from(&model[2], shift),
            )
        };
        let corners = [corner(0), corner(1), corner(2)];
        // Window `k`'s short edges are also windows `k - 1`'s and `k + 1`'s, but evaluating them
        // again in the lanes where they are needed is cheaper than shifting them across lanes.
        let weights = [
            edge_lanes(&corners[1], &corners[2]),
            edge_lanes(&corners[2], &corners[0]),
            edge_lanes(&corners[0], &corners[1]),
        ];
        let candidates = candidate_lanes(weights) & ((1 << count) - 1);
        (candidates != 0).then(|| BlockEdges {
            candidates,
            x: corners.map(|c| c.x.to_array()),
            y: corners.map(|c| c.y.to_array()),
            weights: weights.map(f32x8::to_array),
        })
    }
}

/// Windows intersected together: one `f32x8` lane each.
pub const BLOCK: usize = 8;
// A block box (format 3) bounds exactly one block.
const _: () = assert!(BOX_WINDOWS == BLOCK);

/// Lanes `shift..shift + BLOCK` of `values`.
#[inline(always)]
fn lanes_from(values: &[f32], shift: usize) -> f32x8 {
    let lanes: [f32; BLOCK] = values[shift..shift + BLOCK]
        .try_into()
        .expect("BLOCK lanes");
    f32x8::from(lanes)
}

/// Whether the window with these three corner references is a real triangle rather than a
/// swap. Only candidate lanes are checked: a swap repeats a corner, so one of its edge functions
/// is exactly zero and it would reach [`resolve`], which rejects it (zero determinant), but
/// slowly.
#[inline(always)]
fn is_real_window(corners: &[u8]) -> bool {
    corners[0] != corners[1] && corners[1] != corners[2] && corners[0] != corners[2]
}

/// A ray and a strip's box frame in lanes `x, y, z` (lane 3 unused), to test one block box in
/// a few SIMD operations: per lane the arithmetic of [`PreparedRay::clip_box`] on the planes
/// [`crate::format::block_boxes::decode_plane`] gives (the box's lanes `(code - 8) * scale`
/// are exact, as there). The same operations in every kernel, so the blocks a ray tests do not
/// depend on the kernel; and since the boxes hold their windows and the test is conservative
/// as `clip_box` is, no hit is ever culled.
pub(super) struct BoxTest {
    anchor: f32x4,
    scale: f32x4,
    origin: f32x4,
    entry_reciprocal: f32x4,
    exit_reciprocal: f32x4,
    /// All ones in the lanes of the axes the ray goes down.
    negative: f32x4,
}

impl BoxTest {
    #[inline(always)]
    fn new(ray: &PreparedRay, frame: &BoxFrame) -> BoxTest {
        let lanes = |v: &[f32; 3]| f32x4::from([v[0], v[1], v[2], 0.0]);
        let negative = ray
            .negative
            .map(|n| f32::from_bits(if n { u32::MAX } else { 0 }));
        BoxTest {
            anchor: lanes(&frame.anchor),
            scale: lanes(&frame.scale),
            origin: lanes(&ray.origin),
            entry_reciprocal: lanes(&ray.entry_reciprocal),
            exit_reciprocal: lanes(&ray.exit_reciprocal),
            negative: lanes(&negative),
        }
    }

    /// The ray's interval `(near, far)` in the box of `codes` within `[t_near, t_far]`: it
    /// enters the box when `near <= far`.
    #[inline(always)]
    fn interval(&self, codes: [u8; BOX_BYTES], t_near: f32, t_far: f32) -> (f32, f32) {
        let bias = CODE_BIAS as f32;
        let code = |shift: u8, mask: u8| {
            f32x4::from([
                f32::from(codes[0] >> shift & mask),
                f32::from(codes[1] >> shift & mask),
                f32::from(codes[2] >> shift & mask),
                bias,
            ])
        };
        let bias = f32x4::splat(bias);
        let min = self.anchor + (code(0, MAX_CODE) - bias) * self.scale;
        let max = self.anchor + (code(4, MAX_CODE) - bias) * self.scale;
        let entry_plane = self.negative.select(max, min);
        let exit_plane = self.negative.select(min, max);
        let entry = (entry_plane - self.origin) * self.entry_reciprocal;
        let exit = (exit_plane - self.origin) * self.exit_reciprocal * f32x4::splat(FAR_INFLATION);
        let near = max_not_nan_x4(f32x4::splat(t_near), entry).to_array();
        let far = min_not_nan_x4(f32x4::splat(t_far), exit).to_array();
        (
            max_not_nan(max_not_nan(near[0], near[1]), near[2]),
            min_not_nan(min_not_nan(far[0], far[1]), far[2]),
        )
    }
}

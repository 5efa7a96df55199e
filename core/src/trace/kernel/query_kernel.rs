//! The operations of the query walks (`crate::query`) in one kernel's lanes: a wide node's
//! eight grown boxes clipped at once ([`crossing_nodes`](super::crossing_nodes)), a strip
//! block's candidate windows ([`crossing_blocks`](super::crossing_blocks)) and the box distance
//! bounds of the closest-point search ([`distance_bounds`](super::distance_bounds)).
//!
//! A query walk is generic over [`QueryKernel`] and runs through [`dispatch_query`], which is
//! the tracer's [`dispatch`]: the whole walk of a ray or a point is compiled once for the
//! kernel's instructions, and every operation below is inlined into it, none called (and the
//! CPU asked) per node or strip. Every implementation gives the same bits.

#![allow(unsafe_code)]

use super::crossing_blocks::{candidates_on, StripBlocks};
use super::crossing_nodes::WidenedRay;
use super::distance_bounds::{child_lanes, window_lanes, BlockCorners, LaneBoxes};
use super::portable::Portable;
use super::triangle_lanes::{closest_on_triangles, CornerLanes, LanePoints};
use super::{dispatch, ChildBoxes, Kernel, TraceKernel, Walk, BLOCK};
use crate::format::vertices::VertexAccess;
use crate::format::{WideNode, TOP_WIDTH};
use crate::geometry::Point;
use crate::trace::watertight::{RayPoint, RaySpace};
use wide::f64x4;

/// What the query walks compute in a kernel's lanes; every kernel implements it.
pub(crate) trait QueryKernel {
    /// The children of `node` whose box, grown as the crossing walk grows boxes, the ray may
    /// meet, as a bit mask (bit `k`: slot `k`): all eight boxes in one register where the
    /// kernel has one that wide, else two groups of four decoded in its lanes and tested by
    /// `four`, the walk's four-box test (the same bits).
    fn entered_wide(ray: &WidenedRay, node: &WideNode, four: impl Fn(&ChildBoxes) -> u32) -> u32;

    /// [`box_bound`](super::distance_bounds::box_bound) of each child box of a top-level node.
    fn child_bounds(
        query: &[f64; 3],
        min: &LaneBoxes<TOP_WIDTH>,
        max: &LaneBoxes<TOP_WIDTH>,
    ) -> [f64; TOP_WIDTH];

    /// The eight child boxes of a format 4 node as two groups of four (`(min, max)` by axis
    /// and slot), decoded at once: [`WideNode::decode`]'s bits.
    fn wide_child_boxes(node: &WideNode) -> [ChildBoxes; 2];

    /// [`box_bound`](super::distance_bounds::box_bound) of the box of each window of a block
    /// (its corners' minima and maxima).
    fn window_bounds(query: &[f64; 3], corners: &BlockCorners) -> [f64; BLOCK];

    /// [`QueryKernel::window_bounds`] of a block of lossless `vertices` named by `references`.
    fn vertex_window_bounds(
        query: &[f64; 3],
        vertices: &[Point],
        references: &[u8; BLOCK + 2],
    ) -> [f64; BLOCK];

    /// [`closest_on_triangles`] of four triangles to `p`.
    fn closest_on_triangles(p: &[f64; 3], corners: &CornerLanes) -> LanePoints;

    /// `each(window, corners)` for every candidate window of `blocks`
    /// ([`candidates_on`](super::crossing_blocks::candidates_on)).
    fn for_each_candidate<F: FnMut(usize, [RayPoint; 3])>(
        space: &RaySpace,
        range: (f32, f32),
        blocks: StripBlocks,
        each: &mut F,
    );
}

/// A query walk generic over the kernel, for [`dispatch_query`].
pub(crate) trait QueryWalk {
    type Output;

    fn run<Q: QueryKernel>(self) -> Self::Output;
}

/// Runs `walk` on `kernel` through the tracer's one dispatch point.
#[inline(always)]
pub(crate) fn dispatch_query<W: QueryWalk>(kernel: Kernel, walk: W) -> W::Output {
    dispatch(kernel, AsTraceWalk(walk))
}

/// A query walk as the tracer's [`Walk`]: every [`TraceKernel`] is a [`QueryKernel`].
struct AsTraceWalk<W>(W);

impl<W: QueryWalk> Walk for AsTraceWalk<W> {
    type Output = W::Output;

    #[inline(always)]
    fn run<K: TraceKernel>(self) -> W::Output {
        self.0.run::<K>()
    }
}

impl QueryKernel for Portable {
    #[inline(always)]
    fn entered_wide(_: &WidenedRay, node: &WideNode, four: impl Fn(&ChildBoxes) -> u32) -> u32 {
        let [low, high] = Portable::decode_wide(node);
        four(&low) | four(&high) << TOP_WIDTH
    }

    #[inline(always)]
    fn child_bounds(
        query: &[f64; 3],
        min: &LaneBoxes<TOP_WIDTH>,
        max: &LaneBoxes<TOP_WIDTH>,
    ) -> [f64; TOP_WIDTH] {
        child_lanes(query, min, max)
    }

    #[inline(always)]
    fn wide_child_boxes(node: &WideNode) -> [ChildBoxes; 2] {
        Portable::decode_wide(node)
    }

    #[inline(always)]
    fn window_bounds(query: &[f64; 3], corners: &BlockCorners) -> [f64; BLOCK] {
        window_lanes(query, corners)
    }

    #[inline(always)]
    fn vertex_window_bounds(
        query: &[f64; 3],
        vertices: &[Point],
        references: &[u8; BLOCK + 2],
    ) -> [f64; BLOCK] {
        window_lanes(
            query,
            &vertices.gather::<0, 1, 2, { BLOCK + 2 }>(references, BLOCK + 2),
        )
    }

    #[inline(always)]
    fn closest_on_triangles(p: &[f64; 3], corners: &CornerLanes) -> LanePoints {
        closest_on_triangles::<f64x4>(p, corners)
    }

    #[inline(always)]
    fn for_each_candidate<F: FnMut(usize, [RayPoint; 3])>(
        space: &RaySpace,
        range: (f32, f32),
        blocks: StripBlocks,
        each: &mut F,
    ) {
        candidates_on::<Portable, F>(space, range, blocks, each)
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use crate::trace::kernel::avx2::Avx2;
    use crate::trace::kernel::crossing_nodes::entered_wide_avx2;
    use crate::trace::kernel::distance_bounds::{
        child_bounds_avx2, vertex_window_bounds_avx2, window_bounds_avx2,
    };
    use crate::trace::kernel::triangle_lanes::avx2::closest_on_triangles_avx2;

    // SAFETY (each call below): `Avx2` runs only once the CPU was found to have AVX2 and BMI2
    // (`dispatch`), inside the walk compiled for them.
    impl QueryKernel for Avx2 {
        #[inline(always)]
        fn entered_wide(ray: &WidenedRay, node: &WideNode, _: impl Fn(&ChildBoxes) -> u32) -> u32 {
            // SAFETY: see the impl.
            unsafe { entered_wide_avx2(ray, node) }
        }

        #[inline(always)]
        fn child_bounds(
            query: &[f64; 3],
            min: &LaneBoxes<TOP_WIDTH>,
            max: &LaneBoxes<TOP_WIDTH>,
        ) -> [f64; TOP_WIDTH] {
            // SAFETY: see the impl.
            unsafe { child_bounds_avx2(query, min, max) }
        }

        #[inline(always)]
        fn wide_child_boxes(node: &WideNode) -> [ChildBoxes; 2] {
            Avx2::decode_wide(node)
        }

        #[inline(always)]
        fn window_bounds(query: &[f64; 3], corners: &BlockCorners) -> [f64; BLOCK] {
            // SAFETY: see the impl.
            unsafe { window_bounds_avx2(query, corners) }
        }

        #[inline(always)]
        fn vertex_window_bounds(
            query: &[f64; 3],
            vertices: &[Point],
            references: &[u8; BLOCK + 2],
        ) -> [f64; BLOCK] {
            // SAFETY: see the impl.
            unsafe { vertex_window_bounds_avx2(query, vertices, references) }
        }

        #[inline(always)]
        fn closest_on_triangles(p: &[f64; 3], corners: &CornerLanes) -> LanePoints {
            // SAFETY: see the impl.
            unsafe { closest_on_triangles_avx2(p, corners) }
        }

        #[inline(always)]
        fn for_each_candidate<F: FnMut(usize, [RayPoint; 3])>(
            space: &RaySpace,
            range: (f32, f32),
            blocks: StripBlocks,
            each: &mut F,
        ) {
            candidates_on::<Avx2, F>(space, range, blocks, each)
        }
    }
}

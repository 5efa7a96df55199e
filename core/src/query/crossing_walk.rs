//! One ray's walk to every window it may cross: the top-level hierarchy and each strip's block
//! boxes culled by a widened box test four boxes at a time, then the entered blocks' windows
//! tested in the kernel's lanes ([`crate::trace::kernel::crossing_blocks`]), which hands back
//! the candidates for the exact tie rule.
//!
//! **Why widened boxes.** The tie rule decides a ray through an edge or a vertex on the
//! rounded ray-space corners, which may put the crossing on a triangle the exact ray misses by
//! a few ulps of its distance to the origin; a box holding that triangle on its face must not
//! be culled then, or the crossing is counted on neither side. Every box is therefore grown
//! by [`MARGIN`] times the sum of its distances to the origin on all three axes (the scale of
//! those roundings on any axis) before the conservative slab test of
//! [`crate::trace::prepared`], and the ray's `[tmin, tmax]` by the same relative margin.

use wide::f32x4;

use super::child_box::ChildBox;
use crate::format::reader::{ReducemFile, StripView, TopNodes};
use crate::format::vertices::{StripVertices, VertexAccess};
use crate::format::{TopSlot, TOP_WIDTH};
use crate::geometry::Point;
use crate::trace::kernel::crossing_blocks::{for_each_candidate, StripBlocks, MASK_BLOCKS};
use crate::trace::kernel::Kernel;
use crate::trace::prepared::{max_not_nan_x4, min_not_nan_x4, FAR_INFLATION};
use crate::trace::watertight::{RayPoint, RaySpace};
use crate::trace::Ray;

/// Relative growth of boxes and of the ray's interval: far above the few f32 roundings of the
/// ray-space transform and of the slab test.
const MARGIN: f32 = 1.0 / 65_536.0;

/// Four boxes axis by axis: `min[axis][box]`, `max[axis][box]`.
type FourBoxes = ([[f32; 4]; 3], [[f32; 4]; 3]);

/// A valid ray (finite, non-zero direction, `0 <= tmin <= tmax`) ready for the walk.
pub(super) struct CrossingWalk {
    kernel: Kernel,
    space: RaySpace,
    range: (f32, f32),
    origin: [f32x4; 3],
    entry_reciprocal: [f32x4; 3],
    exit_reciprocal: [f32x4; 3],
    negative: [bool; 3],
    /// `[tmin, tmax]` grown by [`MARGIN`].
    t_near: f32,
    t_far: f32,
}

impl CrossingWalk {
    pub(super) fn new(ray: &Ray, kernel: Kernel) -> CrossingWalk {
        let exit_reciprocal = ray.direction.map(|d| 1.0 / d);
        // Clamped as `PreparedRay` does for subnormal components; `1 / ±0` stays infinite.
        let entry_reciprocal: Point = std::array::from_fn(|axis| {
            let r = exit_reciprocal[axis];
            if ray.direction[axis] == 0.0 {
                r
            } else {
                r.clamp(-f32::MAX, f32::MAX)
            }
        });
        let splat = |v: &Point| v.map(f32x4::splat);
        CrossingWalk {
            kernel,
            space: RaySpace::new(ray.origin, ray.direction),
            range: (ray.tmin, ray.tmax),
            origin: splat(&ray.origin),
            entry_reciprocal: splat(&entry_reciprocal),
            exit_reciprocal: splat(&exit_reciprocal),
            negative: ray.direction.map(|d| d.is_sign_negative()),
            t_near: ray.tmin * (1.0 - MARGIN),
            t_far: ray.tmax * (1.0 + MARGIN),
        }
    }

    /// Calls `each(strip, window, corners)` for every candidate window of the file (see
    /// [`for_each_candidate`]); corrupt nodes reached are skipped as in tracing.
    pub(super) fn run(&self, file: &ReducemFile, each: &mut impl FnMut(u32, usize, [RayPoint; 3])) {
        match file.top_nodes() {
            TopNodes::F32(nodes) => self.nodes(file, nodes, &(), each),
            TopNodes::Grid(nodes, grid) => self.nodes(file, nodes, &grid, each),
        }
    }

    fn nodes<N: ChildBox>(
        &self,
        file: &ReducemFile,
        nodes: &[N],
        grid: &N::Grid,
        each: &mut impl FnMut(u32, usize, [RayPoint; 3]),
    ) {
        if nodes.is_empty() {
            return;
        }
        let mut stack = Vec::with_capacity(64);
        stack.push(0u32);
        let mut visits = file.node_visits();
        while let Some(index) = stack.pop() {
            // A file changed in place after its validation may link nodes in circles.
            visits = match visits.checked_sub(1) {
                Some(left) => left,
                None => return,
            };
            let Some(node) = file.top_node(nodes, index as usize) else {
                continue;
            };
            let mut entered = self.entered(&child_boxes(node, grid));
            while entered != 0 {
                let slot = entered.trailing_zeros() as usize;
                entered &= entered - 1;
                match node.slot(slot) {
                    TopSlot::Internal(child) => stack.push(child),
                    TopSlot::Leaf { first, count } => {
                        for strip in file.leaf_strips(first, count) {
                            self.strip(file, strip, each);
                        }
                    }
                    TopSlot::Empty | TopSlot::Invalid(_) => {}
                }
            }
        }
    }

    /// The candidate windows of strip `strip` in the blocks whose box the ray may meet (every
    /// block when the strip stores no boxes).
    fn strip(
        &self,
        file: &ReducemFile,
        strip: u32,
        each: &mut impl FnMut(u32, usize, [RayPoint; 3]),
    ) {
        let view = file.strip(strip as usize);
        let blocks = view.window_count().div_ceil(BLOCK_WINDOWS);
        let mut candidate = |window: usize, corners: [RayPoint; 3]| each(strip, window, corners);
        for first_block in (0..blocks).step_by(MASK_BLOCKS) {
            let count = (blocks - first_block).min(MASK_BLOCKS);
            let mask = match view.boxes.is_empty() {
                true => u64::MAX >> (MASK_BLOCKS - count),
                false => self.entered_blocks(&view, first_block, count),
            };
            if mask != 0 {
                let blocks = StripBlocks {
                    view: &view,
                    mask,
                    first_block,
                };
                for_each_candidate(self.kernel, &self.space, self.range, blocks, &mut candidate);
            }
        }
    }

    /// Of the `count` blocks from `first_block`, those whose box the ray may meet (all when
    /// the boxes cannot be framed: only in a corrupt strip, which validation reports).
    fn entered_blocks(&self, view: &StripView, first_block: usize, count: usize) -> u64 {
        let anchor = match view.vertices {
            StripVertices::F32(vertices) => vertices.point(0),
            StripVertices::Grid(vertices) => vertices.point(0),
        };
        let all = u64::MAX >> (MASK_BLOCKS - count);
        let Some(frame) = view.boxes.frame(anchor) else {
            return all;
        };
        let mut mask = 0u64;
        for group in (0..count).step_by(4) {
            let lanes = 4.min(count - group);
            // A box past the stored ones (a corrupt strip) stays NaN, which is entered.
            let mut boxes: FourBoxes = ([[f32::NAN; 4]; 3], [[f32::NAN; 4]; 3]);
            for lane in 0..lanes {
                if let Some((min, max)) = view.boxes.decode(&frame, first_block + group + lane) {
                    for axis in 0..3 {
                        boxes.0[axis][lane] = min[axis];
                        boxes.1[axis][lane] = max[axis];
                    }
                }
            }
            let entered = self.entered(&boxes) & ((1 << lanes) - 1);
            mask |= u64::from(entered) << group;
        }
        mask
    }

    /// The boxes the ray may meet within its grown interval, each grown by [`MARGIN`] (module
    /// documentation), as a bit mask. A NaN plane (only in a corrupt box) is entered.
    #[inline(always)]
    fn entered(&self, (min, max): &FourBoxes) -> u32 {
        let low = [0, 1, 2].map(|axis| f32x4::from(min[axis]) - self.origin[axis]);
        let high = [0, 1, 2].map(|axis| f32x4::from(max[axis]) - self.origin[axis]);
        let reach = |axis: usize| low[axis].abs() + high[axis].abs();
        let widen = (reach(0) + reach(1) + reach(2)) * f32x4::splat(MARGIN);
        let mut near = f32x4::splat(self.t_near);
        let mut far = f32x4::splat(self.t_far);
        for axis in 0..3 {
            let (low, high) = (low[axis] - widen, high[axis] + widen);
            let (entry, exit) = match self.negative[axis] {
                true => (high, low),
                false => (low, high),
            };
            let entry = entry * self.entry_reciprocal[axis];
            let exit = exit * self.exit_reciprocal[axis] * f32x4::splat(FAR_INFLATION);
            near = max_not_nan_x4(near, entry);
            far = min_not_nan_x4(far, exit);
        }
        near.simd_le(far).to_bitmask()
    }
}

/// Windows per block box (format 3).
const BLOCK_WINDOWS: usize = crate::format::block_boxes::BOX_WINDOWS;

// The four lanes of a box test are a node's four slots.
const _: () = assert!(TOP_WIDTH == 4);

/// A node's child boxes axis by axis.
#[inline(always)]
fn child_boxes<N: ChildBox>(node: &N, grid: &N::Grid) -> FourBoxes {
    let mut boxes: FourBoxes = ([[0.0; 4]; 3], [[0.0; 4]; 3]);
    for slot in 0..TOP_WIDTH {
        let (min, max) = node.child_box(slot, grid);
        for axis in 0..3 {
            boxes.0[axis][slot] = min[axis];
            boxes.1[axis][slot] = max[axis];
        }
    }
    boxes
}

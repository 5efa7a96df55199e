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

use wide::{f32x4, i32x4};

use super::child_box::ChildBox;
use super::top_walk::{dispatch_top_walk, QueryNode, TopWalk};
use crate::format::block_boxes::{
    BlockBoxes, BoxFrame, BOX_BYTES, BOX_WINDOWS, CODE_BIAS, EXPONENT_BYTES, MAX_CODE,
};
use crate::format::grid::NodeGrid;
use crate::format::reader::{ReducemFile, StripView};
use crate::format::vertices::{StripVertices, VertexAccess};
use crate::format::{GridNode, TopNode, TopSlot, WideNode, INTERNAL_CHILD, TOP_WIDTH};
use crate::geometry::Point;
use crate::trace::kernel::crossing_blocks::{StripBlocks, MASK_BLOCKS};
use crate::trace::kernel::crossing_nodes::WidenedRay;
use crate::trace::kernel::query_kernel::QueryKernel;
use crate::trace::kernel::query_prefetch::{ChildPrefetch, QuerySections};
use crate::trace::kernel::Kernel;
use crate::trace::prepared::{max_not_nan_x4, min_not_nan_x4, PreparedRay, FAR_INFLATION};
use crate::trace::watertight::{RayPoint, RaySpace};
use crate::trace::Ray;

/// Relative growth of boxes and of the ray's interval: far above the few f32 roundings of the
/// ray-space transform and of the slab test.
const MARGIN: f32 = 1.0 / 65_536.0;

/// Leaves queued before the walk views the oldest: their strips' records and blocks are asked
/// for from memory when queued and arrive meanwhile.
pub(super) const LEAVES_AHEAD: usize = 4;

/// How many leaves before its turn a leaf's block is asked for (its record was asked for when
/// it was queued).
pub(super) const BLOCKS_AHEAD: usize = 2;

/// Boxes tested together, in the lanes of one register.
pub(super) const BOX_LANES: usize = 4;

/// Four boxes axis by axis: `min[axis][box]`, `max[axis][box]`.
pub(super) type FourBoxes = ([[f32; BOX_LANES]; 3], [[f32; BOX_LANES]; 3]);

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
    /// The same test's inputs for the kernels that clip a wide node's eight boxes at once.
    widened: WidenedRay,
}

impl CrossingWalk {
    pub(super) fn new(ray: &Ray, kernel: Kernel) -> CrossingWalk {
        let prepared = PreparedRay::new(ray);
        let splat = |v: &Point| v.map(f32x4::splat);
        let (t_near, t_far) = (ray.tmin * (1.0 - MARGIN), ray.tmax * (1.0 + MARGIN));
        CrossingWalk {
            kernel,
            space: prepared.space,
            range: (ray.tmin, ray.tmax),
            origin: splat(&ray.origin),
            entry_reciprocal: splat(&prepared.entry_reciprocal),
            exit_reciprocal: splat(&prepared.exit_reciprocal),
            negative: prepared.negative,
            t_near,
            t_far,
            widened: WidenedRay {
                origin: ray.origin,
                entry_reciprocal: prepared.entry_reciprocal,
                exit_reciprocal: prepared.exit_reciprocal,
                negative: prepared.negative,
                t_near,
                t_far,
                margin: MARGIN,
                far_inflation: FAR_INFLATION,
            },
        }
    }

    /// Calls `each(strip, window, corners)` for every candidate window of the file (see
    /// [`QueryKernel::for_each_candidate`]); corrupt nodes reached are skipped as in tracing.
    /// The whole walk is compiled once for the kernel, its tests inlined; `sections` are
    /// `file`'s.
    pub(super) fn run(
        &self,
        file: &ReducemFile,
        sections: &QuerySections,
        each: &mut impl FnMut(u32, usize, [RayPoint; 3]),
    ) {
        dispatch_top_walk(
            self.kernel,
            file,
            FileWalk {
                walk: self,
                file,
                sections,
                each,
            },
        )
    }

    #[inline(always)]
    fn nodes<N: NodeBoxes, Q: QueryKernel>(
        &self,
        (file, sections): (&ReducemFile, &QuerySections),
        nodes: &[N],
        grid: &N::Grid,
        each: &mut impl FnMut(u32, usize, [RayPoint; 3]),
    ) {
        if nodes.is_empty() {
            return;
        }
        let prefetch = ChildPrefetch::new(sections, nodes);
        let mut pending_nodes = Pending::<u32, 64>::default();
        let mut pending_leaves = Pending::<(u32, u32), 32>::default();
        pending_nodes.push(0);
        let mut visits = file.node_visits();
        loop {
            if pending_leaves.len() > LEAVES_AHEAD || pending_nodes.is_empty() {
                let Some((first, count)) = pending_leaves.pop() else {
                    return;
                };
                if let Some((later, _)) = pending_leaves.get(BLOCKS_AHEAD - 1) {
                    prefetch.leaf_block(later);
                }
                for strip in sections.leaf_strips(first, count) {
                    self.strip::<Q>(file, strip, each);
                }
                continue;
            }
            let Some(index) = pending_nodes.pop() else {
                return;
            };
            // A file changed in place after its validation may link nodes in circles.
            visits = match visits.checked_sub(1) {
                Some(left) => left,
                None => return,
            };
            let Some(node) = file.top_node(nodes, index as usize) else {
                continue;
            };
            let mut entered = node.entered_children::<Q>(self, grid);
            while entered != 0 {
                let slot = entered.trailing_zeros();
                entered &= entered - 1;
                match node.slot(slot as usize) {
                    TopSlot::Internal(child) => {
                        prefetch.child((child, INTERNAL_CHILD));
                        pending_nodes.push(child);
                    }
                    TopSlot::Leaf { first, count } => {
                        match pending_leaves.len() < BLOCKS_AHEAD {
                            true => prefetch.leaf_block(first),
                            false => prefetch.leaf_record(first),
                        }
                        pending_leaves.push((first, count));
                    }
                    TopSlot::Empty | TopSlot::Invalid(_) => {}
                }
            }
        }
    }

    /// The candidate windows of strip `strip` in the blocks whose box the ray may meet (every
    /// block when the strip stores no boxes).
    #[inline(always)]
    pub(super) fn strip<Q: QueryKernel>(
        &self,
        file: &ReducemFile,
        strip: u32,
        each: &mut impl FnMut(u32, usize, [RayPoint; 3]),
    ) {
        let view = file.strip(strip as usize);
        let blocks = view.window_count().div_ceil(BOX_WINDOWS);
        let mut candidate = |window: usize, corners: [RayPoint; 3]| each(strip, window, corners);
        // A plain loop: a `step_by` range's set-up costs as much as a strip's one pass.
        let mut first_block = 0;
        while first_block < blocks {
            let count = (blocks - first_block).min(MASK_BLOCKS);
            let mask = match view.boxes.is_empty() {
                true => u64::MAX >> (MASK_BLOCKS - count),
                false => self.entered_blocks(&view, first_block, count),
            };
            self.candidates::<Q>(&view, first_block, mask, &mut candidate);
            first_block += MASK_BLOCKS;
        }
    }

    /// Calls `each(window, corners)` for the candidate windows of the blocks of `mask` (bit
    /// `k`: block `first_block + k`) of `view`.
    #[inline(always)]
    pub(super) fn candidates<Q: QueryKernel>(
        &self,
        view: &StripView,
        first_block: usize,
        mask: u64,
        each: &mut impl FnMut(usize, [RayPoint; 3]),
    ) {
        if mask != 0 {
            let blocks = StripBlocks {
                view,
                mask,
                first_block,
            };
            Q::for_each_candidate(&self.space, self.range, blocks, each);
        }
    }

    /// Of the `count` blocks from `first_block`, those whose box the ray may meet (all when
    /// the boxes cannot be framed or read: only in a corrupt strip, which validation reports),
    /// four blocks to a node's test: a strip's few blocks cost one or two of them.
    #[inline(always)]
    fn entered_blocks(&self, view: &StripView, first_block: usize, count: usize) -> u64 {
        let all = u64::MAX >> (MASK_BLOCKS - count);
        let Some(frame) = box_frame(view) else {
            return all;
        };
        let mut mask = 0u64;
        let mut first = 0;
        while first < count {
            let lanes = (count - first).min(BOX_LANES);
            let (boxes, unreadable) = block_boxes(&view.boxes, &frame, first_block + first, lanes);
            mask |= u64::from(self.entered(&boxes) | unreadable) << first;
            first += BOX_LANES;
        }
        mask & all
    }

    /// The boxes the ray may meet within its grown interval, each grown by [`MARGIN`] (module
    /// documentation), as a bit mask. A NaN plane (only in a corrupt box) is entered.
    #[inline(always)]
    pub(super) fn entered(&self, (min, max): &FourBoxes) -> u32 {
        // Arrays written out: as `[0, 1, 2].map` the compiler may leave them out of line.
        let relative = |planes: &[[f32; BOX_LANES]; 3], axis: usize| {
            f32x4::from(planes[axis]) - self.origin[axis]
        };
        let low = [relative(min, 0), relative(min, 1), relative(min, 2)];
        let high = [relative(max, 0), relative(max, 1), relative(max, 2)];
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

/// [`CrossingWalk::run`]'s walk of one file, for [`dispatch_top_walk`].
struct FileWalk<'w, 'f, F> {
    walk: &'w CrossingWalk,
    file: &'f ReducemFile,
    sections: &'w QuerySections<'f>,
    each: &'w mut F,
}

impl<F: FnMut(u32, usize, [RayPoint; 3])> TopWalk for FileWalk<'_, '_, F> {
    type Output = ();

    #[inline(always)]
    fn run<Q: QueryKernel, N: QueryNode>(self, nodes: &[N], grid: &N::Grid) {
        let FileWalk {
            walk,
            file,
            sections,
            each,
        } = self;
        walk.nodes::<_, Q>((file, sections), nodes, grid, each)
    }
}

/// The frame `view`'s block boxes are decoded in; `None` when it cannot be read (only in a
/// corrupt strip, which validation reports).
#[inline(always)]
pub(super) fn box_frame(view: &StripView) -> Option<BoxFrame> {
    let anchor = match view.vertices {
        StripVertices::F32(vertices) => vertices.point(0),
        StripVertices::Grid(vertices) => vertices.point(0),
    };
    view.boxes.frame(anchor)
}

/// Blocks `first .. first + lanes` of a strip's boxes (`lanes <= 4`) decoded in `frame` axis
/// by axis, as [`crate::format::block_boxes::decode_plane`] does, bit for bit (the code minus
/// the bias and its product by the power-of-two scale are exact, the sum rounds once); and the
/// lanes whose box cannot be read (bit `k` for block `first + k`).
#[inline(always)]
pub(super) fn block_boxes(
    boxes: &BlockBoxes,
    frame: &BoxFrame,
    first: usize,
    lanes: usize,
) -> (FourBoxes, u32) {
    let mut codes = [[0i32; BOX_LANES]; 3];
    let mut unreadable = 0;
    // All the lanes' codes in one bounds check when they are stored (always but in a corrupt
    // strip), rather than one per box.
    let start = EXPONENT_BYTES + BOX_BYTES * first;
    match boxes.bytes().get(start..start + BOX_BYTES * lanes) {
        Some(run) => {
            for (lane, box_codes) in run.chunks_exact(BOX_BYTES).enumerate() {
                (0..3).for_each(|axis| codes[axis][lane] = i32::from(box_codes[axis]));
            }
        }
        None => {
            for (lane, block) in (first..first + lanes).enumerate() {
                match boxes.codes(block) {
                    Some(box_codes) => {
                        (0..3).for_each(|axis| codes[axis][lane] = i32::from(box_codes[axis]))
                    }
                    None => unreadable |= 1 << lane,
                }
            }
        }
    }
    let planes = |axis: usize| {
        let bytes = i32x4::from(codes[axis]);
        let decode = |code: i32x4| {
            let offset = (code - i32x4::splat(CODE_BIAS)).round_float();
            (f32x4::splat(frame.anchor[axis]) + offset * f32x4::splat(frame.scale[axis])).to_array()
        };
        (
            decode(bytes & i32x4::splat(i32::from(MAX_CODE))),
            decode(bytes >> 4),
        )
    };
    let axes = [0, 1, 2].map(planes);
    (
        (axes.map(|(min, _)| min), axes.map(|(_, max)| max)),
        unreadable,
    )
}

/// Work pending in an unordered walk, first in first out (so that what was asked for from
/// memory when it was queued has time to arrive): inline, then on the heap once more are
/// pending than the ring holds (a ray that enters many nodes of one level, as along a surface).
pub(super) struct Pending<T, const N: usize> {
    ring: [T; N],
    head: usize,
    inline: usize,
    spill: Vec<T>,
}

impl<T: Copy + Default, const N: usize> Default for Pending<T, N> {
    fn default() -> Self {
        Pending {
            ring: [T::default(); N],
            head: 0,
            inline: 0,
            spill: Vec::new(),
        }
    }
}

impl<T: Copy, const N: usize> Pending<T, N> {
    #[inline(always)]
    pub(super) fn push(&mut self, item: T) {
        match self.inline < N {
            true => {
                self.ring[(self.head + self.inline) % N] = item;
                self.inline += 1;
            }
            false => self.spill.push(item),
        }
    }

    /// The oldest inline item, then the spilled ones.
    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<T> {
        if self.inline == 0 {
            return self.spill.pop();
        }
        let item = self.ring[self.head];
        self.head = (self.head + 1) % N;
        self.inline -= 1;
        Some(item)
    }

    /// The item `k` places after the next one to pop, when inline.
    #[inline(always)]
    pub(super) fn get(&self, k: usize) -> Option<T> {
        (k < self.inline).then(|| self.ring[(self.head + k) % N])
    }

    #[inline(always)]
    pub(super) fn len(&self) -> usize {
        self.inline + self.spill.len()
    }

    #[inline(always)]
    pub(super) fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A top-level node record's child boxes as the walk tests them, whatever its layout: the
/// walk's one view of the nodes.
pub(super) trait NodeBoxes: ChildBox {
    /// The children whose box `walk`'s ray may meet ([`CrossingWalk::entered`]), as a bit mask.
    fn entered_children<Q: QueryKernel>(&self, walk: &CrossingWalk, grid: &Self::Grid) -> u32;
}

impl NodeBoxes for TopNode {
    #[inline(always)]
    fn entered_children<Q: QueryKernel>(&self, walk: &CrossingWalk, _: &()) -> u32 {
        walk.entered(&(self.min, self.max))
    }
}

impl NodeBoxes for GridNode {
    /// Through [`NodeGrid::decode_axis`], the expression the writer rounded the boxes outward
    /// with.
    #[inline(always)]
    fn entered_children<Q: QueryKernel>(&self, walk: &CrossingWalk, grid: &NodeGrid) -> u32 {
        let decode = |q: &[[u16; TOP_WIDTH]; 3]| {
            std::array::from_fn(|axis| q[axis].map(|q| grid.decode_axis(q, axis)))
        };
        walk.entered(&(decode(&self.min), decode(&self.max)))
    }
}

impl NodeBoxes for WideNode {
    /// The eight boxes at once in the kernel's lanes, [`WideNode::decode`]'s bits.
    #[inline(always)]
    fn entered_children<Q: QueryKernel>(&self, walk: &CrossingWalk, _: &()) -> u32 {
        Q::entered_wide(&walk.widened, self, |boxes| walk.entered(boxes))
    }
}

// The four lanes of a box test are a node's four slots.
const _: () = assert!(TOP_WIDTH == 4);

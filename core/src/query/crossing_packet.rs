//! Up to eight rays walked together to every window each may cross: one visit of a node, one
//! view of a strip and one decoding of its block boxes serve every ray that reaches them, while
//! each ray keeps its own box tests and edge tests ([`CrossingWalk`]). A ray is offered exactly
//! the candidates its own walk would find, so its crossings are the same bits on any kernel.
//!
//! It pays where the rays are coherent: occupancy rays share a direction and leave nearby
//! points (answered along a Morton curve), so they reach mostly the same nodes and strips.

use arrayvec::ArrayVec;

use super::crossing_walk::{
    block_boxes, box_frame, CrossingWalk, NodeBoxes, Pending, BLOCKS_AHEAD, BOX_LANES, LEAVES_AHEAD,
};
use super::top_walk::{dispatch_top_walk, QueryNode, TopWalk};
use crate::format::block_boxes::BOX_WINDOWS;
use crate::format::reader::{ReducemFile, StripView};
use crate::format::{TopSlot, INTERNAL_CHILD, WIDE_WIDTH};
use crate::trace::kernel::crossing_blocks::MASK_BLOCKS;
use crate::trace::kernel::query_kernel::QueryKernel;
use crate::trace::kernel::query_prefetch::{ChildPrefetch, QuerySections};
use crate::trace::kernel::Kernel;
use crate::trace::watertight::RayPoint;
use crate::trace::Ray;

/// Rays walked together.
pub const PACKET_RAYS: usize = 8;

/// A bit per ray of a packet.
type Lanes = u32;

/// The walks of a packet's rays; lane `k` is ray `k`.
pub(super) struct CrossingPacket {
    kernel: Kernel,
    walks: ArrayVec<CrossingWalk, PACKET_RAYS>,
    /// The lanes whose ray is valid: the others cross nothing and are never walked.
    valid: Lanes,
}

impl CrossingPacket {
    /// The packet of `rays` (at most [`PACKET_RAYS`]); `valid(ray)` says which are walked.
    pub(super) fn new(rays: &[Ray], kernel: Kernel, valid: impl Fn(&Ray) -> bool) -> Self {
        // An invalid ray's lane holds a harmless ray it never walks.
        let stand_in = Ray {
            origin: [0.0; 3],
            direction: [1.0, 0.0, 0.0],
            tmin: 0.0,
            tmax: 0.0,
        };
        let mut packet = CrossingPacket {
            kernel,
            walks: ArrayVec::new(),
            valid: 0,
        };
        for (lane, ray) in rays.iter().take(PACKET_RAYS).enumerate() {
            let walked = valid(ray);
            packet.valid |= Lanes::from(walked) << lane;
            let ray = if walked { ray } else { &stand_in };
            packet.walks.push(CrossingWalk::new(ray, kernel));
        }
        packet
    }

    /// Calls `each(lane, strip, window, corners)` for every candidate window of every valid
    /// lane's ray, as [`CrossingWalk::run`] of that ray calls it (in another order).
    pub(super) fn run(
        &self,
        file: &ReducemFile,
        each: &mut impl FnMut(usize, u32, usize, [RayPoint; 3]),
    ) {
        let walk = PacketWalk {
            packet: self,
            file,
            each,
        };
        dispatch_top_walk(self.kernel, file, walk)
    }

    #[inline(always)]
    fn nodes<N: NodeBoxes, Q: QueryKernel>(
        &self,
        file: &ReducemFile,
        nodes: &[N],
        grid: &N::Grid,
        each: &mut impl FnMut(usize, u32, usize, [RayPoint; 3]),
    ) {
        if nodes.is_empty() || self.valid == 0 {
            return;
        }
        let sections = QuerySections::new(file);
        let prefetch = ChildPrefetch::new(&sections, nodes);
        let mut pending_nodes = Pending::<(u32, Lanes), 64>::default();
        let mut pending_leaves = Pending::<((u32, u32), Lanes), 32>::default();
        pending_nodes.push((0, self.valid));
        let mut visits = file.node_visits();
        loop {
            if pending_leaves.len() > LEAVES_AHEAD || pending_nodes.is_empty() {
                let Some(((first, count), lanes)) = pending_leaves.pop() else {
                    return;
                };
                if let Some(((later, _), _)) = pending_leaves.get(BLOCKS_AHEAD - 1) {
                    prefetch.leaf_block(later);
                }
                for strip in sections.leaf_strips(first, count) {
                    self.strip::<Q>(file, strip, lanes, each);
                }
                continue;
            }
            let Some((index, lanes)) = pending_nodes.pop() else {
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
            let mut by_slot = [0 as Lanes; WIDE_WIDTH];
            let mut entered_any = 0u32;
            for_each_lane(lanes, |lane| {
                let mut entered = node.entered_children::<Q>(&self.walks[lane], grid);
                entered_any |= entered;
                while entered != 0 {
                    by_slot[entered.trailing_zeros() as usize] |= 1 << lane;
                    entered &= entered - 1;
                }
            });
            while entered_any != 0 {
                let slot = entered_any.trailing_zeros();
                entered_any &= entered_any - 1;
                match node.slot(slot as usize) {
                    TopSlot::Internal(child) => {
                        prefetch.child((child, INTERNAL_CHILD));
                        pending_nodes.push((child, by_slot[slot as usize]));
                    }
                    TopSlot::Leaf { first, count } => {
                        match pending_leaves.len() < BLOCKS_AHEAD {
                            true => prefetch.leaf_block(first),
                            false => prefetch.leaf_record(first),
                        }
                        pending_leaves.push(((first, count), by_slot[slot as usize]));
                    }
                    TopSlot::Empty | TopSlot::Invalid(_) => {}
                }
            }
        }
    }

    /// The candidate windows of strip `strip` for the rays of `lanes`: the strip viewed once,
    /// each group of its block boxes decoded once and tested by every lane.
    #[inline(always)]
    fn strip<Q: QueryKernel>(
        &self,
        file: &ReducemFile,
        strip: u32,
        lanes: Lanes,
        each: &mut impl FnMut(usize, u32, usize, [RayPoint; 3]),
    ) {
        let view = file.strip(strip as usize);
        let blocks = view.window_count().div_ceil(BOX_WINDOWS);
        // Plain loops here and over the block boxes, as in `CrossingWalk`.
        let mut first_block = 0;
        while first_block < blocks {
            let count = (blocks - first_block).min(MASK_BLOCKS);
            let masks = self.entered_blocks(&view, lanes, first_block, count);
            // A plain loop: as a closure, this body (the kernel's block tests inlined) was
            // compiled out of line.
            let mut walked = lanes;
            while walked != 0 {
                let lane = walked.trailing_zeros() as usize;
                walked &= walked - 1;
                let mut candidate =
                    |window: usize, corners: [RayPoint; 3]| each(lane, strip, window, corners);
                self.walks[lane].candidates::<Q>(&view, first_block, masks[lane], &mut candidate);
            }
            first_block += MASK_BLOCKS;
        }
    }

    /// Per lane of `lanes`, the blocks of `first_block .. first_block + count` its ray may
    /// meet, as [`CrossingWalk`]'s own test finds them (every block when the strip stores no
    /// boxes or their frame cannot be read).
    #[inline(always)]
    fn entered_blocks(
        &self,
        view: &StripView,
        lanes: Lanes,
        first_block: usize,
        count: usize,
    ) -> [u64; PACKET_RAYS] {
        let all = u64::MAX >> (MASK_BLOCKS - count);
        let frame = match view.boxes.is_empty() {
            true => None,
            false => box_frame(view),
        };
        let Some(frame) = frame else {
            return [all; PACKET_RAYS];
        };
        let mut masks = [0u64; PACKET_RAYS];
        let mut first = 0;
        while first < count {
            let group = (count - first).min(BOX_LANES);
            let (boxes, unreadable) = block_boxes(&view.boxes, &frame, first_block + first, group);
            for_each_lane(lanes, |lane| {
                let entered = self.walks[lane].entered(&boxes) | unreadable;
                masks[lane] |= u64::from(entered) << first;
            });
            first += BOX_LANES;
        }
        masks.map(|mask| mask & all)
    }
}

/// Calls `each(lane)` for every bit of `lanes`, lowest first.
#[inline(always)]
fn for_each_lane(mut lanes: Lanes, mut each: impl FnMut(usize)) {
    while lanes != 0 {
        each(lanes.trailing_zeros() as usize);
        lanes &= lanes - 1;
    }
}

/// [`CrossingPacket::run`]'s walk of one file, for [`dispatch_top_walk`].
struct PacketWalk<'p, 'f, F> {
    packet: &'p CrossingPacket,
    file: &'f ReducemFile,
    each: &'p mut F,
}

impl<F: FnMut(usize, u32, usize, [RayPoint; 3])> TopWalk for PacketWalk<'_, '_, F> {
    type Output = ();

    #[inline(always)]
    fn run<Q: QueryKernel, N: QueryNode>(self, nodes: &[N], grid: &N::Grid) {
        let PacketWalk { packet, file, each } = self;
        packet.nodes::<_, Q>(file, nodes, grid, each)
    }
}

//! Several rays' walks interleaved in one thread ([`CrossingStream`]): their nodes and leaves
//! share the first-in-first-out queues of [`CrossingWalk`], so that the memory each queued item
//! was asked for has the other rays' steps to arrive in, not one ray's few. Incoherent rays (as
//! counting takes them) wait on memory far more than they compute; a ray that finishes hands
//! its slot to the next ray of the batch, so the queues stay full to the batch's end.
//!
//! Each ray keeps its own box and edge tests, so it is offered exactly the candidates its own
//! walk finds, in another order.

use super::crossing_walk::{CrossingWalk, NodeBoxes, Pending, BLOCKS_AHEAD};
use super::top_walk::{dispatch_top_walk, QueryNode, TopWalk};
use crate::format::reader::ReducemFile;
use crate::format::{TopSlot, INTERNAL_CHILD};
use crate::trace::kernel::query_kernel::QueryKernel;
use crate::trace::kernel::query_prefetch::{ChildPrefetch, QuerySections};
use crate::trace::kernel::Kernel;
use crate::trace::watertight::RayPoint;
use crate::trace::Ray;

/// Rays walked at once by one thread.
pub(super) const STREAM_RAYS: usize = 4;

/// Leaves queued before the stream views the oldest, for all its rays together.
const STREAM_LEAVES_AHEAD: usize = 4 * STREAM_RAYS;

/// The node queue: the root of every ray and the nodes they enter, with their slots.
type PendingNodes = Pending<(u32, u32), 256>;

/// The leaf queue: `(first strip, strip count)` and the slot of the ray that entered it.
type PendingLeaves = Pending<((u32, u32), u32), 128>;

/// One ray walking in a slot of the stream. A slot whose ray is done and that the batch has
/// no ray left for has nothing queued, so no item names it.
struct Slot {
    /// The ray's index in the batch.
    ray: usize,
    walk: CrossingWalk,
    /// The ray's queued nodes and leaves: the slot takes the next ray when none is left.
    queued: u32,
    /// Node visits left before the walk is cut short (a file linking nodes in circles).
    visits: usize,
    /// Cut short: its queued items are dropped as they come, as the walk alone drops them.
    cut: bool,
}

/// The walks of a batch of rays, [`STREAM_RAYS`] at a time.
pub(super) struct CrossingStream<'r, V> {
    rays: &'r [Ray],
    kernel: Kernel,
    /// Which rays are walked: the others cross nothing.
    valid: V,
}

impl<'r, V: Fn(&Ray) -> bool> CrossingStream<'r, V> {
    pub(super) fn new(rays: &'r [Ray], kernel: Kernel, valid: V) -> Self {
        CrossingStream {
            rays,
            kernel,
            valid,
        }
    }

    /// Calls `each(ray, strip, window, corners)` for every candidate window of every valid ray
    /// (`ray` its index in the batch), as [`CrossingWalk::run`] of that ray calls it (in another
    /// order).
    pub(super) fn run(
        &self,
        file: &ReducemFile,
        sections: &QuerySections,
        each: &mut impl FnMut(usize, u32, usize, [RayPoint; 3]),
    ) {
        dispatch_top_walk(
            self.kernel,
            file,
            StreamWalk {
                stream: self,
                file,
                sections,
                each,
            },
        )
    }

    /// Gives slot `k` the first valid ray from `*next` on (`*next` moved past it) and queues
    /// its root; leaves the slot idle when the batch has no ray left. Out of line: once a ray,
    /// it would crowd the node test out of the walk's loop.
    #[inline(never)]
    fn start(
        &self,
        (slot, k): (&mut Slot, u32),
        next: &mut usize,
        visits: usize,
        pending_nodes: &mut PendingNodes,
    ) {
        while let Some(ray) = self.rays.get(*next) {
            *next += 1;
            if (self.valid)(ray) {
                slot.ray = *next - 1;
                slot.walk = CrossingWalk::new(ray, self.kernel);
                slot.queued = 1;
                slot.visits = visits;
                slot.cut = false;
                pending_nodes.push((0, k));
                return;
            }
        }
    }

    #[inline(always)]
    fn nodes<N: NodeBoxes, Q: QueryKernel>(
        &self,
        (file, sections): (&ReducemFile, &QuerySections),
        nodes: &[N],
        grid: &N::Grid,
        each: &mut impl FnMut(usize, u32, usize, [RayPoint; 3]),
    ) {
        if nodes.is_empty() {
            return;
        }
        let prefetch = ChildPrefetch::new(sections, nodes);
        let mut pending_nodes = PendingNodes::default();
        let mut pending_leaves = PendingLeaves::default();
        let visits = file.node_visits();
        let mut next = 0;
        let idle = || Slot {
            ray: 0,
            walk: CrossingWalk::new(&IDLE_RAY, self.kernel),
            queued: 0,
            visits: 0,
            cut: true,
        };
        let mut slots: [Slot; STREAM_RAYS] = std::array::from_fn(|_| idle());
        for (k, slot) in slots.iter_mut().enumerate() {
            self.start((slot, k as u32), &mut next, visits, &mut pending_nodes);
        }
        loop {
            if pending_leaves.len() > STREAM_LEAVES_AHEAD || pending_nodes.is_empty() {
                let Some(((first, count), k)) = pending_leaves.pop() else {
                    return;
                };
                if let Some((later, _)) = pending_leaves.get(BLOCKS_AHEAD - 1) {
                    prefetch.leaf_block(later.0);
                }
                let slot = &mut slots[k as usize % STREAM_RAYS];
                if !slot.cut {
                    let ray = slot.ray;
                    let mut candidate = |strip, window, corners| each(ray, strip, window, corners);
                    for strip in sections.leaf_strips(first, count) {
                        slot.walk.strip::<Q>(file, strip, &mut candidate);
                    }
                }
                self.done((slot, k), &mut next, visits, &mut pending_nodes);
                continue;
            }
            let Some((index, k)) = pending_nodes.pop() else {
                return;
            };
            let slot = &mut slots[k as usize % STREAM_RAYS];
            if !slot.cut {
                match slot.visits.checked_sub(1) {
                    Some(left) => {
                        slot.visits = left;
                        let on = (file, &prefetch, nodes, grid);
                        self.visit::<N, Q>(
                            on,
                            index,
                            (slot, k),
                            &mut pending_nodes,
                            &mut pending_leaves,
                        );
                    }
                    // A file changed in place after its validation may link nodes in circles.
                    None => slot.cut = true,
                }
            }
            self.done((slot, k), &mut next, visits, &mut pending_nodes);
        }
    }

    /// Tests node `index` for the ray of slot `k` and queues the children it enters.
    #[inline(always)]
    fn visit<N: NodeBoxes, Q: QueryKernel>(
        &self,
        (file, prefetch, nodes, grid): (&ReducemFile, &ChildPrefetch<N>, &[N], &N::Grid),
        index: u32,
        (slot, k): (&mut Slot, u32),
        pending_nodes: &mut PendingNodes,
        pending_leaves: &mut PendingLeaves,
    ) {
        let Some(node) = file.top_node(nodes, index as usize) else {
            return;
        };
        let mut entered = node.entered_children::<Q>(&slot.walk, grid);
        while entered != 0 {
            let child = entered.trailing_zeros();
            entered &= entered - 1;
            match node.slot(child as usize) {
                TopSlot::Internal(child) => {
                    prefetch.child((child, INTERNAL_CHILD));
                    pending_nodes.push((child, k));
                    slot.queued += 1;
                }
                TopSlot::Leaf { first, count } => {
                    match pending_leaves.len() < BLOCKS_AHEAD {
                        true => prefetch.leaf_block(first),
                        false => prefetch.leaf_record(first),
                    }
                    pending_leaves.push(((first, count), k));
                    slot.queued += 1;
                }
                TopSlot::Empty | TopSlot::Invalid(_) => {}
            }
        }
    }

    /// One queued item of slot `k` walked: when it was the slot's last, the next ray of the
    /// batch takes the slot.
    #[inline(always)]
    fn done(
        &self,
        (slot, k): (&mut Slot, u32),
        next: &mut usize,
        visits: usize,
        pending_nodes: &mut PendingNodes,
    ) {
        slot.queued -= 1;
        if slot.queued == 0 {
            self.start((slot, k), next, visits, pending_nodes);
        }
    }
}

/// The ray of an idle slot, never walked.
const IDLE_RAY: Ray = Ray {
    origin: [0.0; 3],
    direction: [1.0, 0.0, 0.0],
    tmin: 0.0,
    tmax: 0.0,
};

/// [`CrossingStream::run`]'s walk of one file, for [`dispatch_top_walk`].
struct StreamWalk<'s, 'r, 'f, V, F> {
    stream: &'s CrossingStream<'r, V>,
    file: &'f ReducemFile,
    sections: &'s QuerySections<'f>,
    each: &'s mut F,
}

impl<V: Fn(&Ray) -> bool, F: FnMut(usize, u32, usize, [RayPoint; 3])> TopWalk
    for StreamWalk<'_, '_, '_, V, F>
{
    type Output = ();

    #[inline(always)]
    fn run<Q: QueryKernel, N: QueryNode>(self, nodes: &[N], grid: &N::Grid) {
        let StreamWalk {
            stream,
            file,
            sections,
            each,
        } = self;
        stream.nodes::<_, Q>((file, sections), nodes, grid, each)
    }
}

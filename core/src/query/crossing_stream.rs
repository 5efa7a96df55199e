//! Several rays' walks interleaved in one thread ([`CrossingStream`]): their nodes and leaves
//! share the first-in-first-out queues of [`CrossingWalk`], so that the memory each queued item
//! was asked for has the other rays' steps to arrive in, not one ray's few. Incoherent rays (as
//! counting takes them) wait on memory far more than they compute; a ray that finishes hands
//! its slot to the next ray of the batch, so the queues stay full to the batch's end.
//!
//! Each ray keeps its own box and edge tests, so it is offered exactly the candidates its own
//! walk finds, in another order.

use super::crossing_walk::{CrossingWalk, NodeBoxes, Pending, BLOCKS_AHEAD};
use crate::format::reader::{ReducemFile, TopNodes};
use crate::format::{TopSlot, INTERNAL_CHILD};
use crate::trace::kernel::query_kernel::{dispatch_query, QueryKernel, QueryWalk};
use crate::trace::kernel::query_prefetch::{ChildPrefetch, QuerySections};
use crate::trace::kernel::Kernel;
use crate::trace::watertight::RayPoint;
use crate::trace::Ray;

/// Rays walked at once by one thread.
pub(super) const STREAM_RAYS: usize = 4;

/// Leaves queued before the stream views the oldest, for all its rays together.
const STREAM_LEAVES_AHEAD: usize = 4 * STREAM_RAYS;

/// One ray walking in a slot of the stream.
struct Slot {
    /// The ray's index in the batch.
    ray: usize,
    walk: CrossingWalk,
    /// The ray's queued nodes and leaves: the slot is free again when none is left.
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
        dispatch_query(
            self.kernel,
            StreamWalk {
                stream: self,
                file,
                sections,
                each,
            },
        )
    }

    /// The slot of the first valid ray from `*next` on (`*next` moved past it), its root
    /// queued; `None` when the batch has no ray left.
    #[inline(always)]
    fn start(
        &self,
        next: &mut usize,
        visits: usize,
        pending_nodes: &mut Pending<(u32, u32), 256>,
        slot: usize,
    ) -> Option<Slot> {
        while let Some(ray) = self.rays.get(*next) {
            *next += 1;
            if (self.valid)(ray) {
                pending_nodes.push((0, slot as u32));
                return Some(Slot {
                    ray: *next - 1,
                    walk: CrossingWalk::new(ray, self.kernel),
                    queued: 1,
                    visits,
                    cut: false,
                });
            }
        }
        None
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
        let mut pending_nodes = Pending::<(u32, u32), 256>::default();
        let mut pending_leaves = Pending::<((u32, u32), u32), 128>::default();
        let visits = file.node_visits();
        let mut next = 0;
        let mut slots: [Option<Slot>; STREAM_RAYS] = Default::default();
        for (k, slot) in slots.iter_mut().enumerate() {
            *slot = self.start(&mut next, visits, &mut pending_nodes, k);
        }
        loop {
            if pending_leaves.len() > STREAM_LEAVES_AHEAD || pending_nodes.is_empty() {
                let Some(((first, count), k)) = pending_leaves.pop() else {
                    return;
                };
                if let Some(((later, _), _)) = pending_leaves.get(BLOCKS_AHEAD - 1) {
                    prefetch.leaf_block(later);
                }
                if let Some(slot) = slots[k as usize].as_ref().filter(|slot| !slot.cut) {
                    let mut candidate =
                        |strip, window, corners| each(slot.ray, strip, window, corners);
                    for strip in sections.leaf_strips(first, count) {
                        slot.walk.strip::<Q>(file, strip, &mut candidate);
                    }
                }
                self.done(
                    &mut slots,
                    k as usize,
                    (&mut next, visits),
                    &mut pending_nodes,
                );
                continue;
            }
            let Some((index, k)) = pending_nodes.pop() else {
                return;
            };
            if let Some(slot) = slots[k as usize].as_mut().filter(|slot| !slot.cut) {
                if slot.visits > 0 {
                    slot.visits -= 1;
                    self.visit::<N, Q>(
                        (file, &prefetch, nodes, grid),
                        index,
                        (slot, k),
                        (&mut pending_nodes, &mut pending_leaves),
                    );
                } else {
                    // A file changed in place after its validation may link nodes in circles.
                    slot.cut = true;
                }
            }
            self.done(
                &mut slots,
                k as usize,
                (&mut next, visits),
                &mut pending_nodes,
            );
        }
    }

    /// Tests node `index` for the ray of `slot` (slot number `k`) and queues the children it
    /// enters.
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    fn visit<N: NodeBoxes, Q: QueryKernel>(
        &self,
        (file, prefetch, nodes, grid): (&ReducemFile, &ChildPrefetch<N>, &[N], &N::Grid),
        index: u32,
        (slot, k): (&mut Slot, u32),
        (pending_nodes, pending_leaves): (
            &mut Pending<(u32, u32), 256>,
            &mut Pending<((u32, u32), u32), 128>,
        ),
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
        slots: &mut [Option<Slot>; STREAM_RAYS],
        k: usize,
        (next, visits): (&mut usize, usize),
        pending_nodes: &mut Pending<(u32, u32), 256>,
    ) {
        let Some(slot) = &mut slots[k] else {
            return;
        };
        slot.queued -= 1;
        if slot.queued == 0 {
            slots[k] = self.start(next, visits, pending_nodes, k);
        }
    }
}

/// [`CrossingStream::run`]'s walk of one file, for [`dispatch_query`].
struct StreamWalk<'s, 'r, 'f, V, F> {
    stream: &'s CrossingStream<'r, V>,
    file: &'f ReducemFile,
    sections: &'s QuerySections<'f>,
    each: &'s mut F,
}

impl<V: Fn(&Ray) -> bool, F: FnMut(usize, u32, usize, [RayPoint; 3])> QueryWalk
    for StreamWalk<'_, '_, '_, V, F>
{
    type Output = ();

    #[inline(always)]
    fn run<Q: QueryKernel>(self) {
        let StreamWalk {
            stream,
            file,
            sections,
            each,
        } = self;
        let on = (file, sections);
        match file.top_nodes() {
            TopNodes::F32(nodes) => stream.nodes::<_, Q>(on, nodes, &(), each),
            TopNodes::Grid(nodes, grid) => stream.nodes::<_, Q>(on, nodes, &grid, each),
            TopNodes::Wide(nodes) => stream.nodes::<_, Q>(on, nodes, &(), each),
        }
    }
}

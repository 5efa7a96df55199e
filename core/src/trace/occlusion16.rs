//! Sixteen-ray occlusion packets: a hit point's sixteen ambient-occlusion rays (two packets of
//! eight sharing their origin) walk the global hierarchy together, for kernels whose occlusion
//! packets mix direction signs ([`TraceKernel::MIXED_OCCLUSION`]).
//!
//! The two halves keep the eight-lane packet's arithmetic (see [`super::packet`]): each half
//! clips a slot in its own eight lanes, with its own flips and the box of its own segments, so
//! each lane enters exactly the boxes its ray enters alone. What the halves share is the walk:
//! one stack, each node's planes decoded once (picked by the first half's lane 0, the second
//! half's flips taken against it), each strip viewed once for both halves' lanes. A subtree
//! entered by one lane of the sixteen is walked by that lane alone, as in the eight-lane
//! packet. Occlusion answers do not depend on the order of the visits, so the answers are the
//! eight-lane packets' and the single rays'.

use arrayvec::ArrayVec;
use wide::f32x8;

use super::closest::Closest;
use super::kernel::prefetch::Targets;
use super::kernel::{dispatch_mixed_occlusion, LeafLanes, LeafStrip, TraceKernel, Walk};
use super::lanes::{LaneRays, Lanes, PACKET_WIDTH};
use super::packet::{at_most_one, trace_packet, trace_strip_lanes};
use super::ray::Ray;
use super::top::{
    for_each_bit, trace_nodes, walk_top_level, DeferStack, Deferred, TopLevelWalk, TraceNode,
    MAX_WIDTH,
};
use super::Tracer;
use crate::format::INTERNAL_CHILD;

/// Rays walked together: two packets.
const PAIR_WIDTH: usize = 2 * PACKET_WIDTH;

/// The lanes of one half in a sixteen-lane mask.
const HALF_LANES: u32 = (1 << PACKET_WIDTH) - 1;

/// Traces `rays` for occlusion and gives ray `i`'s result to `answer(i, closest)`: sixteen
/// rays together where each of rays `16 k .. 16 k + 8` starts where the ray eight after it
/// does (bit for bit: one hit point's), else eight as an eight-lane packet.
pub(super) fn trace_occlusion(
    tracer: &Tracer,
    rays: &[Ray],
    mut answer: impl FnMut(usize, &Closest),
) {
    let mut pair = [[Closest::none(f32::NEG_INFINITY); PACKET_WIDTH]; 2];
    let mut start = 0;
    while start < rays.len() {
        let rest = &rays[start..];
        let sixteen = rest.first_chunk::<PAIR_WIDTH>().filter(|r| same_origin(r));
        if sixteen.is_some_and(|rays| trace_pair(tracer, rays, &mut pair)) {
            for (k, closest) in pair.iter().flatten().enumerate() {
                answer(start + k, closest);
            }
            start += PAIR_WIDTH;
        } else {
            let end = rest.len().min(PACKET_WIDTH);
            trace_packet(tracer, &rest[..end], true, &mut pair[0]);
            for (k, closest) in pair[0][..end].iter().enumerate() {
                answer(start + k, closest);
            }
            start += end;
        }
    }
}

/// Whether ray `i` of the first half starts where ray `i` of the second does, bit for bit, for
/// every `i`: the slot clips share the planes' differences from the origins.
fn same_origin(rays: &[Ray; PAIR_WIDTH]) -> bool {
    let bits = |ray: &Ray| ray.origin.map(f32::to_bits);
    let (first, second) = rays.split_at(PACKET_WIDTH);
    first.iter().zip(second).all(|(a, b)| bits(a) == bits(b))
}

/// Traces sixteen rays into `closest` (`closest[h][i]` for ray `8 h + i`), overwritten; false
/// (nothing traced) on a kernel whose occlusion packets keep one octant, for which the walk is
/// not compiled.
fn trace_pair(
    tracer: &Tracer,
    rays: &[Ray; PAIR_WIDTH],
    closest: &mut [[Closest; PACKET_WIDTH]; 2],
) -> bool {
    for (closest, ray) in closest.iter_mut().flatten().zip(rays) {
        *closest = Closest::none(ray.tmax);
    }
    let walk = PairWalk {
        tracer,
        rays,
        closest,
    };
    dispatch_mixed_occlusion(tracer.options().kernel, walk).is_some()
}

/// [`trace_pair`]'s walk, for the kernels to run.
struct PairWalk<'a, 't> {
    tracer: &'a Tracer<'t>,
    rays: &'a [Ray; PAIR_WIDTH],
    closest: &'a mut [[Closest; PACKET_WIDTH]; 2],
}

impl Walk for PairWalk<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run<K: TraceKernel>(self) {
        let (first, second) = self.rays.split_at(PACKET_WIDTH);
        let mut prepared = [K::prepared_rays(first), K::prepared_rays(second)];
        let lanes = [
            K::lanes(first, &prepared[0]),
            K::lanes(second, &prepared[1]),
        ];
        let walk = PairNodes {
            pair: &mut Pair::<K>::new(&lanes, self.closest),
            tracer: self.tracer,
            prepared: &mut prepared,
        };
        walk_top_level(self.tracer.file(), walk)
    }
}

/// [`PairWalk`]'s walk from the root, for [`walk_top_level`].
struct PairNodes<'p, 'l, 'c, 't, K: TraceKernel> {
    pair: &'p mut Pair<'l, 'c, K>,
    tracer: &'p Tracer<'t>,
    prepared: &'p mut [K::PreparedRays; 2],
}

impl<K: TraceKernel> TopLevelWalk for PairNodes<'_, '_, '_, '_, K> {
    type Output = ();

    #[inline(always)]
    fn run<N: TraceNode>(self, nodes: &[N], decoder: &N::Decoder) {
        self.pair.walk(self.tracer, (nodes, decoder), self.prepared)
    }
}

/// A leaf entered by some of the sixteen lanes (bit `8 h + i` for lane `i` of half `h`), with
/// each half's intervals in its box.
#[derive(Clone, Copy)]
struct PairLeaf {
    /// First strip and strip count, as a node's slot holds them.
    first: u32,
    count: u32,
    mask: u32,
    t_near: [f32x8; 2],
    t_far: [f32x8; 2],
}

/// An internal child entered: its node and lanes, without their intervals in its box (its
/// children are clipped over each lane's whole interval, as in the eight-lane packet).
#[derive(Clone, Copy)]
struct Internal {
    node: u32,
    mask: u32,
}

/// The two halves' lanes and what the kernel makes of them once.
struct Pair<'l, 'c, C: TraceKernel> {
    lanes: &'l [Lanes; 2],
    mixed: [C::Mixed; 2],
    together: [C::Together; 2],
    closest: &'c mut [[Closest; PACKET_WIDTH]; 2],
    /// The lanes that found an occluder.
    finished: u32,
    /// Each lane's culling bound, `-inf` once it finished.
    limit: [f32x8; 2],
}

impl<'l, 'c, C: TraceKernel> Pair<'l, 'c, C> {
    #[inline(always)]
    fn new(lanes: &'l [Lanes; 2], closest: &'c mut [[Closest; PACKET_WIDTH]; 2]) -> Self {
        let limit = limits(closest, 0);
        Pair {
            lanes,
            mixed: [
                C::mixed(&lanes[0], HALF_LANES, limit[0]),
                C::mixed_against(&lanes[1], HALF_LANES, limit[1], &lanes[0]),
            ],
            together: [C::together(&lanes[0]), C::together(&lanes[1])],
            closest,
            finished: 0,
            limit,
        }
    }

    /// Marks the lanes of `found` finished.
    #[inline(always)]
    fn finish(&mut self, found: u32) {
        if found != 0 {
            self.finished |= found;
            self.limit = limits(self.closest, self.finished);
        }
    }

    /// The walk of the global hierarchy. Unlike the eight-lane packet's walk, a node's leaves
    /// are traced before any of its internal children is entered (the order does not matter
    /// to occlusion), so that an internal child needs no intervals and a node step no stack
    /// of leaves.
    #[inline(always)]
    fn walk<N: TraceNode>(
        &mut self,
        tracer: &Tracer,
        (nodes, decoder): (&[N], &N::Decoder),
        prepared: &mut [C::PreparedRays; 2],
    ) {
        let mut internal = DeferStack::default();
        let mut leaves = ArrayVec::<PairLeaf, MAX_WIDTH>::new();
        let targets = Targets::new(tracer.strip_sections(), nodes);
        let mut current = Some(Internal {
            node: 0,
            mask: (1 << PAIR_WIDTH) - 1,
        });
        let mut visits = nodes.len();
        loop {
            if let Some(node) = current.take() {
                if at_most_one(node.mask) {
                    let found = self.walk_alone(tracer, (nodes, decoder), prepared, node);
                    self.finish(found);
                } else {
                    let Some(left) = visits.checked_sub(1) else {
                        return;
                    };
                    visits = left;
                    if let Some(record) = tracer.file().top_node(nodes, node.node as usize) {
                        let step = (&targets, &mut leaves, &mut internal);
                        current = self.enter_children(step, record, decoder, node.mask);
                    }
                }
            }
            while let Some(leaf) = leaves.pop() {
                let mask = leaf.mask & !self.finished;
                if mask != 0 {
                    let found = self.trace_leaf(tracer, prepared, &PairLeaf { mask, ..leaf });
                    self.finish(found);
                }
            }
            if let Some(node) = &mut current {
                node.mask &= !self.finished;
            }
            while current.is_none_or(|node| node.mask == 0) {
                let Some(node) = internal.pop() else {
                    return;
                };
                current = Some(Internal {
                    mask: node.mask & !self.finished,
                    ..node
                });
            }
        }
    }

    /// Clips the `active` lanes of each half against `node`'s occupied slots that the half's
    /// segments may reach; puts the leaves entered on `leaves`, returns the first internal
    /// child entered and defers the others on `internal`.
    #[inline(always)]
    fn enter_children<N: TraceNode>(
        &self,
        (targets, leaves, internal): (
            &Targets<N>,
            &mut ArrayVec<PairLeaf, MAX_WIDTH>,
            &mut DeferStack<Internal>,
        ),
        node: &N,
        decoder: &N::Decoder,
        active: u32,
    ) -> Option<Internal> {
        let occupied = (node.occupied_mask().trailing_ones() as usize).min(MAX_WIDTH);
        let occupied = (1u32 << occupied) - 1;
        let planes = node.planes::<C>(decoder, &self.lanes[0]);
        let halves = [active & HALF_LANES, active >> PACKET_WIDTH];
        let slots = C::mixed_slots_pair([&self.mixed[0], &self.mixed[1]], &planes);
        let candidates: [u32; 2] = std::array::from_fn(|half| match halves[half] {
            0 => 0,
            _ => slots[half] & occupied,
        });
        let mut first = None;
        for_each_bit(candidates[0] | candidates[1], |slot| {
            let clip = |half: usize| match candidates[half] >> slot & 1 {
                0 => (f32x8::ZERO, f32x8::ZERO, 0),
                _ => {
                    let (lanes, mixed) = (&self.lanes[half], &self.mixed[half]);
                    C::clip_slot_mixed(lanes, mixed, &planes, slot, self.limit[half])
                }
            };
            let both = (candidates[0] & candidates[1]) >> slot & 1 != 0;
            let [(near_0, far_0, mask_0), (near_1, far_1, mask_1)] = match both {
                true => {
                    let lanes = [&self.lanes[0], &self.lanes[1]];
                    let mixed = [&self.mixed[0], &self.mixed[1]];
                    C::clip_slot_pair(lanes, mixed, &planes, slot, self.limit)
                }
                false => [clip(0), clip(1)],
            };
            let mask = (mask_0 & halves[0]) | (mask_1 & halves[1]) << PACKET_WIDTH;
            if mask == 0 {
                return;
            }
            let (child, kind) = node.link(slot);
            targets.child((child, kind));
            if kind != INTERNAL_CHILD {
                leaves.push(PairLeaf {
                    first: child,
                    count: kind,
                    mask,
                    t_near: [near_0, near_1],
                    t_far: [far_0, far_1],
                });
            } else if first.is_none() {
                first = Some(Internal { node: child, mask });
            } else {
                internal.push(Internal { node: child, mask });
            }
        });
        first
    }

    /// The lanes of `entry` (at most one) walk its subtree alone over their whole intervals;
    /// returns those that found an occluder.
    #[inline(always)]
    fn walk_alone<N: TraceNode>(
        &mut self,
        tracer: &Tracer,
        nodes: (&[N], &N::Decoder),
        prepared: &mut [C::PreparedRays; 2],
        entry: Internal,
    ) -> u32 {
        let mut found = 0;
        for_each_bit(entry.mask, |bit| {
            let (half, lane) = (bit / PACKET_WIDTH, bit % PACKET_WIDTH);
            let lanes = &self.lanes[half];
            let start = Deferred {
                child: entry.node,
                kind: INTERNAL_CHILD,
                t_near: lanes.tmin.as_array()[lane],
                t_far: self.limit[half].as_array()[lane],
            };
            let query = tracer.query(prepared[half].ray(lanes, lane), true);
            let closest = &mut self.closest[half][lane];
            if trace_nodes::<N, C, true>(tracer, nodes, &query, start, closest) {
                found |= 1 << bit;
            }
        });
        found
    }

    /// Each half's active lanes test the leaf's strips, each strip viewed once for both
    /// halves; returns the lanes that found an occluder. A lane visits the strips in the order
    /// and with the bounds its ray alone would.
    #[inline(always)]
    fn trace_leaf(
        &mut self,
        tracer: &Tracer,
        prepared: &mut [C::PreparedRays; 2],
        leaf: &PairLeaf,
    ) -> u32 {
        let t_near = leaf.t_near.map(f32x8::to_array);
        let t_far = leaf.t_far.map(f32x8::to_array);
        let mut finished = 0;
        let mut active = leaf.mask;
        for strip in tracer.strip_sections().leaf_strips(leaf.first, leaf.count) {
            let view = tracer.file().strip(strip as usize);
            let offered = LeafStrip {
                view: &view,
                index: strip,
                leaf_windows: tracer.file().leaf_windows(),
            };
            let reaching: [LeafLanes; 2] = std::array::from_fn(|half| LeafLanes {
                active: active >> (PACKET_WIDTH * half) & HALF_LANES,
                t_near: &t_near[half],
                t_far: &t_far[half],
            });
            // Both halves in one pass where both have lanes (a lone lane tests the blocks it
            // enters alone).
            let paired = reaching.iter().all(|leaf| leaf.active != 0);
            let together = [&self.together[0], &self.together[1]];
            let pair = (together, [&self.lanes[0], &self.lanes[1]]);
            let leaves = [&reaching[0], &reaching[1]];
            if let Some(done) = paired
                .then(|| C::trace_strip_pair(pair.0, pair.1, &offered, leaves, self.closest))
                .flatten()
            {
                finished |= done;
                active &= !finished;
                if active == 0 {
                    break;
                }
                continue;
            }
            for (half, reaching) in reaching.iter().enumerate() {
                if reaching.active == 0 {
                    continue;
                }
                let (lanes, closest) = (&self.lanes[half], &mut self.closest[half]);
                let together = &self.together[half];
                let tested =
                    C::trace_strip_together(together, lanes, &offered, reaching, true, closest);
                let done = tested.unwrap_or_else(|| {
                    let packet = (tracer, lanes, &mut prepared[half]);
                    trace_strip_lanes::<C, _, true>(packet, &offered, reaching, closest)
                });
                finished |= done << (PACKET_WIDTH * half);
            }
            active &= !finished;
            if active == 0 {
                break;
            }
        }
        finished
    }
}

/// Each lane's culling bound ([`Closest::reach`]), `-inf` for the `finished` lanes so that
/// nothing is entered for them any more.
#[inline(always)]
fn limits(closest: &[[Closest; PACKET_WIDTH]; 2], finished: u32) -> [f32x8; 2] {
    std::array::from_fn(|half| {
        f32x8::from(std::array::from_fn::<f32, PACKET_WIDTH, _>(|lane| {
            match finished >> (PACKET_WIDTH * half + lane) & 1 {
                0 => closest[half][lane].reach,
                _ => f32::NEG_INFINITY,
            }
        }))
    })
}

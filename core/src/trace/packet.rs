//! Ray packets for coherent rays (Wald's packet traversal; paper 3.2: "larger packets for
//! traversing the high-level hierarchy ... smaller packets for the low-level hierarchy").
//!
//! A packet of [`PACKET_WIDTH`] rays walks the global hierarchy together, clipping all its rays
//! against each child box of a node at once in the kernel's eight lanes (one child after the
//! other) and carrying an active mask; the children entered are visited in [`order_keys`]
//! order. Before that, the kernel bounds the packet's rays together once per packet and culls
//! the children none of them can enter, eight at once ([`TraceKernel::frustum_slots`]): a
//! camera packet enters under two of a node's seven or eight children, and the lanewise clips
//! are then spent on those. The cull skips only children no lane enters, so nothing else
//! changes. At a leaf each active ray traverses the strips alone, unless the kernel tests a short
//! strip for all of them at once. Deviation from the paper: the low-level packet width is one
//! ray, since strip kd-trees are small and per-ray culling there pays more than SIMD width.
//!
//! The packet's rays are prepared once by the kernel, as `PreparedRay::new` prepares a single
//! ray, into structure-of-arrays [`Lanes`], with the same bits.
//!
//! Bit-identical to single rays: a packet is formed only from rays whose direction signs match the
//! first ray's (the others are traced alone), so all lanes pick the same entry and exit planes
//! (deviation: occlusion packets of a kernel with [`TraceKernel::MIXED_OCCLUSION`] take any signs,
//! each lane swapping lane 0's planes where its sign differs, and cull slots by the box of their
//! segments instead of the frustum); the lanewise box arithmetic is the scalar arithmetic of
//! `PreparedRay::clip_box` operation for operation, so a lane enters exactly the boxes its ray
//! enters alone, with the same interval for the same closest-hit bound; children are visited in an
//! order that depends on the direction signs alone, as closest-hit single rays visit them (sorted
//! by keys that are never NaN, the children any lane entered come in each lane's own order); and a
//! lane that is inactive in a subtree tests nothing there. Each lane thus visits the same leaves in
//! the same order with the same bounds as its ray alone, so the results agree bit for bit even on a
//! corrupt file whose boxes do not bound their strips (on a valid file the closest-hit rule alone,
//! smallest `(t, strip, window)`, would make the order irrelevant). Occlusion answers do not depend
//! on the order (see [`super::top`]), so occlusion packets visit a node's children unsorted (the
//! lowest slot entered first), which costs fewer instructions than either sorted order. A subtree
//! below a node that only one lane of a packet enters is walked by that lane alone (the single-ray
//! walk), where one clip tests all of a node's children; a closest-hit lane visits it in the order
//! and with the bounds it would in the packet, before the packet's next deferred child, so its
//! answer is unchanged. A leaf that one lane reaches stays with the packet, whose kernel may test a
//! strip for a lone lane more cheaply than the single-ray walk does.
//!
//! [`order_keys`]: super::top::order_keys

use std::marker::PhantomData;

use arrayvec::ArrayVec;
use wide::f32x8;

use super::closest::Closest;
use super::kernel::prefetch::Targets;
use super::kernel::{dispatch, LeafLanes, LeafStrip, TraceKernel, Walk};
use super::lanes::{LaneRays, Lanes, PACKET_WIDTH};
use super::prepared::{max_not_nan, min_not_nan_x8};
use super::ray::Ray;
use super::top::{
    for_each_bit, trace_nodes, walk_top_level, DeferStack, Deferred, RayWalk, TopLevelWalk,
    TraceNode, MAX_WIDTH,
};
use super::Tracer;
use crate::format::INTERNAL_CHILD;

/// Fewest rays sharing the first ray's direction signs for a packet to be traced as one: with
/// fewer the packet's node tests serve too few lanes to pay for themselves, and its rays are
/// traced alone.
const MIN_PACKET_LANES: usize = 6;

/// Whether `mask` has one lane at most: a packet hands a node's subtree that one lane enters
/// to that lane alone, since a lone lane pays a packet's clip per child for nothing. Two lanes
/// alone cost more than they save, since single rays test strips one ray at a time.
#[inline(always)]
pub(super) fn at_most_one(mask: u32) -> bool {
    mask & mask.wrapping_sub(1) == 0
}

/// A child deferred for some lanes of the packet.
#[derive(Clone, Copy, Default)]
struct PacketDeferred {
    /// As in [`Deferred`]: node index or first strip, and [`INTERNAL_CHILD`] or strip count.
    child: u32,
    kind: u32,
    mask: u32,
    t_near: f32x8,
    t_far: f32x8,
}

/// An internal child deferred by an occlusion packet: its node and lanes, without the lanes'
/// intervals in its box, which only a leaf's strips read (its own children are clipped over
/// each lane's whole interval).
#[derive(Clone, Copy)]
struct Internal {
    node: u32,
    mask: u32,
}

impl Internal {
    /// As the packet walk visits it; the lanes' intervals are theirs in the whole file.
    #[inline(always)]
    fn deferred(self, t_near: f32x8, t_far: f32x8) -> PacketDeferred {
        PacketDeferred {
            child: self.node,
            kind: INTERNAL_CHILD,
            mask: self.mask,
            t_near,
            t_far,
        }
    }
}

/// Traces up to [`PACKET_WIDTH`] rays into `closest`: entry `i` is ray `i`'s closest hit (or,
/// with `any_hit`, a hit that proves occlusion). Entries past `rays.len()` are empty. The
/// packet is prepared and walked in code compiled for the tracer's kernel.
///
/// `closest` is overwritten, not read: the packets of a batch reuse one array rather than
/// copying one out per packet.
pub(super) fn trace_packet(
    tracer: &Tracer,
    rays: &[Ray],
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let rays = &rays[..rays.len().min(PACKET_WIDTH)];
    // The lanes with a ray, then the others: no test of each lane for its ray.
    for (closest, ray) in closest.iter_mut().zip(rays) {
        *closest = Closest::none(ray.tmax);
    }
    for closest in &mut closest[rays.len()..] {
        *closest = Closest::none(f32::NEG_INFINITY);
    }
    if rays.is_empty() {
        return;
    }
    let walk = PacketWalk {
        tracer,
        rays,
        any_hit,
        closest,
    };
    dispatch(tracer.options().kernel, walk);
}

/// [`trace_packet`]'s walk, for the kernels to run: one to [`PACKET_WIDTH`] rays.
struct PacketWalk<'a, 't> {
    tracer: &'a Tracer<'t>,
    rays: &'a [Ray],
    any_hit: bool,
    closest: &'a mut [Closest; PACKET_WIDTH],
}

impl Walk for PacketWalk<'_, '_> {
    type Output = ();

    #[inline(always)]
    fn run<K: TraceKernel>(self) {
        let mut prepared = K::prepared_rays(self.rays);
        let lanes = K::lanes(self.rays, &prepared);
        let packet = (&lanes, &mut prepared);
        let count = self.rays.len();
        trace_lanes::<K, _>(self.tracer, packet, count, self.any_hit, self.closest);
    }
}

/// [`trace_packet`] of the packet's first `count` lanes, compiled for the target of the
/// function it is inlined into, on the kernel `C`: the lanes sharing lane 0's direction signs
/// walk the hierarchy together when there are at least [`MIN_PACKET_LANES`] of them, the
/// others are traced alone. `prepared` gives the lanes' rays as `PreparedRay`s.
#[inline(always)]
fn trace_lanes<C: TraceKernel, P: LaneRays>(
    tracer: &Tracer,
    (lanes, prepared): (&Lanes, &mut P),
    count: usize,
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let mut packet_mask = match any_hit && C::MIXED_OCCLUSION {
        true => (1 << count) - 1,
        false => lanes.octant_lanes(count),
    };
    if (packet_mask.count_ones() as usize) < MIN_PACKET_LANES {
        packet_mask = 0;
    }
    for_each_bit(!packet_mask & ((1 << count) - 1), |lane| {
        let ray = prepared.ray(lanes, lane);
        C::compiled(RayWalk {
            tracer,
            query: &tracer.query(ray, any_hit),
            closest: &mut closest[lane],
        });
    });
    if packet_mask != 0 {
        let packet = (lanes, prepared);
        if any_hit {
            traverse_file::<C, P, true>(tracer, packet, packet_mask, closest)
        } else {
            traverse_file::<C, P, false>(tracer, packet, packet_mask, closest)
        }
    }
}

/// How a packet culls a node's slots before clipping them lane by lane: by its frustum when
/// its lanes share their direction signs, else (occlusion packets of a kernel that mixes signs)
/// by the box of its segments, each lane clipped with its own planes.
enum Cull<C: TraceKernel> {
    Frustum(C::Frustum),
    Mixed(C::Mixed),
}

/// The packet walk's steps at a node.
impl Lanes {
    /// Child `slot` of `node` (whose group's box planes are `planes`) if some `active` lane
    /// enters it within `limit`. A method always inlined, not a closure of `enter_children`:
    /// the compiler once kept such a closure out of line, and the kernel's slot test with it.
    #[inline(always)]
    fn clip_child<N: TraceNode, C: TraceKernel>(
        &self,
        (node, planes, targets): (&N, &C::Planes, &Targets<N>),
        (slot, cull): (usize, &Cull<C>),
        (active, limit): (u32, f32x8),
    ) -> Option<PacketDeferred> {
        let (t_near, t_far, mask) = match cull {
            Cull::Frustum(_) => C::clip_slot(self, planes, slot, limit),
            Cull::Mixed(mixed) => C::clip_slot_mixed(self, mixed, planes, slot, limit),
        };
        let mask = mask & active;
        if mask == 0 {
            return None;
        }
        let (child, kind) = node.link(slot);
        // What visiting it loads first is on its way when it comes off the stack.
        targets.child((child, kind));
        Some(PacketDeferred {
            child,
            kind,
            mask,
            t_near,
            t_far,
        })
    }

    /// Clips the `active` lanes against `node`'s occupied slots; returns the child to visit
    /// first and defers the others: for closest hits so that they come off the stack in
    /// [`order_keys`] order, for occlusion (`ANY_HIT`) as they come, internal children on
    /// `internal` as their node and lanes alone. Empty slots are skipped (by their link: a
    /// grid node's empty box is not missed by construction); validated nodes hold their
    /// occupied slots first. The planes come straight from the node ([`TraceNode::planes`]):
    /// a format 4 node's eight at once.
    ///
    /// [`order_keys`]: super::top::order_keys
    #[inline(always)]
    fn enter_children<N: TraceNode, C: TraceKernel, const ANY_HIT: bool>(
        &self,
        (targets, cull): (&Targets<N>, &Cull<C>),
        node: &N,
        decoder: &N::Decoder,
        active: u32,
        (limit, reach): (f32x8, f32),
        (stack, internal): (&mut DeferStack<PacketDeferred>, &mut DeferStack<Internal>),
    ) -> Option<PacketDeferred> {
        let occupied = (node.occupied_mask().trailing_ones() as usize).min(MAX_WIDTH);
        let planes = node.planes::<C>(decoder, self);
        // Only the slots the packet may enter are clipped lane by lane.
        let culled = match cull {
            Cull::Frustum(frustum) => C::frustum_slots(frustum, &planes, reach),
            Cull::Mixed(mixed) => C::mixed_slots(mixed, &planes),
        };
        let candidates = culled & ((1 << occupied) - 1);
        let clipped = (node, &planes, targets);
        let bounds = (active, limit);
        if ANY_HIT {
            // The first child entered is visited at once (its lanes are within their bounds,
            // which only a leaf changes), the others deferred as they come.
            let mut first = None;
            for_each_bit(candidates, |slot| {
                if let Some(child) = self.clip_child::<N, C>(clipped, (slot, cull), bounds) {
                    match first {
                        None => first = Some(child),
                        Some(_) if child.kind == INTERNAL_CHILD => internal.push(Internal {
                            node: child.child,
                            mask: child.mask,
                        }),
                        Some(_) => stack.push(child),
                    }
                }
            });
            return first;
        }
        // Not an array of defaults: zeroing eight 96-byte entries per node costs more than the
        // pushes.
        let mut entered = ArrayVec::<PacketDeferred, MAX_WIDTH>::new();
        let mut slots = [0; MAX_WIDTH];
        for_each_bit(candidates, |slot| {
            if let Some(child) = self.clip_child::<N, C>(clipped, (slot, cull), bounds) {
                slots[entered.len() % MAX_WIDTH] = slot;
                entered.push(child);
            }
        });
        if entered.len() <= 1 {
            return entered.pop();
        }
        // The entries' indices are sorted, not the entries.
        let mut order = [0, 1, 2, 3, 4, 5, 6, 7];
        let order = &mut order[..entered.len()];
        let keys = C::plane_order_keys(&planes, &self.negative());
        sort_by_keys(order, &slots, &keys);
        for &index in order.iter().skip(1).rev() {
            stack.push(entered[index]);
        }
        order.first().map(|&index| entered[index])
    }
}

/// Insertion sort of the indices of the at most eight children entered (in slot order, entry
/// `i` from slot `slots[i]`) by their slots' keys; stable, so equal keys keep slot order, as
/// [`super::top::sort_by_key`] orders the children a single ray enters. The keys are never
/// NaN ([`order_keys`]), so this order of the children any lane entered, restricted to those a
/// lane entered, is that lane's order alone.
///
/// [`order_keys`]: super::top::order_keys
#[inline(always)]
fn sort_by_keys(indices: &mut [usize], slots: &[usize; MAX_WIDTH], keys: &[f32; MAX_WIDTH]) {
    // Each entry's key looked up by its slot as compared, not the eight slots' keys gathered
    // first; the remainders spare the bounds checks.
    let key = |index: usize| keys[slots[index % MAX_WIDTH] % MAX_WIDTH];
    for i in 1..indices.len() {
        let mut j = i;
        while j > 0 && key(indices[j]) < key(indices[j - 1]) {
            indices.swap(j, j - 1);
            j -= 1;
        }
    }
}

/// The culling bound ([`Closest::reach`]) of every lane, finished lanes (occlusion found, so
/// only with `ANY_HIT`) `-inf` so that nothing is entered for them any more; and the greatest
/// of them, the frustum's, passing over a NaN bound (a lane with one enters nothing) with one
/// compare per lane, not `f32::max`'s NaN fix-ups. Of two zeros it may keep either: the
/// frustum's bound only picks the slots clipped lane by lane, and no comparison tells the
/// zeros apart.
#[inline(always)]
fn bounds<const ANY_HIT: bool>(closest: &[Closest; PACKET_WIDTH], finished: u32) -> (f32x8, f32) {
    let lanes = std::array::from_fn::<f32, PACKET_WIDTH, _>(|lane| {
        if ANY_HIT && finished & (1 << lane) != 0 {
            f32::NEG_INFINITY
        } else {
            closest[lane].reach
        }
    });
    (
        f32x8::from(lanes),
        lanes.into_iter().fold(f32::NEG_INFINITY, max_not_nan),
    )
}

/// The walk of the global hierarchy with the packet's lanes, for occlusion (`ANY_HIT`) or
/// closest hits: one walk each, so that neither tests the query's kind per node or per strip.
#[inline(always)]
fn traverse_file<C: TraceKernel, P: LaneRays, const ANY_HIT: bool>(
    tracer: &Tracer,
    packet: (&Lanes, &mut P),
    packet_mask: u32,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let walk = PacketNodes::<C, P, ANY_HIT> {
        tracer,
        packet,
        packet_mask,
        closest,
        kernel: PhantomData,
    };
    walk_top_level(tracer.file(), walk)
}

/// [`traverse_file`]'s walk from the root, for [`walk_top_level`].
struct PacketNodes<'a, C, P, const ANY_HIT: bool> {
    tracer: &'a Tracer<'a>,
    packet: (&'a Lanes, &'a mut P),
    packet_mask: u32,
    closest: &'a mut [Closest; PACKET_WIDTH],
    kernel: PhantomData<C>,
}

impl<C: TraceKernel, P: LaneRays, const ANY_HIT: bool> TopLevelWalk
    for PacketNodes<'_, C, P, ANY_HIT>
{
    type Output = ();

    #[inline(always)]
    fn run<N: TraceNode>(self, nodes: &[N], decoder: &N::Decoder) {
        let PacketNodes {
            tracer,
            packet,
            packet_mask,
            closest,
            ..
        } = self;
        traverse_nodes::<_, C, P, ANY_HIT>(tracer, (nodes, decoder), packet, packet_mask, closest)
    }
}

#[inline(always)]
fn traverse_nodes<N: TraceNode, C: TraceKernel, P: LaneRays, const ANY_HIT: bool>(
    tracer: &Tracer,
    (nodes, decoder): (&[N], &N::Decoder),
    (lanes, prepared): (&Lanes, &mut P),
    packet_mask: u32,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let mut finished = 0u32;
    let mut stack = DeferStack::default();
    let mut internal = DeferStack::default();
    let together = C::together(lanes);
    let targets = Targets::new(tracer.strip_sections(), nodes);
    // The lanes' culling bounds change only at leaves: gathered once per leaf, not per node.
    let (mut limit, mut reach) = bounds::<ANY_HIT>(closest, finished);
    let cull = match ANY_HIT && C::MIXED_OCCLUSION {
        true => Cull::Mixed(C::mixed(lanes, packet_mask, limit)),
        false => Cull::Frustum(C::frustum(lanes, packet_mask)),
    };
    // The root has no box: every lane starts with its own interval.
    let mut current = PacketDeferred {
        child: 0,
        kind: INTERNAL_CHILD,
        mask: packet_mask,
        t_near: lanes.tmin,
        t_far: limit,
    };
    // `ReducemFile::node_visits`, from the nodes at hand rather than a second look-up.
    let mut visits = nodes.len();
    loop {
        if current.kind == INTERNAL_CHILD && at_most_one(current.mask) {
            let found = walk_alone::<N, C, P, ANY_HIT>(
                tracer,
                (nodes, decoder),
                (lanes, prepared),
                &current,
                closest,
            );
            // A closest-hit lane's bound moves with every hit it finds.
            if !ANY_HIT || found != 0 {
                finished |= found;
                (limit, reach) = bounds::<ANY_HIT>(closest, finished);
            }
        } else if current.mask != 0 {
            if current.kind == INTERNAL_CHILD {
                let Some(left) = visits.checked_sub(1) else {
                    return;
                };
                visits = left;
                let node = tracer.file().top_node(nodes, current.child as usize);
                let entered = node.and_then(|n| {
                    lanes.enter_children::<N, C, ANY_HIT>(
                        (&targets, &cull),
                        n,
                        decoder,
                        current.mask,
                        (limit, reach),
                        (&mut stack, &mut internal),
                    )
                });
                if let Some(first) = entered {
                    current = first;
                    continue;
                }
            } else {
                let packet = (tracer, lanes, &together);
                let found = trace_leaf_lanes::<C, P, ANY_HIT>(packet, prepared, &current, closest);
                // An occlusion lane's bound changes only when it finishes.
                if !ANY_HIT || found != 0 {
                    finished |= found;
                    (limit, reach) = bounds::<ANY_HIT>(closest, finished);
                }
            }
        }
        loop {
            // Occlusion packets take deferred leaves first: the order does not matter to them.
            let deferred = match stack.pop() {
                Some(deferred) => deferred,
                None => match internal.pop() {
                    Some(node) if ANY_HIT => node.deferred(lanes.tmin, limit),
                    _ => return,
                },
            };
            // An occlusion lane entered a child within its bound, which stays until the lane
            // finishes: only finished lanes drop out.
            let alive = match ANY_HIT {
                true => !finished,
                false => C::lanes_at_most(deferred.t_near, limit),
            };
            let mask = deferred.mask & alive;
            if mask != 0 {
                current = PacketDeferred { mask, ..deferred };
                break;
            }
        }
    }
}

/// Each lane of `entry` walks its subtree alone with the single-ray walk; returns the lanes
/// that found an occluder (`ANY_HIT`). Occlusion answers do not depend on the order of the
/// visits, so a lane may leave the packet anywhere; a closest-hit lane visits the subtree's
/// children in the order, and with the bounds, that it would in the packet, all before the
/// packet's next deferred child.
#[inline(always)]
fn walk_alone<N: TraceNode, C: TraceKernel, P: LaneRays, const ANY_HIT: bool>(
    tracer: &Tracer,
    nodes: (&[N], &N::Decoder),
    (lanes, prepared): (&Lanes, &mut P),
    entry: &PacketDeferred,
    closest: &mut [Closest; PACKET_WIDTH],
) -> u32 {
    let (t_near, t_far) = (entry.t_near.to_array(), entry.t_far.to_array());
    let mut found = 0;
    for_each_bit(entry.mask, |lane| {
        let start = Deferred {
            child: entry.child,
            kind: entry.kind,
            t_near: t_near[lane],
            t_far: t_far[lane],
        };
        let query = tracer.query(prepared.ray(lanes, lane), ANY_HIT);
        if trace_nodes::<N, C, ANY_HIT>(tracer, nodes, &query, start, &mut closest[lane]) {
            found |= 1 << lane;
        }
    });
    found
}

/// Each active lane traverses the leaf's strips alone, strip after strip, so that each strip is
/// viewed once for the packet; returns the lanes that found an occluder when `ANY_HIT` is set.
/// A lane visits the strips in the order and with the bounds its ray alone would
/// (`super::top::trace_leaf`). Inlined into the walk, so that the strip walk is entered
/// straight from code compiled for the kernel.
#[inline(always)]
fn trace_leaf_lanes<C: TraceKernel, P: LaneRays, const ANY_HIT: bool>(
    (tracer, lanes, together): (&Tracer, &Lanes, &C::Together),
    prepared: &mut P,
    leaf: &PacketDeferred,
    closest: &mut [Closest; PACKET_WIDTH],
) -> u32 {
    let t_near = leaf.t_near.to_array();
    let t_far = leaf.t_far.to_array();
    let mut finished = 0;
    let mut active = leaf.mask;
    let strips = tracer.strip_sections().leaf_strips(leaf.child, leaf.kind);
    for strip in strips.clone() {
        // A closest-hit lane stops where a hit found since is nearer than its interval: after
        // the leaf's first strip (a lane enters the leaf with `t_near <= t_far` and
        // `t_near <= reach`), one compare on the eight lanes, as `t_near > min(t_far, reach)`
        // lane by lane (`t_near` and `t_far` are not NaN where a lane entered, and the bound
        // is `t_far` where `reach` is NaN, as `f32::min`). An occlusion lane's bound stays what
        // its interval was clipped to until the lane finishes, so the interval needs no
        // clipping again, nor can it be empty.
        if !ANY_HIT && strip != strips.start {
            let reach = f32x8::from(std::array::from_fn::<f32, PACKET_WIDTH, _>(|lane| {
                closest[lane].reach
            }));
            active &= C::lanes_at_most(leaf.t_near, min_not_nan_x8(leaf.t_far, reach));
            if active == 0 {
                break;
            }
        }
        let view = tracer.file().strip_inlined(strip as usize);
        let reaching = LeafLanes {
            active,
            t_near: &t_near,
            t_far: &t_far,
        };
        let offered = LeafStrip {
            view: &view,
            index: strip,
            leaf_windows: tracer.file().leaf_windows(),
        };
        let tested =
            C::trace_strip_together(together, lanes, &offered, &reaching, ANY_HIT, closest);
        let done = tested.unwrap_or_else(|| {
            let packet = (tracer, lanes, &mut *prepared);
            trace_strip_lanes::<C, P, ANY_HIT>(packet, &offered, &reaching, closest)
        });
        finished |= done;
        active &= !done;
        if active == 0 {
            break;
        }
    }
    finished
}

/// Each of the `reaching` lanes traverses the strip alone; returns the lanes that found an
/// occluder when `ANY_HIT` is set.
#[inline(always)]
pub(super) fn trace_strip_lanes<C: TraceKernel, P: LaneRays, const ANY_HIT: bool>(
    (tracer, lanes, prepared): (&Tracer, &Lanes, &mut P),
    strip: &LeafStrip,
    reaching: &LeafLanes,
    closest: &mut [Closest; PACKET_WIDTH],
) -> u32 {
    let mut done = 0;
    for_each_bit(reaching.active, |lane| {
        let closest = &mut closest[lane];
        let t_far = if ANY_HIT {
            reaching.t_far[lane]
        } else {
            reaching.t_far[lane].min(closest.reach)
        };
        let query = tracer.query(prepared.ray(lanes, lane), ANY_HIT);
        let t_near = reaching.t_near[lane];
        if query.trace::<C>(strip.view, strip.index, t_near, t_far, closest) {
            done |= 1 << lane;
        }
    });
    done
}

//! Ray packets for coherent rays (Wald's packet traversal; paper 3.2: "larger packets for
//! traversing the high-level hierarchy ... smaller packets for the low-level hierarchy").
//!
//! A packet of [`PACKET_WIDTH`] rays walks the global hierarchy together, clipping all its rays
//! against each child box of a node at once in SIMD (`wide::f32x8`, one child after the other)
//! and carrying an active mask; the children entered are visited in [`order_keys`] order. At a
//! leaf each active ray traverses the strips alone. Deviation from the paper: the low-level packet width is
//! one ray, since strip kd-trees are small and per-ray culling there pays more than SIMD width.
//!
//! The packet's rays are prepared once, as [`PreparedRay::new`] prepares a single ray, into
//! structure-of-arrays `Lanes`: ray by ray and then lane by lane (`Lanes::of`), or with the
//! AVX2 kernel eight rays at once in AVX2 registers (`super::avx2_setup`), with the same bits.
//!
//! Bit-identical to single rays: a packet is formed only from rays whose direction signs match
//! the first ray's (the others are traced alone), so all lanes pick the same entry and exit
//! planes; the lanewise box arithmetic is the scalar arithmetic of [`PreparedRay::clip_box`]
//! operation for operation, so a lane enters exactly the boxes its ray enters alone, with the
//! same interval for the same closest-hit bound; children are visited in an order that depends
//! on the direction signs alone, as closest-hit single rays visit them (sorted by keys that are
//! never NaN, the children any lane entered come in each lane's own order); and a lane that is
//! inactive in a subtree tests nothing there. Each lane thus visits the same leaves in the same
//! order with the same bounds as its ray alone, so the results agree bit for bit even on a
//! corrupt file whose boxes do not bound their strips (on a valid file the closest-hit rule
//! alone, smallest `(t, strip, window)`, would make the order irrelevant). Occlusion answers do
//! not depend on the order (see [`super::top`]), so occlusion packets visit a node's children in
//! slot order, unsorted: 1.2% fewer instructions per AO ray than the closest-hit order, and 0.4%
//! fewer than sorting by the first active lane's entry distance (callgrind, 100k AO rays of the
//! 1M scan).

use arrayvec::ArrayVec;
use wide::{f32x8, i32x8, u32x4};

use super::prefetch::Targets;
use super::prepared::{max_not_nan_x8, min_not_nan_x8, PreparedRay, FAR_INFLATION};
use super::ray::Ray;
use super::strip::{Closest, StripQuery};
use super::top::{
    for_each_bit, order_keys, trace_ray, ChildBoxes, DeferStack, NodeGridLanes, TraceNode,
};
use super::watertight::RaySpace;
use super::Tracer;
use crate::format::reader::{StripView, TopNodes};
use crate::format::{INTERNAL_CHILD, TOP_WIDTH};

/// Rays per packet at the top level.
pub const PACKET_WIDTH: usize = 8;

/// Fewest rays sharing the first ray's direction signs for a packet to be traced as one: with
/// fewer the packet's node tests serve too few lanes to pay for themselves, and its rays are
/// traced alone (incoherent AO rays from one hit point: 7% fewer instructions per ray, on a 1M
/// scan with 100k AO rays).
const MIN_PACKET_LANES: usize = 6;

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

/// The packet's rays prepared ([`PreparedRay`]) in structure-of-arrays form, lane `i` holding
/// ray `i`'s fields bit for bit (lanes past the rays repeat the last one).
pub(super) struct Lanes {
    pub(super) origin: [f32x8; 3],
    pub(super) entry_reciprocal: [f32x8; 3],
    pub(super) exit_reciprocal: [f32x8; 3],
    pub(super) tmin: f32x8,
    pub(super) tmax: f32x8,
    /// Per axis, bit `i` set where lane `i`'s direction is negative ([`PreparedRay::negative`]).
    pub(super) signs: [u32; 3],
    /// Per axis, all ones in four lanes where the packet's direction (lane 0's) is negative,
    /// for picking a node's planes without branches.
    pub(super) negative_masks: [u32x4; 3],
    /// The lanes' [`RaySpace`]s: `space_axes[role]` is the model axis of ray-space axis `role`
    /// (x, y, z).
    pub(super) space_axes: [i32x8; 3],
    pub(super) shear: [f32x8; 2],
    pub(super) scale_z: f32x8,
}

/// What the packet walk runs per child box and per strip: [`WideKernel`] everywhere, or the
/// AVX2 kernel ([`super::avx2`]). Every implementation runs [`PreparedRay::clip_box`]'s
/// operations in its order on each lane and traces strips as [`StripQuery::trace`], so the
/// lanes' bits agree.
pub(super) trait PacketKernel {
    /// A node's child box planes as [`PacketKernel::clip_slot`] reads them.
    type Planes;

    /// The planes of `boxes` through which the lanes enter and leave each child box: per axis
    /// the minima or the maxima by the direction's sign (shared by all lanes), picked once per
    /// node rather than once per slot.
    fn planes(lanes: &Lanes, boxes: &ChildBoxes) -> Self::Planes;

    /// The lanes' interval in child `slot` of the node whose planes are `planes` within
    /// `[tmin, t_far]`, and the mask of the lanes whose interval is not empty.
    fn clip_slot(
        lanes: &Lanes,
        planes: &Self::Planes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32);

    /// The lanes where `a <= b` (false where either is NaN), as a bit mask.
    fn lanes_at_most(a: f32x8, b: f32x8) -> u32;

    /// What the kernel makes of the packet's lanes once for
    /// [`PacketKernel::trace_strip_together`].
    type Together;

    /// [`PacketKernel::Together`] of the packet `lanes`.
    fn together(lanes: &Lanes) -> Self::Together;

    /// Strip `strip` traced for all the leaf's `active` lanes at once by the kernel's own means,
    /// or `None` for the lane-by-lane walk of [`trace_leaf_lanes`]; as that walk, returns the
    /// lanes that found an occluder when `any_hit` is set.
    #[inline(always)]
    fn trace_strip_together(
        _together: &Self::Together,
        _packet: (&Tracer, &Lanes),
        _strip: (&StripView, u32),
        _leaf: &LeafLanes,
        _any_hit: bool,
        _closest: &mut [Closest; PACKET_WIDTH],
    ) -> Option<u32> {
        None
    }

    /// [`StripQuery::trace`] of one lane.
    fn trace_strip(
        query: &StripQuery,
        view: &StripView,
        strip: u32,
        t_near: f32,
        t_far: f32,
        closest: &mut Closest,
    ) -> bool;
}

/// [`PacketKernel`] in `wide`'s eight lanes (two SSE operations each), strips through
/// [`StripQuery::trace`].
pub(super) struct WideKernel;

impl PacketKernel for WideKernel {
    type Planes = SlotPlanes;
    type Together = ();

    #[inline(always)]
    fn together(_lanes: &Lanes) {}

    #[inline(always)]
    fn planes(lanes: &Lanes, boxes: &ChildBoxes) -> SlotPlanes {
        lanes.planes(boxes)
    }

    #[inline(always)]
    fn clip_slot(
        lanes: &Lanes,
        planes: &SlotPlanes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32) {
        lanes.clip_slot(planes, slot, t_far)
    }

    #[inline(always)]
    fn lanes_at_most(a: f32x8, b: f32x8) -> u32 {
        a.simd_le(b).to_bitmask()
    }

    #[inline(always)]
    fn trace_strip(
        query: &StripQuery,
        view: &StripView,
        strip: u32,
        t_near: f32,
        t_far: f32,
        closest: &mut Closest,
    ) -> bool {
        query.trace(view, strip, t_near, t_far, closest)
    }
}

/// Traces up to [`PACKET_WIDTH`] rays into `closest`: entry `i` is ray `i`'s closest hit (or,
/// with `any_hit`, a hit that proves occlusion). Entries past `rays.len()` are empty.
///
/// With the AVX2 kernel on a CPU that has it, the packet is prepared and walked in code
/// compiled for AVX2 ([`super::avx2::trace_packet`]): the rays are prepared in AVX2 registers
/// ([`super::avx2_setup`]), and each `wide` eight-lane operation of the box tests is one 256-bit
/// instruction instead of two 128-bit ones (2.7% fewer instructions per AO ray and 4% per
/// primary ray for the walk, callgrind, 100k rays of the 1M scan; 9% less CPU time for 3.8M AO
/// rays on one thread). The arithmetic is the same, so the lanes' bits are.
///
/// `closest` is overwritten, not read: the packets of a batch reuse one array (returning it
/// copied 600 bytes a packet: 117.3 -> 115.3 ms of CPU for `reducem query` of the 1M scan's
/// 1M camera rays, 1 thread, `perf stat` task-clock, medians of 9 alternating runs).
pub fn trace_packet(
    tracer: &Tracer,
    rays: &[Ray],
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let rays = &rays[..rays.len().min(PACKET_WIDTH)];
    for (lane, closest) in closest.iter_mut().enumerate() {
        *closest = Closest::none(rays.get(lane).map_or(f32::NEG_INFINITY, |ray| ray.tmax));
    }
    if rays.is_empty() {
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if tracer.options().kernel == super::Kernel::Avx2
        && super::avx2::trace_packet(tracer, rays, any_hit, closest)
    {
        return;
    }
    let mut prepared = prepare(rays);
    let lanes = Lanes::of(&prepared);
    trace_lanes::<WideKernel, _>(
        tracer,
        (&lanes, &mut prepared),
        rays.len(),
        any_hit,
        closest,
    );
}

/// The packet's rays as [`PreparedRay`]s, for the lane-by-lane strip walk and the rays traced
/// alone: all made by the setup, or each made from the lanes when first needed.
pub(super) trait LaneRays {
    /// Lane `lane`'s ray, as [`PreparedRay::new`] makes it.
    fn ray(&mut self, lanes: &Lanes, lane: usize) -> &PreparedRay;
}

impl LaneRays for [PreparedRay; PACKET_WIDTH] {
    #[inline(always)]
    fn ray(&mut self, _lanes: &Lanes, lane: usize) -> &PreparedRay {
        &self[lane % PACKET_WIDTH]
    }
}

impl LaneRays for [Option<PreparedRay>; PACKET_WIDTH] {
    #[inline(always)]
    fn ray(&mut self, lanes: &Lanes, lane: usize) -> &PreparedRay {
        self[lane % PACKET_WIDTH].get_or_insert_with(|| lanes.prepared(lane))
    }
}

/// [`PreparedRay::new`] of each of `rays` (at least one, at most [`PACKET_WIDTH`]); lanes past
/// them repeat the last ray.
pub(super) fn prepare(rays: &[Ray]) -> [PreparedRay; PACKET_WIDTH] {
    std::array::from_fn(|lane| PreparedRay::new(&rays[lane.min(rays.len() - 1)]))
}

/// [`trace_packet`] of the packet's first `count` lanes, compiled for the target of the
/// function it is inlined into, clipping with `C`: the lanes sharing lane 0's direction signs
/// walk the hierarchy together when there are at least [`MIN_PACKET_LANES`] of them, the
/// others are traced alone. `prepared` gives the lanes' rays as [`PreparedRay`]s.
#[inline(always)]
pub(super) fn trace_lanes<C: PacketKernel, P: LaneRays>(
    tracer: &Tracer,
    (lanes, prepared): (&Lanes, &mut P),
    count: usize,
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let mut packet_mask = lanes.octant_lanes(count);
    if (packet_mask.count_ones() as usize) < MIN_PACKET_LANES {
        packet_mask = 0;
    }
    for_each_bit(!packet_mask & ((1 << count) - 1), |lane| {
        let ray = prepared.ray(lanes, lane);
        trace_ray(
            tracer.file(),
            &tracer.query(ray, any_hit),
            &mut closest[lane],
        );
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

impl Lanes {
    /// The lanes of the `prepared` rays, stored lane by lane.
    pub(super) fn of(prepared: &[PreparedRay; PACKET_WIDTH]) -> Lanes {
        // Plain stores lane by lane: gathering each field through a closure per field cost
        // about 5% of an AO ray's instructions.
        let mut origin = [[0.0; PACKET_WIDTH]; 3];
        let mut entry_reciprocal = [[0.0; PACKET_WIDTH]; 3];
        let mut exit_reciprocal = [[0.0; PACKET_WIDTH]; 3];
        let mut space_axes = [[0; PACKET_WIDTH]; 3];
        let mut shear = [[0.0; PACKET_WIDTH]; 2];
        let mut scale_z = [0.0; PACKET_WIDTH];
        let mut tmin = [0.0; PACKET_WIDTH];
        let mut tmax = [0.0; PACKET_WIDTH];
        let mut signs = [0; 3];
        for (lane, ray) in prepared.iter().enumerate() {
            let axes = ray.space.axes();
            for axis in 0..3 {
                origin[axis][lane] = ray.origin[axis];
                entry_reciprocal[axis][lane] = ray.entry_reciprocal[axis];
                exit_reciprocal[axis][lane] = ray.exit_reciprocal[axis];
                signs[axis] |= u32::from(ray.negative[axis]) << lane;
                space_axes[axis][lane] = axes[axis] as i32;
            }
            (shear[0][lane], shear[1][lane]) = ray.space.shears();
            scale_z[lane] = ray.space.scale_z();
            tmin[lane] = ray.tmin;
            tmax[lane] = ray.tmax;
        }
        Lanes {
            origin: origin.map(f32x8::from),
            entry_reciprocal: entry_reciprocal.map(f32x8::from),
            exit_reciprocal: exit_reciprocal.map(f32x8::from),
            tmin: f32x8::from(tmin),
            tmax: f32x8::from(tmax),
            negative_masks: Lanes::negative_masks(&signs),
            signs,
            space_axes: space_axes.map(i32x8::from),
            shear: shear.map(f32x8::from),
            scale_z: f32x8::from(scale_z),
        }
    }

    /// The field `negative_masks` from the lanes' `signs`.
    pub(super) fn negative_masks(signs: &[u32; 3]) -> [u32x4; 3] {
        signs.map(|signs| u32x4::splat(0u32.wrapping_sub(signs & 1)))
    }

    /// The packet's direction signs: lane 0's [`PreparedRay::negative`].
    #[inline(always)]
    pub(super) fn negative(&self) -> [bool; 3] {
        self.signs.map(|signs| signs & 1 != 0)
    }

    /// The first `count` lanes whose direction signs are lane 0's, as a bit mask.
    #[inline(always)]
    fn octant_lanes(&self, count: usize) -> u32 {
        self.signs.iter().fold((1 << count) - 1, |mask, &signs| {
            mask & !(signs ^ 0u32.wrapping_sub(signs & 1))
        })
    }

    /// Lane `lane`'s ray as [`PreparedRay::new`] makes it, bit for bit.
    pub(super) fn prepared(&self, lane: usize) -> PreparedRay {
        // The remainder spares the bounds checks; each field is read by hand, not through
        // `array::map`, which stayed an out-of-line call of 121 instructions a lane (by hand:
        // 27 fewer instructions per primary ray, 39 per AO ray; callgrind, 100k rays of the 1M
        // scan).
        let lane = lane % PACKET_WIDTH;
        let at = |values: &[f32x8; 3]| {
            [
                values[0].as_array()[lane],
                values[1].as_array()[lane],
                values[2].as_array()[lane],
            ]
        };
        let origin = at(&self.origin);
        let axis = |role: usize| self.space_axes[role].as_array()[lane] as usize;
        let space = RaySpace::from_parts(
            origin,
            [axis(0), axis(1), axis(2)],
            [
                self.shear[0].as_array()[lane],
                self.shear[1].as_array()[lane],
            ],
            self.scale_z.as_array()[lane],
        );
        let negative = |axis: usize| self.signs[axis] >> lane & 1 != 0;
        PreparedRay {
            origin,
            exit_reciprocal: at(&self.exit_reciprocal),
            entry_reciprocal: at(&self.entry_reciprocal),
            negative: [negative(0), negative(1), negative(2)],
            space,
            tmin: self.tmin.as_array()[lane],
            tmax: self.tmax.as_array()[lane],
        }
    }

    /// [`PacketKernel::planes`] in plain arrays.
    #[inline(always)]
    fn planes(&self, (min, max): &ChildBoxes) -> SlotPlanes {
        let negative = self.negative();
        let pick = |axis: usize, entry: bool| {
            if negative[axis] == entry {
                max[axis]
            } else {
                min[axis]
            }
        };
        SlotPlanes {
            entry: [0, 1, 2].map(|axis| pick(axis, true)),
            exit: [0, 1, 2].map(|axis| pick(axis, false)),
        }
    }

    /// Lanewise [`PreparedRay::clip_box`] against child `slot` of the node whose planes are
    /// `planes`: the same operations in the same order.
    #[inline(always)]
    fn clip_slot(&self, planes: &SlotPlanes, slot: usize, t_far: f32x8) -> (f32x8, f32x8, u32) {
        let mut near = self.tmin;
        let mut far = t_far;
        for axis in 0..3 {
            let entry = (f32x8::splat(planes.entry[axis][slot]) - self.origin[axis])
                * self.entry_reciprocal[axis];
            let exit = (f32x8::splat(planes.exit[axis][slot]) - self.origin[axis])
                * self.exit_reciprocal[axis]
                * f32x8::splat(FAR_INFLATION);
            near = max_not_nan_x8(near, entry);
            far = min_not_nan_x8(far, exit);
        }
        (near, far, near.simd_le(far).to_bitmask())
    }

    /// Child `slot` of `node` (whose box planes are `planes`) if some `active` lane enters it
    /// within `limit`. A method always inlined, not a closure of `enter_children`: the
    /// compiler once kept such a closure out of line (and the AVX2 slot test with it), which
    /// took 3.8M AO rays on the 10M scan from 1,207 to 1,942 ms of CPU.
    #[inline(always)]
    fn clip_child<N: TraceNode, C: PacketKernel>(
        &self,
        (node, planes, targets): (&N, &C::Planes, &Targets<N>),
        slot: usize,
        (active, limit): (u32, f32x8),
    ) -> Option<PacketDeferred> {
        let (t_near, t_far, mask) = C::clip_slot(self, planes, slot, limit);
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

    /// For occlusion: pushes child `slot` onto `stack` if it is one of the `occupied` first
    /// slots and some lane enters it ([`Lanes::clip_child`]).
    #[inline(always)]
    fn defer_child<N: TraceNode, C: PacketKernel>(
        &self,
        clipped: (&N, &C::Planes, &Targets<N>),
        slot: usize,
        occupied: usize,
        bounds: (u32, f32x8),
        stack: &mut DeferStack<PacketDeferred>,
    ) {
        if slot < occupied {
            if let Some(child) = self.clip_child::<N, C>(clipped, slot, bounds) {
                stack.push(child);
            }
        }
    }

    /// Clips the `active` lanes against `node`'s occupied slots; returns the child to visit
    /// first (for closest hits) and defers the others, so that they come off the stack in
    /// visiting order: [`order_keys`] order for closest hits, slot order for occlusion
    /// (`ANY_HIT`). Empty slots are skipped (by their link: a grid node's empty box is not
    /// missed by construction); validated nodes hold their occupied slots first.
    #[inline(always)]
    fn enter_children<N: TraceNode, C: PacketKernel, const ANY_HIT: bool>(
        &self,
        targets: &Targets<N>,
        node: &N,
        decoder: &N::Decoder,
        active: u32,
        limit: f32x8,
        stack: &mut DeferStack<PacketDeferred>,
    ) -> Option<PacketDeferred> {
        let boxes = node.boxes(decoder);
        let planes = C::planes(self, &boxes);
        let occupied = node.occupied_mask().trailing_ones() as usize;
        let clipped = (node, &planes, targets);
        if ANY_HIT {
            // Slot order is known before clipping: the slots are clipped last to first and
            // each child entered goes straight onto the stack, the first one too (clipping
            // first to first and keeping the first child entered off the stack cost 3,139
            // instead of 3,134 instructions per AO ray, callgrind, 100k rays of the 1M scan).
            // Unrolled by hand: as a loop over the slots it stayed one, with the slot in a
            // register (3,146 instead of 3,134 instructions per AO ray).
            let bounds = (active, limit);
            self.defer_child::<N, C>(clipped, 3, occupied, bounds, stack);
            self.defer_child::<N, C>(clipped, 2, occupied, bounds, stack);
            self.defer_child::<N, C>(clipped, 1, occupied, bounds, stack);
            self.defer_child::<N, C>(clipped, 0, occupied, bounds, stack);
            return None;
        }
        // Not an array of defaults: zeroing four 96-byte entries and filling one per slot cost
        // 2,412 instead of 2,313 instructions per primary ray (callgrind, 100k rays).
        let mut entered = ArrayVec::<PacketDeferred, TOP_WIDTH>::new();
        let mut slots = [0; TOP_WIDTH];
        for slot in 0..TOP_WIDTH {
            if slot >= occupied {
                break;
            }
            if let Some(child) = self.clip_child::<N, C>(clipped, slot, (active, limit)) {
                slots[entered.len()] = slot;
                entered.push(child);
            }
        }
        // The entries' indices are sorted, not the entries.
        let mut order = [0, 1, 2, 3];
        let order = &mut order[..entered.len()];
        if order.len() > 1 {
            let keys = order_keys(&boxes.0, &boxes.1, &self.negative());
            sort_by_keys(order, &slots.map(|slot| keys[slot % TOP_WIDTH]));
        }
        for &index in order.iter().skip(1).rev() {
            stack.push(entered[index]);
        }
        order.first().map(|&index| entered[index])
    }
}

/// Insertion sort of the indices of the at most four children entered (in slot order) by
/// their keys; stable, so equal keys keep slot order, as [`super::top::sort_by_key`] orders
/// the children a single ray enters. The keys are never NaN ([`order_keys`]), so this order of
/// the children any lane entered, restricted to those a lane entered, is that lane's order
/// alone.
#[inline(always)]
fn sort_by_keys(indices: &mut [usize], keys: &[f32; TOP_WIDTH]) {
    // The remainder spares the bounds checks.
    let key = |index: usize| keys[index % TOP_WIDTH];
    for i in 1..indices.len() {
        let mut j = i;
        while j > 0 && key(indices[j]) < key(indices[j - 1]) {
            indices.swap(j, j - 1);
            j -= 1;
        }
    }
}

/// A node's child box planes as a packet sees them (see [`PacketKernel::planes`]),
/// `[axis][slot]`.
pub(super) struct SlotPlanes {
    entry: [[f32; TOP_WIDTH]; 3],
    exit: [[f32; TOP_WIDTH]; 3],
}

/// The culling bound ([`Closest::reach`]) of every lane; finished lanes (occlusion found) get
/// `-inf` so that nothing is entered for them any more.
fn bounds(closest: &[Closest; PACKET_WIDTH], finished: u32) -> f32x8 {
    f32x8::from(std::array::from_fn::<f32, PACKET_WIDTH, _>(|lane| {
        if finished & (1 << lane) != 0 {
            f32::NEG_INFINITY
        } else {
            closest[lane].reach
        }
    }))
}

/// The walk of the global hierarchy with the packet's lanes, for occlusion (`ANY_HIT`) or
/// closest hits: one walk each, so that neither tests the query's kind per node or per strip.
#[inline(always)]
fn traverse_file<C: PacketKernel, P: LaneRays, const ANY_HIT: bool>(
    tracer: &Tracer,
    packet: (&Lanes, &mut P),
    packet_mask: u32,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    match tracer.file().top_nodes() {
        TopNodes::F32(nodes) => {
            traverse_nodes::<_, C, P, ANY_HIT>(tracer, (nodes, &()), packet, packet_mask, closest)
        }
        TopNodes::Grid(nodes, grid) => {
            let decoder = NodeGridLanes::new(&grid);
            let nodes = (nodes, &decoder);
            traverse_nodes::<_, C, P, ANY_HIT>(tracer, nodes, packet, packet_mask, closest)
        }
    }
}

#[inline(always)]
fn traverse_nodes<N: TraceNode, C: PacketKernel, P: LaneRays, const ANY_HIT: bool>(
    tracer: &Tracer,
    (nodes, decoder): (&[N], &N::Decoder),
    (lanes, prepared): (&Lanes, &mut P),
    packet_mask: u32,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let mut finished = 0u32;
    let mut stack = DeferStack::default();
    let together = C::together(lanes);
    let targets = Targets::new(tracer.file(), nodes);
    // The lanes' culling bounds change only at leaves: gathered once per leaf, not per node.
    let mut limit = bounds(closest, finished);
    // The root has no box: every lane starts with its own interval.
    let mut current = PacketDeferred {
        child: 0,
        kind: INTERNAL_CHILD,
        mask: packet_mask,
        t_near: lanes.tmin,
        t_far: limit,
    };
    let mut visits = tracer.file().node_visits();
    loop {
        if current.mask != 0 {
            if current.kind == INTERNAL_CHILD {
                let Some(left) = visits.checked_sub(1) else {
                    return;
                };
                visits = left;
                let node = tracer.file().top_node(nodes, current.child as usize);
                let entered = node.and_then(|n| {
                    lanes.enter_children::<N, C, ANY_HIT>(
                        &targets,
                        n,
                        decoder,
                        current.mask,
                        limit,
                        &mut stack,
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
                    limit = bounds(closest, finished);
                }
            }
        }
        loop {
            let Some(deferred) = stack.pop() else {
                return;
            };
            let alive = C::lanes_at_most(deferred.t_near, limit);
            let mask = deferred.mask & alive;
            if mask != 0 {
                current = PacketDeferred { mask, ..deferred };
                break;
            }
        }
    }
}

/// The lanes reaching a strip of a leaf: their mask and each lane's parameter interval in the
/// leaf box.
pub(super) struct LeafLanes<'a> {
    pub active: u32,
    pub t_near: &'a [f32; PACKET_WIDTH],
    pub t_far: &'a [f32; PACKET_WIDTH],
}

/// Each active lane traverses the leaf's strips alone, strip after strip, so that each strip is
/// viewed once for the packet; returns the lanes that found an occluder when `ANY_HIT` is set.
/// A lane visits the strips in the order and with the bounds its ray alone would
/// ([`super::top::trace_leaf`]). Inlined into the walk, so that with the AVX2 kernel the strip
/// traversal is entered straight from code compiled for AVX2 (`C::trace_strip`), without the
/// per-strip CPU check and calls of [`StripQuery::trace`].
#[inline(always)]
fn trace_leaf_lanes<C: PacketKernel, P: LaneRays, const ANY_HIT: bool>(
    (tracer, lanes, together): (&Tracer, &Lanes, &C::Together),
    prepared: &mut P,
    leaf: &PacketDeferred,
    closest: &mut [Closest; PACKET_WIDTH],
) -> u32 {
    let t_near = leaf.t_near.to_array();
    let t_far = leaf.t_far.to_array();
    let mut finished = 0;
    let mut active = leaf.mask;
    let strips = tracer.file().leaf_strips(leaf.child, leaf.kind);
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
        let view = tracer.file().strip(strip as usize);
        let reaching = LeafLanes {
            active,
            t_near: &t_near,
            t_far: &t_far,
        };
        let packet = (tracer, lanes);
        let tested = C::trace_strip_together(
            together,
            packet,
            (&view, strip),
            &reaching,
            ANY_HIT,
            closest,
        );
        let done = tested.unwrap_or_else(|| {
            let mut done = 0;
            for_each_bit(active, |lane| {
                let closest = &mut closest[lane];
                let t_far = if ANY_HIT {
                    t_far[lane]
                } else {
                    t_far[lane].min(closest.reach)
                };
                let ray = prepared.ray(lanes, lane);
                let query = tracer.query(ray, ANY_HIT);
                if C::trace_strip(&query, &view, strip, t_near[lane], t_far, closest) {
                    done |= 1 << lane;
                }
            });
            done
        });
        finished |= done;
        active &= !done;
        if active == 0 {
            break;
        }
    }
    finished
}

//! Single-ray traversal of the global hierarchy over strips (paper 3.2, first level).
//!
//! Depth-first over the mapped node array (format 4's [`WideNode`]s, or format 3's
//! [`TopNode`]s and [`GridNode`]s, each decoded to f32 boxes, see [`TraceNode`]; traversal is
//! generic over the records and monomorphized). At a node the ray is clipped against all its
//! child boxes at once ([`WideRay::clip_boxes`], SIMD; a format 4 node's eight in one 256-bit
//! test with AVX2); of the children it enters, the first in visiting order is entered at once
//! and the others deferred on a stack with their entry distance. One skeleton serves both
//! queries, compiled for each (`ANY_HIT`), the node step apart: closest hits visit near to far
//! along the octant's diagonal (the same for every ray of a packet, see [`order_keys`]) and
//! drop a deferred child if a nearer hit was found meanwhile; occlusion visits in slot order,
//! unsorted, and ends at the first hit (see `enter_any`). At a leaf each strip's kd-tree is
//! traversed within the leaf box's parameter interval.
//!
//! Every child is clipped over `[tmin, reach]`, not over its parent's interval: the interval of
//! a leaf is then a function of the leaf's box and the closest hit so far alone, as it was with
//! the binary hierarchy, whatever the path to it.

use std::marker::PhantomData;

use arrayvec::ArrayVec;
use wide::{f32x4, u32x4};

use super::closest::Closest;
use super::kernel::codes::widen_codes;
use super::kernel::prefetch::Targets;
use super::kernel::{ChildBoxes, TraceKernel, Walk, WideClip};
use super::lanes::Lanes;
use super::prepared::{PreparedRay, WideRay};
use super::strip::StripQuery;
use super::Tracer;
use crate::format::grid::NodeGrid;
use crate::format::reader::{ReducemFile, TopNodes};
use crate::format::{
    GridNode, NodeRecord, TopNode, WideNode, GRID_LINK_INDEX, GRID_LINK_INDEX_BITS,
    GRID_LINK_INTERNAL, INTERNAL_CHILD, TOP_WIDTH, WIDE_WIDTH,
};

/// A top-level node record as traversal sees it: its child boxes in groups of four as f32, and
/// `(child, kind)` links as [`TopNode`] stores them.
pub trait TraceNode: NodeRecord {
    /// What decoding the boxes takes besides the node.
    type Decoder: Copy;
    /// Whether every ray misses an empty slot's box, so that the box test alone skips it.
    const EMPTY_BOXES_MISS: bool;
    /// Groups of four slots: a walk clips a node's children four at a time.
    const GROUPS: usize = Self::WIDTH / GROUP_WIDTH;

    /// The boxes of slots `4 group .. 4 group + 4`.
    fn boxes(&self, decoder: &Self::Decoder, group: usize) -> ChildBoxes;
    /// `(child, kind)` of an occupied slot, as in [`TopNode`].
    fn link(&self, slot: usize) -> (u32, u32);
    /// Bit `i` set when slot `i` is occupied.
    fn occupied_mask(&self) -> u32;

    /// [`order_keys`] of every slot for a direction of signs `negative`.
    #[inline(always)]
    fn order_keys<K: TraceKernel>(
        &self,
        decoder: &Self::Decoder,
        negative: &[bool; 3],
    ) -> [f32; MAX_WIDTH] {
        let mut keys = [0.0; MAX_WIDTH];
        for group in 0..Self::GROUPS {
            let (min, max) = self.boxes(decoder, group);
            let lanes = group * GROUP_WIDTH..(group + 1) * GROUP_WIDTH;
            keys[lanes].copy_from_slice(&order_keys(&min, &max, negative));
        }
        keys
    }

    /// The planes of every child box through which a packet's lanes enter and leave it
    /// ([`TraceKernel::planes`]); four-wide records by default.
    #[inline(always)]
    fn planes<K: TraceKernel>(&self, decoder: &Self::Decoder, lanes: &Lanes) -> K::Planes {
        const { assert!(Self::GROUPS == 1) };
        K::planes(lanes, &self.boxes(decoder, 0))
    }

    /// The ray's interval in each child box within `[t_near, t_far]` and the mask of the boxes
    /// it enters: the groups' boxes clipped one after the other.
    #[inline(always)]
    fn clip_children<K: TraceKernel>(
        &self,
        decoder: &Self::Decoder,
        (_, ray): (&PreparedRay, &WideRay),
        (t_near, t_far): (f32, f32),
    ) -> WideClip {
        let mut clip: WideClip = Default::default();
        for group in 0..Self::GROUPS {
            let (min, max) = self.boxes(decoder, group);
            let (near, far, mask) = ray.clip_boxes(&min, &max, t_near, t_far);
            let lanes = group * GROUP_WIDTH..(group + 1) * GROUP_WIDTH;
            clip.0[lanes.clone()].copy_from_slice(&near.to_array());
            clip.1[lanes].copy_from_slice(&far.to_array());
            clip.2 |= mask << (group * GROUP_WIDTH);
        }
        clip
    }
}

/// Slots clipped together: a group of a node's children.
pub const GROUP_WIDTH: usize = 4;
/// Slots of the widest node record.
pub const MAX_WIDTH: usize = WIDE_WIDTH;
/// Groups of the widest node record.
pub const MAX_GROUPS: usize = MAX_WIDTH / GROUP_WIDTH;
const _: () = assert!(TOP_WIDTH == GROUP_WIDTH && MAX_WIDTH.is_multiple_of(GROUP_WIDTH));

impl TraceNode for TopNode {
    type Decoder = ();
    const EMPTY_BOXES_MISS: bool = true;

    #[inline(always)]
    fn boxes(&self, _: &(), _group: usize) -> ChildBoxes {
        (self.min, self.max)
    }

    #[inline(always)]
    fn link(&self, slot: usize) -> (u32, u32) {
        (self.child[slot], self.kind[slot])
    }

    /// One SIMD compare of the four kinds, as for [`GridNode`].
    #[inline(always)]
    fn occupied_mask(&self) -> u32 {
        u32x4::from(self.kind).simd_ne(u32x4::ZERO).to_bitmask()
    }
}

/// The node grid in four lanes.
#[derive(Clone, Copy, Debug)]
pub struct NodeGridLanes {
    origin: [f32x4; 3],
    cell: f32x4,
}

impl NodeGridLanes {
    pub fn new(grid: &NodeGrid) -> NodeGridLanes {
        NodeGridLanes {
            origin: grid.origin.map(f32x4::splat),
            cell: f32x4::splat(grid.cell),
        }
    }

    /// [`NodeGrid::decode_axis`] lanewise: an exact u16 → f32 conversion, the exact product
    /// and one rounded sum, so each lane is the scalar expression's value bit for bit.
    #[inline(always)]
    fn decode(&self, q: &[u16; TOP_WIDTH], axis: usize) -> [f32; TOP_WIDTH] {
        (self.origin[axis] + f32x4::from(q.map(f32::from)) * self.cell).to_array()
    }
}

impl TraceNode for GridNode {
    type Decoder = NodeGridLanes;
    /// An empty slot is all zeros: a box at the origin that rays may well enter.
    const EMPTY_BOXES_MISS: bool = false;

    #[inline(always)]
    fn boxes(&self, grid: &NodeGridLanes, _group: usize) -> ChildBoxes {
        let decode = |q: &[[u16; TOP_WIDTH]; 3]| [0, 1, 2].map(|axis| grid.decode(&q[axis], axis));
        (decode(&self.min), decode(&self.max))
    }

    #[inline(always)]
    fn link(&self, slot: usize) -> (u32, u32) {
        unpack_link(self.link[slot])
    }

    /// One SIMD compare of the four links, cheaper than a scalar fold.
    #[inline(always)]
    fn occupied_mask(&self) -> u32 {
        u32x4::from(self.link).simd_ne(u32x4::ZERO).to_bitmask()
    }
}

impl TraceNode for WideNode {
    type Decoder = ();
    /// An empty slot is all zeros, like [`GridNode`]'s.
    const EMPTY_BOXES_MISS: bool = false;

    /// [`WideNode::decode`] lanewise: an exact u8 → f32 conversion, the exact product and one
    /// rounded sum, so each lane is the scalar expression's value bit for bit.
    #[inline(always)]
    fn boxes(&self, _: &(), group: usize) -> ChildBoxes {
        let decode = |q: &[[u8; WIDE_WIDTH]; 3]| {
            [0, 1, 2].map(|axis| {
                let codes = widen_codes(&q[axis])[group % MAX_GROUPS];
                let origin = f32x4::splat(self.origin[axis]);
                (origin + codes * f32x4::splat(self.scale(axis))).to_array()
            })
        };
        (decode(&self.min), decode(&self.max))
    }

    #[inline(always)]
    fn link(&self, slot: usize) -> (u32, u32) {
        unpack_link(self.link[slot])
    }

    #[inline(always)]
    fn order_keys<K: TraceKernel>(&self, _: &(), negative: &[bool; 3]) -> [f32; MAX_WIDTH] {
        K::wide_order_keys(self, negative)
    }

    #[inline(always)]
    fn planes<K: TraceKernel>(&self, _: &(), lanes: &Lanes) -> K::Planes {
        K::wide_planes(lanes, self)
    }

    /// All eight at once on the kernel's widest lanes.
    #[inline(always)]
    fn clip_children<K: TraceKernel>(
        &self,
        _: &(),
        (ray, wide): (&PreparedRay, &WideRay),
        interval: (f32, f32),
    ) -> WideClip {
        K::clip_wide(ray, wide, self, interval)
    }

    #[inline(always)]
    fn occupied_mask(&self) -> u32 {
        let [low, high]: [[u32; GROUP_WIDTH]; 2] = bytemuck::cast(self.link);
        let occupied = |words: [u32; GROUP_WIDTH]| u32x4::from(words).simd_ne(u32x4::ZERO);
        occupied(low).to_bitmask() | occupied(high).to_bitmask() << GROUP_WIDTH
    }
}

/// A one-word link ([`GridNode`]'s and [`WideNode`]'s) as `(child, kind)`.
#[inline(always)]
fn unpack_link(link: u32) -> (u32, u32) {
    let tag = link >> GRID_LINK_INDEX_BITS;
    let kind = if tag == GRID_LINK_INTERNAL {
        INTERNAL_CHILD
    } else {
        tag
    };
    (link & GRID_LINK_INDEX, kind)
}

/// A deferred child: its link and kind as the node's slot holds them, and the ray's interval in
/// its box.
#[derive(Clone, Copy, Default)]
pub struct Deferred {
    /// Node index of an internal child, first strip of a leaf.
    pub child: u32,
    /// [`INTERNAL_CHILD`], or a leaf's strip count.
    pub kind: u32,
    pub t_near: f32,
    pub t_far: f32,
}

impl Deferred {
    /// The root node (which has no box: the ray's own interval).
    pub fn root(ray: &PreparedRay) -> Deferred {
        Deferred {
            child: 0,
            kind: INTERNAL_CHILD,
            t_near: ray.tmin,
            t_far: ray.tmax,
        }
    }
}

/// Deferred entries kept inline. A traversal defers at most seven children per level, and
/// real trees are a dozen or two levels deep at most; the reader admits
/// [`MAX_TOP_DEPTH`](crate::format::MAX_TOP_DEPTH) levels, whose worst case spills to the heap
/// rather than making every ray carry a stack of hundreds of entries.
const INLINE_DEFERRED: usize = 64;

/// The stack of deferred children: inline (never zeroed: an `ArrayVec` leaves unused entries
/// uninitialized, which saved a 512-byte memset per ray), then spilled to the heap.
pub struct DeferStack<T> {
    inline: ArrayVec<T, INLINE_DEFERRED>,
    spill: Vec<T>,
}

impl<T> Default for DeferStack<T> {
    #[inline(always)]
    fn default() -> DeferStack<T> {
        DeferStack {
            inline: ArrayVec::new(),
            spill: Vec::new(),
        }
    }
}

impl<T> DeferStack<T> {
    #[inline(always)]
    pub fn push(&mut self, entry: T) {
        if let Err(full) = self.inline.try_push(entry) {
            self.spill.push(full.element());
        }
    }

    /// The entry pushed last: spilled entries are newer than every inline one.
    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        self.spill.pop().or_else(|| self.inline.pop())
    }
}

/// The walk of the whole file for one ray, as a [`Walk`] for the kernels to run; true when
/// `query.any_hit` found a hit.
pub(super) struct RayWalk<'a, 'q> {
    pub tracer: &'a Tracer<'a>,
    pub query: &'a StripQuery<'q>,
    pub closest: &'a mut Closest,
}

impl Walk for RayWalk<'_, '_> {
    type Output = bool;

    #[inline(always)]
    fn run<K: TraceKernel>(self) -> bool {
        trace_ray::<K>(self.tracer, self.query, self.closest)
    }
}

/// Traverses the whole file for one ray; returns true when `query.any_hit` found a hit.
fn trace_ray<K: TraceKernel>(tracer: &Tracer, query: &StripQuery, closest: &mut Closest) -> bool {
    if query.any_hit {
        trace_file::<K, true>(tracer, query, closest)
    } else {
        trace_file::<K, false>(tracer, query, closest)
    }
}

/// A walk of the top level generic over its node record, for [`walk_top_level`]: each of the
/// tracer's walks is written once over [`TraceNode`] and compiled for every record.
pub(super) trait TopLevelWalk {
    type Output;

    fn run<N: TraceNode>(self, nodes: &[N], decoder: &N::Decoder) -> Self::Output;
}

/// Runs `walk` over `file`'s top-level nodes: the tracer's one dispatch on the record.
#[inline(always)]
pub(super) fn walk_top_level<W: TopLevelWalk>(file: &ReducemFile, walk: W) -> W::Output {
    match file.top_nodes() {
        TopNodes::F32(nodes) => walk.run(nodes, &()),
        TopNodes::Grid(nodes, grid) => walk.run(nodes, &NodeGridLanes::new(&grid)),
        TopNodes::Wide(nodes) => walk.run(nodes, &()),
    }
}

/// [`trace_ray`] for occlusion (`ANY_HIT`) or closest hits.
#[inline(always)]
fn trace_file<K: TraceKernel, const ANY_HIT: bool>(
    tracer: &Tracer,
    query: &StripQuery,
    closest: &mut Closest,
) -> bool {
    let walk = FileRay::<K, ANY_HIT> {
        tracer,
        query,
        closest,
        kernel: PhantomData,
    };
    walk_top_level(tracer.file(), walk)
}

/// [`trace_file`]'s walk from the root, for [`walk_top_level`].
struct FileRay<'a, 'q, K, const ANY_HIT: bool> {
    tracer: &'a Tracer<'a>,
    query: &'a StripQuery<'q>,
    closest: &'a mut Closest,
    kernel: PhantomData<K>,
}

impl<K: TraceKernel, const ANY_HIT: bool> TopLevelWalk for FileRay<'_, '_, K, ANY_HIT> {
    type Output = bool;

    #[inline(always)]
    fn run<N: TraceNode>(self, nodes: &[N], decoder: &N::Decoder) -> bool {
        let FileRay {
            tracer,
            query,
            closest,
            ..
        } = self;
        let root = Deferred::root(query.ray);
        trace_nodes::<_, K, ANY_HIT>(tracer, (nodes, decoder), query, root, closest)
    }
}

/// The walk of the subtree (or leaf) `start`, entered over its interval, for occlusion
/// (`ANY_HIT`, which `query.any_hit` must match) or closest hits: one skeleton, the node step
/// apart; true when an occluder was found. Packets hand it the lanes they no longer serve
/// together.
#[inline(always)]
pub(super) fn trace_nodes<N: TraceNode, K: TraceKernel, const ANY_HIT: bool>(
    tracer: &Tracer,
    (nodes, decoder): (&[N], &N::Decoder),
    query: &StripQuery,
    start: Deferred,
    closest: &mut Closest,
) -> bool {
    let file = tracer.file();
    // A walk started on a leaf traces it at once: no node, stack or prefetch targets to set
    // up for it.
    if start.kind != INTERNAL_CHILD {
        return trace_leaf::<K>(tracer, query, &start, closest);
    }
    let ray = WideRay::new(query.ray);
    let mut stack = DeferStack::default();
    let mut current = start;
    let targets = Targets::new(tracer.strip_sections(), nodes);
    // `ReducemFile::node_visits`, from the nodes at hand rather than a second look-up.
    let mut visits = nodes.len();
    loop {
        if current.kind == INTERNAL_CHILD {
            let Some(left) = visits.checked_sub(1) else {
                return false;
            };
            visits = left;
            // A match rather than `Option::and_then`, whose closure stayed out of line.
            if let Some(node) = file.top_node(nodes, current.child as usize) {
                let walk = (&targets, &ray, query, &mut stack);
                let entered = if ANY_HIT {
                    enter_any::<N, K>(walk, node, decoder, closest)
                } else {
                    enter_children::<N, K>(walk, node, decoder, closest)
                };
                if let Some(nearest) = entered {
                    current = nearest;
                    continue;
                }
            }
        } else if trace_leaf::<K>(tracer, query, &current, closest) {
            return true;
        }
        loop {
            let Some(next) = stack.pop() else {
                return false;
            };
            // An occlusion walk's bound stays `tmax` until its first hit ends it.
            if ANY_HIT || next.t_near <= closest.reach {
                current = next;
                break;
            }
        }
    }
}

/// What a node step of the single-ray walk works with: the prefetch targets, the ray in lanes,
/// the query and the stack of deferred children.
type RayStep<'w, 'a, 'q, N> = (
    &'w Targets<'a, N>,
    &'w WideRay,
    &'w StripQuery<'q>,
    &'w mut DeferStack<Deferred>,
);

/// The ray clipped against `node`'s occupied children: their intervals and the mask of those
/// entered.
#[inline(always)]
fn clip_node<N: TraceNode, K: TraceKernel>(
    (ray, wide): (&PreparedRay, &WideRay),
    node: &N,
    decoder: &N::Decoder,
    closest: &Closest,
) -> WideClip {
    let (near, far, mut mask) =
        node.clip_children::<K>(decoder, (ray, wide), (ray.tmin, closest.reach));
    if !N::EMPTY_BOXES_MISS {
        mask &= node.occupied_mask();
    }
    (near, far, mask)
}

/// Child `slot` of `node` entered over `(near, far)`, its first loads asked for.
#[inline(always)]
fn defer<N: TraceNode>(targets: &Targets<N>, node: &N, slot: usize, clip: &WideClip) -> Deferred {
    let (child, kind) = node.link(slot);
    targets.child((child, kind));
    Deferred {
        child,
        kind,
        t_near: clip.0[slot % MAX_WIDTH],
        t_far: clip.1[slot % MAX_WIDTH],
    }
}

/// For closest hits: clips the ray against `node`'s children; returns the first one entered
/// in [`order_keys`] order (which packets reproduce lane by lane) and defers the others, last
/// first, so that they come off the stack in order.
#[inline(always)]
fn enter_children<N: TraceNode, K: TraceKernel>(
    (targets, ray, query, stack): RayStep<N>,
    node: &N,
    decoder: &N::Decoder,
    closest: &Closest,
) -> Option<Deferred> {
    let clip = clip_node::<N, K>((query.ray, ray), node, decoder, closest);
    let mask = clip.2;
    if mask.is_power_of_two() {
        return Some(defer(targets, node, mask.trailing_zeros() as usize, &clip));
    }
    if mask == 0 {
        return None;
    }
    let keys = node.order_keys::<K>(decoder, &ray.negative);
    let mut entered = [(0.0, Deferred::default()); MAX_WIDTH];
    let mut count = 0;
    for_each_bit(mask, |slot| {
        entered[count] = (keys[slot], defer(targets, node, slot, &clip));
        count += 1;
    });
    let entered = &mut entered[..count];
    sort_by_key(entered);
    entered.iter().skip(1).rev().for_each(|e| stack.push(e.1));
    entered.first().map(|e| e.1)
}

/// For occlusion: clips the ray against `node`'s children; returns the first one it enters in
/// slot order and defers the others, unsorted. The answer does not depend on the order, since
/// the culling bound stays `tmax` until the first hit ends the walk; sorting the children (by
/// entry distance, or picking the nearest) cost more than the occluders it found sooner.
#[inline(always)]
fn enter_any<N: TraceNode, K: TraceKernel>(
    (targets, ray, query, stack): RayStep<N>,
    node: &N,
    decoder: &N::Decoder,
    closest: &Closest,
) -> Option<Deferred> {
    let clip = clip_node::<N, K>((query.ray, ray), node, decoder, closest);
    let mask = clip.2;
    if mask == 0 {
        return None;
    }
    let first = mask.trailing_zeros() as usize;
    let others = mask & (mask - 1);
    for_each_bit(others, |slot| stack.push(defer(targets, node, slot, &clip)));
    Some(defer(targets, node, first, &clip))
}

/// The order in which a node's children are visited, as sort keys: each box's centre (doubled)
/// projected on the diagonal of the ray's octant, so that nearer children along the direction
/// come first. It depends on the direction's signs alone, not on the origin or the entry
/// distances: the rays of a packet share their signs, so each lane visits a node's children in
/// the order it would alone, and packets give the single rays' results bit for bit on any file
/// that opens, even on a corrupt one whose boxes no longer bound their strips (where the order
/// decides which hits are culled). A NaN key (a box with infinite or NaN bounds, in a corrupt
/// file) counts as `-inf`: with no NaN among the keys, sorting any subset of the children gives
/// the order of sorting them all restricted to that subset, which packets rely on: they sort
/// the children any of their lanes entered, and each lane must meet its own in the order it
/// would sort them alone.
#[inline(always)]
pub fn order_keys(
    min: &[[f32; TOP_WIDTH]; 3],
    max: &[[f32; TOP_WIDTH]; 3],
    negative: &[bool; 3],
) -> [f32; TOP_WIDTH] {
    let mut key = f32x4::ZERO;
    for (axis, &negative) in negative.iter().enumerate() {
        let centre = f32x4::from(min[axis]) + f32x4::from(max[axis]);
        key = if negative { key - centre } else { key + centre };
    }
    let nan = key.simd_ne(key);
    nan.bitselect(f32x4::splat(f32::NEG_INFINITY), key)
        .to_array()
}

/// Calls `f` with the index of every set bit of `mask`, lowest first.
#[inline(always)]
pub fn for_each_bit(mut mask: u32, mut f: impl FnMut(usize)) {
    while mask != 0 {
        f(mask.trailing_zeros() as usize);
        mask &= mask - 1;
    }
}

/// Insertion sort of the at most eight children entered by their [`order_keys`]; stable, so
/// equal keys keep slot order.
#[inline(always)]
pub fn sort_by_key<T: Copy>(entries: &mut [(f32, T)]) {
    for i in 1..entries.len() {
        let mut j = i;
        while j > 0 && entries[j].0 < entries[j - 1].0 {
            entries.swap(j, j - 1);
            j -= 1;
        }
    }
}

/// Traverses every strip of a leaf (`leaf.child` its first strip, `leaf.kind` its count) within
/// the leaf box's interval.
#[inline]
fn trace_leaf<K: TraceKernel>(
    tracer: &Tracer,
    query: &StripQuery,
    leaf: &Deferred,
    closest: &mut Closest,
) -> bool {
    let file = tracer.file();
    for strip in tracer.strip_sections().leaf_strips(leaf.child, leaf.kind) {
        let t_far = leaf.t_far.min(closest.reach);
        if leaf.t_near > t_far {
            break;
        }
        let view = file.strip(strip as usize);
        if query.trace::<K>(&view, strip, leaf.t_near, t_far, closest) {
            return true;
        }
    }
    false
}

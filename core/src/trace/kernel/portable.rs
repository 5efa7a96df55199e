//! The portable kernel, which every CPU runs: `wide`'s lanes (eight-lane operations are two
//! SSE2 or NEON operations each), picked when the crate is compiled.

use wide::{f32x4, f32x8};

use super::codes::widen_codes;
use super::{
    BlockEdges, ChildBoxes, EnteredBoxes, LeafLanes, LeafStrip, TraceKernel, Walk, WideClip, BLOCK,
    BOX_GROUP,
};
use crate::format::block_boxes::{BlockBoxes, BoxFrame, BOX_BYTES, CODE_BIAS, MAX_CODE};
use crate::format::references::References;
use crate::format::vertices::VertexAccess;
use crate::format::{WideNode, TOP_WIDTH, WIDE_WIDTH};
use crate::trace::closest::Closest;
use crate::trace::lanes::{prepare, Lanes, PACKET_WIDTH};
use crate::trace::prepared::{
    max_not_nan, max_not_nan_x4, max_not_nan_x8, min_not_nan, min_not_nan_x4, min_not_nan_x8,
    PreparedRay, WideRay, FAR_INFLATION,
};
use crate::trace::ray::Ray;
use crate::trace::top::order_keys;
use crate::trace::watertight::{candidate_lanes, edge_lanes, RaySpace};

/// The portable kernel.
pub(super) struct Portable;

impl TraceKernel for Portable {
    /// Never inlined: each instantiation (an axis order and an encoding of the strip walk, the
    /// single-ray walk) is compiled on its own rather than some into their callers, whose size
    /// then swayed how well the others were optimized.
    #[inline(never)]
    fn compiled<W: Walk>(walk: W) -> W::Output {
        walk.run::<Portable>()
    }

    #[inline(always)]
    fn references(references: &References, first: usize) -> [u8; BLOCK + 2] {
        references.read_block(first)
    }

    /// The block's `BLOCK + 2` positions are gathered once into an array and read as lanes
    /// shifted by 0, 1 and 2 positions as the windows' three corners; each corner is moved to
    /// ray space (x and y) and each edge evaluated in lanes.
    #[inline(always)]
    fn edges<
        V: VertexAccess,
        const KX: usize,
        const KY: usize,
        const KZ: usize,
        const SITE: usize,
    >(
        space: &RaySpace,
        vertices: V,
        references: &[u8; BLOCK + 2],
        count: usize,
        _range: (f32, f32),
    ) -> Option<BlockEdges> {
        let model = vertices.gather::<KX, KY, KZ, { BLOCK + 2 }>(references, count + 2);
        // A position is transformed once per corner it is in (up to three times) rather than
        // once and then shifted through memory: the arithmetic is cheaper than storing lanes and
        // reloading them misaligned, and every copy of a vertex has the same bits.
        let corner = |shift: usize| {
            space.transform_lanes::<KX, KY, KZ>(
                lanes_from(&model[0], shift),
                lanes_from(&model[1], shift),
                lanes_from(&model[2], shift),
            )
        };
        let corners = [corner(0), corner(1), corner(2)];
        // Window `k`'s short edges are also windows `k - 1`'s and `k + 1`'s, but evaluating them
        // again in the lanes where they are needed is cheaper than shifting them across lanes.
        let weights = [
            edge_lanes(&corners[1], &corners[2]),
            edge_lanes(&corners[2], &corners[0]),
            edge_lanes(&corners[0], &corners[1]),
        ];
        let candidates = candidate_lanes(weights) & ((1 << count) - 1);
        (candidates != 0).then(|| BlockEdges {
            candidates,
            x: corners.map(|c| c.x.to_array()),
            y: corners.map(|c| c.y.to_array()),
            weights: weights.map(f32x8::to_array),
        })
    }

    /// One box after the other.
    #[inline(always)]
    fn entered_boxes(
        ray: &PreparedRay,
        boxes: &BlockBoxes,
        frame: &BoxFrame,
        group: usize,
        t_near: f32,
        t_far: f32,
    ) -> EnteredBoxes {
        let test = BoxTest::new(ray, frame);
        let mut entered = EnteredBoxes::default();
        for lane in 0..BOX_GROUP {
            let Some(codes) = boxes.codes(group * BOX_GROUP + lane) else {
                break;
            };
            let (near, far) = test.interval(codes, t_near, t_far);
            entered.near[lane] = near;
            entered.mask |= u32::from(near <= far) << lane;
        }
        entered
    }

    type PreparedRays = [PreparedRay; PACKET_WIDTH];

    #[inline(always)]
    fn prepared_rays(rays: &[Ray]) -> [PreparedRay; PACKET_WIDTH] {
        prepare(rays)
    }

    #[inline(always)]
    fn lanes(_rays: &[Ray], prepared: &[PreparedRay; PACKET_WIDTH]) -> Lanes {
        Lanes::of(prepared)
    }

    type Planes = SlotPlanes;

    #[inline(always)]
    fn planes(lanes: &Lanes, (min, max): &ChildBoxes) -> SlotPlanes {
        let mut planes = SlotPlanes::default();
        for axis in 0..3 {
            planes.set(axis, 0, lanes.negative()[axis], (&min[axis], &max[axis]));
        }
        planes
    }

    #[inline(always)]
    fn wide_planes(lanes: &Lanes, node: &WideNode) -> SlotPlanes {
        let negative = lanes.negative();
        // Axis by axis, not through `array::map`, whose closure may stay a call.
        let planes = [
            wide_axis_planes(node, 0, negative[0]),
            wide_axis_planes(node, 1, negative[1]),
            wide_axis_planes(node, 2, negative[2]),
        ];
        let slots = |lanes: [f32x4; 2]| -> [f32; WIDE_WIDTH] { bytemuck::cast(lanes) };
        SlotPlanes {
            entry: planes.map(|(entry, _)| slots(entry)),
            exit: planes.map(|(_, exit)| slots(exit)),
        }
    }

    #[inline(always)]
    fn clip_slot(
        lanes: &Lanes,
        planes: &SlotPlanes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32) {
        // The remainder spares the bounds checks.
        let slot = slot % WIDE_WIDTH;
        let mut near = lanes.tmin;
        let mut far = t_far;
        for axis in 0..3 {
            let entry = (f32x8::splat(planes.entry[axis][slot]) - lanes.origin[axis])
                * lanes.entry_reciprocal[axis];
            let exit = (f32x8::splat(planes.exit[axis][slot]) - lanes.origin[axis])
                * lanes.exit_reciprocal[axis]
                * f32x8::splat(FAR_INFLATION);
            near = max_not_nan_x8(near, entry);
            far = min_not_nan_x8(far, exit);
        }
        (near, far, near.simd_le(far).to_bitmask())
    }

    #[inline(always)]
    fn decode_wide(node: &WideNode) -> [ChildBoxes; 2] {
        let mut boxes = [([[0.0; TOP_WIDTH]; 3], [[0.0; TOP_WIDTH]; 3]); 2];
        for (axis, &origin) in node.origin.iter().enumerate() {
            let (origin, scale) = (f32x4::splat(origin), f32x4::splat(node.scale(axis)));
            let [min_low, min_high] = widen_codes(&node.min[axis]);
            let [max_low, max_high] = widen_codes(&node.max[axis]);
            boxes[0].0[axis] = (origin + min_low * scale).to_array();
            boxes[1].0[axis] = (origin + min_high * scale).to_array();
            boxes[0].1[axis] = (origin + max_low * scale).to_array();
            boxes[1].1[axis] = (origin + max_high * scale).to_array();
        }
        boxes
    }

    /// Two groups of four boxes, each decoded and clipped as the single-ray walk does; each
    /// plane's eight codes widened once.
    #[inline(always)]
    fn clip_wide(
        _ray: &PreparedRay,
        wide: &WideRay,
        node: &WideNode,
        (t_near, t_far): (f32, f32),
    ) -> WideClip {
        let mut intervals = [(f32x4::splat(t_near), f32x4::splat(t_far)); 2];
        for axis in 0..3 {
            let (entry, exit) = wide_axis_planes(node, axis, wide.negative[axis]);
            for (group, interval) in intervals.iter_mut().enumerate() {
                *interval = wide.clip_axis(axis, (entry[group], exit[group]), *interval);
            }
        }
        let mut clip: WideClip = Default::default();
        for (group, (near, far)) in intervals.into_iter().enumerate() {
            clip.0[group * TOP_WIDTH..][..TOP_WIDTH].copy_from_slice(&near.to_array());
            clip.1[group * TOP_WIDTH..][..TOP_WIDTH].copy_from_slice(&far.to_array());
            clip.2 |= near.simd_le(far).to_bitmask() << (group * TOP_WIDTH);
        }
        clip
    }

    #[inline(always)]
    fn wide_order_keys(node: &WideNode, negative: &[bool; 3]) -> [f32; WIDE_WIDTH] {
        let mut keys = [0.0; WIDE_WIDTH];
        for (group, (min, max)) in Portable::decode_wide(node).iter().enumerate() {
            keys[group * TOP_WIDTH..][..TOP_WIDTH].copy_from_slice(&order_keys(min, max, negative));
        }
        keys
    }

    #[inline(always)]
    fn plane_order_keys(planes: &SlotPlanes, negative: &[bool; 3]) -> [f32; WIDE_WIDTH] {
        let mut key = f32x8::ZERO;
        for (axis, &negative) in negative.iter().enumerate() {
            let centre = f32x8::from(planes.entry[axis]) + f32x8::from(planes.exit[axis]);
            key = if negative { key - centre } else { key + centre };
        }
        let nan = key.simd_ne(key);
        nan.bitselect(f32x8::splat(f32::NEG_INFINITY), key)
            .to_array()
    }

    #[inline(always)]
    fn lanes_at_most(a: f32x8, b: f32x8) -> u32 {
        a.simd_le(b).to_bitmask()
    }

    /// `None` when a lane's reciprocal is infinite or zero or its origin not finite, where
    /// the frustum's bounds would not hold.
    type Frustum = Option<Frustum>;

    #[inline(always)]
    fn frustum(lanes: &Lanes, packet_mask: u32) -> Option<Frustum> {
        Frustum::new(lanes, packet_mask)
    }

    /// Packets keep one octant: the portable packet strip test and box clips pick their planes
    /// by lane 0's signs.
    const MIXED_OCCLUSION: bool = false;

    type Mixed = ();

    #[inline(always)]
    fn mixed(_lanes: &Lanes, _packet_mask: u32, _limit: f32x8) {}

    #[inline(always)]
    fn mixed_against(_lanes: &Lanes, _packet_mask: u32, _limit: f32x8, _first: &Lanes) {}

    #[inline(always)]
    fn mixed_slots(_mixed: &(), _planes: &SlotPlanes) -> u32 {
        u32::MAX
    }

    #[inline(always)]
    fn clip_slot_mixed(
        lanes: &Lanes,
        _mixed: &(),
        planes: &SlotPlanes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32) {
        Portable::clip_slot(lanes, planes, slot, t_far)
    }

    /// Per axis a lane's entry distance `(entry - o) * r` is at least the lesser of
    /// `(entry - o') * r_low` and `(entry - o') * r_high` with `o'` the frustum's entry origin
    /// (each rounded operation is monotone in each operand, and `r` has one sign), and its
    /// exit distance at most the greater such product from the exit origin, inflated as the
    /// lanes' are; a NaN bound keeps the interval's value, as in `clip_slot`, so it culls
    /// nothing. A slot is left out only where the least entry is beyond the greatest exit.
    #[inline(always)]
    fn frustum_slots(frustum: &Option<Frustum>, planes: &SlotPlanes, reach: f32) -> u32 {
        let Some(frustum) = frustum else {
            return u32::MAX;
        };
        let mut near = f32x8::splat(frustum.tmin);
        let mut far = f32x8::splat(reach);
        for axis in 0..3 {
            let low = f32x8::splat(frustum.reciprocal_low[axis]);
            let high = f32x8::splat(frustum.reciprocal_high[axis]);
            let entry = f32x8::from(planes.entry[axis]) - f32x8::splat(frustum.entry_origin[axis]);
            let exit = f32x8::from(planes.exit[axis]) - f32x8::splat(frustum.exit_origin[axis]);
            // Either both products are NaN or neither: which one `fast_min` keeps is moot.
            let entry = (entry * low).fast_min(entry * high);
            let exit = (exit * low).fast_max(exit * high) * f32x8::splat(FAR_INFLATION);
            near = max_not_nan_x8(near, entry);
            far = min_not_nan_x8(far, exit);
        }
        !near.simd_gt(far).to_bitmask()
    }

    type Together = ();

    #[inline(always)]
    fn together(_lanes: &Lanes) {}

    /// Strips are always walked lane by lane.
    #[inline(always)]
    fn trace_strip_together(
        _together: &(),
        _lanes: &Lanes,
        _strip: &LeafStrip,
        _leaf: &LeafLanes,
        _any_hit: bool,
        _closest: &mut [Closest; PACKET_WIDTH],
    ) -> Option<u32> {
        None
    }
}

/// The entry and exit planes of `axis` of a format 4 node's eight children, in two groups of
/// four: the minima unless the direction is negative, decoded as [`WideNode::decode`].
#[inline(always)]
fn wide_axis_planes(node: &WideNode, axis: usize, negative: bool) -> ([f32x4; 2], [f32x4; 2]) {
    let (entry, exit) = match negative {
        true => (&node.max[axis], &node.min[axis]),
        false => (&node.min[axis], &node.max[axis]),
    };
    let (origin, scale) = (
        f32x4::splat(node.origin[axis]),
        f32x4::splat(node.scale(axis)),
    );
    let decode = |codes: &[u8; WIDE_WIDTH]| widen_codes(codes).map(|q| origin + q * scale);
    (decode(entry), decode(exit))
}

/// The packet's rays bounded together, for `TraceKernel::frustum_slots`: per axis the origin
/// that gives a plane's smallest entry distance over the lanes and the one that gives its
/// largest exit distance, and the lanes' least and greatest reciprocal; the least `tmin`.
pub(super) struct Frustum {
    entry_origin: [f32; 3],
    exit_origin: [f32; 3],
    reciprocal_low: [f32; 3],
    reciprocal_high: [f32; 3],
    tmin: f32,
}

impl Frustum {
    /// The bounds over the lanes of `packet_mask`, which share their direction signs.
    fn new(lanes: &Lanes, packet_mask: u32) -> Option<Frustum> {
        let in_packet = |values: f32x8| {
            let values = values.to_array();
            (0..PACKET_WIDTH)
                .filter(move |&lane| packet_mask >> lane & 1 != 0)
                .map(move |lane| values[lane])
        };
        let low = |values: f32x8| in_packet(values).fold(f32::INFINITY, f32::min);
        let high = |values: f32x8| in_packet(values).fold(f32::NEG_INFINITY, f32::max);
        let mut frustum = Frustum {
            entry_origin: [0.0; 3],
            exit_origin: [0.0; 3],
            reciprocal_low: [0.0; 3],
            reciprocal_high: [0.0; 3],
            // `f32::min` passes over a NaN `tmin`, of a lane that enters nothing.
            tmin: low(lanes.tmin),
        };
        for axis in 0..3 {
            let usable = |r: f32| r.is_finite() && r != 0.0;
            if !in_packet(lanes.exit_reciprocal[axis]).all(usable)
                || !in_packet(lanes.origin[axis]).all(f32::is_finite)
            {
                return None;
            }
            let (least, greatest) = (low(lanes.origin[axis]), high(lanes.origin[axis]));
            // A positive direction enters a plane first from the greatest origin and leaves
            // it last from the least; a negative one the other way round.
            (frustum.entry_origin[axis], frustum.exit_origin[axis]) =
                match lanes.signs[axis] & 1 != 0 {
                    true => (least, greatest),
                    false => (greatest, least),
                };
            frustum.reciprocal_low[axis] = low(lanes.exit_reciprocal[axis]);
            frustum.reciprocal_high[axis] = high(lanes.exit_reciprocal[axis]);
        }
        Some(frustum)
    }
}

/// A node's child box planes as a packet sees them (see [`TraceKernel::planes`]),
/// `[axis][slot]`.
#[derive(Default)]
pub(super) struct SlotPlanes {
    entry: [[f32; WIDE_WIDTH]; 3],
    exit: [[f32; WIDE_WIDTH]; 3],
}

impl SlotPlanes {
    /// Slots `first..first + 4` of `axis` from their minima and maxima: the entry planes are
    /// the minima unless the direction is negative.
    #[inline(always)]
    fn set(&mut self, axis: usize, first: usize, negative: bool, planes: ChildPlanes) {
        let (min, max) = planes;
        let (entry, exit) = if negative { (max, min) } else { (min, max) };
        self.entry[axis][first..][..TOP_WIDTH].copy_from_slice(entry);
        self.exit[axis][first..][..TOP_WIDTH].copy_from_slice(exit);
    }
}

/// The minima and maxima of four slots on one axis.
type ChildPlanes<'a> = (&'a [f32; TOP_WIDTH], &'a [f32; TOP_WIDTH]);

/// Lanes `shift..shift + BLOCK` of `values`.
#[inline(always)]
fn lanes_from(values: &[f32], shift: usize) -> f32x8 {
    let lanes: [f32; BLOCK] = values[shift..shift + BLOCK]
        .try_into()
        .expect("BLOCK lanes");
    f32x8::from(lanes)
}

/// A ray and a strip's box frame in lanes `x, y, z` (lane 3 unused), to test one block box in
/// a few SIMD operations: per lane the arithmetic of [`PreparedRay::clip_box`] on the planes
/// [`crate::format::block_boxes::decode_plane`] gives (the box's lanes `(code - 8) * scale`
/// are exact, as there). Since the boxes hold their windows and the test is conservative as
/// `clip_box` is, no hit is ever culled.
struct BoxTest {
    anchor: f32x4,
    scale: f32x4,
    origin: f32x4,
    entry_reciprocal: f32x4,
    exit_reciprocal: f32x4,
    /// All ones in the lanes of the axes the ray goes down.
    negative: f32x4,
}

impl BoxTest {
    #[inline(always)]
    fn new(ray: &PreparedRay, frame: &BoxFrame) -> BoxTest {
        let lanes = |v: &[f32; 3]| f32x4::from([v[0], v[1], v[2], 0.0]);
        let negative = ray
            .negative
            .map(|n| f32::from_bits(if n { u32::MAX } else { 0 }));
        BoxTest {
            anchor: lanes(&frame.anchor),
            scale: lanes(&frame.scale),
            origin: lanes(&ray.origin),
            entry_reciprocal: lanes(&ray.entry_reciprocal),
            exit_reciprocal: lanes(&ray.exit_reciprocal),
            negative: lanes(&negative),
        }
    }

    /// The ray's interval `(near, far)` in the box of `codes` within `[t_near, t_far]`: it
    /// enters the box when `near <= far`.
    #[inline(always)]
    fn interval(&self, codes: [u8; BOX_BYTES], t_near: f32, t_far: f32) -> (f32, f32) {
        let bias = CODE_BIAS as f32;
        let code = |shift: u8, mask: u8| {
            f32x4::from([
                f32::from(codes[0] >> shift & mask),
                f32::from(codes[1] >> shift & mask),
                f32::from(codes[2] >> shift & mask),
                bias,
            ])
        };
        let bias = f32x4::splat(bias);
        let min = self.anchor + (code(0, MAX_CODE) - bias) * self.scale;
        let max = self.anchor + (code(4, MAX_CODE) - bias) * self.scale;
        let entry_plane = self.negative.select(max, min);
        let exit_plane = self.negative.select(min, max);
        let entry = (entry_plane - self.origin) * self.entry_reciprocal;
        let exit = (exit_plane - self.origin) * self.exit_reciprocal * f32x4::splat(FAR_INFLATION);
        let near = max_not_nan_x4(f32x4::splat(t_near), entry).to_array();
        let far = min_not_nan_x4(f32x4::splat(t_far), exit).to_array();
        (
            max_not_nan(max_not_nan(near[0], near[1]), near[2]),
            min_not_nan(min_not_nan(far[0], far[1]), far[2]),
        )
    }
}

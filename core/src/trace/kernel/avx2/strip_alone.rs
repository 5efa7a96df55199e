//! A short strip tested for a lane of a packet as that lane's ray alone would test it: its
//! block boxes four to a pass ([`entered_boxes`]), then each block entered, eight windows at a
//! time. For the one or two lanes that reach most strips of camera packets this costs less
//! than the strip's windows one after the other for all eight rays of the packet
//! ([`super::packet_strips`]), and less than the single-ray walk, which would first make the
//! lane's `PreparedRay` and pick the strip walk compiled for its axes.
//!
//! The lane's ray is read from the packet's lanes (which hold `PreparedRay::new`'s bits), so
//! no `PreparedRay` is made for it; the block's corners and edge functions are
//! [`block_edges`]'s lossless arm with the ray-space axes picked at run time (the lane's, not
//! the walk's constants): the same operations on the same positions, so every box decision,
//! weight, candidate and hit has the single-ray walk's bits.
//!
//! [`block_edges`]: super::blocks::block_edges

use std::arch::x86_64::*;

use super::blocks::{
    entered_boxes, in_range_lanes, shift_lanes, shifted_corners, transform, transpose_positions_on,
    window_candidates, BoxRay,
};
use super::packet_strips::{LaneSpaces, MAX_WINDOWS};
use super::simd::lanes as lanes_of;
use super::Avx2;
use crate::format::reader::StripView;
use crate::trace::closest::Closest;
use crate::trace::kernel::{EnteredBoxes, LeafLanes, TraceKernel, BLOCK, BOX_GROUP};
use crate::trace::lanes::{Lanes, PACKET_WIDTH};
use crate::trace::watertight::{resolve, RayPoint};

/// One lane's ray: what its box test reads (origin and reciprocals per model axis), its ray-space
/// axes as a `vpermilps` control, and its ray space with each quantity in every SIMD lane (the
/// origin on the ray-space axes, the shears, the depth scale).
struct LoneRay {
    model_origin: [f32; 3],
    entry_reciprocal: [f32; 3],
    exit_reciprocal: [f32; 3],
    axes: __m128i,
    origin: [__m256; 3],
    shear: [__m256; 2],
    scale_z: __m256,
    tmin: f32,
}

impl LoneRay {
    /// Lane `lane`'s ray, read from `lanes` and, already moved to its ray-space axes, from
    /// `spaces`.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    fn new((lanes, spaces): (&Lanes, &LaneSpaces), lane: usize) -> LoneRay {
        let lane = lane % PACKET_WIDTH;
        let at = |values: &[wide::f32x8; 3]| values.each_ref().map(|v| v.as_array()[lane]);
        let [a, b, c] = lanes.space_axes.each_ref().map(|a| a.as_array()[lane]);
        let (origin, shear, scale_z) = spaces.lane(lane);
        LoneRay {
            model_origin: at(&lanes.origin),
            entry_reciprocal: at(&lanes.entry_reciprocal),
            exit_reciprocal: at(&lanes.exit_reciprocal),
            axes: _mm_setr_epi32(a, b, c, 3),
            origin,
            shear,
            scale_z,
            tmin: lanes.tmin.as_array()[lane],
        }
    }

    /// What the box test reads, for a direction of signs `negative`.
    #[inline(always)]
    fn boxes<'a>(&'a self, negative: &'a [bool; 3]) -> BoxRay<'a> {
        BoxRay {
            origin: &self.model_origin,
            entry_reciprocal: &self.entry_reciprocal,
            exit_reciprocal: &self.exit_reciprocal,
            negative,
        }
    }
}

/// A block's candidate windows for the lone lane, with each corner's ray-space x, y and depth
/// and the windows' edge functions, per window lane.
struct LoneEdges {
    candidates: u32,
    x: [[f32; BLOCK]; 3],
    y: [[f32; BLOCK]; 3],
    z: [[f32; BLOCK]; 3],
    weights: [[f32; BLOCK]; 3],
}

/// Tests the lossless strip `view` (number `strip`, with `points`, at most [`MAX_WINDOWS`]
/// windows) for lane `lane` of the leaf alone, as the single-ray walk does: its boxes against
/// the lane's interval (clipped to its culling bound for closest hits), the blocks entered in
/// strip order, each skipped when a hit found since is nearer than its box. Returns the lane's
/// bit when it found a hit and `any_hit` is set (it is done). `#[inline]` so that it is
/// compiled with its one caller wherever the compiler places that caller's module.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn trace_strip_alone(
    (lanes, spaces, lane): (&Lanes, &LaneSpaces, usize),
    leaf: &LeafLanes,
    (view, strip, points): (&StripView, u32, &[[f32; 3]]),
    any_hit: bool,
    closest: &mut Closest,
) -> u32 {
    let ray = LoneRay::new((lanes, spaces), lane);
    let lane = lane % PACKET_WIDTH;
    let t_far = if any_hit {
        leaf.t_far[lane]
    } else {
        leaf.t_far[lane].min(closest.reach)
    };
    let count = view.window_count().min(MAX_WINDOWS);
    let blocks = (1 << count.div_ceil(BLOCK)) - 1;
    let entered = match view.boxes.frame(points[0]) {
        Some(frame) => {
            let interval = (leaf.t_near[lane], t_far);
            // Only occlusion packets mix direction signs: the lane's own, else the packet's.
            let negative = match any_hit {
                true => lanes.signs.map(|signs| signs >> lane & 1 != 0),
                false => lanes.negative(),
            };
            entered_boxes(
                ray.boxes(&negative),
                view.boxes.bytes(),
                &frame,
                0,
                interval,
            )
        }
        // A strip without boxes is one kd leaf, whose blocks the walk tests without culling.
        None => EnteredBoxes {
            mask: blocks,
            near: [f32::NEG_INFINITY; BOX_GROUP],
        },
    };
    let mut mask = entered.mask & blocks;
    while mask != 0 {
        let block = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        if entered.near[block % BOX_GROUP] > closest.reach {
            continue;
        }
        let first = block * BLOCK;
        let references = Avx2::references(&view.references, first);
        let block_at = (&references, first, BLOCK.min(count - first));
        if test_block::<0>(&ray, (strip, points), block_at, any_hit, closest) {
            return 1 << lane;
        }
    }
    0
}

/// Tests the block of windows `first ..` (`windows` of them, `references` theirs) of the
/// lossless strip number `strip` for the lone lane `ray`, window after window as the
/// single-ray block does; true when it found a hit and `any_hit` is set (the lane is done).
/// `SITE` tells its two callers apart, so that each instantiation has one caller and is
/// inlined into it.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn test_block<const SITE: usize>(
    ray: &LoneRay,
    (strip, points): (u32, &[[f32; 3]]),
    (references, first, windows): (&[u8; BLOCK + 2], usize, usize),
    any_hit: bool,
    closest: &mut Closest,
) -> bool {
    let Some(edges) = lone_edges::<SITE>(ray, points, (references, windows), closest.t) else {
        return false;
    };
    let mut candidates = edges.candidates;
    while candidates != 0 {
        let k = candidates.trailing_zeros() as usize;
        candidates &= candidates - 1;
        let c: [RayPoint; 3] = std::array::from_fn(|corner| RayPoint {
            x: edges.x[corner][k],
            y: edges.y[corner][k],
            z: edges.z[corner][k],
        });
        let w = edges.weights.map(|w| w[k]);
        if let Some(hit) = resolve(&c, w, ray.tmin, closest.t) {
            let corners = [0, 1, 2].map(|c| references[k + c]);
            let window = (strip, (first + k) as u16);
            closest.offer(hit.t, window, hit.weights, (points, corners));
            if any_hit {
                return true;
            }
        }
    }
    false
}

/// Tests one block of a strip tested for all lanes (`super::packet_strips`) for each of the
/// few lanes `testing` that test it, alone: the same windows in the same order for each lane
/// as the window loop of all lanes, at the cost of one lane's pass rather than eight. Returns
/// the lanes done (a hit found with `any_hit`).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline(never)]
pub(super) fn trace_block_alone(
    (lanes, spaces, testing): (&Lanes, &LaneSpaces, u32),
    (strip, points): (u32, &[[f32; 3]]),
    block: (&[u8; BLOCK + 2], usize, usize),
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) -> u32 {
    let mut done = 0;
    let mut testing = testing;
    while testing != 0 {
        let lane = testing.trailing_zeros() as usize;
        testing &= testing - 1;
        let ray = LoneRay::new((lanes, spaces), lane);
        let closest = &mut closest[lane % PACKET_WIDTH];
        if test_block::<1>(&ray, (strip, points), block, any_hit, closest) {
            done |= 1 << lane;
        }
    }
    done
}

/// The candidate windows of the block whose `BLOCK + 2` references are `references`
/// (`windows` of them real) for the lone lane within `[tmin, tmax]`, or `None`: the
/// single-ray block's candidates ([`super::blocks::block_edges`]), its depths computed for
/// every lane as its in-range test computes them.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn lone_edges<const SITE: usize>(
    ray: &LoneRay,
    points: &[[f32; 3]],
    (references, windows): (&[u8; BLOCK + 2], usize),
    tmax: f32,
) -> Option<LoneEdges> {
    let (head, tail) = transpose_positions_on(points, references, ray.axes);
    let [hx, hy, hz] = transform(head, &ray.origin, &ray.shear);
    let [tx, ty, tz] = transform(tail, &ray.origin, &ray.shear);
    let corners = shifted_corners([hx, hy], [tx, ty]);
    let (weights, candidates) = window_candidates(&corners, references, windows)?;
    let (by_one, by_two) = shift_lanes(hz, tz);
    let depths = [hz, by_one, by_two].map(|offset| _mm256_mul_ps(ray.scale_z, offset));
    let candidates = candidates & in_range_lanes(&weights, &depths, (ray.tmin, tmax));
    if candidates == 0 {
        return None;
    }
    Some(LoneEdges {
        candidates,
        x: corners.map(|[x, _]| lanes_of(x)),
        y: corners.map(|[_, y]| lanes_of(y)),
        z: depths.map(|depth| lanes_of(depth)),
        weights: weights.map(|w| lanes_of(w)),
    })
}

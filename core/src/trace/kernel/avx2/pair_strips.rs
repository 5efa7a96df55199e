//! A short strip tested against both halves of a sixteen-ray occlusion packet in one pass
//! (`TraceKernel::trace_strip_pair`): what [`super::packet_strips`] does for eight lanes, with
//! each strip position loaded once and moved into both halves' ray spaces, each block box's
//! planes decoded once for both halves, and the block and window loops' bookkeeping
//! (references, swap windows, block masks) done once for sixteen lanes rather than twice.
//!
//! Per lane the operations are the eight-lane test's, in its order: the box planes decoded by
//! [`BoxDecoder`] for the first half's lane 0 and each lane's own planes picked by its flips
//! against that lane, the positions moved by each half's [`LaneSpaces::transform`], the edges
//! and candidates of [`super::simd`], candidates finished by [`resolve_lanes`]. A lane tests
//! the blocks and windows it would in its own half's test, so the answers are the same.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use wide::f32x8;

use super::blocks::BlockVertices;
use super::packet_strips::{
    few_lanes, is_real, resolve_lanes, BoxDecoder, LaneSpaces, StripLanes, ENTRY_LANES, MAX_BLOCKS,
    MAX_WINDOWS,
};
use super::simd::{candidate_lanes, edge, lanes as lanes_of, load};
use super::strip_alone::trace_block_alone;
use super::Avx2;
use crate::format::reader::StripView;
use crate::format::vertices::StripVertices;
use crate::trace::closest::Closest;
use crate::trace::kernel::{LeafLanes, LeafStrip, TraceKernel, BLOCK};
use crate::trace::lanes::{Lanes, PACKET_WIDTH};
use crate::trace::prepared::FAR_INFLATION;

/// The lanes of one half in a sixteen-lane mask.
const HALF_LANES: u32 = (1 << PACKET_WIDTH) - 1;

/// Tests strip `offered` for both halves' active lanes (`leaves[h]`, rays `lanes[h]` with ray
/// spaces `spaces[h]`) in one pass when it is one that `trace_strip_together` tests for all
/// lanes at once; returns the lanes that found an occluder (bit `8 h + i` for lane `i` of half
/// `h`), or `None` when the strip is left to each half's own test.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
pub(super) fn trace_strip_pair(
    (spaces, lanes): ([&LaneSpaces; 2], [&Lanes; 2]),
    offered: &LeafStrip,
    leaves: [&LeafLanes; 2],
    closest: &mut [[Closest; PACKET_WIDTH]; 2],
) -> Option<u32> {
    let view = offered.view;
    let StripVertices::F32(points) = view.vertices else {
        return None;
    };
    let windows = view.window_count();
    // As in `trace_strip_together`: a strip with several kd leaves and no boxes (format 2)
    // stays lane by lane.
    let culled_alike = !view.boxes.is_empty() || windows <= offered.leaf_windows;
    if windows > MAX_WINDOWS || !culled_alike {
        return None;
    }
    let entered = entered_blocks((spaces, lanes), leaves, (view, points));
    let [first, second] = closest.each_mut();
    let strip_lanes = [first, second].map(|closest| StripLanes {
        strip: offered.index,
        active: 0,
        any_hit: true,
        closest,
    });
    let active = leaves[0].active | leaves[1].active << PACKET_WIDTH;
    let shared = SharedOrigin::new(lanes);
    let pair = (spaces, lanes, &shared);
    let strip_at = (view, points);
    Some(match shared.origin_of_all {
        true => trace_blocks::<true>(pair, strip_at, &entered, active, strip_lanes),
        false => trace_blocks::<false>(pair, strip_at, &entered, active, strip_lanes),
    })
}

/// The sixteen lanes' one origin, when they all start there (a hit point's rays): a
/// position's difference from it is then taken once, and each half's lanes pick their axes'
/// coordinates from it ([`LaneSpaces::xy_of_difference`]).
struct SharedOrigin {
    /// Whether every lane's origin is lane 0's, bit for bit (the halves are equal lane for
    /// lane already).
    origin_of_all: bool,
    origin: __m128,
}

impl SharedOrigin {
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    fn new(lanes: [&Lanes; 2]) -> SharedOrigin {
        let int = |v: wide::i32x8| -> __m256i { bytemuck::cast(v) };
        let origin = lanes[0].origin.map(|axis| int(bytemuck::cast(axis)));
        let first = origin.map(|axis| _mm256_permutevar8x32_epi32(axis, _mm256_setzero_si256()));
        let equal = (0..3).fold(_mm256_set1_epi32(-1), |equal, axis| {
            _mm256_and_si256(equal, _mm256_cmpeq_epi32(origin[axis], first[axis]))
        });
        let [x, y, z] = lanes[0].origin.map(|axis| axis.as_array()[0]);
        SharedOrigin {
            origin_of_all: _mm256_movemask_epi8(equal) == -1,
            origin: _mm_setr_ps(x, y, z, 0.0),
        }
    }
}

/// Per block of [`BLOCK`] windows the lanes of both halves whose lane-by-lane walk would test
/// it (all of them for a strip without boxes): each box's planes decoded once, then clipped
/// for each half as `packet_strips::entered_blocks` clips them for an occlusion packet.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn entered_blocks(
    (spaces, lanes): ([&LaneSpaces; 2], [&Lanes; 2]),
    leaves: [&LeafLanes; 2],
    (view, points): (&StripView, &[[f32; 3]]),
) -> [u32; MAX_BLOCKS] {
    let active = leaves[0].active | leaves[1].active << PACKET_WIDTH;
    let Some(frame) = view.boxes.frame(points[0]) else {
        return [active; MAX_BLOCKS];
    };
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let negative = lanes.map(Lanes::negative);
    // The planes are picked by the first half's lane 0: the second half's flips are taken
    // against it (its own flips, inverted on the axes where the two lanes 0 differ).
    let flips: [[__m256; 3]; 2] = [0, 1].map(|half| {
        std::array::from_fn(|axis| match negative[half][axis] == negative[0][axis] {
            true => spaces[half].flip[axis],
            false => _mm256_xor_ps(
                spaces[half].flip[axis],
                _mm256_castsi256_ps(_mm256_set1_epi32(-1)),
            ),
        })
    });
    let decoder = BoxDecoder::new(&frame, negative[0]);
    let interval = leaves.map(|leaf| (load(leaf.t_near), load(leaf.t_far)));
    let mut entered = [0; MAX_BLOCKS];
    for (block, entered) in entered.iter_mut().enumerate() {
        let Some(codes) = view.boxes.codes(block) else {
            continue;
        };
        let planes = lanes_of(decoder.planes(codes));
        for half in 0..2 {
            let (mut near, mut far) = interval[half];
            for axis in 0..3 {
                let origin = wide(lanes[half].origin[axis]);
                let (entry, exit) = (
                    _mm256_set1_ps(planes[axis]),
                    _mm256_set1_ps(planes[ENTRY_LANES + axis]),
                );
                let flip = flips[half][axis];
                let (entry, exit) = (
                    _mm256_blendv_ps(entry, exit, flip),
                    _mm256_blendv_ps(exit, entry, flip),
                );
                let entry = _mm256_mul_ps(
                    _mm256_sub_ps(entry, origin),
                    wide(lanes[half].entry_reciprocal[axis]),
                );
                let exit = _mm256_mul_ps(
                    _mm256_mul_ps(
                        _mm256_sub_ps(exit, origin),
                        wide(lanes[half].exit_reciprocal[axis]),
                    ),
                    _mm256_set1_ps(FAR_INFLATION),
                );
                near = _mm256_max_ps(entry, near);
                far = _mm256_min_ps(exit, far);
            }
            let inside = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
            *entered |= (leaves[half].active & inside) << (PACKET_WIDTH * half);
        }
    }
    entered
}

/// Tests every window of the lossless strip `view` against the `active` lanes of both halves
/// (a sixteen-lane mask), block by block as `packet_strips::trace_strip` does for one half;
/// returns the lanes that found an occluder.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
fn trace_blocks<const SHARED: bool>(
    (spaces, rays, shared): ([&LaneSpaces; 2], [&Lanes; 2], &SharedOrigin),
    (view, points): (&StripView, &[[f32; 3]]),
    entered: &[u32; MAX_BLOCKS],
    mut active: u32,
    mut lanes: [StripLanes; 2],
) -> u32 {
    let count = view.window_count().min(MAX_WINDOWS);
    let mut finished = 0;
    for (block, first) in (0..count).step_by(BLOCK).enumerate() {
        let mut testing = entered[block] & active;
        if testing == 0 {
            continue;
        }
        let references = Avx2::references(&view.references, first);
        let windows = BLOCK.min(count - first);
        // A half whose block few lanes test costs their passes alone, as in one half's test.
        for half in 0..2 {
            let shift = PACKET_WIDTH * half;
            let lanes_testing = testing >> shift & HALF_LANES;
            if lanes_testing != 0 && few_lanes(lanes_testing, true) {
                let packet = (rays[half], spaces[half], lanes_testing);
                let strip_at = (lanes[half].strip, points);
                let block_at = (&references, first, windows);
                let closest = &mut *lanes[half].closest;
                let done = trace_block_alone(packet, strip_at, block_at, true, closest);
                finished |= done << shift;
                active &= !(done << shift);
                testing &= !(HALF_LANES << shift);
            }
        }
        let block_at = (points, &references, first, windows);
        let pair = (spaces, shared);
        let done = match (testing & HALF_LANES, testing >> PACKET_WIDTH) {
            (0, 0) => 0,
            (low, 0) => block_windows::<1, SHARED>([0], pair, block_at, [low], &mut lanes),
            (0, high) => block_windows::<1, SHARED>([1], pair, block_at, [high], &mut lanes),
            (low, high) => {
                block_windows::<2, SHARED>([0, 1], pair, block_at, [low, high], &mut lanes)
            }
        };
        finished |= done;
        active &= !done;
        if active == 0 {
            break;
        }
    }
    finished
}

/// The window loop of one block for the halves `halves` (their lanes `testing[i]` each): each
/// position loaded once and moved into every half's ray space, window `k`'s third weight
/// window `k - 1`'s first, as in one half's loop. Returns the lanes done, as a sixteen-lane
/// mask.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn block_windows<const N: usize, const SHARED: bool>(
    halves: [usize; N],
    (spaces, shared): ([&LaneSpaces; 2], &SharedOrigin),
    (points, references, first, windows): (&[[f32; 3]], &[u8; BLOCK + 2], usize, usize),
    mut testing: [u32; N],
    lanes: &mut [StripLanes; 2],
) -> u32 {
    let vertices = BlockVertices::new(points, references);
    let position = |k: usize| {
        let position = vertices.position(k);
        match SHARED {
            true => {
                let difference = _mm_sub_ps(position, shared.origin);
                let both = _mm256_set_m128(difference, difference);
                halves.map(|half| spaces[half].xy_of_difference(both))
            }
            false => halves.map(|half| {
                let [x, y, _] = spaces[half].transform(position);
                [x, y]
            }),
        }
    };
    let mut corner0 = position(0);
    let mut corner1 = position(1);
    let mut edge01: [__m256; N] = std::array::from_fn(|i| edge(&corner0[i], &corner1[i]));
    let mut finished = 0;
    for k in 0..windows {
        let corner2 = position(k + 2);
        let weights: [[__m256; 3]; N] = std::array::from_fn(|i| {
            [
                edge(&corner1[i], &corner2[i]),
                edge(&corner2[i], &corner0[i]),
                edge01[i],
            ]
        });
        let candidates: [u32; N] =
            std::array::from_fn(|i| candidate_lanes(&weights[i]) & testing[i]);
        let any = candidates.iter().fold(0, |any, lanes| any | lanes);
        if any != 0 && is_real(&references[k..k + 3]) {
            let corners = [0, 1, 2].map(|c| references[k + c]);
            for i in 0..N {
                if candidates[i] == 0 {
                    continue;
                }
                let half = halves[i];
                let hit = (candidates[i], first + k, points, corners);
                let done = resolve_lanes::<1>(spaces[half], &weights[i], hit, &mut lanes[half]);
                finished |= done << (PACKET_WIDTH * half);
                testing[i] &= !done;
            }
            if testing.iter().all(|&lanes| lanes == 0) {
                return finished;
            }
        }
        corner0 = corner1;
        corner1 = corner2;
        edge01 = std::array::from_fn(|i| weights[i][0]);
    }
    finished
}

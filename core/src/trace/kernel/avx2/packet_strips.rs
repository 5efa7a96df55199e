//! A short strip tested against all the rays of a packet at once: lanes are rays, and the
//! strip's windows are walked one after the other, each tested against every lane in one pass.
//! The packet walk offers each strip of a leaf here (`TraceKernel::trace_strip_together`); a
//! lossless strip of at most [`MAX_WINDOWS`] windows is tested this way, or by each lane alone
//! when only [`few_lanes`] reach it ([`super::strip_alone`]); any other strip by the
//! lane-by-lane walk.
//!
//! Deviation from the paper, which keeps packets small at the low level: several lanes of a
//! packet (about five for ambient-occlusion rays) reach each short strip, so each position of
//! the strip is moved to every lane's ray space once (a `vpermps` per ray-space axis picks each
//! lane's coordinates), each window costs two edge functions for all lanes (its third is the
//! previous window's first), and the block boxes are clipped for all lanes at once, a box's six
//! planes decoded in one pass ([`BoxDecoder`]). A block that few lanes test after the clip
//! ([`few_lanes`]) is tested for each of them alone (`super::strip_alone::trace_block_alone`), as
//! a strip that few lanes reach is.
//!
//! Bit-identical to the lane-by-lane walk, also on a corrupt file: a lane tests exactly the
//! blocks its walk alone would (the same box decisions: planes decoded with
//! `block_boxes::decode_plane`'s operations, distances as `PreparedRay` computes them, folded into
//! `[t_near, min(t_far, reach)]`, and a block skipped once a hit found since is nearer than its
//! box), every window of them, with the scalar watertight test's operations on its own ray
//! (never fused); a candidate window is finished by the same [`resolve`] and
//! [`Closest::offer`], windows in strip order, so an occlusion lane stops at the same hit. A
//! strip without boxes has one kd leaf here (at most `leaf_windows` windows, which its walk
//! tests whole); a longer one (format 2) keeps its kd-tree lane by lane.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use wide::{f32x8, i32x8};

use super::blocks::BlockVertices;
use super::simd::{
    candidate_lanes, edge, in_range_lanes_between, lanes as lanes_of, load, load_vertex,
};
use super::strip_alone::{trace_block_alone, trace_strip_alone};
use super::Avx2;
use crate::format::block_boxes::{BoxFrame, BOX_BYTES, CODE_BIAS, MAX_CODE};
use crate::format::reader::StripView;
use crate::format::vertices::StripVertices;
use crate::trace::closest::Closest;
use crate::trace::kernel::{LeafLanes, LeafStrip, TraceKernel, BLOCK, BOX_GROUP};
use crate::trace::lanes::{Lanes, PACKET_WIDTH};
use crate::trace::prepared::FAR_INFLATION;
use crate::trace::watertight::{resolve, RayPoint};

/// Most windows of a strip tested for all lanes at once: one group of block boxes, which the
/// lone lane's test clips in one pass. Longer strips (rare at the pipeline's strip length, with
/// their swaps) go lane by lane.
pub(super) const MAX_WINDOWS: usize = BOX_GROUP * BLOCK;

/// The packet's rays as lanes for the strip test: per lane its ray-space axes (as indices into
/// a position's coordinates), the origin's coordinate on each ray-space axis, the shears, the
/// depth scale and `tmin`.
pub(in crate::trace) struct LaneSpaces {
    /// `[role]`: the model axis of the lane's ray-space axis `role` (x, y, z).
    axis: [__m256i; 3],
    /// `[role]`: the origin's coordinate on the lane's ray-space axis `role`.
    origin: [__m256; 3],
    shear: [__m256; 2],
    scale_z: __m256,
    tmin: __m256,
    /// Per model axis all ones in the lanes whose direction sign is not lane 0's (occlusion
    /// packets may mix signs): their entry and exit planes are lane 0's swapped.
    pub(super) flip: [__m256; 3],
}

impl LaneSpaces {
    /// The ray spaces of `lanes`' rays, as the packet's setup computed them, with the origin's
    /// coordinates on each lane's ray-space axes picked.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn new(lanes: &Lanes) -> LaneSpaces {
        let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
        let int = |v: i32x8| -> __m256i { bytemuck::cast(v) };
        let axis = [
            int(lanes.space_axes[0]),
            int(lanes.space_axes[1]),
            int(lanes.space_axes[2]),
        ];
        let origin = [
            wide(lanes.origin[0]),
            wide(lanes.origin[1]),
            wide(lanes.origin[2]),
        ];
        LaneSpaces {
            origin: [
                origin_on(axis[0], &origin),
                origin_on(axis[1], &origin),
                origin_on(axis[2], &origin),
            ],
            axis,
            shear: [wide(lanes.shear[0]), wide(lanes.shear[1])],
            scale_z: wide(lanes.scale_z),
            tmin: wide(lanes.tmin),
            flip: lanes.signs.map(|signs| {
                let differ = (signs ^ 0u32.wrapping_sub(signs & 1)) as i32;
                let each = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
                let set = _mm256_and_si256(_mm256_set1_epi32(differ), each);
                _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, each))
            }),
        }
    }

    /// Lane `lane`'s ray space in every lane: the origin on its ray-space axes, its shears and
    /// its depth scale, each picked by one `vpermps`.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn lane(&self, lane: usize) -> ([__m256; 3], [__m256; 2], __m256) {
        let index = _mm256_set1_epi32(lane as i32);
        let pick = |values: __m256| _mm256_permutevar8x32_ps(values, index);
        (
            self.origin.map(pick),
            self.shear.map(pick),
            pick(self.scale_z),
        )
    }

    /// The model position `[x, y, z, any]` in every lane's ray space: x and y, and the offset
    /// along the lane's ray-space z axis (which the depth scales), with the operations of
    /// `RaySpace::transform`. Each lane picks its axes' coordinates from the position held in
    /// both halves with one in-lane `vpermilps` each, whose control (unlike `vpermps`'s index)
    /// may be read from memory when the window loop runs out of registers.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn transform(&self, position: __m128) -> [__m256; 3] {
        let both = _mm256_set_m128(position, position);
        let a = [0, 1, 2].map(|role| {
            _mm256_sub_ps(
                _mm256_permutevar_ps(both, self.axis[role]),
                self.origin[role],
            )
        });
        let [x, y] = self.sheared(&a);
        [x, y, a[2]]
    }

    /// [`LaneSpaces::transform`]'s x and y from a position's `difference` from the lanes' one
    /// origin (held in both halves): the same subtraction, taken once for all lanes.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn xy_of_difference(&self, difference: __m256) -> [__m256; 2] {
        let a = [0, 1, 2].map(|role| _mm256_permutevar_ps(difference, self.axis[role]));
        self.sheared(&a)
    }

    /// The ray-space x and y of the coordinates `a` on each lane's ray-space axes, relative
    /// to the origin.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    fn sheared(&self, a: &[__m256; 3]) -> [__m256; 2] {
        [
            _mm256_sub_ps(a[0], _mm256_mul_ps(self.shear[0], a[2])),
            _mm256_sub_ps(a[1], _mm256_mul_ps(self.shear[1], a[2])),
        ]
    }
}

/// Per lane the coordinate of `origin` on the model axis `axis` (0, 1 or 2), by two blends.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn origin_on(axis: __m256i, origin: &[__m256; 3]) -> __m256 {
    let on = |model: i32| _mm256_castsi256_ps(_mm256_cmpeq_epi32(axis, _mm256_set1_epi32(model)));
    let x_or_y = _mm256_blendv_ps(origin[0], origin[1], on(1));
    _mm256_blendv_ps(x_or_y, origin[2], on(2))
}

/// What the lanes bring to a strip: its index, the lanes to test, whether any hit ends a lane,
/// and each lane's closest hit so far.
pub(super) struct StripLanes<'a> {
    pub strip: u32,
    pub active: u32,
    pub any_hit: bool,
    pub closest: &'a mut [Closest; PACKET_WIDTH],
}

/// Tests strip `strip` for the `active` lanes when it is lossless, has at most [`MAX_WINDOWS`]
/// windows and its lane-by-lane walk culls by block boxes or has a single kd leaf: for all of
/// them at once, or for each alone when so few reach it ([`few_lanes`]). Returns the lanes
/// done (an occluder found with `any_hit`), or `None` for the lane-by-lane walk. `spaces` are
/// the lanes' ray spaces, made once per packet.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
pub(super) fn trace_strip_together(
    (spaces, lanes): (&LaneSpaces, &Lanes),
    offered: &LeafStrip,
    leaf: &LeafLanes,
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) -> Option<u32> {
    let (view, strip) = (offered.view, offered.index);
    let StripVertices::F32(points) = view.vertices else {
        return None;
    };
    let windows = view.window_count();
    // The lane-by-lane walk culls blocks by their boxes, or descends a kd-tree when the strip
    // has more than one leaf and no boxes (format 2): the latter stays lane by lane.
    let culled_alike = !view.boxes.is_empty() || windows <= offered.leaf_windows;
    if windows > MAX_WINDOWS || !culled_alike {
        return None;
    }
    if few_lanes(leaf.active, any_hit) {
        let mut done = 0;
        let mut active = leaf.active;
        while active != 0 {
            let lane = active.trailing_zeros() as usize;
            active &= active - 1;
            let closest = &mut closest[lane % PACKET_WIDTH];
            let strip_at = (view, strip, points);
            let rays = (lanes, spaces, lane);
            done |= trace_strip_alone(rays, leaf, strip_at, any_hit, closest);
        }
        return Some(done);
    }
    let strip_at = (view, points);
    // Only occlusion packets mix direction signs: closest-hit packets skip the planes' swaps.
    let blocks = match any_hit {
        true => entered_blocks::<true>((spaces, lanes), leaf, strip_at, closest),
        false => entered_blocks::<false>((spaces, lanes), leaf, strip_at, closest),
    };
    let strip_lanes = StripLanes {
        strip,
        active: leaf.active,
        any_hit,
        closest,
    };
    Some(trace_strip(
        (spaces, lanes),
        (view, points),
        &blocks,
        strip_lanes,
    ))
}

/// Whether so few lanes reach a strip (or test a block of it) that each tests it alone: below
/// that, a pass of the packet per window serves too few lanes. Measured on the 10M scan: at
/// most two for closest hits, where each strip view of a camera packet serves few lanes; one
/// for occlusion, whose strips serve more. Bits cleared (`blsr`) rather than counted.
#[inline(always)]
pub(super) fn few_lanes(active: u32, any_hit: bool) -> bool {
    let past_one = active & active.wrapping_sub(1);
    if any_hit {
        past_one == 0
    } else {
        past_one & past_one.wrapping_sub(1) == 0
    }
}

/// Per block of [`BLOCK`] windows, the lanes whose lane-by-lane walk would test it (all of
/// them for a strip without boxes, which has a single leaf), and their entry distances into
/// its box, to be checked against the lanes' culling bounds when the block is reached.
pub(super) struct EnteredBlocks {
    /// Whether the strip has block boxes (a strip without them has one block, which every
    /// lane tests).
    culled: bool,
    lanes: [u32; MAX_BLOCKS],
    near: [__m256; MAX_BLOCKS],
}

/// Most blocks of a strip tested for all lanes at once.
pub(super) const MAX_BLOCKS: usize = MAX_WINDOWS.div_ceil(BLOCK);

/// [`EnteredBlocks`] of the strip for the `active` lanes: each block box clipped for every
/// lane with `BoxTest`'s decisions (its planes decoded as `block_boxes::decode_plane` does,
/// the distances as `PreparedRay` computes them, folded into `[t_near, min(t_far, reach)]`).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
fn entered_blocks<const ANY_HIT: bool>(
    (spaces, lanes): (&LaneSpaces, &Lanes),
    leaf: &LeafLanes,
    (view, points): (&StripView, &[[f32; 3]]),
    closest: &[Closest; PACKET_WIDTH],
) -> EnteredBlocks {
    let mut entered = EnteredBlocks {
        culled: !view.boxes.is_empty(),
        lanes: [leaf.active; MAX_BLOCKS],
        near: [_mm256_setzero_ps(); MAX_BLOCKS],
    };
    let Some(frame) = view.boxes.frame(points[0]) else {
        return entered;
    };
    let t_near = load(leaf.t_near);
    // An occlusion lane's bound is its interval's end until it finds a hit, which ends it.
    let t_far = if ANY_HIT {
        load(leaf.t_far)
    } else {
        _mm256_min_ps(
            load(leaf.t_far),
            load(&std::array::from_fn(|lane| closest[lane].reach)),
        )
    };
    let wide = |v: f32x8| -> __m256 { bytemuck::cast(v) };
    let decoder = BoxDecoder::new(&frame, lanes.negative());
    for block in 0..MAX_BLOCKS {
        let Some(codes) = view.boxes.codes(block) else {
            entered.lanes[block] = 0;
            continue;
        };
        let planes = lanes_of(decoder.planes(codes));
        let mut near = t_near;
        let mut far = t_far;
        for axis in 0..3 {
            let origin = wide(lanes.origin[axis]);
            let (entry, exit) = (
                _mm256_set1_ps(planes[axis]),
                _mm256_set1_ps(planes[ENTRY_LANES + axis]),
            );
            let (entry, exit) = match ANY_HIT {
                true => {
                    let flip = spaces.flip[axis];
                    (
                        _mm256_blendv_ps(entry, exit, flip),
                        _mm256_blendv_ps(exit, entry, flip),
                    )
                }
                false => (entry, exit),
            };
            let entry = _mm256_mul_ps(
                _mm256_sub_ps(entry, origin),
                wide(lanes.entry_reciprocal[axis]),
            );
            let exit = _mm256_mul_ps(
                _mm256_mul_ps(
                    _mm256_sub_ps(exit, origin),
                    wide(lanes.exit_reciprocal[axis]),
                ),
                _mm256_set1_ps(FAR_INFLATION),
            );
            near = _mm256_max_ps(entry, near);
            far = _mm256_min_ps(exit, far);
        }
        let inside = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
        entered.lanes[block] = leaf.active & inside;
        entered.near[block] = near;
    }
    entered
}

/// Lanes of [`BoxDecoder::planes`] before the exit planes: the entry planes of x, y, z, then
/// a spare lane.
pub(super) const ENTRY_LANES: usize = 4;

/// Decodes a block box's six planes in one pass: per lane a code picked from the box's bytes
/// (the entry plane's nibble in lanes 0..3, the exit plane's in 4..7, by the packet's
/// direction signs), then `block_boxes::decode_plane`'s operations in its order (the code less
/// the bias, converted exactly, times the scale, added to the anchor; never fused), so every
/// plane has the scalar decoding's bits.
pub(super) struct BoxDecoder {
    /// Per lane the shift that brings its nibble down: 0 for a minimum's code, 4 for a
    /// maximum's.
    shift: __m256i,
    scale: __m256,
    anchor: __m256,
}

impl BoxDecoder {
    /// The decoder of boxes in `frame` for rays whose direction is negative on the axes
    /// `negative` (their entry plane is the maximum there).
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn new(frame: &BoxFrame, negative: [bool; 3]) -> BoxDecoder {
        let entry_shift = negative.map(|negative| if negative { 4 } else { 0 });
        let [ex, ey, ez] = entry_shift;
        let [sx, sy, sz] = frame.scale;
        let [ax, ay, az] = frame.anchor;
        BoxDecoder {
            shift: _mm256_setr_epi32(ex, ey, ez, 0, 4 - ex, 4 - ey, 4 - ez, 0),
            scale: _mm256_setr_ps(sx, sy, sz, 0.0, sx, sy, sz, 0.0),
            anchor: _mm256_setr_ps(ax, ay, az, 0.0, ax, ay, az, 0.0),
        }
    }

    /// The entry planes (lanes 0..3, x y z) and exit planes (lanes 4..7) of the box with
    /// `codes`; the spare lanes hold 0.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn planes(&self, [x, y, z]: [u8; BOX_BYTES]) -> __m256 {
        // The three bytes in lanes 0..3 and again in 4..7, a zero byte after each triple.
        let bytes = _mm_set1_epi32(i32::from_le_bytes([x, y, z, 0]));
        let codes = _mm256_and_si256(
            _mm256_srlv_epi32(_mm256_cvtepu8_epi32(bytes), self.shift),
            _mm256_set1_epi32(i32::from(MAX_CODE)),
        );
        let steps = _mm256_cvtepi32_ps(_mm256_sub_epi32(codes, _mm256_set1_epi32(CODE_BIAS)));
        _mm256_add_ps(self.anchor, _mm256_mul_ps(steps, self.scale))
    }
}

/// Tests every window of the lossless strip `view` (with `points`) against the `active` lanes;
/// returns the lanes that found a hit when `any_hit` is set (they are done).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
fn trace_strip(
    (spaces, rays): (&LaneSpaces, &Lanes),
    (view, points): (&StripView, &[[f32; 3]]),
    blocks: &EnteredBlocks,
    mut lanes: StripLanes,
) -> u32 {
    let count = view.window_count().min(MAX_WINDOWS);
    let mut finished = 0;
    for (block, first) in (0..count).step_by(BLOCK).enumerate() {
        // As the lane-by-lane walk: a block whose box a lane enters is tested unless a hit
        // found since is nearer than the box; a block no lane tests is skipped.
        // An occlusion lane entered the block's box within its interval, which ends at its
        // bound until it finds a hit, which ends it: only closest-hit lanes check again.
        let within = if blocks.culled && !lanes.any_hit {
            let reach = load(&std::array::from_fn(|lane| lanes.closest[lane].reach));
            let near = _mm256_cmp_ps::<_CMP_LE_OQ>(blocks.near[block], reach);
            _mm256_movemask_ps(near) as u32
        } else {
            u32::MAX
        };
        let mut testing = blocks.lanes[block] & lanes.active & within;
        if testing == 0 {
            continue;
        }
        // Only the references of the blocks tested are spread, as the lane-by-lane walk does.
        let references = Avx2::references(&view.references, first);
        // A block that few lanes test costs their passes alone, not eight lanes'.
        if few_lanes(testing, lanes.any_hit) {
            let block_at = (&references, first, BLOCK.min(count - first));
            let strip_at = (lanes.strip, points);
            let packet = (rays, spaces, testing);
            let done = trace_block_alone(packet, strip_at, block_at, lanes.any_hit, lanes.closest);
            finished |= done;
            lanes.active &= !done;
            if lanes.active == 0 {
                return finished;
            }
            continue;
        }
        let vertices = BlockVertices::new(points, &references);
        let position = |k: usize| {
            let [x, y, _] = spaces.transform(vertices.position(k));
            [x, y]
        };
        let mut corner0 = position(0);
        let mut corner1 = position(1);
        // Window `k`'s third weight, edge(c0, c1), is window `k - 1`'s first.
        let mut edge01 = edge(&corner0, &corner1);
        for k in 0..BLOCK.min(count - first) {
            let corner2 = position(k + 2);
            let weights = [edge(&corner1, &corner2), edge(&corner2, &corner0), edge01];
            let candidates = candidate_lanes(&weights) & testing;
            if candidates != 0 && is_real(&references[k..k + 3]) {
                let corners = [0, 1, 2].map(|c| references[k + c]);
                let hit = (candidates, first + k, points, corners);
                let done = resolve_lanes::<0>(spaces, &weights, hit, &mut lanes);
                finished |= done;
                lanes.active &= !done;
                testing &= !done;
                if lanes.active == 0 {
                    return finished;
                }
            }
            corner0 = corner1;
            corner1 = corner2;
            edge01 = weights[0];
        }
    }
    finished
}

/// Finishes window `window`'s candidate lanes one by one with [`resolve`], as the lane-by-lane
/// walk does; returns the lanes done (a hit found with `any_hit`). `SITE` separates the
/// instantiations of its callers (this module's and `super::pair_strips`'), so that each has
/// one caller and is inlined.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn resolve_lanes<const SITE: usize>(
    spaces: &LaneSpaces,
    weights: &[__m256; 3],
    (candidates, window, points, references): (u32, usize, &[[f32; 3]], [u8; 3]),
    lanes: &mut StripLanes,
) -> u32 {
    // The corners again, with their offsets along the ray: the same operations, the same bits.
    let flat = points.as_flattened();
    let positions = references.map(|r| load_vertex(flat, usize::from(r)));
    let corners = [
        spaces.transform(positions[0]),
        spaces.transform(positions[1]),
        spaces.transform(positions[2]),
    ];
    let depths = corners.map(|[_, _, offset]| _mm256_mul_ps(spaces.scale_z, offset));
    let tmax = load(&std::array::from_fn(|lane| lanes.closest[lane].t));
    let mut candidates = candidates & in_range_lanes_between(weights, &depths, spaces.tmin, tmax);
    let x = corners.map(|[x, _, _]| lanes_of(x));
    let y = corners.map(|[_, y, _]| lanes_of(y));
    let z = depths.map(|depth| lanes_of(depth));
    let w = weights.map(|weight| lanes_of(weight));
    let tmin = lanes_of(spaces.tmin);
    let mut done = 0;
    while candidates != 0 {
        let lane = candidates.trailing_zeros() as usize;
        candidates &= candidates - 1;
        let c: [RayPoint; 3] = std::array::from_fn(|corner| RayPoint {
            x: x[corner][lane],
            y: y[corner][lane],
            z: z[corner][lane],
        });
        let closest = &mut lanes.closest[lane];
        let lane_weights = [w[0][lane], w[1][lane], w[2][lane]];
        if let Some(hit) = resolve(&c, lane_weights, tmin[lane], closest.t) {
            let hit_window = (lanes.strip, window as u16);
            closest.offer(hit.t, hit_window, hit.weights, (points, references));
            if lanes.any_hit {
                done |= 1 << lane;
            }
        }
    }
    done
}

/// Whether a window's three references name three vertices (not a swap).
#[inline(always)]
pub(super) fn is_real(corners: &[u8]) -> bool {
    corners[0] != corners[1] && corners[1] != corners[2] && corners[0] != corners[2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::prepared::PreparedRay;
    use crate::trace::Ray;

    /// Every plane [`BoxDecoder`] decodes has the bits of `block_boxes::decode_plane`, for
    /// every code, both direction signs per axis, and scales from subnormal-adjacent to huge.
    #[test]
    fn box_planes_decode_as_decode_plane() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        use crate::format::block_boxes::{decode_plane, scale};
        let frames = [
            ([0.0, 1.0, -2.0], [127, 126, 128]),
            ([1e-3, -7.25, 3e5], [1, 254, 100]),
            ([f32::MAX, -0.0, 1.5], [200, 140, 3]),
        ];
        for (anchor, exponents) in frames {
            let frame = BoxFrame {
                anchor,
                scale: exponents.map(scale),
            };
            for signs in 0..8 {
                let negative = [0, 1, 2].map(|axis| signs >> axis & 1 == 1);
                // SAFETY: AVX2 and BMI2 were detected above.
                let decoder = unsafe { BoxDecoder::new(&frame, negative) };
                for byte in 0..=255u8 {
                    let codes = [byte, byte.rotate_left(4), byte ^ 0x5A];
                    // SAFETY: as above.
                    let planes = unsafe { lanes_of(decoder.planes(codes)) };
                    for axis in 0..3 {
                        let plane = |code: u8| {
                            decode_plane(anchor[axis], frame.scale[axis], code).to_bits()
                        };
                        let (min, max) = (plane(codes[axis] & MAX_CODE), plane(codes[axis] >> 4));
                        let want = if negative[axis] {
                            (max, min)
                        } else {
                            (min, max)
                        };
                        let got = (planes[axis], planes[ENTRY_LANES + axis]);
                        assert_eq!((got.0.to_bits(), got.1.to_bits()), want, "{codes:?}");
                    }
                }
            }
        }
    }

    /// Each lane of the packet's ray spaces moves a position as its ray's `RaySpace::transform`
    /// does, bit for bit (x, y, and the depth once scaled), for directions along every
    /// permutation of the axes, both signs, and magnitude ties.
    #[test]
    fn lane_spaces_transform_as_each_ray() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        let magnitudes = [
            [1.0, 0.5, 0.25],
            [1.0, 1.0, 0.5],
            [0.5, 1.0, 1.0],
            [1.0, 1.0, 1.0],
        ];
        let mut rays = Vec::new();
        for [a, b, c] in magnitudes {
            for [x, y, z] in [
                [a, b, c],
                [b, c, a],
                [c, a, b],
                [a, c, b],
                [c, b, a],
                [b, a, c],
            ] {
                for signs in 0..8 {
                    let sign = |bit: i32| if signs >> bit & 1 == 1 { -1.0 } else { 1.0 };
                    rays.push(Ray {
                        origin: [0.3 * sign(0), -2.0, 7.5 + signs as f32],
                        direction: [x * sign(0), y * sign(1), z * sign(2)],
                        tmin: 0.0,
                        tmax: f32::INFINITY,
                    });
                }
            }
        }
        let positions = [[0.0, 0.0, 0.0], [1.5, -3.25, 0.125], [-1e-3, 7.0, 1e5]];
        for packet in rays.chunks(PACKET_WIDTH) {
            // SAFETY: AVX2 and BMI2 were detected above.
            let lanes = unsafe { super::super::setup::lanes(packet) };
            // SAFETY: as above.
            let spaces = unsafe { LaneSpaces::new(&lanes) };
            for p in positions {
                // SAFETY: as above.
                let [x, y, offset] =
                    unsafe { spaces.transform(_mm_setr_ps(p[0], p[1], p[2], 0.0)) };
                // SAFETY: as above.
                let depth = unsafe { lanes_of(_mm256_mul_ps(spaces.scale_z, offset)) };
                // SAFETY: as above.
                let (x, y) = unsafe { (lanes_of(x), lanes_of(y)) };
                for (lane, ray) in packet.iter().enumerate() {
                    let expected = PreparedRay::new(ray).space.transform(&p);
                    let got = [x[lane], y[lane], depth[lane]].map(f32::to_bits);
                    let want = [expected.x, expected.y, expected.z].map(f32::to_bits);
                    assert_eq!(got, want, "{ray:?} at {p:?}");
                }
            }
        }
    }
}

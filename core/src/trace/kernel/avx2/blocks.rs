//! The AVX2 strip block: eight windows in one 256-bit register per quantity, lossless vertices
//! moved into lanes without going through memory, and up to four block boxes tested in one
//! pass.
//!
//! Each vertex of a lossless block is one 16-byte load and the positions' lanes come from an
//! in-register transpose, because wide loads of freshly stored scalars (the portable kernel's
//! gathered array) stall on store forwarding. Each position is moved to ray space once, and the
//! windows' second and third corners are the first corners moved across lanes (`vpermps`, in
//! 256-bit registers cheaper than transforming again); `vgatherdps` was slower still on AMD.
//! Grid vertices are decoded as in the portable kernel and loaded. The arithmetic is the
//! portable kernel's, operation for operation (`vsubps`, `vmulps`, `vminps`, `vmaxps`,
//! compares), never fused, so every lane has the same bits as it and the scalar test. A
//! block's packed references are spread into bytes by one BMI2 `pdep` for eight of them.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use super::simd::{candidate_lanes, edge, in_range_lanes_between, lanes};
use crate::format::block_boxes::{BoxFrame, BOX_BYTES, CODE_BIAS, MAX_CODE};
use crate::format::vertices::VertexAccess;
use crate::trace::kernel::{BlockEdges, EnteredBoxes, BLOCK, BOX_GROUP};
use crate::trace::prepared::{PreparedRay, FAR_INFLATION};
use crate::trace::watertight::RaySpace;

/// What a ray's block box test reads of it (`PreparedRay`'s fields, or a packet lane's), by
/// reference: copied, the single-ray walk's fields cost it instructions per strip.
#[derive(Clone, Copy)]
pub(super) struct BoxRay<'a> {
    pub origin: &'a [f32; 3],
    pub entry_reciprocal: &'a [f32; 3],
    pub exit_reciprocal: &'a [f32; 3],
    pub negative: &'a [bool; 3],
}

impl<'a> From<&'a PreparedRay> for BoxRay<'a> {
    #[inline(always)]
    fn from(ray: &'a PreparedRay) -> BoxRay<'a> {
        BoxRay {
            origin: &ray.origin,
            entry_reciprocal: &ray.entry_reciprocal,
            exit_reciprocal: &ray.exit_reciprocal,
            negative: &ray.negative,
        }
    }
}

/// `TraceKernel::entered_boxes` for up to four boxes in one pass: lanes 0-3 hold the boxes'
/// entry planes on an axis and lanes 4-7 their exit planes (which nibble is which follows the
/// ray's direction), so one decode and one distance computation per axis serve every box.
/// Per lane the operations of the portable `BoxTest::interval`: the code less the bias (an exact integer,
/// so converting it after the subtraction gives the same f32), times the scale, plus the
/// anchor; minus the origin, times the reciprocal, times the inflation (times 1.0 for the
/// entry lanes, which is exact); the entry distances folded into `t_near` by `vmaxps` and the
/// exits into `t_far` by `vminps`, as `max_not_nan`/`min_not_nan` fold them. The folding order
/// differs from `interval`'s, but the maximum and minimum of the same values are the same
/// (zeros aside, which `<=` does not tell apart), so the same boxes are entered.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn entered_boxes(
    ray: BoxRay,
    area: &[u8],
    frame: &BoxFrame,
    group: usize,
    (t_near, t_far): (f32, f32),
) -> EnteredBoxes {
    // The group's window: the three bytes before its first box (the exponents for group 0),
    // then its boxes' codes, box `b`'s on axis `a` at byte `3 + 3 b + a`.
    let start = BOX_GROUP * BOX_BYTES * group;
    let window = area.get(start..).unwrap_or_default();
    let boxes = (window.len() / BOX_BYTES).saturating_sub(1).min(BOX_GROUP);
    let bytes = load_window(window);
    let mut near = _mm_set1_ps(t_near);
    let mut far = _mm_set1_ps(t_far);
    for axis in 0..3 {
        let a = axis as i8;
        let codes = _mm256_cvtepu8_epi32(_mm_shuffle_epi8(
            bytes,
            _mm_setr_epi8(
                3 + a,
                6 + a,
                9 + a,
                12 + a,
                3 + a,
                6 + a,
                9 + a,
                12 + a,
                -1,
                -1,
                -1,
                -1,
                -1,
                -1,
                -1,
                -1,
            ),
        ));
        // Entry lanes take the minimum's nibble (low) going up the axis, the maximum's going down.
        let shifts = if ray.negative[axis] {
            _mm256_setr_epi32(4, 4, 4, 4, 0, 0, 0, 0)
        } else {
            _mm256_setr_epi32(0, 0, 0, 0, 4, 4, 4, 4)
        };
        let codes = _mm256_and_si256(
            _mm256_srlv_epi32(codes, shifts),
            _mm256_set1_epi32(i32::from(MAX_CODE)),
        );
        let steps = _mm256_cvtepi32_ps(_mm256_sub_epi32(codes, _mm256_set1_epi32(CODE_BIAS)));
        let planes = _mm256_add_ps(
            _mm256_set1_ps(frame.anchor[axis]),
            _mm256_mul_ps(steps, _mm256_set1_ps(frame.scale[axis])),
        );
        let reciprocals = _mm256_setr_m128(
            _mm_set1_ps(ray.entry_reciprocal[axis]),
            _mm_set1_ps(ray.exit_reciprocal[axis]),
        );
        let inflation = _mm256_setr_m128(_mm_set1_ps(1.0), _mm_set1_ps(FAR_INFLATION));
        let distances = _mm256_mul_ps(
            _mm256_mul_ps(
                _mm256_sub_ps(planes, _mm256_set1_ps(ray.origin[axis])),
                reciprocals,
            ),
            inflation,
        );
        near = _mm_max_ps(_mm256_castps256_ps128(distances), near);
        far = _mm_min_ps(_mm256_extractf128_ps::<1>(distances), far);
    }
    let entered = _mm_movemask_ps(_mm_cmple_ps(near, far)) as u32;
    let mut entry = [0.0; BOX_GROUP];
    // SAFETY: `entry` is four f32 (16 bytes), what the unaligned store writes; SSE is enabled.
    unsafe { _mm_storeu_ps(entry.as_mut_ptr(), near) };
    EnteredBoxes {
        mask: entered & ((1 << boxes) - 1),
        near: entry,
    }
}

/// The first sixteen bytes of `window` (zeros past its end) in one register: two overlapping
/// eight-byte reads when it has at least eight bytes, byte by byte otherwise.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn load_window(window: &[u8]) -> __m128i {
    let length = window.len().min(16);
    let word = |at: usize| u64::from_le_bytes(window[at..at + 8].try_into().expect("8 bytes"));
    let (low, high) = if length >= 8 {
        // Bytes `length - 8 .. length` moved up to their places from byte 8 on.
        let tail = word(length - 8);
        (
            word(0),
            tail.checked_shr(8 * (16 - length) as u32).unwrap_or(0),
        )
    } else {
        let low = window[..length]
            .iter()
            .rev()
            .fold(0u64, |word, &byte| word << 8 | u64::from(byte));
        (low, 0)
    };
    _mm_set_epi64x(high as i64, low as i64)
}

/// [`BlockEdges`] of the block whose `BLOCK + 2` strip references are `references`, or `None`
/// when no lane is a candidate; lanes past `count` are not candidates, nor lanes whose `t` falls
/// outside `range` ([`in_range_lanes`]).
/// `SITE` is the calling walk's (see the strip walk's `intersect_block`): one caller per
/// instantiation, so that it is inlined.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn block_edges<
    V: VertexAccess,
    const KX: usize,
    const KY: usize,
    const KZ: usize,
    const SITE: usize,
>(
    space: &RaySpace,
    vertices: V,
    (references, count, range): (&[u8; BLOCK + 2], usize, (f32, f32)),
) -> Option<BlockEdges> {
    let origin = space.origin_on::<KX, KY, KZ>().map(|o| _mm256_set1_ps(o));
    let (shear_x, shear_y) = space.shears();
    let shear = [_mm256_set1_ps(shear_x), _mm256_set1_ps(shear_y)];
    // Each corner's ray-space x and y; its offset along the ray (for `t`) is needed only for
    // the rare blocks with candidates, so lossless blocks move it across lanes only then.
    let (corners, offsets) = match vertices.lossless() {
        Some(points) => {
            let (head, tail) = transpose_positions::<KX, KY, KZ>(points, references);
            let [hx, hy, hz] = transform(head, &origin, &shear);
            let [tx, ty, tz] = transform(tail, &origin, &shear);
            (
                shifted_corners([hx, hy], [tx, ty]),
                Offsets::Shifted(hz, tz),
            )
        }
        None => {
            let model = vertices.gather::<KX, KY, KZ, { BLOCK + 2 }>(references, count + 2);
            let corners = load_corners(&model).map(|corner| transform(corner, &origin, &shear));
            (
                corners.map(|[x, y, _]| [x, y]),
                Offsets::Corners(corners.map(|[_, _, z]| z)),
            )
        }
    };
    let (weights, candidates) = window_candidates(&corners, references, count)?;
    let offsets = match offsets {
        Offsets::Shifted(head, tail) => {
            let (by_one, by_two) = shift_lanes(head, tail);
            [head, by_one, by_two]
        }
        Offsets::Corners(offsets) => offsets,
    };
    let depths = offsets.map(|offset| _mm256_mul_ps(_mm256_set1_ps(space.scale_z()), offset));
    let candidates = candidates & in_range_lanes(&weights, &depths, range);
    if candidates == 0 {
        return None;
    }
    Some(BlockEdges {
        candidates,
        x: corners.map(|[x, _]| lanes(x)),
        y: corners.map(|[_, y]| lanes(y)),
        weights: weights.map(|w| lanes(w)),
    })
}

/// The edge functions of a block's windows from their corners' ray-space x and y, and the
/// windows that may be hit by them: among the first `count`, not swaps; `None` when none may.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn window_candidates(
    corners: &[[__m256; 2]; 3],
    references: &[u8; BLOCK + 2],
    count: usize,
) -> Option<([__m256; 3], u32)> {
    let weights = [
        edge(&corners[1], &corners[2]),
        edge(&corners[2], &corners[0]),
        edge(&corners[0], &corners[1]),
    ];
    let candidates = candidate_lanes(&weights) & ((1 << count) - 1) & !swap_lanes(references);
    (candidates != 0).then_some((weights, candidates))
}

/// The lanes that `resolve` could accept within `range`: those
/// with a zero weight (resolved exactly, in f64), and those whose `t` is in range, computed as
/// `resolve` computes it, operation for operation (`(w0 z0 + w1 z1 + w2 z2) / (w0 + w1 + w2)`,
/// never fused; its `+ 0.0` changes no comparison). Dropping the others before `resolve` sees
/// them changes no answer: an ambient-occlusion ray starts on a triangle whose window is a
/// candidate with `t` just below `tmin`, and this is where it is rejected.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn in_range_lanes(w: &[__m256; 3], z: &[__m256; 3], (tmin, tmax): (f32, f32)) -> u32 {
    in_range_lanes_between(w, z, _mm256_set1_ps(tmin), _mm256_set1_ps(tmax))
}

/// The block's references from their packed bit stream (`width` bits each): the first eight
/// spread into bytes by one `pdep`, the last two shifted out; what `References::read_block`
/// gives, in about a third of its instructions.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn spread_references(stream: u64, width: u32) -> [u8; BLOCK + 2] {
    let mask = (1u64 << width) - 1;
    let low = _pdep_u64(stream, 0x0101_0101_0101_0101 * mask).to_le_bytes();
    let mut references = [0u8; BLOCK + 2];
    references[..BLOCK].copy_from_slice(&low);
    references[BLOCK] = ((stream >> (BLOCK as u32 * width)) & mask) as u8;
    references[BLOCK + 1] = ((stream >> ((BLOCK as u32 + 1) * width)) & mask) as u8;
    references
}

/// The lanes whose window is a swap (two of its three references equal), which the shared
/// block code would skip one by one (`is_real_window`): a swap has an edge of length zero, so
/// one of its edge functions is exactly zero and it is always a candidate; on AO rays of the 1M
/// scan most candidates were swaps. Bytewise compares of the references against themselves
/// shifted by one and two positions, in one register.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn swap_lanes(references: &[u8; BLOCK + 2]) -> u32 {
    let (head, tail) = references.split_at(8);
    let head = i64::from_le_bytes(head.try_into().expect("eight references"));
    let tail = i16::from_le_bytes(tail.try_into().expect("two references"));
    let all = _mm_insert_epi16::<4>(_mm_cvtsi64_si128(head), i32::from(tail));
    let next = _mm_srli_si128::<1>(all);
    let after = _mm_srli_si128::<2>(all);
    let repeated = _mm_or_si128(
        _mm_or_si128(_mm_cmpeq_epi8(all, next), _mm_cmpeq_epi8(next, after)),
        _mm_cmpeq_epi8(all, after),
    );
    (_mm_movemask_epi8(repeated) as u32) & 0xff
}

/// `RaySpace::transform_lanes`, lanewise the same operations: ray-space x and y of the model
/// positions `[x, y, z]` (in ray-space axis order), and their offset from the origin along the
/// ray-space z axis (which `RaySpace::depth_as` scales).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn transform(
    model: [__m256; 3],
    origin: &[__m256; 3],
    shear: &[__m256; 2],
) -> [__m256; 3] {
    let [x, y, z] = model;
    let ax = _mm256_sub_ps(x, origin[0]);
    let ay = _mm256_sub_ps(y, origin[1]);
    let az = _mm256_sub_ps(z, origin[2]);
    [
        _mm256_sub_ps(ax, _mm256_mul_ps(shear[0], az)),
        _mm256_sub_ps(ay, _mm256_mul_ps(shear[1], az)),
        az,
    ]
}

/// The corners' offsets from the ray origin along the ray-space z axis, as a block computed
/// them: once per position (to be moved across lanes), or once per corner.
#[derive(Clone, Copy)]
enum Offsets {
    Shifted(__m256, __m256),
    Corners([__m256; 3]),
}

/// The three corners `[shift]` of the block's windows from the ray-space positions of its first
/// eight references (`head`) and last two (`tail`, lanes 0 and 1): corner `s` of lane `k` is
/// position `k + s`, moved across lanes (`vpermps`) rather than transformed once per shift. The
/// values are those positions' bits, so every lane is what transforming per shift gives.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn shifted_corners(head: [__m256; 2], tail: [__m256; 2]) -> [[__m256; 2]; 3] {
    let (x1, x2) = shift_lanes(head[0], tail[0]);
    let (y1, y2) = shift_lanes(head[1], tail[1]);
    [head, [x1, y1], [x2, y2]]
}

/// Lanes `k + 1` and `k + 2` of the ten values `head` (lanes 0-7) and `tail` (lanes 0 and 1).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn shift_lanes(head: __m256, tail: __m256) -> (__m256, __m256) {
    let one = _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 7);
    let two = _mm256_setr_epi32(2, 3, 4, 5, 6, 7, 7, 7);
    let tail_high = _mm256_setr_epi32(0, 0, 0, 0, 0, 0, 0, 1);
    let by_one = _mm256_blend_ps::<0b1000_0000>(
        _mm256_permutevar8x32_ps(head, one),
        _mm256_permutevar8x32_ps(tail, _mm256_setzero_si256()),
    );
    let by_two = _mm256_blend_ps::<0b1100_0000>(
        _mm256_permutevar8x32_ps(head, two),
        _mm256_permutevar8x32_ps(tail, tail_high),
    );
    (by_one, by_two)
}

/// The positions of the block's references, axes in ray-space order `KX, KY, KZ`: lane `k` of
/// the first array is vertex `references[k]`, lanes 0 and 1 of the second are vertices
/// `references[8]` and `references[9]` (the other lanes are copies of no meaning). Each vertex
/// is one 16-byte load, transposed in registers.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn transpose_positions<const KX: usize, const KY: usize, const KZ: usize>(
    points: &[[f32; 3]],
    references: &[u8; BLOCK + 2],
) -> ([__m256; 3], [__m256; 3]) {
    let vertices = BlockVertices::new(points, references);
    let v: [__m128; BLOCK + 2] = std::array::from_fn(|k| vertices.position(k));
    let (head, tail) = transpose(&v);
    (
        [head[KX], head[KY], head[KZ]],
        [tail[KX], tail[KY], tail[KZ]],
    )
}

/// [`transpose_positions`] with the ray-space axes known at run time only: `axes` is the
/// `vpermilps` control `[KX, KY, KZ, 3]`, which puts each vertex's coordinates in ray-space
/// order as it is loaded (a lane's ray alone, whose axes are not the walk's constants).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn transpose_positions_on(
    points: &[[f32; 3]],
    references: &[u8; BLOCK + 2],
    axes: __m128i,
) -> ([__m256; 3], [__m256; 3]) {
    let vertices = BlockVertices::new(points, references);
    let v: [__m128; BLOCK + 2] =
        std::array::from_fn(|k| _mm_permutevar_ps(vertices.position(k), axes));
    transpose(&v)
}

/// A lossless block's vertices, loaded by the block's references: each reference clamped to the
/// strip's last vertex once, when made (only a file changed after its validation has larger
/// ones, which then read the last vertex, as `simd::load_vertex` does), so that a vertex load
/// needs no clamp of its own, and the last vertex no special case.
pub(super) struct BlockVertices<'a> {
    flat: &'a [f32],
    /// The block's references, at most the last vertex; zeros past them.
    references: [u8; 16],
}

impl<'a> BlockVertices<'a> {
    /// The vertices `points` of the block with `references`.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn new(points: &'a [[f32; 3]], references: &[u8; BLOCK + 2]) -> BlockVertices<'a> {
        let last = points.len().checked_sub(1).expect("a strip has vertices");
        let mut bytes = [0u8; 16];
        bytes[..BLOCK + 2].copy_from_slice(references);
        // SAFETY: `bytes` is sixteen bytes, what the unaligned load reads and the unaligned
        // store writes; SSE2 is enabled.
        unsafe {
            let stored = _mm_loadu_si128(bytes.as_ptr().cast());
            let bound = _mm_set1_epi8(last.min(255) as u8 as i8);
            _mm_storeu_si128(bytes.as_mut_ptr().cast(), _mm_min_epu8(stored, bound));
        }
        BlockVertices {
            flat: points.as_flattened(),
            references: bytes,
        }
    }

    /// The vertex of reference `k` as `[x, y, z, 0]`: x and y by one 8-byte load, z inserted.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    pub(super) fn position(&self, k: usize) -> __m128 {
        let start = 3 * usize::from(self.references[k]);
        // SAFETY: the references were clamped to the last vertex in `new`, so `start + 3 <=
        // flat.len()`: the 8-byte unaligned load reads floats `start` and `start + 1`, the
        // 4-byte one float `start + 2` (f32-aligned), all inside `flat`; SSE4.1 is enabled.
        unsafe {
            let at = self.flat.as_ptr().add(start);
            let xy = _mm_castsi128_ps(_mm_loadl_epi64(at.cast()));
            // Lane 0 of the loaded z into lane 2 (bits 5:4), no lane zeroed (bits 3:0).
            _mm_insert_ps::<0b0010_0000>(xy, _mm_load_ss(at.add(2)))
        }
    }
}

/// Ten positions `[x, y, z, any]` as lanes: x, y and z of the first eight, and of the last
/// two in lanes 0 and 1 (the other lanes are copies of no meaning).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn transpose(v: &[__m128; BLOCK + 2]) -> ([__m256; 3], [__m256; 3]) {
    // Row `k` holds vertex `k` in its low half and vertex `k + 4` in its high half; a 4×4
    // transpose per half then gives x, y, z of vertices 0-3 | 4-7.
    let row: [__m256; 4] = std::array::from_fn(|k| _mm256_set_m128(v[k + 4], v[k]));
    let xy01 = _mm256_unpacklo_ps(row[0], row[1]);
    let xy23 = _mm256_unpacklo_ps(row[2], row[3]);
    let zw01 = _mm256_unpackhi_ps(row[0], row[1]);
    let zw23 = _mm256_unpackhi_ps(row[2], row[3]);
    let head = [
        _mm256_shuffle_ps::<0b01_00_01_00>(xy01, xy23),
        _mm256_shuffle_ps::<0b11_10_11_10>(xy01, xy23),
        _mm256_shuffle_ps::<0b01_00_01_00>(zw01, zw23),
    ];
    // `[x8, x9, y8, y9]` and `[z8, z9, ..]`, each in both halves.
    let xy89 = _mm256_castps128_ps256(_mm_unpacklo_ps(v[8], v[9]));
    let zw89 = _mm256_castps128_ps256(_mm_unpackhi_ps(v[8], v[9]));
    let tail = [
        xy89,
        _mm256_castps128_ps256(_mm_movehl_ps(
            _mm256_castps256_ps128(xy89),
            _mm256_castps256_ps128(xy89),
        )),
        zw89,
    ];
    (head, tail)
}

/// The portable kernel's decoded block (`[axis][position]`) as `[shift][axis]` lanes.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn load_corners(model: &[[f32; BLOCK + 2]; 3]) -> [[__m256; 3]; 3] {
    std::array::from_fn(|shift| std::array::from_fn(|axis| load(&model[axis], shift)))
}

/// Lanes `shift .. shift + BLOCK` of `values`.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn load(values: &[f32; BLOCK + 2], shift: usize) -> __m256 {
    let lanes: &[f32; BLOCK] = values[shift..shift + BLOCK]
        .first_chunk()
        .expect("BLOCK lanes");
    // SAFETY: `lanes` is eight f32 (32 bytes), what the unaligned load reads; AVX is enabled.
    unsafe { _mm256_loadu_ps(lanes.as_ptr()) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `load_window` of every length up to past sixteen gives the bytes and zeros after them.
    #[test]
    fn windows_load_their_bytes_and_zeros() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        let source: Vec<u8> = (1..=20).collect();
        for length in 0..=source.len() {
            let window = &source[..length];
            // SAFETY: AVX2 and BMI2 were detected just above.
            let loaded: [u8; 16] = bytemuck::cast(unsafe { load_window(window) });
            let expected: [u8; 16] = std::array::from_fn(|i| window.get(i).copied().unwrap_or(0));
            assert_eq!(loaded, expected, "window of {length} bytes");
        }
    }
}

//! A packet's rays prepared in AVX2 registers: `PreparedRay::new` and the ray space of
//! `watertight::RaySpace::new` for eight rays at once, lanes being rays.
//!
//! The eight 32-byte ray records are loaded as eight rows and transposed in registers (an 8×8
//! transpose: origin, direction, `tmin`, `tmax` each in one register), then every quantity is
//! one instruction on eight lanes: the reciprocals `1 / d` by `vdivps`, the entry reciprocal
//! clamped by `vmaxps`/`vminps` and kept unclamped where `d == 0` by `vblendvps`, the sign bits
//! by `vmovmskps`, the dominant `|d|` component by `vcmpps` and blends (with `RaySpace::new`'s
//! tie-breaking: x over y and z, y over z), the axes swapped where `d[kz] < 0`, the shears and
//! the depth scale by `vdivps`. Division, comparison, `and`, `min`, `max` and blends are exact
//! IEEE operations, so every lane holds the bits the scalar code computes for its ray (tested
//! below on signed zeros, subnormals and ties).
//!
//! One setup per packet replaces eight scalar `PreparedRay::new` (each with its branchy choice
//! of the dominant axis and six divisions) and their lane-by-lane transposes (`Lanes::of`). A
//! lane's `PreparedRay` is read back from the lanes only when the lane-by-lane strip walk or a
//! ray traced alone needs it (`Lanes::prepared`), and the packet strips' ray spaces
//! (`packet_strips::LaneSpaces`) are made once per packet from these registers' values.

#![allow(unsafe_code)]

use std::arch::x86_64::*;

use crate::trace::lanes::Lanes;
use crate::trace::ray::Ray;

/// The lanes of `rays` (at least one, at most eight; lanes past them repeat the last ray).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
pub(super) fn lanes(rays: &[Ray]) -> Lanes {
    let rows: [__m256; 8] = match <&[Ray; 8]>::try_from(rays) {
        // A full packet's rows are plain loads, without an index clamped and checked per row.
        Ok(full) => full.map(bytemuck::cast),
        Err(_) => {
            let last = rays.len() - 1;
            std::array::from_fn(|lane| bytemuck::cast(rays[lane.min(last)]))
        }
    };
    let [ox, oy, oz, dx, dy, dz, tmin, tmax] = transpose(rows);
    let zero = _mm256_setzero_ps();
    let one = _mm256_set1_ps(1.0);
    let exit = [
        _mm256_div_ps(one, dx),
        _mm256_div_ps(one, dy),
        _mm256_div_ps(one, dz),
    ];
    let entry = [
        entry_reciprocal(dx, exit[0]),
        entry_reciprocal(dy, exit[1]),
        entry_reciprocal(dz, exit[2]),
    ];
    // `RaySpace::new`: kz is x where |dx| >= |dy| and |dx| >= |dz|, else y where
    // |dy| >= |dz|, else z (false where a magnitude is NaN, as the scalar comparisons).
    let magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX));
    let (mx, my, mz) = (
        _mm256_and_ps(dx, magnitude),
        _mm256_and_ps(dy, magnitude),
        _mm256_and_ps(dz, magnitude),
    );
    let x_dominant = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GE_OQ>(mx, my),
        _mm256_cmp_ps::<_CMP_GE_OQ>(mx, mz),
    );
    let y_over_z = _mm256_cmp_ps::<_CMP_GE_OQ>(my, mz);
    let axes = Axes {
        x_dominant,
        y_over_z,
        flip: zero,
    };
    // The direction on kz, then whether kx and ky swap (`d[kz] < 0`).
    let d_z = axes.pick(dx, dy, dz);
    let axes = Axes {
        flip: _mm256_cmp_ps::<_CMP_LT_OQ>(d_z, zero),
        ..axes
    };
    let (d_x, d_y) = axes.sides(dx, dy, dz);
    let index = |axis: i32| _mm256_castsi256_ps(_mm256_set1_epi32(axis));
    let (i0, i1, i2) = (index(0), index(1), index(2));
    let (axis_x, axis_y) = axes.sides(i0, i1, i2);
    let signs = [
        _mm256_movemask_ps(dx) as u32,
        _mm256_movemask_ps(dy) as u32,
        _mm256_movemask_ps(dz) as u32,
    ];
    let wide = |v: __m256| -> wide::f32x8 { bytemuck::cast(v) };
    let int = |v: __m256| -> wide::i32x8 { bytemuck::cast(v) };
    Lanes {
        origin: [wide(ox), wide(oy), wide(oz)],
        entry_reciprocal: entry.map(wide),
        exit_reciprocal: exit.map(wide),
        tmin: wide(tmin),
        tmax: wide(tmax),
        negative_masks: Lanes::negative_masks(&signs),
        signs,
        space_axes: [int(axis_x), int(axis_y), int(axes.pick(i0, i1, i2))],
        shear: [wide(_mm256_div_ps(d_x, d_z)), wide(_mm256_div_ps(d_y, d_z))],
        scale_z: wide(_mm256_div_ps(one, d_z)),
    }
}

/// Each lane's ray-space axes as masks: which model axis is kz, and where kx and ky swap.
#[derive(Clone, Copy)]
struct Axes {
    x_dominant: __m256,
    y_over_z: __m256,
    flip: __m256,
}

impl Axes {
    /// Per lane the value of the model axis that is kz: `on_x`, `on_y` or `on_z`.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    fn pick(&self, on_x: __m256, on_y: __m256, on_z: __m256) -> __m256 {
        _mm256_blendv_ps(
            _mm256_blendv_ps(on_z, on_y, self.y_over_z),
            on_x,
            self.x_dominant,
        )
    }

    /// The values on kx and ky: axes `(kz + 1) % 3` and `(kz + 2) % 3`, the other way round
    /// where the axes swap.
    #[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
    #[inline]
    fn sides(&self, on_x: __m256, on_y: __m256, on_z: __m256) -> (__m256, __m256) {
        let next = self.pick(on_y, on_z, on_x);
        let after = self.pick(on_z, on_x, on_y);
        (
            _mm256_blendv_ps(next, after, self.flip),
            _mm256_blendv_ps(after, next, self.flip),
        )
    }
}

/// `PreparedRay::new`'s entry reciprocal of the direction component `d` from `r = 1 / d`: `r`
/// clamped to `±f32::MAX` (`vmaxps`/`vminps` keep a NaN `r` as `f32::clamp` does, their second
/// operand being returned where either is NaN), or `r` itself where `d == ±0`.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn entry_reciprocal(d: __m256, r: __m256) -> __m256 {
    let clamped = _mm256_min_ps(
        _mm256_set1_ps(f32::MAX),
        _mm256_max_ps(_mm256_set1_ps(-f32::MAX), r),
    );
    let zero = _mm256_cmp_ps::<_CMP_EQ_OQ>(d, _mm256_setzero_ps());
    _mm256_blendv_ps(clamped, r, zero)
}

/// Rows of eight values as columns: lane `k` of result `i` is lane `i` of `rows[k]`.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn transpose(rows: [__m256; 8]) -> [__m256; 8] {
    let [r0, r1, r2, r3, r4, r5, r6, r7] = rows;
    let (t0, t1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
    let (t2, t3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
    let (t4, t5) = (_mm256_unpacklo_ps(r4, r5), _mm256_unpackhi_ps(r4, r5));
    let (t6, t7) = (_mm256_unpacklo_ps(r6, r7), _mm256_unpackhi_ps(r6, r7));
    // Per 128-bit half, columns 0-3 (low half) and 4-7 (high half) of rows 0-3 and 4-7.
    let s0 = _mm256_shuffle_ps::<0b01_00_01_00>(t0, t2);
    let s1 = _mm256_shuffle_ps::<0b11_10_11_10>(t0, t2);
    let s2 = _mm256_shuffle_ps::<0b01_00_01_00>(t1, t3);
    let s3 = _mm256_shuffle_ps::<0b11_10_11_10>(t1, t3);
    let s4 = _mm256_shuffle_ps::<0b01_00_01_00>(t4, t6);
    let s5 = _mm256_shuffle_ps::<0b11_10_11_10>(t4, t6);
    let s6 = _mm256_shuffle_ps::<0b01_00_01_00>(t5, t7);
    let s7 = _mm256_shuffle_ps::<0b11_10_11_10>(t5, t7);
    [
        _mm256_permute2f128_ps::<0x20>(s0, s4),
        _mm256_permute2f128_ps::<0x20>(s1, s5),
        _mm256_permute2f128_ps::<0x20>(s2, s6),
        _mm256_permute2f128_ps::<0x20>(s3, s7),
        _mm256_permute2f128_ps::<0x31>(s0, s4),
        _mm256_permute2f128_ps::<0x31>(s1, s5),
        _mm256_permute2f128_ps::<0x31>(s2, s6),
        _mm256_permute2f128_ps::<0x31>(s3, s7),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::prepared::PreparedRay;

    /// Direction components where a careless SIMD version would differ: signed zeros,
    /// subnormals (whose reciprocal overflows), ties of magnitude (`1` and `-1`, the zeros, the
    /// subnormals), huge values (whose reciprocal is subnormal).
    const COMPONENTS: [f32; 12] = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.5,
        -3.0,
        1e-45,
        -1e-45,
        2.68e-43,
        f32::MIN_POSITIVE,
        3e38,
        -3e38,
    ];

    /// Every valid ray over the components, with a few origins and intervals.
    fn rays() -> Vec<Ray> {
        let origins = [[0.25, -1e11, 1e11], [-0.0, 0.0, 1e-45], [3.0, -7.5, 0.1]];
        let mut rays = Vec::new();
        for (k, x) in COMPONENTS.into_iter().enumerate() {
            for y in COMPONENTS {
                for z in COMPONENTS {
                    if [x, y, z].iter().all(|&d| d == 0.0) {
                        continue;
                    }
                    rays.push(Ray {
                        origin: origins[k % origins.len()],
                        direction: [x, y, z],
                        tmin: if k % 2 == 0 { 0.0 } else { 1e-3 },
                        tmax: if k % 3 == 0 { f32::INFINITY } else { 5.0 },
                    });
                }
            }
        }
        rays
    }

    /// Every field of the lanes as bits.
    fn bits(lanes: &Lanes) -> Vec<u32> {
        let floats = [
            &lanes.origin[..],
            &lanes.entry_reciprocal[..],
            &lanes.exit_reciprocal[..],
            &lanes.shear[..],
            &[lanes.tmin, lanes.tmax, lanes.scale_z][..],
        ]
        .concat();
        let mut bits: Vec<u32> = floats
            .iter()
            .flat_map(|v| v.to_array().map(f32::to_bits))
            .collect();
        bits.extend(
            lanes
                .space_axes
                .iter()
                .flat_map(|v| v.to_array().map(|a| a as u32)),
        );
        bits.extend(lanes.negative_masks.iter().flat_map(|v| v.to_array()));
        bits.extend(lanes.signs);
        bits
    }

    /// The AVX2 setup gives every lane the bits of `PreparedRay::new` for its ray, field by
    /// field (compared through `Debug`, which prints each float as the shortest decimal that
    /// reads back to the same bits, `-0.0` included, and shows the private ray-space fields),
    /// and the scalar `Lanes::of`'s lanes bit for bit, for packets of one to eight rays.
    #[test]
    fn simd_setup_is_prepared_ray_per_lane() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        let rays = rays();
        for count in 1..=8 {
            for packet in rays.chunks(count) {
                // SAFETY: AVX2 and BMI2 were detected above.
                let simd = unsafe { lanes(packet) };
                let scalar = Lanes::of(&crate::trace::lanes::prepare(packet));
                assert_eq!(bits(&simd), bits(&scalar), "{packet:?}");
                for (lane, ray) in packet.iter().enumerate() {
                    let expected = format!("{:?}", PreparedRay::new(ray));
                    assert_eq!(format!("{:?}", simd.prepared(lane)), expected);
                    assert_eq!(format!("{:?}", scalar.prepared(lane)), expected);
                }
            }
        }
    }
}

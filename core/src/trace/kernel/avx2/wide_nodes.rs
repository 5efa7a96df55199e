//! The eight child boxes of a format 4 node in 256-bit lanes: each plane's eight codes widened
//! to f32 and decoded at once, for packets; and a single ray clipped against all eight.

use std::arch::x86_64::*;

use super::packets::Avx2Planes;
use crate::format::WideNode;
use crate::trace::kernel::{ChildBoxes, WideClip};
use crate::trace::lanes::Lanes;
use crate::trace::prepared::{PreparedRay, FAR_INFLATION};

/// Codes `q` of one plane of eight children decoded: `origin + (q as f32) * scale` per lane,
/// the exact conversion, the exact product and one rounded sum, as [`WideNode::decode`].
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn decode_plane(codes: &[u8; 8], origin: __m256, scale: __m256) -> __m256 {
    let codes = _mm_set_epi64x(0, i64::from_le_bytes(*codes));
    let codes = _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(codes));
    _mm256_add_ps(origin, _mm256_mul_ps(codes, scale))
}

/// The three axes' scales ([`WideNode::scale`]) each in all eight lanes: the exponents moved
/// into place in one register (one load, widening and shift) rather than axis by axis.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
fn scales(node: &WideNode) -> [__m256; 3] {
    let [x, y, z] = node.exponent;
    let exponents = _mm_cvtsi32_si128(i32::from_le_bytes([x, y, z, node.reserved]));
    let scales = _mm_castsi128_ps(_mm_slli_epi32::<23>(_mm_cvtepu8_epi32(exponents)));
    [
        _mm256_broadcastss_ps(scales),
        _mm256_broadcastss_ps(_mm_permute_ps::<0b01_01_01_01>(scales)),
        _mm256_broadcastss_ps(_mm_permute_ps::<0b10_10_10_10>(scales)),
    ]
}

/// [`TraceKernel::decode_wide`](crate::trace::kernel::TraceKernel::decode_wide).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
pub(super) fn decode_wide(node: &WideNode) -> [ChildBoxes; 2] {
    let mut planes = [[[[0.0f32; 4]; 3]; 2]; 2];
    let scales = scales(node);
    for (axis, &origin) in node.origin.iter().enumerate() {
        let origin = _mm256_set1_ps(origin);
        let scale = scales[axis];
        for (side, codes) in [&node.min[axis], &node.max[axis]].into_iter().enumerate() {
            let lanes: [f32; 8] = bytemuck::cast(decode_plane(codes, origin, scale));
            planes[0][side][axis] = [lanes[0], lanes[1], lanes[2], lanes[3]];
            planes[1][side][axis] = [lanes[4], lanes[5], lanes[6], lanes[7]];
        }
    }
    planes.map(|[min, max]| (min, max))
}

/// The codes of `axis`'s entry and exit planes: the minima unless the direction is negative.
#[inline(always)]
fn entry_exit_codes(node: &WideNode, axis: usize, negative: bool) -> (&[u8; 8], &[u8; 8]) {
    match negative {
        true => (&node.max[axis], &node.min[axis]),
        false => (&node.min[axis], &node.max[axis]),
    }
}

/// [`TraceKernel::wide_planes`](crate::trace::kernel::TraceKernel::wide_planes): only the
/// planes the packet's signs pick are decoded, each once for all eight slots.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
pub(super) fn wide_planes(lanes: &Lanes, node: &WideNode) -> Avx2Planes {
    let negative = lanes.negative();
    let scales = scales(node);
    // Axis by axis, not through `array::map`, whose closure may stay a call.
    let axis = |axis: usize| {
        let (entry, exit) = entry_exit_codes(node, axis, negative[axis]);
        let origin = _mm256_set1_ps(node.origin[axis]);
        let scale = scales[axis];
        (
            decode_plane(entry, origin, scale),
            decode_plane(exit, origin, scale),
        )
    };
    let ((entry_x, exit_x), (entry_y, exit_y), (entry_z, exit_z)) = (axis(0), axis(1), axis(2));
    Avx2Planes {
        entry: [entry_x, entry_y, entry_z],
        exit: [exit_x, exit_y, exit_z],
    }
}

/// [`TraceKernel::wide_order_keys`](crate::trace::kernel::TraceKernel::wide_order_keys):
/// `order_keys`' operations in its order on eight lanes (each centre `min + max`).
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
pub(super) fn wide_order_keys(node: &WideNode, negative: &[bool; 3]) -> [f32; 8] {
    let scales = scales(node);
    let centres = std::array::from_fn(|axis| {
        let origin = _mm256_set1_ps(node.origin[axis]);
        let scale = scales[axis];
        let min = decode_plane(&node.min[axis], origin, scale);
        let max = decode_plane(&node.max[axis], origin, scale);
        _mm256_add_ps(min, max)
    });
    keys_of_centres(&centres, negative)
}

/// The order keys of eight boxes from their centres (`min + max` by axis): summed into the key
/// from zero axis by axis, subtracted on negative axes, a NaN key made `-inf`.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline]
pub(super) fn keys_of_centres(centres: &[__m256; 3], negative: &[bool; 3]) -> [f32; 8] {
    let mut key = _mm256_setzero_ps();
    for (&centre, &negative) in centres.iter().zip(negative) {
        key = match negative {
            true => _mm256_sub_ps(key, centre),
            false => _mm256_add_ps(key, centre),
        };
    }
    let nan = _mm256_cmp_ps::<_CMP_UNORD_Q>(key, key);
    bytemuck::cast(_mm256_blendv_ps(
        key,
        _mm256_set1_ps(f32::NEG_INFINITY),
        nan,
    ))
}

/// [`TraceKernel::clip_wide`](crate::trace::kernel::TraceKernel::clip_wide): per lane the
/// portable kernel's operations in its order (decode: the exact u8 → f32 conversion, the exact
/// product, one rounded sum; clip: `WideRay::clip_boxes`), so the same bits.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
pub(super) fn clip_wide(
    ray: &PreparedRay,
    node: &WideNode,
    (t_near, t_far): (f32, f32),
) -> WideClip {
    let mut near = _mm256_set1_ps(t_near);
    let mut far = _mm256_set1_ps(t_far);
    for (axis, &scale) in scales(node).iter().enumerate() {
        let (entry_codes, exit_codes) = entry_exit_codes(node, axis, ray.negative[axis]);
        let origin = _mm256_set1_ps(node.origin[axis]);
        let decode = |codes: &[u8; 8]| decode_plane(codes, origin, scale);
        let ray_origin = _mm256_set1_ps(ray.origin[axis]);
        let entry = _mm256_mul_ps(
            _mm256_sub_ps(decode(entry_codes), ray_origin),
            _mm256_set1_ps(ray.entry_reciprocal[axis]),
        );
        let exit = _mm256_mul_ps(
            _mm256_mul_ps(
                _mm256_sub_ps(decode(exit_codes), ray_origin),
                _mm256_set1_ps(ray.exit_reciprocal[axis]),
            ),
            _mm256_set1_ps(FAR_INFLATION),
        );
        // MAXPS and MINPS return their second operand unless the first is beyond it: the
        // portable kernel's `max_not_nan` and `min_not_nan`, NaN included.
        near = _mm256_max_ps(entry, near);
        far = _mm256_min_ps(exit, far);
    }
    let entered = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    let (mut near_lanes, mut far_lanes) = ([0.0; 8], [0.0; 8]);
    // SAFETY: each array is 32 bytes; unaligned stores.
    unsafe {
        _mm256_storeu_ps(near_lanes.as_mut_ptr(), near);
        _mm256_storeu_ps(far_lanes.as_mut_ptr(), far);
    }
    (near_lanes, far_lanes, entered)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::kernel::avx2::packets::{
        clip_slot, clip_slot_mixed, frustum, frustum_slots, mixed, mixed_slots, plane_order_keys,
    };
    use crate::trace::kernel::portable::Portable;
    use crate::trace::kernel::TraceKernel;
    use crate::trace::lanes::PACKET_WIDTH;
    use crate::trace::prepared::WideRay;
    use crate::trace::ray::Ray;
    use wide::f32x8;

    /// A xorshift generator.
    struct Bits(u64);

    impl Bits {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }

        fn pick<T: Copy>(&mut self, values: &[T]) -> T {
            values[(self.next() % values.len() as u64) as usize]
        }

        fn coordinate(&mut self) -> f32 {
            let unit = (self.next() >> 40) as f32 / (1u64 << 24) as f32;
            (unit - 0.5) * self.pick(&[1.0, 1.0e3, 1.0e-3, 3.0e38])
        }
    }

    /// A node of random codes in frames from tiny to huge.
    fn random_node(bits: &mut Bits) -> WideNode {
        let mut node = WideNode::EMPTY;
        for axis in 0..3 {
            node.origin[axis] = bits.coordinate();
            node.exponent[axis] = bits.pick(&[1, 100, 120, 127, 140, 254]);
            for slot in 0..8 {
                node.min[axis][slot] = bits.next() as u8;
                node.max[axis][slot] = bits.next() as u8;
            }
        }
        node
    }

    #[test]
    fn eight_lanes_decode_and_clip_as_the_portable_groups_of_four() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        let mut bits = Bits(0x243f_6a88_85a3_08d3);
        for _ in 0..100_000 {
            let node = random_node(&mut bits);
            let ray = Ray {
                origin: [0; 3].map(|_| bits.coordinate()),
                direction: [0; 3].map(|_| bits.pick(&[0.0, -0.0, 1.0, -0.5, 1e-30, 3.0])),
                tmin: bits.pick(&[0.0, 1.0]),
                tmax: bits.pick(&[f32::INFINITY, 10.0]),
            };
            let prepared = PreparedRay::new(&ray);
            let wide = WideRay::new(&prepared);
            let interval = (prepared.tmin, prepared.tmax);
            let portable = Portable::clip_wide(&prepared, &wide, &node, interval);
            // SAFETY: the CPU has AVX2 and BMI2, checked above.
            let avx2 = unsafe { clip_wide(&prepared, &node, interval) };
            let as_bits = |c: WideClip| (c.0.map(f32::to_bits), c.1.map(f32::to_bits), c.2);
            assert_eq!(as_bits(avx2), as_bits(portable), "{node:?} {ray:?}");
            let boxes_bits = |boxes: [ChildBoxes; 2]| {
                boxes.map(|(min, max)| {
                    (
                        min.map(|a| a.map(f32::to_bits)),
                        max.map(|a| a.map(f32::to_bits)),
                    )
                })
            };
            let negative = ray.direction.map(|d| d.is_sign_negative());
            // SAFETY: as above.
            let keys = unsafe { wide_order_keys(&node, &negative) };
            assert_eq!(
                keys.map(f32::to_bits),
                Portable::wide_order_keys(&node, &negative).map(f32::to_bits)
            );
            // SAFETY: as above.
            let decoded = unsafe { decode_wide(&node) };
            assert_eq!(
                boxes_bits(decoded),
                boxes_bits(Portable::decode_wide(&node))
            );
        }
    }

    #[test]
    fn the_frustums_keep_every_slot_a_packet_lane_enters() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        let mut bits = Bits(0xa409_3822_299f_31d0);
        let (mut entered, mut culled) = (0, 0);
        for _ in 0..20_000 {
            let node = random_node(&mut bits);
            let signs = [0; 3].map(|_| bits.pick(&[1.0f32, -1.0]));
            // Origins near one another, as a camera's or a hit point's, or anywhere.
            let spread = bits.pick(&[0.0, 1.0e-3, 1.0, 3.0e38]);
            let centre = [0; 3].map(|_| bits.coordinate());
            let rays: Vec<Ray> = (0..PACKET_WIDTH)
                .map(|_| Ray {
                    origin: centre.map(|c| c + spread * (bits.coordinate() / 3.0e38)),
                    direction: signs.map(|sign| sign * bits.pick(&[0.0, 1.0, 0.5, 1e-30, 3.0])),
                    tmin: bits.pick(&[0.0, 1.0]),
                    tmax: bits.pick(&[f32::INFINITY, 10.0, 1.0e-3]),
                })
                .collect();
            let lanes = Portable::lanes(&rays, &Portable::prepared_rays(&rays));
            let packet_mask = 1 | (bits.next() as u32 & 0xFE);
            let bounds = [0; PACKET_WIDTH]
                .map(|_| bits.pick(&[f32::INFINITY, 10.0, 1.0e-3, f32::NEG_INFINITY, f32::NAN]));
            let limit = f32x8::from(bounds);
            // As the packet walk bounds its lanes: NaN bounds passed over.
            let reach = bounds.into_iter().fold(f32::NEG_INFINITY, f32::max);
            // SAFETY: the CPU has AVX2 and BMI2, checked above.
            let (planes, kept) = unsafe {
                let planes = wide_planes(&lanes, &node);
                let frustum = frustum(&lanes, packet_mask);
                let kept = frustum_slots(&frustum, &planes, reach);
                (planes, kept)
            };
            let portable_planes = Portable::wide_planes(&lanes, &node);
            let portable_frustum = Portable::frustum(&lanes, packet_mask);
            let portable = Portable::frustum_slots(&portable_frustum, &portable_planes, reach);
            for slot in 0..8 {
                // SAFETY: as above.
                let (_, _, mask) = unsafe { clip_slot(&lanes, &planes, slot, limit) };
                if mask & packet_mask != 0 {
                    entered += 1;
                    assert_ne!(kept & 1 << slot, 0, "slot {slot} of {node:?} {rays:?}");
                    assert_ne!(portable & 1 << slot, 0, "slot {slot} of {node:?} {rays:?}");
                } else if kept & 1 << slot == 0 {
                    culled += 1;
                }
            }
        }
        assert!(entered > 500 && culled > 5_000, "{entered} {culled}");
    }

    /// Occlusion packets of mixed direction signs: each lane clips a slot as its ray alone
    /// does ([`Portable::clip_wide`], the same bits), and the segments' box keeps every slot
    /// a lane of the packet enters.
    #[test]
    fn mixed_sign_lanes_clip_as_single_rays_and_their_segments_keep_every_slot() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        let mut bits = Bits(0x082e_fa98_ec4e_6c89);
        let (mut entered, mut culled) = (0, 0);
        for _ in 0..20_000 {
            let node = random_node(&mut bits);
            // One origin for all lanes (a hit point's AO rays), nearby ones, or anywhere.
            let spread = bits.pick(&[0.0, 1.0e-3, 1.0, 3.0e38]);
            let centre = [0; 3].map(|_| bits.coordinate());
            let rays: Vec<Ray> = (0..PACKET_WIDTH)
                .map(|_| Ray {
                    origin: centre.map(|c| c + spread * (bits.coordinate() / 3.0e38)),
                    direction: [0; 3].map(|_| {
                        bits.pick(&[1.0f32, -1.0]) * bits.pick(&[0.0, 1.0, 0.5, 1e-30, 3.0, 0.01])
                    }),
                    tmin: bits.pick(&[0.0, 0.0, 1.0e-3, 1.0]),
                    tmax: bits.pick(&[f32::INFINITY, 10.0, 0.2, 1.0e-3]),
                })
                .collect();
            let prepared: Vec<PreparedRay> = rays.iter().map(PreparedRay::new).collect();
            // SAFETY: the CPU has AVX2 and BMI2, checked above.
            let lanes = unsafe { crate::trace::kernel::avx2::setup::lanes(&rays) };
            let packet_mask = 1 | (bits.next() as u32 & 0xFE);
            let bounds = std::array::from_fn::<f32, PACKET_WIDTH, _>(|lane| {
                prepared[lane].tmax * crate::trace::prepared::FAR_INFLATION
            });
            let limit = f32x8::from(bounds);
            // SAFETY: as above.
            let (planes, mixed) = unsafe {
                (
                    wide_planes(&lanes, &node),
                    mixed(&lanes, packet_mask, limit),
                )
            };
            // SAFETY: as above.
            let kept = unsafe { mixed_slots(&mixed, &planes) };
            let alone: Vec<WideClip> = prepared
                .iter()
                .zip(bounds)
                .map(|(ray, bound)| {
                    let wide = WideRay::new(ray);
                    Portable::clip_wide(ray, &wide, &node, (ray.tmin, bound))
                })
                .collect();
            for slot in 0..8 {
                // SAFETY: as above.
                let (near, far, mask) =
                    unsafe { clip_slot_mixed(&lanes, &mixed, &planes, slot, limit) };
                let (near, far) = (near.to_array(), far.to_array());
                for (lane, (alone_near, alone_far, alone_mask)) in alone.iter().enumerate() {
                    let inside = alone_mask >> slot & 1;
                    assert_eq!(mask >> lane & 1, inside, "slot {slot} lane {lane} {rays:?}");
                    if inside != 0 {
                        assert_eq!(near[lane].to_bits(), alone_near[slot].to_bits());
                        assert_eq!(far[lane].to_bits(), alone_far[slot].to_bits());
                    }
                }
                if mask & packet_mask != 0 {
                    entered += 1;
                    assert_ne!(kept & 1 << slot, 0, "slot {slot} of {node:?} {rays:?}");
                } else if kept & 1 << slot == 0 {
                    culled += 1;
                }
            }
        }
        assert!(entered > 500 && culled > 5_000, "{entered} {culled}");
    }

    #[test]
    fn packet_planes_decode_and_clip_as_the_portable_kernel() {
        if !crate::trace::kernel::detect::avx2() {
            return;
        }
        let mut bits = Bits(0x1319_8a2e_0370_7344);
        for _ in 0..20_000 {
            let node = random_node(&mut bits);
            let signs = [0; 3].map(|_| bits.pick(&[1.0f32, -1.0]));
            let rays: Vec<Ray> = (0..PACKET_WIDTH)
                .map(|_| Ray {
                    origin: [0; 3].map(|_| bits.coordinate()),
                    direction: signs.map(|sign| sign * bits.pick(&[0.0, 1.0, 0.5, 1e-30, 3.0])),
                    tmin: bits.pick(&[0.0, 1.0]),
                    tmax: bits.pick(&[f32::INFINITY, 10.0]),
                })
                .collect();
            let lanes = Portable::lanes(&rays, &Portable::prepared_rays(&rays));
            let portable = Portable::wide_planes(&lanes, &node);
            // SAFETY: the CPU has AVX2 and BMI2, checked above.
            let avx2 = unsafe { wide_planes(&lanes, &node) };
            for slot in 0..8 {
                let as_bits = |(near, far, mask): (f32x8, f32x8, u32)| {
                    let each = |v: f32x8| v.to_array().map(f32::to_bits);
                    (each(near), each(far), mask)
                };
                let expected = Portable::clip_slot(&lanes, &portable, slot, lanes.tmax);
                // SAFETY: as above.
                let clipped = unsafe { clip_slot(&lanes, &avx2, slot, lanes.tmax) };
                assert_eq!(as_bits(clipped), as_bits(expected), "{node:?} {rays:?}");
            }
            // The children's order from the planes, as from the decoded boxes.
            let negative = lanes.negative();
            let keys = Portable::wide_order_keys(&node, &negative).map(f32::to_bits);
            let portable_keys = Portable::plane_order_keys(&portable, &negative);
            // SAFETY: as above.
            let avx2_keys = unsafe { plane_order_keys(&avx2, &negative) };
            assert_eq!(
                portable_keys.map(f32::to_bits),
                keys,
                "{node:?} {negative:?}"
            );
            assert_eq!(avx2_keys.map(f32::to_bits), keys, "{node:?} {negative:?}");
        }
    }
}

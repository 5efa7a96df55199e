//! Eight 8-bit codes widened to f32 lanes on each architecture's baseline instructions (SSE2,
//! NEON; a scalar loop elsewhere), for the boxes of format 4 nodes: the exact conversion of
//! each code, in two groups of four, whichever instructions make it.
#![allow(unsafe_code)]

use wide::f32x4;

/// `codes` as f32, codes 0..4 in the first group and 4..8 in the second.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn widen_codes(codes: &[u8; 8]) -> [f32x4; 2] {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of every x86-64 target; no memory is read or written.
    let (low, high) = unsafe {
        let bytes = _mm_set_epi64x(0, i64::from_le_bytes(*codes));
        let zero = _mm_setzero_si128();
        let words = _mm_unpacklo_epi8(bytes, zero);
        (
            _mm_cvtepi32_ps(_mm_unpacklo_epi16(words, zero)),
            _mm_cvtepi32_ps(_mm_unpackhi_epi16(words, zero)),
        )
    };
    [low, high].map(|lanes| f32x4::from(bytemuck::cast::<__m128, [f32; 4]>(lanes)))
}

/// `codes` as f32, codes 0..4 in the first group and 4..8 in the second.
#[cfg(target_arch = "aarch64")]
#[inline(always)]
pub(crate) fn widen_codes(codes: &[u8; 8]) -> [f32x4; 2] {
    use std::arch::aarch64::*;
    let mut lanes = [[0.0f32; 4]; 2];
    // SAFETY: NEON is part of every aarch64 target; each store writes the four f32 of its
    // destination.
    unsafe {
        let words = vmovl_u8(vcreate_u8(u64::from_le_bytes(*codes)));
        vst1q_f32(
            lanes[0].as_mut_ptr(),
            vcvtq_f32_u32(vmovl_u16(vget_low_u16(words))),
        );
        vst1q_f32(lanes[1].as_mut_ptr(), vcvtq_f32_u32(vmovl_high_u16(words)));
    }
    lanes.map(f32x4::from)
}

/// `codes` as f32, codes 0..4 in the first group and 4..8 in the second.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
#[inline(always)]
pub(crate) fn widen_codes(codes: &[u8; 8]) -> [f32x4; 2] {
    let lanes = codes.map(f32::from);
    [0, 1].map(|group| f32x4::from([0, 1, 2, 3].map(|lane| lanes[4 * group + lane])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_widens_to_its_value() {
        for first in (0..=255u8).step_by(8) {
            let codes: [u8; 8] =
                std::array::from_fn(|i| first.wrapping_add((i as u8).wrapping_mul(37)));
            let [low, high] = widen_codes(&codes);
            let lanes = [low.to_array(), high.to_array()].concat();
            assert_eq!(lanes, codes.map(f32::from));
        }
    }
}

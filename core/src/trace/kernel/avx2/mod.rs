//! The AVX2 kernel (x86-64 with AVX2, BMI2, POPCNT and BMI1): strip blocks ([`blocks`]), the packets' box
//! tests ([`packets`]), short strips tested for all of a packet's rays at once
//! ([`packet_strips`]) and for both halves of a sixteen-ray occlusion packet
//! ([`pair_strips`]), the packet's rays prepared in registers ([`setup`]), a ray against all
//! eight children of a format 4 node ([`wide_nodes`]), and what they share ([`simd`]).
//!
//! `wide` picks its instructions when the crate is compiled, so it stays SSE2 inside a function
//! compiled for AVX2; this kernel therefore uses `std::arch` itself. Its functions are
//! `#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]`, one list for all, so that the
//! functions that stay out of line count and walk bit masks in one instruction each (`popcnt`,
//! `tzcnt`, `blsr`) as the walks do; calling them is sound only on a CPU that has these: [`Avx2`] is named only by
//! `kernel::dispatch`, which checks the CPU first, so every `unsafe` call below runs after
//! that check (each says so).

#![allow(unsafe_code)]

mod blocks;
mod packet_strips;
mod packets;
mod pair_strips;
mod setup;
mod simd;
mod strip_alone;
mod wide_nodes;

use wide::f32x8;

use super::{
    BlockEdges, ChildBoxes, EnteredBoxes, LeafLanes, LeafStrip, TraceKernel, Walk, WideClip, BLOCK,
};
use crate::format::block_boxes::{BlockBoxes, BoxFrame};
use crate::format::references::References;
use crate::format::vertices::VertexAccess;
use crate::format::WideNode;
use crate::trace::closest::Closest;
use crate::trace::lanes::{Lanes, PACKET_WIDTH};
use crate::trace::prepared::{PreparedRay, WideRay};
use crate::trace::ray::Ray;
use crate::trace::watertight::RaySpace;

/// The AVX2 kernel. Only `kernel::dispatch` names it, after checking that the CPU has AVX2,
/// BMI2, POPCNT and BMI1; the walks reach it as their kernel parameter.
pub(in crate::trace) struct Avx2;

/// `walk` on the AVX2 kernel, compiled for the kernel's features down to its operations.
#[target_feature(enable = "avx2,bmi2,popcnt,bmi1")]
#[inline(never)]
fn compiled_for_avx2<W: Walk>(walk: W) -> W::Output {
    walk.run::<Avx2>()
}

impl TraceKernel for Avx2 {
    #[inline(always)]
    fn compiled<W: Walk>(walk: W) -> W::Output {
        // SAFETY: `Avx2` runs only once the CPU was found to have AVX2, BMI2, POPCNT and BMI1
        // (module doc).
        unsafe { compiled_for_avx2(walk) }
    }

    #[inline(always)]
    fn references(references: &References, first: usize) -> [u8; BLOCK + 2] {
        match references.block_stream::<{ BLOCK + 2 }>(first) {
            // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
            Some(stream) => unsafe { blocks::spread_references(stream, references.width()) },
            None => references.read_block(first),
        }
    }

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
        range: (f32, f32),
    ) -> Option<BlockEdges> {
        let block = (references, count, range);
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { blocks::block_edges::<V, KX, KY, KZ, SITE>(space, vertices, block) }
    }

    #[inline(always)]
    fn entered_boxes(
        ray: &PreparedRay,
        boxes: &BlockBoxes,
        frame: &BoxFrame,
        group: usize,
        t_near: f32,
        t_far: f32,
    ) -> EnteredBoxes {
        let (bytes, interval) = (boxes.bytes(), (t_near, t_far));
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { blocks::entered_boxes(ray.into(), bytes, frame, group, interval) }
    }

    /// Each lane's `PreparedRay`, for the lane-by-lane strip walk and rays traced alone, is
    /// made from the lanes when first needed: for about a quarter of the lanes of primary rays.
    type PreparedRays = [Option<PreparedRay>; PACKET_WIDTH];

    #[inline(always)]
    fn prepared_rays(_rays: &[Ray]) -> Self::PreparedRays {
        [None; PACKET_WIDTH]
    }

    #[inline(always)]
    fn lanes(rays: &[Ray], _prepared: &Self::PreparedRays) -> Lanes {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { setup::lanes(rays) }
    }

    type Planes = packets::Avx2Planes;

    #[inline(always)]
    fn planes(lanes: &Lanes, boxes: &ChildBoxes) -> packets::Avx2Planes {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::planes(lanes, boxes) }
    }

    #[inline(always)]
    fn wide_planes(lanes: &Lanes, node: &WideNode) -> packets::Avx2Planes {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { wide_nodes::wide_planes(lanes, node) }
    }

    #[inline(always)]
    fn clip_slot(
        lanes: &Lanes,
        planes: &packets::Avx2Planes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32) {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::clip_slot(lanes, planes, slot, t_far) }
    }

    const MIXED_OCCLUSION: bool = true;

    type Mixed = packets::Avx2Mixed;

    #[inline(always)]
    fn mixed(lanes: &Lanes, packet_mask: u32, limit: f32x8) -> packets::Avx2Mixed {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::mixed(lanes, packet_mask, limit) }
    }

    #[inline(always)]
    fn mixed_against(
        lanes: &Lanes,
        packet_mask: u32,
        limit: f32x8,
        first: &Lanes,
    ) -> packets::Avx2Mixed {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::mixed_against(lanes, packet_mask, limit, &first.signs) }
    }

    #[inline(always)]
    fn mixed_slots(mixed: &packets::Avx2Mixed, planes: &packets::Avx2Planes) -> u32 {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::mixed_slots(mixed, planes) }
    }

    #[inline(always)]
    fn mixed_slots_pair(mixed: [&packets::Avx2Mixed; 2], planes: &packets::Avx2Planes) -> [u32; 2] {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::mixed_slots_pair(mixed, planes) }
    }

    #[inline(always)]
    fn clip_slot_mixed(
        lanes: &Lanes,
        mixed: &packets::Avx2Mixed,
        planes: &packets::Avx2Planes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32) {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::clip_slot_mixed(lanes, mixed, planes, slot, t_far) }
    }

    #[inline(always)]
    fn clip_slot_pair(
        lanes: [&Lanes; 2],
        mixed: [&packets::Avx2Mixed; 2],
        planes: &packets::Avx2Planes,
        slot: usize,
        t_far: [f32x8; 2],
    ) -> [(f32x8, f32x8, u32); 2] {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::clip_slot_pair(lanes, mixed, planes, slot, t_far) }
    }

    #[inline(always)]
    fn decode_wide(node: &WideNode) -> [ChildBoxes; 2] {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { wide_nodes::decode_wide(node) }
    }

    #[inline(always)]
    fn clip_wide(
        ray: &PreparedRay,
        _wide: &WideRay,
        node: &WideNode,
        interval: (f32, f32),
    ) -> WideClip {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { wide_nodes::clip_wide(ray, node, interval) }
    }

    #[inline(always)]
    fn wide_order_keys(node: &WideNode, negative: &[bool; 3]) -> [f32; 8] {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { wide_nodes::wide_order_keys(node, negative) }
    }

    #[inline(always)]
    fn plane_order_keys(planes: &packets::Avx2Planes, negative: &[bool; 3]) -> [f32; 8] {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::plane_order_keys(planes, negative) }
    }

    #[inline(always)]
    fn lanes_at_most(a: f32x8, b: f32x8) -> u32 {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::lanes_at_most(a, b) }
    }

    type Frustum = packets::Avx2Frustum;

    #[inline(always)]
    fn frustum(lanes: &Lanes, packet_mask: u32) -> packets::Avx2Frustum {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::frustum(lanes, packet_mask) }
    }

    #[inline(always)]
    fn frustum_slots(
        frustum: &packets::Avx2Frustum,
        planes: &packets::Avx2Planes,
        reach: f32,
    ) -> u32 {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packets::frustum_slots(frustum, planes, reach) }
    }

    type Together = packet_strips::LaneSpaces;

    #[inline(always)]
    fn together(lanes: &Lanes) -> packet_strips::LaneSpaces {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packet_strips::LaneSpaces::new(lanes) }
    }

    #[inline(always)]
    fn trace_strip_together(
        together: &packet_strips::LaneSpaces,
        lanes: &Lanes,
        strip: &LeafStrip,
        leaf: &LeafLanes,
        any_hit: bool,
        closest: &mut [Closest; PACKET_WIDTH],
    ) -> Option<u32> {
        let packet = (together, lanes);
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { packet_strips::trace_strip_together(packet, strip, leaf, any_hit, closest) }
    }

    #[inline(always)]
    fn trace_strip_pair(
        together: [&packet_strips::LaneSpaces; 2],
        lanes: [&Lanes; 2],
        strip: &LeafStrip,
        leaves: [&LeafLanes; 2],
        closest: &mut [[Closest; PACKET_WIDTH]; 2],
    ) -> Option<u32> {
        // SAFETY: as in `compiled`: the kernel's features were detected before this runs.
        unsafe { pair_strips::trace_strip_pair((together, lanes), strip, leaves, closest) }
    }
}

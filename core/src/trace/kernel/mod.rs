//! Everything instruction-set specific beneath the walks: which kernel runs ([`Kernel`], chosen
//! at run time), the operations a kernel provides (`TraceKernel`), the kernels themselves
//! (the portable one everywhere, AVX2 on x86-64), the CPU detection and the prefetches.
//!
//! The walks (`top`, `packet`, `strip`) are generic over `TraceKernel` and never name a
//! kernel; `dispatch` is the one place that maps a [`Kernel`] to its implementation, once per
//! ray or packet. Every kernel runs the same IEEE operations in the same order per lane (no
//! fused multiply-add), so hits and occlusion answers are bit-identical whichever runs, on any
//! architecture.
//!
//! Adding a kernel: a variant of [`Kernel`] (with its name and detection in `detect`), a
//! module implementing `TraceKernel`, and its arm in `dispatch`.
//!
//! `REDUCEM_KERNEL=sse2|avx2` forces a kernel (tests and benchmarks); asking for one this CPU
//! lacks is an error rather than a silent fallback, so a benchmark never reports a kernel it did
//! not run. No AVX-512 kernel: the strip block is eight windows wide, which AVX2 covers in one
//! register, and sixteen-ray packets did not pay at the top level (see the commit history).

#[cfg(target_arch = "x86_64")]
mod avx2;
pub(crate) mod codes;
pub(crate) mod crossing_blocks;
pub(crate) mod crossing_nodes;
mod detect;
pub(crate) mod distance_bounds;
mod portable;
pub(super) mod prefetch;
pub(crate) mod query_kernel;
pub(crate) mod query_prefetch;
pub(crate) mod triangle_lanes;

use std::fmt;

use super::closest::Closest;
use super::lanes::{LaneRays, Lanes, PACKET_WIDTH};
use super::prepared::{PreparedRay, WideRay};
use super::ray::Ray;
use super::watertight::RaySpace;
use crate::format::block_boxes::{BlockBoxes, BoxFrame, BOX_WINDOWS};
use crate::format::reader::StripView;
use crate::format::references::References;
use crate::format::vertices::VertexAccess;
use crate::format::{WideNode, TOP_WIDTH, WIDE_WIDTH};
use wide::f32x8;

/// A tracer kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// The portable kernel: 128-bit lanes through `wide` (SSE2 on x86-64, NEON on aarch64).
    Sse2,
    /// 256-bit AVX2 strip blocks, packet box tests and packet setup (x86-64 with AVX2, BMI2,
    /// POPCNT and BMI1).
    Avx2,
}

/// The environment variable that forces a kernel.
pub const KERNEL_VARIABLE: &str = "REDUCEM_KERNEL";

impl Kernel {
    /// Every kernel, baseline first.
    pub const ALL: [Kernel; 2] = [Kernel::Sse2, Kernel::Avx2];

    /// The fastest kernel this CPU runs.
    pub fn detect() -> Kernel {
        if Kernel::Avx2.is_supported() {
            Kernel::Avx2
        } else {
            Kernel::Sse2
        }
    }

    /// [`Kernel::detect`], unless `REDUCEM_KERNEL` names one: then that one, or an error when
    /// the name is unknown or this CPU cannot run it.
    pub fn from_env() -> Result<Kernel, KernelError> {
        match std::env::var(KERNEL_VARIABLE) {
            Ok(name) => Kernel::by_name(&name),
            Err(_) => Ok(Kernel::detect()),
        }
    }

    /// The kernel of queries that cannot fail on a bad `REDUCEM_KERNEL`: [`Kernel::from_env`]'s
    /// when it names one this CPU runs, else the fastest; read once. The commands refuse a bad
    /// name before querying, and answers do not depend on the kernel.
    pub fn configured() -> Kernel {
        static KERNEL: std::sync::OnceLock<Kernel> = std::sync::OnceLock::new();
        *KERNEL.get_or_init(|| Kernel::from_env().unwrap_or_else(|_| Kernel::detect()))
    }

    /// The kernel called `name` (`sse2`, `avx2`), if this CPU runs it.
    pub fn by_name(name: &str) -> Result<Kernel, KernelError> {
        let kernel = Kernel::ALL
            .into_iter()
            .find(|kernel| kernel.name() == name)
            .ok_or_else(|| KernelError::Unknown(name.to_string()))?;
        if kernel.is_supported() {
            Ok(kernel)
        } else {
            Err(KernelError::Unsupported(kernel))
        }
    }

    /// The kernels this CPU runs, baseline first.
    pub fn supported() -> Vec<Kernel> {
        Kernel::ALL
            .into_iter()
            .filter(|kernel| kernel.is_supported())
            .collect()
    }

    pub fn is_supported(self) -> bool {
        match self {
            Kernel::Sse2 => true,
            Kernel::Avx2 => detect::avx2(),
        }
    }

    /// Whether this kernel's occlusion packets may mix direction signs
    /// ([`TraceKernel::MIXED_OCCLUSION`]) on this CPU, where `dispatch` runs it.
    pub(super) fn mixes_occlusion_signs(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 if detect::avx2() => <avx2::Avx2 as TraceKernel>::MIXED_OCCLUSION,
            _ => <portable::Portable as TraceKernel>::MIXED_OCCLUSION,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Kernel::Sse2 => "sse2",
            Kernel::Avx2 => "avx2",
        }
    }
}

impl fmt::Display for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a forced kernel cannot run.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum KernelError {
    #[error("{KERNEL_VARIABLE}={0}: unknown kernel (expected sse2 or avx2)")]
    Unknown(String),
    #[error("{KERNEL_VARIABLE}={0}: this CPU does not support it")]
    Unsupported(Kernel),
}

/// Runs `walk` on `kernel`'s implementation: the one place where a [`Kernel`] meets its code.
/// A kernel this CPU lacks runs as the portable one.
#[inline(always)]
pub(super) fn dispatch<W: Walk>(kernel: Kernel, walk: W) -> W::Output {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2 if detect::avx2() => avx2::Avx2::compiled(walk),
        _ => walk.run::<portable::Portable>(),
    }
}

/// Runs `walk` on the kernel of `kernel` if its occlusion packets mix direction signs
/// ([`TraceKernel::MIXED_OCCLUSION`]) on this CPU, else returns `None`: walks written for such
/// packets are compiled for those kernels alone.
#[inline(always)]
pub(super) fn dispatch_mixed_occlusion<W: Walk>(
    kernel: Kernel,
    // Only x86-64 has such a kernel; elsewhere the walk is never run.
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))] walk: W,
) -> Option<W::Output> {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2 if detect::avx2() && <avx2::Avx2 as TraceKernel>::MIXED_OCCLUSION => {
            Some(avx2::Avx2::compiled(walk))
        }
        _ => None,
    }
}

/// A walk generic over the kernel: what [`dispatch`] and [`TraceKernel::compiled`] run.
pub(super) trait Walk {
    type Output;

    fn run<K: TraceKernel>(self) -> Self::Output;
}

/// Windows intersected together: one lane each of an eight-lane block.
pub(super) const BLOCK: usize = 8;
// A block box (format 3) bounds exactly one block.
const _: () = assert!(BOX_WINDOWS == BLOCK);

/// Block boxes tested together ([`TraceKernel::entered_boxes`]): a strip of the pipeline's
/// default length (at most 20 windows) has at most three.
pub(super) const BOX_GROUP: usize = 4;

/// Child boxes of a top-level node, axis by axis (`[axis][slot]`): minima, maxima.
pub(super) type ChildBoxes = ([[f32; TOP_WIDTH]; 3], [[f32; TOP_WIDTH]; 3]);

/// A ray clipped against the child boxes of a node: per slot its entry and exit distances, and
/// the mask of the slots whose interval is not empty.
pub(super) type WideClip = ([f32; WIDE_WIDTH], [f32; WIDE_WIDTH], u32);

/// What a kernel computes for a block of windows with candidate lanes (see
/// [`crate::trace::watertight::candidate_lanes`]): the candidates (never 0) and every lane's
/// ray-space corners `[corner]` and edge weights `[corner]`, each lane holding what the scalar
/// test computes for its window.
#[derive(Clone, Copy)]
pub(super) struct BlockEdges {
    pub candidates: u32,
    pub x: [[f32; BLOCK]; 3],
    pub y: [[f32; BLOCK]; 3],
    pub weights: [[f32; BLOCK]; 3],
}

/// The boxes of a group the ray enters: bit `k` of `mask` for box `k` of the group, whose entry
/// distance is `near[k]`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct EnteredBoxes {
    pub mask: u32,
    pub near: [f32; BOX_GROUP],
}

/// The lanes of a packet reaching a strip of a leaf: their mask and each lane's parameter
/// interval in the leaf box.
pub(super) struct LeafLanes<'a> {
    pub active: u32,
    pub t_near: &'a [f32; PACKET_WIDTH],
    pub t_far: &'a [f32; PACKET_WIDTH],
}

/// A strip as a packet's leaf offers it to [`TraceKernel::trace_strip_together`].
pub(super) struct LeafStrip<'a, 'v> {
    pub view: &'a StripView<'v>,
    /// The strip's index in the file.
    pub index: u32,
    /// The file's strip kd-tree leaf size.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub leaf_windows: usize,
}

/// The operations beneath the walks, in one instruction set. Every implementation computes,
/// lane by lane, what the portable kernel computes, bit for bit.
pub(super) trait TraceKernel: query_kernel::QueryKernel {
    /// `walk` run in code compiled for this kernel's instructions, out of line: the walks'
    /// instantiation points (one per ray-space axis order and vertex encoding, one per ray).
    fn compiled<W: Walk>(walk: W) -> W::Output;

    /// The `BLOCK + 2` references of the block from window `first`, as
    /// [`References::read_block`] reads them.
    fn references(references: &References, first: usize) -> [u8; BLOCK + 2];

    /// The block whose `BLOCK + 2` strip references are `references`, or `None` when no lane is
    /// a candidate (the common case: nothing is stored then); lanes past `count` are not
    /// candidates. A kernel may also drop candidates that `resolve` would find outside `range`
    /// (`tmin`, the closest hit's `t`) with nonzero weights, computing their `t` as it does.
    /// `SITE` only separates the instantiations of the calling walks, so that each has one
    /// caller and is inlined.
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
    ) -> Option<BlockEdges>;

    /// The boxes of group `group` (boxes `BOX_GROUP * group ..`) that the ray enters within
    /// `[t_near, t_far]`, with their entry distances: per box what the portable box test
    /// computes, box after box.
    fn entered_boxes(
        ray: &PreparedRay,
        boxes: &BlockBoxes,
        frame: &BoxFrame,
        group: usize,
        t_near: f32,
        t_far: f32,
    ) -> EnteredBoxes;

    /// The packet's rays as they are made for the lane-by-lane strip walk and rays traced alone.
    type PreparedRays: LaneRays;

    /// [`TraceKernel::PreparedRays`] of `rays` (one to [`PACKET_WIDTH`]), before their lanes.
    fn prepared_rays(rays: &[Ray]) -> Self::PreparedRays;

    /// The lanes of `rays` (lanes past them repeat the last ray), each as `PreparedRay::new`
    /// makes its ray, bit for bit; `prepared` are the rays as `prepared_rays` made them. Two
    /// steps rather than one returning both, which copied them on every packet.
    fn lanes(rays: &[Ray], prepared: &Self::PreparedRays) -> Lanes;

    /// A node's child box planes (up to [`WIDE_WIDTH`] slots) as [`TraceKernel::clip_slot`]
    /// reads them.
    type Planes;

    /// The planes of `boxes` (slots 0..4) through which the lanes enter and leave each child
    /// box: per axis the minima or the maxima by the direction's sign (shared by all lanes),
    /// picked once per node rather than once per slot.
    fn planes(lanes: &Lanes, boxes: &ChildBoxes) -> Self::Planes;

    /// [`TraceKernel::planes`] of all eight children of `node`, decoded as
    /// [`WideNode::decode`] decodes them, straight into the kernel's planes.
    fn wide_planes(lanes: &Lanes, node: &WideNode) -> Self::Planes;

    /// The lanes' interval in child `slot` of the node whose planes are `planes` within
    /// `[tmin, t_far]` (`PreparedRay::clip_box`'s operations in its order on each lane), and
    /// the mask of the lanes whose interval is not empty.
    fn clip_slot(
        lanes: &Lanes,
        planes: &Self::Planes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32);

    /// The lanes where `a <= b` (false where either is NaN), as a bit mask.
    fn lanes_at_most(a: f32x8, b: f32x8) -> u32;

    /// The rays of a packet's lanes `packet_mask` (lane 0 among them) bounded together, for
    /// [`TraceKernel::frustum_slots`].
    type Frustum;

    fn frustum(lanes: &Lanes, packet_mask: u32) -> Self::Frustum;

    /// The slots of `planes` that some lane of `frustum` may enter up to `reach` (the
    /// greatest of the lanes' bounds), as a bit mask: a slot left out is one that
    /// [`TraceKernel::clip_slot`] would find entered by none of them, so culling by it changes
    /// no answer.
    fn frustum_slots(frustum: &Self::Frustum, planes: &Self::Planes, reach: f32) -> u32;

    /// Whether occlusion packets may hold rays of differing direction signs (see
    /// [`TraceKernel::Mixed`]): then a batch's occlusion rays are cut into packets in their
    /// order, eight rays of one hit point's sixteen together, rather than grouped by octant.
    const MIXED_OCCLUSION: bool;

    /// An occlusion packet whose lanes' direction signs may differ, for
    /// [`TraceKernel::mixed_slots`] and [`TraceKernel::clip_slot_mixed`]: per axis the lanes
    /// whose sign is not lane 0's (their entry and exit planes are lane 0's swapped), and the
    /// box of the lanes' segments.
    type Mixed;

    /// [`TraceKernel::Mixed`] of the lanes `packet_mask` (lane 0 among them), whose culling
    /// bounds are `limit` (they only shrink while the packet walks).
    fn mixed(lanes: &Lanes, packet_mask: u32, limit: f32x8) -> Self::Mixed;

    /// [`TraceKernel::mixed`] of `lanes` for the planes picked by lane 0 of `first` (another
    /// packet's lanes, which a node's planes were decoded for): flips against `first`'s lane 0.
    fn mixed_against(lanes: &Lanes, packet_mask: u32, limit: f32x8, first: &Lanes) -> Self::Mixed;

    /// The slots of `planes` whose box meets the box of the packet's segments, as a bit mask:
    /// a slot left out is one that [`TraceKernel::clip_slot_mixed`] would find entered by none
    /// of the lanes.
    fn mixed_slots(mixed: &Self::Mixed, planes: &Self::Planes) -> u32;

    /// [`TraceKernel::mixed_slots`] of the two halves of a sixteen-ray packet, `mixed[1]`
    /// taken against the lanes of `mixed[0]` ([`TraceKernel::mixed_against`]).
    #[inline(always)]
    fn mixed_slots_pair(mixed: [&Self::Mixed; 2], planes: &Self::Planes) -> [u32; 2] {
        mixed.map(|mixed| Self::mixed_slots(mixed, planes))
    }

    /// [`TraceKernel::clip_slot`] with each lane's own entry and exit planes: lane 0's swapped
    /// on the axes where the lane's direction sign differs.
    fn clip_slot_mixed(
        lanes: &Lanes,
        mixed: &Self::Mixed,
        planes: &Self::Planes,
        slot: usize,
        t_far: f32x8,
    ) -> (f32x8, f32x8, u32);

    /// [`TraceKernel::clip_slot_mixed`] of the two halves of a sixteen-ray packet (`mixed[1]`
    /// taken against `lanes[0]`) whose halves' origins are equal lane for lane, so that a
    /// kernel may share the work that depends on the origin alone.
    #[inline(always)]
    fn clip_slot_pair(
        lanes: [&Lanes; 2],
        mixed: [&Self::Mixed; 2],
        planes: &Self::Planes,
        slot: usize,
        t_far: [f32x8; 2],
    ) -> [(f32x8, f32x8, u32); 2] {
        [0, 1]
            .map(|half| Self::clip_slot_mixed(lanes[half], mixed[half], planes, slot, t_far[half]))
    }

    /// `node`'s child boxes as [`WideNode::decode`] decodes them, in two groups of four.
    fn decode_wide(node: &WideNode) -> [ChildBoxes; 2];

    /// The ray's interval in each of `node`'s eight child boxes within `interval`, each
    /// box decoded as [`WideNode::decode`] decodes it and clipped as [`WideRay::clip_boxes`]
    /// clips it (the same operations per lane), and the mask of the boxes entered. `wide` is
    /// `ray` in four lanes.
    fn clip_wide(
        ray: &PreparedRay,
        wide: &WideRay,
        node: &WideNode,
        interval: (f32, f32),
    ) -> WideClip;

    /// [`order_keys`](crate::trace::top::order_keys) of `node`'s eight children for a
    /// direction of signs `negative`, each box decoded as [`WideNode::decode`] decodes it.
    fn wide_order_keys(node: &WideNode, negative: &[bool; 3]) -> [f32; WIDE_WIDTH];

    /// [`order_keys`](crate::trace::top::order_keys) of the slots of `planes` (picked for a
    /// direction of signs `negative`): a box's centre is the sum of its entry and exit planes
    /// as of its minimum and maximum (addition commutes bit for bit), so the keys are those
    /// of the decoded boxes without decoding them again.
    fn plane_order_keys(planes: &Self::Planes, negative: &[bool; 3]) -> [f32; WIDE_WIDTH];

    /// What the kernel makes of the packet's lanes once for
    /// [`TraceKernel::trace_strip_together`].
    type Together;

    fn together(lanes: &Lanes) -> Self::Together;

    /// The strip traced for all the leaf's active lanes at once by the kernel's own means, or
    /// `None` for the lane-by-lane walk; as that walk, returns the lanes that found an occluder
    /// when `any_hit` is set. Each lane must test exactly the blocks its own walk would.
    fn trace_strip_together(
        together: &Self::Together,
        lanes: &Lanes,
        strip: &LeafStrip,
        leaf: &LeafLanes,
        any_hit: bool,
        closest: &mut [Closest; PACKET_WIDTH],
    ) -> Option<u32>;

    /// [`TraceKernel::trace_strip_together`] for the two halves of a sixteen-ray occlusion
    /// packet (`leaves[h]` the active lanes of half `h`) in one pass, or `None` to leave the
    /// strip to each half's own test; returns the lanes that found an occluder (bit `8 h + i`
    /// for lane `i` of half `h`). Kernels whose occlusion packets keep one octant never run it.
    fn trace_strip_pair(
        _together: [&Self::Together; 2],
        _lanes: [&Lanes; 2],
        _strip: &LeafStrip,
        _leaves: [&LeafLanes; 2],
        _closest: &mut [[Closest; PACKET_WIDTH]; 2],
    ) -> Option<u32> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_refused() {
        for kernel in Kernel::supported() {
            assert_eq!(Kernel::by_name(kernel.name()), Ok(kernel));
        }
        assert_eq!(
            Kernel::by_name("avx9"),
            Err(KernelError::Unknown("avx9".into()))
        );
        assert!(Kernel::supported().contains(&Kernel::detect()));
        assert_eq!(Kernel::supported()[0], Kernel::Sse2);
    }
}

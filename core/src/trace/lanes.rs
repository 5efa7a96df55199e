//! A packet's rays in structure-of-arrays form, as the packet walk and the kernels share them.

use wide::{f32x8, i32x8, u32x4};

use super::prepared::PreparedRay;
use super::ray::Ray;
use super::watertight::RaySpace;

/// Rays per packet at the top level.
pub(super) const PACKET_WIDTH: usize = 8;

/// The packet's rays prepared ([`PreparedRay`]) in structure-of-arrays form, lane `i` holding
/// ray `i`'s fields bit for bit (lanes past the rays repeat the last one).
pub(super) struct Lanes {
    pub origin: [f32x8; 3],
    pub entry_reciprocal: [f32x8; 3],
    pub exit_reciprocal: [f32x8; 3],
    pub tmin: f32x8,
    pub tmax: f32x8,
    /// Per axis, bit `i` set where lane `i`'s direction is negative ([`PreparedRay::negative`]).
    pub signs: [u32; 3],
    /// Per axis, all ones in four lanes where the packet's direction (lane 0's) is negative,
    /// for picking a node's planes without branches.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub negative_masks: [u32x4; 3],
    /// The lanes' [`RaySpace`]s: `space_axes[role]` is the model axis of ray-space axis `role`
    /// (x, y, z).
    pub space_axes: [i32x8; 3],
    pub shear: [f32x8; 2],
    pub scale_z: f32x8,
}

impl Lanes {
    /// The lanes of the `prepared` rays, stored lane by lane.
    #[inline]
    pub fn of(prepared: &[PreparedRay; PACKET_WIDTH]) -> Lanes {
        // Plain stores lane by lane: gathering each field through a closure per field stayed
        // a call per field.
        let mut origin = [[0.0; PACKET_WIDTH]; 3];
        let mut entry_reciprocal = [[0.0; PACKET_WIDTH]; 3];
        let mut exit_reciprocal = [[0.0; PACKET_WIDTH]; 3];
        let mut space_axes = [[0; PACKET_WIDTH]; 3];
        let mut shear = [[0.0; PACKET_WIDTH]; 2];
        let mut scale_z = [0.0; PACKET_WIDTH];
        let mut tmin = [0.0; PACKET_WIDTH];
        let mut tmax = [0.0; PACKET_WIDTH];
        let mut signs = [0; 3];
        for (lane, ray) in prepared.iter().enumerate() {
            let axes = ray.space.axes();
            for axis in 0..3 {
                origin[axis][lane] = ray.origin[axis];
                entry_reciprocal[axis][lane] = ray.entry_reciprocal[axis];
                exit_reciprocal[axis][lane] = ray.exit_reciprocal[axis];
                signs[axis] |= u32::from(ray.negative[axis]) << lane;
                space_axes[axis][lane] = axes[axis] as i32;
            }
            (shear[0][lane], shear[1][lane]) = ray.space.shears();
            scale_z[lane] = ray.space.scale_z();
            tmin[lane] = ray.tmin;
            tmax[lane] = ray.tmax;
        }
        Lanes {
            origin: origin.map(f32x8::from),
            entry_reciprocal: entry_reciprocal.map(f32x8::from),
            exit_reciprocal: exit_reciprocal.map(f32x8::from),
            tmin: f32x8::from(tmin),
            tmax: f32x8::from(tmax),
            negative_masks: Lanes::negative_masks(&signs),
            signs,
            space_axes: space_axes.map(i32x8::from),
            shear: shear.map(f32x8::from),
            scale_z: f32x8::from(scale_z),
        }
    }

    /// The field `negative_masks` from the lanes' `signs`.
    #[inline]
    pub fn negative_masks(signs: &[u32; 3]) -> [u32x4; 3] {
        signs.map(|signs| u32x4::splat(0u32.wrapping_sub(signs & 1)))
    }

    /// The packet's direction signs: lane 0's [`PreparedRay::negative`].
    #[inline(always)]
    pub fn negative(&self) -> [bool; 3] {
        self.signs.map(|signs| signs & 1 != 0)
    }

    /// The first `count` lanes whose direction signs are lane 0's, as a bit mask.
    #[inline(always)]
    pub fn octant_lanes(&self, count: usize) -> u32 {
        self.signs.iter().fold((1 << count) - 1, |mask, &signs| {
            mask & !(signs ^ 0u32.wrapping_sub(signs & 1))
        })
    }

    /// Lane `lane`'s ray as [`PreparedRay::new`] makes it, bit for bit.
    pub fn prepared(&self, lane: usize) -> PreparedRay {
        // The remainder spares the bounds checks; each field is read by hand, not through
        // `array::map`, whose closure stayed an out-of-line call per lane.
        let lane = lane % PACKET_WIDTH;
        let at = |values: &[f32x8; 3]| {
            [
                values[0].as_array()[lane],
                values[1].as_array()[lane],
                values[2].as_array()[lane],
            ]
        };
        let origin = at(&self.origin);
        let axis = |role: usize| self.space_axes[role].as_array()[lane] as usize;
        let space = RaySpace::from_parts(
            origin,
            [axis(0), axis(1), axis(2)],
            [
                self.shear[0].as_array()[lane],
                self.shear[1].as_array()[lane],
            ],
            self.scale_z.as_array()[lane],
        );
        let negative = |axis: usize| self.signs[axis] >> lane & 1 != 0;
        PreparedRay {
            origin,
            exit_reciprocal: at(&self.exit_reciprocal),
            entry_reciprocal: at(&self.entry_reciprocal),
            negative: [negative(0), negative(1), negative(2)],
            space,
            tmin: self.tmin.as_array()[lane],
            tmax: self.tmax.as_array()[lane],
        }
    }
}

/// The packet's rays as [`PreparedRay`]s, for the lane-by-lane strip walk and the rays traced
/// alone: all made by the setup, or each made from the lanes when first needed.
pub(super) trait LaneRays {
    /// Lane `lane`'s ray, as [`PreparedRay::new`] makes it.
    fn ray(&mut self, lanes: &Lanes, lane: usize) -> &PreparedRay;
}

impl LaneRays for [PreparedRay; PACKET_WIDTH] {
    #[inline(always)]
    fn ray(&mut self, _lanes: &Lanes, lane: usize) -> &PreparedRay {
        &self[lane % PACKET_WIDTH]
    }
}

impl LaneRays for [Option<PreparedRay>; PACKET_WIDTH] {
    #[inline(always)]
    fn ray(&mut self, lanes: &Lanes, lane: usize) -> &PreparedRay {
        self[lane % PACKET_WIDTH].get_or_insert_with(|| lanes.prepared(lane))
    }
}

/// [`PreparedRay::new`] of each of `rays` (at least one, at most [`PACKET_WIDTH`]); lanes past
/// them repeat the last ray.
#[inline]
pub(super) fn prepare(rays: &[Ray]) -> [PreparedRay; PACKET_WIDTH] {
    std::array::from_fn(|lane| PreparedRay::new(&rays[lane.min(rays.len() - 1)]))
}

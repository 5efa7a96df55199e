//! Ray packets for coherent rays (Wald's packet traversal; paper 3.2: "larger packets for
//! traversing the high-level hierarchy ... smaller packets for the low-level hierarchy").
//!
//! A packet of [`PACKET_WIDTH`] rays walks the global hierarchy together, clipping all its rays
//! against a node box at once in SIMD (`wide::f32x8`) and carrying an active mask; at a leaf each
//! active ray traverses the strips alone. Deviation from the paper: the low-level packet width is
//! one ray, since strip kd-trees are small and per-ray culling there pays more than SIMD width.
//!
//! Bit-identical to single rays: a packet is formed only from rays whose direction signs match
//! the first ray's (the others are traced alone), so every internal node orders its children the
//! same way for all lanes as [`super::top`] does for each ray; the lanewise box arithmetic is the
//! scalar arithmetic of [`PreparedRay::clip_box`] operation for operation; and a lane that is
//! inactive in a subtree tests nothing there. Each ray therefore tests the same triangles in the
//! same order, with the same closest-hit bound, as it would alone.

use wide::f32x8;

use super::prepared::{PreparedRay, FAR_INFLATION};
use super::strip::Closest;
use super::top::{ordered_children, trace_leaf, trace_ray, Deferred};
use super::{Ray, Tracer};
use crate::format::{TopNode, MAX_TOP_DEPTH};

/// Rays per packet at the top level.
pub const PACKET_WIDTH: usize = 8;

/// A subtree deferred for some lanes of the packet.
#[derive(Clone, Copy)]
struct PacketDeferred {
    node: u32,
    mask: u32,
    t_near: f32x8,
    t_far: f32x8,
}

/// The packet's rays in structure-of-arrays form.
struct Lanes {
    rays: [PreparedRay; PACKET_WIDTH],
    origin: [f32x8; 3],
    entry_reciprocal: [f32x8; 3],
    exit_reciprocal: [f32x8; 3],
    tmin: f32x8,
}

/// Traces up to [`PACKET_WIDTH`] rays; entry `i` is ray `i`'s closest hit (or, with `any_hit`,
/// a hit that proves occlusion). Entries past `rays.len()` are empty.
pub fn trace_packet(tracer: &Tracer, rays: &[Ray], any_hit: bool) -> [Closest; PACKET_WIDTH] {
    let mut closest = [Closest::none(f32::NEG_INFINITY); PACKET_WIDTH];
    let Some(first) = rays.first() else {
        return closest;
    };
    let octant = first.direction.map(f32::is_sign_negative);
    let mut packet_mask = 0u32;
    for (lane, ray) in rays.iter().enumerate().take(PACKET_WIDTH) {
        closest[lane] = Closest::none(ray.tmax);
        if ray.direction.map(f32::is_sign_negative) == octant {
            packet_mask |= 1 << lane;
        } else {
            let prepared = PreparedRay::new(ray);
            trace_ray(
                tracer.file(),
                &tracer.query(&prepared, any_hit),
                &mut closest[lane],
            );
        }
    }
    if packet_mask != 0 {
        let lanes = Lanes::new(rays);
        traverse(tracer, &lanes, packet_mask, any_hit, &mut closest);
    }
    closest
}

impl Lanes {
    fn new(rays: &[Ray]) -> Lanes {
        let prepared: [PreparedRay; PACKET_WIDTH] =
            std::array::from_fn(|lane| PreparedRay::new(&rays[lane.min(rays.len() - 1)]));
        let gather = |f: &dyn Fn(&PreparedRay) -> f32| f32x8::from(prepared.map(|r| f(&r)));
        Lanes {
            origin: [0, 1, 2].map(|axis| gather(&|r| r.origin[axis])),
            entry_reciprocal: [0, 1, 2].map(|axis| gather(&|r| r.entry_reciprocal[axis])),
            exit_reciprocal: [0, 1, 2].map(|axis| gather(&|r| r.exit_reciprocal[axis])),
            tmin: gather(&|r| r.tmin),
            rays: prepared,
        }
    }

    /// Lanewise [`PreparedRay::clip_box`]: the same operations in the same order.
    #[inline(always)]
    fn clip_box(&self, node: &TopNode, t_far: f32x8) -> (f32x8, f32x8, u32) {
        let mut near = self.tmin;
        let mut far = t_far;
        for (axis, &negative) in self.rays[0].negative.iter().enumerate() {
            let (entry, exit) = if negative {
                (node.max[axis], node.min[axis])
            } else {
                (node.min[axis], node.max[axis])
            };
            let entry = (f32x8::splat(entry) - self.origin[axis]) * self.entry_reciprocal[axis];
            let exit = (f32x8::splat(exit) - self.origin[axis]) * self.exit_reciprocal[axis];
            near = near.max(entry);
            far = far.min(exit * f32x8::splat(FAR_INFLATION));
        }
        (near, far, near.simd_le(far).to_bitmask())
    }
}

/// The culling bound ([`Closest::reach`]) of every lane; finished lanes (occlusion found) get
/// `-inf` so that nothing is entered for them any more.
fn bounds(closest: &[Closest; PACKET_WIDTH], finished: u32) -> f32x8 {
    f32x8::from(std::array::from_fn::<f32, PACKET_WIDTH, _>(|lane| {
        if finished & (1 << lane) != 0 {
            f32::NEG_INFINITY
        } else {
            closest[lane].reach
        }
    }))
}

fn traverse(
    tracer: &Tracer,
    lanes: &Lanes,
    packet_mask: u32,
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) {
    let nodes = tracer.file().top_nodes();
    let mut finished = 0u32;
    let (t_near, t_far, entered) = lanes.clip_box(&nodes[0], bounds(closest, finished));
    let mut stack = [PacketDeferred {
        node: 0,
        mask: 0,
        t_near,
        t_far,
    }; MAX_TOP_DEPTH + 1];
    let mut depth = 0;
    let mut current = PacketDeferred {
        node: 0,
        mask: entered & packet_mask,
        t_near,
        t_far,
    };
    loop {
        if current.mask != 0 {
            let node = &nodes[current.node as usize];
            if node.is_internal() {
                let limit = bounds(closest, finished);
                let (first, second) = ordered_children(&lanes.rays[0], current.node, node);
                let [near, far] = [first, second].map(|child| {
                    let (t_near, t_far, entered) = lanes.clip_box(&nodes[child as usize], limit);
                    PacketDeferred {
                        node: child,
                        mask: entered & current.mask,
                        t_near,
                        t_far,
                    }
                });
                if far.mask != 0 {
                    stack[depth] = far;
                    depth += 1;
                }
                current = near;
                continue;
            }
            finished |= trace_leaf_lanes(tracer, lanes, node, &current, any_hit, closest);
        }
        loop {
            if depth == 0 {
                return;
            }
            depth -= 1;
            let deferred = stack[depth];
            let alive = deferred
                .t_near
                .simd_le(bounds(closest, finished))
                .to_bitmask();
            let mask = deferred.mask & alive;
            if mask != 0 {
                current = PacketDeferred { mask, ..deferred };
                break;
            }
        }
    }
}

/// Each active lane traverses the leaf's strips alone; returns the lanes that found an
/// occluder when `any_hit` is set.
fn trace_leaf_lanes(
    tracer: &Tracer,
    lanes: &Lanes,
    leaf: &TopNode,
    interval: &PacketDeferred,
    any_hit: bool,
    closest: &mut [Closest; PACKET_WIDTH],
) -> u32 {
    let t_near = interval.t_near.to_array();
    let t_far = interval.t_far.to_array();
    let mut finished = 0;
    for lane in 0..PACKET_WIDTH {
        if interval.mask & (1 << lane) == 0 {
            continue;
        }
        let deferred = Deferred {
            node: interval.node,
            t_near: t_near[lane],
            t_far: t_far[lane],
        };
        let query = tracer.query(&lanes.rays[lane], any_hit);
        if trace_leaf(tracer.file(), &query, leaf, &deferred, &mut closest[lane]) {
            finished |= 1 << lane;
        }
    }
    finished
}

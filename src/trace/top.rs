//! Single-ray traversal of the global hierarchy over strips (paper 3.2, first level).
//!
//! Depth-first over the mapped [`TopNode`] array with a fixed stack of
//! [`MAX_TOP_DEPTH`](crate::format::MAX_TOP_DEPTH) + 1 entries (the reader guarantees the depth).
//! At an internal node both children's boxes are clipped; the child on the near side of the
//! node's split axis (by the sign of the ray direction on that axis, the file's ordering hint) is
//! entered first and the other deferred with its entry distance, so that it is dropped if a
//! nearer hit is found meanwhile. At a leaf each strip's kd-tree is traversed within the leaf
//! box's parameter interval.

use super::prepared::PreparedRay;
use super::strip::{Closest, StripQuery};
use crate::format::reader::ReducemFile;
use crate::format::{TopNode, MAX_TOP_DEPTH};

/// A deferred subtree: its node and the ray's interval in its box.
#[derive(Clone, Copy, Default)]
pub struct Deferred {
    pub node: u32,
    pub t_near: f32,
    pub t_far: f32,
}

/// Traverses the whole file for one ray; returns true when `query.any_hit` found a hit.
pub fn trace_ray(file: &ReducemFile, query: &StripQuery, closest: &mut Closest) -> bool {
    let nodes = file.top_nodes();
    let ray = query.ray;
    let Some((t_near, t_far)) = clip(ray, &nodes[0], ray.tmin, closest.reach) else {
        return false;
    };
    let mut stack = [Deferred::default(); MAX_TOP_DEPTH + 1];
    let mut depth = 0;
    let mut current = Deferred {
        node: 0,
        t_near,
        t_far,
    };
    loop {
        let node = &nodes[current.node as usize];
        if node.is_internal() {
            let (first, second) = ordered_children(ray, current.node, node);
            let enter = |child: u32| {
                clip(ray, &nodes[child as usize], ray.tmin, closest.reach).map(|(t_near, t_far)| {
                    Deferred {
                        node: child,
                        t_near,
                        t_far,
                    }
                })
            };
            match (enter(first), enter(second)) {
                (Some(near), Some(far)) => {
                    stack[depth] = far;
                    depth += 1;
                    current = near;
                    continue;
                }
                (Some(only), None) | (None, Some(only)) => {
                    current = only;
                    continue;
                }
                (None, None) => {}
            }
        } else if trace_leaf(file, query, node, &current, closest) {
            return true;
        }
        loop {
            if depth == 0 {
                return false;
            }
            depth -= 1;
            if stack[depth].t_near <= closest.reach {
                current = stack[depth];
                break;
            }
        }
    }
}

/// The children of internal node `index`, near side of its split axis first.
#[inline(always)]
pub fn ordered_children(ray: &PreparedRay, index: u32, node: &TopNode) -> (u32, u32) {
    let (left, right) = (index + 1, node.payload);
    if ray.negative[node.axis()] {
        (right, left)
    } else {
        (left, right)
    }
}

#[inline(always)]
fn clip(ray: &PreparedRay, node: &TopNode, t_near: f32, t_far: f32) -> Option<(f32, f32)> {
    ray.clip_box(&node.min, &node.max, t_near, t_far)
}

/// Traverses every strip of a leaf within the leaf box's interval.
#[inline]
pub fn trace_leaf(
    file: &ReducemFile,
    query: &StripQuery,
    leaf: &TopNode,
    interval: &Deferred,
    closest: &mut Closest,
) -> bool {
    let first = leaf.payload;
    for strip in first..first + leaf.strip_count() {
        let t_far = interval.t_far.min(closest.reach);
        if interval.t_near > t_far {
            break;
        }
        let view = file.strip(strip as usize);
        if query.trace(&view, strip, interval.t_near, t_far, closest) {
            return true;
        }
    }
    false
}

//! Single-ray traversal of the global hierarchy over strips (paper 3.2, first level).
//!
//! Depth-first over the mapped [`TopNode`] array. At a node the ray is clipped against all four
//! child boxes at once ([`WideRay::clip_boxes`], SIMD); the children it enters are visited
//! nearest entry first: the nearest at once, the others deferred on a stack with their entry
//! distance, so that each is dropped if a nearer hit is found meanwhile. At a leaf each strip's
//! kd-tree is traversed within the leaf box's parameter interval.
//!
//! Every child is clipped over `[tmin, reach]`, not over its parent's interval: the interval of
//! a leaf is then a function of the leaf's box and the closest hit so far alone, as it was with
//! the binary hierarchy, whatever the path to it.

use super::prepared::{PreparedRay, WideRay};
use super::strip::{Closest, StripQuery};
use crate::format::reader::ReducemFile;
use crate::format::{TopNode, INTERNAL_CHILD, TOP_WIDTH};

/// A deferred child: its link and kind as the node's slot holds them, and the ray's interval in
/// its box.
#[derive(Clone, Copy, Default)]
pub struct Deferred {
    /// Node index of an internal child, first strip of a leaf.
    pub child: u32,
    /// [`INTERNAL_CHILD`], or a leaf's strip count.
    pub kind: u32,
    pub t_near: f32,
    pub t_far: f32,
}

impl Deferred {
    /// The root node (which has no box: the ray's own interval).
    pub fn root(ray: &PreparedRay) -> Deferred {
        Deferred {
            child: 0,
            kind: INTERNAL_CHILD,
            t_near: ray.tmin,
            t_far: ray.tmax,
        }
    }
}

/// Deferred entries kept inline. A traversal defers at most three children per level, and
/// real trees are a few dozen levels deep at most; the reader admits
/// [`MAX_TOP_DEPTH`](crate::format::MAX_TOP_DEPTH) levels, whose worst case spills to the heap
/// rather than making every ray zero a stack of hundreds of entries.
const INLINE_DEFERRED: usize = 32;

/// The stack of deferred children.
pub struct DeferStack<T> {
    inline: [T; INLINE_DEFERRED],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy + Default> Default for DeferStack<T> {
    #[inline(always)]
    fn default() -> DeferStack<T> {
        DeferStack {
            inline: [T::default(); INLINE_DEFERRED],
            len: 0,
            spill: Vec::new(),
        }
    }
}

impl<T: Copy> DeferStack<T> {
    #[inline(always)]
    pub fn push(&mut self, entry: T) {
        match self.inline.get_mut(self.len) {
            Some(slot) => *slot = entry,
            None => self.spill.push(entry),
        }
        self.len += 1;
    }

    #[inline(always)]
    pub fn pop(&mut self) -> Option<T> {
        self.len = self.len.checked_sub(1)?;
        self.inline
            .get(self.len)
            .copied()
            .or_else(|| self.spill.pop())
    }
}

/// Traverses the whole file for one ray; returns true when `query.any_hit` found a hit.
pub fn trace_ray(file: &ReducemFile, query: &StripQuery, closest: &mut Closest) -> bool {
    let nodes = file.top_nodes();
    let ray = WideRay::new(query.ray);
    let mut stack = DeferStack::default();
    let mut current = Deferred::root(query.ray);
    loop {
        if current.kind == INTERNAL_CHILD {
            let node = &nodes[current.child as usize];
            if let Some(nearest) = enter_children(&ray, node, query.ray.tmin, closest, &mut stack) {
                current = nearest;
                continue;
            }
        } else if trace_leaf(file, query, &current, closest) {
            return true;
        }
        loop {
            let Some(next) = stack.pop() else {
                return false;
            };
            if next.t_near <= closest.reach {
                current = next;
                break;
            }
        }
    }
}

/// Clips the ray against `node`'s children; returns the nearest one entered and defers the
/// others, farthest first, so that they come off the stack nearest first.
#[inline(always)]
fn enter_children(
    ray: &WideRay,
    node: &TopNode,
    tmin: f32,
    closest: &Closest,
    stack: &mut DeferStack<Deferred>,
) -> Option<Deferred> {
    let (near, far, mask) = ray.clip_boxes(&node.min, &node.max, tmin, closest.reach);
    let (near, far) = (near.to_array(), far.to_array());
    let entry = |slot: usize| Deferred {
        child: node.child[slot],
        kind: node.kind[slot],
        t_near: near[slot],
        t_far: far[slot],
    };
    if mask.is_power_of_two() {
        return Some(entry(mask.trailing_zeros() as usize));
    }
    let mut entered = [Deferred::default(); TOP_WIDTH];
    let mut count = 0;
    for_each_bit(mask, |slot| {
        entered[count] = entry(slot);
        count += 1;
    });
    let entered = &mut entered[..count];
    sort_nearest_first(entered, |e| e.t_near);
    entered.iter().skip(1).rev().for_each(|&e| stack.push(e));
    entered.first().copied()
}

/// Calls `f` with the index of every set bit of `mask`, lowest first.
#[inline(always)]
pub fn for_each_bit(mut mask: u32, mut f: impl FnMut(usize)) {
    while mask != 0 {
        f(mask.trailing_zeros() as usize);
        mask &= mask - 1;
    }
}

/// Insertion sort by entry distance for the at most four children entered; stable, so equal
/// distances keep slot order.
#[inline(always)]
pub fn sort_nearest_first<T: Copy>(entries: &mut [T], t_near: impl Fn(&T) -> f32) {
    for i in 1..entries.len() {
        let mut j = i;
        while j > 0 && t_near(&entries[j]) < t_near(&entries[j - 1]) {
            entries.swap(j, j - 1);
            j -= 1;
        }
    }
}

/// Traverses every strip of a leaf (`leaf.child` its first strip, `leaf.kind` its count) within
/// the leaf box's interval.
#[inline]
pub fn trace_leaf(
    file: &ReducemFile,
    query: &StripQuery,
    leaf: &Deferred,
    closest: &mut Closest,
) -> bool {
    let first = leaf.child;
    for strip in first..first + leaf.kind {
        let t_far = leaf.t_far.min(closest.reach);
        if leaf.t_near > t_far {
            break;
        }
        let view = file.strip(strip as usize);
        if query.trace(&view, strip, leaf.t_near, t_far, closest) {
            return true;
        }
    }
    false
}

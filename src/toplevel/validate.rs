//! Structural checks of a built hierarchy: what the tests hold every build to.

use super::occupied;
use super::TopLevel;
use crate::format::{TopSlot, WideNode, MAX_TOP_DEPTH, WIDE_WIDTH};
use crate::geometry::Aabb;

impl TopLevel {
    /// Checks the structure: nodes in preorder within [`MAX_TOP_DEPTH`], frames in range,
    /// occupied slots first and empty ones all zero, every strip in exactly one leaf with leaves
    /// in strip order, every slot's decoded box containing its child's decoded slot boxes or its
    /// strips' bounds.
    pub fn validate(&self, bounds: &[Aabb]) -> Result<(), String> {
        let mut walk = ValidateWalk {
            top: self,
            bounds,
            visited: 0,
            next_strip: 0,
        };
        walk.node(0, None, 0)?;
        if walk.visited != self.nodes.len() {
            return Err(format!(
                "{} nodes, {} reachable",
                self.nodes.len(),
                walk.visited
            ));
        }
        if walk.next_strip != bounds.len() || self.strip_order.len() != bounds.len() {
            return Err(format!(
                "leaves cover {} strips of {}",
                walk.next_strip,
                bounds.len()
            ));
        }
        let mut seen = vec![false; bounds.len()];
        for &strip in &self.strip_order {
            if std::mem::replace(&mut seen[strip as usize], true) {
                return Err(format!("strip {strip} is in two leaves"));
            }
        }
        Ok(())
    }
}

/// The preorder walk of [`TopLevel::validate`].
struct ValidateWalk<'a> {
    top: &'a TopLevel,
    bounds: &'a [Aabb],
    visited: usize,
    next_strip: usize,
}

impl ValidateWalk<'_> {
    /// Checks node `index`, whose parent's slot box is `parent_box` (none for the root).
    fn node(&mut self, index: usize, parent_box: Option<Aabb>, depth: usize) -> Result<(), String> {
        let node = self
            .top
            .nodes
            .get(index)
            .ok_or(format!("node {index} out of range"))?;
        if index != self.visited || depth > MAX_TOP_DEPTH {
            return Err(format!("node {index} is out of preorder or too deep"));
        }
        self.visited += 1;
        if node.reserved != 0 || node.exponent.iter().any(|e| !(1..=254).contains(e)) {
            return Err(format!("node {index} has a frame out of range"));
        }
        let occupied = occupied(node);
        if let Some(slot) = (occupied..WIDE_WIDTH).find(|&slot| !is_zero(node, slot)) {
            return Err(format!("node {index} slot {slot} is not exactly empty"));
        }
        for slot in 0..occupied {
            let (min, max) = node.slot_box(slot);
            let slot_box = Aabb { min, max };
            if (0..3).any(|axis| node.min[axis][slot] > node.max[axis][slot]) {
                return Err(format!("node {index} slot {slot} has an inverted box"));
            }
            if parent_box.is_some_and(|parent| !parent.contains_box(&slot_box)) {
                return Err(format!(
                    "node {index} slot {slot} is outside its parent's box"
                ));
            }
            match node.slot(slot) {
                TopSlot::Internal(child) => self.node(child as usize, Some(slot_box), depth + 1)?,
                TopSlot::Leaf { first, count } => self.leaf(index, &slot_box, first, count)?,
                other => return Err(format!("node {index} slot {slot} holds {other:?}")),
            }
        }
        Ok(())
    }

    fn leaf(
        &mut self,
        index: usize,
        slot_box: &Aabb,
        first: u32,
        count: u32,
    ) -> Result<(), String> {
        if first as usize != self.next_strip {
            return Err(format!(
                "node {index}: leaf at strip {first}, expected {}",
                self.next_strip
            ));
        }
        for position in first as usize..(first + count) as usize {
            let strip = *self
                .top
                .strip_order
                .get(position)
                .ok_or("leaf strip out of range")? as usize;
            let strip_box = self.bounds.get(strip).ok_or("strip id out of range")?;
            if !slot_box.contains_box(strip_box) {
                return Err(format!("node {index} does not contain strip {strip}"));
            }
        }
        self.next_strip += count as usize;
        Ok(())
    }
}

/// Whether `slot` of `node` is all zero bytes: planes and link.
fn is_zero(node: &WideNode, slot: usize) -> bool {
    node.link[slot] == 0
        && (0..3).all(|axis| node.min[axis][slot] == 0 && node.max[axis][slot] == 0)
}

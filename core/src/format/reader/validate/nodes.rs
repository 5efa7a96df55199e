//! Top-level node hierarchy checks: links, boxes, one parent per node, depth, strip count.

use std::mem::size_of;

#[cfg(doc)]
use super::{check_node, Windows};
use crate::format::reader::{FormatError, NodeLayout, ReducemFile};
use crate::format::{
    Defect, FilePart, GridNode, NodeRecord, SectionKind, TopNode, TopSlot, WideNode, MAX_TOP_DEPTH,
};

/// Bytes of one top-level node record of `nodes`.
pub(super) fn node_bytes(nodes: &NodeLayout) -> u64 {
    match nodes {
        NodeLayout::F32 => size_of::<TopNode>() as u64,
        NodeLayout::Grid(_) => size_of::<GridNode>() as u64,
        NodeLayout::Wide => size_of::<WideNode>() as u64,
    }
}

/// The node checks of [`Windows::validate_nodes`], with its one-parent, depth and strip-count
/// bookkeeping, or of [`check_node`] without it.
pub(super) struct TreeCheck<'a> {
    pub(super) opened: &'a ReducemFile,
    pub(super) node_bytes: u64,
    pub(super) nodes: usize,
    /// Each node's depth, `u8::MAX` before its parent is seen; empty when checking a node
    /// alone.
    pub(super) depth: Vec<u8>,
    /// Strips over all leaves so far.
    pub(super) leaf_strips: u64,
}

impl TreeCheck<'_> {
    /// The checks of one node that need no other node, among `nodes` nodes of `node_bytes`.
    pub(super) fn alone(opened: &ReducemFile, nodes: usize, node_bytes: u64) -> TreeCheck<'_> {
        TreeCheck {
            opened,
            node_bytes,
            nodes,
            depth: Vec::new(),
            leaf_strips: 0,
        }
    }

    pub(super) fn fail(
        &self,
        index: usize,
        field: u64,
        defect: Defect,
        detail: String,
    ) -> FormatError {
        self.opened.invalid(
            FilePart::Section(SectionKind::TopNodes),
            self.opened.section_offset(SectionKind::TopNodes)
                + index as u64 * self.node_bytes
                + field,
            defect,
            format!("node {index}: {detail}"),
        )
    }

    pub(super) fn check<N: NodeRecord>(
        &mut self,
        index: usize,
        node: &N,
    ) -> Result<(), FormatError> {
        if self.depth.get(index) == Some(&u8::MAX) {
            return Err(self.fail(index, 0, Defect::BadTree, "has no parent".into()));
        }
        if let Some((field, detail)) = node.frame_defect() {
            return Err(self.fail(index, field, Defect::BadEncoding, detail));
        }
        let occupied = node.occupied();
        let empty_model = index == 0 && self.opened.header.strip_count == 0;
        if occupied == 0 && !empty_model {
            return Err(self.fail(
                index,
                N::KIND_FIELD,
                Defect::BadTree,
                "has no children".into(),
            ));
        }
        for slot in 0..N::WIDTH {
            self.check_slot(index, node, slot, slot >= occupied)?;
        }
        Ok(())
    }

    pub(super) fn check_slot<N: NodeRecord>(
        &mut self,
        index: usize,
        node: &N,
        slot: usize,
        empty: bool,
    ) -> Result<(), FormatError> {
        let child_field = N::CHILD_FIELD + N::LINK_STRIDE * slot as u64;
        let kind_field = N::KIND_FIELD + N::LINK_STRIDE * slot as u64;
        if empty {
            if !node.is_exactly_empty(slot) {
                let detail = format!(
                    "slot {slot} follows an empty slot but is not the exact empty slot ({})",
                    N::EMPTY_SLOT
                );
                return Err(self.fail(index, kind_field, Defect::BadEncoding, detail));
            }
            return Ok(());
        }
        if let Some((axis, field)) = node.inverted_axis(slot) {
            let detail = format!("slot {slot}: box minimum above its maximum on axis {axis}");
            return Err(self.fail(index, field, Defect::BadBounds, detail));
        }
        match node.slot(slot) {
            TopSlot::Internal(child) => self.adopt(index, slot, child as usize, child_field),
            TopSlot::Leaf { first, count } => {
                let strips = self.opened.header.strip_count;
                let end = first as u64 + count as u64;
                if end > strips {
                    let detail = format!("slot {slot}: strips {first}..{end} outside 0..{strips}");
                    return Err(self.fail(index, child_field, Defect::OutOfRange, detail));
                }
                self.leaf_strips += count as u64;
                Ok(())
            }
            TopSlot::Invalid(kind) => Err(self.fail(
                index,
                kind_field,
                Defect::BadEncoding,
                format!("slot {slot}: kind {kind:#x} is neither internal nor a strip count"),
            )),
            TopSlot::Empty => unreachable!("occupied slots come before the first empty one"),
        }
    }

    /// Records node `child` as the child of node `index` in `slot`.
    pub(super) fn adopt(
        &mut self,
        index: usize,
        slot: usize,
        child: usize,
        field: u64,
    ) -> Result<(), FormatError> {
        let nodes = self.nodes;
        if child <= index || child >= nodes {
            let detail = format!("slot {slot}: child {child} outside {}..{nodes}", index + 1);
            return Err(self.fail(index, field, Defect::OutOfRange, detail));
        }
        if self.depth.is_empty() {
            return Ok(());
        }
        let child_depth = self.depth[index] + 1;
        if child_depth as usize > MAX_TOP_DEPTH {
            return Err(self.fail(
                index,
                field,
                Defect::BadTree,
                format!("deeper than {MAX_TOP_DEPTH} levels"),
            ));
        }
        if self.depth[child] != u8::MAX {
            let detail = format!("slot {slot}: child {child} has a second parent");
            return Err(self.fail(index, field, Defect::BadTree, detail));
        }
        self.depth[child] = child_depth;
        Ok(())
    }

    /// The leaves must hold as many strips as the file has: every strip is reachable.
    pub(super) fn finish(&self) -> Result<(), FormatError> {
        let strips = self.opened.header.strip_count;
        if self.leaf_strips != strips {
            let detail = format!(
                "leaves hold {} strips, the file has {strips}",
                self.leaf_strips
            );
            return Err(self.fail(0, 0, Defect::CountMismatch, detail));
        }
        Ok(())
    }
}

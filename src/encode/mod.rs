//! Strip encoding (paper 3.2, Fig. 2): local vertices, an implicit left-balanced spatial kd-tree
//! whose split bounds are the strip's own reordered vertices, and 1-byte local references.
//!
//! For each internal node (preorder `i`, see [`crate::format::implicit_tree`]) the encoder picks a
//! split axis, then stores at slot `2i` a vertex attaining the maximum of the left windows on that
//! axis and at slot `2i + 1` a vertex attaining the minimum of the right windows. The traversal
//! reads those two coordinates as the planes of a spatial kd-tree (a bounding interval hierarchy
//! node), so no plane values are stored beyond the vertices themselves. Vertices never used as a
//! bound follow the bound slots in order of first reference, for locality of the strip walk.
//!
//! A vertex can be the bound of two nodes; it is then stored twice ("hierarchy overhead", the
//! paper's Table 1 metric). As the paper suggests, among equal candidates the encoder prefers a
//! vertex not stored yet. Beyond the paper, the axis choice itself weighs duplication: each axis
//! is scored by the surface-area cost of the two clipped child boxes, inflated by
//! [`DUPLICATE_PENALTY`] per bound that would need a copy, because a copy costs 12 bytes forever
//! while a slightly worse split costs a little traversal time.
//!
//! Deviation from the paper: the split axes are kept as 2-bit fields after the vertices instead
//! of in the sign bits of box-relative coordinates, because box-relative f32 coordinates would
//! round and the representation must stay lossless (bit-exact decoding is what makes tracing
//! watertight across strips).

use std::fmt;

use crate::format::implicit_tree::{internal_nodes, split_point};
use crate::format::{align_up, axis_bytes, VertexEncoding, MAX_STRIP_VERTICES};
use crate::geometry::{Aabb, Point};
use crate::strip::window_count;

/// Relative cost increase of an axis per split bound that must be stored a second time.
pub const DUPLICATE_PENALTY: f64 = 0.5;

/// One encoded strip: its block (padded to 4 bytes) and what the top level needs to know.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedStrip {
    pub bounds: Aabb,
    pub vertex_count: u16,
    pub reference_count: u16,
    /// Stored copies that exist only because a vertex bounds two kd-tree nodes.
    pub hierarchy_copies: u16,
    pub block: Vec<u8>,
}

/// The strip references more distinct vertices than 1-byte local indices can address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TooManyVertices {
    pub needed: usize,
}

impl fmt::Display for TooManyVertices {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "strip needs {} stored vertices, the limit is {MAX_STRIP_VERTICES}",
            self.needed
        )
    }
}

/// Encodes one strip given as mesh vertex indices (swaps included, see [`crate::strip`]).
pub fn encode_strip(
    references: &[u32],
    positions: &[Point],
    leaf_windows: usize,
) -> Result<EncodedStrip, TooManyVertices> {
    let mut layout = StripLayout::new(references, positions);
    let windows = window_count(references.len());
    let nodes = internal_nodes(windows, leaf_windows);
    layout.slots.reserve(2 * nodes);
    let mut axes = Vec::with_capacity(nodes);
    let root_box = layout.range_bounds(0, references.len());
    layout.place_splits(0, windows, root_box, leaf_windows, &mut axes);
    layout.place_remaining_vertices();
    let needed = layout.slots.len();
    if needed > MAX_STRIP_VERTICES {
        return Err(TooManyVertices { needed });
    }
    Ok(layout.into_encoded(&axes, root_box))
}

/// Splits a strip that cannot be encoded into two halves that share two references.
///
/// The cut is at an even window so that the second half keeps the parity, and with it the
/// winding, of every window.
pub fn split_strip(references: &[u32]) -> (&[u32], &[u32]) {
    let windows = window_count(references.len());
    let cut = (windows / 2) & !1;
    let cut = cut.max(2).min(windows);
    (&references[..cut + 2], &references[cut..])
}

/// Mutable state of one strip's encoding: distinct vertices and their stored slots.
struct StripLayout<'a> {
    positions: &'a [Point],
    /// Sorted distinct mesh vertex indices of the strip.
    distinct: Vec<u32>,
    /// Each reference as an index into `distinct`.
    local: Vec<u16>,
    /// First slot holding each distinct vertex, `None` until stored.
    home: Vec<Option<u16>>,
    /// Stored vertices in file order, as indices into `distinct`.
    slots: Vec<u16>,
    hierarchy_copies: u16,
}

impl<'a> StripLayout<'a> {
    fn new(references: &[u32], positions: &'a [Point]) -> StripLayout<'a> {
        let mut distinct = references.to_vec();
        distinct.sort_unstable();
        distinct.dedup();
        let local = references
            .iter()
            .map(|r| distinct.binary_search(r).unwrap_or_default() as u16)
            .collect();
        StripLayout {
            positions,
            home: vec![None; distinct.len()],
            distinct,
            local,
            slots: Vec::new(),
            hierarchy_copies: 0,
        }
    }

    fn point(&self, local: u16) -> &Point {
        &self.positions[self.distinct[local as usize] as usize]
    }

    /// Bounds of the vertices referenced by `local[start..end]`.
    fn range_bounds(&self, start: usize, end: usize) -> Aabb {
        Aabb::from_points(self.local[start..end].iter().map(|&v| self.point(v)))
    }

    /// Preorder walk over internal nodes, choosing each node's axis and bound vertices.
    fn place_splits(
        &mut self,
        lo: usize,
        hi: usize,
        node_box: Aabb,
        leaf_windows: usize,
        axes: &mut Vec<u8>,
    ) {
        if hi - lo <= leaf_windows {
            return;
        }
        let mid = split_point(lo, hi);
        // Window k references positions k..k+3, so windows [lo, mid) reference [lo, mid + 2).
        let left = lo..mid + 2;
        let right = mid..hi + 2;
        let choice = (0..3)
            .map(|axis| {
                self.split_choice(
                    axis,
                    left.clone(),
                    right.clone(),
                    &node_box,
                    (mid - lo, hi - mid),
                )
            })
            .min_by(|a, b| a.cost.total_cmp(&b.cost))
            .unwrap_or_else(|| unreachable!("three axes"));
        axes.push(choice.axis as u8);
        self.store(choice.left_bound);
        self.store(choice.right_bound);
        let mut left_box = node_box;
        left_box.max[choice.axis] =
            left_box.max[choice.axis].min(self.point(choice.left_bound)[choice.axis]);
        let mut right_box = node_box;
        right_box.min[choice.axis] =
            right_box.min[choice.axis].max(self.point(choice.right_bound)[choice.axis]);
        self.place_splits(lo, mid, left_box, leaf_windows, axes);
        self.place_splits(mid, hi, right_box, leaf_windows, axes);
    }

    /// The cheapest bounds on `axis`. Each side considers the exact extreme of its windows and,
    /// when that vertex is already stored, the tightest not-yet-stored vertex beyond it: a looser
    /// but still conservative plane that costs no copy.
    fn split_choice(
        &self,
        axis: usize,
        left: std::ops::Range<usize>,
        right: std::ops::Range<usize>,
        node_box: &Aabb,
        windows: (usize, usize),
    ) -> SplitChoice {
        let upper = self.extreme(left, axis, |a, b| a > b);
        let lower = self.extreme(right, axis, |a, b| a < b);
        let uppers = [
            Some(upper),
            self.unstored_beyond(upper, axis, |a, b| a >= b),
        ];
        let lowers = [
            Some(lower),
            self.unstored_beyond(lower, axis, |a, b| a <= b),
        ];
        let mut best: Option<SplitChoice> = None;
        for left_bound in uppers.into_iter().flatten() {
            for right_bound in lowers.into_iter().flatten() {
                let choice = self.score(axis, left_bound, right_bound, node_box, windows);
                if best.as_ref().is_none_or(|b| choice.cost < b.cost) {
                    best = Some(choice);
                }
            }
        }
        best.unwrap_or_else(|| unreachable!("the exact extremes are always candidates"))
    }

    fn score(
        &self,
        axis: usize,
        left_bound: u16,
        right_bound: u16,
        node_box: &Aabb,
        (left_windows, right_windows): (usize, usize),
    ) -> SplitChoice {
        let mut left_box = *node_box;
        left_box.max[axis] = left_box.max[axis].min(self.point(left_bound)[axis]);
        let mut right_box = *node_box;
        right_box.min[axis] = right_box.min[axis].max(self.point(right_bound)[axis]);
        let area_cost = left_box.surface_area() * left_windows as f64
            + right_box.surface_area() * right_windows as f64;
        let copies = [left_bound, right_bound]
            .iter()
            .filter(|&&v| self.home[v as usize].is_some())
            .count()
            + usize::from(left_bound == right_bound);
        SplitChoice {
            axis,
            left_bound,
            right_bound,
            cost: area_cost * (1.0 + DUPLICATE_PENALTY * copies as f64),
        }
    }

    /// When `exact` is already stored: the not-yet-stored vertex whose coordinate on `axis` is
    /// `as_loose_as` the exact one's and closest to it (lowest index among equals).
    fn unstored_beyond(
        &self,
        exact: u16,
        axis: usize,
        as_loose_as: fn(f32, f32) -> bool,
    ) -> Option<u16> {
        self.home[exact as usize]?;
        let limit = self.point(exact)[axis];
        (0..self.distinct.len() as u16)
            .filter(|&v| self.home[v as usize].is_none())
            .filter(|&v| as_loose_as(self.point(v)[axis], limit))
            .min_by(|&a, &b| {
                let distance = |v: u16| (self.point(v)[axis] - limit).abs();
                distance(a).total_cmp(&distance(b)).then(a.cmp(&b))
            })
    }

    /// The vertex of `local[range]` most extreme on `axis` under `better`; among equal
    /// coordinates, one not stored yet, then the lowest index (for determinism).
    fn extreme(
        &self,
        range: std::ops::Range<usize>,
        axis: usize,
        better: fn(f32, f32) -> bool,
    ) -> u16 {
        let mut best = self.local[range.start];
        for &v in &self.local[range] {
            let (value, best_value) = (self.point(v)[axis], self.point(best)[axis]);
            let tie_preferred = value == best_value && self.prefers(v, best);
            if better(value, best_value) || tie_preferred {
                best = v;
            }
        }
        best
    }

    fn prefers(&self, candidate: u16, current: u16) -> bool {
        let unstored = |v: u16| self.home[v as usize].is_none();
        match (unstored(candidate), unstored(current)) {
            (true, false) => true,
            (false, true) => false,
            _ => candidate < current,
        }
    }

    fn store(&mut self, vertex: u16) {
        let slot = self.slots.len() as u16;
        match self.home[vertex as usize] {
            Some(_) => self.hierarchy_copies += 1,
            None => self.home[vertex as usize] = Some(slot),
        }
        self.slots.push(vertex);
    }

    fn place_remaining_vertices(&mut self) {
        for i in 0..self.local.len() {
            let vertex = self.local[i];
            if self.home[vertex as usize].is_none() {
                self.store(vertex);
            }
        }
    }

    fn into_encoded(self, axes: &[u8], bounds: Aabb) -> EncodedStrip {
        let encoding = VertexEncoding::F32;
        let unpadded = self.slots.len() * encoding.bytes_per_vertex()
            + axis_bytes(axes.len())
            + self.local.len();
        let mut block = Vec::with_capacity(align_up(unpadded as u64, 4) as usize);
        for &vertex in &self.slots {
            for coordinate in self.point(vertex) {
                block.extend_from_slice(&coordinate.to_le_bytes());
            }
        }
        block.extend(axes.chunks(4).map(pack_axes));
        block.extend(
            self.local
                .iter()
                .map(|&v| self.home[v as usize].unwrap_or_default() as u8),
        );
        block.resize(align_up(block.len() as u64, 4) as usize, 0);
        EncodedStrip {
            bounds,
            vertex_count: self.slots.len() as u16,
            reference_count: self.local.len() as u16,
            hierarchy_copies: self.hierarchy_copies,
            block,
        }
    }
}

struct SplitChoice {
    axis: usize,
    left_bound: u16,
    right_bound: u16,
    cost: f64,
}

/// Packs up to four 2-bit axes, node `i` of the group in bits `2i..2i+2`.
fn pack_axes(group: &[u8]) -> u8 {
    group
        .iter()
        .enumerate()
        .fold(0, |byte, (i, &axis)| byte | (axis << (2 * i)))
}

/// Checks an encoded strip's hierarchy: every node's stored bounds contain the vertices of the
/// windows on their side, along the node's axis, and every reference is in range.
pub fn validate(strip: &EncodedStrip, leaf_windows: usize) -> Result<(), String> {
    let record = crate::format::StripRecord {
        data_word: 0,
        vertex_count: strip.vertex_count,
        reference_count: strip.reference_count,
    };
    let windows = window_count(strip.reference_count as usize);
    let table = crate::format::implicit_tree::NodeCountTable::new(leaf_windows, windows);
    let view = crate::format::reader::strip_view(&strip.block, &record, &table);
    if let Some(r) = view
        .references
        .iter()
        .find(|&&r| r as usize >= view.vertices.len())
    {
        return Err(format!("reference {r} out of range"));
    }
    let mut next_node = 0;
    validate_node(&view, 0, windows, leaf_windows, &mut next_node)?;
    let all = Aabb::from_points(view.references.iter().map(|&r| &view.vertices[r as usize]));
    if all != strip.bounds {
        return Err(format!(
            "strip bounds {:?} differ from its vertices' {all:?}",
            strip.bounds
        ));
    }
    Ok(())
}

fn validate_node(
    view: &crate::format::reader::StripView<'_>,
    lo: usize,
    hi: usize,
    leaf_windows: usize,
    next_node: &mut usize,
) -> Result<(), String> {
    if hi - lo <= leaf_windows {
        return Ok(());
    }
    let node = *next_node;
    *next_node += 1;
    let mid = split_point(lo, hi);
    let axis = view.axis(node);
    let coordinate = |position: usize| view.vertices[view.references[position] as usize][axis];
    let (upper, lower) = (
        view.vertices[2 * node][axis],
        view.vertices[2 * node + 1][axis],
    );
    if (lo..mid + 2).any(|p| coordinate(p) > upper) {
        return Err(format!(
            "node {node}: left windows exceed the upper bound {upper} on axis {axis}"
        ));
    }
    if (mid..hi + 2).any(|p| coordinate(p) < lower) {
        return Err(format!(
            "node {node}: right windows go below the lower bound {lower} on axis {axis}"
        ));
    }
    validate_node(view, lo, mid, leaf_windows, next_node)?;
    validate_node(view, mid, hi, leaf_windows, next_node)
}

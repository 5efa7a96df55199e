//! Strip encoding (paper 3.2, Fig. 2): local vertices, an implicit left-balanced spatial kd-tree
//! whose split bounds are the strip's own reordered vertices, and 1-byte local references (packed
//! since format 3.0).
//!
//! For each internal node (preorder `i`, see [`crate::format::implicit_tree`]) the encoder picks
//! the split axis whose exact child extremes give the lowest surface-area cost, then stores at
//! slot `2i` a vertex at or above the maximum of the left windows on that axis and at slot
//! `2i + 1` a vertex at or below the minimum of the right windows. The traversal reads those two
//! coordinates as the planes of a spatial kd-tree (a bounding interval hierarchy node), so no
//! plane values are stored beyond the vertices themselves. Vertices never used as a bound follow
//! the bound slots in order of first reference, for locality of the strip walk.
//!
//! A vertex that bounds two nodes is stored twice ("hierarchy overhead", the paper's Table 1
//! metric). The paper minimizes this by "considering previously unused candidates first"; see
//! `assign_bounds` for how far we take that.
//!
//! Deviation from the paper: the split axes are kept as 2-bit fields after the vertices instead
//! of in the sign bits of box-relative coordinates, because box-relative f32 coordinates would
//! round and the representation must stay lossless (bit-exact decoding is what makes tracing
//! watertight across strips).
//!
//! Quantized strips ([`Positions::Grid`]) are laid out on their decoded positions, exactly as
//! lossless strips on theirs, and store the grid points instead of f32 copies
//! ([`crate::format::quantized`]). Decoding is monotone in the grid point, so every bound holds
//! on what the reader decodes, bit for bit. Their references are packed at the bits the strip's
//! vertex count needs ([`crate::format::references`]).
//!
//! Format 3.0 packs the references of lossless strips too and appends the strip's block boxes
//! ([`crate::format::block_boxes`]); see there for what they cost and gain.

pub(crate) mod attributes;
pub(crate) mod block_boxes;

use std::fmt;

pub(crate) use attributes::{AttributeSource, StripAttributes};

use crate::format::implicit_tree::{internal_nodes, is_leaf, split_point};
use crate::format::reader::VertexLayout;
use crate::format::references::pack;
use crate::format::{align_up, axis_bytes, quantized, MAX_STRIP_VERTICES};
use crate::geometry::{Aabb, Point};
use crate::strip_windows::window_count;

/// The vertices strips are encoded from.
#[derive(Clone, Copy, Debug)]
pub enum Positions<'a> {
    /// Stored as bit-exact f32 copies.
    F32(&'a [Point]),
    /// Stored as grid points of `bits` bits; `decoded` are their positions
    /// ([`crate::format::grid::Grid::decode`]), on which the bounds are chosen.
    Grid {
        points: &'a [[u32; 3]],
        decoded: &'a [Point],
        bits: u32,
    },
}

impl<'a> Positions<'a> {
    /// Where the reader will see the vertices.
    fn decoded(&self) -> &'a [Point] {
        match *self {
            Positions::F32(points) => points,
            Positions::Grid { decoded, .. } => decoded,
        }
    }
}

/// How far beyond its exact extreme a split bound may lie, as a fraction of the node's extent on
/// the split axis, to use a vertex not stored yet instead of a copy.
const MAX_LOOSENESS: f32 = 0.25;

/// One encoded strip: its block (padded to 4 bytes) and what the top level needs to know.
#[derive(Clone, Debug, PartialEq)]
pub struct EncodedStrip {
    pub bounds: Aabb,
    pub vertex_count: u16,
    pub reference_count: u16,
    /// Stored copies that exist only because a vertex bounds two kd-tree nodes.
    pub hierarchy_copies: u16,
    pub block: Vec<u8>,
    /// The mesh vertex each stored vertex is a copy of, in stored order.
    pub vertex_sources: Vec<u32>,
    /// What the attribute sections store for this strip (empty when the file has none).
    pub attributes: StripAttributes,
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

/// Encodes one strip given as mesh vertex indices (swaps included, see [`crate::strip_windows`]).
pub fn encode_strip(
    references: &[u32],
    positions: Positions,
    leaf_windows: usize,
) -> Result<EncodedStrip, TooManyVertices> {
    let mut layout = StripLayout::new(references, positions);
    let windows = window_count(references.len());
    let nodes = internal_nodes(windows, leaf_windows);
    let mut splits = Vec::with_capacity(nodes);
    let root_box = layout.range_bounds(0, references.len());
    layout.choose_splits(0, windows, root_box, leaf_windows, &mut splits);
    layout.assign_bounds(&splits);
    layout.place_remaining_vertices();
    let axes: Vec<u8> = splits.iter().map(|s| s.axis as u8).collect();
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
    positions: Positions<'a>,
    /// The positions the reader will decode.
    decoded: &'a [Point],
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
    fn new(references: &[u32], positions: Positions<'a>) -> StripLayout<'a> {
        let mut distinct = references.to_vec();
        distinct.sort_unstable();
        distinct.dedup();
        let local = references
            .iter()
            .map(|r| distinct.binary_search(r).unwrap_or_default() as u16)
            .collect();
        StripLayout {
            positions,
            decoded: positions.decoded(),
            home: vec![None; distinct.len()],
            distinct,
            local,
            slots: Vec::new(),
            hierarchy_copies: 0,
        }
    }

    fn point(&self, local: u16) -> &Point {
        &self.decoded[self.distinct[local as usize] as usize]
    }

    /// Bounds of the vertices referenced by `local[start..end]`.
    fn range_bounds(&self, start: usize, end: usize) -> Aabb {
        Aabb::from_points(self.local[start..end].iter().map(|&v| self.point(v)))
    }

    /// Preorder walk over internal nodes choosing each node's axis by the surface-area cost of
    /// the two clipped child boxes, with the children's exact extremes as planes.
    fn choose_splits(
        &self,
        lo: usize,
        hi: usize,
        node_box: Aabb,
        leaf_windows: usize,
        splits: &mut Vec<NodeSplit>,
    ) {
        if is_leaf(lo, hi, leaf_windows) {
            return;
        }
        let mid = split_point(lo, hi, leaf_windows);
        // Window k references positions k..k+3, so windows [lo, mid) reference [lo, mid + 2).
        let (left, right) = (lo..mid + 2, mid..hi + 2);
        let split = (0..3)
            .map(|axis| NodeSplit {
                axis,
                upper: self.extreme(left.clone(), axis, |a, b| a > b),
                lower: self.extreme(right.clone(), axis, |a, b| a < b),
                node_box,
            })
            .min_by(|a, b| {
                let windows = SideWindows {
                    left: mid - lo,
                    right: hi - mid,
                };
                let cost = |s: &NodeSplit| self.split_cost(s, windows);
                cost(a).total_cmp(&cost(b))
            })
            .unwrap_or_else(|| unreachable!("three axes"));
        let (left_box, right_box) = self.child_boxes(&split);
        splits.push(split);
        self.choose_splits(lo, mid, left_box, leaf_windows, splits);
        self.choose_splits(mid, hi, right_box, leaf_windows, splits);
    }

    fn child_boxes(&self, split: &NodeSplit) -> (Aabb, Aabb) {
        let axis = split.axis;
        let (mut left, mut right) = (split.node_box, split.node_box);
        left.max[axis] = left.max[axis].min(self.point(split.upper)[axis]);
        right.min[axis] = right.min[axis].max(self.point(split.lower)[axis]);
        (left, right)
    }

    fn split_cost(&self, split: &NodeSplit, windows: SideWindows) -> f64 {
        let (left, right) = self.child_boxes(split);
        left.surface_area() * windows.left as f64 + right.surface_area() * windows.right as f64
    }

    /// The exact extreme of `local[range]` on `axis` under `better` (lowest index among equals).
    fn extreme(
        &self,
        range: std::ops::Range<usize>,
        axis: usize,
        better: fn(f32, f32) -> bool,
    ) -> u16 {
        let mut best = self.local[range.start];
        for &v in &self.local[range] {
            let (value, best_value) = (self.point(v)[axis], self.point(best)[axis]);
            if better(value, best_value) || (value == best_value && v < best) {
                best = v;
            }
        }
        best
    }

    /// Fills the bound slots, most constrained slot first, each with the not-yet-stored vertex
    /// closest to its exact extreme among those that keep the plane conservative and within
    /// [`MAX_LOOSENESS`] of the node's extent; with none left, the exact extreme is stored again.
    ///
    /// Deviation from the paper, which takes a split-vertex candidate equal to the extreme:
    /// with leaves of two windows a strip has about as many bound slots as distinct vertices,
    /// so exact candidates collide constantly (over half the input vertices were copied on a
    /// scanned surface). A slightly looser plane costs a little culling; a copy costs 12 bytes.
    fn assign_bounds(&mut self, splits: &[NodeSplit]) {
        let slots: Vec<BoundSlot> = splits.iter().flat_map(|s| self.bound_slots(s)).collect();
        let mut order: Vec<usize> = (0..slots.len()).collect();
        order.sort_by_key(|&slot| (self.candidates(&slots[slot]).count(), slot));
        let mut assigned = vec![0u16; slots.len()];
        let mut taken = vec![false; self.distinct.len()];
        for slot in order {
            let bound = &slots[slot];
            let closest = self
                .candidates(bound)
                .filter(|&v| !taken[v as usize])
                .min_by(|&a, &b| {
                    let distance = |v: u16| (self.point(v)[bound.axis] - bound.limit).abs();
                    distance(a).total_cmp(&distance(b)).then(a.cmp(&b))
                });
            let vertex = closest.unwrap_or(bound.exact);
            taken[vertex as usize] = true;
            assigned[slot] = vertex;
        }
        for vertex in assigned {
            self.store(vertex);
        }
    }

    fn bound_slots(&self, split: &NodeSplit) -> [BoundSlot; 2] {
        let axis = split.axis;
        let reach = MAX_LOOSENESS * split.node_box.extent(axis);
        let slot = |exact: u16, upper: bool| {
            let limit = self.point(exact)[axis];
            let far = if upper { limit + reach } else { limit - reach };
            BoundSlot {
                axis,
                exact,
                limit,
                range: if upper { (limit, far) } else { (far, limit) },
            }
        };
        [slot(split.upper, true), slot(split.lower, false)]
    }

    fn candidates<'s>(&'s self, bound: &'s BoundSlot) -> impl Iterator<Item = u16> + 's {
        (0..self.distinct.len() as u16).filter(move |&v| {
            let value = self.point(v)[bound.axis];
            bound.range.0 <= value && value <= bound.range.1
        })
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

    /// The stored vertices in the file's encoding.
    fn vertex_bytes(&self) -> Vec<u8> {
        let mesh_vertex = |slot: &u16| self.distinct[*slot as usize] as usize;
        match self.positions {
            Positions::F32(points) => self
                .slots
                .iter()
                .flat_map(|slot| points[mesh_vertex(slot)])
                .flat_map(f32::to_le_bytes)
                .collect(),
            Positions::Grid { points, bits, .. } => {
                let stored: Vec<[u32; 3]> =
                    self.slots.iter().map(|s| points[mesh_vertex(s)]).collect();
                let layout = quantized::AxisWordLayout::Packed { grid_bits: bits };
                quantized::pack(&stored, bits, layout)
            }
        }
    }

    fn into_encoded(self, axes: &[u8], bounds: Aabb) -> EncodedStrip {
        let mut block = self.vertex_bytes();
        block.reserve(axis_bytes(axes.len()) + self.local.len() + 3);
        block.extend(axes.chunks(4).map(pack_axes));
        let references: Vec<u8> = self
            .local
            .iter()
            .map(|&v| self.home[v as usize].unwrap_or_default() as u8)
            .collect();
        block.extend(pack(&references, self.slots.len()));
        let positions: Vec<Point> = self.local.iter().map(|&v| *self.point(v)).collect();
        block.extend(block_boxes::encode(&positions, *self.point(self.slots[0])));
        block.resize(align_up(block.len() as u64, 4) as usize, 0);
        EncodedStrip {
            vertex_sources: self
                .slots
                .iter()
                .map(|&s| self.distinct[s as usize])
                .collect(),
            attributes: StripAttributes::default(),
            bounds,
            vertex_count: self.slots.len() as u16,
            reference_count: self.local.len() as u16,
            hierarchy_copies: self.hierarchy_copies,
            block,
        }
    }
}

/// How many windows a node's split puts in each child.
#[derive(Clone, Copy)]
struct SideWindows {
    left: usize,
    right: usize,
}

/// A node's split axis and the exact extremes of its children (left maximum, right minimum).
struct NodeSplit {
    axis: usize,
    upper: u16,
    lower: u16,
    node_box: Aabb,
}

/// One bound slot: any vertex whose coordinate on `axis` lies in `range` keeps the plane
/// conservative (at or beyond the exact extreme `limit`) and close enough to be useful.
struct BoundSlot {
    axis: usize,
    exact: u16,
    limit: f32,
    range: (f32, f32),
}

/// Packs up to four 2-bit axes, node `i` of the group in bits `2i..2i+2`.
fn pack_axes(group: &[u8]) -> u8 {
    group
        .iter()
        .enumerate()
        .fold(0, |byte, (i, &axis)| byte | (axis << (2 * i)))
}

/// Checks an encoded strip's hierarchy as the reader decodes it (`layout`): every node's stored
/// bounds contain the vertices of the windows on their side, along the node's axis, and every
/// reference is in range.
pub fn validate(
    strip: &EncodedStrip,
    leaf_windows: usize,
    layout: &VertexLayout,
) -> Result<(), String> {
    let record = crate::format::StripRecord {
        data_word: 0,
        vertex_count: strip.vertex_count,
        reference_count: strip.reference_count,
    };
    let windows = window_count(strip.reference_count as usize);
    let view = crate::format::reader::strip_view(&strip.block, &record, leaf_windows, layout);
    let references = view.references.to_vec();
    if let Some(r) = references
        .iter()
        .find(|&&r| r as usize >= view.vertices.len())
    {
        return Err(format!("reference {r} out of range"));
    }
    let mut next_node = 0;
    validate_node(&view, 0, windows, leaf_windows, &mut next_node)?;
    let referenced: Vec<Point> = references
        .iter()
        .map(|&r| view.vertices.point(r as usize))
        .collect();
    let all = Aabb::from_points(&referenced);
    if all != strip.bounds {
        return Err(format!(
            "strip bounds {:?} differ from its vertices' {all:?}",
            strip.bounds
        ));
    }
    validate_boxes(&view, &referenced)
}

/// Checks that every decoded block box holds its windows' positions (`referenced`, strip
/// order).
fn validate_boxes(
    view: &crate::format::reader::StripView<'_>,
    referenced: &[Point],
) -> Result<(), String> {
    use crate::format::block_boxes::BOX_WINDOWS;
    let Some(frame) = view.boxes.frame(view.vertices.point(0)) else {
        return Ok(());
    };
    for (index, first) in (0..view.window_count()).step_by(BOX_WINDOWS).enumerate() {
        let (min, max) = view
            .boxes
            .decode(&frame, index)
            .ok_or_else(|| format!("block box {index} missing"))?;
        let end = (first + BOX_WINDOWS + 2).min(referenced.len());
        if let Some(p) = referenced[first..end]
            .iter()
            .find(|p| (0..3).any(|a| p[a] < min[a] || p[a] > max[a]))
        {
            return Err(format!("block box {index} {min:?}..{max:?} misses {p:?}"));
        }
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
    if is_leaf(lo, hi, leaf_windows) {
        return Ok(());
    }
    let node = *next_node;
    *next_node += 1;
    let mid = split_point(lo, hi, leaf_windows);
    let axis = view.axis(node);
    let coordinate = |position: usize| {
        view.vertices
            .coordinate(view.references.get(position) as usize, axis)
    };
    let (upper, lower) = (
        view.vertices.coordinate(2 * node, axis),
        view.vertices.coordinate(2 * node + 1, axis),
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

//! The child boxes of every top-level node record, decoded alike for the closest-point walk,
//! which bounds their distance to a point (the crossing walk reads boxes as stored:
//! `crossing_walk::NodeBoxes`).

use crate::format::grid::NodeGrid;
use crate::format::{GridNode, NodeRecord, TopNode, WideNode, TOP_WIDTH};
use crate::geometry::Point;
use crate::trace::kernel::distance_bounds::LaneBoxes;

/// A top-level node record's child boxes as f32 `(min, max)`.
pub(crate) trait ChildBox: NodeRecord {
    /// What decoding a box takes besides the node.
    type Grid;
    fn child_box(&self, slot: usize, grid: &Self::Grid) -> (Point, Point);

    /// The boxes of slots `4 group .. 4 group + 4` at once, by axis and slot (`[axis][slot]`):
    /// minima, maxima. Slots that hold no child decode as whatever their planes store.
    fn child_boxes(
        &self,
        grid: &Self::Grid,
        group: usize,
    ) -> (LaneBoxes<TOP_WIDTH>, LaneBoxes<TOP_WIDTH>) {
        let boxes: [(Point, Point); TOP_WIDTH] =
            std::array::from_fn(|lane| self.child_box(group * TOP_WIDTH + lane, grid));
        (
            std::array::from_fn(|axis| boxes.map(|(min, _)| min[axis])),
            std::array::from_fn(|axis| boxes.map(|(_, max)| max[axis])),
        )
    }
}

impl ChildBox for TopNode {
    type Grid = ();

    fn child_box(&self, slot: usize, _: &()) -> (Point, Point) {
        self.slot_box(slot)
    }

    /// The record stores its boxes by axis and slot already.
    fn child_boxes(&self, _: &(), _group: usize) -> (LaneBoxes<TOP_WIDTH>, LaneBoxes<TOP_WIDTH>) {
        (self.min, self.max)
    }
}

impl ChildBox for GridNode {
    type Grid = NodeGrid;

    /// Through [`NodeGrid::decode_axis`], the expression the writer rounded the boxes outward
    /// with.
    fn child_box(&self, slot: usize, grid: &NodeGrid) -> (Point, Point) {
        let decode = |q: &[[u16; TOP_WIDTH]; 3]| {
            std::array::from_fn(|axis| grid.decode_axis(q[axis][slot], axis))
        };
        (decode(&self.min), decode(&self.max))
    }
}

impl ChildBox for WideNode {
    type Grid = ();

    /// Through [`WideNode::decode`], the expression the writer rounded the boxes outward with.
    fn child_box(&self, slot: usize, _: &()) -> (Point, Point) {
        self.slot_box(slot)
    }
}

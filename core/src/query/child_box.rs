//! The child boxes of every top-level node record, decoded alike for the closest-point walk,
//! which bounds their distance to a point (the crossing walk reads boxes as stored:
//! `crossing_walk::NodeBoxes`).

use crate::format::grid::NodeGrid;
use crate::format::{GridNode, NodeRecord, TopNode, WideNode, TOP_WIDTH};
use crate::trace::kernel::distance_bounds::LaneBoxes;
use crate::trace::kernel::query_kernel::QueryKernel;

/// A group of four child boxes by axis and slot (`[axis][slot]`): minima, maxima.
pub(crate) type FourBoxes = (LaneBoxes<TOP_WIDTH>, LaneBoxes<TOP_WIDTH>);

/// A top-level node record's child boxes as f32, in groups of four slots.
pub(crate) trait ChildBox: NodeRecord {
    /// What decoding a box takes besides the node.
    type Grid;
    /// Every slot's box in groups of four (group `g`: slots `4 g .. 4 g + 4`); slots that hold
    /// no child decode as whatever their planes store.
    type Groups: AsRef<[FourBoxes]>;
    fn child_boxes<Q: QueryKernel>(&self, grid: &Self::Grid) -> Self::Groups;
}

impl ChildBox for TopNode {
    type Grid = ();
    type Groups = [FourBoxes; 1];

    /// The record stores its boxes by axis and slot already.
    #[inline(always)]
    fn child_boxes<Q: QueryKernel>(&self, _: &()) -> [FourBoxes; 1] {
        [(self.min, self.max)]
    }
}

impl ChildBox for GridNode {
    type Grid = NodeGrid;
    type Groups = [FourBoxes; 1];

    /// Through [`NodeGrid::decode_axis`], the expression the writer rounded the boxes outward
    /// with.
    #[inline(always)]
    fn child_boxes<Q: QueryKernel>(&self, grid: &NodeGrid) -> [FourBoxes; 1] {
        let decode = |q: &[[u16; TOP_WIDTH]; 3]| {
            std::array::from_fn(|axis| q[axis].map(|q| grid.decode_axis(q, axis)))
        };
        [(decode(&self.min), decode(&self.max))]
    }
}

impl ChildBox for WideNode {
    type Grid = ();
    type Groups = [FourBoxes; 2];

    /// All eight at once in the kernel's lanes: [`WideNode::decode`]'s bits, the expression
    /// the writer rounded the boxes outward with.
    #[inline(always)]
    fn child_boxes<Q: QueryKernel>(&self, _: &()) -> [FourBoxes; 2] {
        Q::wide_child_boxes(self)
    }
}

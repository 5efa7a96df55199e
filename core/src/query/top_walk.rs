//! The query walks' one dispatch point: the kernel and the top level's node layout are picked
//! together, so that each walk is written once, generic over both, and compiled for each pair.

use super::child_box::ChildBox;
use super::crossing_walk::NodeBoxes;
use crate::format::reader::{ReducemFile, TopNodes};
use crate::trace::kernel::query_kernel::{dispatch_query, QueryKernel, QueryWalk};
use crate::trace::kernel::Kernel;

/// A top-level node record as every query walk reads it: boxes bounded against a point
/// ([`ChildBox`]) and entered by a ray ([`NodeBoxes`]), decoded with the same grid.
pub(super) trait QueryNode: ChildBox + NodeBoxes {}

impl<N: ChildBox + NodeBoxes> QueryNode for N {}

/// A query walk over the top level, generic over the kernel and the node record, for
/// [`dispatch_top_walk`].
pub(super) trait TopWalk {
    type Output;

    fn run<Q: QueryKernel, N: QueryNode>(self, nodes: &[N], grid: &N::Grid) -> Self::Output;
}

/// Runs `walk` over `file`'s top level on `kernel`.
#[inline(always)]
pub(super) fn dispatch_top_walk<W: TopWalk>(
    kernel: Kernel,
    file: &ReducemFile,
    walk: W,
) -> W::Output {
    dispatch_query(kernel, OnTopLevel { file, walk })
}

/// A [`TopWalk`] with the file whose nodes it walks, as a [`QueryWalk`].
struct OnTopLevel<'f, W> {
    file: &'f ReducemFile,
    walk: W,
}

impl<W: TopWalk> QueryWalk for OnTopLevel<'_, W> {
    type Output = W::Output;

    #[inline(always)]
    fn run<Q: QueryKernel>(self) -> W::Output {
        match self.file.top_nodes() {
            TopNodes::F32(nodes) => self.walk.run::<Q, _>(nodes, &()),
            TopNodes::Grid(nodes, grid) => self.walk.run::<Q, _>(nodes, &grid),
            TopNodes::Wide(nodes) => self.walk.run::<Q, _>(nodes, &()),
        }
    }
}

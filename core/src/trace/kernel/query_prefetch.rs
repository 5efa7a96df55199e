//! The tracer's prefetches ([`prefetch`](super::prefetch)) for the query walks, which live
//! outside `crate::trace`: a walk that asks for every entered child of a node before it
//! visits the first overlaps the loads of the later ones with that visit.

use super::prefetch::{StripSections, Targets};
use crate::format::reader::ReducemFile;

/// The sections of one file that the query walks prefetch from, looked up once for a batch of
/// queries rather than per ray or point.
#[derive(Clone, Copy)]
pub(crate) struct QuerySections<'a>(StripSections<'a>);

impl<'a> QuerySections<'a> {
    pub(crate) fn new(file: &'a ReducemFile) -> QuerySections<'a> {
        QuerySections(StripSections::new(file))
    }

    /// [`ReducemFile::leaf_strips`] from the strip records looked up with the sections, not per
    /// leaf.
    #[inline(always)]
    pub(crate) fn leaf_strips(&self, first: u32, count: u32) -> std::ops::Range<u32> {
        self.0.leaf_strips(first, count)
    }
}

/// What a query walk over `nodes` (one file's top-level nodes) prefetches from.
pub(crate) struct ChildPrefetch<'a, N>(Targets<'a, N>);

impl<'a, N> ChildPrefetch<'a, N> {
    #[inline(always)]
    pub(crate) fn new(sections: &QuerySections<'a>, nodes: &'a [N]) -> ChildPrefetch<'a, N> {
        ChildPrefetch(Targets::new(&sections.0, nodes))
    }

    /// Asks for what visiting the child linked as `(child, kind)` (as a node's slot links it:
    /// an internal node's index and `INTERNAL_CHILD`, or a leaf's first strip and count)
    /// loads first.
    #[inline(always)]
    pub(crate) fn child(&self, link: (u32, u32)) {
        self.0.child(link)
    }

    /// Asks for the record of a leaf's first strip `first` alone, no load waiting on it.
    #[inline(always)]
    pub(crate) fn leaf_record(&self, first: u32) {
        self.0.strip_record(first as usize)
    }

    /// Asks for the block of a leaf's first strip `first`, which its record (asked for by
    /// [`ChildPrefetch::leaf_record`] some steps before) locates.
    #[inline(always)]
    pub(crate) fn leaf_block(&self, first: u32) {
        self.0.block(first as usize)
    }
}

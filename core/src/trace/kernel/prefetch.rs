//! Software prefetches for the traversal's dependent loads. On a model much larger than the
//! caches the walks wait on memory more than they compute: a child's node, a leaf's strip record
//! and then the strip's block are each loaded only once the load before it has arrived. Asking
//! for them when a child is clipped, before the walk reaches it, overlaps those waits with the
//! rest of the walk. Both walks and every kernel prefetch the same way (the figures are in the
//! commits that added each prefetch).
//!
//! A prefetch reads nothing into the program and faults on no address, whatever the address, so
//! the pointers here may point anywhere; it needs no detection (SSE is in x86-64's baseline,
//! `prfm` in every aarch64 CPU).

#![allow(unsafe_code)]

use crate::format::reader::ReducemFile;
use crate::format::{SectionKind, StripRecord, F32_VERTEX_BYTES, INTERNAL_CHILD};

/// Most cache lines of a strip's block prefetched from its start ([`lines`]): 512 bytes hold a
/// lossless block of the pipeline's strips (at most 22 vertices, 264 bytes, and its
/// [`BLOCK_TAIL_BYTES`]).
const MAX_LINES: usize = 8;

/// More than the references, split axes and block boxes of a strip of the pipeline's length
/// take (22 packed references of 5 bits, one byte of axes, 12 bytes of boxes).
const BLOCK_TAIL_BYTES: usize = 48;

/// A file's strip records and strip data, looked up once per tracer rather than per walk.
#[derive(Clone, Copy)]
pub(in crate::trace) struct StripSections<'a> {
    records: &'a [StripRecord],
    data: &'a [u8],
}

impl<'a> StripSections<'a> {
    pub(in crate::trace) fn new(file: &'a ReducemFile) -> StripSections<'a> {
        StripSections {
            records: file.strip_records(),
            data: file.section_bytes(SectionKind::StripData),
        }
    }

    /// [`ReducemFile::leaf_strips`] from the records at hand, not looked up per leaf.
    #[inline(always)]
    pub(in crate::trace) fn leaf_strips(&self, first: u32, count: u32) -> std::ops::Range<u32> {
        let end = first.saturating_add(count).min(self.records.len() as u32);
        first.min(end)..end
    }
}

/// What a walk over `nodes` (one file's top-level nodes) prefetches from.
pub(in crate::trace) struct Targets<'a, N> {
    nodes: &'a [N],
    records: &'a [StripRecord],
    data: &'a [u8],
}

impl<'a, N> Targets<'a, N> {
    pub(in crate::trace) fn new(strips: &StripSections<'a>, nodes: &'a [N]) -> Targets<'a, N> {
        Targets {
            nodes,
            records: strips.records,
            data: strips.data,
        }
    }

    /// Asks for what visiting the child `(child, kind)` (as a node's slot links it) loads
    /// first: an internal child's node; a leaf's first strip record and that strip's block,
    /// which the record locates. (Asking again when the strip is viewed gained nothing.)
    #[inline(always)]
    pub(in crate::trace) fn child(&self, (child, kind): (u32, u32)) {
        if kind == INTERNAL_CHILD {
            record(self.nodes, child as usize);
        } else {
            self.block(child as usize);
        }
    }

    /// Asks for strip `strip`'s record alone, not the block it locates: a walk that views the
    /// strip later asks for the block once the record has arrived ([`Targets::block`]).
    #[inline(always)]
    pub(in crate::trace) fn strip_record(&self, strip: usize) {
        record(self.records, strip);
    }

    /// The lines of strip `strip`'s block from its start, its length estimated from its record
    /// as a lossless block's: its vertices and [`BLOCK_TAIL_BYTES`].
    #[inline(always)]
    pub(in crate::trace) fn block(&self, strip: usize) {
        let Some(record) = self.records.get(strip) else {
            return;
        };
        let first = self
            .data
            .as_ptr()
            .wrapping_add(record.data_word as usize * 4);
        let length = record.vertex_count as usize * F32_VERTEX_BYTES + BLOCK_TAIL_BYTES;
        lines(first, first.wrapping_add(length));
    }
}

/// Asks for record `index` of `records`; `index` may be out of bounds.
#[inline(always)]
fn record<T>(records: &[T], index: usize) {
    let start = records.as_ptr().wrapping_add(index).cast::<u8>();
    for offset in (0..std::mem::size_of::<T>()).step_by(64) {
        line(start.wrapping_add(offset));
    }
}

/// Asks for the cache lines from `first` on, at most [`MAX_LINES`] of them until the one
/// holding `last`, and that one.
#[inline(always)]
fn lines(first: *const u8, last: *const u8) {
    let mut next = first;
    for _ in 0..MAX_LINES {
        line(next);
        next = next.wrapping_add(64);
        if next >= last {
            break;
        }
    }
    line(last);
}

/// Asks for the cache line holding `address` into every cache level (`prefetcht0`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn line(address: *const u8) {
    use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
    // SAFETY: a prefetch reads nothing and faults on no address; SSE is in the baseline.
    unsafe { _mm_prefetch::<_MM_HINT_T0>(address.cast::<i8>()) };
}

/// Asks for the cache line holding `address` into the first-level data cache (`prfm pldl1keep`;
/// the intrinsic is not stable yet).
#[cfg(target_arch = "aarch64")]
#[inline(always)]
fn line(address: *const u8) {
    // SAFETY: `prfm` reads nothing into a register, writes nothing and faults on no address.
    unsafe {
        std::arch::asm!(
            "prfm pldl1keep, [{address}]",
            address = in(reg) address,
            options(nostack, preserves_flags, readonly)
        )
    };
}

/// No prefetch elsewhere: the walks give the same answers without it.
#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
#[inline(always)]
fn line(_address: *const u8) {}

//! Software prefetches for the traversal's dependent loads (`_mm_prefetch`). On a model much
//! larger than the caches the walks wait on memory more than they compute: a child's node, a
//! leaf's strip record and then the strip's block are each loaded only once the load before it
//! has arrived. Asking for them when a child is clipped, before the walk reaches it, overlaps
//! those waits with the rest of the walk.
//!
//! Both walks and every kernel prefetch the same way ([`Targets::child`] has the AVX2 packets'
//! figures). With the baseline SSE2 kernel, 1,048,576 camera rays four times over on the 10M
//! scan took 1,093 -> 936 ms of CPU and 3.8M AO rays 2,417 -> 1,967 ms (`reducem query`, 1
//! thread, `perf stat` task-clock, medians of 3 alternating runs); single rays
//! (`examples/bench_trace.rs`, AVX2, 1 thread, 10M scan) 4.18 -> 4.46 Mrays/s on camera rays,
//! 1.96 on AO rays either way.
//!
//! `_mm_prefetch` is an SSE instruction, which every x86-64 CPU has (the target's baseline), so
//! no detection precedes it; a prefetch reads nothing into the program and faults on no address,
//! whatever the address, so the pointers here may point anywhere.

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

/// What a walk over `nodes` (one file's top-level nodes) prefetches from.
pub(super) struct Targets<'a, N> {
    nodes: &'a [N],
    records: &'a [StripRecord],
    data: &'a [u8],
}

impl<'a, N> Targets<'a, N> {
    pub(super) fn new(file: &'a ReducemFile, nodes: &'a [N]) -> Targets<'a, N> {
        Targets {
            nodes,
            records: file.strip_records(),
            data: file.section_bytes(SectionKind::StripData),
        }
    }

    /// Asks for what visiting the child `(child, kind)` (as a node's slot links it) loads
    /// first: an internal child's node; a leaf's first strip record and that strip's block,
    /// which the record locates.
    ///
    /// Child nodes: 3.8M AO rays on the 1M scan, one thread, 1,292 -> 1,264 ms of CPU for 3
    /// more instructions a ray. Records and blocks (`reducem query`, 1 thread, `perf stat`
    /// task-clock, medians of 5 alternating runs): 1,048,576 camera rays four times over on the
    /// 10M scan, the record alone 751 -> 721 ms, the block too 709 -> 665 ms; with 2 threads
    /// the whole `reducem query` of them 108.8 -> 103.9 ms of wall time; AO rays and the 1M
    /// scan unchanged (10M AO 1,200 ms with the record alone, 1,196 with the block).
    ///
    /// Asking again for the block's lines when the strip is viewed, which paid before the
    /// block was asked for at clip time (765 -> 690 ms), gained nothing since: 670 against 665
    /// ms without it, AO 1,196 against 1,185.
    #[inline(always)]
    pub(super) fn child(&self, (child, kind): (u32, u32)) {
        if kind == INTERNAL_CHILD {
            record(self.nodes, child as usize);
        } else {
            self.block(child as usize);
        }
    }

    /// The lines of strip `strip`'s block from its start, its length estimated from its record
    /// as a lossless block's: its vertices and [`BLOCK_TAIL_BYTES`].
    #[inline(always)]
    fn block(&self, strip: usize) {
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

/// Asks for the cache line holding `address` (SSE's `prefetcht0`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn line(address: *const u8) {
    use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
    // SAFETY: a prefetch reads nothing and faults on no address; SSE is in the baseline.
    unsafe { _mm_prefetch::<_MM_HINT_T0>(address.cast::<i8>()) };
}

/// No prefetch off x86-64: the walks give the same answers without it.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn line(_address: *const u8) {}

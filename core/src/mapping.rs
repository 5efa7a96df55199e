//! The project's one memory mapping of a file.

use std::fs::File;
use std::io;

use memmap2::{Mmap, MmapOptions};

/// Maps all of `file` read-only.
pub fn map_file(file: &File) -> io::Result<Mmap> {
    let length = file.metadata()?.len();
    let length = usize::try_from(length).map_err(|_| io::Error::other("file too large to map"))?;
    map_range(file, 0, length)
}

/// Maps `length` bytes of `file` from `offset` read-only. Out-of-core passes map one window at a
/// time and drop it before the next, so resident memory stays bounded by the window size rather
/// than the file size.
///
/// # Safety
/// The project's one `unsafe` call outside the SIMD kernel module (`trace/avx2.rs`) and the
/// report's Embree adapter (`embree_peer.rs`, behind the `embree` feature, whose C callback
/// counts Embree's allocations): `reducem-core` and `reducem` deny `unsafe_code` everywhere
/// else. A mapping is undefined behaviour if another
/// process truncates or rewrites the file while it is mapped. ReduceM files and pipeline outputs
/// are only ever replaced by atomic rename, never modified in place, so a live mapping keeps
/// seeing the old inode; inputs belong to the user, who must not edit them during a run. Every
/// reader bounds-checks against the mapped length and never trusts the content, so a file that
/// is corrupt (rather than concurrently modified) cannot cause out-of-bounds reads.
#[allow(unsafe_code)]
pub fn map_range(file: &File, offset: u64, length: usize) -> io::Result<Mmap> {
    let mut options = MmapOptions::new();
    options.offset(offset).len(length);
    // SAFETY: see the function documentation; files are replaced by rename, never in place.
    unsafe { options.map(file) }
}

/// Advises the kernel that `map` will be read at scattered pages (madvise random): a page fault
/// then reads the page alone instead of the read-around window (`read_ahead_kb` of the device,
/// 128 KiB by default, 8 MiB on some virtual disks) around it.
pub fn advise_scattered_reads(map: &Mmap) {
    // A hint only: a kernel that refuses it pages as it would have without, so the error has no
    // consequence for correctness.
    let _ = map.advise(memmap2::Advice::Random);
}

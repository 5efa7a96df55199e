//! The project's one memory mapping of a file.

use std::fs::{self, File};
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
/// One of the project's few `unsafe` calls (with [`drop_cached_pages`] and [`release_pages`])
/// outside the tracer's SIMD kernel modules (`trace/kernel/`), besides the signal handling of
/// `signals` and the report's Embree adapter (`embree_peer.rs`, behind the `embree` feature,
/// whose C callback counts Embree's allocations): `reducem-core` and `reducem` deny
/// `unsafe_code` everywhere else. A mapping is undefined behaviour if another process truncates
/// or rewrites the file while it is mapped. ReduceM files and pipeline outputs are only ever
/// replaced by atomic rename, never modified in place, so a live mapping keeps
/// seeing the old inode; inputs belong to the user, who must not edit them during a run. Every
/// reader bounds-checks against the mapped length and never trusts the content, so a file that
/// is corrupt (rather than concurrently modified) cannot cause out-of-bounds reads. A file
/// truncated under the mapping anyway faults with SIGBUS; the mapping is noted so that the
/// handler of `signals` names the file.
#[allow(unsafe_code)]
pub fn map_range(file: &File, offset: u64, length: usize) -> io::Result<Mmap> {
    let mut options = MmapOptions::new();
    options.offset(offset).len(length);
    // SAFETY: see the function documentation; files are replaced by rename, never in place.
    let map = unsafe { options.map(file) }?;
    crate::signals::note_mapping(map.as_ptr(), map.len(), file);
    Ok(map)
}

/// Advises the kernel that `map` will be read at scattered pages (madvise random): a page fault
/// then reads the page alone instead of the read-around window (`read_ahead_kb` of the device,
/// 128 KiB by default, 8 MiB on some virtual disks) around it, and not the 2 MiB folio that
/// [`advise_default_reads`]' huge pages would read.
pub fn advise_scattered_reads(map: &Mmap) {
    // A hint only: a kernel that refuses it pages as it would have without, so the error has no
    // consequence for correctness.
    let _ = map.advise(memmap2::Advice::Random);
    advise_huge_pages(map, false);
}

/// Advises the kernel that `map` will be read as it would be by default (madvise normal), with
/// the read-around window, in 2 MiB pages where the page cache holds (or reads) 2 MiB folios:
/// walks over the whole file miss the TLB far less.
pub fn advise_default_reads(map: &Mmap) {
    // A hint only, as above.
    let _ = map.advise(memmap2::Advice::Normal);
    advise_huge_pages(map, true);
}

#[cfg(target_os = "linux")]
fn advise_huge_pages(map: &Mmap, huge: bool) {
    let advice = match huge {
        true => memmap2::Advice::HugePage,
        false => memmap2::Advice::NoHugePage,
    };
    // A hint only, as above (kernels without transparent huge pages refuse it).
    let _ = map.advise(advice);
}

/// Elsewhere the kernel picks the page size alone.
#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_map: &Mmap, _huge: bool) {}

/// Offsets of [`release_pages`] are rounded to this, a multiple of every page size in use.
const RELEASE_ALIGN: usize = 1 << 16;

/// Releases the pages of `map` that lie wholly in its bytes `range` (madvise DONTNEED, rounded
/// inwards to [`RELEASE_ALIGN`]) once nothing more is read from them: unmapping them then costs
/// the caller nothing at the end. A hint: a later read of them reads the file's page again.
#[cfg(unix)]
#[allow(unsafe_code)]
pub fn release_pages(map: &Mmap, range: std::ops::Range<usize>) {
    let start = range.start.next_multiple_of(RELEASE_ALIGN);
    let end = range.end.min(map.len()) / RELEASE_ALIGN * RELEASE_ALIGN;
    if start < end {
        // SAFETY: `map` maps a file shared and read-only: a released page is read again from
        // the file, whose bytes do not change while mapped (see `map_range`), so references
        // into the mapping keep seeing the same bytes.
        let advised = unsafe {
            map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, start, end - start)
        };
        // A hint only, as above.
        let _ = advised;
    }
}

/// Without madvise, the pages stay mapped until the mapping is dropped.
#[cfg(not(unix))]
pub fn release_pages(_map: &Mmap, _range: std::ops::Range<usize>) {}

/// Asks the kernel to drop `file`'s clean pages from the page cache (fadvise DONTNEED); the
/// file's contents stay as they are. A hint: a kernel that refuses it keeps the pages.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn drop_cached_pages(file: &File) {
    use std::os::fd::AsRawFd;
    // SAFETY: fadvise reads and writes no memory of this process, and `file` stays open for the
    // call.
    let _ = unsafe { libc::posix_fadvise(file.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
}

/// Without fadvise, the pages are left to the kernel.
#[cfg(not(target_os = "linux"))]
pub fn drop_cached_pages(_file: &File) {}

/// Allocates the blocks of `file`'s first `bytes` bytes before they are written (fallocate,
/// keeping the file's size), so that each written page need not reserve its block. A hint: a
/// file system that cannot allocate ahead allocates as the pages are written.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn allocate_ahead(file: &File, bytes: u64) {
    use std::os::fd::AsRawFd;
    let Ok(length) = libc::off_t::try_from(bytes) else {
        return;
    };
    // SAFETY: fallocate reads and writes no memory of this process, and `file` stays open for
    // the call.
    let _ = unsafe { libc::fallocate(file.as_raw_fd(), libc::FALLOC_FL_KEEP_SIZE, 0, length) };
}

/// Without fallocate, blocks are allocated as the pages are written.
#[cfg(not(target_os = "linux"))]
pub fn allocate_ahead(_file: &File, _bytes: u64) {}

/// Supplies the pages of `memory` (anonymous, page-aligned) before it is written, in one call
/// rather than a fault a page (MADV_POPULATE_WRITE). A hint: a kernel before 5.14 refuses it,
/// and the pages then fault in as they are written.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn populate_for_writing<T>(memory: &mut [std::mem::MaybeUninit<T>]) {
    let bytes = std::mem::size_of_val(memory);
    // SAFETY: the advice covers exactly the memory this exclusive borrow holds; populating
    // only maps its pages writable and leaves their contents as they are.
    let _ = unsafe { libc::madvise(memory.as_mut_ptr().cast(), bytes, libc::MADV_POPULATE_WRITE) };
}

/// Without MADV_POPULATE_WRITE, the pages fault in as they are written.
#[cfg(not(target_os = "linux"))]
pub fn populate_for_writing<T>(_memory: &mut [std::mem::MaybeUninit<T>]) {}

/// Writes all of `parts`, one after the other, from `offset` of `file`: one pwritev for up to
/// [`VECTORED_PARTS`] of them, again for what a short write left.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn write_all_vectored_at(
    file: &File,
    mut parts: &mut [io::IoSlice<'_>],
    mut offset: u64,
) -> io::Result<()> {
    use std::os::fd::AsRawFd;
    while !parts.is_empty() {
        let at = libc::off_t::try_from(offset).map_err(io::Error::other)?;
        let count = parts.len().min(VECTORED_PARTS) as libc::c_int;
        // SAFETY: an IoSlice has an iovec's layout on Unix; the kernel only reads the first
        // `count` of them and the bytes they describe, all borrowed for the call, and `file`
        // stays open for it.
        let wrote = unsafe { libc::pwritev(file.as_raw_fd(), parts.as_ptr().cast(), count, at) };
        if wrote < 0 {
            let error = io::Error::last_os_error();
            if error.kind() == io::ErrorKind::Interrupted {
                continue;
            }
            return Err(error);
        }
        if wrote == 0 {
            return Err(io::ErrorKind::WriteZero.into());
        }
        offset += wrote as u64;
        io::IoSlice::advance_slices(&mut parts, wrote as usize);
    }
    Ok(())
}

/// Parts one pwritev takes at most: Linux's IOV_MAX.
#[cfg(target_os = "linux")]
const VECTORED_PARTS: usize = 1024;

/// Without pwritev, one write per part.
#[cfg(not(target_os = "linux"))]
pub fn write_all_vectored_at(
    file: &File,
    parts: &mut [io::IoSlice<'_>],
    mut offset: u64,
) -> io::Result<()> {
    for part in parts.iter() {
        crate::atomic::write_all_at(file, part, offset)?;
        offset += part.len() as u64;
    }
    Ok(())
}

/// The memory the kernel reports it could give without swapping (`MemAvailable` of
/// `/proc/meminfo`, free pages plus reclaimable page cache), or `None` where there is no such
/// file (not Linux) or it does not say.
pub fn available_memory_bytes() -> Option<u64> {
    parse_available_memory(&fs::read_to_string("/proc/meminfo").ok()?)
}

fn parse_available_memory(meminfo: &str) -> Option<u64> {
    let line = meminfo
        .lines()
        .find_map(|line| line.strip_prefix("MemAvailable:"))?;
    let kib = line.trim().strip_suffix("kB")?.trim().parse::<u64>().ok()?;
    kib.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn available_memory_is_read_in_bytes() {
        let meminfo = "MemTotal:       24683860 kB\nMemFree:         9520000 kB\n\
                       MemAvailable:    3145728 kB\nBuffers:            1234 kB\n";
        assert_eq!(parse_available_memory(meminfo), Some(3 << 30));
        assert_eq!(parse_available_memory("MemTotal: 1 kB\n"), None);
        assert_eq!(parse_available_memory("MemAvailable: lots\n"), None);
    }
}

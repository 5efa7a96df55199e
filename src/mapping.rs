//! The project's one memory mapping of a file.

use std::fs::File;
use std::io;

use memmap2::Mmap;

/// Maps `file` read-only.
///
/// # Safety
/// This is the only `unsafe` call in the project. A mapping is undefined behaviour if another
/// process truncates or rewrites the file while it is mapped. ReduceM files and pipeline outputs
/// are only ever replaced by atomic rename, never modified in place, so a live mapping keeps
/// seeing the old inode; inputs belong to the user, who must not edit them during a run. Every
/// reader bounds-checks against the mapped length and never trusts the content, so a file that
/// is corrupt (rather than concurrently modified) cannot cause out-of-bounds reads.
pub fn map_file(file: &File) -> io::Result<Mmap> {
    // SAFETY: see the function documentation; files are replaced by rename, never in place.
    unsafe { Mmap::map(file) }
}

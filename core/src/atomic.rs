//! Atomic file replacement: every output of the project is written through here, so a crash, a
//! kill or a full disk never leaves a half-written file under a final name, and never destroys an
//! earlier good file. Outputs written in one call use [`write_atomically`]; a writer that streams
//! its output over many calls (`pipeline gen`) writes to [`temporary_path`], syncs it and moves it
//! into place with [`replace`].

use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TryRecvError};
use std::sync::Mutex;
use std::thread::Thread;

/// `dir/.name.tmp-PID`: same directory, so the rename is atomic; hidden, so globs skip it; the
/// owner's pid, so a later run can tell a dead process's temporary from a live one's. The path
/// is noted as this process's, so that SIGINT or SIGTERM removes it (`signals`).
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let temporary = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    crate::signals::note_temporary(&temporary);
    temporary
}

/// A file name's owner pid and the name it is a temporary of (`.out.rdm.tmp-PID` gives `PID`
/// and `out.rdm`; a temporary of a temporary gives the innermost name), or `None` when the name
/// is not a temporary's.
fn temporary_owner(file_name: &str) -> Option<(u32, &str)> {
    let hidden = file_name.strip_prefix('.')?;
    let (_, pid) = hidden.rsplit_once(".tmp-")?;
    let pid = pid
        .parse()
        .ok()
        .filter(|_| pid.bytes().all(|b| b.is_ascii_digit()))?;
    let (name, _) = hidden.trim_start_matches('.').split_once(".tmp-")?;
    Some((pid, name))
}

/// Removes the temporaries in `dir` whose owner process is gone (killed before it could remove
/// them): all of them, or with `of` only those of that file name. Returns the removed paths
/// with their sizes.
pub fn remove_dead_temporaries(dir: &Path, of: Option<&str>) -> io::Result<Vec<(PathBuf, u64)>> {
    let mut removed = Vec::new();
    let entries = match fs::read_dir(dir) {
        Err(error) if error.kind() == io::ErrorKind::NotFound => return Ok(removed),
        entries => entries?,
    };
    for entry in entries {
        let entry = entry?;
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let Some((owner, name)) = temporary_owner(&file_name) else {
            continue;
        };
        let ours = owner == std::process::id();
        if ours || of.is_some_and(|of| of != name) || crate::signals::process_alive(owner) {
            continue;
        }
        let bytes = entry.metadata().map_or(0, |meta| meta.len());
        match fs::remove_file(entry.path()) {
            Err(error) if error.kind() != io::ErrorKind::NotFound => return Err(error),
            _ => removed.push((entry.path(), bytes)),
        }
    }
    Ok(removed)
}

/// Writes `path` through a temporary file in the same directory, fsyncs it, renames it into place
/// and fsyncs the directory. On any error the temporary is removed and an existing file at `path`
/// is untouched.
pub fn write_atomically(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    write_atomically_with(path, body)
}

/// [`write_atomically`] with a body that returns a value, or fails with an error of its own
/// (say, the input turned out corrupt after the output was begun): nothing is then renamed.
pub fn write_atomically_with<T, E: From<io::Error>>(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> Result<T, E>,
) -> Result<T, E> {
    let temporary = temporary_path(path);
    let written = std::thread::scope(|scope| {
        let evicting = is_large_file(path).then(|| scope.spawn(|| evict_cached_pages(path)));
        let written = write_and_sync(&temporary, body);
        if let Some(evicting) = evicting {
            let _ = evicting.join();
        }
        written
    });
    let result =
        written.and_then(|value| replace(&temporary, path).map_err(E::from).map(|()| value));
    if result.is_err() {
        let _ = fs::remove_file(&temporary);
    }
    result
}

/// Replaced files at least this large have their cached pages dropped while the new file is
/// written ([`evict_cached_pages`]); a smaller one is not worth starting a thread for.
const EVICT_BYTES: u64 = 1 << 22;

fn is_large_file(path: &Path) -> bool {
    fs::metadata(path).is_ok_and(|metadata| metadata.is_file() && metadata.len() >= EVICT_BYTES)
}

/// Drops the cached pages of the file at `path`, which is about to be replaced, from the page
/// cache: the rename that replaces it frees them otherwise, while the process waits for it (a
/// 64 MiB hit file: about half the rename's time). The file's contents are untouched.
fn evict_cached_pages(path: &Path) {
    if let Ok(file) = File::open(path) {
        crate::mapping::drop_cached_pages(&file);
    }
}

/// Bytes a buffered output is written in: whole multiples of 2 MiB at offsets that are, so that
/// the page cache holds a freshly written file (a converted model) in 2 MiB folios, which the
/// tracer's mapping then maps with 2 MiB pages (fewer TLB misses over the whole file).
const WRITE_RUN_BYTES: usize = 4 << 20;

/// A writer over [`write_atomically`]'s buffered output that lets it reach the file only in
/// whole buffers ([`WRITE_RUN_BYTES`] at offsets that are multiples of it), however its writes
/// are cut: a plain `BufWriter` passes on a partial buffer before a write that does not fit, and
/// every run after it would start off the 2 MiB boundaries.
pub struct WholeRuns<'a>(pub &'a mut BufWriter<File>);

impl Write for WholeRuns<'_> {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let capacity = self.0.capacity();
        if self.0.buffer().len() == capacity {
            self.0.flush()?;
        }
        let room = capacity - self.0.buffer().len();
        if room == capacity && bytes.len() >= capacity {
            let whole = bytes.len() - bytes.len() % capacity;
            self.0.get_mut().write_all(&bytes[..whole])?;
            return Ok(whole);
        }
        self.0.write(&bytes[..bytes.len().min(room)])
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()
    }
}

fn write_and_sync<T, E: From<io::Error>>(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> Result<T, E>,
) -> Result<T, E> {
    let mut out = BufWriter::with_capacity(WRITE_RUN_BYTES, File::create(path)?);
    let value = body(&mut out)?;
    out.flush()?;
    out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
    Ok(value)
}

/// Runs `write`, which writes `file` and reports each write's byte count to the function it is
/// given, while another thread syncs the file's data to disk each time [`BACKGROUND_SYNC_BYTES`]
/// more bytes were written: the final fsync of [`write_atomically`] then flushes only the tail,
/// instead of the whole file after the work is done (a 67 MB hit file: 28-31 ms of fsync on the
/// test machine's virtual disk; far more on a spinning one). Durability is unchanged: only the
/// final fsync, before the rename, is relied on.
pub fn write_syncing_behind<T>(
    file: &File,
    write: impl FnOnce(&(dyn Fn(usize) + Sync)) -> io::Result<T>,
) -> io::Result<T> {
    let written = AtomicUsize::new(0);
    let done = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let syncer = scope.spawn(|| sync_behind(file, &written, &done));
        let wake = syncer.thread().clone();
        let count = |bytes: usize| {
            let before = written.fetch_add(bytes, Ordering::Release);
            if (before + bytes) / BACKGROUND_SYNC_BYTES != before / BACKGROUND_SYNC_BYTES {
                wake.unpark();
            }
        };
        let result = write(&count);
        done.store(true, Ordering::Release);
        wake.unpark();
        let synced = syncer
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        let value = result?;
        synced.map(|()| value)
    })
}

/// Bytes written between two background syncs of [`write_syncing_behind`]: at most what is
/// left to flush when the writing ends, which the final fsync then waits for. With 8 MiB, a
/// `reducem query` of 1M camera rays (a 16 MiB hit file, 2 threads) took 0.212 s (median of 15
/// alternating runs) while other jobs wrote to the same disk, and 0.160 s with 1 MiB; on an idle
/// disk 0.068 and 0.067 s.
pub const BACKGROUND_SYNC_BYTES: usize = 1 << 20;

/// The syncing thread of [`write_syncing_behind`]: syncs whenever a step more was written,
/// until `done`.
fn sync_behind(file: &File, written: &AtomicUsize, done: &AtomicBool) -> io::Result<()> {
    let mut synced = 0;
    while !done.load(Ordering::Acquire) {
        let now = written.load(Ordering::Acquire);
        if now - synced >= BACKGROUND_SYNC_BYTES {
            file.sync_data()?;
            synced = now;
        } else {
            std::thread::park();
        }
    }
    Ok(())
}

/// Runs `produce`, which hands blocks of `file` to the [`WriteBehind`] it is given, while
/// another thread writes them at their offsets (and [`write_syncing_behind`] syncs them): the
/// threads that produce the bytes never wait on the file's locks. A buffered write takes the
/// file's inode lock, and on ext4 its block reservation waits for the lock that background
/// writeback holds while it allocates blocks; with two threads writing their own blocks, one
/// stalled there (60 ms at a time on a busy disk) stalled the other on the inode lock. The
/// writing thread first allocates the file's first `bytes_ahead` bytes
/// ([`crate::mapping::allocate_ahead`]), off the producers' way: 0.1 to 7 ms for 64 MiB. The
/// writing thread's error, if any, is returned first.
pub fn write_behind<T>(
    file: &File,
    bytes_ahead: u64,
    produce: impl FnOnce(&WriteBehind) -> io::Result<T>,
) -> io::Result<T> {
    write_syncing_behind(file, |written| {
        let spare = Mutex::new(Vec::new());
        let (blocks, queued) = mpsc::sync_channel(WRITE_BEHIND_BLOCKS);
        std::thread::scope(|scope| {
            let writer = scope.spawn(|| {
                crate::mapping::allocate_ahead(file, bytes_ahead);
                write_queued(file, queued, &spare, written)
            });
            let behind = WriteBehind {
                blocks: Some(blocks),
                spare: &spare,
                writer: writer.thread().clone(),
                queued: AtomicUsize::new(0),
                queued_bytes: AtomicUsize::new(0),
            };
            let result = produce(&behind);
            drop(behind);
            let wrote = writer
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            wrote.and(result)
        })
    })
}

/// Blocks queued for [`write_behind`]'s writing thread at most, after which the producers
/// wait: 16 MiB of `reducem query`'s 64 KiB blocks of hits, what 2 threads trace in about 100 ms
/// on the 10M scan, more than the longest stall of the writing thread seen (60 ms; 64 blocks
/// let the tracing threads wait 50 ms). A buffer is allocated only when none is spare, so the
/// queue's memory is taken only while the disk falls behind.
const WRITE_BEHIND_BLOCKS: usize = 256;

/// Blocks queued between two wakes of [`write_behind`]'s writing thread at most: a quarter of
/// what the queue holds, so that it is woken well before the producers would wait on a full
/// queue.
const WAKE_BLOCKS: usize = WRITE_BEHIND_BLOCKS / 4;

/// Where the producers of [`write_behind`] hand their blocks.
pub struct WriteBehind<'a> {
    /// Taken when dropped, which tells the writing thread that no more blocks come.
    blocks: Option<SyncSender<(u64, Block)>>,
    /// Buffers whose bytes were written, for the producers to fill again.
    spare: &'a Mutex<Vec<Block>>,
    /// Woken each time a run's bytes ([`RUN_BYTES`]) or [`WAKE_BLOCKS`] blocks more were
    /// queued, and at the end, rather than after each block: each wake preempted a producer
    /// (3,700 times in a run of 15M occlusion rays, whose blocks are 4 KiB). It polls the
    /// queue and parks rather than waiting on the channel, so that a send never takes the
    /// channel's lock of waiting receivers: under load, a preempted writer holding that lock
    /// stalled the tracing threads (120-160 ms a run).
    writer: Thread,
    /// Blocks and bytes queued so far.
    queued: AtomicUsize,
    queued_bytes: AtomicUsize,
}

impl WriteBehind<'_> {
    /// A buffer to fill: one whose bytes were written already (its length and contents as they
    /// were), else a new one. Never waits: a new one while the writing thread holds the spares.
    pub fn buffer(&self) -> Block {
        let spare = self.spare.try_lock().ok().and_then(|mut spare| spare.pop());
        spare.unwrap_or_default()
    }

    /// Queues `bytes` to be written at `offset`; fails once the writing thread stopped on an
    /// error (which [`write_behind`] then returns).
    pub fn write_at(&self, bytes: Block, offset: u64) -> io::Result<()> {
        let len = bytes.len();
        let sent = self
            .blocks
            .as_ref()
            .map(|blocks| blocks.send((offset, bytes)));
        let blocks = self.queued.fetch_add(1, Ordering::Relaxed) + 1;
        let before = self.queued_bytes.fetch_add(len, Ordering::Relaxed);
        if blocks.is_multiple_of(WAKE_BLOCKS) || (before + len) / RUN_BYTES != before / RUN_BYTES {
            self.writer.unpark();
        }
        match sent {
            Some(Ok(())) => Ok(()),
            _ => Err(io::Error::other("the writing thread stopped")),
        }
    }
}

impl Drop for WriteBehind<'_> {
    /// Disconnects the queue, then wakes the writing thread to see it (also when a producer
    /// panicked, which would otherwise leave it parked and the scope waiting for it).
    fn drop(&mut self) {
        drop(self.blocks.take());
        self.writer.unpark();
    }
}

/// The writing thread of [`write_behind`]: writes each queued block at its offset, counts it
/// for the syncing thread and keeps its buffer for the producers, until they are done.
fn write_queued(
    file: &File,
    queued: Receiver<(u64, Block)>,
    spare: &Mutex<Vec<Block>>,
    written: &(dyn Fn(usize) + Sync),
) -> io::Result<()> {
    let mut out = BlockWriter::start(file, written, spare);
    loop {
        let (offset, block) = match queued.try_recv() {
            Ok(block) => block,
            Err(TryRecvError::Empty) => {
                std::thread::park();
                continue;
            }
            Err(TryRecvError::Disconnected) => return out.finish(),
        };
        out.write(block, offset)?;
    }
}

/// Bytes of consecutive blocks that [`BlockWriter`] gathers into one vectored write: a run of
/// 64 KiB blocks takes one system call instead of sixteen.
const RUN_BYTES: usize = 1 << 20;

/// Runs of consecutive blocks [`BlockWriter`] gathers at once: the tracing threads each finish
/// chunks in their own stretch of the file.
const OPEN_RUNS: usize = 4;

/// Bytes of a [`Page`]: the smallest page size of the systems built for.
const PAGE_BYTES: usize = 4096;

/// One page of a [`Block`], page-aligned so that its pages can be populated in one call.
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(4096))]
struct Page([u8; PAGE_BYTES]);

/// A buffer of [`write_behind`]'s producers, in whole pages, which [`Block::resize`] populates
/// at once. Its length is any.
#[derive(Default)]
pub struct Block {
    pages: Vec<Page>,
    len: usize,
}

impl Block {
    /// The block of `bytes`' length holding them.
    pub fn from_bytes(bytes: &[u8]) -> Block {
        let mut block = Block::default();
        block.resize(bytes.len());
        block.copy_from_slice(bytes);
        block
    }

    /// Makes the block `len` bytes long: bytes it had stay, new ones are zero. New pages are
    /// populated in one call before they are zeroed: a run's new blocks took a page fault
    /// every 4 KiB.
    pub fn resize(&mut self, len: usize) {
        let pages = len.div_ceil(PAGE_BYTES);
        if let Some(more) = pages.checked_sub(self.pages.len()).filter(|&more| more > 0) {
            self.pages.reserve_exact(more);
            crate::mapping::populate_for_writing(&mut self.pages.spare_capacity_mut()[..more]);
        }
        self.pages.resize(pages, Page([0; PAGE_BYTES]));
        self.len = len;
    }
}

impl std::ops::Deref for Block {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.pages)[..self.len]
    }
}

impl std::ops::DerefMut for Block {
    fn deref_mut(&mut self) -> &mut [u8] {
        &mut bytemuck::cast_slice_mut(&mut self.pages)[..self.len]
    }
}

/// How [`write_queued`] writes blocks: runs of consecutive blocks in one vectored write each,
/// through the page cache, which the syncing thread flushes behind the writing. Writing past
/// the page cache (O_DIRECT) was measured slower on a virtual disk: each write waits for the
/// device, and the writing fell behind the trace (`docs/BENCHMARKS.md`, session 31).
struct BlockWriter<'a> {
    file: &'a File,
    written: &'a (dyn Fn(usize) + Sync),
    /// Where written blocks go back to the producers.
    spare: &'a Mutex<Vec<Block>>,
    /// Written blocks not handed back yet: the producers held the spares.
    unreturned: Vec<Block>,
    runs: Vec<Run>,
}

/// Consecutive blocks gathered for one vectored write, from `start` in the file.
struct Run {
    start: u64,
    blocks: Vec<Block>,
    len: usize,
}

impl Run {
    fn new(start: u64) -> Run {
        Run {
            start,
            blocks: Vec::new(),
            len: 0,
        }
    }

    fn end(&self) -> u64 {
        self.start + self.len as u64
    }
}

impl<'a> BlockWriter<'a> {
    fn start(
        file: &'a File,
        written: &'a (dyn Fn(usize) + Sync),
        spare: &'a Mutex<Vec<Block>>,
    ) -> BlockWriter<'a> {
        BlockWriter {
            file,
            written,
            spare,
            unreturned: Vec::new(),
            runs: Vec::new(),
        }
    }

    /// Writes `block` at `offset`, or gathers it for a later run's write.
    fn write(&mut self, block: Block, offset: u64) -> io::Result<()> {
        if block.len() > RUN_BYTES {
            write_all_at(self.file, &block, offset)?;
            (self.written)(block.len());
            self.recycle([block]);
            return Ok(());
        }
        let index = self.run_ending_at(offset, block.len())?;
        let run = &mut self.runs[index];
        run.len += block.len();
        run.blocks.push(block);
        Ok(())
    }

    /// Hands written blocks back to the producers; kept for the next time rather than waited
    /// for while a producer takes a spare, since a dropped block is a new one's page faults.
    fn recycle(&mut self, blocks: impl IntoIterator<Item = Block>) {
        self.unreturned.extend(blocks);
        if let Ok(mut spare) = self.spare.try_lock() {
            spare.append(&mut self.unreturned);
        }
    }

    /// The run that `len` bytes at `offset` continue, with room for them: an open one, else a
    /// new one in place of the longest once [`OPEN_RUNS`] are open.
    fn run_ending_at(&mut self, offset: u64, len: usize) -> io::Result<usize> {
        let continued = |run: &Run| run.end() == offset;
        if let Some(index) = self.runs.iter().position(continued) {
            if self.runs[index].len + len > RUN_BYTES {
                self.write_run(index)?;
            }
            return Ok(index);
        }
        if self.runs.len() < OPEN_RUNS {
            self.runs.push(Run::new(offset));
            return Ok(self.runs.len() - 1);
        }
        let longest = (0..self.runs.len())
            .max_by_key(|&index| self.runs[index].len)
            .unwrap_or_default();
        self.write_run(longest)?;
        self.runs[longest].start = offset;
        Ok(longest)
    }

    /// Writes run `index`'s blocks; the run then continues after them.
    fn write_run(&mut self, index: usize) -> io::Result<()> {
        let run = &mut self.runs[index];
        let (start, len) = (run.start, run.len);
        if len == 0 {
            return Ok(());
        }
        let blocks = std::mem::take(&mut run.blocks);
        run.start += len as u64;
        run.len = 0;
        write_blocks_at(self.file, &blocks, start)?;
        (self.written)(len);
        self.recycle(blocks);
        Ok(())
    }

    /// Writes every gathered run.
    fn finish(mut self) -> io::Result<()> {
        for index in 0..self.runs.len() {
            self.write_run(index)?;
        }
        Ok(())
    }
}

/// Writes consecutive `blocks` from `offset` of `file` in one vectored write (as few as the
/// kernel takes).
fn write_blocks_at(file: &File, blocks: &[Block], offset: u64) -> io::Result<()> {
    let mut parts: Vec<io::IoSlice> = blocks.iter().map(|block| io::IoSlice::new(block)).collect();
    crate::mapping::write_all_vectored_at(file, &mut parts, offset)
}

/// Writes all of `bytes` at `offset` of `file`, leaving the file's cursor alone on Unix.
#[cfg(unix)]
pub fn write_all_at(file: &File, bytes: &[u8], offset: u64) -> io::Result<()> {
    std::os::unix::fs::FileExt::write_all_at(file, bytes, offset)
}

/// Writes all of `bytes` at `offset` of `file`.
#[cfg(windows)]
pub fn write_all_at(file: &File, mut bytes: &[u8], mut offset: u64) -> io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !bytes.is_empty() {
        match file.seek_write(bytes, offset) {
            Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
            Ok(written) => {
                bytes = &bytes[written..];
                offset += written as u64;
            }
            Err(error) if error.kind() == io::ErrorKind::Interrupted => {}
            Err(error) => return Err(error),
        }
    }
    Ok(())
}

/// Renames the synced `temporary` over `path` and fsyncs the directory, so that the rename
/// itself survives a crash.
pub fn replace(temporary: &Path, path: &Path) -> io::Result<()> {
    check_replaceable(path)?;
    fs::rename(temporary, path)?;
    sync_directory(path)
}

fn sync_directory(path: &Path) -> io::Result<()> {
    let directory = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    File::open(directory)?.sync_all()
}

/// Refuses to replace anything but a regular file (following symlinks): a rename over
/// `/dev/null`, a FIFO or a socket would put a regular file in its place (a process allowed to
/// write in `/dev` replaced `/dev/null` itself, and every later redirection to it wrote into a
/// file). A path that does not exist yet is fine.
fn check_replaceable(path: &Path) -> io::Result<()> {
    match fs::metadata(path) {
        Ok(metadata) if !metadata.is_file() => Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} is not a regular file (a device, FIFO or socket), and outputs are written \
                 through a temporary file renamed over it: name a file",
                path.display()
            ),
        )),
        _ => Ok(()),
    }
}

/// Whether `a` and `b` name one existing file: the same path after canonicalisation, or the
/// same device and inode (a symlink to it, a hard link). False when either does not exist, so a
/// new output never matches.
pub fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(meta_a), Ok(meta_b)) = (fs::metadata(a), fs::metadata(b)) else {
        return false;
    };
    same_inode(&meta_a, &meta_b) || fs::canonicalize(a).ok() == fs::canonicalize(b).ok()
}

#[cfg(unix)]
fn same_inode(a: &fs::Metadata, b: &fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    (a.dev(), a.ino()) == (b.dev(), b.ino())
}

#[cfg(not(unix))]
fn same_inode(_: &fs::Metadata, _: &fs::Metadata) -> bool {
    false
}

/// Checks, before any work is done, that [`write_atomically`] can write `path`: `path` is not a
/// directory and its directory takes a new file (the temporary file is created there and removed
/// again). Catches a missing or read-only directory in seconds instead of after hours of work.
pub fn check_writable(path: &Path) -> io::Result<()> {
    if path.is_dir() {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            format!("{} is a directory, not a file name", path.display()),
        ));
    }
    check_replaceable(path)?;
    let temporary = temporary_path(path);
    let directory = temporary
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    File::create(&temporary).map_err(|error| {
        io::Error::new(
            error.kind(),
            format!("cannot create a file in {}: {error}", directory.display()),
        )
    })?;
    // Strip tasks on other hosts may probe the same name at once (pids repeat across hosts):
    // the file being gone already is fine.
    match fs::remove_file(&temporary) {
        Err(error) if error.kind() == io::ErrorKind::NotFound => Ok(()),
        removed => removed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporaries_are_told_by_name_and_only_dead_owners_are_removed() {
        assert_eq!(temporary_owner(".out.rdm.tmp-42"), Some((42, "out.rdm")));
        assert_eq!(
            temporary_owner("..out.rdm.tmp-42.tmp-42"),
            Some((42, "out.rdm"))
        );
        assert_eq!(temporary_owner("out.rdm.tmp-42"), None);
        assert_eq!(temporary_owner(".out.rdm.tmp-4x"), None);
        assert_eq!(temporary_owner(".out.rdm"), None);
        let dir = std::env::temp_dir().join(format!("dead-temporaries-{}", std::process::id()));
        fs::create_dir_all(&dir).expect("dir");
        // A pid above the kernel's largest (2^22) names no process.
        let dead = u32::pow(2, 22) + 7;
        let own = std::process::id();
        let names = [
            format!(".out.rdm.tmp-{dead}"),
            format!(".other.rdm.tmp-{dead}"),
            format!(".out.rdm.tmp-{own}"),
            "out.rdm".to_string(),
        ];
        for name in &names {
            fs::write(dir.join(name), b"12345").expect("write");
        }
        let removed = remove_dead_temporaries(&dir, Some("out.rdm")).expect("sweep");
        assert_eq!(removed, vec![(dir.join(&names[0]), 5)]);
        let removed = remove_dead_temporaries(&dir, None).expect("sweep");
        assert_eq!(removed, vec![(dir.join(&names[1]), 5)]);
        assert!(dir.join(&names[2]).exists() && dir.join(&names[3]).exists());
        fs::remove_dir_all(&dir).expect("remove");
    }

    /// A file written across several background syncs holds exactly what was written, and the
    /// writer's value or error comes back.
    #[test]
    fn writing_while_syncing_behind_keeps_every_byte_and_the_outcome() {
        let path = std::env::temp_dir().join(format!("sync-behind-{}", std::process::id()));
        let file = File::create(&path).expect("create");
        let block: Vec<u8> = (0..1 << 20).map(|i: u32| (i % 251) as u8).collect();
        let blocks = 2 * BACKGROUND_SYNC_BYTES / block.len() + 3;
        let value = write_syncing_behind(&file, |written| {
            for _ in 0..blocks {
                (&file).write_all(&block)?;
                written(block.len());
            }
            Ok(7)
        })
        .expect("written");
        assert_eq!(value, 7);
        assert_eq!(fs::read(&path).expect("read"), block.repeat(blocks));
        let failed = write_syncing_behind(&file, |_| -> io::Result<()> {
            Err(io::Error::other("disk full"))
        });
        assert_eq!(
            failed.expect_err("the writer's error").to_string(),
            "disk full"
        );
        fs::remove_file(&path).expect("remove");
    }

    /// Hands `expected`'s blocks of `block_bytes` to `behind` from `threads` threads, thread `k`
    /// taking every `threads`th block from block `k` (last first when `reversed`).
    fn write_blocks_from_threads(
        behind: &WriteBehind,
        expected: &[u8],
        block_bytes: usize,
        threads: usize,
        reversed: bool,
    ) {
        let blocks = expected.len() / block_bytes;
        std::thread::scope(|scope| {
            for first in 0..threads {
                scope.spawn(move || {
                    let mut order: Vec<usize> = (first..blocks).step_by(threads).collect();
                    if reversed {
                        order.reverse();
                    }
                    for block in order {
                        let mut buffer = behind.buffer();
                        buffer.resize(block_bytes);
                        buffer.copy_from_slice(&expected[block * block_bytes..][..block_bytes]);
                        let offset = (block * block_bytes) as u64;
                        behind.write_at(buffer, offset).expect("queued");
                    }
                });
            }
        });
    }

    /// Blocks handed to the writing thread by several threads, in any order and more than its
    /// queue holds, land at their offsets; a failed write is the error returned.
    #[test]
    fn writing_behind_puts_every_block_at_its_offset_and_returns_the_error() {
        let path = std::env::temp_dir().join(format!("write-behind-{}", std::process::id()));
        let file = File::create(&path).expect("create");
        let (block_bytes, blocks) = (1000, 3 * WRITE_BEHIND_BLOCKS + 5);
        let expected: Vec<u8> = (0..blocks * block_bytes).map(|i| (i % 251) as u8).collect();
        let value = write_behind(&file, 0, |behind| {
            write_blocks_from_threads(behind, &expected, block_bytes, 4, true);
            Ok(7)
        })
        .expect("written");
        assert_eq!(value, 7);
        assert_eq!(fs::read(&path).expect("read"), expected);
        let read_only = File::open(&path).expect("open");
        let failed = write_behind(&read_only, 0, |behind| {
            behind.write_at(Block::from_bytes(&[1; 10]), 0)
        });
        assert!(failed.is_err());
        fs::remove_file(&path).expect("remove");
    }

    /// Blocks gathered into runs from several threads, more than the open runs hold and of a
    /// size that is no divisor of a run, then a last short block and one larger than a run,
    /// land at their offsets.
    #[test]
    fn blocks_gathered_into_runs_land_at_their_offsets() {
        let path = std::env::temp_dir().join(format!("write-runs-{}", std::process::id()));
        let file = File::create(&path).expect("create");
        let block_bytes = 3 * PAGE_BYTES + 5;
        let blocks = OPEN_RUNS * RUN_BYTES / block_bytes + 9;
        let (tail, large) = (1000, RUN_BYTES + 3);
        let total = blocks * block_bytes + tail + large;
        let expected: Vec<u8> = (0..total).map(|i| (i % 251) as u8).collect();
        write_behind(&file, total as u64, |behind| {
            let (gathered, rest) = expected.split_at(blocks * block_bytes);
            write_blocks_from_threads(behind, gathered, block_bytes, 3, false);
            let at = gathered.len() as u64;
            behind.write_at(Block::from_bytes(&rest[..tail]), at)?;
            behind.write_at(Block::from_bytes(&rest[tail..]), at + tail as u64)
        })
        .expect("written");
        assert_eq!(fs::read(&path).expect("read"), expected);
        fs::remove_file(&path).expect("remove");
    }

    /// Writes cut at any size reach the file only in whole buffers, at offsets that are
    /// multiples of the buffer, and in their order.
    #[test]
    fn whole_runs_reach_the_file_at_multiples_of_the_buffer() {
        use std::io::Seek;
        let path = std::env::temp_dir().join(format!("whole-runs-{}", std::process::id()));
        let capacity = 16;
        let mut buffered = BufWriter::with_capacity(capacity, File::create(&path).expect("create"));
        let mut runs = WholeRuns(&mut buffered);
        let mut expected = Vec::new();
        for (i, length) in [1, 7, 19, 3, 16, 40, 5, 32, 11, 2].into_iter().enumerate() {
            let bytes: Vec<u8> = (0..length).map(|k| (i * 31 + k) as u8).collect();
            runs.write_all(&bytes).expect("written");
            expected.extend_from_slice(&bytes);
            let reached = runs.0.get_mut().stream_position().expect("position");
            assert_eq!(reached % capacity as u64, 0, "after write {i}");
        }
        runs.flush().expect("flushed");
        drop(buffered);
        assert_eq!(fs::read(&path).expect("read"), expected);
        fs::remove_file(&path).expect("remove");
    }

    /// A socket (like a device or a FIFO, not a regular file) is neither accepted as an output
    /// nor replaced, and stays what it was.
    #[cfg(unix)]
    #[test]
    fn an_output_that_is_not_a_regular_file_is_refused_and_left_alone() {
        use std::os::unix::fs::FileTypeExt;
        let path = std::env::temp_dir().join(format!("not-a-file-{}.sock", std::process::id()));
        let _ = fs::remove_file(&path);
        let _socket = std::os::unix::net::UnixListener::bind(&path).expect("bind a socket");
        let refused = check_writable(&path).expect_err("a socket is not an output");
        assert!(
            refused.to_string().contains("not a regular file"),
            "{refused}"
        );
        let written = write_atomically(&path, |out| out.write_all(b"answers"));
        assert!(written.is_err());
        assert!(fs::metadata(&path)
            .expect("still there")
            .file_type()
            .is_socket());
        assert!(!temporary_path(&path).exists());
        fs::remove_file(&path).expect("remove");
    }
}

//! The work-directory lock that keeps overlapping cron runs apart.
//!
//! An advisory lock (`File::try_lock`, flock on Unix) on `<work>/lock`: the kernel drops it when
//! the holding process exits, however it dies, so a lock left by a dead process never blocks. The
//! holder writes its pid, host and start time into the file so that a second run can name it:
//! in one write over the old line, never truncating first, so a reader sees a whole line.
//! Caveat: on network filesystems flock may be per host or unsupported (see README, cluster use).

use std::fs::{File, OpenOptions};
use std::io::Read;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use anyhow::Context;

/// The work directory is locked by another live run.
#[derive(Debug, thiserror::Error)]
#[error("work directory {} is locked by another run ({holder})", dir.display())]
pub struct LockedError {
    pub dir: PathBuf,
    pub holder: String,
}

/// Held for the life of a run; dropping it (or the process dying) releases the lock.
#[derive(Debug)]
pub struct WorkLock {
    _file: File,
}

impl WorkLock {
    /// Takes the lock without waiting: shared (strip tasks of one job array, which coordinate
    /// per chunk) or exclusive (every other run).
    pub fn acquire(dir: &Path, shared: bool) -> anyhow::Result<WorkLock> {
        let path = dir.join("lock");
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("opening {}", path.display()))?;
        let attempt = if shared {
            file.try_lock_shared()
        } else {
            file.try_lock()
        };
        if let Err(error) = attempt {
            return Err(match error {
                std::fs::TryLockError::WouldBlock => LockedError {
                    dir: dir.to_path_buf(),
                    holder: read_holder(&mut file),
                }
                .into(),
                std::fs::TryLockError::Error(error) => {
                    anyhow::Error::new(error).context(format!("locking {}", path.display()))
                }
            });
        }
        let line = format!("{}\n", holder_description());
        file.write_all_at(line.as_bytes(), 0)
            .and_then(|()| file.set_len(line.len() as u64))
            .and_then(|()| file.sync_data())
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(WorkLock { _file: file })
    }
}

/// An exclusive lock on one chunk's unit, so that tasks sharing a work directory never work on
/// the same chunk.
pub struct ChunkLock {
    _file: File,
}

impl ChunkLock {
    /// `None` when another task holds the chunk.
    pub fn try_acquire(path: &Path) -> anyhow::Result<Option<ChunkLock>> {
        let file = File::create(path).with_context(|| format!("creating {}", path.display()))?;
        match file.try_lock() {
            Ok(()) => Ok(Some(ChunkLock { _file: file })),
            Err(std::fs::TryLockError::WouldBlock) => Ok(None),
            Err(std::fs::TryLockError::Error(error)) => {
                Err(anyhow::Error::new(error).context(format!("locking {}", path.display())))
            }
        }
    }
}

/// The holder's line: the first one, whole (a longer line written before may trail it until
/// the holder has cut the file to its own).
fn read_holder(file: &mut File) -> String {
    let mut text = String::new();
    let _ = file.read_to_string(&mut text);
    match text.split_once('\n') {
        Some((holder, _)) if !holder.trim().is_empty() => holder.trim().to_string(),
        _ => "holder unknown".to_string(),
    }
}

fn holder_description() -> String {
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
    format!(
        "pid {} on host {} since {}",
        std::process::id(),
        host.trim(),
        crate::time::iso8601(std::time::SystemTime::now())
    )
}

#[cfg(test)]
mod tests {
    use std::io::Seek;

    /// A reader between the holder's write and its cut of the file sees the new line whole,
    /// followed by the rest of a longer old one: it reads the first line only.
    #[test]
    fn the_holder_line_is_read_whole_while_it_is_being_replaced() {
        let path = std::env::temp_dir().join(format!("holder-{}", std::process::id()));
        let old = "pid 4000000 on host a-much-longer-host-name since 2026-01-01T00:00:00Z\n";
        let new = "pid 7 on host h since 2026-11-24T22:41:07Z\n";
        std::fs::write(&path, old).expect("write");
        let mut file = super::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&path)
            .expect("open");
        super::FileExt::write_all_at(&file, new.as_bytes(), 0).expect("write");
        assert_eq!(super::read_holder(&mut file), new.trim());
        file.rewind().expect("rewind");
        file.set_len(0).expect("cut");
        assert_eq!(super::read_holder(&mut file), "holder unknown");
        std::fs::remove_file(&path).expect("remove");
    }
    #[test]
    fn the_holder_is_named_with_an_iso_8601_start_time() {
        let holder = super::holder_description();
        let since = holder.rsplit(" since ").next().unwrap_or_default();
        assert!(holder.starts_with(&format!("pid {} on host ", std::process::id())));
        assert_eq!(since.len(), "2026-11-24T22:41:07Z".len(), "{holder}");
        assert!(
            since.ends_with('Z') && since.as_bytes()[10] == b'T',
            "{holder}"
        );
    }
}

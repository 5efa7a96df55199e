//! Atomic file replacement: every output of the project is written through here, so a crash, a
//! kill or a full disk never leaves a half-written file under a final name, and never destroys an
//! earlier good file. Outputs written in one call use [`write_atomically`]; a writer that streams
//! its output over many calls (`pipeline gen`) writes to [`temporary_path`], syncs it and moves it
//! into place with [`replace`].

use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// `dir/.name.tmp-PID`: same directory, so the rename is atomic; hidden, so globs skip it.
pub fn temporary_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Writes `path` through a temporary file in the same directory, fsyncs it, renames it into place
/// and fsyncs the directory. On any error the temporary is removed and an existing file at `path`
/// is untouched.
pub fn write_atomically(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    let temporary = temporary_path(path);
    let result = write_and_sync(&temporary, body).and_then(|()| replace(&temporary, path));
    if result.is_err() {
        let _ = fs::remove_file(&temporary);
    }
    result
}

fn write_and_sync(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    let mut out = BufWriter::with_capacity(1 << 20, File::create(path)?);
    body(&mut out)?;
    out.flush()?;
    out.into_inner().map_err(|e| e.into_error())?.sync_all()
}

/// Renames the synced `temporary` over `path` and fsyncs the directory, so that the rename
/// itself survives a crash.
pub fn replace(temporary: &Path, path: &Path) -> io::Result<()> {
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

//! Where a command's output goes: `-` is standard output; a path that exists and is not a
//! regular file (`/dev/null`, a FIFO, a terminal, `/dev/stdout`) is written directly, in order,
//! with no temporary file; anything else is a regular file, replaced atomically through a
//! temporary file and a rename ([`crate::atomic`]). Nothing is ever renamed over a device.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::atomic;
use crate::exit_code::UsageError;

/// The output argument that names standard output.
pub const STDOUT_ARGUMENT: &str = "-";

/// Bytes buffered before a write to a stream: few system calls, and a reader of a pipe gets
/// whole blocks.
const STREAM_BUFFER_BYTES: usize = 1 << 20;

/// An output, checked and (for a stream) opened before any work.
pub enum Destination {
    /// Standard output (`-`).
    Stdout,
    /// An existing file that is not a regular one, opened for writing.
    Direct { path: PathBuf, file: File },
    /// A regular file (or a new one), replaced atomically.
    Replace(PathBuf),
}

impl Destination {
    /// The destination of the output argument `path`, refused before any work when it is one of
    /// `inputs` (by path, symlink or hard link: writing it would destroy the input) or cannot be
    /// written (a directory, a missing or read-only directory, a device that refuses writing).
    pub fn prepare(path: &Path, inputs: &[&Path]) -> anyhow::Result<Destination> {
        if path.as_os_str() == STDOUT_ARGUMENT {
            return Ok(Destination::Stdout);
        }
        let stream = is_stream(path);
        let same = |input: &&&Path| match stream {
            true => same_inode(path, input),
            false => atomic::same_file(path, input),
        };
        if let Some(input) = inputs.iter().find(same) {
            anyhow::bail!(UsageError(format!(
                "output {} is the input {} (the same file); writing it would destroy the input, \
                 so choose another output path",
                path.display(),
                input.display()
            )));
        }
        let context = || format!("output {}", path.display());
        if stream {
            // Opening a FIFO waits for its reader, as any writer to a FIFO does.
            let file = File::options()
                .write(true)
                .open(path)
                .with_context(context)?;
            return Ok(Destination::Direct {
                path: path.to_path_buf(),
                file,
            });
        }
        atomic::check_writable(path).with_context(context)?;
        Ok(Destination::Replace(path.to_path_buf()))
    }

    /// Whether the output goes to standard output, which then carries nothing else.
    pub fn is_stdout(&self) -> bool {
        matches!(self, Destination::Stdout)
    }

    /// The output's name in messages.
    pub fn name(&self) -> String {
        match self {
            Destination::Stdout => "standard output".into(),
            Destination::Direct { path, .. } | Destination::Replace(path) => {
                path.display().to_string()
            }
        }
    }

    /// Writes the output with `body`: a regular file through a temporary renamed into place
    /// only when `body` succeeds; a stream directly, in order (what `body` wrote before failing
    /// has been sent).
    pub fn write<T, E: From<io::Error>>(
        &self,
        body: impl FnOnce(&mut dyn Write) -> Result<T, E>,
    ) -> Result<T, E> {
        match self {
            Destination::Stdout => write_stream(io::stdout().lock(), body),
            Destination::Direct { file, .. } => write_stream(file, body),
            Destination::Replace(path) => atomic::write_atomically_with(path, |out| body(out)),
        }
    }
}

fn write_stream<T, E: From<io::Error>>(
    stream: impl Write,
    body: impl FnOnce(&mut dyn Write) -> Result<T, E>,
) -> Result<T, E> {
    let mut out = BufWriter::with_capacity(STREAM_BUFFER_BYTES, stream);
    let value = body(&mut out)?;
    out.flush()?;
    Ok(value)
}

/// Whether the output argument `path` is written as a stream: `-`, a path that exists and is
/// neither a regular file nor a directory, or one of this process's open descriptors (`/dev/stdout`, `/dev/fd/N`,
/// `/proc/self/fd/N`), which a rename would replace by a file instead of writing through.
pub fn is_stream(path: &Path) -> bool {
    if path.as_os_str() == STDOUT_ARGUMENT {
        return true;
    }
    let descriptor = ["/dev/stdout", "/dev/stderr", "/dev/fd/", "/proc/self/fd/"]
        .iter()
        .any(|prefix| path.starts_with(prefix));
    let special = |metadata: std::fs::Metadata| !metadata.is_file() && !metadata.is_dir();
    descriptor || std::fs::metadata(path).is_ok_and(special)
}

/// Whether `a` and `b` are one open file, device or pipe. Unlike [`atomic::same_file`], no
/// path comparison: two pipes (`/dev/stdin`, `/dev/stdout`) have no path, yet differ.
#[cfg(unix)]
fn same_inode(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => (a.dev(), a.ino()) == (b.dev(), b.ino()),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_inode(a: &Path, b: &Path) -> bool {
    atomic::same_file(a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_and_descriptors_are_streams_and_new_or_regular_files_are_not() {
        assert!(is_stream(Path::new("-")));
        assert!(is_stream(Path::new("/dev/null")));
        assert!(is_stream(Path::new("/dev/stdout")));
        assert!(is_stream(Path::new("/proc/self/fd/1")));
        assert!(!is_stream(Path::new("/nonexistent/new-output.png")));
        assert!(!is_stream(Path::new("Cargo.toml")));
        assert!(!is_stream(Path::new("src")));
    }
}

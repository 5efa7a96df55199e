//! gzip- and zstd-compressed inputs, recognised by their magic bytes.
//!
//! The readers need random access (the PLY stream maps windows, STL checks its size), so the
//! content is decompressed, streaming, into a temporary file under the system's temporary
//! directory, read from there like a plain file and deleted when the reader is done. The
//! converted file is therefore byte-identical to the plain input's; errors name the compressed
//! file, with offsets and lines counted in its decompressed content.

use std::fs::File;
use std::io::{self, BufWriter, Read};
use std::path::Path;

use super::error::{InputError, InputErrorKind, Location};
use super::ply::io_error;
use super::temporary::TemporaryFile;

/// A compression around a mesh file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    Gzip,
    Zstd,
}

impl Compression {
    /// The compression whose magic bytes `head` starts with.
    pub fn of(head: &[u8]) -> Option<Compression> {
        if head.starts_with(&[0x1f, 0x8b]) {
            Some(Compression::Gzip)
        } else if head.starts_with(&[0x28, 0xb5, 0x2f, 0xfd]) {
            Some(Compression::Zstd)
        } else {
            None
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Compression::Gzip => "gzip",
            Compression::Zstd => "zstd",
        }
    }

    /// The file name suffix it conventionally adds, with its dot.
    pub fn extension(self) -> &'static str {
        match self {
            Compression::Gzip => ".gz",
            Compression::Zstd => ".zst",
        }
    }

    fn decoder(self, path: &Path) -> Result<Box<dyn Read>, InputError> {
        let file = File::open(path).map_err(|error| io_error(path, &error))?;
        Ok(match self {
            // Multi-member, as `cat a.gz b.gz` and parallel compressors (pigz) write.
            Compression::Gzip => Box::new(flate2::read::MultiGzDecoder::new(file)),
            Compression::Zstd => {
                let decoder = zstd::stream::read::Decoder::new(file)
                    .map_err(|error| self.error(path, 0, &error))?;
                Box::new(decoder)
            }
        })
    }

    fn error(self, path: &Path, decompressed: u64, error: &io::Error) -> InputError {
        let kind = InputErrorKind::Decompression {
            compression: self.name(),
            detail: format!("after {decompressed} decompressed bytes: {error}").into(),
        };
        InputError::new(path, Location::File, kind)
    }
}

/// Up to `limit` bytes of the decompressed content (fewer when it is shorter or corrupt early:
/// the full decompression reports the defect).
pub(crate) fn head(
    path: &Path,
    compression: Compression,
    limit: usize,
) -> Result<Vec<u8>, InputError> {
    let mut head = vec![0u8; limit];
    let mut decoder = compression.decoder(path)?;
    let mut filled = 0;
    while filled < limit {
        match decoder.read(&mut head[filled..]) {
            Ok(0) | Err(_) => break,
            Ok(read) => filled += read,
        }
    }
    head.truncate(filled);
    Ok(head)
}

/// Decompresses `path` into a new temporary file, keeping the name's inner extension.
pub(crate) fn decompress(
    path: &Path,
    compression: Compression,
) -> Result<TemporaryFile, InputError> {
    let inner_name = path
        .file_name()
        .and_then(|name| name.to_str())
        .map(|name| name.strip_suffix(compression.extension()).unwrap_or(name))
        .unwrap_or("input");
    let (decompressed, file) = TemporaryFile::create(path, inner_name)?;
    let mut decoder = compression.decoder(path)?;
    let mut writer = BufWriter::with_capacity(1 << 20, file);
    let mut buffer = vec![0u8; 1 << 20];
    let mut written = 0u64;
    loop {
        let read = match decoder.read(&mut buffer) {
            Ok(0) => break,
            Ok(read) => read,
            Err(error) if error.kind() == io::ErrorKind::Interrupted => continue,
            Err(error) => return Err(compression.error(path, written, &error)),
        };
        io::Write::write_all(&mut writer, &buffer[..read])
            .map_err(|error| io_error(decompressed.path(), &error))?;
        written += read as u64;
    }
    io::Write::flush(&mut writer).map_err(|error| io_error(decompressed.path(), &error))?;
    Ok(decompressed)
}

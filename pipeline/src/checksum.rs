//! Content checks of the work directory's files: each file's XXH3 is computed while it is
//! written and recorded in the manifest beside its size, and checked once per run before the
//! file is trusted again, so a damaged work directory costs a rebuild, never a wrong output.

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::Path;

use serde::{Deserialize, Serialize};
use xxhash_rust::xxh3::Xxh3;

/// A file's size and content hash, as recorded when it was written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Checksum {
    pub bytes: u64,
    /// XXH3-64 of the whole file, as 16 hex digits in the manifest.
    #[serde(with = "hex")]
    pub xxh3: u64,
}

/// Writes `path` atomically (`reducem::atomic::write_atomically`) and returns the checksum of
/// the bytes written, hashed on the way out instead of read back.
pub fn write_atomically_checked(
    path: &Path,
    body: impl FnOnce(&mut HashingWriter<&mut BufWriter<File>>) -> io::Result<()>,
) -> io::Result<Checksum> {
    reducem::atomic::write_atomically_with(path, |out| {
        let mut hashing = HashingWriter::new(out);
        body(&mut hashing)?;
        Ok(hashing.checksum())
    })
}

/// The checksum of a file as it is now, read in 1 MiB blocks (constant memory).
pub fn checksum_file(path: &Path) -> io::Result<Checksum> {
    let mut file = File::open(path)?;
    let mut hasher = Xxh3::new();
    let mut buffer = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = file.read(&mut buffer)?;
        if n == 0 {
            return Ok(Checksum {
                bytes,
                xxh3: hasher.digest(),
            });
        }
        hasher.update(&buffer[..n]);
        bytes += n as u64;
    }
}

/// A writer that hashes and counts what passes through it.
pub struct HashingWriter<W> {
    inner: W,
    hasher: Xxh3,
    bytes: u64,
}

impl<W: Write> HashingWriter<W> {
    pub fn new(inner: W) -> HashingWriter<W> {
        HashingWriter {
            inner,
            hasher: Xxh3::new(),
            bytes: 0,
        }
    }

    pub fn checksum(&self) -> Checksum {
        Checksum {
            bytes: self.bytes,
            xxh3: self.hasher.digest(),
        }
    }
}

impl<W: Write> Write for HashingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let written = self.inner.write(buf)?;
        self.hasher.update(&buf[..written]);
        self.bytes += written as u64;
        Ok(written)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// A 64-bit hash as 16 hex digits, as every other hash in the manifest is shown.
mod hex {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(value: &u64, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&format!("{value:016x}"))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<u64, D::Error> {
        let text = String::deserialize(deserializer)?;
        u64::from_str_radix(&text, 16).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_checksum_written_is_the_checksum_read() {
        let dir = std::env::temp_dir().join(format!("checksum-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("file");
        let block: Vec<u8> = (0..3 << 19).map(|i: u32| (i % 253) as u8).collect();
        let written = write_atomically_checked(&path, |out| out.write_all(&block)).expect("write");
        assert_eq!(written.bytes, block.len() as u64);
        assert_eq!(written.xxh3, xxhash_rust::xxh3::xxh3_64(&block));
        assert_eq!(checksum_file(&path).expect("read"), written);
        let json = serde_json::to_string(&written).expect("json");
        assert_eq!(
            serde_json::from_str::<Checksum>(&json).expect("parse"),
            written
        );
        std::fs::remove_dir_all(&dir).expect("remove");
    }
}

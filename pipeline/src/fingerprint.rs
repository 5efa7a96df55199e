//! Stage fingerprints, after cargo's: a unit of work (a stage, or one chunk of a stage) is fresh
//! when the hash of everything it depends on — its inputs' content hashes, the config keys that
//! affect it, the format version and this program's version — equals the hash recorded when it
//! last completed. The named parts are recorded too, so `status` can say which one changed.

use std::collections::BTreeMap;
use std::io;
use std::path::Path;

use xxhash_rust::xxh3::Xxh3;

/// The named parts a unit of work depends on.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Fingerprint {
    parts: BTreeMap<String, String>,
}

impl Fingerprint {
    /// Starts a fingerprint, already covering the format and program versions.
    pub fn new() -> Fingerprint {
        let mut fingerprint = Fingerprint::default();
        fingerprint.add(
            "format_version",
            format!(
                "{}.{}",
                reducem::format::VERSION_MAJOR,
                reducem::format::VERSION_MINOR
            ),
        );
        fingerprint.add("program_version", env!("CARGO_PKG_VERSION"));
        fingerprint
    }

    pub fn add(&mut self, name: &str, value: impl ToString) -> &mut Fingerprint {
        self.parts.insert(name.to_string(), value.to_string());
        self
    }

    pub fn with(mut self, name: &str, value: impl ToString) -> Fingerprint {
        self.add(name, value);
        self
    }

    pub fn parts(&self) -> &BTreeMap<String, String> {
        &self.parts
    }

    /// The hash of all parts, as 16 hex digits.
    pub fn digest(&self) -> String {
        let mut hasher = Xxh3::new();
        for (name, value) in &self.parts {
            for part in [name, value] {
                hasher.update(&(part.len() as u64).to_le_bytes());
                hasher.update(part.as_bytes());
            }
        }
        format!("{:016x}", hasher.digest())
    }
}

/// XXH3-64 of a file's bytes as 16 hex digits, read in 1 MiB blocks (constant memory).
pub fn hash_file(path: &Path) -> io::Result<String> {
    crate::checksum::checksum_file(path).map(|checksum| format!("{:016x}", checksum.xxh3))
}

//! The manifest: what completed, with which fingerprint, producing which files.
//!
//! It lives at `<work>/manifest.json` and is rewritten atomically (temp file, fsync, rename)
//! after a unit's outputs have been renamed into place, never before: a run killed at any moment
//! leaves either the old record (the unit is redone, rewriting identical bytes) or the new one
//! (the outputs it names are complete). Each output's size and content hash are recorded, and
//! a unit whose outputs no longer match is stale.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::checksum::Checksum;
use crate::fingerprint::Fingerprint;
use reducem::atomic::write_atomically;

/// Bumped when the manifest layout changes; an unknown version means "nothing is fresh". 2:
/// outputs carry their content hash.
const MANIFEST_VERSION: u32 = 2;

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub version: u32,
    /// Completed units by key: a stage name, or `stage/chunk-N` for one chunk of a stage.
    pub units: BTreeMap<String, UnitRecord>,
    /// Cached content hash of the input, valid while its identity is unchanged.
    pub input: Option<InputIdentity>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnitRecord {
    pub fingerprint: String,
    pub parts: BTreeMap<String, String>,
    /// Outputs relative to the work directory (the final output absolute), with their sizes
    /// and content hashes.
    pub outputs: BTreeMap<String, Checksum>,
}

/// An input file's identity (path, size, modification time) and its content hash.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputIdentity {
    pub path: String,
    pub bytes: u64,
    pub modified_ns: u128,
    pub hash: String,
}

/// Whether a unit must run, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Freshness {
    Fresh,
    Pending,
    Stale(String),
    /// The named output's content is not what was written: the unit is rebuilt.
    Changed(String),
}

impl Manifest {
    /// Loads the manifest; a missing or unreadable one is empty (everything pending).
    pub fn load(path: &Path) -> Manifest {
        std::fs::read(path)
            .ok()
            .and_then(|bytes| serde_json::from_slice::<Manifest>(&bytes).ok())
            .filter(|m| m.version == MANIFEST_VERSION)
            .unwrap_or_default()
    }

    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        let mut saved = self.clone();
        saved.version = MANIFEST_VERSION;
        let json = serde_json::to_vec_pretty(&saved).map_err(std::io::Error::other)?;
        write_atomically(path, |file| std::io::Write::write_all(file, &json))
    }

    /// Compares the recorded unit with what it would depend on now, and checks its outputs'
    /// sizes (their contents are checked by `Job::freshness`, once per run).
    pub fn freshness(&self, work_dir: &Path, key: &str, fingerprint: &Fingerprint) -> Freshness {
        let Some(record) = self.units.get(key) else {
            return Freshness::Pending;
        };
        if record.fingerprint != fingerprint.digest() {
            return Freshness::Stale(changed_parts(&record.parts, fingerprint.parts()));
        }
        for (output, Checksum { bytes, .. }) in &record.outputs {
            match std::fs::metadata(work_dir.join(output)) {
                Ok(meta) if meta.len() == *bytes => {}
                Ok(meta) => {
                    return Freshness::Stale(format!(
                        "{output} is {} bytes, expected {bytes}",
                        meta.len()
                    ))
                }
                Err(_) => return Freshness::Stale(format!("{output} is missing")),
            }
        }
        Freshness::Fresh
    }

    pub fn record(
        &mut self,
        key: &str,
        fingerprint: &Fingerprint,
        outputs: BTreeMap<String, Checksum>,
    ) {
        self.units.insert(
            key.to_string(),
            UnitRecord {
                fingerprint: fingerprint.digest(),
                parts: fingerprint.parts().clone(),
                outputs,
            },
        );
    }
}

/// Marks the content of a generated input.
pub const GENERATED: &str = "generated: ";

/// Marks an input content that status could not know without hashing the file.
pub const UNHASHED: &str = "unhashed: ";

fn changed_parts(
    recorded: &BTreeMap<String, String>,
    current: &BTreeMap<String, String>,
) -> String {
    let mut changes = Vec::new();
    for (name, value) in current {
        match recorded.get(name) {
            Some(old) if old == value => {}
            Some(old) => changes.push(describe_change(name, old, value)),
            None => changes.push(format!("{name} is new (recorded by an older version)")),
        }
    }
    changes.extend(
        recorded
            .keys()
            .filter(|k| !current.contains_key(*k))
            .map(|k| format!("{k} no longer applies (recorded by an older version)")),
    );
    changes.join("; ")
}

/// One changed part in words: stage digests and content hashes mean nothing to a user, so they
/// are named by what changed rather than shown.
fn describe_change(name: &str, old: &str, new: &str) -> String {
    if let Some(stage) = name.strip_suffix("_stage") {
        return format!("the {stage} stage's results changed");
    }
    match name {
        "input" => describe_input_change(old, new),
        "top_level" => "the top-level hierarchy parameters of the program changed".into(),
        "format_version" => format!("the file format version changed from {old} to {new}"),
        "program_version" => format!("the program version changed from {old} to {new}"),
        _ => format!("{name} changed from {old} to {new}"),
    }
}

fn describe_input_change(old: &str, new: &str) -> String {
    if let Some(identity) = new.strip_prefix(UNHASHED) {
        return format!(
            "input changed: {identity} (the next run hashes it again and redoes the work only \
             if its content differs)"
        );
    }
    let generated = GENERATED;
    if let Some(new) = new.strip_prefix(generated) {
        return match old.strip_prefix(generated) {
            Some(old) => format!("the generated input changed from a {old} to a {new}"),
            None if old.starts_with("generated:") => "the generated input is now streamed from \
                the generator (an older version wrote it to a file)"
                .into(),
            None => format!("the input is now a generated {new}"),
        };
    }
    "the input's content changed".into()
}

//! The job a run works on: its configuration, work directory, progress and manifest, shared by
//! every stage and by the input's resolution.

use std::collections::{BTreeMap, HashMap};
use std::sync::Mutex;

use anyhow::Context;

use crate::checksum::{self, Checksum};
use crate::config::Config;
use crate::fingerprint::Fingerprint;
use crate::manifest::{Freshness, Manifest};
use crate::progress::Progress;
use crate::workdir::WorkDir;

/// What every stage works with.
pub struct Job<'a> {
    pub config: &'a Config,
    pub work: WorkDir,
    pub progress: &'a Progress,
    manifest: Mutex<Manifest>,
    /// Outputs whose content this run wrote or checked against the manifest: each file is
    /// hashed at most once per run.
    checked: Mutex<HashMap<String, Checksum>>,
}

impl<'a> Job<'a> {
    pub fn new(config: &'a Config, work: WorkDir, progress: &'a Progress) -> Job<'a> {
        let manifest = Manifest::load(&work.manifest());
        Job {
            config,
            work,
            progress,
            manifest: Mutex::new(manifest),
            checked: Mutex::new(HashMap::new()),
        }
    }

    /// Whether unit `key` is done for `fingerprint`, its outputs in place with the sizes and
    /// contents recorded when they were written.
    pub fn freshness(&self, key: &str, fingerprint: &Fingerprint) -> Freshness {
        let (freshness, outputs) = {
            let manifest = self.lock_manifest();
            let outputs = manifest.units.get(key).map(|unit| unit.outputs.clone());
            (
                manifest.freshness(self.work.root(), key, fingerprint),
                outputs,
            )
        };
        if freshness != Freshness::Fresh {
            return freshness;
        }
        let changed = outputs
            .unwrap_or_default()
            .into_iter()
            .find(|(output, recorded)| !self.content_matches(output, recorded));
        match changed {
            Some((output, _)) => Freshness::Changed(output),
            None => Freshness::Fresh,
        }
    }

    /// Whether `output` holds what was recorded, hashing it only the first time in this run.
    fn content_matches(&self, output: &str, recorded: &Checksum) -> bool {
        if self.checked_lock().get(output) == Some(recorded) {
            return true;
        }
        let matches = checksum::checksum_file(&self.work.file(output)).ok() == Some(*recorded);
        if matches {
            self.checked_lock().insert(output.to_string(), *recorded);
        }
        matches
    }

    /// Logs, when a unit is redone because one of its outputs changed, which file and what is
    /// rebuilt.
    pub fn note_rebuild(&self, stage: &str, freshness: &Freshness, rebuilt: &str) {
        if let Freshness::Changed(output) = freshness {
            self.progress.event(
                stage,
                "rebuild",
                &format!("{output} changed since it was written; rebuilding {rebuilt}"),
            );
        }
    }

    /// Writes `relative` atomically through `body` and returns its checksum, known to be this
    /// run's.
    pub fn write_output(
        &self,
        relative: &str,
        body: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
    ) -> anyhow::Result<(String, Checksum)> {
        let path = self.work.file(relative);
        let written = checksum::write_atomically_checked(&path, |out| body(out))
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(self.written(relative, written))
    }

    /// Notes that this run wrote `output` with `checksum`, for [`Job::complete`].
    pub fn written(&self, output: &str, checksum: Checksum) -> (String, Checksum) {
        self.checked_lock().insert(output.to_string(), checksum);
        (output.to_string(), checksum)
    }

    /// Records a unit as complete, after its outputs (paths relative to the work directory, or
    /// absolute) were renamed into place, and saves the manifest atomically.
    pub fn complete(
        &self,
        key: &str,
        fingerprint: &Fingerprint,
        outputs: &[(String, Checksum)],
    ) -> anyhow::Result<()> {
        let outputs: BTreeMap<String, Checksum> = outputs.iter().cloned().collect();
        self.update_manifest(|manifest| manifest.record(key, fingerprint, outputs))
    }

    /// Applies `change` to the manifest on disk and saves it, under an exclusive lock on
    /// `<work>/manifest.lock`: sharded tasks of one job complete units concurrently from several
    /// processes, so each update rereads the latest manifest instead of overwriting it with a
    /// stale copy.
    pub fn update_manifest(&self, change: impl FnOnce(&mut Manifest)) -> anyhow::Result<()> {
        let lock_path = self.work.file("manifest.lock");
        let lock = std::fs::File::create(&lock_path)
            .with_context(|| format!("opening {}", lock_path.display()))?;
        lock.lock()
            .with_context(|| format!("locking {}", lock_path.display()))?;
        let path = self.work.manifest();
        let mut latest = Manifest::load(&path);
        change(&mut latest);
        latest
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))?;
        *self.lock_manifest() = latest;
        Ok(())
    }

    /// Rereads the manifest from disk (another process may have completed units since).
    pub fn reload_manifest(&self) {
        *self.lock_manifest() = Manifest::load(&self.work.manifest());
    }

    pub fn manifest(&self) -> std::sync::MutexGuard<'_, Manifest> {
        self.lock_manifest()
    }

    fn lock_manifest(&self) -> std::sync::MutexGuard<'_, Manifest> {
        self.manifest
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn checked_lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, Checksum>> {
        self.checked
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

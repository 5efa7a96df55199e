//! `pipeline run`: the staged, resumable conversion. Each stage checks its fingerprint against
//! the manifest, skips fresh work and records new work after its outputs are in place, so a run
//! killed at any moment resumes where it stopped and ends with the same bytes.
//!
//! `--stage` runs one stage whose predecessors are done, and `--shard I/N` splits the strip
//! stage's chunks over the tasks of a batch job array (see `scripts/slurm/`). Strip tasks share
//! the work directory (a shared lock, plus an exclusive lock per chunk); every other run holds
//! it exclusively.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context;

use crate::config::{Config, ConfigError};
use crate::error::InStage;
use crate::error::UsageError;
use crate::lock::{LockedError, WorkLock};
use crate::preflight::{self, Naming};
use crate::progress::{LogFormat, Progress};
use crate::stage::Job;
pub use crate::stage::{Shard, StageName, UpstreamPending};
use crate::stages::{self, UnitOfWork, STAGES};
use crate::status;
use crate::workdir::WorkDir;

/// What to do when another run holds the work directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IfLocked {
    /// Exit at once with code 75, naming the holder.
    Fail,
    /// Exit at once with code 0 (for cron jobs that overlap by design).
    Skip,
    /// Wait for the holder to finish, for at most the duration if one is given (then fail as
    /// `Fail` does): for cron jobs that would rather queue than skip.
    Wait(Option<Duration>),
}

impl std::str::FromStr for IfLocked {
    type Err = String;

    /// `fail`, `skip`, `wait` or `wait=SECONDS`.
    fn from_str(text: &str) -> Result<IfLocked, String> {
        match text.split_once('=') {
            None if text == "fail" => Ok(IfLocked::Fail),
            None if text == "skip" => Ok(IfLocked::Skip),
            None if text == "wait" => Ok(IfLocked::Wait(None)),
            Some(("wait", seconds)) => match seconds.parse::<u64>() {
                Ok(seconds) => Ok(IfLocked::Wait(Some(Duration::from_secs(seconds)))),
                Err(_) => Err(format!("{seconds:?} is not a whole number of seconds")),
            },
            _ => Err(format!("{text:?} is not fail, skip, wait or wait=SECONDS")),
        }
    }
}

/// How often a waiting run tries the lock again.
const LOCK_RETRY: Duration = Duration::from_millis(500);

pub struct RunOptions {
    pub log_format: LogFormat,
    /// Remove the work directory after a successful run, as `[work] keep = false` does.
    pub clean_after: bool,
    pub if_locked: IfLocked,
    pub stage: Option<StageName>,
    pub shard: Shard,
}

pub fn run(config_path: &Path, options: &RunOptions) -> anyhow::Result<()> {
    run_reporting(config_path, options, Progress::new(options.log_format))
}

/// [`run`] reporting to `progress` instead of as `options.log_format` says (the Python
/// package's reports to `logging`).
pub fn run_reporting(
    config_path: &Path,
    options: &RunOptions,
    progress: Progress,
) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = Config::load(config_path)?;
    let per_chunk = options
        .stage
        .is_some_and(|name| stages::stage(name).unit == UnitOfWork::Chunk);
    if options.shard != Shard::WHOLE && !per_chunk {
        anyhow::bail!(UsageError("--shard applies to --stage strip only".into()));
    }
    if let Some(message) = preflight::unsafe_paths(&config, config_path, Naming::Config) {
        return Err(ConfigError::new(config_path, message).into());
    }
    preflight::check_input_attributes(&config)?;
    preflight::prepare_output(&config)?;
    let work = WorkDir::new(config.work_dir());
    work.create()
        .with_context(|| format!("creating {}", work.root().display()))?;
    // A per-chunk stage locks each chunk, so the tasks of one job share the work directory.
    let Some(_lock) = lock_work_dir(&work, per_chunk, options.if_locked, &progress)? else {
        return Ok(());
    };
    if !per_chunk {
        remove_dead_temporaries(&config, &work, &progress)?;
    }
    let job = Job::new(&config, work, &progress);
    let result = match options.stage {
        None => stages::run_all(&job),
        Some(stage) => stages::run_one(&job, stage, options.shard),
    };
    if let Err(error) = result {
        return Err(match status::first_unfinished_stage(&job) {
            Some(stage) => error.context(InStage(stage)),
            None => error,
        });
    }
    let last = STAGES[STAGES.len() - 1].name;
    let finished = options.stage.is_none_or(|stage| stage == last);
    if finished && (options.clean_after || !config.work.keep) {
        remove_work_dir(&config, config_path)?;
        let root = config.work_dir();
        progress.event("run", "clean", &format!("removed {}", root.display()));
    }
    let seconds = started.elapsed().as_secs_f64();
    let counts = finished.then(|| output_counts(&config));
    progress.summary(seconds, counts.flatten());
    Ok(())
}

/// Takes the work directory's lock as `if_locked` says; `None` when the run is to be skipped.
fn lock_work_dir(
    work: &WorkDir,
    shared: bool,
    if_locked: IfLocked,
    progress: &Progress,
) -> anyhow::Result<Option<WorkLock>> {
    let started = Instant::now();
    let mut waiting = false;
    loop {
        let error = match WorkLock::acquire(work.root(), shared) {
            Ok(lock) => return Ok(Some(lock)),
            Err(error) if error.is::<LockedError>() => error,
            Err(error) => return Err(error),
        };
        match if_locked {
            IfLocked::Fail => return Err(error),
            IfLocked::Skip => {
                let message = format!("{error:#}; skipping (--if-locked skip)");
                progress.event("run", "skip", &message);
                return Ok(None);
            }
            IfLocked::Wait(Some(limit)) if started.elapsed() >= limit => {
                let seconds = limit.as_secs();
                return Err(error.context(format!("gave up after waiting {seconds} s")));
            }
            IfLocked::Wait(_) => {
                if !waiting {
                    let message = format!("{error:#}; waiting for it (--if-locked wait)");
                    progress.event("run", "wait", &message);
                    waiting = true;
                }
                crate::interrupt::check()?;
                std::thread::sleep(LOCK_RETRY);
            }
        }
    }
}

/// Removes the temporaries that killed runs left in the work directory and beside the output.
/// Only under the exclusive lock: then no other run of this job can be writing one.
fn remove_dead_temporaries(
    config: &Config,
    work: &WorkDir,
    progress: &Progress,
) -> anyhow::Result<()> {
    let output = &config.output.path;
    let output_dir = output
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let output_name = output.file_name().map(|n| n.to_string_lossy().into_owned());
    let work_dirs = ["", "chunks", "strips", "locks"].map(|dir| (work.file(dir), None));
    let mut removed = Vec::new();
    for (dir, of) in work_dirs
        .into_iter()
        .chain([(output_dir.into(), output_name)])
    {
        let found = reducem::atomic::remove_dead_temporaries(&dir, of.as_deref())
            .with_context(|| format!("removing temporaries of killed runs in {}", dir.display()))?;
        removed.extend(found);
    }
    if !removed.is_empty() {
        let bytes: u64 = removed.iter().map(|(_, bytes)| bytes).sum();
        let message = format!(
            "removed {} temporaries of killed runs ({bytes} bytes)",
            removed.len()
        );
        progress.event("run", "clean", &message);
    }
    Ok(())
}

/// What the finished file holds, for the summary.
fn output_counts(config: &Config) -> Option<serde_json::Value> {
    let file = reducem::format::reader::ReducemFile::open(&config.output.path).ok()?;
    let header = file.header();
    Some(serde_json::json!({
        "triangles": header.triangle_count,
        "strips": header.strip_count,
        "bytes": std::fs::metadata(&config.output.path).ok()?.len(),
    }))
}

/// `pipeline clean`: removes the work directory (under its lock, so not from under a run), only
/// one that pipeline made and that holds neither the input nor the output.
pub fn clean(config_path: &Path) -> anyhow::Result<()> {
    let config = Config::load(config_path)?;
    let root = config.work_dir();
    if !root.exists() {
        eprintln!("pipeline: nothing to clean at {}", root.display());
        return Ok(());
    }
    let lock = WorkLock::acquire(&root, false)?;
    remove_work_dir(&config, config_path)?;
    drop(lock);
    eprintln!("pipeline: removed {}", root.display());
    Ok(())
}

/// Removes the work directory, which the caller holds locked, if it is safe to.
fn remove_work_dir(config: &Config, config_path: &Path) -> anyhow::Result<()> {
    if let Some(message) = preflight::unsafe_to_clean(config, config_path) {
        return Err(ConfigError::new(config_path, message).into());
    }
    let root = config.work_dir();
    std::fs::remove_dir_all(&root).with_context(|| format!("removing {}", root.display()))
}

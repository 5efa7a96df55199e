//! `pipeline run`: the staged, resumable conversion. Each stage checks its fingerprint against
//! the manifest, skips fresh work and records new work after its outputs are in place, so a run
//! killed at any moment resumes where it stopped and ends with the same bytes.
//!
//! `--stage` runs one stage whose predecessors are done, and `--shard I/N` splits the strip
//! stage's chunks over the tasks of a batch job array (see `scripts/slurm/`). Strip tasks share
//! the work directory (a shared lock, plus an exclusive lock per chunk); every other run holds
//! it exclusively.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;

use crate::config::{Config, ConfigError};
use crate::input;
use crate::lock::{LockedError, WorkLock};
use crate::outcome::InStage;
use crate::preflight::{self, Naming};
use crate::progress::{LogFormat, Progress};
use crate::stage::chunk::Chunked;
use crate::stage::hierarchy::Hierarchy;
use crate::stage::merge::Merged;
use crate::stage::{chunk, hierarchy, merge, strip, write, Job};
pub use crate::stage::{Shard, StageName, UpstreamPending};
use crate::status;
use crate::workdir::WorkDir;

/// What to do when another run holds the work directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum IfLocked {
    /// Exit at once with code 75, naming the holder.
    Fail,
    /// Exit at once with code 0 (for cron jobs that overlap by design).
    Skip,
}

pub struct RunOptions {
    pub log_format: LogFormat,
    /// Remove the work directory after a successful run, as `[work] keep = false` does.
    pub clean_after: bool,
    pub if_locked: IfLocked,
    pub stage: Option<StageName>,
    pub shard: Shard,
}

/// A command line (or environment) that cannot be run as given.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

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
    if options.shard != Shard::WHOLE && options.stage != Some(StageName::Strip) {
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
    let shared = options.stage == Some(StageName::Strip);
    let _lock = match WorkLock::acquire(work.root(), shared) {
        Ok(lock) => lock,
        Err(error) if options.if_locked == IfLocked::Skip && error.is::<LockedError>() => {
            progress.event(
                "run",
                "skip",
                &format!("{error:#}; skipping (--if-locked skip)"),
            );
            return Ok(());
        }
        Err(error) => return Err(error),
    };
    let job = Job::new(&config, work, &progress);
    let result = match options.stage {
        None => run_all(&job),
        Some(stage) => run_stage(&job, stage, options.shard),
    };
    if let Err(error) = result {
        return Err(match status::first_unfinished_stage(&job) {
            Some(stage) => error.context(InStage(stage)),
            None => error,
        });
    }
    let finished = matches!(options.stage, None | Some(StageName::Write));
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

fn run_all(job: &Job) -> anyhow::Result<()> {
    let input = input::resolve(job)?;
    let chunked = chunk::run(job, &input)?;
    let strip_digest = strip::run(job, &chunked, Shard::WHOLE)?;
    let merged = merge::run(job, &chunked, &strip_digest)?;
    let hierarchy = hierarchy::run(job, &merged)?;
    write::run(job, &merged, &hierarchy)
}

fn run_stage(job: &Job, stage: StageName, shard: Shard) -> anyhow::Result<()> {
    match stage {
        StageName::Chunk => chunk::run(job, &input::resolve(job)?).map(drop),
        StageName::Strip => strip::run(job, &chunked(job)?, shard).map(drop),
        StageName::Merge => {
            let chunked = chunked(job)?;
            merge::run(job, &chunked, &stripped(job, &chunked)?).map(drop)
        }
        StageName::Hierarchy => hierarchy::run(job, &merged(job)?).map(drop),
        StageName::Write => {
            let merged = merged(job)?;
            write::run(job, &merged, &built_hierarchy(job, &merged)?)
        }
    }
}

fn chunked(job: &Job) -> anyhow::Result<Chunked> {
    let input = input::peek(job).map_err(|reason| UpstreamPending {
        needed: StageName::Chunk,
        reason,
    })?;
    chunk::fresh_result(job, &chunk::fingerprint(job, &input)).ok_or_else(|| {
        UpstreamPending {
            needed: StageName::Chunk,
            reason: "not run, or stale".into(),
        }
        .into()
    })
}

fn stripped(job: &Job, chunked: &Chunked) -> anyhow::Result<String> {
    let missing = strip::pending_chunks(job, chunked, Shard::WHOLE);
    if !missing.is_empty() {
        let reason = format!(
            "{} of {} chunks pending, first {}",
            missing.len(),
            chunked.chunk_count(),
            missing[0]
        );
        return Err(UpstreamPending {
            needed: StageName::Strip,
            reason,
        }
        .into());
    }
    Ok(strip::digest(job, chunked))
}

fn merged(job: &Job) -> anyhow::Result<Merged> {
    let chunked = chunked(job)?;
    let fingerprint = merge::fingerprint(&stripped(job, &chunked)?);
    merge::fresh_result(job, &fingerprint).ok_or_else(|| {
        UpstreamPending {
            needed: StageName::Merge,
            reason: "not run, or stale".into(),
        }
        .into()
    })
}

fn built_hierarchy(job: &Job, merged: &Merged) -> anyhow::Result<Hierarchy> {
    hierarchy::fresh_result(job, &hierarchy::fingerprint(merged)).ok_or_else(|| {
        UpstreamPending {
            needed: StageName::Hierarchy,
            reason: "not run, or stale".into(),
        }
        .into()
    })
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

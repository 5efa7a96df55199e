//! `pipeline run`: the staged, resumable conversion. Each stage checks its fingerprint against
//! the manifest, skips fresh work and records new work after its outputs are in place, so a run
//! killed at any moment resumes where it stopped and ends with the same bytes.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;

use crate::config::Config;
use crate::input;
use crate::lock::{LockedError, WorkLock};
use crate::progress::{LogFormat, Progress};
use crate::stage::{chunk, hierarchy, merge, strip, write, Job};
use crate::workdir::WorkDir;

/// What to do when another run holds the work directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum IfLocked {
    /// Exit at once with code 75, naming the holder.
    Fail,
    /// Exit at once with code 0 (for cron jobs that overlap by design).
    Skip,
}

pub fn run(config_path: &Path, log_format: LogFormat, if_locked: IfLocked) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = Config::load(config_path)?;
    let work = WorkDir::new(config.work_dir());
    work.create()
        .with_context(|| format!("creating {}", work.root().display()))?;
    let progress = Progress::new(log_format);
    let _lock = match WorkLock::acquire(work.root()) {
        Ok(lock) => lock,
        Err(error) if if_locked == IfLocked::Skip && error.is::<LockedError>() => {
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
    let input = input::resolve(&job)?;
    let chunked = chunk::run(&job, &input)?;
    let strip_digest = strip::run(&job, &chunked)?;
    let merged = merge::run(&job, chunked.chunk_count(), &strip_digest)?;
    let hierarchy = hierarchy::run(&job, &merged)?;
    write::run(&job, &merged, &hierarchy)?;
    progress.event(
        "run",
        "done",
        &format!("finished in {:.1} s", started.elapsed().as_secs_f64()),
    );
    Ok(())
}

/// `pipeline clean`: removes the work directory (under its lock, so not from under a run).
pub fn clean(config_path: &Path) -> anyhow::Result<()> {
    let config = Config::load(config_path)?;
    let root = config.work_dir();
    if !root.exists() {
        eprintln!("pipeline: nothing to clean at {}", root.display());
        return Ok(());
    }
    let lock = WorkLock::acquire(&root)?;
    std::fs::remove_dir_all(&root).with_context(|| format!("removing {}", root.display()))?;
    drop(lock);
    eprintln!("pipeline: removed {}", root.display());
    Ok(())
}

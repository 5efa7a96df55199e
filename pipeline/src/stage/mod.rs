//! The stages of a conversion, one file each, in run order. A stage only orchestrates: it
//! decides from the manifest whether its work is fresh, calls the algorithms in the `reducem`
//! library, writes its outputs atomically and records them in the manifest last.

pub mod chunk;
pub mod hierarchy;
pub mod merge;
pub mod strip;
pub mod write;

use std::path::Path;
use std::str::FromStr;
use std::sync::Mutex;

use anyhow::Context;

use crate::checksum::Checksum;
use crate::fingerprint::Fingerprint;
pub use crate::job::Job;
use crate::manifest::Freshness;

/// The stages, in run order, as `--stage` names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum StageName {
    /// Partition the input into chunks.
    Chunk,
    /// Strips and a hierarchy per chunk (the long stage; shardable).
    Strip,
    /// Collect the chunks' strip tables.
    Merge,
    /// The hierarchy over the chunks.
    Hierarchy,
    /// Write and verify the ReduceM file.
    Write,
}

impl std::fmt::Display for StageName {
    /// As `--stage` names it.
    fn fmt(&self, formatter: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let value = clap::ValueEnum::to_possible_value(self).ok_or(std::fmt::Error)?;
        formatter.write_str(value.get_name())
    }
}

/// Shard `index` of `count`: the strip stage's chunks `c` with `c % count == index`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// From `SLURM_ARRAY_TASK_ID` and `SLURM_ARRAY_TASK_COUNT` when both are set.
    pub fn from_slurm_env() -> anyhow::Result<Shard> {
        match (
            std::env::var("SLURM_ARRAY_TASK_ID"),
            std::env::var("SLURM_ARRAY_TASK_COUNT"),
        ) {
            (Ok(index), Ok(count)) => format!("{index}/{count}").parse().map_err(|e: String| {
                anyhow::anyhow!("SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT: {e}")
            }),
            _ => Ok(Shard::WHOLE),
        }
    }

    pub fn owns(&self, chunk: usize) -> bool {
        chunk % self.count == self.index
    }
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(text: &str) -> Result<Shard, String> {
        let parsed = text
            .split_once('/')
            .and_then(|(i, n)| Some((i.trim().parse().ok()?, n.trim().parse().ok()?)));
        match parsed {
            Some((index, count)) if index < count => Ok(Shard { index, count }),
            _ => Err(format!("shard {text:?} is not I/N with 0 <= I < N")),
        }
    }
}

/// A stage was asked for before the stages it needs were done.
#[derive(Debug, thiserror::Error)]
#[error("stage {needed:?} is not done yet ({reason}); run it first")]
pub struct UpstreamPending {
    pub needed: StageName,
    pub reason: String,
}

/// A stage result that carries the digest of the fingerprint that made it.
pub trait Stamped {
    fn digest(&self) -> &str;
}

/// A stage's recorded JSON result, if the unit is fresh and the file was made by `fingerprint`.
pub fn fresh_output<T: Stamped + serde::de::DeserializeOwned>(
    job: &Job,
    unit: &str,
    file: &str,
    fingerprint: &Fingerprint,
) -> Option<T> {
    if job.freshness(unit, fingerprint) != Freshness::Fresh {
        return None;
    }
    let result: T = read_json(&job.work.file(file)).ok()?;
    (result.digest() == fingerprint.digest()).then_some(result)
}

/// Reads a small JSON output of an earlier stage.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> anyhow::Result<T> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("parsing {}", path.display()))
}

/// Writes a small JSON output (`relative` to the work directory) atomically; its checksum.
pub fn write_json(
    job: &Job,
    relative: &str,
    value: &impl serde::Serialize,
) -> anyhow::Result<(String, Checksum)> {
    let json = serde_json::to_vec_pretty(value)?;
    job.write_output(relative, |out| out.write_all(&json))
}

/// Runs `work` for every unit, at most one unit per rayon thread at a time, and returns the
/// first error.
///
/// Memory is what bounds a stage (threads × one chunk), so units must not nest: with a plain
/// `par_iter`, a thread waiting inside a unit's own parallel loop may steal and start another
/// unit. Here each worker runs its units on a private one-thread pool, so the library's
/// parallel loops inside a unit stay on that worker. With fewer units than threads, units run
/// one after another and use the whole pool inside.
pub fn for_each_unit(
    units: &[usize],
    work: impl Fn(usize) -> anyhow::Result<()> + Sync,
) -> anyhow::Result<()> {
    let threads = rayon::current_num_threads();
    if units.len() < threads {
        return units.iter().try_for_each(|&unit| {
            crate::interrupt::check()?;
            work(unit)
        });
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failure = Mutex::new(None);
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                let pool = match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
                    Ok(pool) => pool,
                    Err(error) => return record_failure(&failure, error.into()),
                };
                loop {
                    let index = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(&unit) = units.get(index) else {
                        return;
                    };
                    let result = crate::interrupt::check()
                        .map_err(anyhow::Error::from)
                        .and_then(|()| pool.install(|| work(unit)));
                    if let Err(error) = result {
                        next.store(units.len(), std::sync::atomic::Ordering::Relaxed);
                        return record_failure(&failure, error);
                    }
                }
            });
        }
    });
    match failure.into_inner().unwrap_or_else(|p| p.into_inner()) {
        Some(error) => Err(error),
        None => Ok(()),
    }
}

fn record_failure(failure: &Mutex<Option<anyhow::Error>>, error: anyhow::Error) {
    let mut slot = failure.lock().unwrap_or_else(|p| p.into_inner());
    slot.get_or_insert(error);
}

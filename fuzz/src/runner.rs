//! Runs a target over the corpus and then over mutants, for a number of cases or seconds.
//!
//! Each case runs on a worker thread under `catch_unwind`; the calling thread waits for it with
//! a timeout, so a panic is caught and recorded and a hang is detected instead of stalling the
//! campaign. Findings are written to the crash directory named by target, kind and input hash,
//! ready to be moved into `fuzz/regressions/<target>/` once fixed. A hung worker cannot be
//! stopped from outside, so a hang ends the campaign (the caller exits the process).

use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::mutate::{Corruption, Mutator};
use crate::targets::{Outcome, Target, Workspace};

/// When a campaign stops, and how long one case may take.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    pub cases: Option<u64>,
    pub duration: Option<Duration>,
    pub case_timeout: Duration,
}

/// Where a campaign's inputs come from.
pub enum Inputs {
    /// The corpus as is, then mutants of it.
    Mutants,
    /// Only corruptions of the corpus, cycling through every [`Corruption`].
    Corruptions,
}

#[derive(Debug, Default)]
pub struct Report {
    pub executions: u64,
    pub accepted: u64,
    pub rejected: u64,
    /// Saved crash files, one per distinct panic message location.
    pub panics: Vec<(PathBuf, String)>,
    /// Every panicking case, including repeats of a saved one.
    pub panicking_cases: u64,
    pub hang: Option<PathBuf>,
    pub elapsed: Duration,
}

type CaseResult = Result<Outcome, String>;

/// Runs one campaign of `target` over `corpus` (non-empty), seeded with `seed`.
pub fn run_campaign(
    target: Target,
    corpus: Vec<Vec<u8>>,
    inputs: Inputs,
    seed: u64,
    limits: Limits,
    scratch: &Path,
    crashes: &Path,
) -> std::io::Result<Report> {
    assert!(!corpus.is_empty(), "a campaign needs a corpus");
    let last_panic = capture_panic_messages();
    let (case_sender, case_receiver) = mpsc::channel::<Vec<u8>>();
    let (result_sender, result_receiver) = mpsc::channel::<CaseResult>();
    let workspace = Workspace::new(scratch)?;
    std::thread::spawn(move || {
        for bytes in case_receiver {
            let result = panic::catch_unwind(AssertUnwindSafe(|| workspace.run(target, &bytes)))
                .map_err(|_| {
                    last_panic
                        .lock()
                        .map(|m| m.clone())
                        .unwrap_or_default()
                        .unwrap_or_else(|| "panic without a message".into())
                });
            if result_sender.send(result).is_err() {
                break;
            }
        }
    });

    let mut mutator = Mutator::new(seed, target.structure());
    let start = Instant::now();
    let mut report = Report::default();
    let mut case = 0u64;
    loop {
        let out_of_cases = limits.cases.is_some_and(|n| case >= n);
        let out_of_time = limits.duration.is_some_and(|d| start.elapsed() >= d);
        if out_of_cases || out_of_time {
            break;
        }
        let source = &corpus[case as usize % corpus.len()];
        let bytes = match inputs {
            Inputs::Mutants if case < corpus.len() as u64 => source.clone(),
            Inputs::Mutants => mutator.mutate(source, &corpus),
            Inputs::Corruptions => {
                let kind = Corruption::ALL[(case / corpus.len() as u64) as usize % 3];
                mutator.corrupt(source, kind)
            }
        };
        case += 1;
        case_sender
            .send(bytes.clone())
            .expect("the worker is alive");
        report.executions += 1;
        match result_receiver.recv_timeout(limits.case_timeout) {
            Ok(Ok(Outcome::Accepted)) => report.accepted += 1,
            Ok(Ok(Outcome::Rejected)) => report.rejected += 1,
            Ok(Err(message)) => {
                report.panicking_cases += 1;
                let site = panic_site(&message);
                if !report.panics.iter().any(|(_, m)| panic_site(m) == site) {
                    let path = save(crashes, target, "panic", &bytes)?;
                    report.panics.push((path, message));
                }
            }
            Err(_) => {
                report.hang = Some(save(crashes, target, "hang", &bytes)?);
                break;
            }
        }
    }
    report.elapsed = start.elapsed();
    Ok(report)
}

/// Replaces the panic hook with one that keeps the last message instead of printing it, so a
/// campaign's output stays readable; the worker reads it after `catch_unwind`.
fn capture_panic_messages() -> Arc<Mutex<Option<String>>> {
    let last = Arc::new(Mutex::new(None));
    let slot = Arc::clone(&last);
    panic::set_hook(Box::new(move |info| {
        if let Ok(mut message) = slot.lock() {
            *message = Some(info.to_string());
        }
    }));
    last
}

/// The `file:line:column` part of a hook message: panics at one site count as one finding.
fn panic_site(message: &str) -> &str {
    message
        .lines()
        .next()
        .unwrap_or_default()
        .trim_start_matches("panicked at ")
        .trim_end_matches(':')
}

fn save(crashes: &Path, target: Target, kind: &str, bytes: &[u8]) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(crashes)?;
    let hash = xxhash_rust::xxh3::xxh3_64(bytes);
    let path = crashes.join(format!(
        "{}-{kind}-{hash:016x}.{}",
        target.name(),
        target.extension()
    ));
    std::fs::write(&path, bytes)?;
    Ok(path)
}

/// Every file of `dir` (none if it does not exist), sorted by name.
pub fn read_corpus(dir: &Path) -> std::io::Result<Vec<Vec<u8>>> {
    let mut paths: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(entries) => entries
            .map(|entry| entry.map(|e| e.path()))
            .collect::<Result<_, _>>()?,
        Err(error) if error.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(error) => return Err(error),
    };
    paths.sort();
    paths.iter().map(std::fs::read).collect()
}

//! `reducem-fuzz`: runs fuzz campaigns and (re)writes the generated seed corpus.
//!
//! ```text
//! reducem-fuzz run all --seconds 1800        # every target, 30 minutes each
//! reducem-fuzz run reducem --cases 100000    # one target, fixed number of cases
//! reducem-fuzz run reducem --corruptions --cases 100000   # bit flips, truncations, swaps only
//! reducem-fuzz seed fuzz/corpus
//! ```
//!
//! One line per target reports executions, accepted and rejected inputs, panics and hangs; the
//! exit status is non-zero when anything was found.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use reducem_fuzz::runner::{read_corpus, run_campaign, Inputs, Limits};
use reducem_fuzz::seeds::write_seeds;
use reducem_fuzz::targets::Target;

#[derive(Parser)]
#[command(
    name = "reducem-fuzz",
    about = "Mutation fuzzing of reducem on stable Rust"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fuzz one target (ply, obj, stl, reducem, rays) or `all`, one after the other.
    Run {
        target: String,
        /// Stop each target after this many seconds.
        #[arg(long)]
        seconds: Option<u64>,
        /// Stop each target after this many cases.
        #[arg(long)]
        cases: Option<u64>,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Only corrupt the corpus (bit flips, truncations, section swaps) instead of mutating.
        #[arg(long)]
        corruptions: bool,
        /// A case running longer than this is a hang.
        #[arg(long, default_value_t = 20)]
        case_timeout_seconds: u64,
        #[arg(long, default_value = "fuzz/corpus")]
        corpus: PathBuf,
        #[arg(long, default_value = "fuzz/crashes")]
        crashes: PathBuf,
        /// Threads for the code under test (rayon); 1 keeps a campaign to one core.
        #[arg(long, default_value_t = 1)]
        threads: usize,
    },
    /// Write the generated seeds (ReduceM, ray and binary PLY files) into a corpus directory.
    Seed { corpus: PathBuf },
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Seed { corpus } => match write_seeds(&corpus) {
            Ok(()) => ExitCode::SUCCESS,
            Err(error) => {
                eprintln!("reducem-fuzz: {}: {error}", corpus.display());
                ExitCode::FAILURE
            }
        },
        Command::Run {
            target,
            seconds,
            cases,
            seed,
            corruptions,
            case_timeout_seconds,
            corpus,
            crashes,
            threads,
        } => {
            let targets = if target == "all" {
                Target::ALL.to_vec()
            } else if let Some(target) = Target::from_name(&target) {
                vec![target]
            } else {
                eprintln!("reducem-fuzz: unknown target {target:?} (ply, obj, reducem, rays, all)");
                return ExitCode::FAILURE;
            };
            if seconds.is_none() && cases.is_none() {
                eprintln!("reducem-fuzz: give --seconds or --cases");
                return ExitCode::FAILURE;
            }
            rayon_threads(threads);
            let limits = Limits {
                cases,
                duration: seconds.map(Duration::from_secs),
                case_timeout: Duration::from_secs(case_timeout_seconds),
            };
            let mut clean = true;
            for target in targets {
                match campaign(target, seed, corruptions, limits, &corpus, &crashes) {
                    Ok(found_nothing) => clean &= found_nothing,
                    Err(error) => {
                        eprintln!("reducem-fuzz: {}: {error}", target.name());
                        return ExitCode::FAILURE;
                    }
                }
            }
            if clean {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

/// Runs and reports one target; `Ok(true)` when nothing was found.
fn campaign(
    target: Target,
    seed: u64,
    corruptions: bool,
    limits: Limits,
    corpus: &std::path::Path,
    crashes: &std::path::Path,
) -> std::io::Result<bool> {
    let inputs = read_corpus(&corpus.join(target.name()))?;
    if inputs.is_empty() {
        return Err(std::io::Error::other(format!(
            "no seeds in {}",
            corpus.join(target.name()).display()
        )));
    }
    let scratch = std::env::temp_dir().join(format!(
        "reducem-fuzz-{}-{}",
        target.name(),
        std::process::id()
    ));
    let mode = if corruptions {
        Inputs::Corruptions
    } else {
        Inputs::Mutants
    };
    let report = run_campaign(target, inputs, mode, seed, limits, &scratch, crashes)?;
    let seconds = report.elapsed.as_secs_f64();
    println!(
        "{}: {} executions in {seconds:.0} s ({:.0}/s), {} accepted, {} rejected, \
         {} panicking cases ({} distinct), {} hangs",
        target.name(),
        report.executions,
        report.executions as f64 / seconds.max(1e-9),
        report.accepted,
        report.rejected,
        report.panicking_cases,
        report.panics.len(),
        u8::from(report.hang.is_some()),
    );
    for (path, message) in &report.panics {
        println!("  panic saved to {}: {message}", path.display());
    }
    if let Some(path) = &report.hang {
        println!("  hang saved to {}", path.display());
        // The hung worker cannot be stopped; leave before it holds up the next target.
        std::process::exit(2);
    }
    std::fs::remove_dir_all(&scratch)?;
    Ok(report.panics.is_empty())
}

fn rayon_threads(threads: usize) {
    // Only fails if the global pool already exists, which nothing here creates first.
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global();
}

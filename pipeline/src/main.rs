//! The `pipeline` command: converts meshes to ReduceM files (`run`, `status`, `clean`) and
//! generates synthetic meshes (`gen`). Exit codes are a contract with cron jobs and are listed in README.md.

mod chunk_io;
mod config;
mod fingerprint;
mod input;
mod interrupt;
mod lock;
mod manifest;
mod progress;
mod run;
mod stage;
mod status;
mod workdir;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use reducem::gen;

/// mimalloc returns freed chunk memory to the system promptly; with glibc's per-thread arenas
/// the resident set of a long run crept up chunk after chunk (6.3 GB peak over 76 chunks
/// against 2.4 GB over 26, for the same chunk size).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Exit codes (sysexits.h values, as batch schedulers expect).
mod exit {
    pub const USAGE: u8 = 64;
    pub const BAD_INPUT: u8 = 65;
    pub const INTERNAL: u8 = 70;
    pub const IO: u8 = 74;
    pub const TEMPORARY: u8 = 75;
    pub const CONFIG: u8 = 78;
}

#[derive(Parser)]
#[command(
    name = "pipeline",
    version,
    about = "Convert massive meshes to ReduceM files"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run (or resume) the conversion described by CONFIG.
    Run {
        config: PathBuf,
        /// Progress bars on a terminal, plain log lines otherwise; or force one.
        #[arg(long, value_enum, default_value_t = progress::LogFormat::Auto)]
        log_format: progress::LogFormat,
        /// When another run holds the work directory: fail with exit code 75, or skip with 0.
        #[arg(long, value_enum, default_value_t = run::IfLocked::Fail)]
        if_locked: run::IfLocked,
        /// Run only this stage; the stages before it must be done.
        #[arg(long, value_enum)]
        stage: Option<run::StageName>,
        /// With `--stage strip`: process only chunks c with c mod N = I. Defaults to
        /// SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT when those are set.
        #[arg(long, value_name = "I/N")]
        shard: Option<run::Shard>,
    },
    /// List stages and chunks as done, pending or stale, with the reason.
    Status { config: PathBuf },
    /// Remove the work directory of CONFIG.
    Clean { config: PathBuf },
    /// Stream a synthetic mesh to binary PLY.
    Gen {
        kind: gen::Kind,
        #[arg(long)]
        triangles: u64,
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(error) => {
            let code = if error.use_stderr() { exit::USAGE } else { 0 };
            let _ = error.print();
            return ExitCode::from(code);
        }
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("pipeline: error: {error:#}");
            ExitCode::from(exit_code(&error))
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run {
            config,
            log_format,
            if_locked,
            stage,
            shard,
        } => {
            interrupt::install()?;
            let shard = match (shard, stage) {
                (Some(shard), _) => shard,
                (None, Some(run::StageName::Strip)) => run::Shard::from_slurm_env()?,
                (None, _) => run::Shard::WHOLE,
            };
            let options = run::RunOptions {
                log_format,
                if_locked,
                stage,
                shard,
            };
            run::run(&config, &options)
        }
        Command::Status { config } => status::status(&config),
        Command::Clean { config } => run::clean(&config),
        Command::Gen {
            kind,
            triangles,
            output,
            seed,
        } => {
            let summary = gen::generate(kind, triangles, seed, &output)?;
            eprintln!(
                "pipeline: wrote {} ({} vertices, {} triangles)",
                output.display(),
                summary.vertices,
                summary.triangles
            );
            Ok(())
        }
    }
}

/// Classifies an error by the typed errors in its chain.
fn exit_code(error: &anyhow::Error) -> u8 {
    for cause in error.chain() {
        if cause.is::<run::UsageError>() {
            return exit::USAGE;
        }
        if cause.is::<lock::LockedError>()
            || cause.is::<interrupt::Interrupted>()
            || cause.is::<run::UpstreamPending>()
        {
            return exit::TEMPORARY;
        }
        if cause.is::<config::ConfigError>() {
            return exit::CONFIG;
        }
        if cause.is::<reducem::input::InputError>() {
            return exit::BAD_INPUT;
        }
        if cause.is::<std::io::Error>() || cause.is::<reducem::format::writer::WriteError>() {
            return exit::IO;
        }
    }
    exit::INTERNAL
}

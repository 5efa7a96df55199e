//! The `pipeline` command: converts meshes to ReduceM files (`run`, `status`, `clean`) and
//! generates synthetic meshes (`gen`). Exit codes are a contract with cron jobs and are listed in README.md.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Parser, Subcommand};
use pipeline::{config, convert, interrupt, outcome, progress, run, status};
use reducem::exit_code as exit;
use reducem_gen as gen;

/// mimalloc returns freed chunk memory to the system promptly; with glibc's per-thread arenas
/// the resident set of a long run crept up chunk after chunk (6.3 GB peak over 76 chunks
/// against 2.4 GB over 26, for the same chunk size).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "pipeline",
    version,
    about = "Convert massive meshes to ReduceM files",
    after_help = exit::HELP
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// How a job runs, for `run` and `convert` alike.
#[derive(clap::Args)]
struct JobFlags {
    /// Progress bars on a terminal, plain log lines otherwise; or force one.
    #[arg(long, value_enum, default_value_t = progress::LogFormat::Auto)]
    log_format: progress::LogFormat,
    /// When another run holds the work directory: fail with exit code 75, skip with 0, or
    /// wait for it to finish (with =SECONDS at most that long, then fail with 75).
    #[arg(long, default_value = "fail", value_name = "fail|skip|wait[=SECONDS]")]
    if_locked: run::IfLocked,
    /// Remove the work directory after a successful run (as `[work] keep = false`).
    #[arg(long)]
    clean_after: bool,
}

impl JobFlags {
    fn options(self, stage: Option<run::StageName>, shard: run::Shard) -> run::RunOptions {
        run::RunOptions {
            log_format: self.log_format,
            clean_after: self.clean_after,
            if_locked: self.if_locked,
            stage,
            shard,
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Run (or resume) the conversion described by CONFIG.
    #[command(after_help = exit::HELP)]
    Run {
        /// The job's configuration file (TOML; see README.md, Configuration).
        config: PathBuf,
        #[command(flatten)]
        job: JobFlags,
        /// Run only this stage; the stages before it must be done.
        #[arg(long, value_enum)]
        stage: Option<run::StageName>,
        /// With `--stage strip`: process only chunks c with c mod N = I. Defaults to
        /// SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT when those are set.
        #[arg(long, value_name = "I/N")]
        shard: Option<run::Shard>,
    },
    /// Convert one mesh without a configuration file: writes the equivalent configuration to
    /// WORK/convert.toml and runs (or resumes) it like `run`.
    #[command(after_help = exit::HELP)]
    Convert {
        #[arg(help = convert_input_help())]
        input: PathBuf,
        /// The ReduceM file to write.
        #[arg(short, long)]
        output: PathBuf,
        /// Most triangles per strip (default 20; shorter strips trace faster, cost more bytes).
        #[arg(long)]
        max_length: Option<usize>,
        /// Vertex encoding: f32 (lossless, the default) or grid (quantized).
        #[arg(long, value_enum)]
        encoding: Option<config::VertexEncodingName>,
        /// Grid bits per axis with --encoding grid, 1 to 24 (default 20).
        #[arg(long, requires = "encoding")]
        grid_bits: Option<u32>,
        /// Work directory for intermediate files (default OUTPUT.work).
        #[arg(long)]
        work: Option<PathBuf>,
        #[command(flatten)]
        attributes: AttributeFlags,
        /// Keep the work directory after a successful conversion (it is removed by default; an
        /// unfinished conversion always keeps it, to resume).
        #[arg(long, conflicts_with = "clean_after")]
        keep_work: bool,
        #[command(flatten)]
        job: JobFlags,
    },
    /// List stages and chunks as done, pending or stale, with the reason.
    #[command(after_help = exit::HELP)]
    Status {
        /// The job's configuration file.
        config: PathBuf,
    },
    /// Remove the work directory of CONFIG (only one that pipeline made).
    #[command(after_help = exit::HELP)]
    Clean {
        /// The job's configuration file.
        config: PathBuf,
    },
    /// Stream a synthetic mesh to binary PLY (STL or GLB for a .stl or .glb output).
    #[command(after_help = exit::HELP)]
    Gen {
        /// The kind of mesh.
        #[arg(value_parser = kind_parser())]
        kind: gen::Kind,
        /// About how many triangles: each kind rounds to its own structure (a 1M isosurface
        /// has 1,000,772); at least the kind's smallest mesh (terrain, cad 2; scan, soup 18;
        /// sphere 20; isosurface 96).
        #[arg(long)]
        triangles: u64,
        /// The file to write: binary PLY, binary STL for a .stl name, GLB for a .glb name.
        #[arg(short, long)]
        output: PathBuf,
        /// Seed of the generator: the same seed gives the same mesh.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// With a .stl output: ASCII STL instead of binary.
        #[arg(long)]
        ascii: bool,
        /// With a .glb output: positions quantized to unsigned shorts (KHR_mesh_quantization)
        /// instead of floats.
        #[arg(long)]
        quantized: bool,
    },
}

/// The format `pipeline gen` writes `output` in: by its extension, `--ascii` for STL and
/// `--quantized` for GLB.
fn gen_output_format(
    output: &Path,
    ascii: bool,
    quantized: bool,
) -> anyhow::Result<gen::OutputFormat> {
    use gen::OutputFormat::{Glb, Stl};
    Ok(
        match (gen::OutputFormat::for_path(output), ascii, quantized) {
            (Stl(_), true, false) => Stl(gen::StlFlavour::Ascii),
            (Glb(_), false, true) => Glb(gen::GlbFlavour::Quantized),
            (_, true, _) => anyhow::bail!(exit::UsageError("--ascii needs a .stl output".into())),
            (_, _, true) => {
                anyhow::bail!(exit::UsageError("--quantized needs a .glb output".into()))
            }
            (format, false, false) => format,
        },
    )
}

/// `pipeline gen`'s KIND: the generator's kinds, each with its description in `--help` (the
/// library's `Kind` knows nothing of clap).
/// The input formats, from reducem's table of formats.
fn convert_input_help() -> String {
    format!(
        "The mesh to convert ({}, plain or gzip/zstd-compressed)",
        reducem::input::format_names()
    )
}

fn kind_parser() -> impl clap::builder::TypedValueParser<Value = gen::Kind> {
    let kinds = gen::Kind::ALL.map(|kind| PossibleValue::new(kind.name()).help(kind.description()));
    PossibleValuesParser::new(kinds).try_map(|name| name.parse::<gen::Kind>())
}

fn main() -> ExitCode {
    let started = std::time::Instant::now();
    let cli = match reducem::cli::parse_or_exit::<Cli>() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    let json = cli.command.log_format() == Some(progress::LogFormat::Json);
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            if json {
                let seconds = started.elapsed().as_secs_f64();
                eprintln!("{}", outcome::error_json(&error, seconds));
            } else if error
                .chain()
                .any(|cause| cause.is::<interrupt::Interrupted>())
            {
                eprintln!("pipeline: {error:#}");
            } else {
                eprintln!("pipeline: error: {error:#}");
            }
            ExitCode::from(outcome::classify(&error).0)
        }
    }
}

impl Command {
    fn log_format(&self) -> Option<progress::LogFormat> {
        match self {
            Command::Run { job, .. } | Command::Convert { job, .. } => Some(job.log_format),
            _ => None,
        }
    }
}

/// `pipeline convert`'s `[attributes]` keys.
#[derive(Clone, Debug, clap::Args)]
struct AttributeFlags {
    /// Store the input face id of every triangle ([attributes] face_ids).
    #[arg(long)]
    face_ids: bool,
    /// Store per-vertex normals from the input: oct8 (2 bytes, within 0.64 degrees) or oct16
    /// (4 bytes, within 0.0073 degrees) per stored vertex ([attributes] normals).
    #[arg(long, value_parser = normal_encodings())]
    normals: Option<String>,
    /// Store per-vertex RGBA8 colours from the input ([attributes] colors).
    #[arg(long)]
    colors: bool,
}

/// The values of `--normals`, described.
fn normal_encodings() -> clap::builder::PossibleValuesParser {
    use clap::builder::PossibleValue;
    clap::builder::PossibleValuesParser::new([
        PossibleValue::new("none").help("No normals (the default)"),
        PossibleValue::new("oct8").help("Two signed bytes per stored vertex"),
        PossibleValue::new("oct16").help("Two signed 16-bit words per stored vertex"),
    ])
}

impl AttributeFlags {
    /// The flags as configuration settings (none for what was not asked for).
    fn settings(&self) -> Vec<(String, String)> {
        let mut settings = Vec::new();
        if self.face_ids {
            settings.push(("face_ids".to_string(), "true".to_string()));
        }
        if let Some(normals) = &self.normals {
            settings.push(("normals".to_string(), format!("\"{normals}\"")));
        }
        if self.colors {
            settings.push(("colors".to_string(), "true".to_string()));
        }
        settings
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run {
            config,
            job,
            stage,
            shard,
        } => {
            interrupt::install()?;
            let shard = match (shard, stage) {
                (Some(shard), _) => shard,
                (None, Some(run::StageName::Strip)) => run::Shard::from_slurm_env()?,
                (None, _) => run::Shard::WHOLE,
            };
            run::run(&config, &job.options(stage, shard))
        }
        Command::Convert {
            input,
            output,
            max_length,
            encoding,
            grid_bits,
            work,
            attributes,
            keep_work,
            job,
        } => {
            interrupt::install()?;
            let mut options = job.options(None, run::Shard::WHOLE);
            options.clean_after = !keep_work;
            let args = convert::ConvertArgs {
                input,
                output,
                max_length,
                encoding,
                grid_bits,
                work,
                settings: attributes.settings(),
            };
            convert::convert(&args, &options)
        }
        Command::Status { config } => status::status(&config),
        Command::Clean { config } => run::clean(&config),
        Command::Gen {
            kind,
            triangles,
            output,
            seed,
            ascii,
            quantized,
        } => {
            reducem_core::signals::install_for_tool()?;
            if let Some(message) = config::too_few_triangles(kind, triangles) {
                anyhow::bail!(exit::UsageError(format!("--triangles {message}")));
            }
            let format = gen_output_format(&output, ascii, quantized)?;
            let summary = gen::generate_as(kind, triangles, seed, &output, format)?;
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

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    #[test]
    fn every_argument_of_every_command_has_a_description() {
        let undescribed = reducem::cli::undescribed_arguments(&super::Cli::command());
        assert!(undescribed.is_empty(), "no description: {undescribed:?}");
    }
}

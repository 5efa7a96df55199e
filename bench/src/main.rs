//! The `reducem-bench` command: measurements of ReduceM that need the tools beside the paper
//! (generated meshes, the baseline BVH, meshoptimizer, Embree), so they live outside `reducem`.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use reducem::exit_code;
use reducem_bench::report::{self, ReportConfig, Scale};

#[derive(Parser)]
#[command(
    name = "reducem-bench",
    version,
    about = "Measure ReduceM against its peers",
    after_help = exit_code::HELP
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Measure the trade-offs report: OUT/REPORT.md with its tables, plots and images.
    #[command(after_help = exit_code::HELP)]
    Report {
        /// Mesh and image sizes: tiny (seconds), medium (minutes), full (about 30 minutes).
        #[arg(long, value_enum, default_value = "full")]
        scale: Scale,
        /// Directory of the report (REPORT.md, plots, images).
        #[arg(long, default_value = "report")]
        out: PathBuf,
        /// Generated meshes (kept between runs) and converted files.
        #[arg(long, default_value = "target/report-work")]
        work: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = match reducem::cli::parse_or_exit::<Cli>() {
        Ok(cli) => cli,
        Err(code) => return code,
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("reducem-bench: error: {error:#}");
            ExitCode::from(exit_code_of(&error))
        }
    }
}

/// Reading and writing failures are I/O (74); anything else is internal (70), since the report
/// reads no user input besides its arguments.
fn exit_code_of(error: &anyhow::Error) -> u8 {
    if error.chain().any(|cause| cause.is::<std::io::Error>()) {
        exit_code::IO
    } else {
        exit_code::INTERNAL
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Report { scale, out, work } => {
            let config = ReportConfig {
                scale,
                out_dir: out,
                work_dir: work,
            };
            let (_, written) = report::run(&config)?;
            println!("wrote {}", written.report.display());
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

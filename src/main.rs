//! The `reducem` command: inspect, decode (and, later, render and query) ReduceM files.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};
use reducem::format::reader::ReducemFile;

#[derive(Parser)]
#[command(name = "reducem", version, about = "Inspect and decode ReduceM files")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print the statistics of a ReduceM file.
    Inspect {
        file: PathBuf,
        /// One JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Also verify every section checksum (reads the whole file).
        #[arg(long)]
        verify: bool,
    },
    /// Write every encoded triangle, in input winding, as binary little-endian PLY.
    Decode {
        file: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
    },
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("reducem: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Inspect { file, json, verify } => inspect(&file, json, verify),
        Command::Decode { file, output } => {
            let opened = ReducemFile::open(&file)?;
            reducem::decode::write_ply(&opened, &output)
                .with_context(|| format!("writing {}", output.display()))
        }
    }
}

fn inspect(path: &std::path::Path, json: bool, verify: bool) -> anyhow::Result<()> {
    let file = ReducemFile::open(path)?;
    if verify {
        file.verify_checksums()?;
    }
    let stats = reducem::inspect::file_stats(&file);
    if json {
        println!("{}", serde_json::to_string(&stats)?);
        return Ok(());
    }
    println!("{}", path.display());
    println!(
        "  triangles          {} ({} dropped as degenerate)",
        stats.triangles, stats.dropped_triangles
    );
    println!(
        "  strips             {} (avg {:.2}, max {} triangles)",
        stats.strips, stats.avg_strip_length, stats.max_strip_length
    );
    println!(
        "  vertices           {} input, {} stored ({} for the strip hierarchies: {:.2}%)",
        stats.input_vertices,
        stats.stored_vertices,
        stats.hierarchy_vertices,
        stats.hierarchy_overhead_pct
    );
    println!(
        "  file               {} bytes, {:.2} bytes/triangle",
        stats.file_bytes, stats.bytes_per_triangle
    );
    for (section, bytes) in &stats.bytes_by_section {
        println!(
            "    {section:<16} {bytes:>14} bytes  {:>6.2} B/tri",
            *bytes as f64 / stats.triangles.max(1) as f64
        );
    }
    if verify {
        println!("  checksums          ok");
    }
    Ok(())
}

//! The `reducem` command: inspect, decode, query and render ReduceM files.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};
use reducem::format::reader::ReducemFile;
use reducem::trace::{ray_file, Kernel, TraceOptions, Tracer};

#[derive(Parser)]
#[command(
    name = "reducem",
    version,
    about = "Inspect, decode, query and render ReduceM files"
)]
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
    /// Write every encoded triangle, in input winding, as binary little-endian PLY (positions as
    /// stored: the quantized ones for a grid file).
    Decode {
        file: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Trace a binary ray file (f32 x 8 per ray: origin, direction, tmin, tmax) and write the
    /// closest hits (f32 x 4 per ray: t, normal; t = inf on a miss) or, with --occluded, one byte
    /// per ray (1 = occluded).
    Query {
        file: PathBuf,
        #[arg(long)]
        rays: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long)]
        occluded: bool,
    },
    /// Render an image of the model as a scene file describes it, tracing only the effects the
    /// scene asks for.
    Render {
        file: PathBuf,
        #[arg(long)]
        scene: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
        /// Print the report as one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Measure the trade-offs report: OUT/REPORT.md with its tables, plots and images.
    #[cfg(feature = "report")]
    Report {
        /// Mesh and image sizes: tiny (seconds), medium (minutes), full (about 30 minutes).
        #[arg(long, value_enum, default_value = "full")]
        scale: reducem::report::Scale,
        #[arg(long, default_value = "report")]
        out: PathBuf,
        /// Generated meshes (kept between runs) and converted files.
        #[arg(long, default_value = "target/report-work")]
        work: PathBuf,
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
        Command::Query {
            file,
            rays,
            output,
            occluded,
        } => query(&file, &rays, &output, occluded),
        Command::Render {
            file,
            scene,
            output,
            json,
        } => render(&file, &scene, &output, json),
        #[cfg(feature = "report")]
        Command::Report { scale, out, work } => report(scale, out, work),
    }
}

#[cfg(feature = "report")]
fn report(
    scale: reducem::report::Scale,
    out_dir: PathBuf,
    work_dir: PathBuf,
) -> anyhow::Result<()> {
    let config = reducem::report::ReportConfig {
        scale,
        out_dir,
        work_dir,
    };
    let (_, written) = reducem::report::run(&config)?;
    println!("wrote {}", written.report.display());
    Ok(())
}

fn query(path: &Path, rays: &Path, output: &Path, occluded: bool) -> anyhow::Result<()> {
    let kernel = Kernel::from_env()?;
    // Opening validates the model and reading parses the rays: both on every core, together.
    let (rays, file) = rayon::join(|| ray_file::read_rays(rays), || ReducemFile::open(path));
    let (rays, file) = (rays?, file?);
    let tracer = Tracer::new(
        &file,
        TraceOptions {
            kernel,
            ..TraceOptions::default()
        },
    );
    let bytes = if occluded {
        ray_file::trace_occlusion(&tracer, &rays)
    } else {
        ray_file::trace_hits(&tracer, &rays)
    };
    ray_file::write_atomically(output, &bytes)
        .with_context(|| format!("writing {}", output.display()))
}

fn render(path: &Path, scene: &Path, output: &Path, json: bool) -> anyhow::Result<()> {
    let scene = reducem::render::scene::Scene::load(scene)?;
    let file = ReducemFile::open(path)?;
    let report = reducem::render::render_to_png(&file, &scene, output)?;
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{report}");
    }
    Ok(())
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
        "  top level          {} nodes of {} children, {} bytes each",
        stats.top_nodes,
        reducem::format::TOP_WIDTH,
        stats.top_node_bytes
    );
    println!(
        "  vertices stored as {}",
        match stats.grid_bits {
            0 => "f32 (lossless)".to_string(),
            bits => format!("points of a {bits}-bit grid, cell {:e}", stats.grid_cell),
        }
    );
    println!(
        "  position error     max {:.3e} ({:.3e} of the diagonal), rms {:.3e} ({:.3e})",
        stats.position_error_max,
        stats.position_error_max_relative,
        stats.position_error_rms,
        stats.position_error_rms_relative
    );
    if stats.weld_tolerance > 0.0 {
        println!(
            "  weld               {} vertices merged within {:e}: moved max {:.3e}, rms {:.3e}",
            stats.welded_vertices,
            stats.weld_tolerance,
            stats.weld_displacement_max,
            stats.weld_displacement_rms
        );
    }
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

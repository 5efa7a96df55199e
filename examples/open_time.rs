//! Time to open a model and trace its first ray, in one fresh process, advised as `reducem query`
//! advises a one-ray batch: what a batch job that asks one question of a big model waits for. Prints `open_ms trace_ms hit`. Run through
//! `scripts/bench_open.sh`, which drops the model's pages for the cold figures and takes medians.

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use reducem::format::reader::{ReducemFile, Validation};
use reducem::trace::ray_file::read_rays;
use reducem::trace::{TraceOptions, Tracer};

#[derive(Parser)]
struct Args {
    model: PathBuf,
    /// A ray file whose first ray is traced.
    #[arg(long)]
    rays: PathBuf,
    /// Validate every strip and node at open (as before lazy validation) instead of on first use.
    #[arg(long)]
    full: bool,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let rays = read_rays(&args.rays)?;
    let validation = if args.full {
        Validation::Full
    } else {
        Validation::Lazy
    };
    let started = Instant::now();
    let file = ReducemFile::open_with(&args.model, validation)?;
    let opened = started.elapsed();
    // What `reducem query` does for a batch this small.
    file.advise_batch(1);
    let tracer = Tracer::new(&file, TraceOptions::default());
    let hit = tracer.intersect(&rays[0]);
    let traced = started.elapsed() - opened;
    if let Some(defect) = file.defect() {
        return Err(defect.into());
    }
    println!(
        "{:.3} {:.3} {}",
        opened.as_secs_f64() * 1e3,
        traced.as_secs_f64() * 1e3,
        hit.is_some()
    );
    Ok(())
}

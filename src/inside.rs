//! `reducem inside`: whether each point of a point file is inside the surface.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use reducem::output::Destination;
use reducem::query::occupancy;

use crate::closest::{in_pool, points_and_file};

#[derive(Clone, Debug, clap::Args)]
pub struct InsideArgs {
    /// The ReduceM file.
    pub file: PathBuf,
    /// The point file: f32 x 3 per point (x, y, z), little endian; `-` reads standard input.
    #[arg(long)]
    points: PathBuf,
    /// The answer file (replaced atomically; `-` or a device or FIFO written directly; never an
    /// input): one u8 per point, 1 inside, 0 outside.
    #[arg(short, long)]
    output: PathBuf,
    /// Rays per point on a mesh that is not closed (inside when most cross the surface an odd
    /// number of times); a closed mesh needs one ray and the answer is exact.
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    samples: u32,
    /// Worker threads; 0 uses one per core.
    #[arg(long, value_name = "N", default_value_t = 0)]
    threads: usize,
}

pub fn run(args: InsideArgs) -> anyhow::Result<()> {
    let output = Destination::prepare(&args.output, &[&args.file, &args.points])?;
    in_pool(args.threads, || answer(&args, &output))
}

fn answer(args: &InsideArgs, output: &Destination) -> anyhow::Result<()> {
    let (points, file) = points_and_file(&args.points, &args.file)?;
    let started = Instant::now();
    let answers = occupancy(&file, &points, args.samples);
    let seconds = started.elapsed().as_secs_f64();
    super::complete(&file)?;
    let bytes: Vec<u8> = answers
        .inside
        .iter()
        .map(|&inside| u8::from(inside))
        .collect();
    output
        .write(|out| out.write_all(&bytes))
        .with_context(|| format!("writing {}", output.name()))?;
    let inside = answers.inside.iter().filter(|&&inside| inside).count();
    eprintln!(
        "reducem: inside: points={} inside={inside} exact={} seconds={seconds:.6} threads={}",
        points.len(),
        answers.exact,
        rayon::current_num_threads()
    );
    Ok(())
}

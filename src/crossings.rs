//! `reducem query --count` and `--all`: every crossing of every ray of a ray file, counted or
//! listed (docs/QUERIES.md).

use std::path::Path;
use std::time::Instant;

use anyhow::Context;

use reducem::format::reader::ReducemFile;
use reducem::output::Destination;
use reducem::query::{all_hits_on, count_crossings_on, AllHits, FaceIds};
use reducem::trace::ray_file::{InvalidRays, RayFile};
use reducem::trace::Kernel;

/// What `query` answers about every crossing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crossings {
    /// A `u32` per ray.
    Count,
    /// Per ray a `u32` n, then n records of `f32 t, u32 face id, f32 u, f32 v`.
    All,
}

pub fn run(
    path: &Path,
    rays_path: &Path,
    output: &Destination,
    mode: Crossings,
    invalid_rays: InvalidRays,
) -> anyhow::Result<()> {
    let kernel = Kernel::from_env()?;
    let (rays, file) = rayon::join(
        || RayFile::open(rays_path, invalid_rays),
        || ReducemFile::open(path),
    );
    let (rays, file) = (rays?, file?);
    file.advise_batch(rays.len());
    let started = Instant::now();
    let (bytes, crossings) = match mode {
        Crossings::Count => {
            let counts = count_crossings_on(&file, rays.records(), kernel);
            let total = counts.iter().map(|&n| u64::from(n)).sum::<u64>();
            (counts.iter().flat_map(|n| n.to_le_bytes()).collect(), total)
        }
        Crossings::All => {
            let hits = all_hits_on(&file, rays.records(), &FaceIds::of(&file), kernel);
            (encode_all(&hits), hits.hits.len() as u64)
        }
    };
    let seconds = started.elapsed().as_secs_f64();
    // Answers that met a corrupt part of a lazily validated file are incomplete.
    super::complete(&file)?;
    output
        .write(|out| out.write_all(&bytes))
        .with_context(|| format!("writing {}", output.name()))?;
    let rate = rays.len() as f64 / seconds.max(f64::MIN_POSITIVE) / 1e6;
    eprintln!(
        "reducem: query: rays={} crossings={crossings} seconds={seconds:.6} mrays_per_s={rate:.3} \
         threads={}",
        rays.len(),
        rayon::current_num_threads()
    );
    Ok(())
}

/// The `--all` records: per ray its count, then its hits.
fn encode_all(hits: &AllHits) -> Vec<u8> {
    let rays = hits.splits.len().saturating_sub(1);
    let mut bytes = Vec::with_capacity(4 * rays + 16 * hits.hits.len());
    for ray in hits.splits.windows(2) {
        let list = &hits.hits[ray[0] as usize..ray[1] as usize];
        bytes.extend_from_slice(&(list.len() as u32).to_le_bytes());
        for hit in list {
            for word in [
                hit.t.to_bits(),
                hit.face_id,
                hit.u.to_bits(),
                hit.v.to_bits(),
            ] {
                bytes.extend_from_slice(&word.to_le_bytes());
            }
        }
    }
    bytes
}

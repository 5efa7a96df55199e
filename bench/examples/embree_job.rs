//! A batch job answered by Intel Embree 3 the way a user without ReduceM would run it: read the
//! mesh, build the scene (default flags), trace a ray file, write the answers in the format of
//! `reducem query` (`t nx ny nz` per ray, or one occlusion byte). Prints the time of each phase
//! on stderr. The peer of `reducem query` in `scripts/bench_jobs.sh`; needs the `embree` feature.
//!
//! `cargo run --release -p reducem-bench --features embree --example embree_job -- MESH.ply --rays RAYS -o OUT`

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use embree::{Device, IntersectContext, RayHit, Scene};
use rayon::prelude::*;
use reducem::input::PlyFile;
use reducem::trace::ray_file::{self, HIT_BYTES};
use reducem::trace::Ray;
use reducem_bench::workload::engines::{embree_ray, triangle_geometry};

#[derive(Parser)]
struct Args {
    /// The mesh (binary or ASCII PLY), read without welding.
    mesh: PathBuf,
    /// The ray file (f32 × 8 per ray, as `reducem query` reads it).
    #[arg(long)]
    rays: PathBuf,
    /// The answers.
    #[arg(short, long)]
    output: PathBuf,
    /// Occlusion queries instead of closest hits.
    #[arg(long)]
    occluded: bool,
}

/// Rays per rayon task, as `reducem query` hands them out.
const CHUNK: usize = 4096;

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let started = Instant::now();
    let mesh = PlyFile::open(&args.mesh)?.read_mesh()?;
    let read = started.elapsed().as_secs_f64();
    let device = Device::new();
    let mut scene = Scene::new(&device);
    scene.attach_geometry(triangle_geometry(&device, &mesh));
    let committed = scene.commit();
    drop(mesh);
    let built = started.elapsed().as_secs_f64();
    let rays = ray_file::read_rays(&args.rays)?;
    let loaded = started.elapsed().as_secs_f64();
    let answers = if args.occluded {
        occlusion_bytes(&committed, &rays)
    } else {
        hit_bytes(&committed, &rays)
    };
    let traced = started.elapsed().as_secs_f64();
    reducem::atomic::write_atomically(&args.output, |out| out.write_all(&answers))?;
    let total = started.elapsed().as_secs_f64();
    eprintln!(
        "embree_job: rays={} read={read:.3} build={:.3} load_rays={:.3} trace={:.3} write={:.3} total={total:.3}",
        rays.len(),
        built - read,
        loaded - built,
        traced - loaded,
        total - traced,
    );
    Ok(())
}

fn hit_bytes(scene: &embree::CommittedScene, rays: &[Ray]) -> Vec<u8> {
    let mut bytes = vec![0; rays.len() * HIT_BYTES];
    bytes
        .par_chunks_mut(CHUNK * HIT_BYTES)
        .zip(rays.par_chunks(CHUNK))
        .for_each(|(out, rays)| {
            let mut context = IntersectContext::coherent();
            for (ray, record) in rays.iter().zip(out.chunks_exact_mut(HIT_BYTES)) {
                let mut query = RayHit::new(embree_ray(ray));
                scene.intersect(&mut context, &mut query);
                let fields = if query.hit.hit() {
                    let normal = [query.hit.Ng_x, query.hit.Ng_y, query.hit.Ng_z];
                    let length = normal.iter().map(|c| c * c).sum::<f32>().sqrt();
                    let [x, y, z] = normal.map(|c| c / length);
                    [query.ray.tfar, x, y, z]
                } else {
                    [f32::INFINITY, 0.0, 0.0, 0.0]
                };
                for (field, out) in fields.iter().zip(record.chunks_exact_mut(4)) {
                    out.copy_from_slice(&field.to_le_bytes());
                }
            }
        });
    bytes
}

fn occlusion_bytes(scene: &embree::CommittedScene, rays: &[Ray]) -> Vec<u8> {
    let mut bytes = vec![0; rays.len()];
    bytes
        .par_chunks_mut(CHUNK)
        .zip(rays.par_chunks(CHUNK))
        .for_each(|(out, rays)| {
            let mut context = IntersectContext::incoherent();
            for (ray, byte) in rays.iter().zip(out) {
                let mut query = embree_ray(ray);
                scene.occluded(&mut context, &mut query);
                *byte = u8::from(query.tfar == f32::NEG_INFINITY);
            }
        });
    bytes
}

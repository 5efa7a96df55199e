//! Tracing benchmark: ReduceM against the in-project SAH BVH baseline and (with the `embree`
//! feature) Intel Embree 3, on the same rays. Run through `scripts/bench_trace.sh`.
//!
//! Workloads at `--size`² pixels: the renderer's rays for `configs/scenes/ao16.toml` with
//! `--antialiasing`² camera rays per pixel (default 4) and `--ao-samples` AO samples per hit
//! ([`RaySet`]), primary rays from an automatic camera and AO rays
//! from ReduceM's primary hits (cosine hemisphere, 5% of the bounds diagonal, origins pushed off
//! the surface), so every engine traces exactly the same rays. Each figure is the median of
//! `--runs` runs per thread count. `--check-ao` also checks, ray by ray, every AO ray the
//! engines answer differently against the watertight brute force over the decoded triangles.
//!
//! Memory: ReduceM's file size and the resident part of its mapping after the runs; the
//! baseline's node, index and vertex arrays; Embree's growth of process RSS while it builds its
//! scene from the indexed mesh (its own buffers included). Figures, not assertions.

#[path = "../../tests/common/mod.rs"]
mod common;

use std::path::PathBuf;
use std::time::Instant;

use clap::Parser;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use reducem::conversion::{
    convert_mesh, BuildParams, PIPELINE_LEAF_WINDOWS, PIPELINE_MAX_STRIP_LENGTH,
};
use reducem::format::reader::ReducemFile;
use reducem::format::{VERSION_MAJOR, VERSION_MINOR};
use reducem::geometry::Point;
use reducem::render::residency;
use reducem::render::sampling::Surface;
use reducem::trace::ray_file::encode_rays;
use reducem::trace::{Kernel, Ray, TraceOptions, Tracer, BATCH_RAYS};
use reducem_bench::baseline::TriangleBvh;
use reducem_bench::workload::engines::{Baseline, Engine, ReduceM};
use reducem_bench::workload::{load_mesh, median_timed, RaySet};

/// Rays handed to one rayon task, for every engine: as many as ReduceM's batch calls hand
/// out ([`BATCH_RAYS`]), so that it groups them in packets as a user's batch would. (With
/// 64-ray tasks, four hit points' AO rays, ReduceM's AO ran at 3.25 Mrays/s on 1 thread
/// instead of 4.26; Embree, which traces one ray at a time, gave the same figures with both:
/// 13.26 / 7.64 and 13.26 / 7.70 Mrays/s primary / AO.)
const CHUNK: usize = BATCH_RAYS;

#[derive(Parser)]
struct Args {
    #[arg(long, default_value = "scan")]
    kind: reducem_gen::Kind,
    #[arg(long, default_value_t = 1_000_000)]
    triangles: u64,
    #[arg(long, default_value_t = 1024)]
    size: u32,
    #[arg(long, default_value_t = 16)]
    ao_samples: u32,
    /// Camera rays per pixel, `n × n` on the renderer's regular grid: the default 2 gives
    /// issue 33's workload of 1024² × 4 camera rays (16 AO rays per hit of each).
    #[arg(long, default_value_t = 2)]
    antialiasing: u32,
    #[arg(long, default_value_t = 3)]
    runs: usize,
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// Strip-RT's maximum strip length for the converted file (the pipeline's default; the
    /// paper's is 60; shorter strips trace faster and take more bytes).
    #[arg(long, default_value_t = PIPELINE_MAX_STRIP_LENGTH)]
    max_strip_length: usize,
    /// Strip kd-tree leaf size of the converted file (the pipeline's default).
    #[arg(long, default_value_t = PIPELINE_LEAF_WINDOWS)]
    leaf_windows: usize,
    /// Convert with 64-byte grid top-level nodes (`[strip] grid_nodes`): fewer bytes, slower.
    #[arg(long)]
    grid_nodes: bool,
    /// ReduceM's `TraceOptions::subtree_windows`.
    #[arg(long, default_value_t = TraceOptions::default().subtree_windows)]
    subtree_windows: usize,
    /// Benchmark ReduceM alone (for tuning).
    #[arg(long)]
    reducem_only: bool,
    /// Check the AO rays the engines disagree on against the brute force (slow: every such ray
    /// is tested against every triangle).
    #[arg(long)]
    check_ao: bool,
    /// Trace this converted file (any vertex encoding) instead of converting the mesh; ReduceM
    /// alone (`scripts/bench_quantized.sh`).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Also write the rays as `reducem query` ray files, `primary.rays` and `ao.rays` in this
    /// directory, for the whole-process comparison of `scripts/bench_trace.sh`.
    #[arg(long)]
    write_rays: Option<PathBuf>,
    /// Where generated meshes and converted files are cached between runs.
    #[arg(long, default_value = "/tmp/reducem-bench")]
    dir: PathBuf,
}

/// Each engine's occlusion answer per AO ray, for `--check-ao`.
type Answers = Vec<(String, Vec<bool>)>;

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    std::fs::create_dir_all(&args.dir)?;
    let name = format!("{}-{}", args.kind.name(), args.triangles);
    // Loaded only when needed, so that tuning runs on a cached file trace and nothing else.
    let mut mesh = None;
    let (length, leaf) = (args.max_strip_length, args.leaf_windows);
    let nodes = if args.grid_nodes { "-grid-nodes" } else { "" };
    let model = args.model.clone().unwrap_or_else(|| {
        args.dir.join(format!(
            "{name}-length{length}-leaf{leaf}{nodes}-v{VERSION_MAJOR}.{VERSION_MINOR}.rdm"
        ))
    });
    if !model.exists() {
        let started = Instant::now();
        let mesh = mesh.insert(load_mesh(args.kind, args.triangles, &args.dir)?);
        let mut params = BuildParams {
            leaf_windows: leaf,
            grid_nodes: args.grid_nodes,
            ..BuildParams::default()
        };
        params.stripify.max_length = length;
        convert_mesh(mesh, &params, &model)?;
        println!("converted in {:.1} s", started.elapsed().as_secs_f64());
    }
    let file = ReducemFile::open(&model)?;
    println!(
        "{name}: {} triangles, {} strips (max length {}, leaf {}), file {:.1} MiB ({:.2} B/tri); {}x{} pixels x {} camera rays, AO {} samples, median of {} runs",
        file.header().triangle_count,
        file.strip_count(),
        file.header().max_strip_length,
        file.leaf_windows(),
        mib(file.file_bytes()),
        file.file_bytes() as f64 / file.header().triangle_count.max(1) as f64,
        args.size,
        args.size,
        args.antialiasing.pow(2),
        args.ao_samples,
        args.runs
    );
    println!("  model: {}", model.display());
    let rays = RaySet::supersampled(&file, args.size, args.ao_samples, args.antialiasing);
    println!(
        "  {} primary rays, {} AO rays",
        rays.primary.len(),
        rays.ambient_occlusion.len()
    );
    if args.check_ao {
        check_origins(&file, &rays.primary);
    }
    if let Some(dir) = &args.write_rays {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join("primary.rays"), encode_rays(&rays.primary))?;
        std::fs::write(dir.join("ao.rays"), encode_rays(&rays.ambient_occlusion))?;
    }

    let mut answers = Answers::new();
    for kernel in kernels()? {
        for packets in [true, false] {
            let tracer = Tracer::new(
                &file,
                TraceOptions {
                    packets,
                    subtree_windows: args.subtree_windows,
                    kernel,
                },
            );
            let name = if packets { "packets" } else { "single" };
            run_engine(
                &format!("reducem {kernel} {name}"),
                &ReduceM(tracer),
                &rays,
                &args,
                &mut answers,
            );
        }
    }
    let memory = residency::measure(&model, file.file_bytes());
    println!(
        "  reducem memory: file {:.1} MiB, mapping resident {:.1} MiB, process RSS {:.1} MiB (includes the rays, and the mesh copy when this run converted the file)",
        mib(memory.file_bytes),
        mib(memory.mapped_resident_bytes.unwrap_or(0)),
        mib(memory.process_rss_bytes.unwrap_or(0))
    );
    if args.reducem_only || args.model.is_some() {
        return Ok(());
    }

    let mesh = match mesh {
        Some(mesh) => mesh,
        None => load_mesh(args.kind, args.triangles, &args.dir)?,
    };
    let started = Instant::now();
    let bvh = TriangleBvh::build(&mesh);
    println!(
        "  baseline built in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    run_engine(
        "baseline SAH BVH",
        &Baseline(&bvh),
        &rays,
        &args,
        &mut answers,
    );
    println!(
        "  baseline memory: {:.1} MiB (nodes, indices, vertices)",
        mib(bvh.memory_bytes())
    );
    drop(bvh);

    #[cfg(feature = "embree")]
    embree(&mesh, &rays, &args, &mut answers);
    #[cfg(not(feature = "embree"))]
    println!("  embree: not built (cargo feature `embree`, needs libembree-dev)");
    if args.check_ao {
        check_ao(&file, &rays.ambient_occlusion, &answers);
    }
    Ok(())
}

/// The kernel `REDUCEM_KERNEL` names, else every kernel this CPU runs.
fn kernels() -> anyhow::Result<Vec<Kernel>> {
    if std::env::var_os(reducem::trace::kernel::KERNEL_VARIABLE).is_some() {
        return Ok(vec![Kernel::from_env()?]);
    }
    Ok(Kernel::supported())
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// Times `engine` on both ray sets for every thread count; with `--check-ao`, also records its
/// answer for every AO ray.
fn run_engine(name: &str, engine: &dyn Engine, rays: &RaySet, args: &Args, answers: &mut Answers) {
    for &threads in &args.threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let trace = |rays: &[Ray], count: &(dyn Fn(&[Ray]) -> usize + Sync)| {
            median_timed(args.runs, || {
                pool.install(|| rays.par_chunks(CHUNK).map(count).sum::<usize>())
            })
        };
        let (primary_seconds, hits) = trace(&rays.primary, &|c| engine.count_hits(c));
        let (ao_seconds, occluded) = trace(&rays.ambient_occlusion, &|c| engine.count_occluded(c));
        println!(
            "  {name:<22} {threads} thread(s): primary {:>7.2} Mrays/s ({hits} hits), AO {:>7.2} Mrays/s ({occluded} occluded)",
            rays.primary.len() as f64 / primary_seconds / 1e6,
            rays.ambient_occlusion.len() as f64 / ao_seconds / 1e6,
        );
    }
    if args.check_ao {
        let occluded = rays
            .ambient_occlusion
            .par_iter()
            .map(|ray| engine.count_occluded(std::slice::from_ref(ray)) == 1)
            .collect();
        answers.push((name.to_string(), occluded));
    }
}

/// Prints how many primary hits have their AO origin on or behind the plane of the triangle hit:
/// their AO rays can hit the surface they leave (acne), whatever the engine.
fn check_origins(file: &ReducemFile, primary: &[Ray]) {
    let tracer = Tracer::new(file, TraceOptions::default());
    let hits = tracer.intersect_batch(primary);
    let surfaces: Vec<_> = primary
        .iter()
        .zip(hits)
        .filter_map(|(ray, hit)| {
            let hit = hit?;
            Some((Surface::at_hit(file, ray, &hit)?, hit))
        })
        .collect();
    let behind = surfaces
        .iter()
        .filter(|(surface, hit)| !in_front(surface, &common::hit_triangle(file, hit)))
        .count();
    println!(
        "  AO origins on or behind the surface they leave: {behind} of {} primary hits",
        surfaces.len()
    );
}

/// Whether the surface's origin lies strictly on its normal's side of the triangle's plane.
fn in_front(surface: &Surface, triangle: &[Point; 3]) -> bool {
    let [a, b, c] = triangle.map(|p| DVec3::from(Vec3::from(p)));
    let plane_normal = (b - a).cross(c - a);
    let side = plane_normal.dot(surface.origin.as_dvec3() - a);
    side * plane_normal.dot(surface.normal.as_dvec3()) > 0.0
}

/// Prints how many AO rays the engines answer differently and, per engine, how many of those it
/// answers unlike the brute force, with the first few rays.
fn check_ao(file: &ReducemFile, rays: &[Ray], answers: &Answers) {
    let disputed: Vec<usize> = (0..rays.len())
        .filter(|&k| answers.iter().any(|(_, a)| a[k] != answers[0].1[k]))
        .collect();
    let truth: Vec<Option<f32>> = disputed
        .par_iter()
        .map(|&k| common::brute_force(file, &rays[k]).map(|(t, _)| t))
        .collect();
    println!(
        "  AO check: the engines disagree on {} of {} rays; the brute force finds {} of them occluded",
        disputed.len(),
        rays.len(),
        truth.iter().flatten().count()
    );
    for (name, occluded) in answers {
        let wrong = disputed
            .iter()
            .zip(&truth)
            .filter(|(&k, t)| occluded[k] != t.is_some())
            .count();
        println!("    {name:<20} unlike the brute force on {wrong}");
    }
    for (&k, t) in disputed.iter().zip(&truth).take(5) {
        let said: Vec<bool> = answers.iter().map(|(_, a)| a[k]).collect();
        println!(
            "    ray {k} {:?}: engines {said:?}, brute-force hit at {t:?}",
            rays[k]
        );
    }
}

#[cfg(feature = "embree")]
fn embree(mesh: &reducem::mesh::Mesh, rays: &RaySet, args: &Args, answers: &mut Answers) {
    use embree::{Device, Scene};
    use reducem::render::residency::process_rss;
    use reducem_bench::workload::engines::{triangle_geometry, Embree};

    let rss_before = process_rss().unwrap_or(0);
    let device = Device::new();
    let mut scene = Scene::new(&device);
    scene.attach_geometry(triangle_geometry(&device, mesh));
    let started = Instant::now();
    let engine = Embree(scene.commit());
    let built = started.elapsed().as_secs_f64();
    let rss_after = process_rss().unwrap_or(0);
    println!("  embree built in {built:.1} s");
    run_engine("embree 3 (single)", &engine, rays, args, answers);
    println!(
        "  embree memory: {:.1} MiB (process RSS growth while building its scene)",
        mib(rss_after.saturating_sub(rss_before))
    );
}

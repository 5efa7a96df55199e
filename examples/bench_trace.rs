//! Tracing benchmark: ReduceM against the in-project SAH BVH baseline and (with the `embree`
//! feature) Intel Embree 3, on the same rays. Run through `scripts/bench_trace.sh`.
//!
//! Workloads at `--size`² pixels: primary rays from an automatic camera, and `--ao-samples`
//! ambient-occlusion rays per primary hit (cosine hemisphere, 5% of the bounds diagonal, origins
//! pushed off the surface as the renderer does). AO rays are derived from ReduceM's primary hits
//! with the renderer's stateless hash, so every engine traces exactly the same rays. Each figure
//! is the median of `--runs` runs per thread count.
//!
//! Memory: ReduceM's file size and the resident part of its mapping after the runs; the
//! baseline's node, index and vertex arrays; Embree's growth of process RSS while it builds its
//! scene from the indexed mesh (its own buffers included). Figures, not assertions.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Parser;
use glam::Vec3;
use rayon::prelude::*;
use reducem::baseline::TriangleBvh;
use reducem::build::{convert_mesh, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::geometry::Aabb;
use reducem::mesh::Mesh;
use reducem::render::camera::Camera;
use reducem::render::residency;
use reducem::render::sampling::{cosine_hemisphere, offset_origin, sample};
use reducem::render::scene::CameraSettings;
use reducem::trace::{Ray, TraceOptions, Tracer};

#[derive(Parser)]
struct Args {
    #[arg(long, value_enum, default_value = "scan")]
    kind: reducem::gen::Kind,
    #[arg(long, default_value_t = 1_000_000)]
    triangles: u64,
    #[arg(long, default_value_t = 1024)]
    size: u32,
    #[arg(long, default_value_t = 16)]
    ao_samples: u32,
    #[arg(long, default_value_t = 3)]
    runs: usize,
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// ReduceM's `TraceOptions::subtree_windows`.
    #[arg(long, default_value_t = TraceOptions::default().subtree_windows)]
    subtree_windows: usize,
    /// Benchmark ReduceM alone (for tuning).
    #[arg(long)]
    reducem_only: bool,
    /// Where generated meshes and converted files are cached between runs.
    #[arg(long, default_value = "/tmp/reducem-bench")]
    dir: PathBuf,
}

/// A primary hit's secondary-ray frame.
#[derive(Clone, Copy)]
struct Surface {
    origin: Vec3,
    normal: Vec3,
}

/// One engine under test.
trait Engine: Sync {
    fn name(&self) -> String;
    /// Closest-hit queries over a batch; returns the number of hits.
    fn intersect_batch(&self, rays: &[Ray]) -> u64;
    fn occluded(&self, ray: &Ray) -> bool;
}

struct ReduceM<'f> {
    tracer: Tracer<'f>,
}

impl Engine for ReduceM<'_> {
    fn name(&self) -> String {
        if self.tracer.options().packets {
            "reducem (packets)".into()
        } else {
            "reducem (single)".into()
        }
    }
    fn intersect_batch(&self, rays: &[Ray]) -> u64 {
        self.tracer.intersect_chunk(rays).iter().flatten().count() as u64
    }
    fn occluded(&self, ray: &Ray) -> bool {
        self.tracer.occluded(ray)
    }
}

struct Baseline {
    bvh: TriangleBvh,
}

impl Engine for Baseline {
    fn name(&self) -> String {
        "baseline SAH BVH".into()
    }
    fn intersect_batch(&self, rays: &[Ray]) -> u64 {
        rays.iter()
            .filter(|r| self.bvh.intersect(r).is_some())
            .count() as u64
    }
    fn occluded(&self, ray: &Ray) -> bool {
        self.bvh.occluded(ray)
    }
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    std::fs::create_dir_all(&args.dir)?;
    let name = format!("{:?}-{}", args.kind, args.triangles).to_lowercase();
    let ply = args.dir.join(format!("{name}.ply"));
    // Loaded only when needed, so that tuning runs on a cached file trace and nothing else.
    let mut mesh = None;
    let model = args.dir.join(format!("{name}.rdm"));
    if !model.exists() {
        let started = Instant::now();
        let mesh = mesh.insert(load_mesh(&args, &ply)?);
        convert_mesh(mesh, &BuildParams::default(), &model)?;
        println!("converted in {:.1} s", started.elapsed().as_secs_f64());
    }
    let file = ReducemFile::open(&model)?;
    println!(
        "{name}: {} triangles, {} strips, file {:.1} MiB; {}x{} pixels, AO {} samples, median of {} runs",
        file.header().triangle_count,
        file.strip_count(),
        mib(file.file_bytes()),
        args.size,
        args.size,
        args.ao_samples,
        args.runs
    );
    let bounds = Aabb {
        min: file.header().bounds_min,
        max: file.header().bounds_max,
    };
    let primary = primary_rays(&bounds, args.size);
    let reference = Tracer::new(&file, TraceOptions::default());
    let surfaces = surfaces(&reference, &primary);
    let ao_distance = 0.05 * (Vec3::from(bounds.max) - Vec3::from(bounds.min)).length();
    let workload = Workload {
        primary: &primary,
        surfaces: &surfaces,
        ao_samples: args.ao_samples,
        ao_distance,
    };
    println!(
        "  {} primary rays, {} hits, {} AO rays",
        primary.len(),
        surfaces.len(),
        surfaces.len() as u64 * args.ao_samples as u64
    );

    for packets in [true, false] {
        let engine = ReduceM {
            tracer: Tracer::new(
                &file,
                TraceOptions {
                    packets,
                    subtree_windows: args.subtree_windows,
                },
            ),
        };
        run_engine(&engine, &workload, &args);
    }
    let memory = residency::measure(&model, file.file_bytes());
    println!(
        "  reducem memory: file {:.1} MiB, mapping resident {:.1} MiB, process RSS {:.1} MiB (includes the mesh copy when this run converted the file)",
        mib(memory.file_bytes),
        mib(memory.mapped_resident_bytes.unwrap_or(0)),
        mib(memory.process_rss_bytes.unwrap_or(0))
    );
    if args.reducem_only {
        return Ok(());
    }

    let mesh = match mesh {
        Some(mesh) => mesh,
        None => load_mesh(&args, &ply)?,
    };
    let started = Instant::now();
    let baseline = Baseline {
        bvh: TriangleBvh::build(&mesh),
    };
    println!(
        "  baseline built in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    run_engine(&baseline, &workload, &args);
    println!(
        "  baseline memory: {:.1} MiB (nodes, indices, vertices)",
        mib(baseline.bvh.memory_bytes())
    );
    drop(baseline);

    #[cfg(feature = "embree")]
    embree_engine::run(&mesh, &workload, &args);
    #[cfg(not(feature = "embree"))]
    println!("  embree: not built (cargo feature `embree`, needs libembree-dev)");
    Ok(())
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

fn load_mesh(args: &Args, ply: &Path) -> anyhow::Result<Mesh> {
    if !ply.exists() {
        reducem::gen::generate(args.kind, args.triangles, 1, ply)?;
    }
    Ok(reducem::input::read_mesh(ply)?)
}

fn primary_rays(bounds: &Aabb, size: u32) -> Vec<Ray> {
    let settings = CameraSettings {
        auto: true,
        position: None,
        look_at: None,
        direction: None,
        up: [0.0, 0.0, 1.0],
        fov_degrees: 40.0,
    };
    let camera = Camera::new(&settings, bounds, size, size);
    // 8×8 tiles in row-major tile order, as the renderer traces them.
    let mut rays = Vec::with_capacity((size * size) as usize);
    for tile_y in (0..size).step_by(8) {
        for tile_x in (0..size).step_by(8) {
            for y in tile_y..(tile_y + 8).min(size) {
                for x in tile_x..(tile_x + 8).min(size) {
                    rays.push(camera.primary_ray(x, y));
                }
            }
        }
    }
    rays
}

fn surfaces(tracer: &Tracer, primary: &[Ray]) -> Vec<Surface> {
    let hits = tracer.intersect_batch(primary);
    primary
        .iter()
        .zip(hits)
        .filter_map(|(ray, hit)| {
            let hit = hit?;
            let direction = Vec3::from(ray.direction);
            let normal = Vec3::from(hit.normal);
            let normal = if normal.dot(direction) > 0.0 {
                -normal
            } else {
                normal
            };
            let point = Vec3::from(ray.origin) + direction * hit.t;
            Some(Surface {
                origin: offset_origin(point, normal),
                normal,
            })
        })
        .collect()
}

struct Workload<'a> {
    primary: &'a [Ray],
    surfaces: &'a [Surface],
    ao_samples: u32,
    ao_distance: f32,
}

impl Workload<'_> {
    fn ao_ray(&self, index: usize, sample_index: u32) -> Ray {
        let surface = &self.surfaces[index];
        let u1 = sample(1, index as u32, sample_index, 0);
        let u2 = sample(1, index as u32, sample_index, 1);
        Ray {
            origin: surface.origin.into(),
            direction: cosine_hemisphere(surface.normal, u1, u2).into(),
            tmin: 0.0,
            tmax: self.ao_distance,
        }
    }
}

fn run_engine(engine: &dyn Engine, workload: &Workload, args: &Args) {
    for &threads in &args.threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let (primary_seconds, hits) = median_run(args.runs, || {
            pool.install(|| {
                workload
                    .primary
                    .par_chunks(64)
                    .map(|chunk| engine.intersect_batch(chunk))
                    .sum::<u64>()
            })
        });
        let (ao_seconds, occluded) = median_run(args.runs, || {
            pool.install(|| {
                (0..workload.surfaces.len())
                    .into_par_iter()
                    .with_min_len(64)
                    .map(|i| {
                        (0..workload.ao_samples)
                            .filter(|&s| engine.occluded(&workload.ao_ray(i, s)))
                            .count() as u64
                    })
                    .sum::<u64>()
            })
        });
        let ao_rays = workload.surfaces.len() as f64 * workload.ao_samples as f64;
        println!(
            "  {:<20} {threads} thread(s): primary {:>7.2} Mrays/s ({hits} hits), AO {:>7.2} Mrays/s ({occluded} occluded)",
            engine.name(),
            workload.primary.len() as f64 / primary_seconds / 1e6,
            ao_rays / ao_seconds / 1e6,
        );
    }
}

/// Runs `f` `runs` times; the median duration and the last result.
fn median_run(runs: usize, mut f: impl FnMut() -> u64) -> (f64, u64) {
    let mut times = Vec::with_capacity(runs);
    let mut result = 0;
    for _ in 0..runs.max(1) {
        let started = Instant::now();
        result = f();
        times.push(started.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], result)
}

#[cfg(feature = "embree")]
mod embree_engine {
    //! Embree 3 through the `embree` crate: one triangle geometry over the indexed mesh,
    //! single-ray `rtcIntersect1` / `rtcOccluded1` queries.

    use super::{mib, run_engine, Args, Engine, Workload};
    use embree::{CommittedScene, Device, Geometry, IntersectContext, RayHit, Scene, TriangleMesh};
    use reducem::mesh::Mesh;
    use reducem::render::residency::process_rss;
    use reducem::trace::Ray;

    struct Embree<'a> {
        scene: CommittedScene<'a>,
    }

    fn to_embree(ray: &Ray) -> embree::Ray {
        embree::Ray {
            org_x: ray.origin[0],
            org_y: ray.origin[1],
            org_z: ray.origin[2],
            dir_x: ray.direction[0],
            dir_y: ray.direction[1],
            dir_z: ray.direction[2],
            tnear: ray.tmin,
            tfar: ray.tmax,
            time: 0.0,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }

    impl Engine for Embree<'_> {
        fn name(&self) -> String {
            "embree 3 (single)".into()
        }
        fn intersect_batch(&self, rays: &[Ray]) -> u64 {
            let mut context = IntersectContext::coherent();
            rays.iter()
                .filter(|ray| {
                    let mut query = RayHit::new(to_embree(ray));
                    self.scene.intersect(&mut context, &mut query);
                    query.hit.hit()
                })
                .count() as u64
        }
        fn occluded(&self, ray: &Ray) -> bool {
            let mut context = IntersectContext::incoherent();
            let mut query = to_embree(ray);
            self.scene.occluded(&mut context, &mut query);
            // Embree marks an occluded ray by setting tfar to -inf.
            query.tfar == f32::NEG_INFINITY
        }
    }

    pub fn run(mesh: &Mesh, workload: &Workload, args: &Args) {
        let rss_before = process_rss().unwrap_or(0);
        let device = Device::new();
        let mut triangles =
            TriangleMesh::unanimated(&device, mesh.triangles.len(), mesh.positions.len());
        {
            let mut vertices = triangles.vertex_buffer.map();
            for (i, p) in mesh.positions.iter().enumerate() {
                let v = &mut vertices[i];
                v.x = p[0];
                v.y = p[1];
                v.z = p[2];
                v.w = 0.0;
            }
        }
        {
            let mut indices = triangles.index_buffer.map();
            for (i, t) in mesh.triangles.iter().enumerate() {
                let index = &mut indices[i];
                index.x = t[0];
                index.y = t[1];
                index.z = t[2];
            }
        }
        let mut geometry = Geometry::Triangle(triangles);
        geometry.commit();
        let mut scene = Scene::new(&device);
        scene.attach_geometry(geometry);
        let started = std::time::Instant::now();
        let engine = Embree {
            scene: scene.commit(),
        };
        let built = started.elapsed().as_secs_f64();
        let rss_after = process_rss().unwrap_or(0);
        println!("  embree built in {built:.1} s");
        run_engine(&engine, workload, args);
        println!(
            "  embree memory: {:.1} MiB (process RSS growth while building its scene)",
            mib(rss_after.saturating_sub(rss_before))
        );
    }
}

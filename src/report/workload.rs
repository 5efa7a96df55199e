//! What every section measures with: generated meshes, timed conversions and the ray sets.
//!
//! The rays are made once per mesh and traced by every engine and every file variant of that
//! mesh, so speeds differ only by what is being compared. AO rays start at ReduceM's primary
//! hits, pushed off the surface and sampled as the renderer does
//! ([`crate::render::sampling`]); like the renderer, primary rays are traced as packets in 8×8
//! tiles and AO rays one by one.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use glam::Vec3;

use crate::build::{convert_mesh, BuildParams};
use crate::format::reader::ReducemFile;
use crate::gen::Kind;
use crate::geometry::Aabb;
use crate::inspect::{file_stats, FileStats};
use crate::mesh::Mesh;
use crate::render::camera::Camera;
use crate::render::sampling::{cosine_hemisphere, offset_origin, sample};
use crate::render::scene::CameraSettings;
use crate::trace::{Ray, TraceOptions, Tracer};

/// AO ray length as a fraction of the bounds diagonal (the renderer's default).
pub const AO_DISTANCE_FRACTION: f32 = 0.05;
/// Seed of the AO sample hash for the speed measurements.
const AO_SEED: u32 = 1;

/// Generates the mesh once into `work` (kept for later runs) and reads it.
pub fn load_mesh(kind: Kind, triangles: u64, work: &Path) -> anyhow::Result<Mesh> {
    let ply = work.join(format!("{}-{triangles}.ply", kind_name(kind)));
    if !ply.exists() {
        crate::gen::generate(kind, triangles, 1, &ply)?;
    }
    crate::input::read_mesh(&ply).with_context(|| format!("reading {}", ply.display()))
}

pub fn kind_name(kind: Kind) -> String {
    format!("{kind:?}").to_lowercase()
}

/// Runs `f` `runs` times (at least once); the median duration in seconds and the last result.
pub fn median_timed<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let started = Instant::now();
    let mut result = f();
    let mut times = vec![started.elapsed().as_secs_f64()];
    for _ in 1..runs {
        let started = Instant::now();
        result = f();
        times.push(started.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    (times[times.len() / 2], result)
}

/// A converted file with its statistics and median build time.
pub struct Converted {
    pub path: PathBuf,
    pub stats: FileStats,
    pub build_seconds: f64,
}

/// Converts `mesh` with `params` to `work/name.rdm`, timing the median of `runs` conversions
/// (Strip-RT, encoding, top level and writing).
pub fn convert_timed(
    mesh: &Mesh,
    params: &BuildParams,
    work: &Path,
    name: &str,
    runs: usize,
) -> anyhow::Result<Converted> {
    let path = work.join(format!("{name}.rdm"));
    let (build_seconds, written) = median_timed(runs, || convert_mesh(mesh, params, &path));
    written?;
    let stats = file_stats(&ReducemFile::open(&path)?);
    Ok(Converted {
        path,
        stats,
        build_seconds,
    })
}

/// The rays of one mesh.
pub struct RaySet {
    /// In 8×8 tile order, as the renderer traces them.
    pub primary: Vec<Ray>,
    pub ambient_occlusion: Vec<Ray>,
}

impl RaySet {
    /// Primary rays of a `size`² image and `ao_per_hit` AO rays per primary hit of `file`.
    pub fn new(file: &ReducemFile, size: u32, ao_per_hit: u32) -> RaySet {
        let bounds = Aabb {
            min: file.header().bounds_min,
            max: file.header().bounds_max,
        };
        let primary = primary_rays(&bounds, size);
        let tracer = Tracer::new(file, TraceOptions::default());
        let hits = tracer.intersect_batch(&primary);
        let distance =
            AO_DISTANCE_FRACTION * (Vec3::from(bounds.max) - Vec3::from(bounds.min)).length();
        let mut ambient_occlusion = Vec::new();
        for (index, (ray, hit)) in primary.iter().zip(hits).enumerate() {
            let Some(hit) = hit else { continue };
            let direction = Vec3::from(ray.direction);
            let normal = facing(Vec3::from(hit.normal), direction);
            let origin = offset_origin(Vec3::from(ray.origin) + direction * hit.t, normal);
            ambient_occlusion.extend((0..ao_per_hit).map(|s| {
                Ray {
                    origin: origin.into(),
                    direction: cosine_hemisphere(
                        normal,
                        sample(AO_SEED, index as u32, s, 0),
                        sample(AO_SEED, index as u32, s, 1),
                    )
                    .into(),
                    tmin: 0.0,
                    tmax: distance,
                }
            }));
        }
        RaySet {
            primary,
            ambient_occlusion,
        }
    }
}

/// The normal turned towards the side the ray came from.
fn facing(normal: Vec3, direction: Vec3) -> Vec3 {
    if normal.dot(direction) > 0.0 {
        -normal
    } else {
        normal
    }
}

/// The camera every section uses: automatic framing, seen from above one corner.
pub fn camera_settings() -> CameraSettings {
    CameraSettings {
        auto: true,
        position: None,
        look_at: None,
        direction: Some([1.0, 0.8, 1.2]),
        up: [0.0, 0.0, 1.0],
        fov_degrees: 40.0,
    }
}

fn primary_rays(bounds: &Aabb, size: u32) -> Vec<Ray> {
    let camera = Camera::new(&camera_settings(), bounds, size, size);
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

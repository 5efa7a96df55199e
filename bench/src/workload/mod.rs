//! What the benchmarks measure with, `examples/bench_trace.rs` and the report (feature `report`)
//! alike: generated meshes cached on disk, timed conversions, medians, and one set of rays.
//!
//! The rays are the renderer's own for [`ao_scene`] (`configs/scenes/ao16.toml` at `size`²
//! pixels): primary rays in the renderer's order (8×8 tiles of 4×2 packet blocks) and, per
//! primary hit, its AO samples from the same secondary-ray frame ([`Surface::at_hit`]) and the
//! same stateless per-pixel seeds. Every engine traces this one set, so the engines differ only
//! in how they trace it.

#[cfg(feature = "embree")]
mod embree_engine;
pub mod engines;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;

use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::inspect::{file_stats, FileStats};
use reducem::mesh::Mesh;
use reducem::render::rays::RendererRays;
use reducem::render::scene::{
    AmbientOcclusion, CameraSettings, DirectionalLight, ImageSettings, Scene, Shading,
};
use reducem::trace::Ray;
use reducem_gen::Kind;

/// Generates the mesh once into `work` (kept for later runs) and reads it.
pub fn load_mesh(kind: Kind, triangles: u64, work: &Path) -> anyhow::Result<Mesh> {
    let ply = work.join(format!("{}-{triangles}.ply", kind.name()));
    if !ply.exists() {
        reducem_gen::generate(kind, triangles, 1, &ply)?;
    }
    reducem::input::read_mesh(&ply).with_context(|| format!("reading {}", ply.display()))
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

/// The camera every measurement uses: automatic framing, seen from above one corner.
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

/// The scene of `configs/scenes/ao16.toml` at `size`² pixels and `samples` AO samples.
pub fn ao_scene(size: u32, samples: u32) -> Scene {
    Scene {
        image: ImageSettings {
            width: size,
            height: size,
            antialiasing: 1,
        },
        camera: camera_settings(),
        shading: Shading {
            ambient: 0.8,
            ..Shading::default()
        },
        directional_light: vec![DirectionalLight {
            direction: [-0.4, -0.3, -1.0],
            intensity: 0.3,
            cast_shadows: false,
            relative_to_camera: false,
        }],
        point_light: Vec::new(),
        ambient_occlusion: Some(AmbientOcclusion {
            samples,
            ..AmbientOcclusion::default()
        }),
    }
}

/// The rays of one mesh.
pub struct RaySet {
    /// In the renderer's order (8×8 tiles of 4×2 packet blocks), as it traces them.
    pub primary: Vec<Ray>,
    /// `ao_per_hit` per primary hit, in the order of `primary`.
    pub ambient_occlusion: Vec<Ray>,
}

impl RaySet {
    /// The rays the renderer traces for `ao_scene(size, ao_per_hit)` on `file`, the shadowless
    /// light aside.
    pub fn new(file: &ReducemFile, size: u32, ao_per_hit: u32) -> RaySet {
        RaySet::supersampled(file, size, ao_per_hit, 1)
    }

    /// [`RaySet::new`] with `antialiasing`² camera rays per pixel: the rays of the finer image
    /// the renderer traces for `[image] antialiasing`, `size × antialiasing` pixels each way.
    pub fn supersampled(
        file: &ReducemFile,
        size: u32,
        ao_per_hit: u32,
        antialiasing: u32,
    ) -> RaySet {
        let scene = ao_scene(size * antialiasing, ao_per_hit);
        let rays = RendererRays::of(file, &scene).expect("the AO scene plans ambient occlusion");
        RaySet {
            primary: rays.primary,
            ambient_occlusion: rays.ambient_occlusion,
        }
    }
}

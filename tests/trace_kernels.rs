//! Every tracer kernel this CPU runs gives the baseline kernel's answers bit for bit, single
//! rays and packets, on every `gen` kind, lossless and on a grid, for camera rays, AO rays from
//! the hits and rays aimed at vertices and edge midpoints. (Closed-mesh escapes and the
//! extreme-geometry suite run per kernel through `common::tracer_variants`.)

mod common;

use common::*;
use reducem::conversion::{convert_mesh, BuildParams, PIPELINE_MAX_STRIP_LENGTH};
use reducem::format::reader::ReducemFile;
use reducem::input::read_mesh;
use reducem::render::rays::RendererRays;
use reducem::render::scene::Scene;
use reducem::trace::{Kernel, Ray};
use reducem_gen::{generate, Kind};

/// The benchmarks' view (`configs/scenes/ao16.toml`) at 48² pixels with 4 AO samples.
const AO_SCENE: &str = "
[image]
width = 48
height = 48
[camera]
auto = true
direction = [1.0, 0.8, 1.2]
fov_degrees = 40.0
[ambient_occlusion]
samples = 4
";

/// The renderer's rays for [`AO_SCENE`]: camera rays in its tile order and, per primary hit,
/// its AO rays from the same secondary-ray frame and per-pixel seeds.
fn renderer_rays(file: &ReducemFile) -> (Vec<Ray>, Vec<Ray>) {
    let scene = Scene::parse("AO_SCENE".as_ref(), AO_SCENE).expect("AO scene");
    let rays = RendererRays::of(file, &scene).expect("the scene plans ambient occlusion");
    (rays.primary, rays.ambient_occlusion)
}

/// Camera rays, 4 AO rays per hit, rays aimed at a few hundred vertices and edge midpoints,
/// and rays aimed at targets far apart, so that a packet's lanes part and one or two of them
/// reach each strip (which AVX2 packets test for each such lane alone).
fn probe_rays(file: &ReducemFile, mesh: &reducem::mesh::Mesh) -> Vec<Ray> {
    let (primary, ambient_occlusion) = renderer_rays(file);
    let (min, max) = (file.header().bounds_min, file.header().bounds_max);
    let outside: [f32; 3] = std::array::from_fn(|a| max[a] + (max[a] - min[a]) + 1.0);
    let targets = vertex_and_edge_targets(mesh);
    let aimed = targets
        .iter()
        .step_by(7)
        .take(600)
        .map(|&target| ray_towards(outside, target));
    let scattered = targets
        .iter()
        .step_by(97)
        .take(400)
        .map(|&target| ray_towards(outside, target));
    primary
        .into_iter()
        .chain(ambient_occlusion)
        .chain(aimed)
        .chain(scattered)
        .collect()
}

fn check_kind(kind: Kind, grid_bits: Option<u32>) {
    check_kind_with(kind, grid_bits, BuildParams::default().stripify.max_length);
}

/// [`check_kind`] with strips of at most `max_length` triangles.
fn check_kind_with(kind: Kind, grid_bits: Option<u32>, max_length: usize) {
    let name = format!(
        "{kind:?}-{}-{max_length}",
        grid_bits.map_or("f32".into(), |b| b.to_string())
    );
    let ply = temp_path(&format!("kernels-{name}.ply"));
    generate(kind, 6000, 5, &ply).expect("generate");
    let mesh = read_mesh(&ply).expect("read");
    let path = temp_path(&format!("kernels-{name}.rdm"));
    let mut params = BuildParams {
        grid_bits,
        ..BuildParams::default()
    };
    params.stripify.max_length = max_length;
    convert_mesh(&mesh, &params, &path).expect("convert");
    let file = ReducemFile::open(&path).expect("open");
    let rays = probe_rays(&file, &mesh);
    let variants = tracer_variants(&file);
    let (_, baseline) = &variants[0];
    let hits = baseline.intersect_batch(&rays);
    let occluded = baseline.occluded_batch(&rays);
    assert!(
        hits.iter().filter(|h| h.is_some()).count() > rays.len() / 10,
        "{name}: too few hits for a meaningful comparison"
    );
    for (variant, tracer) in &variants[1..] {
        let variant_hits = tracer.intersect_batch(&rays);
        let variant_occluded = tracer.occluded_batch(&rays);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(
                hit_bits(&hits[i]),
                hit_bits(&variant_hits[i]),
                "{name}: {variant} hit differs for {ray:?}"
            );
            assert_eq!(
                occluded[i], variant_occluded[i],
                "{name}: {variant} occlusion differs for {ray:?}"
            );
        }
    }
}

#[test]
fn every_kernel_agrees_on_lossless_files() {
    let names: Vec<&str> = Kernel::supported().iter().map(|k| k.name()).collect();
    println!("kernels compared: {}", names.join(", "));
    for kind in Kind::ALL {
        check_kind(kind, None);
    }
}

#[test]
fn every_kernel_agrees_on_grid_files() {
    for kind in Kind::ALL {
        check_kind(kind, Some(16));
    }
}

/// The pipeline's strips (at most 20 triangles): AVX2 packets test such strips for several rays
/// at once (the AVX2 kernel's packet strips), and must still give each ray's own answers.
#[test]
fn every_kernel_agrees_on_pipeline_length_strips() {
    for kind in Kind::ALL {
        check_kind_with(kind, None, PIPELINE_MAX_STRIP_LENGTH);
    }
}

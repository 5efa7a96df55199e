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
use reducem::trace::{Kernel, Ray, TraceOptions, Tracer};
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

/// Sixteen occlusion rays per camera hit, all from the hit point and spread over the sphere
/// (every direction sign), as a renderer's ambient-occlusion rays come; with `moved`, the
/// origin of each group's ray `moved` nudged off the point.
fn occlusion_groups(file: &ReducemFile, moved: Option<usize>) -> Vec<Ray> {
    let (primary, _) = renderer_rays(file);
    let tracer = Tracer::new(file, TraceOptions::default());
    let (min, max) = (file.header().bounds_min, file.header().bounds_max);
    let diagonal = (0..3)
        .map(|a| (max[a] - min[a]).powi(2))
        .sum::<f32>()
        .sqrt();
    let mut rays = Vec::new();
    for (point, (ray, hit)) in primary
        .iter()
        .zip(tracer.intersect_batch(&primary))
        .enumerate()
    {
        let Some(hit) = hit else { continue };
        let origin: [f32; 3] = std::array::from_fn(|a| ray.origin[a] + hit.t * ray.direction[a]);
        for k in 0..16 {
            // A Fibonacci sphere turned by the point's index.
            let z = 1.0 - (2 * k + 1) as f32 / 16.0;
            let angle = k as f32 * 2.399_963 + point as f32 * 0.37;
            let radius = (1.0 - z * z).sqrt();
            let mut origin = origin;
            if moved == Some(k) {
                origin[0] += diagonal * 1e-3;
            }
            rays.push(Ray {
                origin,
                direction: [radius * angle.cos(), radius * angle.sin(), z],
                tmin: diagonal * 1e-4,
                tmax: diagonal * 0.3,
            });
        }
    }
    // A batch whose length is not a multiple of sixteen.
    rays.truncate(rays.len() - 5);
    rays
}

/// Occlusion packets of a hit point's sixteen rays (walked together where ray `i` shares its
/// origin with ray `8 + i` for every `i`, as eight-ray packets where one does not) answer as
/// single rays do, whatever the kernel; the sixteen walk tests short lossless strips for both
/// halves in one pass.
#[test]
fn sixteen_ray_occlusion_packets_agree_with_single_rays() {
    for (kind, grid_bits) in [(Kind::ALL[0], None), (Kind::ALL[1], Some(16))] {
        let name = format!("sixteen-{kind:?}-{grid_bits:?}");
        let ply = temp_path(&format!("{name}.ply"));
        generate(kind, 6000, 5, &ply).expect("generate");
        let mesh = read_mesh(&ply).expect("read");
        let path = temp_path(&format!("{name}.rdm"));
        let params = BuildParams {
            grid_bits,
            ..BuildParams::default()
        };
        convert_mesh(&mesh, &params, &path).expect("convert");
        let file = ReducemFile::open(&path).expect("open");
        let single = Tracer::new(
            &file,
            TraceOptions {
                packets: false,
                kernel: Kernel::Sse2,
                ..TraceOptions::default()
            },
        );
        // Shared origins; one ray of the first half moved; the second half's first ray moved;
        // another ray of the second half moved.
        for moved in [None, Some(3), Some(8), Some(11)] {
            let rays = occlusion_groups(&file, moved);
            let expected = single.occluded_batch(&rays);
            let occluded = expected.iter().filter(|&&o| o).count();
            assert!(
                occluded > rays.len() / 10 && occluded < rays.len() * 9 / 10,
                "{name}: {occluded} of {} rays occluded, too few or too many to compare",
                rays.len()
            );
            for kernel in Kernel::supported() {
                let options = TraceOptions {
                    kernel,
                    ..TraceOptions::default()
                };
                let packets = Tracer::new(&file, options).occluded_batch(&rays);
                for (i, ray) in rays.iter().enumerate() {
                    assert_eq!(
                        expected[i], packets[i],
                        "{name} {kernel} {moved:?}: occlusion differs for {ray:?}"
                    );
                }
            }
        }
    }
}

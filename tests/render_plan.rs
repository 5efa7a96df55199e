//! The renderer traces exactly what the scene plans, reproducibly, without self-intersection.

mod common;

use std::path::Path;

use common::*;
use reducem::format::reader::ReducemFile;
use reducem::mesh::Mesh;
use reducem::render::scene::Scene;
use reducem::render::{render, Frame, RenderReport};
use reducem::trace::{TraceOptions, Tracer};

const CAMERA: &str = "[image]\nwidth = 48\nheight = 40\n\
    [camera]\nauto = true\ndirection = [0.3, -0.5, 1.0]\nup = [0.0, 0.0, 1.0]\n";

fn scene(extra: &str) -> Scene {
    Scene::parse(Path::new("test.toml"), &format!("{CAMERA}{extra}")).expect("scene")
}

fn render_with(file: &ReducemFile, scene: &Scene, threads: usize) -> (Frame, RenderReport) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| render(&Tracer::new(file, TraceOptions::default()), scene))
}

fn torus_file(name: &str) -> ReducemFile {
    open_with_long_strips(&torus(40, 16), name, 60)
}

fn hit_pixels(frame: &Frame, scene: &Scene) -> usize {
    frame
        .pixels
        .iter()
        .filter(|p| **p != scene.shading.background)
        .count()
}

#[test]
fn no_lights_and_no_ao_trace_only_primary_rays() {
    let file = torus_file("plan-primary.rdm");
    let scene = scene("");
    let (frame, report) = render_with(&file, &scene, 2);
    assert_eq!(report.rays_of("primary"), 48 * 40);
    assert_eq!(report.rays_of("shadows"), 0);
    assert_eq!(report.rays_of("ambient_occlusion"), 0);
    assert_eq!(report.total_rays, 48 * 40);
    assert!(hit_pixels(&frame, &scene) > 200);
}

#[test]
fn shadow_rays_only_for_the_light_that_casts_them() {
    let file = torus_file("plan-shadows.rdm");
    let scene = scene(
        "[[directional_light]]\ndirection = [0.2, 0.1, -1.0]\ncast_shadows = true\n\
         [[point_light]]\nposition = [0.0, 0.0, 8.0]\nintensity = 40.0\n",
    );
    let (_, report) = render_with(&file, &scene, 2);
    let [casting, silent] = report.shadow_rays_per_light[..] else {
        panic!("two lights expected");
    };
    assert!(casting > 100, "{casting} shadow rays");
    assert_eq!(silent, 0);
    assert_eq!(report.rays_of("shadows"), casting);
    assert_eq!(report.rays_of("ambient_occlusion"), 0);
}

#[test]
fn ao_traces_its_samples_per_hit_pixel() {
    let file = torus_file("plan-ao.rdm");
    let scene = scene("[ambient_occlusion]\nsamples = 5\nmax_distance = 0.5\n");
    let (frame, report) = render_with(&file, &scene, 2);
    let hits = frame
        .pixels
        .iter()
        .filter(|p| **p != scene.shading.background)
        .count() as u64;
    assert_eq!(report.rays_of("ambient_occlusion"), 5 * hits);
    assert_eq!(report.rays_of("shadows"), 0);
}

#[test]
fn image_is_identical_for_one_and_two_threads() {
    let file = torus_file("plan-threads.rdm");
    let scene = scene(
        "[[directional_light]]\ndirection = [0.2, 0.1, -1.0]\ncast_shadows = true\n\
         [ambient_occlusion]\nsamples = 4\n",
    );
    let (one, _) = render_with(&file, &scene, 1);
    let (two, _) = render_with(&file, &scene, 2);
    assert_eq!(one, two);
}

/// A flat square of `n` × `n` quads at height `z`, offset by `shift` in x and y.
fn flat_square(n: u32, z: f32, shift: f32) -> Mesh {
    let mut mesh = grid(n, n);
    for p in &mut mesh.positions {
        *p = [p[0] + shift, p[1] + shift, z];
    }
    mesh
}

/// Every hit pixel of a lone flat surface is fully lit and fully open: one value.
fn assert_no_acne(mesh: &Mesh, name: &str) {
    let file = open_with_long_strips(mesh, name, 40);
    let scene = scene(
        "[[directional_light]]\ndirection = [0.3, 0.2, -1.0]\ncast_shadows = true\n\
         [ambient_occlusion]\nsamples = 8\nmax_distance = 4.0\n",
    );
    let (frame, report) = render_with(&file, &scene, 2);
    let lit: Vec<&[f32; 3]> = frame
        .pixels
        .iter()
        .filter(|p| **p != scene.shading.background)
        .collect();
    assert!(
        lit.len() > 500,
        "{name}: the square fills little of the image"
    );
    assert!(lit.iter().all(|p| *p == lit[0]), "acne on {name}");
    assert!(report.rays_of("shadows") > 500);
}

#[test]
fn no_shadow_or_ao_acne_far_from_the_origin() {
    for shift in [0.0f32, 1e5] {
        assert_no_acne(&flat_square(16, 1e5, shift), &format!("acne-{shift}.rdm"));
    }
}

/// Near z = 0 the origin moves up by an absolute 2^-16; with the camera about 130 units away,
/// hit points computed as `origin + t * direction` are off the plane by as much (`cad`'s base
/// slab).
#[test]
fn no_shadow_or_ao_acne_on_a_plane_through_zero_seen_from_afar() {
    assert_no_acne(&flat_square(64, 0.0, -32.0), "acne-zero.rdm");
}

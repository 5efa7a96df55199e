//! Rays from inside closed meshes never escape, even through vertices and edge midpoints, far
//! from the origin and at small scale; packets give bit-identical results to single rays.

mod common;

use common::*;
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::geometry::Point;
use reducem::mesh::Mesh;
use reducem::trace::{TraceOptions, Tracer};

/// Interior points of a mesh that is a sphere of `radius` around `center`.
fn interior_points(center: Point, radius: f32) -> Vec<Point> {
    let mut rng = SplitMix64::new(3);
    let mut points = vec![center];
    for _ in 0..4 {
        points.push(center.map(|c| c + rng.range(-0.4, 0.4) * radius));
    }
    points
}

fn check_sphere(mesh: &Mesh, center: Point, radius: f32, what: &str) {
    let inside = interior_points(center, radius);
    let long = open_with_long_strips(mesh, &format!("{what}-long.rdm"), 100);
    assert_closed(&long, mesh, &inside, what);
    let path = temp_path(&format!("{what}-build.rdm"));
    convert_mesh(mesh, &BuildParams::default(), &path).expect("convert");
    let built = ReducemFile::open(&path).expect("open");
    assert_closed(&built, mesh, &inside, what);
}

/// [`check_sphere`] with vertices on grids from coarse (but with no triangle collapsing) to the
/// finest: the targets are the quantized vertices and edge midpoints.
fn check_sphere_on_grids(mesh: &Mesh, center: Point, radius: f32, what: &str) {
    let inside = interior_points(center, radius);
    for bits in [10, 16, 20, 24] {
        let (quantized, _) = quantized_input(mesh, bits);
        let name = format!("{what}-{bits}");
        let long = open_with_long_strips_on_grid(mesh, &format!("{name}-long.rdm"), 100, bits);
        assert_closed(&long, &quantized, &inside, &name);
        let path = temp_path(&format!("{name}-build.rdm"));
        let params = BuildParams {
            grid_bits: Some(bits),
            ..BuildParams::default()
        };
        convert_mesh(mesh, &params, &path).expect("convert");
        let built = ReducemFile::open(&path).expect("open");
        assert_eq!(built.header().dropped_triangle_count, 0, "{name}");
        assert_closed(&built, &quantized, &inside, &name);
    }
}

#[test]
fn rays_from_inside_quantized_spheres_never_escape() {
    check_sphere_on_grids(&icosphere(3), [0.0; 3], 1.0, "sphere-grid");
    let offset = transformed(&icosphere(3), |x| x + 1e5);
    check_sphere_on_grids(&offset, [1e5; 3], 1.0, "sphere-grid-offset");
    let tiny = transformed(&icosphere(3), |x| x * 1e-3);
    check_sphere_on_grids(&tiny, [0.0; 3], 1e-3, "sphere-grid-tiny");
}

#[test]
fn rays_from_inside_a_sphere_never_escape() {
    check_sphere(&icosphere(3), [0.0; 3], 1.0, "sphere");
}

#[test]
fn rays_from_inside_an_offset_sphere_never_escape() {
    let mesh = transformed(&icosphere(3), |x| x + 1e5);
    check_sphere(&mesh, [1e5; 3], 1.0, "sphere-offset");
}

#[test]
fn rays_from_inside_a_tiny_sphere_never_escape() {
    let mesh = transformed(&icosphere(3), |x| x * 1e-3);
    check_sphere(&mesh, [0.0; 3], 1e-3, "sphere-tiny");
}

#[test]
fn rays_from_inside_a_torus_never_escape() {
    let mesh = torus(24, 12);
    let file = open_with_long_strips(&mesh, "torus-inside.rdm", 100);
    // Points on the torus' core circle (radius 3 around the z axis).
    let inside: Vec<Point> = (0..6)
        .map(|i| {
            let angle = i as f32 * 1.1;
            [3.0 * angle.cos(), 3.0 * angle.sin(), 0.1]
        })
        .collect();
    let targets = vertex_and_edge_targets(&mesh);
    let tracer = Tracer::new(&file, TraceOptions::default());
    for origin in inside {
        for &target in &targets {
            let ray = ray_towards(origin, target);
            assert!(tracer.intersect(&ray).is_some(), "{ray:?} escaped");
        }
    }
}

#[test]
fn packets_match_single_rays_bit_for_bit() {
    let mesh = torus(30, 14);
    let file = open_with_long_strips(&mesh, "torus-packets.rdm", 80);
    let mut rng = SplitMix64::new(99);
    // Camera-like coherent rays, then incoherent ones with mixed direction signs.
    let mut rays = Vec::new();
    for y in 0..40 {
        for x in 0..40 {
            let target = [x as f32 * 0.2 - 4.0, y as f32 * 0.2 - 4.0, 0.0];
            rays.push(ray_towards([0.3, -0.2, 9.0], target));
        }
    }
    for _ in 0..2000 {
        let mut ray = random_ray_in_the_slab(&mut rng);
        ray.tmax = rng.range(0.5, 3.0);
        rays.push(ray);
    }
    let single = Tracer::new(
        &file,
        TraceOptions {
            packets: false,
            ..TraceOptions::default()
        },
    );
    let packets = Tracer::new(
        &file,
        TraceOptions {
            packets: true,
            ..TraceOptions::default()
        },
    );
    let a = single.intersect_batch(&rays);
    let b = packets.intersect_batch(&rays);
    assert!(a.iter().filter(|h| h.is_some()).count() > 1000);
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        assert_eq!(hit_bits(x), hit_bits(y), "ray {i}: {:?}", rays[i]);
    }
    assert_eq!(single.occluded_batch(&rays), packets.occluded_batch(&rays));
    let one_by_one: Vec<_> = rays.iter().map(|r| single.intersect(r)).collect();
    assert_eq!(
        one_by_one.iter().map(hit_bits).collect::<Vec<_>>(),
        a.iter().map(hit_bits).collect::<Vec<_>>()
    );
}

#[test]
fn rays_from_inside_the_generated_sphere_never_escape() {
    let path = temp_path("gen-sphere.ply");
    reducem_gen::generate(reducem_gen::Kind::Sphere, 2000, 1, &path).expect("generate");
    let sphere = reducem::input::read_mesh(&path).expect("read");
    check_sphere(&sphere, [0.0; 3], 1.0, "gen-sphere");
    let offset = transformed(&sphere, |x| x + 1e5);
    check_sphere(&offset, [1e5; 3], 1.0, "gen-sphere-offset");
    let tiny = transformed(&sphere, |x| x * 1e-3);
    check_sphere(&tiny, [0.0; 3], 1e-3, "gen-sphere-tiny");
}

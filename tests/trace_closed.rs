//! Rays from inside closed meshes never escape, even through vertices and edge midpoints, far
//! from the origin and at small scale; packets give bit-identical results to single rays.

mod common;

use common::*;
use reducem::conversion::{convert_mesh, BuildParams, PIPELINE_MAX_STRIP_LENGTH};
use reducem::decode;
use reducem::format::reader::ReducemFile;
use reducem::geometry::Point;
use reducem::input::read_mesh;
use reducem::mesh::Mesh;
use reducem::trace::{Ray, TraceOptions, Tracer};

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

/// 3000 rays between random points of the box ±5 around `offset`.
fn rays_around(offset: f32) -> Vec<Ray> {
    let mut rng = SplitMix64::new(17);
    (0..3000)
        .map(|_| {
            let mut point = || [0, 1, 2].map(|_| rng.range(-5.0, 5.0) + offset);
            let (origin, target) = (point(), point());
            ray_towards(origin, target)
        })
        .collect()
}

/// Each ray's closest hit as its distance's bits and its triangle's, and its occlusion answer.
type TriangleHits = Vec<(Option<(u32, [[u32; 3]; 3])>, bool)>;

fn triangle_hits(file: &ReducemFile, tracer: &Tracer, rays: &[Ray]) -> TriangleHits {
    let hits = tracer.intersect_batch(rays);
    let occluded = tracer.occluded_batch(rays);
    hits.iter()
        .map(|hit| hit.map(|h| (h.t.to_bits(), canonical(hit_triangle(file, &h)))))
        .zip(occluded)
        .collect()
}

/// Each ray's closest hit, every field's bits, and its occlusion answer.
fn all_bits(tracer: &Tracer, rays: &[Ray]) -> Vec<(Option<[u32; 8]>, bool)> {
    let hits = tracer.intersect_batch(rays);
    hits.iter()
        .map(hit_bits)
        .zip(tracer.occluded_batch(rays))
        .collect()
}

/// A 3.1 file's top-level nodes (128-byte f32 ones, or 64-byte grid ones in a lossless file)
/// and the 96-byte wide nodes of its mesh converted now (with the 3.1 pipeline's strip length,
/// so the strips are the same) hold the same strips with boxes rounded outward: every ray gets
/// the same hit, bit for bit, and the same occlusion answer, in every tracer configuration.
#[test]
fn format_3_1_nodes_and_wide_nodes_give_bit_identical_hits() {
    let rays = rays_around(0.0);
    let mesh = read_mesh(&fixture_path("tests/fixtures", "torus-24-12.ply")).expect("ply");
    let mut params = BuildParams::default();
    params.stripify.max_length = PIPELINE_MAX_STRIP_LENGTH;
    let (_, new) = converted(&mesh, &params, "wide-torus.rdm");
    assert_eq!(new.header().version_major, 4);
    for name in ["torus-format-3.1.rdm", "torus-grid-nodes-format-3.1.rdm"] {
        let old = ReducemFile::open(&fixture_path("tests/fixtures", name)).expect("open");
        assert_eq!(old.header().version_major, 3, "{name}");
        assert_eq!(
            decode::triangles(&new).collect::<Vec<_>>(),
            decode::triangles(&old).collect::<Vec<_>>(),
            "{name}: the same strips"
        );
        let expected = all_bits(&Tracer::new(&old, TraceOptions::default()), &rays);
        assert!(expected.iter().filter(|(_, o)| *o).count() > 500, "{name}");
        for (variant, tracer) in tracer_variants(&old).iter().chain(&tracer_variants(&new)) {
            let hits = all_bits(tracer, &rays);
            let differing: Vec<_> = (0..rays.len())
                .filter(|&i| hits[i] != expected[i])
                .map(|i| (i, hits[i], expected[i]))
                .collect();
            assert!(differing.is_empty(), "{name} {variant}: {differing:?}");
        }
    }
}

/// Far from the origin, where an 8-bit plane is far coarser than the coordinates' ulp, a
/// format 4 file's hits are the brute-force reference's: the same distance and triangle.
#[test]
fn wide_nodes_far_from_the_origin_give_the_reference_hits() {
    let offset = 1e5;
    let mut mesh = torus(40, 18);
    for p in &mut mesh.positions {
        *p = p.map(|c| c + offset);
    }
    let (_, file) = converted(&mesh, &BuildParams::default(), "wide-far.rdm");
    assert_eq!(file.header().version_major, 4);
    let rays = rays_around(offset);
    let expected: Vec<_> = rays
        .iter()
        .map(|ray| brute_force(&file, ray).map(|(t, triangle)| (t.to_bits(), canonical(triangle))))
        .collect();
    assert!(expected.iter().filter(|hit| hit.is_some()).count() > 500);
    for (variant, tracer) in tracer_variants(&file) {
        let hits = triangle_hits(&file, &tracer, &rays);
        let closest: Vec<_> = hits.iter().map(|(hit, _)| *hit).collect();
        assert_eq!(closest, expected, "{variant}");
        let occluded = hits.iter().map(|(_, o)| *o);
        assert!(
            occluded.zip(&expected).all(|(o, hit)| o == hit.is_some()),
            "{variant}"
        );
    }
}

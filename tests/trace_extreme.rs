//! Numerically hard geometry and rays against the brute-force watertight reference: offsets of
//! 1e6, scales from 1e-6 to 1e6, needles of aspect ratio 1e6, nearly coplanar and duplicate
//! triangles, rays along edges, from the surface, with signed zeros and with `tmin = tmax`,
//! coordinates near the f32 limits; and rays from inside closed meshes that must never escape.
//!
//! Agreement rule (as in `trace_agreement.rs`): hit or miss exactly as the reference says, `t`
//! within 1e-6 relative of the reference's (two triangles may hit at numerically the same
//! point), `t` bit-equal to the reported triangle's own `t`, packets bit-equal to single rays.
//!
//! The escape sweep here traces about 250,000 rays; `escape_campaign` (ignored, run by
//! `scripts/hostile.sh`) traces `REDUCEM_ESCAPE_RAYS` (default 10 million) over the same configs.

mod common;

use common::*;
use reducem::conversion::{convert_mesh, BuildParams, ChunkStats};
use reducem::format::reader::ReducemFile;
use reducem::geometry::Point;
use reducem::mesh::Mesh;
use reducem::trace::watertight::{intersect_triangle, RaySpace};
use reducem::trace::{Hit, Ray, TraceOptions, Tracer};

/// The mesh converted by the real build and, as a second layout, written as long strips.
fn both_layouts(mesh: &Mesh, name: &str) -> (ChunkStats, [ReducemFile; 2]) {
    let path = temp_path(&format!("{name}-build.rdm"));
    let stats = convert_mesh(mesh, &BuildParams::default(), &path).expect("convert");
    let built = ReducemFile::open(&path).expect("open");
    (
        stats,
        [
            built,
            open_with_long_strips(mesh, &format!("{name}-long.rdm"), 120),
        ],
    )
}

/// Checks every ray on both layouts; returns how many hit.
fn check_rays(mesh: &Mesh, rays: &[Ray], name: &str) -> usize {
    let (_, files) = both_layouts(mesh, name);
    // Both layouts agree with the reference, so they hit the same rays.
    let [built, long] = &files;
    check_rays_on(long, rays, name);
    check_rays_on(built, rays, name)
}

/// The triangle a hit names is hit by the ray on its own, at bit-identical `t`.
fn assert_reported_triangle_hit(file: &ReducemFile, ray: &Ray, hit: &Hit, name: &str) {
    let own = intersect_triangle(
        &RaySpace::new(ray.origin, ray.direction),
        &hit_triangle(file, hit),
        ray.tmin,
        ray.tmax,
    )
    .expect("the reported triangle is hit");
    assert_eq!(own.t.to_bits(), hit.t.to_bits(), "{name}: {ray:?}");
}

fn check_rays_on(file: &ReducemFile, rays: &[Ray], name: &str) -> usize {
    let variants = tracer_variants(file);
    let hits = variants[0].1.intersect_batch(rays);
    for (variant, tracer) in &variants {
        let variant_hits = tracer.intersect_batch(rays);
        let occluded = tracer.occluded_batch(rays);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(
                hit_bits(&hits[i]),
                hit_bits(&variant_hits[i]),
                "{name}: {variant} differs for {ray:?}"
            );
            assert_eq!(
                occluded[i],
                hits[i].is_some(),
                "{name}: {variant} occluded {ray:?}"
            );
        }
    }
    for (i, ray) in rays.iter().enumerate() {
        let reference = brute_force(file, ray);
        assert_eq!(
            hits[i].is_some(),
            reference.is_some(),
            "{name}: {ray:?}: tracer {:?}, reference {reference:?}",
            hits[i]
        );
        let (Some(hit), Some((t, _))) = (hits[i], reference) else {
            continue;
        };
        assert!(
            (hit.t - t).abs() <= 1e-6 * t.abs().max(f32::MIN_POSITIVE),
            "{name}: t {} vs reference {t} for {ray:?}",
            hit.t
        );
        assert!(ray.tmin <= hit.t && hit.t <= ray.tmax, "{name}: {ray:?}");
        assert_reported_triangle_hit(file, ray, &hit, name);
    }
    hits.iter().filter(|h| h.is_some()).count()
}

/// Random rays through the mesh's bounds plus rays aimed at every vertex and edge midpoint,
/// from origins up to one extent outside the bounds.
fn probing_rays(mesh: &Mesh, random: usize, seed: u64) -> Vec<Ray> {
    let bounds = mesh.bounds();
    let mut rng = SplitMix64::new(seed);
    let outside = |rng: &mut SplitMix64| -> Point {
        std::array::from_fn(|i| {
            let extent = bounds.max[i] - bounds.min[i];
            rng.range(bounds.min[i] - extent, bounds.max[i] + extent)
        })
    };
    let mut rays: Vec<Ray> = (0..random)
        .map(|_| {
            let origin = outside(&mut rng);
            let target = std::array::from_fn(|i| rng.range(bounds.min[i], bounds.max[i]));
            ray_towards(origin, target)
        })
        .collect();
    for target in vertex_and_edge_targets(mesh) {
        let origin = outside(&mut rng);
        rays.push(ray_towards(origin, target));
    }
    rays.retain(|ray| ray.direction != [0.0; 3]);
    rays
}

#[test]
fn offsets_and_scales_from_1e_minus_6_to_1e6_agree() {
    let shapes = [
        ("sphere", icosphere(2)),
        ("grid", grid(8, 6)),
        ("soup", soup(150, 21)),
    ];
    for scale in [1e-6f32, 1e-3, 1.0, 1e3, 1e6] {
        // At 1e6 the f32 spacing is 0.0625, so only shapes at least ~100 units large keep their
        // triangles; smaller ones collapse and are tested unshifted.
        let offsets: &[f32] = if scale >= 1e3 {
            &[0.0, 1e6, -1e6]
        } else {
            &[0.0]
        };
        for &offset in offsets {
            for (shape, mesh) in &shapes {
                let mesh = transformed(mesh, |x| x * scale + offset);
                let name = format!("{shape}-x{scale:e}+{offset:e}");
                let hits = check_rays(&mesh, &probing_rays(&mesh, 200, 5), &name);
                assert!(hits > 100, "{name}: only {hits} hits");
            }
        }
    }
}

/// Needles: triangles 1 long and 1e-6 wide (aspect ratio 1e6) in several orientations, side by
/// side and crossing each other.
fn needles(count: u32) -> Mesh {
    let mut rng = SplitMix64::new(17);
    let mut mesh = Mesh::default();
    for i in 0..count {
        let base: Point = [rng.unit(), rng.unit(), rng.unit()];
        let along: Point = [
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        ];
        let across: Point = [1e-6, if i % 2 == 0 { 0.0 } else { 1e-6 }, 0.0];
        let first = mesh.positions.len() as u32;
        mesh.positions.push(base);
        mesh.positions.push([0, 1, 2].map(|k| base[k] + along[k]));
        mesh.positions
            .push([0, 1, 2].map(|k| base[k] + along[k] * 0.5 + across[k]));
        mesh.triangles.push([first, first + 1, first + 2]);
    }
    mesh
}

#[test]
fn needles_of_aspect_ratio_1e6_agree() {
    let mesh = needles(300);
    let mut rays = probing_rays(&mesh, 500, 8);
    // Rays straight at the needles' middles, across their width.
    for t in &mesh.triangles {
        let [a, b, c] = mesh.triangle_points(t);
        let middle = [0, 1, 2].map(|k| (a[k] + b[k]) * 0.25 + c[k] * 0.5);
        rays.push(ray_towards([middle[0], middle[1], middle[2] + 3.0], middle));
    }
    check_rays(&mesh, &rays, "needles");
    check_rays(
        &slivers(200),
        &probing_rays(&slivers(200), 500, 9),
        "slivers",
    );
}

/// Overlapping triangles in planes 0, 1e-7 and exactly 0 again, rotated against each other.
fn coplanar_stack() -> Mesh {
    let mut mesh = Mesh::default();
    for (layer, (z, angle)) in [(0.0f32, 0.0f32), (1e-7, 0.3), (0.0, 0.7), (-1e-7, 1.1)]
        .into_iter()
        .enumerate()
    {
        let first = mesh.positions.len() as u32;
        for corner in 0..3 {
            let a = angle + corner as f32 * std::f32::consts::TAU / 3.0;
            let tilt = if layer == 3 {
                1e-7 * corner as f32
            } else {
                0.0
            };
            mesh.positions
                .push([2.0 * a.cos(), 2.0 * a.sin(), z + tilt]);
        }
        mesh.triangles.push([first, first + 1, first + 2]);
    }
    mesh
}

#[test]
fn nearly_coplanar_overlapping_triangles_agree() {
    let mesh = coplanar_stack();
    let mut rng = SplitMix64::new(4);
    let mut rays = probing_rays(&mesh, 500, 3);
    for _ in 0..500 {
        let target = [rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), 0.0];
        let height = if rng.unit() < 0.5 { 3.0 } else { -3.0 };
        rays.push(ray_towards(
            [target[0] * 0.9, target[1] * 1.1, height],
            target,
        ));
        // Grazing rays, nearly in the planes.
        rays.push(ray_towards(
            [-5.0, target[1], 1e-6],
            [5.0, -target[1], -1e-6],
        ));
    }
    let hits = check_rays(&mesh, &rays, "coplanar");
    assert!(hits > 300, "only {hits} hits");
}

#[test]
fn exact_duplicate_triangles_agree_and_stay_closed() {
    let sphere = icosphere(2);
    let mut doubled = sphere.clone();
    // The same indices again, and the same positions under new indices.
    doubled.triangles.extend(sphere.triangles.iter().rev());
    let offset = doubled.positions.len() as u32;
    doubled.positions.extend(sphere.positions.iter());
    doubled
        .triangles
        .extend(sphere.triangles.iter().map(|t| t.map(|v| v + offset)));
    let (stats, files) = both_layouts(&doubled, "duplicates");
    assert_eq!(
        stats.triangles + stats.dropped_triangles,
        doubled.triangles.len() as u64
    );
    let rays = probing_rays(&doubled, 300, 12);
    for file in &files {
        check_rays_on(file, &rays, "duplicates");
        assert_closed(file, &doubled, &[[0.0; 3], [0.3, -0.2, 0.1]], "duplicates");
    }
}

#[test]
fn rays_along_edges_agree() {
    for (name, mesh) in [("grid", grid(6, 5)), ("sphere", icosphere(1))] {
        let mut rays = Vec::new();
        for t in &mesh.triangles {
            for i in 0..3 {
                let p = mesh.positions[t[i] as usize];
                let q = mesh.positions[t[(i + 1) % 3] as usize];
                let direction = [0, 1, 2].map(|k| q[k] - p[k]);
                let before = [0, 1, 2].map(|k| p[k] - direction[k]);
                rays.push(Ray {
                    origin: before,
                    direction,
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
                // Starting on the edge's first vertex, along the edge.
                rays.push(Ray {
                    origin: p,
                    direction,
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
            }
        }
        check_rays(&mesh, &rays, &format!("{name}-edges"));
    }
}

#[test]
fn rays_starting_on_the_surface_agree() {
    let mesh = icosphere(2);
    let mut rng = SplitMix64::new(6);
    let mut rays = Vec::new();
    for t in &mesh.triangles {
        let [a, b, c] = mesh.triangle_points(t);
        let (u, v) = (rng.unit() * 0.5, rng.unit() * 0.5);
        let inner = [0, 1, 2].map(|k| a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]));
        let midpoint = [0, 1, 2].map(|k| a[k] * 0.5 + b[k] * 0.5);
        for origin in [a, midpoint, inner] {
            let direction = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ];
            rays.push(Ray {
                origin,
                direction,
                tmin: 0.0,
                tmax: f32::INFINITY,
            });
            rays.push(Ray {
                origin,
                direction,
                tmin: 1e-4,
                tmax: f32::INFINITY,
            });
        }
    }
    let hits = check_rays(&mesh, &rays, "surface-origins");
    assert!(hits > rays.len() / 3, "only {hits} of {} hit", rays.len());
}

#[test]
fn degenerate_intervals_tmin_equal_tmax_agree() {
    let mesh = icosphere(2);
    let (_, files) = both_layouts(&mesh, "tmin-tmax");
    let tracer = Tracer::new(&files[0], TraceOptions::default());
    let mut rays = Vec::new();
    for ray in probing_rays(&mesh, 300, 14) {
        let Some(hit) = tracer.intersect(&ray) else {
            continue;
        };
        for t in [f32::from_bits(hit.t.to_bits() + 1), hit.t * 0.5, 0.0] {
            rays.push(Ray {
                tmin: t,
                tmax: t,
                ..ray
            });
        }
    }
    let infinite = Ray {
        origin: [0.0, 0.0, 5.0],
        direction: [0.0, 0.0, -1.0],
        tmin: f32::INFINITY,
        tmax: f32::INFINITY,
    };
    rays.push(infinite);
    for file in &files {
        check_rays_on(file, &rays, "tmin-tmax");
        let tracer = Tracer::new(file, TraceOptions::default());
        assert_eq!(tracer.intersect(&infinite), None);
    }
}

#[test]
fn tmin_equal_tmax_at_the_hit_reports_it() {
    let mesh = icosphere(2);
    let (_, files) = both_layouts(&mesh, "tmin-tmax-exact");
    for file in &files {
        let tracer = Tracer::new(file, TraceOptions::default());
        for ray in probing_rays(&mesh, 300, 14) {
            if let Some(hit) = tracer.intersect(&ray) {
                let exact = Ray {
                    tmin: hit.t,
                    tmax: hit.t,
                    ..ray
                };
                assert!(brute_force(file, &exact).is_some(), "{exact:?}");
                assert_eq!(
                    tracer.intersect(&exact).map(|h| h.t),
                    Some(hit.t),
                    "{exact:?}"
                );
            }
        }
    }
}

#[test]
fn zero_hit_distance_keeps_its_sign() {
    let mesh = grid(6, 5);
    let (_, files) = both_layouts(&mesh, "zero-sign");
    for file in &files {
        let tracer = Tracer::new(file, TraceOptions::default());
        for t in &mesh.triangles {
            let [p, q, _] = mesh.triangle_points(t);
            let ray = Ray {
                origin: p,
                direction: [0, 1, 2].map(|k| q[k] - p[k]),
                tmin: 0.0,
                tmax: f32::INFINITY,
            };
            if let Some(hit) = tracer.intersect(&ray) {
                assert_reported_triangle_hit(file, &ray, &hit, "");
            }
        }
    }
}

#[test]
fn signed_zero_directions_give_the_same_hit() {
    // A grid's vertices and edges lie on integer lines: axis-parallel rays hit them exactly.
    let mesh = transformed(&grid(6, 5), |x| x * 1e3 + 1e6);
    let (_, files) = both_layouts(&mesh, "signed-zeros");
    for file in &files {
        let tracer = Tracer::new(file, TraceOptions::default());
        let mut rays = Vec::new();
        for target in vertex_and_edge_targets(&mesh) {
            for height in [1e4f32, -1e4] {
                let variants: Vec<Ray> = [[0.0f32, 0.0], [-0.0, 0.0], [0.0, -0.0], [-0.0, -0.0]]
                    .into_iter()
                    .map(|[x, y]| Ray {
                        origin: [target[0], target[1], target[2] + height],
                        direction: [x, y, -height.signum()],
                        tmin: 0.0,
                        tmax: f32::INFINITY,
                    })
                    .collect();
                let first = tracer.intersect(&variants[0]).map(|h| h.t.to_bits());
                assert!(first.is_some(), "{:?} missed", variants[0]);
                for ray in &variants[1..] {
                    assert_eq!(tracer.intersect(ray).map(|h| h.t.to_bits()), first);
                }
                rays.extend(variants);
            }
        }
        check_rays_on(file, &rays, "signed-zeros");
    }
}

/// The unit sphere scaled by `scale`, traced with the unit sphere's probing rays scaled along.
fn check_scaled_sphere(scale: f32) {
    let mesh = transformed(&icosphere(1), |x| x * scale);
    let rays: Vec<Ray> = probing_rays(&icosphere(1), 300, 2)
        .iter()
        .map(|ray| Ray {
            origin: ray.origin.map(|x| x * scale),
            ..*ray
        })
        .collect();
    let name = format!("huge-{scale:e}");
    let hits = check_rays(&mesh, &rays, &name);
    assert!(hits > 100, "{name}: only {hits} hits");
}

#[test]
fn large_coordinates_convert_and_agree() {
    for scale in [1e9f32, 1e11] {
        check_scaled_sphere(scale);
    }
}

/// Beyond `MAX_COORDINATE` the f32 watertight test could overflow (edge functions are products
/// of two coordinates, `t` of three), so conversion refuses the mesh with an error naming the
/// vertex and writes nothing; the readers refuse such files the same way (tests/input_*.rs).
#[test]
fn coordinates_near_the_f32_limits_are_refused_with_a_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut cases: Vec<(Mesh, String)> = [1e13f32, 1e20, 1e30, 1e38]
        .into_iter()
        .map(|scale| {
            (
                transformed(&icosphere(1), |x| x * scale),
                "vertex 0:".into(),
            )
        })
        .collect();
    let mut near_max = icosphere(1);
    near_max.positions[5] = [1.0, -f32::MAX, 0.5];
    cases.push((near_max, "vertex 5: coordinate y = -3.4028235e38".into()));
    for (mesh, expected) in cases {
        let path = dir.path().join("refused.rdm");
        let error = convert_mesh(&mesh, &BuildParams::default(), &path)
            .expect_err("out-of-range mesh converted");
        let message = error.to_string();
        assert!(
            message.contains(&expected) && message.contains("outside the supported range ±1e11"),
            "{message}"
        );
        assert!(!path.exists(), "a file was written for {expected}");
    }
}

/// Interior points of a sphere of `radius` around `center`.
fn interior_points(center: Point, radius: f32, count: usize, seed: u64) -> Vec<Point> {
    let mut rng = SplitMix64::new(seed);
    let mut points = vec![center];
    while points.len() < count {
        points.push(center.map(|c| c + rng.range(-0.5, 0.5) * radius));
    }
    points
}

/// Scale and offset of the unit sphere in the escape sweep: every scale from 1e-6 to 1e6, and
/// offsets of 1e6 where the sphere is large enough to keep its shape in f32 at that offset.
const ESCAPE_CONFIGS: [(f32, f32); 9] = [
    (1e-6, 0.0),
    (1e-6, 1e-4),
    (1e-3, 0.0),
    (1.0, 0.0),
    (1.0, 1e3),
    (1e3, 1e6),
    (1e3, -1e6),
    (1e6, 0.0),
    (1e6, 1e6),
];

/// Traces at least `rays` rays from inside the sphere over every config; returns the count.
fn escape_sweep(rays: usize) -> usize {
    let sphere = icosphere(3);
    let per_origin = 4 * vertex_and_edge_targets(&sphere).len();
    let origins = rays.div_ceil(ESCAPE_CONFIGS.len() * 2 * per_origin);
    let mut traced = 0;
    for (scale, offset) in ESCAPE_CONFIGS {
        let mesh = transformed(&sphere, |x| x * scale + offset);
        let name = format!("escape-x{scale:e}+{offset:e}");
        let (stats, files) = both_layouts(&mesh, &name);
        assert_eq!(
            stats.dropped_triangles, 0,
            "{name}: the sphere lost triangles"
        );
        let inside = interior_points([offset; 3], scale, origins, 31);
        for file in &files {
            traced += assert_closed(file, &mesh, &inside, &name);
        }
    }
    traced
}

#[test]
fn rays_from_inside_never_escape_across_offsets_and_scales() {
    let traced = escape_sweep(250_000);
    assert!(traced >= 200_000, "only {traced} rays");
}

#[test]
#[ignore = "10 million rays: run by scripts/hostile.sh"]
fn escape_campaign() {
    let rays = std::env::var("REDUCEM_ESCAPE_RAYS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000_000);
    let traced = escape_sweep(rays);
    println!("escape campaign: {traced} rays from inside, 0 escapes");
    assert!(traced >= rays, "only {traced} of {rays} rays");
}

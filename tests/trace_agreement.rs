//! The tracer against a brute-force watertight test over every decoded triangle.
//!
//! Tolerance: the tracer and the reference run the same per-triangle arithmetic, so a hit's `t`
//! must match the reference's to within 1e-6 relative (it is bit-equal unless two triangles hit
//! at numerically the same point, where either may win), and the reported triangle must be the
//! reference's or share a vertex with it.

mod common;

use common::*;
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::geometry::Point;
use reducem::mesh::Mesh;
use reducem::trace::watertight::{intersect_triangle, RaySpace};
use reducem::trace::{unit_normal, Kernel, Ray, TraceOptions, Tracer};

/// Checks one ray against the reference; returns whether it hit.
fn check_ray(tracer: &Tracer, ray: &Ray) -> bool {
    let file = tracer.file();
    let hit = tracer.intersect(ray);
    let reference = brute_force(file, ray);
    assert_eq!(
        hit.is_some(),
        reference.is_some(),
        "hit/miss disagree for {ray:?}: tracer {hit:?}, reference {reference:?}"
    );
    assert_eq!(tracer.occluded(ray), hit.is_some(), "occluded for {ray:?}");
    let (Some(hit), Some((t, triangle))) = (hit, reference) else {
        return false;
    };
    assert!(
        (hit.t - t).abs() <= 1e-6 * t.abs().max(1e-6),
        "t {} vs reference {t} for {ray:?}",
        hit.t
    );
    let reported = hit_triangle(file, &hit);
    assert!(
        reported == triangle || shares_vertex(&reported, &triangle),
        "tracer hit {reported:?}, reference {triangle:?} for {ray:?}"
    );
    let own = intersect_triangle(
        &RaySpace::new(ray.origin, ray.direction),
        &reported,
        ray.tmin,
        ray.tmax,
    )
    .expect("the reported triangle is hit");
    assert_eq!(
        own.t.to_bits(),
        hit.t.to_bits(),
        "t differs from its triangle's"
    );
    check_hit_point(ray, &hit, &reported);
    true
}

/// The barycentrics and normal describe the hit point on the reported triangle.
fn check_hit_point(ray: &Ray, hit: &reducem::trace::Hit, corners: &[Point; 3]) {
    let w0 = 1.0 - hit.u - hit.v;
    for axis in 0..3 {
        let on_triangle =
            w0 * corners[0][axis] + hit.u * corners[1][axis] + hit.v * corners[2][axis];
        let on_ray = ray.origin[axis] + hit.t * ray.direction[axis];
        let scale = corners.iter().map(|c| c[axis].abs()).fold(1.0f32, f32::max);
        assert!(
            (on_triangle - on_ray).abs() <= 1e-3 * scale,
            "hit point {on_triangle} vs ray point {on_ray} on axis {axis}"
        );
    }
    let length: f32 = hit.normal.iter().map(|x| x * x).sum::<f32>().sqrt();
    assert!((length - 1.0).abs() < 1e-5, "normal {:?}", hit.normal);
    assert_eq!(
        hit.normal.map(f32::to_bits),
        unit_normal(corners).map(f32::to_bits),
        "normal {:?} is not its triangle's",
        hit.normal
    );
}

fn random_rays(mesh: &Mesh, count: usize, seed: u64) -> Vec<Ray> {
    let bounds = mesh.bounds();
    let mut rng = SplitMix64::new(seed);
    let mut rays = Vec::with_capacity(count);
    for _ in 0..count {
        let origin: Point = std::array::from_fn(|i| {
            let extent = bounds.max[i] - bounds.min[i];
            rng.range(bounds.min[i] - extent, bounds.max[i] + extent)
        });
        let target: Point = std::array::from_fn(|i| rng.range(bounds.min[i], bounds.max[i]));
        rays.push(ray_towards(origin, target));
    }
    rays
}

fn aimed_rays(mesh: &Mesh, seed: u64) -> Vec<Ray> {
    let bounds = mesh.bounds();
    let mut rng = SplitMix64::new(seed);
    vertex_and_edge_targets(mesh)
        .into_iter()
        .map(|target| {
            let origin: Point = std::array::from_fn(|i| {
                let extent = (bounds.max[i] - bounds.min[i]).max(1.0);
                rng.range(bounds.min[i] - extent, bounds.max[i] + extent)
            });
            ray_towards(origin, target)
        })
        .collect()
}

fn check_mesh(mesh: &Mesh, name: &str) {
    let long = open_with_long_strips(mesh, &format!("{name}-long.rdm"), 120);
    let path = temp_path(&format!("{name}-build.rdm"));
    convert_mesh(mesh, &BuildParams::default(), &path).expect("convert");
    let built = ReducemFile::open(&path).expect("open");
    check_files(mesh, name, &[&long, &built]);
}

/// [`check_mesh`] for files with vertices on a `bits`-bit grid: the reference intersects the
/// decoded (quantized) triangles.
fn check_mesh_on_grid(mesh: &Mesh, name: &str, bits: u32) {
    let long = open_with_long_strips_on_grid(mesh, &format!("{name}-long-{bits}.rdm"), 120, bits);
    let path = temp_path(&format!("{name}-build-{bits}.rdm"));
    let params = BuildParams {
        grid_bits: Some(bits),
        ..BuildParams::default()
    };
    convert_mesh(mesh, &params, &path).expect("convert");
    let built = ReducemFile::open(&path).expect("open");
    check_files(mesh, &format!("{name} at {bits} bits"), &[&long, &built]);
}

fn check_files(mesh: &Mesh, name: &str, files: &[&ReducemFile]) {
    for &file in files {
        for (subtree_windows, kernel) in [1, 4, 64]
            .into_iter()
            .flat_map(|size| Kernel::supported().into_iter().map(move |k| (size, k)))
        {
            let options = TraceOptions {
                subtree_windows,
                packets: false,
                kernel,
            };
            let tracer = Tracer::new(file, options);
            let mut hits = 0;
            for ray in random_rays(mesh, 300, 7)
                .iter()
                .chain(&aimed_rays(mesh, 11))
            {
                hits += check_ray(&tracer, ray) as usize;
            }
            assert!(hits > 50, "{name}: only {hits} hits, the test is too weak");
        }
    }
}

#[test]
fn grid_agrees_with_brute_force() {
    check_mesh(&grid(12, 9), "grid");
}

#[test]
fn torus_agrees_with_brute_force() {
    check_mesh(&torus(16, 10), "torus");
}

#[test]
fn icosphere_agrees_with_brute_force() {
    check_mesh(&icosphere(2), "icosphere");
}

#[test]
fn soup_agrees_with_brute_force() {
    check_mesh(&soup(300, 5), "soup");
}

#[test]
fn slivers_agree_with_brute_force() {
    check_mesh(&slivers(60), "slivers");
}

#[test]
fn quantized_files_agree_with_brute_force_on_their_triangles() {
    for bits in [12, 20] {
        check_mesh_on_grid(&grid(12, 9), "grid", bits);
        check_mesh_on_grid(&torus(16, 10), "torus", bits);
        check_mesh_on_grid(&soup(300, 5), "soup", bits);
        check_mesh_on_grid(&slivers(60), "slivers", bits);
    }
}

#[test]
fn axis_parallel_rays_with_signed_zeros_hit_grid_vertices() {
    let mesh = grid(6, 5);
    let file = open_with_long_strips(&mesh, "grid-axis.rdm", 40);
    let tracer = Tracer::new(&file, TraceOptions::default());
    for target in vertex_and_edge_targets(&mesh) {
        for zero_x in [0.0f32, -0.0] {
            for zero_y in [0.0f32, -0.0] {
                let down = Ray {
                    origin: [target[0], target[1], 5.0],
                    direction: [zero_x, zero_y, -1.0],
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                };
                assert!(check_ray(&tracer, &down), "missed {target:?} from above");
                let up = Ray {
                    origin: [target[0], target[1], -5.0],
                    direction: [zero_x, zero_y, 1.0],
                    ..down
                };
                assert!(check_ray(&tracer, &up), "missed {target:?} from below");
            }
        }
    }
}

#[test]
fn axis_parallel_rays_in_bounding_planes() {
    // Rays running exactly in the plane of a box face or a kd-tree split plane.
    let mesh = grid(5, 5);
    let file = open_with_long_strips(&mesh, "grid-planes.rdm", 30);
    let tracer = Tracer::new(&file, TraceOptions::default());
    for y in [0.0f32, 0.5, 1.0, 5.0] {
        for z in [0.0f32, 0.1, 0.2, 0.4] {
            for dx in [1.0f32, -1.0] {
                for zero in [0.0f32, -0.0] {
                    let ray = Ray {
                        origin: [if dx > 0.0 { -1.0 } else { 6.0 }, y, z],
                        direction: [dx, zero, zero],
                        tmin: 0.0,
                        tmax: f32::INFINITY,
                    };
                    check_ray(&tracer, &ray);
                }
            }
        }
    }
}

#[test]
fn tmin_and_tmax_bound_the_hits() {
    let mesh = grid(4, 4);
    let file = open_with_long_strips(&mesh, "grid-range.rdm", 20);
    let tracer = Tracer::new(&file, TraceOptions::default());
    let ray = Ray {
        origin: [1.3, 2.6, 5.0],
        direction: [0.0, 0.0, -1.0],
        tmin: 0.0,
        tmax: f32::INFINITY,
    };
    let t = tracer.intersect(&ray).expect("hit").t;
    assert_eq!(
        tracer.intersect(&Ray { tmax: t, ..ray }).map(|h| h.t),
        Some(t)
    );
    assert_eq!(
        tracer.intersect(&Ray {
            tmax: t * 0.99,
            ..ray
        }),
        None
    );
    assert_eq!(
        tracer.intersect(&Ray {
            tmin: t * 1.01,
            ..ray
        }),
        None
    );
    assert!(!tracer.occluded(&Ray {
        tmax: t * 0.99,
        ..ray
    }));
}

/// A mesh of every generator kind, read back through the input module.
fn generated(kind: reducem_gen::Kind, triangles: u64) -> Mesh {
    let path = temp_path(&format!("gen-{kind:?}.ply"));
    reducem_gen::generate(kind, triangles, 3, &path).expect("generate");
    reducem::input::read_mesh(&path).expect("read generated mesh")
}

#[test]
fn every_generator_kind_agrees_with_brute_force() {
    use reducem_gen::Kind;
    for kind in Kind::ALL {
        let mesh = generated(kind, 1500);
        let path = temp_path(&format!("gen-{kind:?}.rdm"));
        convert_mesh(&mesh, &BuildParams::default(), &path).expect("convert");
        let file = ReducemFile::open(&path).expect("open");
        let tracer = Tracer::new(&file, TraceOptions::default());
        let mut aimed = aimed_rays(&mesh, 13);
        aimed.truncate(3000);
        let mut hits = 0;
        for ray in random_rays(&mesh, 300, 9).iter().chain(&aimed) {
            hits += check_ray(&tracer, ray) as usize;
        }
        assert!(hits > 100, "{kind:?}: only {hits} hits");
    }
}

/// Ambient-occlusion-like rays from scattered points of a scan, short and in every direction:
/// packets of them part ways after a few nodes, so most subtrees are walked by one lane alone.
/// Every kernel's packets must answer as the reference over all triangles.
#[test]
fn scattered_occlusion_packets_agree_with_brute_force() {
    let mesh = common::generated(reducem_gen::Kind::Scan, 6000);
    let (_, file) = converted(&mesh, &BuildParams::default(), "scattered-occlusion.rdm");
    let (min, max) = (file.header().bounds_min, file.header().bounds_max);
    let diagonal = (0..3)
        .map(|a| (max[a] - min[a]).powi(2))
        .sum::<f32>()
        .sqrt();
    let mut rng = SplitMix64::new(23);
    let rays: Vec<Ray> = (0..1600)
        .map(|_| Ray {
            origin: *rng.pick(&mesh.positions),
            direction: [0; 3].map(|_| rng.range(-1.0, 1.0)),
            tmin: 1e-4 * diagonal,
            tmax: rng.range(0.01, 0.2) * diagonal,
        })
        .collect();
    let expected: Vec<bool> = rays
        .iter()
        .map(|ray| brute_force(&file, ray).is_some())
        .collect();
    let occluded = expected.iter().filter(|&&o| o).count();
    assert!(
        occluded > 200 && rays.len() - occluded > 200,
        "{occluded} of {} occluded: the test is too weak",
        rays.len()
    );
    for kernel in Kernel::supported() {
        let options = TraceOptions {
            packets: true,
            kernel,
            ..TraceOptions::default()
        };
        let answers = Tracer::new(&file, options).occluded_batch(&rays);
        for ((ray, answer), expected) in rays.iter().zip(answers).zip(&expected) {
            assert_eq!(answer, *expected, "{kernel}: occlusion of {ray:?}");
        }
    }
}

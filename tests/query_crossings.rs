//! Every crossing of a ray, inside/outside and signed distance (`reducem::query`, `reducem
//! query --count/--all`, `reducem inside`, `reducem closest --signed`): counts and hit lists
//! equal a float64 brute force away from edges on every generator kind and on grid files; rays
//! through the vertices, edge midpoints and centroids of closed meshes in extreme transforms
//! count exactly one crossing from inside and an even number from outside; occupancy and the
//! sign of signed distance equal a float64 generalized winding number; the stored edge counts
//! equal a brute-force count; corrupt files fail the commands with exit 65.

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use common::{
    converted, fixture_path, generated, icosphere, open_with_long_strips,
    open_with_long_strips_on_grid, temp_path, torus, SplitMix64,
};
use reducem::conversion::BuildParams;
use reducem::decode;
use reducem::format::model::Closedness;
use reducem::format::reader::ReducemFile;
use reducem::geometry::Point;
use reducem::mesh::Mesh;
use reducem::query::crossings::{
    all_hits_on, count_crossings_on, crossing, for_each_crossing_of_packet, RayHit, PACKET_RAYS,
};
use reducem::query::occupancy::point_inside;
use reducem::query::{all_hits, count_crossings, occupancy, signed_closest_points, FaceIds};
use reducem::trace::watertight::RaySpace;
use reducem::trace::{Kernel, Ray};
use reducem_gen::Kind;

type Vector = [f64; 3];

fn wide(p: &Point) -> Vector {
    p.map(f64::from)
}

fn sub(x: &Vector, y: &Vector) -> Vector {
    std::array::from_fn(|i| x[i] - y[i])
}

fn dot(x: &Vector, y: &Vector) -> f64 {
    (0..3).map(|i| x[i] * y[i]).sum()
}

fn cross(x: &Vector, y: &Vector) -> Vector {
    [
        x[1] * y[2] - x[2] * y[1],
        x[2] * y[0] - x[0] * y[2],
        x[0] * y[1] - x[1] * y[0],
    ]
}

fn norm(x: &Vector) -> f64 {
    dot(x, x).sqrt()
}

/// The brute force's verdict on one ray and triangle.
#[derive(Debug, PartialEq)]
enum Verdict {
    Hit(f64),
    Miss,
    /// Too near an edge, a vertex, the plane or an end of the ray for float32 to decide.
    Unsure,
}

/// Möller–Trumbore in f64 with margins: barycentrics and `t` farther than `margin` (relative)
/// from their limits decide, anything nearer is unsure.
fn brute_force(ray: &Ray, triangle: &[Point; 3]) -> Verdict {
    let margin = 1e-4;
    let [a, b, c] = triangle.map(|p| wide(&p));
    let (origin, direction) = (wide(&ray.origin), wide(&ray.direction));
    let (e1, e2) = (sub(&b, &a), sub(&c, &a));
    let p = cross(&direction, &e2);
    let det = dot(&e1, &p);
    let scale = norm(&direction) * norm(&e1) * norm(&e2);
    if det.abs() <= margin * scale {
        return Verdict::Unsure;
    }
    let s = sub(&origin, &a);
    let u = dot(&s, &p) / det;
    let q = cross(&s, &e1);
    let v = dot(&direction, &q) / det;
    let t = dot(&e2, &q) / det;
    let weights = [1.0 - u - v, u, v];
    if weights.iter().any(|&w| w < -margin) {
        return Verdict::Miss;
    }
    if weights.iter().any(|&w| w < margin) {
        return Verdict::Unsure;
    }
    let (tmin, tmax) = (f64::from(ray.tmin), f64::from(ray.tmax));
    let slack = margin * (1.0 + t.abs());
    match t {
        t if t < tmin - slack || t > tmax + slack => Verdict::Miss,
        t if t < tmin + slack || t > tmax - slack => Verdict::Unsure,
        t => Verdict::Hit(t),
    }
}

/// Random rays through the bounds of `triangles`, some bounded.
fn random_rays(triangles: &[[Point; 3]], count: usize, seed: u64) -> Vec<Ray> {
    let points: Vec<&Point> = triangles.iter().flatten().collect();
    let low: Point = std::array::from_fn(|i| points.iter().map(|p| p[i]).fold(f32::MAX, f32::min));
    let high: Point = std::array::from_fn(|i| points.iter().map(|p| p[i]).fold(f32::MIN, f32::max));
    let mut rng = SplitMix64::new(seed);
    let mut point = |spread: f32| -> Point {
        std::array::from_fn(|i| {
            let (middle, half) = ((low[i] + high[i]) / 2.0, (high[i] - low[i]) / 2.0);
            rng.range(middle - spread * half, middle + spread * half)
        })
    };
    (0..count)
        .map(|k| {
            let origin = point(1.5);
            let target = point(1.0);
            Ray {
                origin,
                direction: std::array::from_fn(|i| target[i] - origin[i]),
                tmin: 0.0,
                tmax: if k % 3 == 0 { 1.0 } else { f32::INFINITY },
            }
        })
        .collect()
}

/// Counts and hit lists of `file` for random rays equal the brute force over its decoded
/// triangles, for every ray the brute force is sure of; returns how many rays were compared.
fn assert_file_exact(what: &str, file: &ReducemFile) -> usize {
    let triangles: Vec<[Point; 3]> = decode::triangles(file).collect();
    let rays = random_rays(&triangles, 400, 11);
    let counts = count_crossings(file, &rays);
    let hits = all_hits(file, &rays, &FaceIds::of(file));
    let mut compared = 0;
    for (index, ray) in rays.iter().enumerate() {
        let verdicts: Vec<Verdict> = triangles.iter().map(|t| brute_force(ray, t)).collect();
        if verdicts.contains(&Verdict::Unsure) {
            continue;
        }
        let mut expected: Vec<(f64, u32)> = verdicts
            .iter()
            .enumerate()
            .filter_map(|(face, v)| match v {
                Verdict::Hit(t) => Some((*t, face as u32)),
                _ => None,
            })
            .collect();
        expected.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let listed = &hits.hits[hits.splits[index] as usize..hits.splits[index + 1] as usize];
        assert_eq!(
            counts[index] as usize,
            expected.len(),
            "{what}: ray {index} {ray:?}"
        );
        let mut faces: Vec<u32> = listed.iter().map(|h| h.face_id).collect();
        faces.sort_unstable();
        let mut expected_faces: Vec<u32> = expected.iter().map(|e| e.1).collect();
        expected_faces.sort_unstable();
        assert_eq!(faces, expected_faces, "{what}: ray {index}");
        for pair in listed.windows(2) {
            assert!(
                (pair[0].t, pair[0].face_id) <= (pair[1].t, pair[1].face_id),
                "{what}: ray {index} hits out of order"
            );
        }
        for hit in listed {
            let t = expected
                .iter()
                .find(|e| e.1 == hit.face_id)
                .expect("listed")
                .0;
            assert!(
                (f64::from(hit.t) - t).abs() <= 1e-4 * (1.0 + t.abs()),
                "{what}: ray {index} face {} t {} against {t}",
                hit.face_id,
                hit.t
            );
        }
        compared += 1;
    }
    assert!(file.defect().is_none(), "{what}");
    compared
}

#[test]
fn every_generated_kind_counts_and_lists_as_the_brute_force() {
    for kind in Kind::ALL {
        let mesh = generated(kind, 2_000);
        let name = format!("crossings-{}.rdm", kind.name());
        let (_, file) = converted(&mesh, &BuildParams::default(), &name);
        let compared = assert_file_exact(kind.name(), &file);
        assert!(
            compared >= 200,
            "{}: only {compared} rays away from edges",
            kind.name()
        );
    }
}

#[test]
fn grid_files_count_their_quantized_triangles() {
    for (kind, bits) in [(Kind::Scan, 12), (Kind::Sphere, 16)] {
        let mesh = generated(kind, 2_000);
        let params = BuildParams {
            grid_bits: Some(bits),
            ..BuildParams::default()
        };
        let name = format!("crossings-grid-{}.rdm", kind.name());
        let (_, file) = converted(&mesh, &params, &name);
        let compared = assert_file_exact(&name, &file);
        assert!(
            compared >= 200,
            "{name}: only {compared} rays away from edges"
        );
    }
}

/// The crossings of `ray` by the scalar tie rule ([`crossing`]) on every triangle, in `decode`
/// order, nothing culled: what every kernel's walk must list, bit for bit.
fn scalar_hits(triangles: &[[Point; 3]], ray: &Ray) -> Vec<RayHit> {
    let space = RaySpace::new(ray.origin, ray.direction);
    let mut hits: Vec<RayHit> = triangles
        .iter()
        .enumerate()
        .filter_map(|(face, triangle)| {
            let hit = crossing(&space, triangle, ray.tmin, ray.tmax)?;
            Some(RayHit {
                t: hit.t,
                face_id: face as u32,
                u: hit.weights[1],
                v: hit.weights[2],
            })
        })
        .collect();
    hits.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.face_id.cmp(&b.face_id)));
    hits
}

fn hit_bits(hits: &[RayHit]) -> Vec<[u32; 4]> {
    hits.iter()
        .map(|h| [h.t.to_bits(), h.face_id, h.u.to_bits(), h.v.to_bits()])
        .collect()
}

/// Every kernel's counts and hit lists equal the scalar tie rule on every triangle, bit for
/// bit, for random rays and for rays through every vertex and edge midpoint.
fn assert_kernels_equal_the_scalar_rule(what: &str, file: &ReducemFile) {
    let triangles: Vec<[Point; 3]> = decode::triangles(file).collect();
    let mut rays = random_rays(&triangles, 200, 5);
    let points: Vec<Point> = triangles.iter().flatten().copied().collect();
    let centre: Point = std::array::from_fn(|i| {
        let sum: f64 = points.iter().map(|p| f64::from(p[i])).sum();
        (sum / points.len() as f64) as f32
    });
    let corners_and_midpoints = triangles.iter().take(300).flat_map(|[a, b, _]| {
        [
            *a,
            std::array::from_fn(|i| ((f64::from(a[i]) + f64::from(b[i])) / 2.0) as f32),
        ]
    });
    rays.extend(rays_at(centre, &corners_and_midpoints.collect::<Vec<_>>()));
    let expected: Vec<Vec<RayHit>> = rays
        .iter()
        .map(|ray| scalar_hits(&triangles, ray))
        .collect();
    let face_ids = FaceIds::of(file);
    for kernel in Kernel::supported() {
        let counts = count_crossings_on(file, &rays, kernel);
        let listed = all_hits_on(file, &rays, &face_ids, kernel);
        for (index, expected) in expected.iter().enumerate() {
            let hits =
                &listed.hits[listed.splits[index] as usize..listed.splits[index + 1] as usize];
            assert_eq!(
                hit_bits(hits),
                hit_bits(expected),
                "{what} {kernel}: ray {index} {:?}",
                rays[index]
            );
            assert_eq!(
                counts[index] as usize,
                expected.len(),
                "{what} {kernel}: ray {index}"
            );
        }
    }
    assert_packets_list_what_single_rays_list(what, file, &rays, &expected);
    assert_batches_with_invalid_rays_count_each_ray(what, file, &rays, &expected);
    assert!(file.defect().is_none(), "{what}");
}

/// A batch of the rays twice over (longer than one task's interleaved walks) with an invalid
/// ray after every seventh counts each valid ray's `expected` hits and nothing for the others.
fn assert_batches_with_invalid_rays_count_each_ray(
    what: &str,
    file: &ReducemFile,
    rays: &[Ray],
    expected: &[Vec<RayHit>],
) {
    let invalid = Ray {
        origin: [0.0; 3],
        direction: [0.0; 3],
        tmin: 0.0,
        tmax: f32::INFINITY,
    };
    let mut batch = Vec::new();
    let mut wanted = Vec::new();
    for (k, (ray, hits)) in rays
        .iter()
        .zip(expected)
        .cycle()
        .take(2 * rays.len())
        .enumerate()
    {
        batch.push(*ray);
        wanted.push(hits.len() as u32);
        if k % 7 == 6 {
            batch.push(invalid);
            wanted.push(0);
        }
    }
    for kernel in Kernel::supported() {
        assert_eq!(
            count_crossings_on(file, &batch, kernel),
            wanted,
            "{what} {kernel}"
        );
    }
}

/// Rays walked in packets of several sizes up to [`PACKET_RAYS`] (with an invalid ray among
/// them when there is room), on every kernel, find exactly the hits each ray finds alone
/// (`expected`).
fn assert_packets_list_what_single_rays_list(
    what: &str,
    file: &ReducemFile,
    rays: &[Ray],
    expected: &[Vec<RayHit>],
) {
    let face_ids = FaceIds::of(file);
    let invalid = Ray {
        origin: [f32::NAN, 0.0, 0.0],
        direction: [1.0, 0.0, 0.0],
        tmin: 0.0,
        tmax: f32::INFINITY,
    };
    for kernel in Kernel::supported() {
        for valid in [1, 3, PACKET_RAYS - 1, PACKET_RAYS] {
            for (chunk, first) in rays.chunks(valid).zip((0..).step_by(valid)) {
                let mut packet = chunk.to_vec();
                let hole = (packet.len() < PACKET_RAYS).then_some(packet.len() / 2);
                if let Some(hole) = hole {
                    packet.insert(hole, invalid);
                }
                let mut hits = vec![Vec::new(); packet.len()];
                for_each_crossing_of_packet(file, &packet, kernel, |lane, strip, window, hit| {
                    hits[lane].push(RayHit {
                        t: hit.t,
                        face_id: face_ids.id(file, strip, window).unwrap(),
                        u: hit.weights[1],
                        v: hit.weights[2],
                    })
                });
                if let Some(hole) = hole {
                    let skipped = hits.remove(hole);
                    assert!(
                        skipped.is_empty(),
                        "{what} {kernel}: an invalid ray crosses"
                    );
                }
                for (lane, mut lane_hits) in hits.into_iter().enumerate() {
                    lane_hits.sort_by(|a, b| a.t.total_cmp(&b.t).then(a.face_id.cmp(&b.face_id)));
                    let index = first + lane;
                    assert_eq!(
                        hit_bits(&lane_hits),
                        hit_bits(&expected[index]),
                        "{what} {kernel}: {valid} rays to a packet, ray {index}"
                    );
                }
            }
        }
    }
}

#[test]
fn every_kernel_lists_what_the_scalar_tie_rule_lists() {
    for kind in Kind::ALL {
        let mesh = generated(kind, 1_500);
        let name = format!("crossings-kernels-{}.rdm", kind.name());
        let (_, file) = converted(&mesh, &BuildParams::default(), &name);
        assert_kernels_equal_the_scalar_rule(kind.name(), &file);
    }
    let scan = generated(Kind::Scan, 1_500);
    let params = BuildParams {
        grid_bits: Some(12),
        ..BuildParams::default()
    };
    let (_, file) = converted(&scan, &params, "crossings-kernels-grid.rdm");
    assert_kernels_equal_the_scalar_rule("grid scan", &file);
    // Strips of up to 1000 windows store no block boxes and span more than one block mask.
    let sphere = icosphere(3);
    let file = open_with_long_strips(&sphere, "crossings-kernels-long.rdm", 1_000);
    assert_kernels_equal_the_scalar_rule("long strips", &file);
    let file = open_with_long_strips_on_grid(&sphere, "crossings-kernels-long-grid.rdm", 1_000, 14);
    assert_kernels_equal_the_scalar_rule("long grid strips", &file);
}

/// `mesh` with every position rotated about an oblique axis, scaled and moved, in f64 then
/// rounded once.
fn placed(mesh: &Mesh, scale: f64, offset: f64) -> Mesh {
    let (c, s) = (0.6f64, 0.8f64);
    let rotate = |p: Vector| -> Vector {
        let x = [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]];
        [c * x[0] + s * x[2], x[1], -s * x[0] + c * x[2]]
    };
    Mesh {
        positions: mesh
            .positions
            .iter()
            .map(|p| rotate(wide(p)).map(|x| (x * scale + offset) as f32))
            .collect(),
        triangles: mesh.triangles.clone(),
        ..Mesh::default()
    }
}

/// Every vertex, edge midpoint and centroid of `mesh`, as f32 points.
fn vertex_edge_and_centroid_targets(mesh: &Mesh) -> Vec<Point> {
    let mut targets = mesh.positions.clone();
    for t in &mesh.triangles {
        let [a, b, c] = mesh.triangle_points(t).map(|p| wide(&p));
        for (p, q) in [(a, b), (b, c), (c, a)] {
            targets.push(std::array::from_fn(|i| ((p[i] + q[i]) / 2.0) as f32));
        }
        targets.push(std::array::from_fn(|i| ((a[i] + b[i] + c[i]) / 3.0) as f32));
    }
    targets
}

fn rays_at(origin: Point, targets: &[Point]) -> Vec<Ray> {
    targets
        .iter()
        .map(|target| Ray {
            origin,
            direction: std::array::from_fn(|i| target[i] - origin[i]),
            tmin: 0.0,
            tmax: f32::INFINITY,
        })
        .collect()
}

#[test]
fn rays_through_vertices_edges_and_centroids_of_closed_meshes_count_exactly() {
    let sphere = icosphere(3);
    for (scale, offset) in [
        (1.0, 0.0),
        (100.0, 1e5),
        (1e-3, 0.0),
        (1e-3, 1.0),
        (1e3, -1e4),
    ] {
        let mesh = placed(&sphere, scale, offset);
        let what = format!("icosphere x{scale} + {offset}");
        let (_, file) = converted(&mesh, &BuildParams::default(), "crossings-hard.rdm");
        assert!(file.closed(), "{what}: {:?}", file.closedness());
        let targets = vertex_edge_and_centroid_targets(&mesh);
        let centre = [offset as f32; 3];
        let outside = [0, 1, 2].map(|i| (offset + scale * [2.9, -1.7, 2.3][i]) as f32);
        for kernel in Kernel::supported() {
            for (k, count) in count_crossings_on(&file, &rays_at(centre, &targets), kernel)
                .iter()
                .enumerate()
            {
                assert_eq!(
                    *count, 1,
                    "{what} {kernel}: from the centre at {:?}",
                    targets[k]
                );
            }
            for (k, count) in count_crossings_on(&file, &rays_at(outside, &targets), kernel)
                .iter()
                .enumerate()
            {
                assert_eq!(
                    count % 2,
                    0,
                    "{what} {kernel}: from outside at {:?}: {count}",
                    targets[k]
                );
            }
        }
    }
    let ring = torus(40, 16);
    let (_, file) = converted(&ring, &BuildParams::default(), "crossings-torus.rdm");
    assert!(file.closed());
    let targets = vertex_edge_and_centroid_targets(&ring);
    for (k, count) in count_crossings(&file, &rays_at([3.0, 0.0, 0.0], &targets))
        .iter()
        .enumerate()
    {
        assert_eq!(
            count % 2,
            1,
            "torus: from inside the tube at {:?}: {count}",
            targets[k]
        );
    }
}

/// The generalized winding number of `point` in f64 (van Oosterom and Strackee's solid angle).
fn winding_number(triangles: &[[Point; 3]], point: &Vector) -> f64 {
    let total: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|p| sub(&wide(&p), point));
            let (la, lb, lc) = (norm(&a), norm(&b), norm(&c));
            let numerator = dot(&a, &cross(&b, &c));
            let denominator = la * lb * lc + dot(&a, &b) * lc + dot(&b, &c) * la + dot(&c, &a) * lb;
            2.0 * numerator.atan2(denominator)
        })
        .sum();
    total / (4.0 * std::f64::consts::PI)
}

/// Points at `fraction` of the bounds' diagonal on both sides of the centroids of `triangles`.
fn points_beside(triangles: &[[Point; 3]], fraction: f64) -> Vec<Point> {
    let points: Vec<Vector> = triangles.iter().flatten().map(wide).collect();
    let low: Vector = std::array::from_fn(|i| points.iter().map(|p| p[i]).fold(f64::MAX, f64::min));
    let high: Vector =
        std::array::from_fn(|i| points.iter().map(|p| p[i]).fold(f64::MIN, f64::max));
    let step = fraction * norm(&sub(&high, &low));
    let mut beside = Vec::new();
    for t in triangles.iter().step_by(7) {
        let [a, b, c] = t.map(|p| wide(&p));
        let normal = cross(&sub(&b, &a), &sub(&c, &a));
        let length = norm(&normal);
        if length == 0.0 {
            continue;
        }
        for side in [-1.0, 1.0] {
            beside.push(std::array::from_fn(|i| {
                ((a[i] + b[i] + c[i]) / 3.0 + side * step * normal[i] / length) as f32
            }));
        }
    }
    beside
}

#[test]
fn occupancy_and_signs_equal_the_winding_number_on_closed_meshes() {
    let meshes = [
        ("icosphere", placed(&icosphere(3), 10.0, 1e3)),
        ("torus", torus(48, 20)),
        ("sphere", generated(Kind::Sphere, 2_000)),
    ];
    for (what, mesh) in meshes {
        let (_, file) = converted(&mesh, &BuildParams::default(), "crossings-occupancy.rdm");
        assert!(file.closed(), "{what}: {:?}", file.closedness());
        let triangles: Vec<[Point; 3]> = decode::triangles(&file).collect();
        let points = points_beside(&triangles, 1e-4);
        let answers = occupancy(&file, &points, 1);
        let signed = signed_closest_points(&file, &points, f32::INFINITY, 1);
        assert!(answers.exact && signed.exact, "{what}");
        for (k, point) in points.iter().enumerate() {
            let inside = winding_number(&triangles, &wide(point)) > 0.5;
            assert_eq!(answers.inside[k], inside, "{what}: point {k} {point:?}");
            assert_eq!(signed.signed_distance(k) < 0.0, inside, "{what}: point {k}");
        }
    }
}

#[test]
fn open_meshes_vote_and_say_they_are_not_exact() {
    let mesh = generated(Kind::Terrain, 2_000);
    let (_, file) = converted(&mesh, &BuildParams::default(), "crossings-open.rdm");
    assert!(!file.closed());
    let points = points_beside(&decode::triangles(&file).collect::<Vec<_>>(), 1e-3);
    let answers = occupancy(&file, &points, 5);
    assert!(!answers.exact);
    assert_eq!(answers.inside.len(), points.len());
    // The packets' votes are each point's own.
    for (k, point) in points.iter().enumerate() {
        assert_eq!(
            answers.inside[k],
            point_inside(&file, point, 5),
            "point {k}"
        );
    }
    assert!(answers.inside.iter().any(|&inside| inside));
    assert!(answers.inside.iter().any(|&inside| !inside));
}

/// Boundary and non-manifold edges of `mesh`'s non-degenerate triangles by a hash map of
/// position pairs: the definition, counted another way.
fn brute_force_edges(mesh: &Mesh) -> Closedness {
    let mut uses: HashMap<([u32; 3], [u32; 3]), (u32, u32)> = HashMap::new();
    for t in &mesh.triangles {
        let corners = mesh.triangle_points(t);
        let [a, b, c] = corners.map(|p| wide(&p));
        if t[0] == t[1]
            || t[1] == t[2]
            || t[0] == t[2]
            || norm(&cross(&sub(&b, &a), &sub(&c, &a))) == 0.0
        {
            continue;
        }
        let bits = corners.map(|p| p.map(f32::to_bits));
        for i in 0..3 {
            let (p, q) = (bits[i], bits[(i + 1) % 3]);
            let entry = uses.entry((p.min(q), p.max(q))).or_default();
            match p < q {
                true => entry.0 += 1,
                false => entry.1 += 1,
            }
        }
    }
    let mut counts = Closedness::default();
    for (forward, backward) in uses.values() {
        match (forward, backward) {
            (1, 0) | (0, 1) => counts.boundary_edges += 1,
            (1, 1) => {}
            _ => counts.nonmanifold_edges += 1,
        }
    }
    counts
}

#[test]
fn stored_edge_counts_equal_the_brute_force() {
    let mut fin = icosphere(1);
    let [a, b, _] = fin.triangles[0];
    fin.positions.push([0.0, 0.0, 3.0]);
    fin.triangles.push([a, b, fin.positions.len() as u32 - 1]);
    let mut flipped = torus(12, 8);
    flipped.triangles[5].swap(0, 1);
    let meshes = [
        ("icosphere", icosphere(2)),
        ("torus", torus(20, 10)),
        ("fin", fin),
        ("flipped", flipped),
        ("terrain", generated(Kind::Terrain, 2_000)),
        ("scan", generated(Kind::Scan, 2_000)),
        ("cad", generated(Kind::Cad, 2_000)),
    ];
    for (what, mesh) in meshes {
        let (_, file) = converted(&mesh, &BuildParams::default(), "crossings-edges.rdm");
        assert_eq!(file.closedness(), Some(brute_force_edges(&mesh)), "{what}");
    }
}

fn write_points(name: &str, points: &[Point]) -> PathBuf {
    let path = temp_path(name);
    let bytes: Vec<u8> = points
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    std::fs::write(&path, bytes).expect("write points");
    path
}

fn write_rays(name: &str, rays: &[Ray]) -> PathBuf {
    let path = temp_path(name);
    std::fs::write(&path, reducem::trace::ray_file::encode_rays(rays)).expect("write rays");
    path
}

fn reducem(args: &[&str], output: &Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(args)
        .arg(output)
        .output()
        .expect("run reducem")
}

fn words(path: &Path) -> Vec<u32> {
    let bytes = std::fs::read(path).expect("read answers");
    bytes
        .chunks_exact(4)
        .map(|w| u32::from_le_bytes(w.try_into().unwrap()))
        .collect()
}

#[test]
fn the_commands_write_the_documented_records() {
    let mesh = icosphere(2);
    let (path, file) = converted(&mesh, &BuildParams::default(), "crossings-cli.rdm");
    let model = path.to_str().unwrap();
    let targets = vertex_edge_and_centroid_targets(&mesh);
    let mut rays = rays_at([0.0; 3], &targets[..50]);
    rays.extend(rays_at([2.5, 0.1, 0.2], &targets[50..100]));
    let ray_path = write_rays("crossings-cli.rays", &rays);
    let rays_arg = ray_path.to_str().unwrap();

    let out = temp_path("crossings-cli.count");
    let run = reducem(&["query", model, "--rays", rays_arg, "--count", "-o"], &out);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(words(&out), count_crossings(&file, &rays));

    let out = temp_path("crossings-cli.all");
    let run = reducem(&["query", model, "--rays", rays_arg, "--all", "-o"], &out);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let expected = all_hits(&file, &rays, &FaceIds::of(&file));
    let mut words_expected = Vec::new();
    for ray in expected.splits.windows(2) {
        words_expected.push(ray[1] - ray[0]);
        for hit in &expected.hits[ray[0] as usize..ray[1] as usize] {
            words_expected.extend([
                hit.t.to_bits(),
                hit.face_id,
                hit.u.to_bits(),
                hit.v.to_bits(),
            ]);
        }
    }
    assert_eq!(words(&out), words_expected);

    let points = vec![
        [0.0, 0.0, 0.0],
        [0.5, 0.1, -0.2],
        [2.0, 0.0, 0.0],
        [0.0, -1.5, 0.3],
    ];
    let points_path = write_points("crossings-cli.points", &points);
    let points_arg = points_path.to_str().unwrap();
    let out = temp_path("crossings-cli.inside");
    let run = reducem(&["inside", model, "--points", points_arg, "-o"], &out);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(std::fs::read(&out).unwrap(), vec![1, 1, 0, 0]);

    let out = temp_path("crossings-cli.signed");
    let run = reducem(
        &["closest", model, "--points", points_arg, "--signed", "-o"],
        &out,
    );
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let records = words(&out);
    for (k, record) in records.chunks_exact(8).enumerate() {
        let inside = k < 2;
        assert_eq!(f32::from_bits(record[0]) < 0.0, inside, "point {k}");
        assert_eq!(record[7], u32::from(inside) | 2, "point {k} flags");
    }
}

#[test]
fn corrupt_files_fail_the_commands_with_exit_65() {
    let (path, _) = converted(
        &torus(30, 12),
        &BuildParams::default(),
        "crossings-corrupt-src.rdm",
    );
    let mut bytes = std::fs::read(&path).expect("read");
    // The model record's flags: its checksum no longer matches.
    bytes[500] ^= 0x01;
    let corrupt = temp_path("crossings-corrupt.rdm");
    std::fs::write(&corrupt, bytes).expect("write");
    let model = corrupt.to_str().unwrap();
    let rays = write_rays(
        "crossings-corrupt.rays",
        &rays_at([3.0, 0.0, 0.0], &[[9.0, 1.0, 0.5]]),
    );
    let points = write_points("crossings-corrupt.points", &[[3.0, 0.0, 0.0]]);
    for args in [
        vec![
            "query",
            model,
            "--rays",
            rays.to_str().unwrap(),
            "--count",
            "-o",
        ],
        vec![
            "query",
            model,
            "--rays",
            rays.to_str().unwrap(),
            "--all",
            "-o",
        ],
        vec!["inside", model, "--points", points.to_str().unwrap(), "-o"],
        vec![
            "closest",
            model,
            "--points",
            points.to_str().unwrap(),
            "--signed",
            "-o",
        ],
    ] {
        let out = temp_path("crossings-corrupt.out");
        let run = reducem(&args, &out);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(65), "{args:?}: {stderr}");
        assert!(stderr.contains("crossings-corrupt.rdm"), "{stderr}");
        assert!(!out.exists(), "{args:?}: no answers written");
    }
}

/// A `REDUCEM_KERNEL` naming no kernel this CPU runs is a usage error for every point and
/// crossing query, as for tracing: nothing is answered on a kernel nobody asked for.
#[test]
fn an_unknown_forced_kernel_is_refused_by_every_query_command() {
    let (path, _) = converted(&icosphere(1), &BuildParams::default(), "kernel-refused.rdm");
    let model = path.to_str().unwrap();
    let rays = write_rays(
        "kernel-refused.rays",
        &rays_at([0.0; 3], &[[1.0, 0.2, 0.1]]),
    );
    let points = write_points("kernel-refused.points", &[[0.1, 0.0, 0.0]]);
    let (rays, points) = (rays.to_str().unwrap(), points.to_str().unwrap());
    for args in [
        vec!["query", model, "--rays", rays, "--count", "-o"],
        vec!["query", model, "--rays", rays, "--all", "-o"],
        vec!["inside", model, "--points", points, "-o"],
        vec!["closest", model, "--points", points, "--signed", "-o"],
    ] {
        let out = temp_path("kernel-refused.out");
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_reducem"))
            .env("REDUCEM_KERNEL", "avx9")
            .args(&args)
            .arg(&out)
            .output()
            .expect("run reducem");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(64), "{args:?}: {stderr}");
        assert!(stderr.contains("REDUCEM_KERNEL=avx9"), "{stderr}");
        assert!(!out.exists(), "{args:?}: no answers written");
    }
}

fn inspect_json(path: &Path) -> serde_json::Value {
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(["inspect", "--json"])
        .arg(path)
        .output()
        .expect("run reducem");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    serde_json::from_slice(&run.stdout).expect("json")
}

#[test]
fn inspect_reports_closedness_and_3_0_files_read_as_unknown() {
    let (path, _) = converted(
        &torus(20, 10),
        &BuildParams::default(),
        "crossings-inspect.rdm",
    );
    let stats = inspect_json(&path);
    assert_eq!(stats["format_version"], "4.0");
    assert_eq!(stats["closed"], true);
    assert_eq!(stats["boundary_edges"], 0);
    assert_eq!(stats["nonmanifold_edges"], 0);
    assert_eq!(stats["up"], serde_json::Value::Null);

    // A torus as a 3.1 writer wrote it, and as a 3.0 writer would have: minor 0, zeros where
    // the model record is.
    let fixture = fixture_path("tests/fixtures", "torus-format-3.1.rdm");
    let stats = inspect_json(&fixture);
    assert_eq!(stats["format_version"], "3.1");
    assert_eq!(stats["closed"], true);
    assert_eq!(stats["boundary_edges"], 0);
    assert_eq!(stats["nonmanifold_edges"], 0);
    let mut bytes = std::fs::read(&fixture).expect("read");
    bytes[10..12].copy_from_slice(&0u16.to_le_bytes());
    bytes[480..512].fill(0);
    let checksum = xxhash_rust::xxh3::xxh3_64(&bytes[..200]);
    bytes[200..208].copy_from_slice(&checksum.to_le_bytes());
    let older = temp_path("crossings-inspect-3.0.rdm");
    std::fs::write(&older, bytes).expect("write");
    let file = ReducemFile::open(&older).expect("a 3.0 file still reads");
    assert_eq!(
        (file.closedness(), file.closed(), file.up_axis()),
        (None, false, None)
    );
    let stats = inspect_json(&older);
    assert_eq!(stats["format_version"], "3.0");
    assert_eq!(stats["closed"], false);
    assert_eq!(stats["boundary_edges"], serde_json::Value::Null);
    assert_eq!(stats["nonmanifold_edges"], serde_json::Value::Null);
    let answers = occupancy(&file, &[[3.0, 0.0, 0.0]], 3);
    assert_eq!((answers.inside, answers.exact), (vec![true], false));
}

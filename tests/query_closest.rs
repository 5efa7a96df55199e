//! Closest points (`reducem::query`, `reducem closest`) against a float64 brute force over the
//! decoded triangles: on every generator kind, lossless and grid files, points on the surface,
//! at vertices, near and far, the distance agrees within a few float32 ulps of the coordinates
//! and the returned point lies on the returned face; `--max-distance` cuts off where the brute
//! force says; the CLI writes the 32-byte records and refuses bad point files.

mod common;

use std::path::{Path, PathBuf};

use common::{canonical, converted, generated, temp_path, torus, SplitMix64};
use reducem::conversion::BuildParams;
use reducem::decode;
use reducem::format::reader::{ReducemFile, Validation};
use reducem::format::SectionKind;
use reducem::geometry::Point;
use reducem::query::{closest_points, ClosestPoint, ClosestPointSearch, FaceIds};
use reducem::trace::kernel::Kernel;
use reducem_gen::Kind;

type Vector = [f64; 3];

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

fn segment_distance(p: &Vector, x: &Vector, y: &Vector) -> f64 {
    let d = sub(y, x);
    let length = dot(&d, &d);
    let t = match length > 0.0 {
        true => (dot(&sub(p, x), &d) / length).clamp(0.0, 1.0),
        false => 0.0,
    };
    let q: Vector = std::array::from_fn(|i| x[i] + t * d[i]);
    dot(&sub(p, &q), &sub(p, &q)).sqrt()
}

/// The distance from `p` to a triangle in f64, another way than the library's: the plane's
/// distance when the projection falls inside, else the nearest edge.
fn triangle_distance(p: &Point, triangle: &[Point; 3]) -> f64 {
    let p = p.map(f64::from);
    let t = triangle.map(|c| c.map(f64::from));
    let normal = cross(&sub(&t[1], &t[0]), &sub(&t[2], &t[0]));
    let area = dot(&normal, &normal);
    if area > 0.0 {
        let height = dot(&sub(&p, &t[0]), &normal) / area;
        let q: Vector = std::array::from_fn(|i| p[i] - height * normal[i]);
        let inside = (0..3).all(|i| {
            let edge = sub(&t[(i + 1) % 3], &t[i]);
            dot(&cross(&edge, &sub(&q, &t[i])), &normal) >= 0.0
        });
        if inside {
            return height.abs() * area.sqrt();
        }
    }
    (0..3)
        .map(|i| segment_distance(&p, &t[i], &t[(i + 1) % 3]))
        .fold(f64::INFINITY, f64::min)
}

/// The brute force's nearest distance and the row of a nearest triangle.
fn brute_force(triangles: &[[Point; 3]], p: &Point) -> (f64, usize) {
    triangles
        .iter()
        .enumerate()
        .map(|(row, t)| (triangle_distance(p, t), row))
        .fold(
            (f64::INFINITY, usize::MAX),
            |a, b| if b.0 < a.0 { b } else { a },
        )
}

/// A few float32 ulps of the largest coordinate in play.
fn tolerance(triangles: &[[Point; 3]], points: &[Point]) -> f64 {
    let largest = triangles
        .iter()
        .flatten()
        .chain(points)
        .flatten()
        .fold(0.0f32, |m, c| m.max(c.abs()));
    8.0 * f64::from(f32::EPSILON) * f64::from(largest.max(1e-30))
}

/// Points on the surface, at vertices, near it (within 1% of the diagonal) and far from it.
fn query_points(triangles: &[[Point; 3]], count: usize, seed: u64) -> Vec<Point> {
    let mut rng = SplitMix64::new(seed);
    let corners: Vec<Point> = triangles.iter().flatten().copied().collect();
    let (lo, hi) = corners.iter().fold(
        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                std::array::from_fn(|i| lo[i].min(p[i])),
                std::array::from_fn(|i| hi[i].max(p[i])),
            )
        },
    );
    let diagonal = (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f32>().sqrt();
    let on_surface = |rng: &mut SplitMix64| {
        let t = triangles[rng.below(triangles.len())];
        let (mut u, mut v) = (rng.unit(), rng.unit());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        std::array::from_fn(|i| t[0][i] + u * (t[1][i] - t[0][i]) + v * (t[2][i] - t[0][i]))
    };
    (0..count)
        .map(|k| match k % 4 {
            0 => on_surface(&mut rng),
            1 => corners[rng.below(corners.len())],
            2 => {
                let p: Point = on_surface(&mut rng);
                std::array::from_fn(|i| p[i] + 0.01 * diagonal * rng.range(-0.6, 0.6))
            }
            _ => std::array::from_fn(|i| {
                let middle = 0.5 * (lo[i] + hi[i]);
                middle + (hi[i] - lo[i]).max(1.0) * rng.range(-1.5, 1.5)
            }),
        })
        .collect()
}

/// Checks `answers` (for `points`, with `max_distance`) against the brute force over
/// `triangles`, `file`'s triangles in `decode` order; `face_triangle` maps a face id to its
/// triangle. The barycentrics are those of the stored window's corners, which keep the input
/// winding but not necessarily its first corner.
fn assert_exact(
    what: &str,
    (file, triangles): (&ReducemFile, &[[Point; 3]]),
    points: &[Point],
    (answers, max_distance): (&[Option<ClosestPoint>], f32),
    face_triangle: &dyn Fn(u32) -> [Point; 3],
    face_ids: &[Option<u32>],
) {
    let tol = tolerance(triangles, points);
    for (k, (p, answer)) in points.iter().zip(answers).enumerate() {
        let (expected, _) = brute_force(triangles, p);
        let case = format!("{what}: point {k} {p:?}, brute force {expected}");
        let Some(found) = answer else {
            assert!(
                expected > f64::from(max_distance) - tol,
                "{case}: none found"
            );
            continue;
        };
        assert!(
            expected <= f64::from(max_distance) + tol,
            "{case}: beyond the limit"
        );
        let distance = f64::from(found.distance);
        assert!((distance - expected).abs() <= tol, "{case}: {found:?}");
        let face = face_ids[k].unwrap_or_else(|| panic!("{case}: no face id"));
        let triangle = face_triangle(face);
        assert!(
            triangle_distance(&found.point, &triangle) <= tol,
            "{case}: {found:?} is not on face {face} {triangle:?}"
        );
        assert!(
            (triangle_distance(p, &triangle) - expected).abs() <= tol,
            "{case}: face {face} is not a nearest one"
        );
        let to_point = (0..3)
            .map(|i| (f64::from(found.point[i]) - f64::from(p[i])).powi(2))
            .sum::<f64>()
            .sqrt();
        assert!(
            (to_point - distance).abs() <= 2.0 * tol,
            "{case}: {found:?}"
        );
        let stored = file
            .strip(found.strip as usize)
            .window_points(found.window as usize)
            .expect("a real triangle");
        assert_eq!(
            canonical(stored),
            canonical(triangle),
            "{case}: face {face}"
        );
        let (u, v) = (f64::from(found.u), f64::from(found.v));
        assert!(
            u >= 0.0 && v >= 0.0 && u + v <= 1.0 + 1e-6,
            "{case}: {found:?}"
        );
        let weighted: Vector = std::array::from_fn(|i| {
            let [a, b, c] = stored.map(|corner| f64::from(corner[i]));
            a + u * (b - a) + v * (c - a)
        });
        let off = (0..3)
            .map(|i| (weighted[i] - f64::from(found.point[i])).abs())
            .fold(0.0, f64::max);
        assert!(off <= tol, "{case}: u, v give {weighted:?}");
    }
}

/// Every answer of `file` for `points` checked against the brute force over its decoded
/// triangles, face ids being rows in `decode` order.
fn assert_file_exact(what: &str, file: &ReducemFile, points: &[Point], max_distance: f32) {
    let triangles: Vec<[Point; 3]> = decode::triangles(file).collect();
    let answers = closest_points(file, points, max_distance);
    let names = FaceIds::of(file);
    let ids: Vec<Option<u32>> = answers
        .iter()
        .map(|a| a.and_then(|a| names.id(file, a.strip, a.window)))
        .collect();
    let row = |face: u32| triangles[face as usize];
    let answered = (&answers[..], max_distance);
    assert_exact(what, (file, &triangles), points, answered, &row, &ids);
    assert!(file.defect().is_none(), "{what}");
}

#[test]
fn every_generated_kind_answers_as_the_brute_force() {
    for kind in Kind::ALL {
        let mesh = generated(kind, 3_000);
        let name = format!("closest-{}.rdm", kind.name());
        let (_, file) = converted(&mesh, &BuildParams::default(), &name);
        let triangles: Vec<[Point; 3]> = decode::triangles(&file).collect();
        let points = query_points(&triangles, 160, 11);
        assert_file_exact(kind.name(), &file, &points, f32::INFINITY);
    }
}

#[test]
fn grid_files_answer_on_their_quantized_triangles() {
    for (kind, bits, grid_nodes) in [
        (Kind::Scan, 12, true),
        (Kind::Sphere, 16, false),
        (Kind::Cad, 10, true),
    ] {
        let params = BuildParams {
            grid_bits: Some(bits),
            grid_nodes,
            ..BuildParams::default()
        };
        let mesh = generated(kind, 3_000);
        let name = format!("closest-grid-{}-{bits}.rdm", kind.name());
        let (_, file) = converted(&mesh, &params, &name);
        let triangles: Vec<[Point; 3]> = decode::triangles(&file).collect();
        let points = query_points(&triangles, 160, 12);
        assert_file_exact(&name, &file, &points, f32::INFINITY);
    }
}

/// A batch large enough to be answered in spatial order equals the same points searched one
/// at a time in input order, with every kernel, bit for bit; and agrees with the brute force.
#[test]
fn every_kernel_and_the_spatial_order_answer_as_one_point_at_a_time() {
    for (kind, grid_bits) in [(Kind::Scan, None), (Kind::Cad, Some(12))] {
        let params = BuildParams {
            grid_bits,
            grid_nodes: grid_bits.is_some(),
            ..BuildParams::default()
        };
        let mesh = generated(kind, 3_000);
        let name = format!("closest-order-{}.rdm", kind.name());
        let (_, file) = converted(&mesh, &params, &name);
        let triangles: Vec<[Point; 3]> = decode::triangles(&file).collect();
        let points = query_points(&triangles, 6_000, 13);
        let batch = closest_points(&file, &points, f32::INFINITY);
        for kernel in Kernel::supported() {
            let mut search = ClosestPointSearch::with_kernel(&file, kernel);
            for (k, point) in points.iter().enumerate() {
                let alone = search.closest(point, f32::INFINITY);
                let bits = |a: Option<ClosestPoint>| {
                    a.map(|a| {
                        (
                            a.distance.to_bits(),
                            a.point.map(f32::to_bits),
                            a.strip,
                            a.window,
                        )
                    })
                };
                assert_eq!(bits(alone), bits(batch[k]), "{name} {kernel}: point {k}");
                // Without a previous point to bound the search.
                let fresh =
                    ClosestPointSearch::with_kernel(&file, kernel).closest(point, f32::INFINITY);
                assert_eq!(
                    bits(fresh),
                    bits(batch[k]),
                    "{name} {kernel}: point {k} alone"
                );
                assert_eq!(
                    alone.map(|a| (a.u.to_bits(), a.v.to_bits())),
                    batch[k].map(|a| (a.u.to_bits(), a.v.to_bits()))
                );
            }
        }
        assert_file_exact(&name, &file, &points, f32::INFINITY);
    }
}

#[test]
fn the_maximum_distance_cuts_off_where_the_brute_force_says() {
    let mesh = generated(Kind::Isosurface, 2_000);
    let (_, file) = converted(&mesh, &BuildParams::default(), "closest-limit.rdm");
    let triangles: Vec<[Point; 3]> = decode::triangles(&file).collect();
    let points = query_points(&triangles, 200, 13);
    let mut distances: Vec<f64> = points
        .iter()
        .map(|p| brute_force(&triangles, p).0)
        .collect();
    distances.sort_by(f64::total_cmp);
    for quantile in [0.0, 0.3, 0.6, 0.9] {
        let limit = distances[(quantile * distances.len() as f64) as usize] as f32;
        let answers = closest_points(&file, &points, limit);
        let found = answers.iter().filter(|a| a.is_some()).count();
        assert!(found > 0, "limit {limit}: points on the surface are found");
        assert!(found < points.len(), "limit {limit}: far points are not");
        assert_file_exact(&format!("limit {limit}"), &file, &points, limit);
    }
}

#[test]
fn stored_face_ids_name_the_input_triangle() {
    let mut mesh = torus(40, 24);
    let count = mesh.triangles.len() as u32;
    mesh.face_ids = Some((0..count).map(|i| (i * 7919) % count + 1000).collect());
    let mut params = BuildParams::default();
    params.attributes.face_ids = true;
    let (_, file) = converted(&mesh, &params, "closest-face-ids.rdm");
    assert!(matches!(FaceIds::of(&file), FaceIds::Stored));
    let triangles: Vec<[Point; 3]> = decode::triangles(&file).collect();
    let points = query_points(&triangles, 200, 14);
    let answers = closest_points(&file, &points, f32::INFINITY);
    let ids: Vec<Option<u32>> = answers
        .iter()
        .map(|a| a.and_then(|a| file.face_id(a.strip as usize, a.window as usize)))
        .collect();
    let ids_in = mesh.face_ids.clone().expect("ids");
    let input = |face: u32| {
        let row = ids_in
            .iter()
            .position(|&id| id == face)
            .expect("an input id");
        mesh.triangle_points(&mesh.triangles[row])
    };
    let answers_and_limit = (&answers[..], f32::INFINITY);
    let triangles = (&file, &triangles[..]);
    assert_exact(
        "face ids",
        triangles,
        &points,
        answers_and_limit,
        &input,
        &ids,
    );
}

/// `bytes` with strip `strip`'s record claiming one vertex: corrupt in every encoding.
fn with_corrupt_strip(bytes: &[u8], strip: usize) -> Vec<u8> {
    let entry = 104 + (SectionKind::StripRecords as usize - 1) * 32;
    let field = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let record = field(entry + 8) + strip * 8;
    let mut corrupt = bytes.to_vec();
    corrupt[record + 4..record + 6].copy_from_slice(&1u16.to_le_bytes());
    corrupt
}

#[test]
fn a_corrupt_strip_reached_by_a_query_is_the_defect_reported() {
    let (path, intact) = converted(&torus(60, 30), &BuildParams::default(), "closest-lazy.rdm");
    let strip = intact.strip_count() / 2;
    let corrupt_path = temp_path("closest-lazy-corrupt.rdm");
    let bytes = std::fs::read(&path).expect("read");
    std::fs::write(&corrupt_path, with_corrupt_strip(&bytes, strip)).expect("write");
    let corrupt = ReducemFile::open_with(&corrupt_path, Validation::Lazy).expect("opens lazily");
    let view = intact.strip(strip);
    let centroids: Vec<Point> = (0..view.window_count())
        .filter_map(|k| view.window_points(k))
        .map(|[a, b, c]| std::array::from_fn(|i| (a[i] + b[i] + c[i]) / 3.0))
        .collect();
    closest_points(&corrupt, &centroids, f32::INFINITY);
    let defect = corrupt
        .defect()
        .expect("the corrupt strip was reached")
        .to_string();
    assert!(defect.contains("closest-lazy-corrupt.rdm"), "{defect}");
    assert!(defect.contains(&format!("strip {strip}")), "{defect}");
    assert!(defect.contains(" at byte "), "{defect}");
    let model = corrupt_path.to_str().unwrap();
    let points = write_points("closest-lazy.points", &centroids);
    let out = temp_path("closest-lazy.out");
    let run = reducem(
        &["closest", model, "--points", points.to_str().unwrap(), "-o"],
        &out,
    );
    assert_eq!(run.status.code(), Some(65), "{}", stderr(&run));
    assert!(!out.exists(), "no incomplete answers written");
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

/// `reducem` with `args` followed by `output`.
fn reducem(args: &[&str], output: &Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(args)
        .arg(output)
        .output()
        .expect("run reducem")
}

fn stderr(output: &std::process::Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn the_command_writes_one_32_byte_record_per_point() {
    let mesh = generated(Kind::Terrain, 2_000);
    let (path, file) = converted(&mesh, &BuildParams::default(), "closest-cli.rdm");
    let triangles: Vec<[Point; 3]> = decode::triangles(&file).collect();
    let points = query_points(&triangles, 120, 16);
    let limit = 0.5 * brute_force(&triangles, &points[3]).0 as f32;
    let points_path = write_points("closest-cli.points", &points);
    let out = temp_path("closest-cli.out");
    let args = [
        "closest",
        path.to_str().unwrap(),
        "--points",
        points_path.to_str().unwrap(),
        "--max-distance",
        &limit.to_string(),
        "--threads",
        "2",
        "-o",
    ];
    let run = reducem(&args, &out);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        stderr(&run).contains("reducem: closest: points=120 "),
        "{}",
        stderr(&run)
    );
    let bytes = std::fs::read(&out).expect("answers");
    assert_eq!(bytes.len(), 32 * points.len());
    let expected = closest_points(&file, &points, limit);
    let names = FaceIds::of(&file);
    let mut misses = 0;
    for (k, (record, answer)) in bytes.chunks_exact(32).zip(&expected).enumerate() {
        let word = |i: usize| u32::from_le_bytes(record[4 * i..4 * i + 4].try_into().unwrap());
        assert_eq!(word(7), 0, "point {k}: flags");
        let Some(answer) = answer else {
            misses += 1;
            assert_eq!(f32::from_bits(word(0)), f32::INFINITY, "point {k}");
            assert_eq!(word(4), u32::MAX, "point {k}");
            assert!((1..4).chain(5..7).all(|i| f32::from_bits(word(i)).is_nan()));
            continue;
        };
        let id = names.id(&file, answer.strip, answer.window).expect("a row");
        let bits = [
            answer.distance.to_bits(),
            answer.point[0].to_bits(),
            answer.point[1].to_bits(),
            answer.point[2].to_bits(),
            id,
            answer.u.to_bits(),
            answer.v.to_bits(),
        ];
        assert_eq!((0..7).map(word).collect::<Vec<_>>(), bits, "point {k}");
    }
    assert!(
        misses > 0 && misses < points.len(),
        "{misses} beyond {limit}"
    );
}

#[test]
fn the_command_refuses_bad_point_files_and_arguments() {
    let (path, _) = converted(&torus(12, 8), &BuildParams::default(), "closest-bad.rdm");
    let model = path.to_str().unwrap();
    let out = temp_path("closest-bad.out");
    std::fs::write(&out, b"earlier answers").expect("write");
    let run_with = |points: &Path, extra: &[&str]| {
        let mut args = vec!["closest", model, "--points", points.to_str().unwrap()];
        args.extend(extra);
        args.push("-o");
        reducem(&args, &out)
    };
    let short = temp_path("closest-bad-short.points");
    std::fs::write(&short, [0u8; 25]).expect("write");
    let run = run_with(&short, &[]);
    assert_eq!(run.status.code(), Some(65));
    assert!(
        stderr(&run).contains("closest-bad-short.points: 25 bytes"),
        "{}",
        stderr(&run)
    );

    let nan = write_points("closest-bad-nan.points", &[[0.0; 3], [1.0, f32::NAN, 2.0]]);
    let run = run_with(&nan, &[]);
    assert_eq!(run.status.code(), Some(65));
    assert!(
        stderr(&run).contains("point 1 (byte 16): coordinate y"),
        "{}",
        stderr(&run)
    );

    let fine = write_points("closest-bad-fine.points", &[[0.0; 3]]);
    let run = run_with(&fine, &["--max-distance", "-1"]);
    assert_eq!(run.status.code(), Some(64), "{}", stderr(&run));
    let run = run_with(&temp_path("closest-bad-missing.points"), &[]);
    assert_eq!(run.status.code(), Some(74), "{}", stderr(&run));
    assert_eq!(std::fs::read(&out).expect("kept"), b"earlier answers");

    let run = reducem(&["closest", model, "--points", model, "-o"], &path);
    assert_eq!(run.status.code(), Some(64), "{}", stderr(&run));
    assert!(ReducemFile::open(&path).is_ok(), "the model is intact");
}

//! `reducem query`: ray files against the library, and malformed ray files rejected.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;
use reducem::trace::ray_file::{encode_rays, RAY_BYTES};
use reducem::trace::{Kernel, Ray, TraceOptions, Tracer};

fn run_query(model: &Path, rays: &Path, out: &Path, occluded: bool) -> std::process::Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_reducem"));
    command
        .arg("query")
        .arg(model)
        .arg("--rays")
        .arg(rays)
        .arg("-o")
        .arg(out);
    if occluded {
        command.arg("--occluded");
    }
    command.output().expect("run reducem")
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

fn sample_rays() -> Vec<Ray> {
    let mut rng = SplitMix64::new(17);
    (0..500)
        .map(|_| {
            let origin = [
                rng.range(-6.0, 6.0),
                rng.range(-6.0, 6.0),
                rng.range(-3.0, 3.0),
            ];
            let target = [
                rng.range(-4.0, 4.0),
                rng.range(-4.0, 4.0),
                rng.range(-1.0, 1.0),
            ];
            let mut ray = ray_towards(origin, target);
            ray.tmax = if rng.unit() < 0.5 {
                f32::INFINITY
            } else {
                rng.range(0.1, 2.0)
            };
            ray
        })
        .collect()
}

#[test]
fn query_round_trip_matches_the_library() {
    let mesh = torus(20, 10);
    let model = temp_path("query-torus.rdm");
    write_strips(&mesh, &long_strips(&mesh, 50), 2, &model);
    let file = reducem::format::reader::ReducemFile::open(&model).expect("open");
    let tracer = Tracer::new(&file, TraceOptions::default());
    let rays = sample_rays();
    let ray_path = temp_path("query.rays");
    std::fs::write(&ray_path, encode_rays(&rays)).expect("write rays");

    let hits_path = temp_path("query.hits");
    let output = run_query(&model, &ray_path, &hits_path, false);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let values = f32s(&std::fs::read(&hits_path).expect("hits"));
    assert_eq!(values.len(), 4 * rays.len());
    let mut hit_count = 0;
    for (ray, record) in rays.iter().zip(values.chunks_exact(4)) {
        match tracer.intersect(ray) {
            Some(hit) => {
                hit_count += 1;
                assert_eq!(record[0].to_bits(), hit.t.to_bits());
                assert_eq!(record[1..], hit.normal[..]);
            }
            None => assert_eq!(record, [f32::INFINITY, 0.0, 0.0, 0.0]),
        }
    }
    assert!(hit_count > 50 && hit_count < rays.len());

    let occluded_path = temp_path("query.occluded");
    let output = run_query(&model, &ray_path, &occluded_path, true);
    assert!(output.status.success());
    let bytes = std::fs::read(&occluded_path).expect("occluded");
    let expected: Vec<u8> = rays.iter().map(|r| tracer.occluded(r) as u8).collect();
    assert_eq!(bytes, expected);
}

/// Runs a query over `bytes` as the ray file; it must fail with `expected` in the message and
/// write nothing.
fn assert_rejected(bytes: &[u8], name: &str, expected: &str) {
    let mesh = grid(3, 3);
    // A model per case: tests run in parallel, and two writers of one path would collide.
    let model = temp_path(&format!("{name}.rdm"));
    write_strips(&mesh, &long_strips(&mesh, 10), 2, &model);
    let ray_path = temp_path(name);
    std::fs::write(&ray_path, bytes).expect("write rays");
    let out = temp_path(&format!("{name}.hits"));
    let output = run_query(&model, &ray_path, &out, false);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{name} accepted");
    assert!(
        stderr.contains(name),
        "message does not name the file: {stderr}"
    );
    assert!(
        stderr.contains(expected),
        "expected {expected:?} in: {stderr}"
    );
    assert!(!out.exists(), "output written for {name}");
}

fn good_ray() -> Ray {
    Ray {
        origin: [0.5, 0.5, 3.0],
        direction: [0.0, 0.0, -1.0],
        tmin: 0.0,
        tmax: f32::INFINITY,
    }
}

#[test]
fn malformed_ray_files_are_rejected_with_position() {
    let two = encode_rays(&[good_ray(), good_ray()]);
    assert_rejected(
        &two[..RAY_BYTES + 20],
        "truncated.rays",
        "52 bytes is not a multiple of 32 (8 little-endian f32 per ray): ray 1 at byte 32",
    );
    let nan = encode_rays(&[
        good_ray(),
        Ray {
            origin: [0.0, f32::NAN, 0.0],
            ..good_ray()
        },
    ]);
    assert_rejected(&nan, "nan.rays", "ray 1 at byte 36: oy is NaN");
    let zero = encode_rays(&[Ray {
        direction: [0.0, -0.0, 0.0],
        ..good_ray()
    }]);
    assert_rejected(&zero, "zero.rays", "ray 0 at byte 12: direction is zero");
    let reversed = encode_rays(&[
        good_ray(),
        good_ray(),
        Ray {
            tmin: 2.0,
            tmax: 1.0,
            ..good_ray()
        },
    ]);
    assert_rejected(
        &reversed,
        "reversed.rays",
        "ray 2 at byte 88: tmin 2 is greater than tmax 1",
    );
    let negative = encode_rays(&[Ray {
        tmin: -1.0,
        ..good_ray()
    }]);
    assert_rejected(
        &negative,
        "negative.rays",
        "ray 0 at byte 24: tmin -1 is negative",
    );
}

#[test]
fn nan_and_infinite_fields_are_rejected_by_name() {
    let names = ["ox", "oy", "oz", "dx", "dy", "dz", "tmin", "tmax"];
    for (field, name) in names.iter().enumerate() {
        let mut bytes = encode_rays(&[good_ray(), good_ray()]);
        let at = RAY_BYTES + 4 * field;
        bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let offset = format!("ray 1 at byte {at}: {name} is NaN");
        assert_rejected(&bytes, &format!("nan-{name}.rays"), &offset);
        // tmax may be +inf (an unbounded ray); tmin = +inf is a valid, empty interval.
        if field < 6 {
            for infinity in [f32::INFINITY, f32::NEG_INFINITY] {
                bytes[at..at + 4].copy_from_slice(&infinity.to_le_bytes());
                let expected = format!("ray 1 at byte {at}: {name} is infinite");
                assert_rejected(&bytes, &format!("inf-{name}.rays"), &expected);
            }
        }
    }
    let mut negative_tmax = good_ray();
    negative_tmax.tmax = f32::NEG_INFINITY;
    assert_rejected(
        &encode_rays(&[negative_tmax]),
        "negative-tmax.rays",
        "ray 0 at byte 24: tmin 0 is greater than tmax -inf",
    );
}

#[test]
fn an_invalid_ray_rejects_the_batch_with_exit_code_65() {
    let mesh = grid(3, 3);
    let model = temp_path("invalid-default.rdm");
    write_strips(&mesh, &long_strips(&mesh, 10), 2, &model);
    let zero = Ray {
        direction: [0.0; 3],
        ..good_ray()
    };
    let ray_path = temp_path("invalid-default.rays");
    std::fs::write(&ray_path, encode_rays(&[good_ray(), zero])).expect("write rays");
    let out = temp_path("invalid-default.hits");
    let output = run_query(&model, &ray_path, &out, false);
    assert_eq!(output.status.code(), Some(65));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("ray 1 at byte 44: direction is zero"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn invalid_rays_miss_answers_each_as_a_miss_and_counts_them() {
    let mesh = grid(3, 3);
    let model = temp_path("invalid-miss.rdm");
    write_strips(&mesh, &long_strips(&mesh, 10), 2, &model);
    let nan = Ray {
        origin: [f32::NAN, 0.0, 0.0],
        ..good_ray()
    };
    let zero = Ray {
        direction: [0.0; 3],
        ..good_ray()
    };
    let rays = [nan, good_ray(), zero, good_ray()];
    let ray_path = temp_path("invalid-miss.rays");
    std::fs::write(&ray_path, encode_rays(&rays)).expect("write rays");
    let file = reducem::format::reader::ReducemFile::open(&model).expect("open");
    let tracer = Tracer::new(&file, TraceOptions::default());
    let hit = tracer
        .intersect(&good_ray())
        .expect("the good ray hits the grid");

    for occluded in [false, true] {
        let out = temp_path(&format!("invalid-miss-{occluded}.out"));
        let mut command = Command::new(env!("CARGO_BIN_EXE_reducem"));
        command
            .arg("query")
            .arg(&model)
            .arg("--rays")
            .arg(&ray_path);
        command.arg("-o").arg(&out).args(["--invalid-rays", "miss"]);
        if occluded {
            command.arg("--occluded");
        }
        let output = command.output().expect("run reducem");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{stderr}");
        assert!(
            stderr.contains("2 invalid rays answered as misses (first: ")
                && stderr.contains("ray 0 at byte 0: ox is NaN"),
            "{stderr}"
        );
        let summary = stderr
            .lines()
            .find(|line| line.starts_with("reducem: query: rays="))
            .unwrap_or_else(|| panic!("no summary line in {stderr}"));
        assert!(
            summary.contains("rays=4 invalid=2 hits=2 seconds=")
                && summary.contains(" mrays_per_s="),
            "{summary}"
        );
        let bytes = std::fs::read(&out).expect("answers");
        if occluded {
            assert_eq!(bytes, [0, 1, 0, 1]);
        } else {
            let miss = [f32::INFINITY, 0.0, 0.0, 0.0];
            let good = [hit.t, hit.normal[0], hit.normal[1], hit.normal[2]];
            assert_eq!(f32s(&bytes), [miss, good, miss, good].concat());
        }
    }
}

#[test]
fn a_valid_query_prints_one_summary_line() {
    let mesh = torus(20, 10);
    let model = temp_path("query-summary.rdm");
    write_strips(&mesh, &long_strips(&mesh, 50), 2, &model);
    let rays = sample_rays();
    let ray_path = temp_path("query-summary.rays");
    std::fs::write(&ray_path, encode_rays(&rays)).expect("write rays");
    let output = run_query(&model, &ray_path, &temp_path("query-summary.hits"), false);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(
        lines[0].starts_with("reducem: query: rays=500 invalid=0 hits="),
        "{stderr}"
    );
}

/// `REDUCEM_KERNEL` forces a kernel: each one this CPU runs writes the same bytes and names
/// itself in the summary line; an unknown one is a usage error that traces nothing.
#[test]
fn every_forced_kernel_writes_the_same_hits_and_says_so() {
    let mesh = torus(20, 10);
    let model = temp_path("query-kernels.rdm");
    write_strips(&mesh, &long_strips(&mesh, 50), 2, &model);
    let ray_path = temp_path("query-kernels.rays");
    std::fs::write(&ray_path, encode_rays(&sample_rays())).expect("write rays");
    let query = |kernel: &str, out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_reducem"))
            .env("REDUCEM_KERNEL", kernel)
            .args(["query".as_ref(), model.as_os_str(), "--rays".as_ref()])
            .args([ray_path.as_os_str(), "-o".as_ref(), out.as_os_str()])
            .output()
            .expect("run reducem")
    };
    let mut outputs = Vec::new();
    for kernel in Kernel::supported() {
        let out = temp_path(&format!("query-kernels-{kernel}.hits"));
        let output = query(kernel.name(), &out);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{stderr}");
        assert!(
            stderr.trim_end().ends_with(&format!(" kernel={kernel}")),
            "{stderr}"
        );
        outputs.push(std::fs::read(&out).expect("hits"));
    }
    assert!(outputs.windows(2).all(|pair| pair[0] == pair[1]));
    let out = temp_path("query-kernels-unknown.hits");
    let output = query("avx9", &out);
    assert_eq!(output.status.code(), Some(64));
    assert!(String::from_utf8_lossy(&output.stderr).contains("REDUCEM_KERNEL=avx9"));
    assert!(!out.exists());
}

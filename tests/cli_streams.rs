//! `reducem` inputs and outputs that are not regular files: `-` for standard input and output,
//! pipes through `sh -c`, FIFOs and `/dev/null`, each giving the very bytes of the file-to-file
//! run; a ray stream that is not a whole number of records is refused naming its byte count.

mod common;

use std::io::{Read, Write};
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use common::{temp_path, torus, SplitMix64};
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::trace::ray_file::encode_rays;
use reducem::trace::Ray;

const REDUCEM: &str = env!("CARGO_BIN_EXE_reducem");

fn reducem(args: &[&str]) -> Output {
    Command::new(REDUCEM)
        .args(args)
        .output()
        .expect("run reducem")
}

/// Runs `script` in `sh` with `$REDUCEM` set.
fn shell(script: &str) -> Output {
    Command::new("sh")
        .args(["-c", script])
        .env("REDUCEM", REDUCEM)
        .output()
        .expect("run sh")
}

fn succeeded(output: Output) -> Output {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    output
}

fn model(name: &str) -> PathBuf {
    let path = temp_path(name);
    convert_mesh(&torus(24, 12), &BuildParams::default(), &path).expect("convert");
    path
}

/// A FIFO at a fresh path.
fn fifo(name: &str) -> PathBuf {
    let path = temp_path(name);
    let _ = std::fs::remove_file(&path);
    let made = Command::new("mkfifo")
        .arg(&path)
        .status()
        .expect("run mkfifo");
    assert!(made.success());
    path
}

/// Rays from one camera position (traced in their own order, more than one streamed batch) and
/// rays from scattered origins (reordered for tracing, answers put back in input order).
fn ray_sets() -> [(&'static str, Vec<u8>); 2] {
    let mut rng = SplitMix64::new(7);
    let mut unit = move || rng.range(-1.0, 1.0);
    let camera: Vec<Ray> = (0..270_000)
        .map(|_| Ray {
            origin: [0.0, -8.0, 4.0],
            direction: [0.4 * unit(), 8.0, -4.0 + unit()],
            tmin: 0.0,
            tmax: f32::INFINITY,
        })
        .collect();
    let scattered: Vec<Ray> = (0..70_000)
        .map(|_| {
            let origin = [3.0 * unit(), 3.0 * unit(), 3.0 * unit()];
            Ray {
                origin,
                direction: origin.map(|x| -x + 0.2 * unit()),
                tmin: 0.0,
                tmax: 2.5,
            }
        })
        .collect();
    [
        ("camera", encode_rays(&camera)),
        ("scattered", encode_rays(&scattered)),
    ]
}

/// `reducem query` answers from files, the reference every stream must match.
fn query_file(model: &Path, rays: &Path, name: &str, flags: &[&str]) -> Vec<u8> {
    let output = temp_path(name);
    let (model, rays) = (model.to_str().unwrap(), rays.to_str().unwrap());
    let args = [
        "query",
        model,
        "--rays",
        rays,
        "-o",
        output.to_str().unwrap(),
    ];
    succeeded(reducem(&[&args[..], flags].concat()));
    std::fs::read(&output).unwrap()
}

#[test]
fn query_reads_rays_from_pipes_and_writes_answers_to_pipes_byte_for_byte() {
    let model = model("streams-query.rdm");
    for (name, bytes) in ray_sets() {
        let rays = temp_path(&format!("streams-{name}.rays"));
        std::fs::write(&rays, &bytes).unwrap();
        for flags in [&[][..], &["--occluded"], &["--format", "full"]] {
            let expected = query_file(&model, &rays, &format!("streams-{name}.hits"), flags);
            let records = expected.chunks(expected.len() / (bytes.len() / 32));
            let hits = records.filter(|record| match record.len() {
                1 => record[0] == 1,
                _ => record[..4] != f32::INFINITY.to_le_bytes(),
            });
            assert!(
                hits.count() > 1000,
                "{name} {flags:?}: too few hits to compare"
            );
            let flags = flags.join(" ");
            let (model, rays) = (model.display(), rays.display());
            let piped = succeeded(shell(&format!(
                "cat '{rays}' | \"$REDUCEM\" query '{model}' --rays - -o - {flags} | cat"
            )));
            assert!(piped.stdout == expected, "{name} {flags}: - to -");
            let dev_stdin = succeeded(shell(&format!(
                "cat '{rays}' | \"$REDUCEM\" query '{model}' --rays /dev/stdin -o /dev/stdout \
                 {flags} | cat"
            )));
            assert!(dev_stdin.stdout == expected, "{name} {flags}: /dev/std*");
            let summary = String::from_utf8_lossy(&piped.stderr);
            let count = bytes.len() / 32;
            assert!(summary.contains(&format!("rays={count} ")), "{summary}");
        }
    }
}

#[test]
fn query_reads_and_writes_fifos_and_writes_to_dev_null() {
    let model = model("streams-fifo.rdm");
    let [(_, bytes), _] = ray_sets();
    let rays = temp_path("streams-fifo-reference.rays");
    std::fs::write(&rays, &bytes).unwrap();
    let expected = query_file(&model, &rays, "streams-fifo-reference.hits", &[]);

    let (ray_fifo, hit_fifo) = (fifo("streams-rays.fifo"), fifo("streams-hits.fifo"));
    let writer = {
        let (path, bytes) = (ray_fifo.clone(), bytes.clone());
        std::thread::spawn(move || std::fs::write(path, bytes).expect("write the ray FIFO"))
    };
    let reader = {
        let path = hit_fifo.clone();
        std::thread::spawn(move || std::fs::read(path).expect("read the hit FIFO"))
    };
    let model_arg = model.to_str().unwrap();
    let args = [
        "query",
        model_arg,
        "--rays",
        ray_fifo.to_str().unwrap(),
        "-o",
    ];
    succeeded(reducem(
        &[&args[..], &[hit_fifo.to_str().unwrap()]].concat(),
    ));
    writer.join().unwrap();
    assert!(reader.join().unwrap() == expected);
    for fifo in [&ray_fifo, &hit_fifo] {
        assert!(
            std::fs::metadata(fifo).unwrap().file_type().is_fifo(),
            "{fifo:?} replaced"
        );
    }

    let rays_arg = rays.to_str().unwrap();
    succeeded(reducem(&[
        "query",
        model_arg,
        "--rays",
        rays_arg,
        "-o",
        "/dev/null",
    ]));
    let null = std::fs::metadata("/dev/null").unwrap();
    assert!(null.file_type().is_char_device() && null.len() == 0);
}

#[test]
fn a_ray_stream_that_is_not_whole_records_is_refused_naming_its_byte_count() {
    let model = model("streams-truncated.rdm");
    let model_arg = model.to_str().unwrap();
    let mut child = Command::new(REDUCEM)
        .args(["query", model_arg, "--rays", "-", "-o", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run reducem");
    let mut stdin = child.stdin.take().unwrap();
    // Two writes: the stream's length is known only at its end.
    stdin.write_all(&[0; 40]).unwrap();
    stdin.write_all(&[0; 3]).unwrap();
    drop(stdin);
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(65), "{stderr}");
    assert!(
        stderr.contains(
            "standard input: 43 bytes is not a multiple of 32 (8 little-endian f32 per ray): \
             ray 1 at byte 32 is incomplete"
        ),
        "{stderr}"
    );
    assert!(output.stdout.is_empty());

    let fifo = fifo("streams-truncated.fifo");
    let writer = {
        let path = fifo.clone();
        std::thread::spawn(move || std::fs::write(path, [0; 33]).expect("write the FIFO"))
    };
    let hits = temp_path("streams-truncated.hits");
    let fifo_arg = fifo.to_str().unwrap();
    let result = reducem(&[
        "query",
        model_arg,
        "--rays",
        fifo_arg,
        "-o",
        hits.to_str().unwrap(),
    ]);
    writer.join().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(65), "{stderr}");
    assert!(
        stderr.contains(&format!("{fifo_arg}: 33 bytes is not a multiple of 32")),
        "{stderr}"
    );
    assert!(!hits.exists());
}

#[test]
fn decode_writes_to_standard_output_and_dev_null() {
    let model = model("streams-decode.rdm");
    let ply = temp_path("streams-decode.ply");
    let model_arg = model.to_str().unwrap();
    succeeded(reducem(&["decode", model_arg, "-o", ply.to_str().unwrap()]));
    let expected = std::fs::read(&ply).unwrap();
    let piped = succeeded(shell(&format!(
        "\"$REDUCEM\" decode '{model_arg}' -o - | cat"
    )));
    assert!(piped.stdout == expected);
    let output = succeeded(reducem(&["decode", model_arg, "-o", "/dev/null"]));
    assert!(output.stdout.is_empty());
}

#[test]
fn render_writes_images_to_standard_output_fifos_and_dev_null() {
    let model = model("streams-render.rdm");
    let scene = temp_path("streams-render.toml");
    std::fs::write(
        &scene,
        "[image]\nwidth = 40\nheight = 24\n[camera]\nauto = true\n\
         [ambient_occlusion]\nsamples = 4\n",
    )
    .unwrap();
    let (model_arg, scene_arg) = (model.to_str().unwrap(), scene.to_str().unwrap());
    let render = |output: &str| {
        reducem(&[
            "render", model_arg, "--scene", scene_arg, "-o", output, "--json",
        ])
    };
    let png = temp_path("streams-render.png");
    let report = succeeded(render(png.to_str().unwrap())).stdout;
    assert!(report.starts_with(b"{"), "the report on standard output");
    let expected_png = std::fs::read(&png).unwrap();

    let piped = succeeded(shell(&format!(
        "\"$REDUCEM\" render '{model_arg}' --scene '{scene_arg}' -o - --json | cat"
    )));
    assert!(piped.stdout == expected_png);
    assert!(
        piped.stderr.starts_with(b"{"),
        "the report on standard error"
    );

    let pfm = temp_path("streams-render.pfm");
    succeeded(render(pfm.to_str().unwrap()));
    let expected_pfm = std::fs::read(&pfm).unwrap();
    let fifo = fifo("streams-render.pfm");
    let reader = {
        let path = fifo.clone();
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            std::fs::File::open(path)
                .unwrap()
                .read_to_end(&mut bytes)
                .unwrap();
            bytes
        })
    };
    succeeded(render(fifo.to_str().unwrap()));
    assert!(reader.join().unwrap() == expected_pfm);
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());

    succeeded(render("/dev/null"));
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
}

#[test]
fn render_reads_its_scene_from_standard_input() {
    let model = model("streams-scene.rdm");
    let scene = temp_path("streams-scene.toml");
    std::fs::write(
        &scene,
        "[image]\nwidth = 24\nheight = 16\n[camera]\nauto = true\n",
    )
    .unwrap();
    let (png, piped_png) = (
        temp_path("streams-scene.png"),
        temp_path("streams-scene-piped.png"),
    );
    let model_arg = model.to_str().unwrap();
    let args = [
        "render",
        model_arg,
        "--scene",
        scene.to_str().unwrap(),
        "-o",
    ];
    succeeded(reducem(&[&args[..], &[png.to_str().unwrap()]].concat()));
    succeeded(shell(&format!(
        "cat '{}' | \"$REDUCEM\" render '{model_arg}' --scene - -o '{}'",
        scene.display(),
        piped_png.display()
    )));
    assert!(std::fs::read(&png).unwrap() == std::fs::read(&piped_png).unwrap());

    let invalid = shell(&format!(
        "echo 'fov = 3' | \"$REDUCEM\" render '{model_arg}' --scene - -o '{}'",
        piped_png.display()
    ));
    let stderr = String::from_utf8_lossy(&invalid.stderr);
    assert_eq!(invalid.status.code(), Some(78), "{stderr}");
    assert!(
        stderr.contains("standard input: ") && stderr.contains("unknown field `fov`"),
        "{stderr}"
    );
}

#[test]
fn a_model_from_a_stream_is_refused_as_a_usage_error_not_read_as_empty() {
    let model = model("streams-model.rdm");
    for (script, name) in [
        ("cat '{}' | \"$REDUCEM\" inspect -", "-"),
        (
            "cat '{}' | \"$REDUCEM\" decode /dev/stdin -o /dev/null",
            "/dev/stdin",
        ),
    ] {
        let result = shell(&script.replace("{}", model.to_str().unwrap()));
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(64), "{stderr}");
        assert!(
            stderr.contains(&format!(
                "{name}: a ReduceM file is mapped, so it must be a regular file, not standard \
                 input, a pipe or a device"
            )),
            "{stderr}"
        );
    }
}

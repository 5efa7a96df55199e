//! The `reducem` command-line contract: `inspect --json` keys and consistency (the precision
//! keys included), `decode` output for lossless and grid files, outputs that would overwrite an
//! input or cannot be written refused before any work, exit codes and `--help`.

mod common;

use std::process::Command;

use common::{canonical_sorted, expected_triangles, quantized_input, temp_path, torus};
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::geometry::distance;
use reducem::input::read_mesh;

fn reducem(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(args)
        .output()
        .expect("run reducem")
}

#[test]
fn inspect_json_has_the_contract_keys_and_adds_up() {
    let mesh = torus(40, 20);
    let path = temp_path("cli-inspect.rdm");
    convert_mesh(&mesh, &BuildParams::default(), &path).expect("convert");
    let output = reducem(&["inspect", path.to_str().unwrap(), "--json", "--verify"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    for key in [
        "triangles",
        "dropped_triangles",
        "strips",
        "input_vertices",
        "stored_vertices",
        "file_bytes",
        "bytes_per_triangle",
        "bytes_by_section",
        "hierarchy_overhead_pct",
        "avg_strip_length",
        "max_strip_length",
    ] {
        assert!(stats.get(key).is_some(), "missing key {key}");
    }
    assert_eq!(stats["triangles"], 1600);
    assert_eq!(stats["input_vertices"], 800);
    let file_bytes = std::fs::metadata(&path).unwrap().len();
    assert_eq!(stats["file_bytes"], file_bytes);
    let section_sum: u64 = stats["bytes_by_section"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(section_sum, file_bytes);
    assert!(stats["max_strip_length"].as_u64().unwrap() <= 60);
    let leaf = BuildParams::default().leaf_windows as u64;
    assert_eq!(stats["leaf_windows"], leaf);
    assert_eq!(stats["leaf_triangles"], leaf, "the former name stays");
}

#[test]
fn decode_writes_the_input_triangles_as_ply() {
    let mesh = torus(30, 12);
    let path = temp_path("cli-decode.rdm");
    let ply = temp_path("cli-decode.ply");
    convert_mesh(&mesh, &BuildParams::default(), &path).expect("convert");
    let output = reducem(&[
        "decode",
        path.to_str().unwrap(),
        "-o",
        ply.to_str().unwrap(),
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let decoded = read_mesh(&ply).expect("decoded PLY reads back");
    let decoded_triangles = decoded.triangles.iter().map(|t| decoded.triangle_points(t));
    assert_eq!(
        canonical_sorted(decoded_triangles),
        expected_triangles(&mesh)
    );
}

#[test]
fn a_corrupt_file_is_an_error_naming_it() {
    let path = temp_path("cli-corrupt.rdm");
    std::fs::write(&path, b"not a reducem file").unwrap();
    let output = reducem(&["inspect", path.to_str().unwrap()]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("cli-corrupt.rdm") && stderr.contains("header"),
        "{stderr}"
    );
}

#[test]
fn inspect_json_reports_the_grid_and_the_position_error() {
    let mesh = torus(40, 20);
    let path = temp_path("cli-inspect-grid.rdm");
    let params = BuildParams {
        grid_bits: Some(16),
        ..BuildParams::default()
    };
    convert_mesh(&mesh, &params, &path).expect("convert");
    let output = reducem(&["inspect", path.to_str().unwrap(), "--json", "--verify"]);
    assert!(output.status.success());
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    let (quantized, grid) = quantized_input(&mesh, 16);
    let largest = mesh
        .positions
        .iter()
        .zip(&quantized.positions)
        .map(|(p, q)| distance(p, q))
        .fold(0.0, f64::max);
    assert_eq!(stats["format_version"], "4.0");
    assert_eq!(stats["vertex_encoding"], "grid");
    assert_eq!(stats["top_node_bytes"], 96);
    assert_eq!(stats["top_node_width"], 8);
    assert_eq!(stats["grid_bits"], 16);
    assert_eq!(
        stats["grid_cell"].as_f64().map(|c| c as f32),
        Some(grid.cell)
    );
    assert_eq!(stats["position_error_max"].as_f64(), Some(largest));
    let diagonal = stats["bounds_diagonal"].as_f64().unwrap();
    assert_eq!(
        stats["position_error_max_relative"].as_f64(),
        Some(largest / diagonal)
    );
    assert!(stats["position_error_rms"].as_f64().unwrap() <= largest);
    assert_eq!(stats["weld_tolerance"], 0.0);
    assert_eq!(stats["welded_vertices"], 0);

    let lossless = temp_path("cli-inspect-f32.rdm");
    convert_mesh(&mesh, &BuildParams::default(), &lossless).expect("convert");
    let output = reducem(&["inspect", lossless.to_str().unwrap(), "--json"]);
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    assert_eq!(stats["vertex_encoding"], "f32");
    assert_eq!(stats["format_version"], "4.0");
    assert_eq!(stats["top_node_bytes"], 96);
    assert_eq!(stats["grid_bits"], 0);
    assert_eq!(stats["position_error_max"], 0.0);

    // Lossless grid nodes are no longer written: a 3.1 file of them.
    let grid_nodes = common::fixture_path("tests/fixtures", "torus-grid-nodes-format-3.1.rdm");
    let output = reducem(&["inspect", grid_nodes.to_str().unwrap(), "--json"]);
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    assert_eq!(stats["vertex_encoding"], "f32");
    assert_eq!(stats["format_version"], "3.1");
    assert_eq!(stats["top_node_bytes"], 64);

    let grid_nodes = temp_path("cli-inspect-f32-grid-nodes.rdm");
    let params = BuildParams {
        grid_nodes: true,
        ..BuildParams::default()
    };
    convert_mesh(&mesh, &params, &grid_nodes).expect("convert");
    // Format 4 has one node record for every encoding: the option is accepted and changes
    // nothing.
    let read = |path: &std::path::Path| std::fs::read(path).expect("read");
    assert!(read(&grid_nodes) == read(&lossless));
}

#[test]
fn decode_writes_the_quantized_triangles_of_a_grid_file() {
    let mesh = torus(30, 12);
    let path = temp_path("cli-decode-grid.rdm");
    let ply = temp_path("cli-decode-grid.ply");
    let params = BuildParams {
        grid_bits: Some(12),
        ..BuildParams::default()
    };
    convert_mesh(&mesh, &params, &path).expect("convert");
    let output = reducem(&[
        "decode",
        path.to_str().unwrap(),
        "-o",
        ply.to_str().unwrap(),
    ]);
    assert!(output.status.success());
    let decoded = read_mesh(&ply).expect("decoded PLY reads back");
    let decoded_triangles = decoded.triangles.iter().map(|t| decoded.triangle_points(t));
    let (quantized, _) = quantized_input(&mesh, 12);
    assert_eq!(
        canonical_sorted(decoded_triangles),
        expected_triangles(&quantized)
    );
}

/// A small converted model at `temp_path(name)`.
fn small_model(name: &str) -> std::path::PathBuf {
    let path = temp_path(name);
    convert_mesh(&torus(12, 6), &BuildParams::default(), &path).expect("convert");
    path
}

/// A scene that renders the model in a few pixels.
fn small_scene(name: &str) -> std::path::PathBuf {
    let path = temp_path(name);
    std::fs::write(
        &path,
        "[image]\nwidth = 8\nheight = 8\n[camera]\nauto = true\n",
    )
    .unwrap();
    path
}

/// Runs `args`, expects `code` and a message naming `output` and `input`, and checks `input`
/// still holds `before`.
fn assert_refused(args: &[&str], output: &std::path::Path, input: &std::path::Path, before: &[u8]) {
    let result = reducem(args);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(64), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "output {} is the input {}",
            output.display(),
            input.display()
        )),
        "{stderr}"
    );
    assert!(std::fs::read(input).unwrap() == before, "the input changed");
    assert!(result.stdout.is_empty(), "work was done: {result:?}");
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_kept() {
    let model = small_model("cli-same.rdm");
    let before = std::fs::read(&model).unwrap();
    let model_arg = model.to_str().unwrap();
    assert_refused(
        &["decode", model_arg, "-o", model_arg],
        &model,
        &model,
        &before,
    );

    let scene = small_scene("cli-same-scene.toml");
    let scene_text = std::fs::read(&scene).unwrap();
    let scene_arg = scene.to_str().unwrap();
    let render = ["render", model_arg, "--scene", scene_arg, "-o"];
    assert_refused(
        &[&render[..], &[model_arg]].concat(),
        &model,
        &model,
        &before,
    );
    assert_refused(
        &[&render[..], &[scene_arg]].concat(),
        &scene,
        &scene,
        &scene_text,
    );

    let symlink = temp_path("cli-same-symlink.rdm");
    let _ = std::fs::remove_file(&symlink);
    std::os::unix::fs::symlink(&model, &symlink).unwrap();
    let symlink_arg = symlink.to_str().unwrap();
    assert_refused(
        &[&render[..], &[symlink_arg]].concat(),
        &symlink,
        &model,
        &before,
    );

    let rays = temp_path("cli-same.rays");
    let ray = reducem::trace::Ray {
        origin: [0.0, 0.0, 5.0],
        direction: [0.0, 0.0, -1.0],
        tmin: 0.0,
        tmax: f32::INFINITY,
    };
    let ray_bytes = reducem::trace::ray_file::encode_rays(&[ray]);
    std::fs::write(&rays, &ray_bytes).unwrap();
    let hard_link = temp_path("cli-same-hard-link.rays");
    let _ = std::fs::remove_file(&hard_link);
    std::fs::hard_link(&rays, &hard_link).unwrap();
    let (rays_arg, link_arg) = (rays.to_str().unwrap(), hard_link.to_str().unwrap());
    let query = ["query", model_arg, "--rays", rays_arg, "-o", link_arg];
    assert_refused(&query, &hard_link, &rays, &ray_bytes);
}

#[test]
fn an_output_that_cannot_be_written_fails_before_the_work_with_74() {
    let model = small_model("cli-unwritable.rdm");
    let scene = small_scene("cli-unwritable-scene.toml");
    let directory = temp_path("cli-unwritable-dir");
    std::fs::create_dir_all(&directory).unwrap();
    let missing = temp_path("cli-missing-dir/image.png");
    // sysfs refuses new files even to root: a read-only directory wherever the tests run.
    let read_only = std::path::PathBuf::from("/sys/reducem-cli-test.png");
    for output in [&directory, &missing, &read_only] {
        let result = reducem(&[
            "render",
            model.to_str().unwrap(),
            "--scene",
            scene.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(74), "{stderr}");
        assert!(
            stderr.contains(&format!("output {}", output.display())),
            "{stderr}"
        );
        assert!(
            result.stdout.is_empty(),
            "rendered before failing: {result:?}"
        );
    }
    let stderr = String::from_utf8_lossy(
        &reducem(&[
            "decode",
            model.to_str().unwrap(),
            "-o",
            directory.to_str().unwrap(),
        ])
        .stderr,
    )
    .to_string();
    assert!(stderr.contains("is a directory"), "{stderr}");
    assert!(!missing.parent().unwrap().exists());
}

#[test]
fn exit_codes_follow_the_one_table() {
    assert_eq!(reducem(&[]).status.code(), Some(64));
    assert_eq!(reducem(&["inspect"]).status.code(), Some(64));
    assert_eq!(reducem(&["render", "--bogus"]).status.code(), Some(64));
    assert_eq!(reducem(&["--version"]).status.code(), Some(0));
    let corrupt = temp_path("cli-exit-corrupt.rdm");
    std::fs::write(&corrupt, b"not a reducem file").unwrap();
    assert_eq!(
        reducem(&["inspect", corrupt.to_str().unwrap()])
            .status
            .code(),
        Some(65)
    );
    let missing = temp_path("cli-exit-missing.rdm");
    let result = reducem(&["inspect", missing.to_str().unwrap()]);
    assert_eq!(result.status.code(), Some(74));
    assert!(String::from_utf8_lossy(&result.stderr).contains("cli-exit-missing.rdm"));

    let model = small_model("cli-exit-scene.rdm");
    let scene = temp_path("cli-exit-bad-scene.toml");
    std::fs::write(
        &scene,
        "[image]\nwidth = 0\nheight = 8\n[camera]\nauto = true\n",
    )
    .unwrap();
    let image = temp_path("cli-exit-scene.png");
    let result = reducem(&[
        "render",
        model.to_str().unwrap(),
        "--scene",
        scene.to_str().unwrap(),
        "-o",
        image.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(78), "{stderr}");
    assert!(
        stderr.contains("cli-exit-bad-scene.toml") && stderr.contains("image"),
        "{stderr}"
    );
}

#[test]
fn help_shows_the_exit_codes_and_render_help_the_scene_documentation() {
    let help = String::from_utf8_lossy(&reducem(&["--help"]).stdout).to_string();
    for line in [
        "Exit codes",
        "64  usage",
        "65  bad input",
        "74  I/O",
        "78  configuration",
    ] {
        assert!(help.contains(line), "{line} missing in {help}");
    }
    let render = String::from_utf8_lossy(&reducem(&["render", "--help"]).stdout).to_string();
    assert!(render.contains("docs/SCENES.md"), "{render}");
    assert!(
        render.contains("Exit codes") && render.contains("78  configuration"),
        "{render}"
    );
    assert!(std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("docs/SCENES.md")
        .is_file());
}

/// The width, height and linear pixels of a PFM file, rows from the bottom.
fn read_pfm(path: &std::path::Path) -> (u32, u32, Vec<[f32; 3]>) {
    let bytes = std::fs::read(path).expect("image");
    let text_end = bytes
        .iter()
        .enumerate()
        .filter(|(_, b)| **b == b'\n')
        .nth(2)
        .expect("three header lines")
        .0;
    let header = String::from_utf8_lossy(&bytes[..text_end]).to_string();
    let mut lines = header.lines();
    assert_eq!(lines.next(), Some("PF"));
    let size: Vec<u32> = lines
        .next()
        .unwrap()
        .split(' ')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(lines.next(), Some("-1.0"));
    let pixels = bytes[text_end + 1..]
        .chunks_exact(12)
        .map(|p| {
            std::array::from_fn(|c| f32::from_le_bytes(p[4 * c..4 * c + 4].try_into().unwrap()))
        })
        .collect();
    (size[0], size[1], pixels)
}

/// Renders `model` with `scene_text` and the extra arguments into a PFM; the output of the run.
fn render_pfm(
    model: &std::path::Path,
    name: &str,
    scene_text: &str,
    extra: &[&str],
) -> std::process::Output {
    let scene = temp_path(&format!("{name}.toml"));
    std::fs::write(&scene, scene_text).unwrap();
    let image = temp_path(&format!("{name}.pfm"));
    let args = [
        "render",
        model.to_str().unwrap(),
        "--scene",
        scene.to_str().unwrap(),
        "-o",
        image.to_str().unwrap(),
    ];
    reducem(&[&args[..], extra].concat())
}

#[test]
fn render_overrides_set_the_size_and_ao_and_shadows_only_darken() {
    let model = temp_path("cli-scene.rdm");
    convert_mesh(&torus(48, 24), &BuildParams::default(), &model).expect("convert");
    // The light comes low from +x: the ring's +x half shadows the inner wall of its -x half,
    // which the camera sees over the +x half.
    let base = "[camera]\ndirection = [1.0, 0.0, 0.9]\n[shading]\nambient = 0.5\n\
                [[directional_light]]\ndirection = [-1.0, 0.0, -0.1]\nintensity = 0.5\n";
    let size = ["--width", "40", "--height", "30", "--fov", "50"];
    let primary = render_pfm(&model, "cli-scene-primary", base, &size);
    assert!(
        primary.status.success(),
        "{}",
        String::from_utf8_lossy(&primary.stderr)
    );
    let shadows = format!("{base}cast_shadows = true\n");
    let shadowed = render_pfm(&model, "cli-scene-shadows", &shadows, &size);
    assert!(shadowed.status.success());
    let occluded = render_pfm(
        &model,
        "cli-scene-ao",
        base,
        &[&size[..], &["--ao-samples", "16", "--ao-distance", "6"]].concat(),
    );
    assert!(occluded.status.success());

    let (width, height, primary) = read_pfm(&temp_path("cli-scene-primary.pfm"));
    assert_eq!((width, height), (40, 30));
    assert_eq!(primary.len(), 40 * 30);
    for name in ["cli-scene-shadows.pfm", "cli-scene-ao.pfm"] {
        let (_, _, image) = read_pfm(&temp_path(name));
        assert_eq!(image.len(), primary.len());
        let darker = image
            .iter()
            .zip(&primary)
            .filter(|(a, b)| a.iter().zip(b.iter()).all(|(x, y)| x < y))
            .count();
        let brighter = image
            .iter()
            .zip(&primary)
            .any(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x > &(y + 1e-6)));
        assert!(
            !brighter,
            "{name} is brighter than the primary image somewhere"
        );
        assert!(
            darker > 20,
            "{name}: only {darker} pixels darker than the primary image"
        );
    }
}

#[test]
fn antialiasing_traces_n_by_n_samples_per_pixel_and_keeps_the_size() {
    let model = small_model("cli-scene-aa.rdm");
    let scene = "[camera]\ndirection = [1.0, 0.0, 0.9]\n";
    let args = [
        "--width",
        "40",
        "--height",
        "30",
        "--antialiasing",
        "3",
        "--json",
    ];
    let output = render_pfm(&model, "cli-scene-aa", scene, &args);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).expect("JSON report");
    assert_eq!(
        (report["width"].as_u64(), report["height"].as_u64()),
        (Some(40), Some(30))
    );
    assert_eq!(report["effects"][0]["effect"], "primary");
    assert_eq!(report["effects"][0]["rays"], 40 * 30 * 9);
    let (width, height, pixels) = read_pfm(&temp_path("cli-scene-aa.pfm"));
    assert_eq!((width, height, pixels.len()), (40, 30, 1200));
    let single = render_pfm(&model, "cli-scene-aa1", scene, &args[..4]);
    assert!(single.status.success());
    let (_, _, single) = read_pfm(&temp_path("cli-scene-aa1.pfm"));
    assert_ne!(
        pixels, single,
        "antialiasing changed nothing at the silhouette"
    );
}

#[test]
fn render_refuses_an_unknown_image_format_and_invalid_overrides_with_64() {
    let model = small_model("cli-scene-refused.rdm");
    let scene = small_scene("cli-scene-refused.toml");
    let jpg = temp_path("cli-scene-refused.jpg");
    let args = [
        "render",
        model.to_str().unwrap(),
        "--scene",
        scene.to_str().unwrap(),
        "-o",
    ];
    let result = reducem(&[&args[..], &[jpg.to_str().unwrap()]].concat());
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(64), "{stderr}");
    assert!(
        stderr.contains("unknown image format (the extension must be .png or .pfm)"),
        "{stderr}"
    );
    assert!(!jpg.exists() && result.stdout.is_empty());

    let png = temp_path("cli-scene-refused.png");
    let result = reducem(&[&args[..], &[png.to_str().unwrap(), "--width", "0"]].concat());
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(64), "{stderr}");
    assert!(
        stderr.contains("the command line makes image invalid: 0x8"),
        "{stderr}"
    );
    assert!(!png.exists());
}

//! `reducem render` arguments: negative numbers in vector options, and degenerate cameras
//! refused before anything is traced or written.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{temp_path, torus};
use reducem::conversion::{convert_mesh, BuildParams};

fn reducem(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(args)
        .output()
        .expect("run reducem")
}

fn model(name: &str) -> PathBuf {
    let path = temp_path(name);
    convert_mesh(&torus(12, 6), &BuildParams::default(), &path).expect("convert");
    path
}

fn scene(name: &str, camera: &str) -> PathBuf {
    let path = temp_path(name);
    let text = format!("[image]\nwidth = 8\nheight = 8\n[camera]\n{camera}");
    std::fs::write(&path, text).unwrap();
    path
}

/// Renders `model` with the automatic scene and `camera` arguments to `output`.
fn render(model: &Path, output: &Path, camera: &[&str]) -> Output {
    // A scene per output: tests run in parallel, and one rewriting a shared scene file while
    // another's render reads it made the reader fail now and then.
    let name = output.file_name().unwrap().to_str().unwrap();
    let scene = scene(&format!("{name}.toml"), "auto = true\n");
    let base = [
        "render",
        model.to_str().unwrap(),
        "--scene",
        scene.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
    ];
    reducem(&[&base[..], camera].concat())
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn vector_options_take_negative_numbers_as_separate_values() {
    let model = model("cli-arguments-negative.rdm");
    let separate = temp_path("cli-arguments-separate.pfm");
    let joined = temp_path("cli-arguments-joined.pfm");
    let result = render(
        &model,
        &separate,
        &[
            "--camera-position",
            "-2,-3,1.5",
            "--look-at",
            "-0.02,0.1,0",
            "--camera-up",
            "-0,0,1",
        ],
    );
    assert_eq!(result.status.code(), Some(0), "{}", stderr(&result));
    let result = render(
        &model,
        &joined,
        &[
            "--camera-position=-2,-3,1.5",
            "--look-at=-0.02,0.1,0",
            "--camera-up=-0,0,1",
        ],
    );
    assert_eq!(result.status.code(), Some(0), "{}", stderr(&result));
    assert_eq!(
        std::fs::read(&separate).unwrap(),
        std::fs::read(&joined).unwrap()
    );
    let negative_exposure = render(&model, &joined, &["--exposure", "-1"]);
    assert_eq!(negative_exposure.status.code(), Some(64));
    assert!(
        stderr(&negative_exposure).contains("shading.exposure invalid: -1 must be positive"),
        "{}",
        stderr(&negative_exposure)
    );
}

#[test]
fn degenerate_cameras_on_the_command_line_are_usage_errors_and_write_nothing() {
    let model = model("cli-arguments-degenerate.rdm");
    let output = temp_path("cli-arguments-degenerate.png");
    let cases: [(&[&str], &str); 4] = [
        (
            &["--camera-position", "1,2,3", "--look-at", "1,2,3"],
            "camera.look_at invalid: [1.0, 2.0, 3.0] is the camera position [1.0, 2.0, 3.0]",
        ),
        (&["--camera-up", "0,0,0"], "camera.up invalid: [0.0, 0.0, 0.0] must be finite and non-zero"),
        (
            &["--camera-position", "0,0,5", "--look-at", "0,0,-1"],
            "camera.up invalid: [0.0, 0.0, 1.0] is parallel to the view direction [0.0, 0.0, -6.0]",
        ),
        (
            &["--camera-position", "3,0,0", "--look-at", "0,0,0", "--camera-up", "-2,0,0"],
            "camera.up invalid: [-2.0, 0.0, 0.0] is parallel to the view direction [-3.0, 0.0, 0.0]",
        ),
    ];
    for (camera, message) in cases {
        let result = render(&model, &output, camera);
        assert_eq!(
            result.status.code(),
            Some(64),
            "{camera:?}: {}",
            stderr(&result)
        );
        assert!(
            stderr(&result).contains(&format!("the command line makes {message}")),
            "{camera:?}: {}",
            stderr(&result)
        );
        assert!(result.stdout.is_empty(), "rendered: {result:?}");
        assert!(!output.exists(), "{camera:?} wrote {}", output.display());
    }
}

#[test]
fn degenerate_cameras_in_a_scene_file_are_scene_errors_naming_the_file() {
    let model = model("cli-arguments-scene.rdm");
    let output = temp_path("cli-arguments-scene.png");
    let cases = [
        (
            "position = [1.0, 2.0, 3.0]\nlook_at = [1.0, 2.0, 3.0]\n",
            "camera.look_at: [1.0, 2.0, 3.0] is the camera position",
        ),
        (
            "direction = [0.0, 0.0, 2.0]\n",
            "camera.up: [0.0, 0.0, 1.0] is parallel to the view direction [-0.0, -0.0, -2.0]",
        ),
    ];
    for (index, (camera, message)) in cases.into_iter().enumerate() {
        let scene = scene(&format!("cli-arguments-degenerate-{index}.toml"), camera);
        let result = reducem(&[
            "render",
            model.to_str().unwrap(),
            "--scene",
            scene.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
        ]);
        assert_eq!(result.status.code(), Some(78), "{}", stderr(&result));
        assert!(
            stderr(&result).contains(&format!("{}: {message}", scene.display())),
            "{}",
            stderr(&result)
        );
        assert!(!output.exists());
    }
}

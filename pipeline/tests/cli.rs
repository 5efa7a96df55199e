//! The `pipeline` command-line contract: `run` on a generated input, `gen`, config errors with
//! line and column, and the documented exit codes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn pipeline(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(args)
        .output()
        .expect("run pipeline")
}

fn write_config(dir: &Path, body: &str) -> PathBuf {
    let path = dir.join("job.toml");
    std::fs::write(&path, body).expect("write config");
    path
}

#[test]
fn run_converts_a_generated_mesh() {
    let dir = temp_dir("run");
    let config = write_config(
        &dir,
        "[input.generate]\nkind = \"sphere\"\ntriangles = 5000\n\n[output]\npath = \"sphere.rdm\"\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap()]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let file = reducem::format::reader::ReducemFile::open(&dir.join("sphere.rdm")).expect("open");
    assert_eq!(
        file.header().triangle_count,
        5120,
        "20·16² triangles for 5000 requested"
    );
}

#[test]
fn unknown_config_key_names_line_and_column() {
    let dir = temp_dir("unknown-key");
    let config = write_config(
        &dir,
        "[input]\npath = \"x.ply\"\n\n[output]\npath = \"x.rdm\"\n\n[strip]\nmax_lenght = 60\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(78));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("job.toml") && stderr.contains("line 8") && stderr.contains("column 1"),
        "{stderr}"
    );
    assert!(stderr.contains("max_lenght"), "{stderr}");
}

#[test]
fn malformed_input_exits_65_and_names_the_byte() {
    let dir = temp_dir("bad-input");
    let ply = dir.join("bad.ply");
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bytes.extend(v.to_le_bytes());
    }
    bytes.push(3);
    for i in [0i32, 1, 7] {
        bytes.extend(i.to_le_bytes());
    }
    std::fs::write(&ply, bytes).unwrap();
    let config = write_config(
        &dir,
        "[input]\npath = \"bad.ply\"\n\n[output]\npath = \"bad.rdm\"\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(65));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("bad.ply")
            && stderr.contains("'face' #0")
            && stderr.contains("out of range"),
        "{stderr}"
    );
    assert!(!dir.join("bad.rdm").exists());
}

#[test]
fn usage_errors_exit_64() {
    assert_eq!(pipeline(&["run"]).status.code(), Some(64));
    assert_eq!(
        pipeline(&["gen", "teapot", "--triangles", "10", "-o", "x.ply"])
            .status
            .code(),
        Some(64)
    );
}

#[test]
fn gen_writes_the_requested_kind() {
    let dir = temp_dir("gen");
    let out = dir.join("terrain.ply");
    let output = pipeline(&[
        "gen",
        "terrain",
        "--triangles",
        "2000",
        "-o",
        out.to_str().unwrap(),
        "--seed",
        "3",
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mesh = reducem::input::read_mesh(&out).expect("read back");
    assert_eq!(mesh.triangles.len(), 2 * 32 * 32);
}

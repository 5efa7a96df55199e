//! Stage-by-stage runs with the strip stage split over concurrent shard processes (as Slurm
//! array tasks run it) give the same bytes as one whole run; stages refuse to run before their
//! predecessors; shards default from the Slurm environment.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-shard-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn job(dir: &Path, output: &str, work: &str) -> PathBuf {
    let input = dir.join("input.ply");
    if !input.exists() {
        reducem_gen::generate(reducem_gen::Kind::Terrain, 50_000, 3, &input).expect("generate");
    }
    let config = dir.join(format!("{work}.toml"));
    let body = format!(
        "[input]\npath = \"input.ply\"\n[output]\npath = \"{output}\"\n[work]\ndir = \"{work}\"\n[chunk]\nmax_triangles = 6000\n"
    );
    fs::write(&config, body).expect("config");
    config
}

fn pipeline(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_pipeline"));
    command.args(args).args(["--log-format", "plain"]);
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().expect("run pipeline")
}

fn assert_ok(output: &Output) {
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

#[test]
fn sharded_strip_stage_matches_a_whole_run() {
    let dir = temp_dir("match");
    let whole = job(&dir, "whole.rdm", "whole.work");
    assert_ok(&pipeline(&["run", whole.to_str().unwrap()], &[]));

    let sharded = job(&dir, "sharded.rdm", "sharded.work");
    let config = sharded.to_str().unwrap();
    assert_ok(&pipeline(&["run", config, "--stage", "chunk"], &[]));
    let tasks: Vec<_> = (0..3)
        .map(|task| {
            Command::new(env!("CARGO_BIN_EXE_pipeline"))
                .args(["run", config, "--stage", "strip", "--log-format", "plain"])
                .env("SLURM_ARRAY_TASK_ID", task.to_string())
                .env("SLURM_ARRAY_TASK_COUNT", "3")
                .spawn()
                .expect("spawn shard")
        })
        .collect();
    for task in tasks {
        assert!(task.wait_with_output().expect("shard").status.success());
    }
    for stage in ["merge", "hierarchy", "write"] {
        assert_ok(&pipeline(&["run", config, "--stage", stage], &[]));
    }
    assert!(fs::read(dir.join("whole.rdm")).unwrap() == fs::read(dir.join("sharded.rdm")).unwrap());
    let manifest = fs::read_to_string(dir.join("sharded.work/manifest.json")).unwrap();
    assert!(
        manifest.matches("strip/chunk-").count() >= 8,
        "every chunk recorded:\n{manifest}"
    );
}

#[test]
fn a_stage_before_its_predecessors_exits_75() {
    let dir = temp_dir("order");
    let config = job(&dir, "out.rdm", "out.work");
    let output = pipeline(&["run", config.to_str().unwrap(), "--stage", "merge"], &[]);
    assert_eq!(output.status.code(), Some(75));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("stage Chunk is not done yet"), "{stderr}");
}

#[test]
fn a_retried_shard_redoes_nothing() {
    let dir = temp_dir("retry");
    let config = job(&dir, "out.rdm", "out.work");
    let config = config.to_str().unwrap();
    assert_ok(&pipeline(&["run", config, "--stage", "chunk"], &[]));
    assert_ok(&pipeline(
        &["run", config, "--stage", "strip", "--shard", "1/2"],
        &[],
    ));
    let retry = pipeline(&["run", config, "--stage", "strip", "--shard", "1/2"], &[]);
    assert_ok(&retry);
    assert!(String::from_utf8_lossy(&retry.stderr).contains("0 chunks converted"));
    let merge_early = pipeline(&["run", config, "--stage", "merge"], &[]);
    assert_eq!(merge_early.status.code(), Some(75), "shard 0 has not run");
}

#[test]
fn a_bad_shard_is_a_usage_error() {
    let dir = temp_dir("bad");
    let config = job(&dir, "out.rdm", "out.work");
    let output = pipeline(
        &[
            "run",
            config.to_str().unwrap(),
            "--stage",
            "strip",
            "--shard",
            "2/2",
        ],
        &[],
    );
    assert_eq!(output.status.code(), Some(64));
}

//! The `pipeline` command-line contract: `run` on a generated input, `gen`, config errors with
//! line and column, and the documented exit codes.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::pipeline;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-cli-{}-{name}", std::process::id()));
    // Emptied first: an earlier run whose process had the same id may have left files (a work
    // directory, an output) that these tests take as their own doing.
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
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

/// A small mesh at `dir/name`.
fn small_mesh(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    reducem_gen::generate(reducem_gen::Kind::Sphere, 500, 1, &path).expect("generate");
    path
}

/// Runs `args`, expects `code` and every one of `expected` in the message, and checks that the
/// files in `kept` still hold their bytes.
fn assert_refused(args: &[&str], code: i32, expected: &[&str], kept: &[(&Path, &[u8])]) {
    let output = pipeline(args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(code), "{stderr}");
    for text in expected {
        assert!(stderr.contains(text), "{text:?} missing in {stderr}");
    }
    for (path, bytes) in kept {
        assert!(std::fs::read(path).unwrap() == *bytes, "{path:?} changed");
    }
}

#[test]
fn an_output_path_that_is_the_input_is_refused_before_any_stage() {
    let dir = temp_dir("same-file");
    let mesh = small_mesh(&dir, "model.ply");
    let before = std::fs::read(&mesh).unwrap();
    std::os::unix::fs::symlink(&mesh, dir.join("link.ply")).ok();
    std::fs::hard_link(&mesh, dir.join("hard.ply")).ok();
    for output in ["model.ply", "link.ply", "hard.ply", "./model.ply"] {
        let config = write_config(
            &dir,
            &format!("[input]\npath = \"model.ply\"\n[output]\npath = \"{output}\"\n"),
        );
        let config_arg = config.to_str().unwrap();
        let named = format!("[output] path {}", dir.join(output).display());
        let input = format!("is the input {}", mesh.display());
        let expected = ["job.toml", named.as_str(), input.as_str()];
        assert_refused(&["run", config_arg], 78, &expected, &[(&mesh, &before)]);
        assert!(!dir.join("job.work").exists(), "a stage ran");
    }
    let config = write_config(
        &dir,
        "[input]\npath = \"model.ply\"\n[output]\npath = \"job.toml\"\n",
    );
    let config_text = std::fs::read(&config).unwrap();
    let expected = ["is the input", "job.toml (the same file)"];
    let kept: [(&Path, &[u8]); 1] = [(&config, &config_text)];
    assert_refused(&["run", config.to_str().unwrap()], 78, &expected, &kept);
}

#[test]
fn a_work_directory_holding_the_input_or_not_made_by_pipeline_is_refused() {
    let dir = temp_dir("work-holds-input");
    let mesh = small_mesh(&dir, "model.ply");
    let before = std::fs::read(&mesh).unwrap();
    let config = write_config(
        &dir,
        "[input]\npath = \"model.ply\"\n[output]\npath = \"out/model.rdm\"\n[work]\ndir = \".\"\n",
    );
    let config_arg = config.to_str().unwrap();
    let expected = ["[work] dir", "contains", "model.ply"];
    assert_refused(&["run", config_arg], 78, &expected, &[(&mesh, &before)]);
    assert!(!dir.join("out").exists() && !dir.join("manifest.json").exists());
    let expected = ["was not made by pipeline", "not removing it"];
    assert_refused(&["clean", config_arg], 78, &expected, &[(&mesh, &before)]);

    let mine = dir.join("mine");
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "precious").unwrap();
    let config = write_config(
        &dir,
        "[input]\npath = \"model.ply\"\n[output]\npath = \"model.rdm\"\n[work]\ndir = \"mine\"\n",
    );
    let config_arg = config.to_str().unwrap();
    let expected = ["already exists, is not empty and was not made by pipeline"];
    assert_refused(&["run", config_arg], 78, &expected, &[(&mesh, &before)]);
    assert_refused(
        &["clean", config_arg],
        78,
        &["was not made by pipeline"],
        &[],
    );
    assert_eq!(
        std::fs::read_to_string(mine.join("notes.txt")).unwrap(),
        "precious"
    );
}

#[test]
fn clean_removes_the_work_directory_pipeline_made() {
    let dir = temp_dir("clean");
    small_mesh(&dir, "model.ply");
    let config = write_config(
        &dir,
        "[input]\npath = \"model.ply\"\n[output]\npath = \"model.rdm\"\n",
    );
    let config_arg = config.to_str().unwrap();
    assert_eq!(pipeline(&["run", config_arg]).status.code(), Some(0));
    assert!(dir.join("job.work/pipeline-work-dir").is_file());
    assert_eq!(pipeline(&["clean", config_arg]).status.code(), Some(0));
    assert!(!dir.join("job.work").exists() && dir.join("model.rdm").exists());
}

#[test]
fn an_unwritable_output_fails_before_the_first_stage_with_74() {
    let dir = temp_dir("unwritable-output");
    let mesh = small_mesh(&dir, "model.ply");
    let before = std::fs::read(&mesh).unwrap();
    std::fs::create_dir_all(dir.join("taken.rdm")).unwrap();
    std::fs::write(dir.join("file"), "a file, not a directory").unwrap();
    // sysfs refuses new files even to root: a read-only directory wherever the tests run.
    for (output, expected) in [
        ("taken.rdm", "is a directory"),
        ("file/model.rdm", "creating the output directory"),
        ("/sys/model.rdm", "cannot create a file in /sys"),
    ] {
        let config = write_config(
            &dir,
            &format!(
                "[input]\npath = \"model.ply\"\n[output]\npath = \"{output}\"\n\
                 [work]\ndir = \"work\"\n"
            ),
        );
        assert_refused(
            &["run", config.to_str().unwrap()],
            74,
            &[expected],
            &[(&mesh, &before)],
        );
        assert!(!dir.join("work").exists(), "a stage ran for {output}");
    }
}

#[test]
fn help_shows_the_exit_codes() {
    let expected = [
        "Exit codes",
        "64  usage",
        "75  try again later",
        "78  configuration",
        "130  stopped by SIGINT",
    ];
    for command in [&["--help"][..], &["run", "--help"], &["convert", "--help"]] {
        let help = String::from_utf8_lossy(&pipeline(command).stdout).to_string();
        for line in expected {
            assert!(help.contains(line), "{line} missing in {help}");
        }
    }
}

#[test]
fn obj_errors_name_line_and_byte_and_unknown_statements_are_reported_once() {
    let dir = temp_dir("obj");
    std::fs::write(dir.join("bad.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let config = write_config(
        &dir,
        "[input]\npath = \"bad.obj\"\n[output]\npath = \"bad.rdm\"\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(65), "{stderr}");
    assert!(
        stderr.contains("bad.obj: element 'face' #0 at byte 30 (line 4): OBJ: face vertex index 9"),
        "{stderr}"
    );

    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\ncurv 0 1 1 2\nf 1 2 3\nsurf 0 1 0 1 1\ncurv 0 1 2 3\n";
    std::fs::write(dir.join("curves.obj"), text).unwrap();
    let config = write_config(
        &dir,
        "[input]\npath = \"curves.obj\"\n[output]\npath = \"curves.rdm\"\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap(), "--log-format", "plain"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    let reports: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("unknown OBJ"))
        .collect();
    assert_eq!(reports.len(), 1, "{stderr}");
    assert!(
        reports[0].contains(
            "3 unknown OBJ statements ignored (first at line 4, byte 24; 'curv' 2, 'surf' 1)"
        ),
        "{stderr}"
    );
}

/// `pipeline status` of `config`, checked to hold no internal token (hashes, digests).
fn status_in_words(config: &Path) -> String {
    let text = String::from_utf8_lossy(&pipeline(&["status", config.to_str().unwrap()]).stdout)
        .to_string();
    let hex_token = text
        .split(|c: char| !c.is_ascii_alphanumeric())
        .any(|word| word.len() >= 16 && word.chars().all(|c| c.is_ascii_hexdigit()));
    assert!(
        !hex_token && !text.contains("unhashed:") && !text.contains("_stage"),
        "{text}"
    );
    text
}

#[test]
fn status_explains_staleness_in_words() {
    let dir = temp_dir("status-words");
    let mesh = small_mesh(&dir, "model.ply");
    let body = "[input]\npath = \"model.ply\"\n[output]\npath = \"model.rdm\"\n[chunk]\nmax_triangles = 400\n";
    let config = write_config(&dir, body);
    assert_eq!(
        pipeline(&["run", config.to_str().unwrap()]).status.code(),
        Some(0)
    );

    reducem_gen::generate(reducem_gen::Kind::Sphere, 2000, 1, &mesh).expect("generate");
    let bytes = std::fs::metadata(&mesh).unwrap().len();
    let text = status_in_words(&config);
    assert!(
        text.contains(&format!(
            "chunk                stale: input changed: now {bytes} bytes, modified 20"
        )),
        "{text}"
    );
    assert!(
        text.contains("redoes the work only if its content differs"),
        "{text}"
    );

    write_config(&dir, &body.replace("400", "300"));
    let stage = pipeline(&["run", config.to_str().unwrap(), "--stage", "chunk"]);
    assert_eq!(
        stage.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&stage.stderr)
    );
    let text = status_in_words(&config);
    assert!(
        text.contains("strip/chunk-000000   stale: the chunk stage's results changed"),
        "{text}"
    );
}

#[test]
fn convert_writes_the_equivalent_config_and_resumes_like_run() {
    let dir = temp_dir("convert");
    let mesh = small_mesh(&dir, "model.ply");
    let output = dir.join("out/model.rdm");
    let args = [
        "convert",
        mesh.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--max-length",
        "16",
        "--encoding",
        "grid",
        "--grid-bits",
        "16",
        "--log-format",
        "plain",
        "--keep-work",
    ];
    let first = pipeline(&args);
    assert_eq!(
        first.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let file = reducem::format::reader::ReducemFile::open(&output).expect("open");
    assert_eq!(file.precision().grid_bits, 16);
    let config = dir.join("out/model.rdm.work/convert.toml");
    let text = std::fs::read_to_string(&config).expect("the equivalent config");
    assert!(
        text.contains("max_length = 16") && text.contains("encoding = \"grid\""),
        "{text}"
    );

    let again = String::from_utf8_lossy(&pipeline(&args).stderr).to_string();
    assert!(
        again.contains("chunk: fresh") && again.contains("write: fresh"),
        "{again}"
    );
    let run = pipeline(&["run", config.to_str().unwrap(), "--log-format", "plain"]);
    assert!(String::from_utf8_lossy(&run.stderr).contains("write: fresh"));
    let status = String::from_utf8_lossy(&pipeline(&["status", config.to_str().unwrap()]).stdout)
        .to_string();
    assert!(
        status.lines().skip(2).all(|l| l.ends_with("done")),
        "{status}"
    );
}

#[test]
fn convert_refuses_unsafe_paths_and_bad_options_with_64_before_any_work() {
    let dir = temp_dir("convert-refused");
    let mesh = small_mesh(&dir, "model.ply");
    let before = std::fs::read(&mesh).unwrap();
    let mesh_arg = mesh.to_str().unwrap();
    let kept: [(&Path, &[u8]); 1] = [(&mesh, &before)];
    let same = format!("output {mesh_arg} is the input {mesh_arg}");
    assert_refused(&["convert", mesh_arg, "-o", mesh_arg], 64, &[&same], &kept);
    assert!(!dir.join("model.ply.work").exists(), "a stage ran");

    let output = dir.join("model.rdm");
    let output_arg = output.to_str().unwrap();
    let dir_arg = dir.to_str().unwrap();
    let expected = [&format!("work directory {dir_arg} contains {mesh_arg}")[..]];
    assert_refused(
        &["convert", mesh_arg, "-o", output_arg, "--work", dir_arg],
        64,
        &expected,
        &kept,
    );
    let grid_bits = ["convert", mesh_arg, "-o", output_arg, "--grid-bits", "16"];
    assert_refused(&grid_bits, 64, &["--encoding"], &kept);
    let f32_bits = [&grid_bits[..], &["--encoding", "f32"]].concat();
    assert_refused(
        &f32_bits,
        64,
        &["--grid-bits applies to --encoding grid only"],
        &kept,
    );
    let too_many = [
        "convert",
        mesh_arg,
        "-o",
        output_arg,
        "--encoding",
        "grid",
        "--grid-bits",
        "30",
    ];
    assert_refused(&too_many, 64, &["grid_bits 30 is outside 1..=24"], &kept);
    assert!(
        !output.exists() && !dir.join("model.rdm.work").exists(),
        "a stage ran"
    );
}

/// The last stderr line of `output`, parsed as one JSON object.
fn last_json(output: &Output) -> serde_json::Value {
    let stderr = String::from_utf8_lossy(&output.stderr);
    let last = stderr.lines().last().unwrap_or_default();
    serde_json::from_str(last).unwrap_or_else(|e| panic!("{e}: not JSON: {stderr}"))
}

#[test]
fn json_logs_end_with_the_error_or_the_summary_as_objects() {
    let dir = temp_dir("json");
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    let header = bytes.len() as u64;
    for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        bytes.extend(v.to_le_bytes());
    }
    bytes.push(3);
    for i in [0i32, 1, 7] {
        bytes.extend(i.to_le_bytes());
    }
    std::fs::write(dir.join("bad.ply"), bytes).unwrap();
    let config = write_config(
        &dir,
        "[input]\npath = \"bad.ply\"\n[output]\npath = \"bad.rdm\"\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap(), "--log-format", "json"]);
    assert_eq!(output.status.code(), Some(65));
    let error = last_json(&output);
    assert_eq!(error["event"], "error");
    assert_eq!(error["kind"], "bad_input");
    assert_eq!(error["exit_code"], 65);
    assert_eq!(error["file"], dir.join("bad.ply").display().to_string());
    assert_eq!(error["element"], "face");
    assert_eq!(error["index"], 0);
    assert_eq!(error["offset"], header + 36 + 1 + 8);
    assert_eq!(error["stage"], "chunk");
    assert!(error["chunk"].is_null() && error["counts"].is_null());
    assert!(
        error["seconds"].as_f64().is_some_and(|s| s >= 0.0),
        "{error}"
    );

    let config = write_config(
        &dir,
        "[input.generate]\nkind = \"sphere\"\ntriangles = 5000\n[output]\npath = \"s.rdm\"\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap(), "--log-format", "json"]);
    assert_eq!(output.status.code(), Some(0));
    let summary = last_json(&output);
    assert_eq!(summary["event"], "done");
    assert_eq!(summary["kind"], "success");
    assert_eq!(summary["counts"]["triangles"], 5120);
    let bytes = std::fs::metadata(dir.join("s.rdm")).unwrap().len();
    assert_eq!(summary["counts"]["bytes"], bytes);
    assert!(summary["seconds"].as_f64().is_some(), "{summary}");
    for key in ["file", "element", "offset", "chunk"] {
        assert!(summary.get(key).is_some(), "{key} missing in {summary}");
    }

    let work = dir.join("job.work");
    let lock = std::fs::File::options()
        .write(true)
        .open(work.join("lock"))
        .unwrap();
    lock.try_lock().expect("the test takes the lock");
    let output = pipeline(&["run", config.to_str().unwrap(), "--log-format", "json"]);
    assert_eq!(output.status.code(), Some(75));
    let locked = last_json(&output);
    assert_eq!(locked["kind"], "locked");
    assert_eq!(locked["file"], work.display().to_string());
    let message = locked["message"].as_str().unwrap_or_default();
    assert!(
        message.contains(" since 20") && message.ends_with("Z)"),
        "{locked}"
    );
}

#[test]
fn a_failing_chunk_is_named_in_the_json_error() {
    let dir = temp_dir("json-chunk");
    let config = write_config(
        &dir,
        "[input.generate]\nkind = \"sphere\"\ntriangles = 5000\n[output]\npath = \"s.rdm\"\n\
         [chunk]\nmax_triangles = 1000\n",
    );
    let config_arg = config.to_str().unwrap();
    let chunked = pipeline(&["run", config_arg, "--stage", "chunk"]);
    assert_eq!(chunked.status.code(), Some(0));
    // Other bytes, with the manifest's checksum made to match them (as if the damage had
    // happened before the chunk was hashed): the chunk stage counts as done.
    let chunk = dir.join("job.work/chunks/chunk-000002.mesh.zst");
    let size = std::fs::metadata(&chunk).unwrap().len() as usize;
    std::fs::write(&chunk, vec![0x5a; size]).unwrap();
    let manifest_path = dir.join("job.work/manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&manifest_path).unwrap()).unwrap();
    let hash = xxhash_rust::xxh3::xxh3_64(&vec![0x5a; size]);
    manifest["units"]["chunk"]["outputs"]["chunks/chunk-000002.mesh.zst"]["xxh3"] =
        format!("{hash:016x}").into();
    std::fs::write(&manifest_path, serde_json::to_vec(&manifest).unwrap()).unwrap();
    let output = pipeline(&["run", config_arg, "--log-format", "json"]);
    assert_ne!(output.status.code(), Some(0));
    let error = last_json(&output);
    assert_eq!(error["stage"], "strip", "{error}");
    assert_eq!(error["chunk"], 2, "{error}");
}

#[test]
fn the_default_work_directory_follows_the_config_or_an_existing_former_default() {
    let dir = temp_dir("default-work");
    small_mesh(&dir, "model.ply");
    let body = "[input]\npath = \"model.ply\"\n[output]\npath = \"model.rdm\"\n";
    let config = write_config(&dir, &format!("{body}[work]\ndir = \"model.rdm.work\"\n"));
    let config_arg = config.to_str().unwrap();
    assert_eq!(pipeline(&["run", config_arg]).status.code(), Some(0));
    write_config(&dir, body);
    let status = String::from_utf8_lossy(&pipeline(&["status", config_arg]).stdout).to_string();
    assert!(
        status.starts_with(&format!(
            "work directory {}",
            dir.join("model.rdm.work").display()
        )),
        "{status}"
    );
    assert!(
        status.lines().skip(2).all(|l| l.ends_with("done")),
        "{status}"
    );

    std::fs::remove_dir_all(dir.join("model.rdm.work")).unwrap();
    assert_eq!(pipeline(&["run", config_arg]).status.code(), Some(0));
    assert!(dir.join("job.work/manifest.json").is_file());
}

#[test]
fn keep_false_and_clean_after_remove_the_work_directory_after_success() {
    let dir = temp_dir("keep");
    let mesh = small_mesh(&dir, "model.ply");
    let config = write_config(
        &dir,
        "[input]\npath = \"model.ply\"\n[output]\npath = \"model.rdm\"\n[work]\nkeep = false\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap(), "--log-format", "plain"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains(&format!("removed {}", dir.join("job.work").display())),
        "{stderr}"
    );
    assert!(dir.join("model.rdm").is_file() && !dir.join("job.work").exists());

    let converted = dir.join("converted.rdm");
    let args = [
        "convert",
        mesh.to_str().unwrap(),
        "-o",
        converted.to_str().unwrap(),
        "--clean-after",
    ];
    assert_eq!(pipeline(&args).status.code(), Some(0));
    assert!(converted.is_file() && !dir.join("converted.rdm.work").exists());
}

#[test]
fn too_few_triangles_for_the_kind_are_refused() {
    let dir = temp_dir("too-few");
    let out = dir.join("tiny.ply");
    let output = pipeline(&[
        "gen",
        "isosurface",
        "--triangles",
        "50",
        "-o",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(64), "{stderr}");
    assert!(
        stderr.contains("--triangles 50 is too few: the smallest isosurface mesh has 96 triangles"),
        "{stderr}"
    );
    assert!(!out.exists());
    let config = write_config(
        &dir,
        "[input.generate]\nkind = \"scan\"\ntriangles = 0\n[output]\npath = \"x.rdm\"\n",
    );
    let output = pipeline(&["run", config.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(78), "{stderr}");
    assert!(
        stderr.contains("[input.generate] triangles = 0 is too few"),
        "{stderr}"
    );
    let help = String::from_utf8_lossy(&pipeline(&["gen", "--help"]).stdout).to_string();
    assert!(help.contains("1,000,772"), "{help}");
}

//! Nothing lost, nothing trusted blindly: the work directory's files are checked against the
//! checksums recorded when they were written, the final file is verified before it replaces
//! an earlier output, and work resumed from the files of every stage boundary ends in the
//! same bytes.

mod common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

use common::{pipeline, temporaries};

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("pipeline-integrity-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

fn run(config: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["run", config.to_str().unwrap(), "--log-format", "plain"];
    args.extend(extra);
    pipeline(&args)
}

fn run_ok(config: &Path, extra: &[&str]) -> String {
    let output = run(config, extra);
    assert!(output.status.success(), "{}", stderr(&output));
    stderr(&output)
}

fn status(config: &Path) -> String {
    let output = pipeline(&["status", config.to_str().unwrap()]);
    String::from_utf8_lossy(&output.stdout).into_owned()
}

/// A job on a generated scan of 20,000 triangles in chunks of 4,000, with `extra` keys.
fn job(dir: &Path, extra: &str) -> PathBuf {
    let config = dir.join("job.toml");
    let body = format!(
        "[input.generate]\nkind = \"scan\"\ntriangles = 20000\nseed = 3\n\n[output]\n\
         path = \"out.rdm\"\n\n[chunk]\nmax_triangles = 4000\n{extra}"
    );
    fs::write(&config, body).expect("config");
    config
}

fn flip_middle_byte(path: &Path) {
    let mut bytes = fs::read(path).expect("read");
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x04;
    fs::write(path, bytes).expect("write");
}

#[test]
fn a_changed_work_file_of_each_kind_is_named_stale_and_rebuilt_to_the_same_bytes() {
    let dir = temp_dir("flips");
    let config = job(&dir, "");
    run_ok(&config, &[]);
    let output = dir.join("out.rdm");
    let reference = fs::read(&output).expect("output");
    let absolute_output = std::path::absolute(&output).unwrap().display().to_string();
    let cases = [
        ("chunks/plan.json", "chunk", "every chunk"),
        ("chunks/chunk-000001.mesh.zst", "chunk", "every chunk"),
        ("chunks/border-000001.edges", "chunk", "every chunk"),
        (
            "strips/chunk-000002.strips",
            "strip/chunk-000002",
            "chunk 2",
        ),
        ("merge.json", "merge", "it"),
        ("hierarchy.json", "hierarchy", "it"),
        (absolute_output.as_str(), "write", "it"),
    ];
    for (file, unit, rebuilt) in cases {
        let path = dir.join("job.work").join(file);
        flip_middle_byte(&path);
        let text = status(&config);
        let stale = format!("{unit:<20} stale: {file} changed since it was written");
        assert!(text.contains(&stale), "{file}: {text}");
        let log = run_ok(&config, &[]);
        let rebuilding = format!("{file} changed since it was written; rebuilding {rebuilt}");
        assert!(log.contains(&rebuilding), "{file}: {log}");
        assert!(
            fs::read(&output).unwrap() == reference,
            "{file}: output differs"
        );
        let text = status(&config);
        assert!(text.lines().skip(2).all(|l| l.ends_with("done")), "{text}");
    }
    assert_eq!(temporaries(&dir), Vec::<PathBuf>::new());
    let _ = fs::remove_dir_all(&dir);
}

/// Sets the checksum the manifest records for `file` to its current content's, as if the
/// damage had happened before it was hashed, and forgets the write stage.
fn damage_beyond_the_checksums(work: &Path, file: &str) {
    let manifest_path = work.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_slice(&fs::read(&manifest_path).unwrap()).unwrap();
    let hash = xxhash_rust::xxh3::xxh3_64(&fs::read(work.join(file)).unwrap());
    let units = manifest["units"].as_object_mut().unwrap();
    for unit in units.values_mut() {
        if let Some(recorded) = unit["outputs"].get_mut(file) {
            recorded["xxh3"] = format!("{hash:016x}").into();
        }
    }
    units.remove("write");
    fs::write(&manifest_path, serde_json::to_vec(&manifest).unwrap()).unwrap();
}

#[test]
fn a_file_failing_its_final_verification_leaves_the_earlier_output_and_the_stage_undone() {
    let dir = temp_dir("verify");
    let config = job(&dir, "");
    run_ok(&config, &[]);
    let output = dir.join("out.rdm");
    let reference = fs::read(&output).expect("output");
    let strips = dir.join("job.work/strips/chunk-000001.strips");
    let good = fs::read(&strips).unwrap();
    let mut bad = good.clone();
    // The first node's first child link, far beyond the file's nodes and strips: the final
    // check refuses it.
    bad[256..260].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
    fs::write(&strips, &bad).unwrap();
    damage_beyond_the_checksums(&dir.join("job.work"), "strips/chunk-000001.strips");
    for _attempt in 0..2 {
        let failed = run(&config, &[]);
        let message = stderr(&failed);
        assert_eq!(failed.status.code(), Some(70), "{message}");
        assert!(
            message.contains(
                "out.rdm: the new file failed verification and was removed; the earlier file \
                 is unchanged and the write stage is not recorded as done"
            ),
            "{message}"
        );
        assert!(!message.contains("write: fresh"), "{message}");
        assert!(
            fs::read(&output).unwrap() == reference,
            "the earlier output changed"
        );
        assert!(
            status(&config).contains("write                pending: never run"),
            "{}",
            status(&config)
        );
        assert_eq!(temporaries(&dir), Vec::<PathBuf>::new());
    }
    fs::write(&strips, &good).unwrap();
    damage_beyond_the_checksums(&dir.join("job.work"), "strips/chunk-000001.strips");
    run_ok(&config, &[]);
    assert!(fs::read(&output).unwrap() == reference);
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn a_border_edge_file_damaged_after_hashing_fails_the_merge_and_counts_nothing() {
    let dir = temp_dir("edges");
    let config = job(&dir, "");
    run_ok(&config, &[]);
    let output = dir.join("out.rdm");
    let reference = fs::read(&output).expect("output");
    let work = dir.join("job.work");
    let edges = work.join("chunks/border-000002.edges");
    flip_middle_byte(&edges);
    damage_beyond_the_checksums(&work, "chunks/border-000002.edges");
    forget_unit(&work, "merge");
    let failed = run(&config, &[]);
    let message = stderr(&failed);
    assert_eq!(failed.status.code(), Some(70), "{message}");
    assert!(
        message.contains("border-000002.edges: border edges damaged (the edges' checksum"),
        "{message}"
    );
    assert!(fs::read(&output).unwrap() == reference);
    assert!(status(&config).contains("merge                pending: never run"));
    let _ = fs::remove_dir_all(&dir);
}

/// Removes `unit` from the manifest, as if it had never run.
fn forget_unit(work: &Path, unit: &str) {
    let manifest_path = work.join("manifest.json");
    let mut manifest: serde_json::Value =
        serde_json::from_slice(&fs::read(&manifest_path).unwrap()).unwrap();
    manifest["units"].as_object_mut().unwrap().remove(unit);
    fs::write(&manifest_path, serde_json::to_vec(&manifest).unwrap()).unwrap();
}

/// Binary PLY of a 70 × 50 height field with a normal and a colour per vertex.
fn attributed_surface(path: &Path) {
    let (columns, rows) = (70u32, 50u32);
    let vertices = (columns + 1) * (rows + 1);
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\n\
         property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
         property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        2 * columns * rows
    )
    .into_bytes();
    for y in 0..=rows {
        for x in 0..=columns {
            let (u, v) = (x as f32 * 0.137, y as f32 * 0.091);
            let (dx, dy) = (0.3 * u.cos(), -0.3 * v.sin());
            let length = (dx * dx + dy * dy + 1.0).sqrt();
            let values = [
                u,
                v,
                0.3 * u.sin() + 0.3 * v.cos(),
                -dx / length,
                -dy / length,
            ];
            for value in values.into_iter().chain([1.0 / length]) {
                bytes.extend_from_slice(&value.to_le_bytes());
            }
            bytes.extend_from_slice(&[(x * 3) as u8, (y * 5) as u8, 200]);
        }
    }
    let id = |x: u32, y: u32| (y * (columns + 1) + x) as i32;
    for y in 0..rows {
        for x in 0..columns {
            for triangle in [
                [id(x, y), id(x + 1, y), id(x + 1, y + 1)],
                [id(x, y), id(x + 1, y + 1), id(x, y + 1)],
            ] {
                bytes.push(3);
                triangle
                    .iter()
                    .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
            }
        }
    }
    fs::write(path, bytes).expect("write PLY");
}

/// Runs `config` through once, then again from nothing with every stage in a process of its
/// own (so each reads the files the one before it left), then writes the output again from
/// the recorded stages alone: every way ends in the same bytes.
fn assert_each_stage_boundary_resumes_to_the_same_bytes(config: &Path) {
    let dir = config.parent().unwrap();
    let output = dir.join("out.rdm");
    run_ok(config, &[]);
    let reference = fs::read(&output).expect("output");
    fs::remove_dir_all(dir.join("job.work")).unwrap();
    fs::remove_file(&output).unwrap();
    for stage in ["chunk", "strip", "merge", "hierarchy", "write"] {
        run_ok(config, &["--stage", stage]);
    }
    assert!(
        fs::read(&output).unwrap() == reference,
        "staged output differs"
    );
    fs::remove_file(&output).unwrap();
    let log = run_ok(config, &[]);
    assert!(log.contains("hierarchy: fresh"), "{log}");
    assert!(
        fs::read(&output).unwrap() == reference,
        "rewritten output differs"
    );
}

#[test]
fn grid_attribute_and_generated_jobs_resume_from_every_stage_boundary_to_the_same_bytes() {
    let grid = temp_dir("boundaries-grid");
    assert_each_stage_boundary_resumes_to_the_same_bytes(&job(
        &grid,
        "\n[vertices]\nencoding = \"grid\"\ngrid_bits = 16\n",
    ));
    let generated = temp_dir("boundaries-generated");
    assert_each_stage_boundary_resumes_to_the_same_bytes(&job(&generated, ""));
    let attributes = temp_dir("boundaries-attributes");
    attributed_surface(&attributes.join("surface.ply"));
    let config = attributes.join("job.toml");
    fs::write(
        &config,
        "[input]\npath = \"surface.ply\"\n\n[output]\npath = \"out.rdm\"\n\n[chunk]\n\
         max_triangles = 1500\n\n[vertices]\nencoding = \"grid\"\ngrid_bits = 14\n\n\
         [attributes]\nface_ids = true\nnormals = \"oct8\"\ncolors = true\n",
    )
    .unwrap();
    assert_each_stage_boundary_resumes_to_the_same_bytes(&config);
    for dir in [grid, generated, attributes] {
        let _ = fs::remove_dir_all(dir);
    }
}

/// Work files carry f32 bounds and f64 error measures as JSON numbers: every finite value
/// must read back with the bits it was written with.
#[test]
fn floats_round_trip_through_work_file_json_bit_for_bit() {
    let mut random = reducem::splitmix::SplitMix64::new(27);
    for _ in 0..500_000 {
        let bits = random.next_u64();
        let double = f64::from_bits(bits);
        let single = f32::from_bits(bits as u32);
        if double.is_finite() {
            let json = serde_json::to_string(&double).unwrap();
            let back: f64 = serde_json::from_str(&json).unwrap();
            assert_eq!(back.to_bits(), double.to_bits(), "{json}");
        }
        if single.is_finite() {
            let json = serde_json::to_string(&single).unwrap();
            let back: f32 = serde_json::from_str(&json).unwrap();
            assert_eq!(back.to_bits(), single.to_bits(), "{json}");
        }
    }
}

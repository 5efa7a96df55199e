//! `pipeline convert` and its work directory: removed after a successful conversion unless
//! `--keep-work`, kept while the conversion is unfinished, never created for an input that
//! cannot be read.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::pipeline;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "pipeline-convert-work-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// A 6 × 6 quad grid as OBJ: 72 triangles.
fn grid_obj(dir: &Path) -> PathBuf {
    let mut text = String::new();
    for y in 0..7 {
        for x in 0..7 {
            text += &format!("v {x} {y} {}\n", (x * y) % 3);
        }
    }
    for y in 0..6 {
        for x in 0..6 {
            let corner = 1 + y * 7 + x;
            let (right, up) = (corner + 1, corner + 7);
            text += &format!(
                "f {corner} {right} {}\nf {corner} {} {up}\n",
                up + 1,
                up + 1
            );
        }
    }
    let path = dir.join("grid.obj");
    std::fs::write(&path, text).expect("write the mesh");
    path
}

fn convert(input: &Path, output: &Path, flags: &[&str]) -> Output {
    let args = [
        "convert",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
    ];
    pipeline(&[&args[..], &["--log-format", "plain"], flags].concat())
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

#[test]
fn a_successful_convert_removes_its_work_directory_unless_kept() {
    let dir = temp_dir("removed");
    let input = grid_obj(&dir);
    let output = dir.join("grid.rdm");
    let work = dir.join("grid.rdm.work");

    let removed = convert(&input, &output, &[]);
    assert_eq!(removed.status.code(), Some(0), "{}", stderr(&removed));
    assert!(
        stderr(&removed).contains(&format!("removed {}", work.display())),
        "{}",
        stderr(&removed)
    );
    assert!(!work.exists(), "{} is left behind", work.display());
    let converted = std::fs::read(&output).expect("the output");
    let listing: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        listing.len(),
        2,
        "only the input and the output: {listing:?}"
    );

    std::fs::remove_file(&output).unwrap();
    let kept = convert(&input, &output, &["--keep-work"]);
    assert_eq!(kept.status.code(), Some(0), "{}", stderr(&kept));
    assert!(work.join("convert.toml").is_file() && work.join("manifest.json").is_file());
    assert_eq!(std::fs::read(&output).unwrap(), converted);

    let resumed = convert(&input, &output, &[]);
    assert_eq!(resumed.status.code(), Some(0), "{}", stderr(&resumed));
    assert!(
        stderr(&resumed).contains("write: fresh"),
        "{}",
        stderr(&resumed)
    );
    assert!(!work.exists(), "{} is left behind", work.display());
    assert_eq!(std::fs::read(&output).unwrap(), converted);
}

#[test]
fn an_unfinished_convert_keeps_its_work_directory_to_resume() {
    let dir = temp_dir("unfinished");
    let input = dir.join("broken.obj");
    std::fs::write(&input, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n").unwrap();
    let output = dir.join("broken.rdm");
    let failed = convert(&input, &output, &[]);
    assert_eq!(failed.status.code(), Some(65), "{}", stderr(&failed));
    assert!(dir.join("broken.rdm.work/convert.toml").is_file());
    assert!(!output.exists());
}

#[test]
fn a_convert_of_an_unreadable_input_creates_nothing() {
    let dir = temp_dir("missing");
    let output = dir.join("new/sub/model.rdm");
    let work = dir.join("work");
    for input in [dir.join("missing.obj"), dir.clone()] {
        let failed = convert(&input, &output, &["--work", work.to_str().unwrap()]);
        assert_eq!(failed.status.code(), Some(74), "{}", stderr(&failed));
        assert!(
            stderr(&failed).contains(&format!("input {}", input.display())),
            "{}",
            stderr(&failed)
        );
        let listing: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert!(listing.is_empty(), "created {listing:?}");
    }
}

#[test]
fn keep_work_and_clean_after_contradict_each_other() {
    let dir = temp_dir("contradiction");
    let input = grid_obj(&dir);
    let output = dir.join("grid.rdm");
    let refused = convert(&input, &output, &["--keep-work", "--clean-after"]);
    assert_eq!(refused.status.code(), Some(64), "{}", stderr(&refused));
    assert!(
        stderr(&refused).contains("'--keep-work' cannot be used with '--clean-after'"),
        "{}",
        stderr(&refused)
    );
    assert!(!output.exists() && !dir.join("grid.rdm.work").exists());
}

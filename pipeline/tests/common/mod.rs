//! Shared support of the pipeline's command tests: running the binary, finding temporaries.
#![allow(dead_code)]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `pipeline` binary with `args` to its end.
pub fn pipeline(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(args)
        .output()
        .expect("run pipeline")
}

/// Every temporary (`.NAME.tmp-PID`) under `dir`, recursively.
pub fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in fs::read_dir(dir).expect("list").flatten() {
        let path = entry.path();
        if path.is_dir() {
            found.extend(temporaries(&path));
        } else if entry.file_name().to_string_lossy().contains(".tmp-") {
            found.push(path);
        }
    }
    found
}

/// A fresh directory `pipeline-TEST-PID-NAME` under the system's temporary directory.
pub fn temp_dir(test: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-{test}-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// `pipeline convert INPUT -o OUTPUT`: its exit code and standard error.
pub fn convert(input: &Path, output: &Path) -> (Option<i32>, String) {
    let result = pipeline(&[
        "convert",
        input.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
        "--log-format",
        "plain",
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr).into_owned();
    (result.status.code(), stderr)
}

/// Writes each `(name, bytes, expected)` input into `dir` and converts it: exit 65, and an error
/// naming the file and saying `expected`.
pub fn assert_broken_inputs_exit_65(dir: &Path, cases: Vec<(&str, Vec<u8>, &str)>) {
    for (name, bytes, expected) in cases {
        let input = dir.join(name);
        fs::write(&input, bytes).unwrap();
        let (code, stderr) = convert(&input, &dir.join("out.rdm"));
        assert_eq!(code, Some(65), "{name}: {stderr}");
        assert!(stderr.contains(expected), "{name}: {stderr}");
        assert!(stderr.contains(name), "{name}: {stderr}");
    }
}

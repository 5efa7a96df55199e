//! Renamed config keys keep their old names: `[strip] leaf_windows` was `leaf_triangles`, and a
//! config with either converts to the same bytes.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use reducem::format::reader::ReducemFile;

fn convert(dir: &Path, name: &str, strip: &str) -> PathBuf {
    let out = dir.join(format!("{name}.rdm"));
    let config = dir.join(format!("{name}.toml"));
    let body = format!(
        "[input.generate]\nkind = \"scan\"\ntriangles = 3000\n\n[output]\npath = {out:?}\n\n\
         [strip]\n{strip}\n"
    );
    fs::write(&config, body).expect("config");
    let output = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", config.to_str().unwrap(), "--log-format", "plain"])
        .output()
        .expect("run pipeline");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    out
}

#[test]
fn leaf_triangles_is_read_as_leaf_windows() {
    let dir = std::env::temp_dir().join(format!("pipeline-config-keys-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    let new = convert(&dir, "new", "leaf_windows = 2");
    let old = convert(&dir, "old", "leaf_triangles = 2");
    assert_eq!(ReducemFile::open(&new).expect("open").leaf_windows(), 2);
    assert_eq!(fs::read(&new).expect("new"), fs::read(&old).expect("old"));
    let _ = fs::remove_dir_all(&dir);
}

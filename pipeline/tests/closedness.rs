//! The model record through the staged job: a model converted as one chunk stores the edge
//! counts of the in-memory path (which `reducem`'s tests check against a brute force), one of
//! several chunks stores them as unknown; `[input] up` is stored (y by default for PLY) and an
//! unknown axis is refused.

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::model::UpAxis;
use reducem::format::reader::ReducemFile;
use reducem::input::read_mesh;
use reducem_gen::{generate, Kind};

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("pipeline-closedness-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Runs the job on `input` with `max_triangles` per chunk and `extra` input keys.
fn staged(dir: &Path, input: &Path, max_triangles: u64, extra: &str) -> ReducemFile {
    let out = dir.join(format!("out-{max_triangles}{}.rdm", extra.len()));
    let config = dir.join("job.toml");
    let body = format!(
        "[input]\npath = {input:?}\n{extra}\n[output]\npath = {out:?}\n\n[chunk]\nmax_triangles = {max_triangles}\n"
    );
    fs::write(&config, body).expect("config");
    let run = common::pipeline(&["run", config.to_str().unwrap(), "--log-format", "plain"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    ReducemFile::open(&out).expect("open")
}

#[test]
fn one_chunk_stores_the_edge_counts_and_several_leave_them_unknown() {
    let dir = temp_dir("chunks");
    for kind in [Kind::Sphere, Kind::Terrain, Kind::Cad] {
        let input = dir.join(format!("{}.ply", kind.name()));
        generate(kind, 4_000, 3, &input).expect("generate");
        let in_memory = dir.join("memory.rdm");
        convert_mesh(
            &read_mesh(&input).expect("read"),
            &BuildParams::default(),
            &in_memory,
        )
        .expect("convert");
        let expected = ReducemFile::open(&in_memory).expect("open").closedness();
        assert!(expected.is_some());
        let one = staged(&dir, &input, 1_000_000, "");
        assert_eq!(one.closedness(), expected, "{}", kind.name());
        assert_eq!(one.up_axis(), Some(UpAxis::Y));
        let several = staged(&dir, &input, 1_000, "");
        assert_eq!((several.closedness(), several.closed()), (None, false));
    }
    let sphere = dir.join("sphere.ply");
    assert!(staged(&dir, &sphere, 1_000_000, "").closed());
    let z_up = staged(&dir, &sphere, 1_000_000, "up = \"z\"");
    assert_eq!(z_up.up_axis(), Some(UpAxis::Z));
}

#[test]
fn an_unknown_up_axis_is_refused() {
    let dir = temp_dir("up");
    let config = dir.join("job.toml");
    fs::write(
        &config,
        "[input]\npath = \"in.ply\"\nup = \"x\"\n\n[output]\npath = \"out.rdm\"\n",
    )
    .expect("config");
    let run = common::pipeline(&["run", config.to_str().unwrap(), "--log-format", "plain"]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("up") && stderr.contains("job.toml"),
        "{stderr}"
    );
}

//! Files stay byte-identical across refactorings: every generator kind, converted in memory
//! (`reducem::conversion::convert_mesh`) and by the staged job in several chunks, with f32 vertices,
//! grid vertices and f32 vertices with grid nodes, hashes to the value recorded when the test was
//! written (at 7bca529; recorded again for format 3.0's block boxes and packed references). A
//! deliberate format or build change updates the table (the failure prints the new values).
//! `soup` hashes as `scan` does: it is scan's surface with unshared vertices, which the
//! bit-identical weld joins again. A job on `[input.generate]`, which streams the generator into
//! the chunk stage without a file, hashes as the staged job on the PLY that `pipeline gen` writes
//! for the same parameters.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use reducem::conversion::{convert_mesh, BuildParams, PIPELINE_LEAF_WINDOWS};
use reducem::input::read_mesh;
use reducem_gen::{generate, Kind};

const TRIANGLES: u64 = 6_000;
const CHUNK_TRIANGLES: u64 = 2_000;

/// XXH3-64 of each output: (kind, vertices, in-memory file, staged file).
#[rustfmt::skip]
const RECORDED: [(&str, &str, u64, u64); 18] = [
    ("scan", "f32", 0x4cd4b9b8e2fd4d9d, 0x12b01c479dd75b57),
    ("scan", "grid", 0x309fc8bad869e4e7, 0x9aa113305e9c476f),
    ("scan", "f32-grid-nodes", 0x1bb3fe8590b15fd6, 0x4e405b091ce83d01),
    ("terrain", "f32", 0xe45329068be2bc91, 0xcc73ed3b269f8784),
    ("terrain", "grid", 0x515a612c1eabfa4b, 0xa10a9ad813631af4),
    ("terrain", "f32-grid-nodes", 0x35196ee39146fc34, 0x08ef265ca163a35a),
    ("isosurface", "f32", 0x0f80f572b3ec7041, 0xdebf96fc875febc0),
    ("isosurface", "grid", 0x78a606d3c6c3e144, 0xa0327dfd93186beb),
    ("isosurface", "f32-grid-nodes", 0x46328802ee89865c, 0x1e224e2cdaa2d050),
    ("cad", "f32", 0xf0e9ab58537b75d9, 0xf012618ac181a7e5),
    ("cad", "grid", 0x8d583b63e26e9bf8, 0xf6b98f9041da05ec),
    ("cad", "f32-grid-nodes", 0x76937adea4e9a6d1, 0x6cea70893b299e71),
    ("soup", "f32", 0x4cd4b9b8e2fd4d9d, 0x12b01c479dd75b57),
    ("soup", "grid", 0x309fc8bad869e4e7, 0x9aa113305e9c476f),
    ("soup", "f32-grid-nodes", 0x1bb3fe8590b15fd6, 0x4e405b091ce83d01),
    ("sphere", "f32", 0x1ae07c033f9a339f, 0x08fc4a1d7c826bac),
    ("sphere", "grid", 0xc0571ebc05e370cc, 0x64055232e9f04d27),
    ("sphere", "f32-grid-nodes", 0x4e1e27603046ae33, 0xbe3220ceef91c1c3),
];

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-golden-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn kind(name: &str) -> Kind {
    name.parse().expect("kind")
}

/// The build parameters of the staged job's config for `vertices`.
fn params(vertices: &str) -> BuildParams {
    BuildParams {
        leaf_windows: PIPELINE_LEAF_WINDOWS,
        grid_bits: (vertices == "grid").then_some(20),
        grid_nodes: vertices == "f32-grid-nodes",
        ..BuildParams::default()
    }
}

/// The staged job with the in-memory path's strip length (the paper's 60, the pipeline's default
/// when the hashes were recorded).
fn staged(dir: &Path, input: &Path, vertices: &str, out: &Path) {
    staged_from(dir, &format!("[input]\npath = {input:?}\n"), vertices, out);
}

/// [`staged`] on the generated mesh the golden PLY files hold, streamed from the generator.
fn staged_generated(dir: &Path, kind_name: &str, vertices: &str, out: &Path) {
    let input =
        format!("[input.generate]\nkind = {kind_name:?}\ntriangles = {TRIANGLES}\nseed = 3\n");
    staged_from(dir, &input, vertices, out);
}

fn staged_from(dir: &Path, input: &str, vertices: &str, out: &Path) {
    let config = dir.join("job.toml");
    let encoding = if vertices == "grid" { "grid" } else { "f32" };
    let body = format!(
        "{input}\n[output]\npath = {out:?}\n\n[chunk]\nmax_triangles = \
         {CHUNK_TRIANGLES}\n\n[strip]\nmax_length = 60\ngrid_nodes = {}\n\n[vertices]\nencoding = \"{encoding}\"\n",
        vertices == "f32-grid-nodes"
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
}

fn hash(path: &Path) -> u64 {
    xxhash_rust::xxh3::xxh3_64(&fs::read(path).expect("read output"))
}

#[test]
fn outputs_match_the_recorded_hashes() {
    let dir = temp_dir("recorded");
    let mut actual = Vec::new();
    for &(kind_name, vertices, _, _) in &RECORDED {
        let input = dir.join(format!("{kind_name}.ply"));
        if !input.exists() {
            generate(kind(kind_name), TRIANGLES, 3, &input).expect("generate");
        }
        let in_memory = dir.join(format!("{kind_name}-{vertices}-memory.rdm"));
        let mesh = read_mesh(&input).expect("read");
        convert_mesh(&mesh, &params(vertices), &in_memory).expect("convert");
        let chunked = dir.join(format!("{kind_name}-{vertices}-staged.rdm"));
        staged(&dir, &input, vertices, &chunked);
        actual.push((kind_name, vertices, hash(&in_memory), hash(&chunked)));
    }
    let table: String = actual
        .iter()
        .map(|(k, v, m, s)| format!("    ({k:?}, {v:?}, {m:#018x}, {s:#018x}),\n"))
        .collect();
    assert!(
        actual == RECORDED,
        "outputs differ from the recorded hashes; now:\n{table}"
    );
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn generated_inputs_convert_to_the_files_of_their_ply() {
    let dir = temp_dir("generated");
    let cases = RECORDED
        .iter()
        .filter(|&&(kind_name, vertices, ..)| vertices == "f32" || kind_name == "scan");
    for &(kind_name, vertices, _, recorded) in cases {
        let out = dir.join(format!("{kind_name}-{vertices}.rdm"));
        staged_generated(&dir, kind_name, vertices, &out);
        assert_eq!(hash(&out), recorded, "{kind_name} {vertices}");
        let work_files: Vec<_> = fs::read_dir(dir.join("job.work"))
            .expect("work directory")
            .map(|entry| entry.expect("entry").file_name())
            .collect();
        assert!(
            !work_files
                .iter()
                .any(|name| name.to_string_lossy().ends_with(".ply")),
            "no input file is written: {work_files:?}"
        );
    }
    let _ = fs::remove_dir_all(&dir);
}

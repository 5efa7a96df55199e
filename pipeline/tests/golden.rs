//! Files stay byte-identical across refactorings: every generator kind, converted in memory
//! (`reducem::conversion::convert_mesh`) and by the staged job in several chunks, with f32 vertices,
//! grid vertices and f32 vertices with grid nodes, hashes to the value recorded when the test was
//! written (at 7bca529; recorded again for format 3.0's block boxes and packed references, for 3.1's model record, for its edge counts of models in several chunks, for format 4's collapse choosing leaves by the SAH, for grid files for format 4.1's pooled vertices, and for pooled files' header counting the pools' points as stored vertices). A
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
    ("scan", "f32", 0xd3f79dba9a939399, 0x2ed1a6af8ca3d2f5),
    ("scan", "grid", 0xb40e5b59fca81c0c, 0xe9772d7ed101bab7),
    ("scan", "f32-grid-nodes", 0xd3f79dba9a939399, 0x2ed1a6af8ca3d2f5),
    ("terrain", "f32", 0x978fa766553caca2, 0x0d648db4f6c01029),
    ("terrain", "grid", 0x1c84d8436f4b7a35, 0xedc52afaac826dc5),
    ("terrain", "f32-grid-nodes", 0x978fa766553caca2, 0x0d648db4f6c01029),
    ("isosurface", "f32", 0xd0d928b7c4501cf6, 0xaa6cca337a981062),
    ("isosurface", "grid", 0x009d8680c28cc07e, 0x380cbc356e0c1211),
    ("isosurface", "f32-grid-nodes", 0xd0d928b7c4501cf6, 0xaa6cca337a981062),
    ("cad", "f32", 0x9a9760c068549711, 0x5f062e6d4bcffe5e),
    ("cad", "grid", 0x66cbd1d5c130a68b, 0x5d341c1bc7ac5af8),
    ("cad", "f32-grid-nodes", 0x9a9760c068549711, 0x5f062e6d4bcffe5e),
    ("soup", "f32", 0xd3f79dba9a939399, 0x2ed1a6af8ca3d2f5),
    ("soup", "grid", 0xb40e5b59fca81c0c, 0xe9772d7ed101bab7),
    ("soup", "f32-grid-nodes", 0xd3f79dba9a939399, 0x2ed1a6af8ca3d2f5),
    ("sphere", "f32", 0x4da03e57266fe679, 0x916fbae2b8735f42),
    ("sphere", "grid", 0x5330f84eb1bbeeff, 0x2bb30ca2d2d05ab7),
    ("sphere", "f32-grid-nodes", 0x4da03e57266fe679, 0x916fbae2b8735f42),
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

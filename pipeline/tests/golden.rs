//! Files stay byte-identical across refactorings: every generator kind, converted in memory
//! (`reducem::conversion::convert_mesh`) and by the staged job in several chunks, with f32 vertices,
//! grid vertices and f32 vertices with grid nodes, hashes to the value recorded when the test was
//! written (at 7bca529; recorded again for format 3.0's block boxes and packed references, for 3.1's model record and for its edge counts of models in several chunks). A
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
    ("scan", "f32", 0x74b1be557bdd7223, 0xad8220b628caa178),
    ("scan", "grid", 0x531c07ba8ef04e4b, 0x3b4c1711247ade4c),
    ("scan", "f32-grid-nodes", 0xd250702ed35a73bd, 0xc86c2309ad2a4387),
    ("terrain", "f32", 0xb619e44b4505c929, 0x0ce35cba0b202c66),
    ("terrain", "grid", 0xeabcf3558bd02ab8, 0xeb41441955aeb816),
    ("terrain", "f32-grid-nodes", 0xcd03c5664c8d766e, 0x4ea786e2dc8d4725),
    ("isosurface", "f32", 0x5f395a590f0dbb0f, 0xadc73afd6c3591f3),
    ("isosurface", "grid", 0xae5396b939dc5ff2, 0x9e67c6c2ef6db419),
    ("isosurface", "f32-grid-nodes", 0x59092e302f0bccf2, 0x4561309bfa7b8f84),
    ("cad", "f32", 0x2d90c094ac3e4b6d, 0x27e8387fd3b929dc),
    ("cad", "grid", 0xfd6613a4a47f10e2, 0x017ab0ebbbb954c3),
    ("cad", "f32-grid-nodes", 0x0c6a724abbd1127a, 0x7bef10291fb97c18),
    ("soup", "f32", 0x74b1be557bdd7223, 0xad8220b628caa178),
    ("soup", "grid", 0x531c07ba8ef04e4b, 0x3b4c1711247ade4c),
    ("soup", "f32-grid-nodes", 0xd250702ed35a73bd, 0xc86c2309ad2a4387),
    ("sphere", "f32", 0xa15d596856e8b7f7, 0xa6929e0481be68a1),
    ("sphere", "grid", 0x57c265308157238a, 0xf21989d441614361),
    ("sphere", "f32-grid-nodes", 0xf37590984e1d94be, 0xbba823a81eca7cd3),
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

//! The staged runner: lossless across chunks, byte-identical for any thread count and across
//! kills at random moments, invalidation of exactly the affected stages, and the work-dir lock;
//! grid vertices on one model grid across chunks, and the model-wide tolerance weld.

use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use reducem::format::grid::Grid;
use reducem::format::reader::ReducemFile;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-resume-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn pipeline() -> Command {
    Command::new(env!("CARGO_BIN_EXE_pipeline"))
}

fn run(args: &[&str]) -> Output {
    pipeline().args(args).output().expect("run pipeline")
}

/// A generated `scan` input (shared by the job configs) and a config converting it in chunks.
fn job(dir: &Path, extra: &str) -> PathBuf {
    let input = dir.join("input.ply");
    if !input.exists() {
        reducem_gen::generate(reducem_gen::Kind::Scan, 60_000, 5, &input).expect("generate");
    }
    let config = dir.join("job.toml");
    let body = format!(
        "[input]\npath = \"input.ply\"\n\n[output]\npath = \"out.rdm\"\n\n[chunk]\nmax_triangles = 8000\n{extra}"
    );
    fs::write(&config, body).expect("config");
    config
}

fn run_ok(config: &Path, env_threads: &str) -> Output {
    let output = pipeline()
        .args(["run", config.to_str().unwrap(), "--log-format", "plain"])
        .env("RAYON_NUM_THREADS", env_threads)
        .output()
        .expect("run");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

fn canonical_sorted(triangles: impl Iterator<Item = [[f32; 3]; 3]>) -> Vec<[[u32; 3]; 3]> {
    let mut all: Vec<_> = triangles
        .map(|t| {
            let bits = t.map(|p| p.map(f32::to_bits));
            let first = (0..3).min_by_key(|&i| bits[i]).unwrap_or(0);
            [0, 1, 2].map(|k| bits[(first + k) % 3])
        })
        .collect();
    all.sort_unstable();
    all
}

#[test]
fn chunked_conversion_is_lossless() {
    let dir = temp_dir("lossless");
    let config = job(&dir, "");
    run_ok(&config, "2");
    let file = ReducemFile::open(&dir.join("out.rdm")).expect("open");
    let mesh = reducem::input::read_mesh(&dir.join("input.ply")).expect("input");
    let expected = canonical_sorted(mesh.triangles.iter().map(|t| mesh.triangle_points(t)));
    assert_eq!(
        canonical_sorted(reducem::decode::triangles(&file)),
        expected
    );
    assert!(
        fs::read_dir(dir.join("job.work/strips")).unwrap().count() >= 7,
        "several chunks"
    );
}

#[test]
fn output_is_identical_for_one_and_two_threads() {
    let dir = temp_dir("threads");
    let config = job(&dir, "");
    run_ok(&config, "1");
    let one = fs::read(dir.join("out.rdm")).unwrap();
    fs::remove_dir_all(dir.join("job.work")).unwrap();
    run_ok(&config, "2");
    assert!(
        one == fs::read(dir.join("out.rdm")).unwrap(),
        "outputs differ"
    );
}

#[test]
fn runs_killed_at_random_moments_resume_to_identical_bytes() {
    let dir = temp_dir("kill");
    let config = job(&dir, "");
    let started = Instant::now();
    run_ok(&config, "2");
    let full = started.elapsed();
    let reference = fs::read(dir.join("out.rdm")).unwrap();
    kill_and_resume(
        &config,
        &dir.join("out.rdm"),
        &reference,
        full,
        12,
        0x2545_f491_4f6c_dd1d,
    );
}

/// `trials` times: removes the job's work directory and output, SIGKILLs two runs of `config`
/// at pseudo-random moments within `full` (xorshift from `seed`), runs it to the end and expects
/// `output` to hold `reference`'s bytes.
fn kill_and_resume(
    config: &Path,
    output: &Path,
    reference: &[u8],
    full: Duration,
    trials: usize,
    seed: u64,
) {
    let work = config.with_extension("work");
    let mut state = seed;
    for trial in 0..trials {
        fs::remove_dir_all(&work).unwrap();
        fs::remove_file(output).unwrap();
        for _kill in 0..2 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let delay = full.mul_f64((state % 1000) as f64 / 1000.0);
            let mut child = pipeline()
                .args(["run", config.to_str().unwrap(), "--log-format", "plain"])
                .stderr(Stdio::null())
                .spawn()
                .expect("spawn");
            std::thread::sleep(delay);
            child.kill().expect("SIGKILL");
            child.wait().expect("reap");
        }
        run_ok(config, "2");
        assert!(
            reference == fs::read(output).unwrap(),
            "trial {trial}: output differs after kills"
        );
    }
}

/// A job on `[input.generate]` for the parameters of [`job`]'s input, streamed without a file.
fn generated_job(dir: &Path) -> PathBuf {
    let config = dir.join("generated.toml");
    let body = "[input.generate]\nkind = \"scan\"\ntriangles = 60000\nseed = 5\n\n[output]\n\
                path = \"generated.rdm\"\n\n[chunk]\nmax_triangles = 8000\n";
    fs::write(&config, body).expect("config");
    config
}

#[test]
fn a_generated_input_killed_at_random_moments_resumes_to_the_bytes_of_its_ply() {
    let dir = temp_dir("generated-kill");
    run_ok(&job(&dir, ""), "2");
    let reference = fs::read(dir.join("out.rdm")).unwrap();
    let config = generated_job(&dir);
    let started = Instant::now();
    run_ok(&config, "2");
    let full = started.elapsed();
    assert!(reference == fs::read(dir.join("generated.rdm")).unwrap());
    let output = dir.join("generated.rdm");
    kill_and_resume(&config, &output, &reference, full, 4, 0x9e37_79b9_7f4a_7c15);
}

#[test]
fn a_changed_generated_input_is_named_in_status_and_reruns_from_chunk() {
    let dir = temp_dir("generated-status");
    let config = generated_job(&dir);
    run_ok(&config, "2");
    let status = |config: &Path| {
        String::from_utf8_lossy(&run(&["status", config.to_str().unwrap()]).stdout).to_string()
    };
    let text = status(&config);
    assert!(
        text.contains(
            "input                the scan mesh of about 60000 triangles, seed 5, generator \
             version 1 (streamed from the generator, no input file)"
        ),
        "{text}"
    );
    assert!(text.lines().skip(2).all(|l| l.ends_with("done")), "{text}");
    let body = fs::read_to_string(&config).unwrap();
    fs::write(&config, body.replace("seed = 5", "seed = 6")).unwrap();
    let text = status(&config);
    assert!(
        text.contains(
            "chunk                stale: the generated input changed from a scan mesh of about \
             60000 triangles, seed 5, generator version 1 to a scan mesh of about 60000 \
             triangles, seed 6, generator version 1"
        ),
        "{text}"
    );
    let log = String::from_utf8_lossy(&run_ok(&config, "2").stderr).to_string();
    assert!(!log.contains("chunk: fresh"), "{log}");
}

#[test]
fn a_config_change_reruns_only_the_stages_it_affects() {
    let dir = temp_dir("invalidate");
    let config = job(&dir, "");
    run_ok(&config, "2");
    let status = run(&["status", config.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&status.stdout);
    assert!(text.lines().skip(2).all(|l| l.ends_with("done")), "{text}");

    let config = job(&dir, "\n[strip]\nmax_length = 30\n");
    let text =
        String::from_utf8_lossy(&run(&["status", config.to_str().unwrap()]).stdout).to_string();
    assert!(text.contains("chunk                done"), "{text}");
    assert!(
        text.contains("strip/chunk-000000   stale: strip.max_length changed from 20 to 30"),
        "{text}"
    );
    assert!(
        text.contains("merge                pending: waits for strip"),
        "{text}"
    );
    let log = String::from_utf8_lossy(&run_ok(&config, "2").stderr).to_string();
    assert!(log.contains("chunk: fresh"), "{log}");
    assert!(
        !log.contains("strip: done in") || log.contains("0 fresh"),
        "{log}"
    );

    fs::write(
        &config,
        fs::read_to_string(&config)
            .unwrap()
            .replace("out.rdm\"", "other.rdm\""),
    )
    .unwrap();
    let text =
        String::from_utf8_lossy(&run(&["status", config.to_str().unwrap()]).stdout).to_string();
    assert!(text.contains("hierarchy            done"), "{text}");
    assert!(
        text.contains("write                stale: output.path changed"),
        "{text}"
    );
    let log = String::from_utf8_lossy(&run_ok(&config, "2").stderr).to_string();
    for stage in [
        "chunk: fresh",
        "merge: fresh",
        "hierarchy: fresh",
        "0 chunks converted",
    ] {
        assert!(log.contains(stage), "{stage} missing in {log}");
    }
    assert!(fs::read(dir.join("other.rdm")).unwrap() == fs::read(dir.join("out.rdm")).unwrap());
}

#[test]
fn a_held_lock_exits_75_naming_the_holder_or_skips() {
    let dir = temp_dir("lock");
    let config = job(&dir, "");
    fs::create_dir_all(dir.join("job.work")).unwrap();
    // The holder is another run of pipeline, which marked the directory as its own.
    fs::write(dir.join("job.work/pipeline-work-dir"), "").unwrap();
    let mut holder = File::options()
        .create(true)
        .truncate(true)
        .write(true)
        .open(dir.join("job.work/lock"))
        .unwrap();
    writeln!(
        holder,
        "pid 4242 on host testhost since 1970-01-01T00:00:01Z"
    )
    .unwrap();
    holder.try_lock().expect("test takes the lock");

    let output = run(&["run", config.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(75));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("locked by another run") && stderr.contains("pid 4242 on host testhost"),
        "{stderr}"
    );
    assert_eq!(
        run(&["run", config.to_str().unwrap(), "--if-locked", "skip"])
            .status
            .code(),
        Some(0)
    );
    assert!(!dir.join("out.rdm").exists());

    drop(holder);
    // The file is still there with a dead holder's text: a stale lock never blocks.
    run_ok(&config, "2");
    assert!(dir.join("out.rdm").exists());
}

#[test]
fn a_run_dying_while_writing_leaves_the_previous_output_untouched() {
    let dir = temp_dir("file-size-limit");
    let config = job(&dir, "");
    run_ok(&config, "2");
    let before = fs::read(dir.join("out.rdm")).unwrap();
    // A changed config forces new outputs; a 64-block file-size limit stops the run while it
    // writes them (like a full disk, but independent of the user's privileges).
    let config = job(&dir, "\n[strip]\nmax_length = 30\n");
    let output = Command::new("sh")
        .args([
            "-c",
            "ulimit -f 64; exec \"$0\" run \"$1\"",
            env!("CARGO_BIN_EXE_pipeline"),
        ])
        .arg(&config)
        .output()
        .expect("run under a file-size limit");
    assert!(!output.status.success());
    assert!(
        before == fs::read(dir.join("out.rdm")).unwrap(),
        "the previous output changed"
    );
    run_ok(&config, "2");
    assert!(
        before != fs::read(dir.join("out.rdm")).unwrap(),
        "the new run did not replace it"
    );
}

/// The input's triangles with every corner on `grid`, without the ones that collapse.
fn quantized_triangles(mesh: &reducem::mesh::Mesh, grid: &Grid) -> Vec<[[u32; 3]; 3]> {
    canonical_sorted(
        mesh.triangles
            .iter()
            .map(|t| {
                mesh.triangle_points(t)
                    .map(|p| grid.decode(&grid.quantize(&p)))
            })
            .filter(|[a, b, c]| !reducem::geometry::is_degenerate(a, b, c)),
    )
}

#[test]
fn a_quantized_chunked_conversion_decodes_to_the_quantized_input_for_any_thread_count() {
    let dir = temp_dir("grid");
    let config = job(&dir, "\n[vertices]\nencoding = \"grid\"\ngrid_bits = 16\n");
    run_ok(&config, "2");
    let file = ReducemFile::open(&dir.join("out.rdm")).expect("open");
    let mesh = reducem::input::read_mesh(&dir.join("input.ply")).expect("input");
    let grid = Grid::over(&mesh.bounds(), 16);
    assert_eq!(file.precision().grid(), grid);
    assert_eq!(
        canonical_sorted(reducem::decode::triangles(&file)),
        quantized_triangles(&mesh, &grid)
    );
    assert!(file.precision().error_max <= grid.cell as f64);
    let two = fs::read(dir.join("out.rdm")).unwrap();
    fs::remove_dir_all(dir.join("job.work")).unwrap();
    run_ok(&config, "1");
    assert!(
        two == fs::read(dir.join("out.rdm")).unwrap(),
        "outputs differ"
    );
}

#[test]
fn vertex_options_rerun_only_the_stages_they_affect() {
    let dir = temp_dir("vertex-options");
    run_ok(&job(&dir, ""), "2");
    let config = job(&dir, "\n[vertices]\nencoding = \"grid\"\ngrid_bits = 18\n");
    let text =
        String::from_utf8_lossy(&run(&["status", config.to_str().unwrap()]).stdout).to_string();
    assert!(text.contains("chunk                done"), "{text}");
    assert!(
        text.contains("strip/chunk-000000   stale: vertices.grid_bits changed from none to 18"),
        "{text}"
    );
    let log = String::from_utf8_lossy(&run_ok(&config, "2").stderr).to_string();
    assert!(log.contains("chunk: fresh"), "{log}");

    let config = job(
        &dir,
        "\n[vertices]\nencoding = \"grid\"\ngrid_bits = 18\nweld_tolerance = 0.001\n",
    );
    let text =
        String::from_utf8_lossy(&run(&["status", config.to_str().unwrap()]).stdout).to_string();
    assert!(
        text.contains(
            "chunk                stale: vertices.weld_tolerance changed from 0 to 0.001"
        ),
        "{text}"
    );
}

/// A binary little-endian PLY of `mesh`.
fn write_ply(mesh: &reducem::mesh::Mesh, path: &Path) {
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )
    .into_bytes();
    bytes.extend(
        mesh.positions
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes()),
    );
    for triangle in &mesh.triangles {
        bytes.push(3);
        bytes.extend(triangle.iter().flat_map(|&v| (v as i32).to_le_bytes()));
    }
    fs::write(path, bytes).expect("write PLY");
}

/// A 60 × 50 quad grid whose every triangle has its own copies of its corners, each moved by
/// up to 1e-5 per axis: shared vertices perturbed as in separately exported parts.
fn perturbed_grid() -> reducem::mesh::Mesh {
    let mut mesh = reducem::mesh::Mesh::default();
    let id = |x: u32, y: u32| y * 61 + x;
    for y in 0..=50 {
        for x in 0..=60 {
            mesh.positions.push([x as f32, y as f32, 0.0]);
        }
    }
    for y in 0..50 {
        for x in 0..60 {
            mesh.triangles
                .push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
            mesh.triangles
                .push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
        }
    }
    reducem_gen::perturbed_copies(&mesh, 1e-5, 3)
}

#[test]
fn a_weld_tolerance_reconnects_a_perturbed_model_across_chunks() {
    let dir = temp_dir("weld");
    let perturbed = perturbed_grid();
    write_ply(&perturbed, &dir.join("perturbed.ply"));
    let config = dir.join("weld.toml");
    let body = |tolerance: &str| {
        format!(
            "[input]\npath = \"perturbed.ply\"\n[output]\npath = \"out.rdm\"\n[chunk]\n\
             max_triangles = 1500\n[vertices]\nweld_tolerance = {tolerance}\n"
        )
    };
    fs::write(&config, body("0")).unwrap();
    run_ok(&config, "2");
    let apart = ReducemFile::open(&dir.join("out.rdm")).expect("open");
    assert_eq!(apart.header().strip_count, 6000);

    fs::write(&config, body("1e-4")).unwrap();
    run_ok(&config, "2");
    let file = ReducemFile::open(&dir.join("out.rdm")).expect("open");
    let (welded, stats) = reducem::input::weld_within_tolerance(perturbed, 1e-4);
    assert_eq!(welded.positions.len(), 61 * 51);
    assert_eq!(
        canonical_sorted(reducem::decode::triangles(&file)),
        canonical_sorted(welded.triangles.iter().map(|t| welded.triangle_points(t)))
    );
    let precision = file.precision();
    assert_eq!(precision.weld_tolerance, 1e-4);
    assert_eq!(precision.welded_vertex_count, stats.displacement.count);
    assert_eq!(precision.weld_displacement_max, stats.displacement.max);
    assert!(
        file.header().strip_count < 6000 / 5,
        "{} strips",
        file.header().strip_count
    );
}

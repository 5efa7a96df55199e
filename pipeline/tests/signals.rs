//! Signals, locks and leftovers: SIGINT and SIGTERM end a run at its next safe point with the
//! documented exit code and words, and the same command resumes to the same bytes; no
//! temporary outlives its process; a locked work directory can be waited for.

mod common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::temporaries;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-signals-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn command(config: &Path, extra: &[&str]) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_pipeline"));
    command
        .args(["run", config.to_str().unwrap(), "--log-format", "plain"])
        .args(extra)
        .env("RAYON_NUM_THREADS", "2");
    command
}

fn run_ok(config: &Path) -> String {
    let output = command(config, &[]).output().expect("run");
    let log = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{log}");
    log
}

/// A job on a generated scan of `triangles` in chunks of 8,000.
fn job(dir: &Path, triangles: u64) -> PathBuf {
    let config = dir.join("job.toml");
    let body = format!(
        "[input.generate]\nkind = \"scan\"\ntriangles = {triangles}\nseed = 9\n\n[output]\n\
         path = \"out.rdm\"\n\n[chunk]\nmax_triangles = 8000\n"
    );
    fs::write(&config, body).expect("config");
    config
}

fn send(child: &Child, signal: &str) {
    let sent = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(sent.success());
}

/// Waits (polling) until `ready` holds or `child` has exited.
fn wait_until(child: &mut Child, ready: impl Fn() -> bool) {
    while !ready() && child.try_wait().expect("poll").is_none() {
        std::thread::sleep(Duration::from_millis(1));
    }
}

fn any_file(dir: &Path, matches: impl Fn(&str) -> bool) -> bool {
    fs::read_dir(dir).is_ok_and(|entries| {
        entries
            .flatten()
            .any(|e| matches(&e.file_name().to_string_lossy()))
    })
}

#[test]
fn sigint_and_sigterm_end_each_stage_with_their_code_and_the_job_resumes_to_the_same_bytes() {
    let dir = temp_dir("stages");
    let config = job(&dir, 120_000);
    run_ok(&config);
    let reference = fs::read(dir.join("out.rdm")).expect("output");
    let work = dir.join("job.work");
    let in_chunk: &dyn Fn() -> bool =
        &|| any_file(&work.join("chunks"), |n| n.starts_with("spill-"));
    let in_strip: &dyn Fn() -> bool = &|| any_file(&work.join("strips"), |n| n.contains(".tmp-"));
    let in_write: &dyn Fn() -> bool = &|| {
        any_file(&dir, |n| {
            n.starts_with(".out.rdm.tmp-") || n.starts_with("..out.rdm")
        })
    };
    for (stage, ready) in [
        ("chunk", in_chunk),
        ("strip", in_strip),
        ("write", in_write),
    ] {
        for (signal, code) in [("INT", 130), ("TERM", 75)] {
            fs::remove_dir_all(&work).unwrap();
            fs::remove_file(dir.join("out.rdm")).unwrap();
            if stage == "write" {
                // Every stage before write done, so the signal finds the run writing.
                for before in ["chunk", "strip", "merge", "hierarchy"] {
                    let output = command(&config, &["--stage", before]).output().unwrap();
                    assert!(output.status.success());
                }
            }
            let mut child = command(&config, &[])
                .stderr(Stdio::piped())
                .spawn()
                .expect("spawn");
            wait_until(&mut child, ready);
            send(&child, signal);
            let output = child.wait_with_output().expect("wait");
            let log = String::from_utf8_lossy(&output.stderr);
            let finished_first = stage == "write" && output.status.success();
            if !finished_first {
                assert_eq!(output.status.code(), Some(code), "{stage} {signal}: {log}");
                assert!(
                    log.contains("interrupted; run the same command again to resume"),
                    "{stage} {signal}: {log}"
                );
            }
            assert_eq!(temporaries(&dir), Vec::<PathBuf>::new(), "{stage} {signal}");
            run_ok(&config);
            assert!(
                fs::read(dir.join("out.rdm")).unwrap() == reference,
                "{stage} {signal}: resumed output differs"
            );
        }
    }
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn a_run_removes_the_temporaries_of_dead_runs_and_only_those() {
    let dir = temp_dir("dead-temporaries");
    let config = job(&dir, 20_000);
    run_ok(&config);
    let reference = fs::read(dir.join("out.rdm")).expect("output");
    // Above the kernel's largest pid (2^22): no process has it.
    let dead = (1u32 << 22) + 11;
    let left = [
        dir.join(format!(".out.rdm.tmp-{dead}")),
        dir.join(format!("job.work/strips/.chunk-000001.strips.tmp-{dead}")),
        dir.join(format!("job.work/.manifest.json.tmp-{dead}")),
    ];
    let kept = [
        dir.join(format!(".notes.txt.tmp-{dead}")),
        dir.join(format!(".out.rdm.tmp-{}", std::process::id())),
    ];
    for path in left.iter().chain(&kept) {
        fs::write(path, vec![1u8; 1000]).unwrap();
    }
    let log = run_ok(&config);
    assert!(
        log.contains("removed 3 temporaries of killed runs (3000 bytes)"),
        "{log}"
    );
    assert!(left.iter().all(|path| !path.exists()));
    assert!(kept.iter().all(|path| path.exists()));
    assert!(fs::read(dir.join("out.rdm")).unwrap() == reference);
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn runs_killed_at_any_moment_leave_no_temporary_after_a_successful_rerun() {
    let dir = temp_dir("kill-loop");
    let config = job(&dir, 60_000);
    let started = Instant::now();
    run_ok(&config);
    let full = started.elapsed();
    let reference = fs::read(dir.join("out.rdm")).expect("output");
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for trial in 0..6 {
        fs::remove_dir_all(dir.join("job.work")).unwrap();
        for _kill in 0..3 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let mut child = command(&config, &[])
                .stderr(Stdio::null())
                .spawn()
                .expect("spawn");
            std::thread::sleep(full.mul_f64((state % 1000) as f64 / 1000.0));
            child.kill().expect("SIGKILL");
            child.wait().expect("reap");
        }
        run_ok(&config);
        assert_eq!(temporaries(&dir), Vec::<PathBuf>::new(), "trial {trial}");
        assert!(
            fs::read(dir.join("out.rdm")).unwrap() == reference,
            "trial {trial}"
        );
    }
    let _ = fs::remove_dir_all(&dir);
}

fn hold_lock(dir: &Path) -> fs::File {
    fs::create_dir_all(dir.join("job.work")).unwrap();
    fs::write(dir.join("job.work/pipeline-work-dir"), "").unwrap();
    fs::write(
        dir.join("job.work/lock"),
        "pid 4242 on host testhost since 1970-01-01T00:00:01Z\n",
    )
    .unwrap();
    let holder = fs::File::options()
        .write(true)
        .open(dir.join("job.work/lock"))
        .unwrap();
    holder.try_lock().expect("test takes the lock");
    holder
}

#[test]
fn if_locked_wait_queues_behind_the_holder_or_gives_up_after_its_seconds() {
    let dir = temp_dir("wait");
    let config = job(&dir, 20_000);
    let holder = hold_lock(&dir);
    let gave_up = command(&config, &["--if-locked", "wait=1"])
        .output()
        .expect("run");
    let log = String::from_utf8_lossy(&gave_up.stderr);
    assert_eq!(gave_up.status.code(), Some(75), "{log}");
    assert!(
        log.contains("waiting for it (--if-locked wait)")
            && log.contains("gave up after waiting 1 s: work directory")
            && log.contains("pid 4242 on host testhost"),
        "{log}"
    );
    let waiting = command(&config, &["--if-locked", "wait"])
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    std::thread::sleep(Duration::from_millis(1500));
    drop(holder);
    let output = waiting.wait_with_output().expect("wait");
    let log = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{log}");
    assert!(log.contains("waiting for it"), "{log}");
    assert!(dir.join("out.rdm").exists());
    let refused = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", config.to_str().unwrap(), "--if-locked", "wait=soon"])
        .output()
        .expect("run");
    assert_eq!(refused.status.code(), Some(64));
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn a_mesh_without_triangles_is_bad_input_naming_the_file() {
    let dir = temp_dir("no-triangles");
    fs::write(dir.join("empty.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    let config = dir.join("job.toml");
    fs::write(
        &config,
        "[input]\npath = \"empty.obj\"\n[output]\npath = \"out.rdm\"\n",
    )
    .unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", config.to_str().unwrap()])
        .output()
        .expect("run");
    let log = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(65), "{log}");
    assert!(
        log.contains("empty.obj: the mesh has no triangles, so there is nothing to convert"),
        "{log}"
    );
    assert!(!dir.join("out.rdm").exists());
    let _ = fs::remove_dir_all(&dir);
}

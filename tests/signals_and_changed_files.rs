//! `reducem` ending on a signal or a changed file: SIGINT during a query removes its temporary
//! hit file, and a model truncated while a query reads it ends the query with exit code 74 and
//! a message naming the file, not a bare SIGBUS.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use common::*;
use reducem::trace::ray_file::encode_rays;

/// A torus model and a ray file of `count` rays through it, in a directory of their own.
fn model_and_rays(name: &str, count: usize) -> (PathBuf, PathBuf) {
    let dir = temp_path(name);
    std::fs::create_dir_all(&dir).expect("dir");
    let mesh = torus(300, 150);
    let model = dir.join("model.rdm");
    write_strips(&mesh, &long_strips(&mesh, 40), 2, &model);
    let mut rng = SplitMix64::new(5);
    let rays: Vec<_> = (0..count)
        .map(|_| {
            let origin = [rng.range(-6.0, 6.0), rng.range(-6.0, 6.0), 4.0];
            let target = [rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), 0.0];
            ray_towards(origin, target)
        })
        .collect();
    let ray_path = dir.join("rays.bin");
    std::fs::write(&ray_path, encode_rays(&rays)).expect("rays");
    (model, ray_path)
}

fn query(model: &Path, rays: &Path, hits: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_reducem"))
        .arg("query")
        .arg(model)
        .arg("--rays")
        .arg(rays)
        .arg("-o")
        .arg(hits)
        .env("RAYON_NUM_THREADS", "2")
        .stderr(Stdio::piped())
        .spawn()
        .expect("run reducem")
}

/// The temporaries (`.NAME.tmp-PID`) in `dir`.
fn temporaries(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .expect("list")
        .flatten()
        .map(|entry| entry.path())
        .filter(|path| path.to_string_lossy().contains(".tmp-"))
        .collect()
}

/// Waits until the query has opened `model` and created its temporary hit file. The model is
/// looked for in the process's mappings first: the empty temporary that checks the output's
/// directory is gone before the model is opened, so a temporary seen after the mapping is the
/// hit file.
fn wait_for_temporary(child: &mut Child, dir: &Path, model: &Path) {
    let model = model.canonicalize().expect("model");
    let maps = format!("/proc/{}/maps", child.id());
    let mapped =
        || std::fs::read_to_string(&maps).is_ok_and(|text| text.contains(model.to_str().unwrap()));
    while !mapped() || temporaries(dir).is_empty() {
        assert!(child.try_wait().expect("poll").is_none(), "ended early");
        std::thread::sleep(Duration::from_millis(1));
    }
}

#[test]
fn sigint_during_a_query_removes_its_temporary_hit_file() {
    use std::os::unix::process::ExitStatusExt;
    let (model, rays) = model_and_rays("sigint-query", 2_000_000);
    let dir = model.parent().unwrap();
    let mut child = query(&model, &rays, &dir.join("hits.bin"));
    wait_for_temporary(&mut child, dir, &model);
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(sent.success());
    let output = child.wait_with_output().expect("wait");
    assert_eq!(output.status.signal(), Some(2), "{output:?}");
    assert_eq!(temporaries(dir), Vec::<PathBuf>::new());
    assert!(!dir.join("hits.bin").exists());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_model_truncated_during_a_query_ends_it_with_74_naming_the_file() {
    let (model, rays) = model_and_rays("truncated-query", 2_000_000);
    let dir = model.parent().unwrap();
    let mut child = query(&model, &rays, &dir.join("hits.bin"));
    wait_for_temporary(&mut child, dir, &model);
    std::fs::OpenOptions::new()
        .write(true)
        .open(&model)
        .and_then(|file| file.set_len(4096))
        .expect("truncate");
    let output = child.wait_with_output().expect("wait");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(74), "{stderr}");
    let canonical = model.canonicalize().expect("model");
    let expected = format!(
        "reducem: error: {} changed while it was mapped (truncated or rewritten in place by \
         another process); files are replaced by rename, never modified in place",
        canonical.display()
    );
    assert!(stderr.contains(&expected), "{stderr}");
    let _ = std::fs::remove_dir_all(dir);
}

/// Overwrites 64 KiB at pseudo-random places of `path`, in place, until `stop`.
fn overwrite_in_place(path: &Path, seed: u64, stop: &std::sync::atomic::AtomicBool) {
    use std::os::unix::fs::FileExt;
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .expect("open");
    let length = file.metadata().expect("size").len();
    let mut rng = SplitMix64::new(seed);
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        let block: Vec<u8> = (0..1 << 16).map(|_| rng.next_u64() as u8).collect();
        let at = rng.next_u64() % length.saturating_sub(1 << 16).max(1);
        file.write_all_at(&block, at).expect("overwrite");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// A file changed in place under a query may give wrong answers, or an error, but the query
/// ends: no panic, no crash, no walk in circles.
#[test]
fn a_model_overwritten_during_queries_never_panics_or_hangs() {
    use std::os::unix::process::ExitStatusExt;
    let (model, rays) = model_and_rays("overwritten-query", 300_000);
    let pristine = std::fs::read(&model).expect("model");
    let dir = model.parent().unwrap();
    for trial in 0..6 {
        std::fs::write(&model, &pristine).expect("restore");
        let mut child = query(&model, &rays, &dir.join("hits.bin"));
        let stop = std::sync::atomic::AtomicBool::new(false);
        let status = std::thread::scope(|scope| {
            scope.spawn(|| overwrite_in_place(&model, trial, &stop));
            // Far beyond the query's time (well under a second): only a walk in circles
            // reaches it.
            let deadline = std::time::Instant::now() + Duration::from_secs(120);
            let status = loop {
                if let Some(status) = child.try_wait().expect("poll") {
                    break Some(status);
                }
                if std::time::Instant::now() > deadline {
                    child.kill().expect("kill");
                    break None;
                }
                std::thread::sleep(Duration::from_millis(10));
            };
            stop.store(true, std::sync::atomic::Ordering::Relaxed);
            status
        });
        let output = child.wait_with_output().expect("reap");
        let stderr = String::from_utf8_lossy(&output.stderr);
        let status = status.unwrap_or_else(|| panic!("trial {trial}: still running: {stderr}"));
        assert_eq!(status.signal(), None, "trial {trial}: {stderr}");
        assert_ne!(status.code(), Some(101), "trial {trial}: {stderr}");
        assert!(!stderr.contains("panicked"), "trial {trial}: {stderr}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

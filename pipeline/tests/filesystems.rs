//! Read-only and full filesystems: the run fails with exit code 74 and a message that names
//! the path once and the OS error once, and leaves no temporary. Each case mounts a small tmpfs
//! in a mount namespace of its own (`unshare`), and is skipped with a message where that is not
//! permitted.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pipeline-fs-{}-{name}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(dir.join("mnt")).expect("temp dir");
    dir
}

fn can_mount() -> bool {
    let probe = temp_dir("probe");
    let mounted = Command::new("unshare")
        .args([
            "-rm",
            "sh",
            "-c",
            "mount -t tmpfs tmpfs \"$0\"",
            probe.join("mnt").to_str().unwrap(),
        ])
        .output()
        .is_ok_and(|output| output.status.success());
    let _ = fs::remove_dir_all(&probe);
    if !mounted {
        eprintln!(
            "skipped: mounting a tmpfs in a mount namespace (unshare -rm) is not permitted here"
        );
    }
    mounted
}

/// Runs `script` (sh, with `$0` the mount point and `$1` the pipeline binary) in a mount
/// namespace where a tmpfs of `size` is mounted at `mount`.
fn in_namespace(mount: &Path, size: &str, script: &str) -> Output {
    let body = format!("mount -t tmpfs -o size={size} tmpfs \"$0\" && {script}");
    Command::new("unshare")
        .args(["-rm", "sh", "-c", &body])
        .arg(mount)
        .arg(env!("CARGO_BIN_EXE_pipeline"))
        .output()
        .expect("unshare")
}

const JOB: &str = "[input.generate]\nkind = \"scan\"\ntriangles = 20000\nseed = 3\n\n[output]\n\
                   path = \"out.rdm\"\n\n[chunk]\nmax_triangles = 4000\n";

fn assert_names_path_and_error_once(output: &Output, path: &str, error: &str) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(74), "{stderr}");
    assert!(stderr.contains(path), "{path} not named: {stderr}");
    assert_eq!(stderr.matches(error).count(), 1, "{stderr}");
}

#[test]
fn a_full_filesystem_fails_with_74_naming_the_file_and_leaves_no_temporary() {
    if !can_mount() {
        return;
    }
    let dir = temp_dir("full");
    let mount = dir.join("mnt");
    // The job's work files take about 1 MB: 300 KiB fills up in the chunk or strip stage.
    let script = format!(
        "printf '{}' > \"$0/job.toml\" && \"$1\" run \"$0/job.toml\" --log-format plain; \
         code=$?; ls -aR \"$0\" >&2; exit $code",
        JOB.replace('\n', "\\n")
    );
    let output = in_namespace(&mount, "300k", &script);
    assert_names_path_and_error_once(
        &output,
        &mount.display().to_string(),
        "No space left on device",
    );
    let listing = String::from_utf8_lossy(&output.stderr);
    assert!(
        !listing.contains(".tmp-"),
        "a temporary was left: {listing}"
    );
    let _ = fs::remove_dir_all(&dir);
}

#[test]
fn a_read_only_filesystem_fails_with_74_naming_the_path_for_run_and_clean() {
    if !can_mount() {
        return;
    }
    let dir = temp_dir("read-only");
    let mount = dir.join("mnt");
    // run fails at its first check, the output's directory; clean at the work directory's lock.
    for (command, path) in [
        ("run", mount.clone()),
        ("clean", mount.join("job.work/lock")),
    ] {
        let script = format!(
            "printf '{}' > \"$0/job.toml\" && mkdir -p \"$0/job.work\" && \
             touch \"$0/job.work/pipeline-work-dir\" && mount -o remount,ro \"$0\" && \
             exec \"$1\" {command} \"$0/job.toml\"",
            JOB.replace('\n', "\\n")
        );
        let output = in_namespace(&mount, "1m", &script);
        assert_names_path_and_error_once(
            &output,
            &path.display().to_string(),
            "Read-only file system",
        );
    }
    let _ = fs::remove_dir_all(&dir);
}

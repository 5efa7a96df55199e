//! A mapped file truncated by another process ends the process with exit code 74 and a message
//! naming the file, instead of a bare SIGBUS. The test runs itself again as the process that
//! maps, truncates and reads.

use std::process::Command;

const CHILD: &str = "MAPPED_FILE_TRUNCATED_CHILD";

#[test]
fn a_read_beyond_a_truncated_mapping_exits_74_naming_the_file() {
    if let Some(path) = std::env::var_os(CHILD) {
        read_after_truncation(std::path::Path::new(&path));
    }
    let dir = std::env::temp_dir().join(format!("mapped-truncated-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let path = dir.join("model.rdm");
    std::fs::write(&path, vec![7u8; 1 << 16]).expect("write");
    let child = Command::new(std::env::current_exe().expect("this test"))
        .args([
            "--exact",
            "a_read_beyond_a_truncated_mapping_exits_74_naming_the_file",
        ])
        .env(CHILD, &path)
        .output()
        .expect("run the child");
    let stderr = String::from_utf8_lossy(&child.stderr);
    assert_eq!(child.status.code(), Some(74), "{stderr}");
    let expected = format!(
        "error: {} changed while it was mapped (truncated or rewritten in place by another \
         process); files are replaced by rename, never modified in place",
        path.display()
    );
    assert!(stderr.contains(&expected), "{stderr}");
    std::fs::remove_dir_all(&dir).expect("remove");
}

/// Maps `path`, truncates it to one page and reads the last byte it had.
fn read_after_truncation(path: &std::path::Path) -> ! {
    reducem_core::signals::install_bus_handler().expect("handler");
    let file = std::fs::File::open(path).expect("open");
    let map = reducem_core::mapping::map_file(&file).expect("map");
    std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .and_then(|f| f.set_len(4096))
        .expect("truncate");
    let byte = std::hint::black_box(&map[..])[map.len() - 1];
    panic!("read {byte} beyond the end of a truncated file without a fault");
}

//! The facts a reader needs to judge the report's timings: machine, load, commit and date.
//!
//! Read from `/proc` and from `git` and `date` at the start of a run. A fact that cannot be read
//! is reported as "unknown" rather than failing the report: the measurements stay valid.

use std::process::Command;

use super::Scale;

#[derive(Clone, Debug, PartialEq)]
pub struct MachineFacts {
    pub cpu_model: String,
    pub cores: usize,
    pub memory_gib: Option<f64>,
    /// `/proc/loadavg`'s 1-minute figure at the start: other work on the machine slows timings.
    pub load_average: Option<f64>,
    pub commit: String,
    /// Whether the working tree differed from the commit.
    pub dirty: bool,
    pub date_utc: String,
    pub scale: Scale,
    pub embree: bool,
}

const UNKNOWN: &str = "unknown";

impl MachineFacts {
    pub fn read(scale: Scale) -> MachineFacts {
        let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        MachineFacts {
            cpu_model: field(&cpuinfo, "model name").unwrap_or_else(|| UNKNOWN.into()),
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            memory_gib: memory_gib(),
            load_average: load_average(),
            commit: command_output("git", &["rev-parse", "HEAD"]).unwrap_or_else(|| UNKNOWN.into()),
            dirty: command_output("git", &["status", "--porcelain", "--untracked-files=no"])
                .is_some_and(|s| !s.is_empty()),
            date_utc: command_output("date", &["-u", "+%Y-%m-%d %H:%M:%S UTC"])
                .unwrap_or_else(|| UNKNOWN.into()),
            scale,
            embree: cfg!(feature = "embree"),
        }
    }
}

/// The value of the first `key : value` line of a `/proc` file.
fn field(text: &str, key: &str) -> Option<String> {
    text.lines()
        .filter_map(|line| line.split_once(':'))
        .find(|(k, _)| k.trim() == key)
        .map(|(_, v)| v.trim().to_string())
}

fn memory_gib() -> Option<f64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: f64 = field(&meminfo, "MemTotal")?
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    Some(kib / (1024.0 * 1024.0))
}

fn load_average() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

fn command_output(program: &str, args: &[&str]) -> Option<String> {
    let output = Command::new(program).args(args).output().ok()?;
    output
        .status
        .success()
        .then(|| String::from_utf8_lossy(&output.stdout).trim().to_string())
}

//! How much of a mapped file is resident after a frame (paper section 5: memory footprint).
//!
//! Linux reports per-mapping resident memory in `/proc/self/smaps`; the mapping of the file is
//! found by its path, and the `Rss:` lines of every range mapping it are added. Process RSS comes
//! from `/proc/self/status` (`VmRSS`). Both are plain text reads, no `unsafe`; on systems without
//! `/proc` the numbers are absent rather than wrong.

use std::path::Path;

use serde::Serialize;

/// Memory of one render, in bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Residency {
    pub file_bytes: u64,
    /// Resident bytes of the file's mapping, if `/proc/self/smaps` could be read.
    pub mapped_resident_bytes: Option<u64>,
    /// Resident set of the whole process, if `/proc/self/status` could be read.
    pub process_rss_bytes: Option<u64>,
}

/// Measures the residency of the mapping of `path` now.
pub fn measure(path: &Path, file_bytes: u64) -> Residency {
    Residency {
        file_bytes,
        mapped_resident_bytes: mapping_rss(path),
        process_rss_bytes: process_rss(),
    }
}

/// Sum of `Rss:` over the mappings of `path` in this process.
pub fn mapping_rss(path: &Path) -> Option<u64> {
    let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
    let target = std::fs::canonicalize(path).ok()?;
    let target = target.to_str()?;
    let mut in_target = false;
    let mut total = 0;
    for line in smaps.lines() {
        if is_mapping_header(line) {
            in_target = line.ends_with(target) && mapped_path(line) == Some(target);
        } else if in_target {
            if let Some(kib) = kib_field(line, "Rss:") {
                total += kib * 1024;
            }
        }
    }
    Some(total)
}

/// `VmRSS` of this process.
pub fn process_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status
        .lines()
        .find_map(|line| kib_field(line, "VmRSS:"))
        .map(|kib| kib * 1024)
}

/// A mapping header starts with an address range `start-end`; field lines start with a name.
fn is_mapping_header(line: &str) -> bool {
    line.split_whitespace()
        .next()
        .and_then(|range| range.split_once('-'))
        .is_some_and(|(start, end)| {
            u64::from_str_radix(start, 16).is_ok() && u64::from_str_radix(end, 16).is_ok()
        })
}

/// The pathname column of a mapping header (the sixth field; paths may contain spaces).
fn mapped_path(header: &str) -> Option<&str> {
    let mut rest = header;
    for _ in 0..5 {
        rest = rest.trim_start();
        rest = &rest[rest.find(char::is_whitespace)?..];
    }
    Some(rest.trim())
}

fn kib_field(line: &str, name: &str) -> Option<u64> {
    let value = line.strip_prefix(name)?.trim();
    value.strip_suffix("kB")?.trim().parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_headers_and_fields() {
        let header = "7f00-7f10 r--s 00000000 08:01 1234    /tmp/a model.rdm";
        assert!(is_mapping_header(header));
        assert_eq!(mapped_path(header), Some("/tmp/a model.rdm"));
        assert!(!is_mapping_header("Rss:                 12 kB"));
        assert_eq!(kib_field("Rss:                 12 kB", "Rss:"), Some(12));
    }
}

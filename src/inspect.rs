//! Statistics of a ReduceM file, as `reducem inspect` prints them.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::format::reader::ReducemFile;
use crate::format::{SectionKind, HEADER_PAGE};
use crate::strip;

/// What `reducem inspect --json` prints. Field names are a contract with other tools.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FileStats {
    pub format_version: String,
    pub vertex_encoding: String,
    pub triangles: u64,
    pub dropped_triangles: u64,
    pub strips: u64,
    pub input_vertices: u64,
    pub stored_vertices: u64,
    /// Stored copies that exist only to encode the strip hierarchies.
    pub hierarchy_vertices: u64,
    /// Top-level nodes (4-wide, 128 bytes each since format 2).
    pub top_nodes: u64,
    pub leaf_triangles: u32,
    pub file_bytes: u64,
    pub bytes_per_triangle: f64,
    /// Section name → bytes; includes the header page and inter-section padding, so the values
    /// sum to `file_bytes`.
    pub bytes_by_section: BTreeMap<String, u64>,
    /// Hierarchy vertices as % of input vertices (the paper's Table 1 metric).
    pub hierarchy_overhead_pct: f64,
    pub avg_strip_length: f64,
    pub max_strip_length: u64,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
}

/// Gathers the statistics; walks every strip once for the length figures.
pub fn file_stats(file: &ReducemFile) -> FileStats {
    let header = file.header();
    let lengths =
        (0..file.strip_count()).map(|s| strip::triangles(file.strip(s).references).count() as u64);
    let max_strip_length = lengths.max().unwrap_or(0);
    let mut bytes_by_section = BTreeMap::new();
    bytes_by_section.insert("header".to_string(), HEADER_PAGE);
    let mut section_total = HEADER_PAGE;
    for kind in SectionKind::ALL {
        let bytes = file.section_bytes(kind).len() as u64;
        bytes_by_section.insert(kind.name().to_string(), bytes);
        section_total += bytes;
    }
    bytes_by_section.insert("padding".to_string(), file.file_bytes() - section_total);
    FileStats {
        format_version: format!("{}.{}", header.version_major, header.version_minor),
        vertex_encoding: "f32".into(),
        triangles: header.triangle_count,
        dropped_triangles: header.dropped_triangle_count,
        strips: header.strip_count,
        input_vertices: header.input_vertex_count,
        stored_vertices: header.stored_vertex_count,
        hierarchy_vertices: header.hierarchy_vertex_count,
        top_nodes: file.top_nodes().len() as u64,
        leaf_triangles: header.leaf_windows,
        file_bytes: file.file_bytes(),
        bytes_per_triangle: ratio(file.file_bytes(), header.triangle_count),
        bytes_by_section,
        hierarchy_overhead_pct: 100.0
            * ratio(header.hierarchy_vertex_count, header.input_vertex_count),
        avg_strip_length: ratio(header.triangle_count, header.strip_count),
        max_strip_length,
        bounds_min: header.bounds_min,
        bounds_max: header.bounds_max,
    }
}

fn ratio(numerator: u64, denominator: u64) -> f64 {
    if denominator == 0 {
        0.0
    } else {
        numerator as f64 / denominator as f64
    }
}

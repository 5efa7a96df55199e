//! Statistics of a ReduceM file, as `reducem inspect` prints them.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::format::attributes::AttributeSection;
use crate::format::reader::{ReducemFile, TopNodes};
use crate::format::{
    GridNode, SectionKind, TopNode, VertexEncoding, WideNode, HEADER_PAGE, TOP_WIDTH, WIDE_WIDTH,
};
use crate::geometry::distance;

/// What `reducem inspect --json` prints. Field names are a contract with other tools.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FileStats {
    pub format_version: String,
    pub vertex_encoding: String,
    /// The header's `vertex_encoding` value (5: grid vertices in shared pools, format 4.1).
    pub vertex_encoding_value: u32,
    pub triangles: u64,
    pub dropped_triangles: u64,
    pub strips: u64,
    pub input_vertices: u64,
    /// Vertices stored over all strips; in pooled grid files the pools' points, counted from
    /// the pools (the header of an earlier 4.1 writer's file counts the strips' views instead).
    pub stored_vertices: u64,
    /// Stored copies that exist only to encode the strip hierarchies.
    pub hierarchy_vertices: u64,
    /// Top-level nodes.
    pub top_nodes: u64,
    /// Child slots per top-level node: 8 since format 4, 4 before.
    pub top_node_width: u64,
    /// Bytes per top-level node: 96 since format 4; before, 128 for f32 boxes and 64 for grid
    /// nodes (grid files, and lossless files since format 2.4).
    pub top_node_bytes: u64,
    /// Windows per leaf of the strips' kd-trees (`[strip] leaf_windows`).
    pub leaf_windows: u32,
    /// The same value under its name before the rename, kept for tools that read it.
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
    /// Length of the bounds' diagonal: what the relative errors are relative to.
    pub bounds_diagonal: f64,
    /// Bits per axis of the vertex grid; 0 for f32 vertices.
    pub grid_bits: u32,
    /// Grid step (the same on every axis); 0 for f32 vertices.
    pub grid_cell: f32,
    /// Largest and root mean square distance from an input vertex (after welding) to where the
    /// file stores it, absolute and over [`FileStats::bounds_diagonal`]; 0 for f32 vertices.
    pub position_error_max: f64,
    pub position_error_rms: f64,
    pub position_error_max_relative: f64,
    pub position_error_rms_relative: f64,
    /// Input vertices closer than this were merged before conversion; 0: bit-identical only.
    pub weld_tolerance: f32,
    /// Input vertices merged into another by the tolerance, and how far they moved.
    pub welded_vertices: u64,
    pub weld_displacement_max: f64,
    pub weld_displacement_rms: f64,
    /// The attributes stored besides positions (format 2.5): whether face ids are, the normal
    /// encoding (`none`, `oct8`, `oct16`), whether colours are.
    pub face_ids: bool,
    pub normals: String,
    pub colors: bool,
    /// Largest angle between an input normal and its stored code, in degrees; 0 without
    /// normals.
    pub normal_error_max_degrees: f64,
    /// Every edge has exactly two triangles running it in opposite directions (format 3.1);
    /// false when unknown.
    pub closed: bool,
    /// Edges used by one triangle, and by more than two or two in one direction; `null` when
    /// the file does not say (before 3.1, or a conversion of several chunks).
    pub boundary_edges: Option<u64>,
    pub nonmanifold_edges: Option<u64>,
    /// The up-axis hint, `"y"` or `"z"`; `null` when unknown.
    pub up: Option<&'static str>,
}

/// Gathers the statistics; walks every strip once for the length figures.
pub fn file_stats(file: &ReducemFile) -> FileStats {
    let header = file.header();
    let lengths = (0..file.strip_count()).map(|s| file.strip(s).triangles().len() as u64);
    let max_strip_length = lengths.max().unwrap_or(0);
    let mut bytes_by_section = BTreeMap::new();
    bytes_by_section.insert("header".to_string(), HEADER_PAGE);
    let mut section_total = HEADER_PAGE;
    for kind in SectionKind::ALL {
        let bytes = file.section_bytes(kind).len() as u64;
        bytes_by_section.insert(kind.name().to_string(), bytes);
        section_total += bytes;
    }
    let attributes = file.attributes();
    for kind in AttributeSection::ALL
        .into_iter()
        .filter(|&k| attributes.has(k))
    {
        let bytes = file.attribute_bytes(kind).len() as u64;
        bytes_by_section.insert(kind.name().to_string(), bytes);
        section_total += bytes;
    }
    bytes_by_section.insert("padding".to_string(), file.file_bytes() - section_total);
    let precision = file.precision();
    let diagonal = match header.triangle_count {
        0 => 0.0,
        _ => distance(&header.bounds_min, &header.bounds_max),
    };
    let encoding = VertexEncoding::from_u32(header.vertex_encoding).unwrap_or(VertexEncoding::F32);
    FileStats {
        format_version: format!("{}.{}", header.version_major, header.version_minor),
        vertex_encoding: encoding.name().into(),
        vertex_encoding_value: header.vertex_encoding,
        triangles: header.triangle_count,
        dropped_triangles: header.dropped_triangle_count,
        strips: header.strip_count,
        input_vertices: header.input_vertex_count,
        stored_vertices: file.pool_points().unwrap_or(header.stored_vertex_count),
        hierarchy_vertices: header.hierarchy_vertex_count,
        top_nodes: file.top_nodes().len() as u64,
        top_node_width: match file.top_nodes() {
            TopNodes::F32(_) | TopNodes::Grid(..) => TOP_WIDTH as u64,
            TopNodes::Wide(_) => WIDE_WIDTH as u64,
        },
        top_node_bytes: match file.top_nodes() {
            TopNodes::F32(_) => size_of::<TopNode>() as u64,
            TopNodes::Grid(..) => size_of::<GridNode>() as u64,
            TopNodes::Wide(_) => size_of::<WideNode>() as u64,
        },
        leaf_windows: header.leaf_windows,
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
        bounds_diagonal: diagonal,
        grid_bits: precision.grid_bits,
        grid_cell: precision.grid_cell,
        position_error_max: precision.error_max,
        position_error_rms: precision.error_rms,
        position_error_max_relative: relative(precision.error_max, diagonal),
        position_error_rms_relative: relative(precision.error_rms, diagonal),
        weld_tolerance: precision.weld_tolerance,
        welded_vertices: precision.welded_vertex_count,
        weld_displacement_max: precision.weld_displacement_max,
        weld_displacement_rms: precision.weld_displacement_rms,
        face_ids: attributes.face_ids,
        normals: attributes.normals.name().to_string(),
        colors: attributes.colors,
        normal_error_max_degrees: file.attribute_record().normal_error_max_degrees,
        closed: file.closed(),
        boundary_edges: file.closedness().map(|c| c.boundary_edges),
        nonmanifold_edges: file.closedness().map(|c| c.nonmanifold_edges),
        up: file.up_axis().map(|up| up.name()),
    }
}

/// The text `inspect` prints for closedness and the up axis.
pub fn model_line(stats: &FileStats) -> String {
    let edges = match (stats.boundary_edges, stats.nonmanifold_edges) {
        (Some(boundary), Some(nonmanifold)) => format!(
            "{}: {boundary} boundary edges, {nonmanifold} non-manifold edges",
            if stats.closed { "closed" } else { "not closed" }
        ),
        _ => "closedness unknown".to_string(),
    };
    format!("{edges}; up {}", stats.up.unwrap_or("unknown"))
}

fn relative(error: f64, diagonal: f64) -> f64 {
    if diagonal > 0.0 {
        error / diagonal
    } else {
        0.0
    }
}

fn ratio(numerator: u64, denominator: u64) -> f64 {
    if denominator == 0 {
        0.0
    } else {
        numerator as f64 / denominator as f64
    }
}

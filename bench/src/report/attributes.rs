//! Section 8: what attributes cost (format 2.5). The sweep mesh is given per-vertex normals and
//! colours made from its own geometry ([`with_synthetic_attributes`]) and converted without
//! attributes and with face ids, normals (oct8, then oct16) and colours. Bytes come from each
//! written file's attribute sections; speed from the sweep's rays, the same for every file:
//! primary and AO rays (which never read attributes, so they should not slow down) and the
//! primary rays traced as `reducem query` does, writing the compact record (t and normal) or
//! the full one (which reads every final hit's face id, normal and colour).

use std::path::Path;
use std::time::Instant;

use super::markdown::{Section, Table};
use super::speed::{self, Speed};
use super::sweeps::Subject;
use super::Sizes;
use crate::workload::convert_timed;
use crate::workload::engines::ReduceM;
use reducem::conversion::BuildParams;
use reducem::format::attributes::{AttributeSection, AttributeSet, NormalEncoding};
use reducem::format::reader::ReducemFile;
use reducem::format::SECTION_ALIGN;
use reducem::inspect::FileStats;
use reducem::mesh::Mesh;
use reducem::trace::ray_file::{trace_hits_as, HitFormat};
use reducem::trace::{TraceOptions, Tracer};

/// The attribute sets converted: none, then everything with each normal encoding.
pub const VARIANTS: [AttributeSet; 3] = [
    AttributeSet {
        face_ids: false,
        normals: NormalEncoding::None,
        colors: false,
    },
    AttributeSet {
        face_ids: true,
        normals: NormalEncoding::Oct8,
        colors: true,
    },
    AttributeSet {
        face_ids: true,
        normals: NormalEncoding::Oct16,
        colors: true,
    },
];

/// One converted file: its attribute sections' sizes and its speed.
#[derive(Clone, Debug, PartialEq)]
pub struct AttributeRow {
    pub attributes: AttributeSet,
    pub stats: FileStats,
    /// Bytes of every attribute section the file has, in file order.
    pub section_bytes: Vec<(AttributeSection, u64)>,
    pub speed: Speed,
    /// Primary rays traced and written as `reducem query` does, compact records.
    pub query_compact_mrays: f64,
    /// The same with `--format full` records, which read each hit's attributes.
    pub query_full_mrays: f64,
}

impl AttributeRow {
    /// Bytes of section `kind`, 0 when the file lacks it.
    pub fn bytes(&self, kind: AttributeSection) -> u64 {
        self.section_bytes
            .iter()
            .find(|(k, _)| *k == kind)
            .map_or(0, |&(_, bytes)| bytes)
    }

    pub fn per_triangle(&self, bytes: u64) -> f64 {
        bytes as f64 / self.stats.triangles.max(1) as f64
    }

    /// Stored vertices, each with one colour.
    pub fn colored_vertices(&self) -> u64 {
        self.bytes(AttributeSection::Colors) / 4
    }
}

/// `mesh` with per-vertex normals, the area-weighted average of the faces around each vertex,
/// and colours that run with the position across the bounds (red along x, green along y, blue
/// along z): what a scan's normals and colours look like to the encoders.
pub fn with_synthetic_attributes(mesh: &Mesh) -> Mesh {
    let mut sums = vec![[0.0f64; 3]; mesh.positions.len()];
    for triangle in &mesh.triangles {
        let [a, b, c] = triangle.map(|v| mesh.positions[v as usize].map(f64::from));
        let (ab, ac) = (sub(b, a), sub(c, a));
        // The cross product's length is twice the area: the sum weights faces by area.
        let normal = [
            ab[1] * ac[2] - ab[2] * ac[1],
            ab[2] * ac[0] - ab[0] * ac[2],
            ab[0] * ac[1] - ab[1] * ac[0],
        ];
        for &vertex in triangle {
            let sum = &mut sums[vertex as usize];
            *sum = std::array::from_fn(|axis| sum[axis] + normal[axis]);
        }
    }
    let normals = sums
        .iter()
        .map(|sum| {
            let length = sum.iter().map(|c| c * c).sum::<f64>().sqrt();
            match length > 0.0 {
                true => sum.map(|c| (c / length) as f32),
                false => [0.0, 0.0, 1.0],
            }
        })
        .collect();
    let bounds = mesh.bounds();
    let colors = mesh
        .positions
        .iter()
        .map(|p| {
            let channel = |axis: usize| {
                let extent = (bounds.max[axis] - bounds.min[axis]).max(f32::MIN_POSITIVE);
                ((p[axis] - bounds.min[axis]) / extent * 255.0).round() as u8
            };
            [channel(0), channel(1), channel(2), 255]
        })
        .collect();
    Mesh {
        normals: Some(normals),
        colors: Some(colors),
        ..mesh.clone()
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|axis| a[axis] - b[axis])
}

/// Converts the sweep mesh with every [`VARIANTS`] set and measures each file.
pub fn collect(subject: &Subject, work: &Path, sizes: &Sizes) -> anyhow::Result<Vec<AttributeRow>> {
    let mesh = with_synthetic_attributes(&subject.mesh);
    VARIANTS
        .iter()
        .map(|&attributes| {
            let params = BuildParams {
                attributes,
                ..BuildParams::default()
            };
            let converted = convert_timed(&mesh, &params, work, "attributes", 1)?;
            let file = ReducemFile::open(&converted.path)?;
            let section_bytes = AttributeSection::ALL
                .into_iter()
                .filter(|&kind| attributes.has(kind))
                .map(|kind| (kind, file.attribute_bytes(kind).len() as u64))
                .collect();
            let engine = ReduceM(Tracer::new(&file, TraceOptions::default()));
            let speed = speed::measure(&engine, &subject.rays, sizes.runs, sizes.min_trace_seconds);
            let query = |format| query_mrays(&engine.0, subject, format, sizes);
            Ok(AttributeRow {
                attributes,
                stats: converted.stats,
                section_bytes,
                speed,
                query_compact_mrays: query(HitFormat::Compact),
                query_full_mrays: query(HitFormat::Full),
            })
        })
        .collect()
}

/// Median Mrays/s of tracing the primary rays and writing their hit records in `format`.
fn query_mrays(tracer: &Tracer, subject: &Subject, format: HitFormat, sizes: &Sizes) -> f64 {
    let rays = &subject.rays.primary;
    let mut rates: Vec<f64> = (0..sizes.runs.max(1))
        .map(|_| {
            let started = Instant::now();
            let mut passes = 0;
            while passes == 0 || started.elapsed().as_secs_f64() < sizes.min_trace_seconds {
                std::hint::black_box(trace_hits_as(tracer, rays, format));
                passes += 1;
            }
            let seconds = started.elapsed().as_secs_f64().max(1e-9);
            (rays.len() * passes) as f64 / seconds / 1e6
        })
        .collect();
    rates.sort_by(f64::total_cmp);
    rates[rates.len() / 2]
}

/// `[attributes]` as a config would say it.
pub fn label(set: &AttributeSet) -> String {
    let mut parts = Vec::new();
    if set.face_ids {
        parts.push("face ids".to_string());
    }
    if set.normals != NormalEncoding::None {
        parts.push(format!("{} normals", set.normals.name()));
    }
    if set.colors {
        parts.push("colours".to_string());
    }
    match parts.is_empty() {
        true => "none".to_string(),
        false => parts.join(" + "),
    }
}

/// The row storing `normals` (with face ids and colours, unless `None`: nothing).
fn with_normals(rows: &[AttributeRow], normals: NormalEncoding) -> Option<&AttributeRow> {
    rows.iter().find(|r| r.attributes.normals == normals)
}

pub fn section(rows: &[AttributeRow]) -> anyhow::Result<Section> {
    let plain = with_normals(rows, NormalEncoding::None).ok_or_else(|| {
        anyhow::anyhow!("no row without attributes in the attribute measurements")
    })?;
    let oct16 = with_normals(rows, NormalEncoding::Oct16)
        .ok_or_else(|| anyhow::anyhow!("no oct16 row in the attribute measurements"))?;
    let oct8 = with_normals(rows, NormalEncoding::Oct8)
        .ok_or_else(|| anyhow::anyhow!("no oct8 row in the attribute measurements"))?;
    let mut cost = Table::new(vec![
        "attribute",
        "sections",
        "bytes",
        "B/tri",
        "B/stored vertex",
    ]);
    let vertices = oct16.colored_vertices().max(1) as f64;
    let mut push = |name: &str, row: &AttributeRow, kinds: &[AttributeSection], per_vertex| {
        let bytes: u64 = kinds.iter().map(|&kind| row.bytes(kind)).sum();
        let names: Vec<&str> = kinds.iter().map(|kind| kind.name()).collect();
        cost.push(vec![
            name.to_string(),
            names.join(" + "),
            bytes.to_string(),
            format!("{:.3}", row.per_triangle(bytes)),
            match per_vertex {
                true => format!("{:.2}", bytes as f64 / vertices),
                false => "—".to_string(),
            },
        ]);
    };
    let face_ids = [AttributeSection::FaceIds, AttributeSection::FaceIdGroups];
    push("face ids", oct16, &face_ids, false);
    push("normals, oct8", oct8, &[AttributeSection::Normals], true);
    push("normals, oct16", oct16, &[AttributeSection::Normals], true);
    push("colours", oct16, &[AttributeSection::Colors], true);
    push(
        "per-vertex index",
        oct16,
        &[AttributeSection::VertexGroups],
        false,
    );
    let sections: u64 = oct16.section_bytes.iter().map(|&(_, bytes)| bytes).sum();
    let growth = oct16
        .stats
        .file_bytes
        .saturating_sub(plain.stats.file_bytes);
    let padding = growth.saturating_sub(sections);
    cost.push(vec![
        "alignment padding".to_string(),
        format!("up to {SECTION_ALIGN} per section"),
        padding.to_string(),
        format!("{:.3}", oct16.per_triangle(padding)),
        "—".to_string(),
    ]);
    cost.push(vec![
        format!("all: {}", label(&oct16.attributes)),
        "file growth".to_string(),
        growth.to_string(),
        format!("{:.3}", oct16.per_triangle(growth)),
        "—".to_string(),
    ]);

    let mut speed = Table::new(vec![
        "attributes",
        "file B/tri",
        "primary Mrays/s",
        "AO Mrays/s",
        "query Mrays/s",
        "query --format full Mrays/s",
        "primary hits",
        "AO occluded",
    ]);
    for r in rows {
        speed.push(vec![
            label(&r.attributes),
            format!("{:.2}", r.stats.bytes_per_triangle),
            format!("{:.2}", r.speed.primary_mrays),
            format!("{:.2}", r.speed.ao_mrays),
            format!("{:.2}", r.query_compact_mrays),
            format!("{:.2}", r.query_full_mrays),
            r.speed.primary_hits.to_string(),
            r.speed.ao_occluded.to_string(),
        ]);
    }
    let markdown = format!(
        "## 8. Attributes\n\n\
         The sweep mesh with per-vertex normals (area-weighted averages of the faces around each \
         vertex) and colours (running with the position) made from its geometry, converted with \
         `[attributes] face_ids = true`, `normals = \"oct8\"` or `\"oct16\"` and \
         `colors = true`. Bytes per attribute, from the file's section table: face ids are a \
         bit-packed stream with a group index; normals and colours are stored per stored \
         vertex ({:.2} per triangle: strips repeat the vertices they share), found through \
         the per-vertex index that both use.\n\n{}\
         The same rays on the file without attributes and with them: primary and AO rays never \
         read attributes; the query columns trace the primary rays and write `reducem query`'s \
         records, compact (t and normal) or `--format full` (which reads each hit's face id, \
         normal and colour).\n\n{}",
        vertices / oct16.stats.triangles.max(1) as f64,
        cost.to_markdown(),
        speed.to_markdown(),
    );
    Ok(Section {
        markdown,
        plots: Vec::new(),
    })
}

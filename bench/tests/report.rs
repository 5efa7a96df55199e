//! The trade-offs report (feature `report`): the tiny configuration end to end, checking that
//! every table and plot is produced and that the numbers agree with each other; and the
//! meshoptimizer path of the stripifier comparison, which must be lossless like Strip-RT's.
#![cfg(feature = "report")]

#[path = "../../tests/common/mod.rs"]
mod common;

use std::path::PathBuf;
use std::sync::OnceLock;

use common::{canonical_sorted, expected_triangles, grid, icosphere, temp_path, torus};
use reducem::conversion::{encode_stripification, write_chunk, BuildParams};
use reducem::format::attributes::AttributeSection;
use reducem::format::reader::ReducemFile;
use reducem::format::SECTION_ALIGN;
use reducem::mesh::Mesh;
use reducem::{decode, strip_windows};
use reducem_bench::report::stripifier::{limit_length, meshopt_stripification};
use reducem_bench::report::{self, memory, sweeps, ReportConfig, ReportData, Scale, Written};

/// One tiny run shared by the tests that read its output.
fn tiny_report() -> &'static (ReportData, Written) {
    static REPORT: OnceLock<(ReportData, Written)> = OnceLock::new();
    REPORT.get_or_init(|| {
        let dir = temp_path("report");
        let config = ReportConfig {
            scale: Scale::Tiny,
            out_dir: dir.join("out"),
            work_dir: dir.join("work"),
        };
        report::run(&config).expect("tiny report")
    })
}

#[test]
fn report_names_machine_commit_and_date_and_every_section() {
    let (data, written) = tiny_report();
    let text = std::fs::read_to_string(&written.report).expect("REPORT.md");
    for needle in [
        "| date |",
        "| commit |",
        "| CPU |",
        "## 1. Memory",
        "## 2. Stripifier",
        "## 3. Strip length",
        "## 4. Leaf size",
        "## 5. SAH quality",
        "## 6. Accuracy",
        "## 7. Vertex precision",
        "## 8. Attributes",
    ] {
        assert!(text.contains(needle), "REPORT.md lacks {needle:?}");
    }
    assert!(text.contains(&data.machine.commit));
    assert!(data.machine.cores >= 1);
}

#[test]
fn every_plot_is_an_svg_with_labelled_axes_referenced_by_the_report() {
    let (_, written) = tiny_report();
    let text = std::fs::read_to_string(&written.report).expect("REPORT.md");
    assert_eq!(written.plots.len(), 10);
    for plot in &written.plots {
        let svg = std::fs::read_to_string(plot).expect("plot");
        assert!(svg.starts_with("<svg"), "{}", plot.display());
        assert!(
            svg.contains("<circle"),
            "{} has no data points",
            plot.display()
        );
        let name = plot.file_name().expect("name").to_string_lossy();
        assert!(
            text.contains(&format!("(plots/{name})")),
            "{name} not linked"
        );
        // Every axis label names its unit in parentheses.
        assert!(svg.matches(" (").count() >= 2, "{name} lacks axis units");
    }
    for image in &written.images {
        assert!(std::fs::metadata(image).expect("image").len() > 0);
    }
}

#[test]
fn memory_parts_sum_to_the_totals_and_reducem_total_is_the_file_size() {
    let (data, _) = tiny_report();
    let kinds = report::MEMORY_KINDS.len();
    let per_kind = if cfg!(feature = "embree") { 5 } else { 3 };
    assert_eq!(data.memory.len(), kinds * per_kind);
    for row in &data.memory {
        assert_eq!(row.parts.total(), row.total_bytes, "{row:?}");
        assert!(row.total_bytes > 0);
    }
    for row in data
        .memory
        .iter()
        .filter(|r| r.representation == memory::REDUCEM)
    {
        let file = temp_path("report").join(format!("work/{}.rdm", row.kind));
        let bytes = std::fs::metadata(&file).expect("file").len();
        assert_eq!(row.total_bytes, bytes, "{}", row.kind);
    }
}

#[test]
fn engines_answer_the_same_rays_alike() {
    let (data, _) = tiny_report();
    for kind in report::MEMORY_KINDS.map(|k| format!("{k:?}").to_lowercase()) {
        let speeds: Vec<_> = data
            .memory
            .iter()
            .filter(|r| r.kind == kind)
            .filter_map(|r| r.speed)
            .collect();
        // ReduceM and the baseline, and Embree's two scenes when built with it.
        assert!(speeds.len() >= 2, "{kind}");
        let reducem = speeds[0];
        assert!(reducem.primary_hits > 0, "{kind}: the camera sees the mesh");
        for other in &speeds[1..] {
            assert_eq!(
                (other.primary_hits, other.ao_occluded),
                (reducem.primary_hits, reducem.ao_occluded),
                "{kind}"
            );
        }
        assert!(reducem.primary_mrays > 0.0 && reducem.ao_mrays > 0.0);
    }
}

#[test]
fn stripifiers_store_the_same_triangles() {
    let (data, _) = tiny_report();
    assert_eq!(data.stripifiers.len(), 2 * report::MEMORY_KINDS.len());
    for pair in data.stripifiers.chunks(2) {
        let (strip_rt, meshopt) = (&pair[0], &pair[1]);
        assert_eq!(strip_rt.kind, meshopt.kind);
        assert_eq!(strip_rt.stats.triangles, meshopt.stats.triangles);
        assert_eq!(strip_rt.speed.primary_hits, meshopt.speed.primary_hits);
        assert!(meshopt.stats.max_strip_length <= 60);
    }
}

#[test]
fn sweeps_cover_their_parameters_consistently() {
    let (data, _) = tiny_report();
    assert_eq!(data.strip_lengths.len(), sweeps::STRIP_LENGTHS.len());
    for row in &data.strip_lengths {
        assert!(row.stats.max_strip_length <= row.max_length as u64);
        assert!(row.stats.avg_strip_length <= row.max_length as f64);
    }
    assert_eq!(
        data.leaf_subtree.len(),
        sweeps::LEAF_SIZES.len() * sweeps::SUBTREE_SIZES.len()
    );
    for per_leaf in data.leaf_subtree.chunks(sweeps::SUBTREE_SIZES.len()) {
        assert!(per_leaf
            .iter()
            .all(|r| r.bytes_per_triangle == per_leaf[0].bytes_per_triangle));
        let hits = per_leaf[0].speed.primary_hits;
        assert!(per_leaf.iter().all(|r| r.speed.primary_hits == hits));
    }
    assert_eq!(data.sah_bins.len(), 2 * sweeps::SAH_BINS.len());
    assert!(data.sah_bins.iter().all(|r| r.build_seconds > 0.0));
}

#[test]
fn precision_rows_trade_error_for_bytes_and_the_weld_joins_strips() {
    let (data, _) = tiny_report();
    let rows = &data.precision;
    assert_eq!(rows.len(), 1 + report::precision::GRID_BITS.len());
    let (lossless, grids) = rows.split_first().unwrap();
    assert_eq!(lossless.grid_bits, None);
    assert_eq!(lossless.stats.position_error_max, 0.0);
    for pair in grids.windows(2) {
        assert!(pair[0].grid_bits < pair[1].grid_bits);
        assert!(pair[1].stats.position_error_max < pair[0].stats.position_error_max);
        assert!(pair[0].stats.bytes_per_triangle < pair[1].stats.bytes_per_triangle);
    }
    for grid in grids {
        assert!(grid.stats.bytes_per_triangle < lossless.stats.bytes_per_triangle);
        let bound = grid.stats.grid_cell as f64 * 3f64.sqrt() / 2.0;
        assert!(grid.stats.position_error_max <= bound * 1.0001, "{grid:?}");
    }
    let [apart, welded] = &data.weld[..] else {
        panic!("two weld rows")
    };
    assert_eq!(apart.stats.triangles, welded.stats.triangles);
    assert_eq!(apart.stats.avg_strip_length, 1.0);
    assert!(welded.stats.avg_strip_length > 2.0, "{welded:?}");
    assert!(welded.weld.displacement.max <= welded.weld.tolerance as f64);
}

#[test]
fn more_ao_samples_cost_more_rays_and_lower_the_error() {
    let (data, _) = tiny_report();
    let rows = &data.ambient_occlusion;
    assert_eq!(rows.len(), report::accuracy::SAMPLE_COUNTS.len());
    let per_sample = rows[0].ao_rays / rows[0].samples as u64;
    assert!(per_sample > 0);
    assert!(rows
        .iter()
        .all(|r| r.ao_rays == per_sample * r.samples as u64));
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    assert!(last.rmse < first.rmse / 4.0, "{first:?} {last:?}");
}

#[test]
fn attributes_cost_their_sections_and_leave_the_answers_unchanged() {
    let (data, written) = tiny_report();
    let rows = &data.attributes;
    assert_eq!(rows.len(), report::attributes::VARIANTS.len());
    let (plain, stored) = rows.split_first().expect("rows");
    assert!(plain.section_bytes.is_empty());
    let [oct8, oct16] = stored else {
        panic!("two rows with attributes")
    };
    for row in stored {
        assert_eq!(row.stats.triangles, plain.stats.triangles);
        assert_eq!(
            (row.speed.primary_hits, row.speed.ao_occluded),
            (plain.speed.primary_hits, plain.speed.ao_occluded)
        );
        let sections: u64 = row.section_bytes.iter().map(|&(_, bytes)| bytes).sum();
        let growth = row.stats.file_bytes - plain.stats.file_bytes;
        // Each section starts on an aligned offset.
        let padding = SECTION_ALIGN * row.section_bytes.len() as u64;
        assert!(
            (sections..sections + padding).contains(&growth),
            "the file grows by {growth} for {sections} bytes of sections"
        );
        assert!(row.colored_vertices() >= row.stats.triangles / 3);
        let face_ids =
            row.bytes(AttributeSection::FaceIds) + row.bytes(AttributeSection::FaceIdGroups);
        assert!(row.per_triangle(face_ids) <= 4.0, "{row:?}");
    }
    let normals = |row: &report::attributes::AttributeRow| row.bytes(AttributeSection::Normals);
    assert_eq!(normals(oct8) * 2, normals(oct16));
    assert_eq!(normals(oct16), 4 * oct16.colored_vertices());
    assert_eq!(oct8.colored_vertices(), oct16.colored_vertices());
    let text = std::fs::read_to_string(&written.report).expect("REPORT.md");
    assert!(text.contains("| normals, oct16 | normals |"), "{text}");
}

#[test]
fn synthetic_attributes_are_area_weighted_normals_and_positional_colours() {
    let sphere = icosphere(3);
    let with = report::attributes::with_synthetic_attributes(&sphere);
    let normals = with.normals.expect("normals");
    for (normal, position) in normals.iter().zip(&sphere.positions) {
        let cosine: f32 = (0..3).map(|axis| normal[axis] * position[axis]).sum();
        assert!(cosine > 0.999, "{normal:?} at {position:?}");
    }
    let colors = with.colors.expect("colours");
    let bounds = sphere.bounds();
    for (color, position) in colors.iter().zip(&sphere.positions) {
        for axis in 0..3 {
            if position[axis] == bounds.min[axis] {
                assert_eq!(color[axis], 0);
            }
            if position[axis] == bounds.max[axis] {
                assert_eq!(color[axis], 255);
            }
        }
        assert_eq!(color[3], 255);
    }
}

/// Converts through meshoptimizer's strips and checks that decoding gives the input back.
fn assert_meshopt_round_trip(name: &str, mesh: &Mesh, max_length: usize) {
    let stripification = meshopt_stripification(mesh, max_length);
    for s in &stripification.strips {
        assert!(
            strip_windows::triangles(s).count() <= max_length,
            "{name}: strip too long"
        );
    }
    let mut params = BuildParams::default();
    params.stripify.max_length = max_length;
    let chunk = encode_stripification(mesh, &stripification, params.leaf_windows);
    let path: PathBuf = temp_path(&format!("meshopt-{name}-{max_length}.rdm"));
    write_chunk(&chunk, &params, &path).expect("write");
    let file = ReducemFile::open(&path).expect("open");
    file.verify_checksums().expect("checksums");
    assert_eq!(
        canonical_sorted(decode::triangles(&file)),
        expected_triangles(mesh),
        "{name}: decoded triangles differ"
    );
}

#[test]
fn meshopt_strips_round_trip_losslessly() {
    for max_length in [1, 2, 3, 60] {
        assert_meshopt_round_trip("grid", &grid(20, 15), max_length);
        assert_meshopt_round_trip("torus", &torus(32, 12), max_length);
    }
    let mut nasty = grid(6, 6);
    nasty.triangles.push([3, 3, 4]);
    let flipped = nasty.triangles[20];
    nasty.triangles[20] = [flipped[0], flipped[2], flipped[1]];
    assert_meshopt_round_trip("nasty", &nasty, 60);
}

#[test]
fn length_limit_keeps_every_windows_winding() {
    // Windows 1 and 2 are swaps, the others real triangles.
    let strip = [0, 1, 2, 2, 3, 4, 5, 6];
    let original: Vec<_> = strip_windows::triangles(&strip).collect();
    for max_length in 1..=6 {
        let pieces = limit_length(&strip, max_length);
        let rejoined: Vec<_> = pieces
            .iter()
            .flat_map(|p| strip_windows::triangles(p))
            .collect();
        assert_eq!(rejoined, original, "max_length {max_length}");
        assert!(pieces
            .iter()
            .all(|p| strip_windows::triangles(p).count() <= max_length));
    }
}

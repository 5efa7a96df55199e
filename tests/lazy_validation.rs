//! Lazy validation ([`Validation::Lazy`], what `ReducemFile::open` does above
//! [`EAGER_VALIDATION_BYTES`]): a file corrupt in one strip opens, answers the rays that do not
//! reach that strip exactly as the intact file does, and reports the defect, with the file and
//! byte a full validation names, once a ray reaches it; `reducem query` then fails with exit code
//! 65 and writes nothing, and `validate_all` and `reducem inspect --verify` find the defect
//! without tracing. Over thousands of corruptions, lazy and full validation agree on which files
//! are sound, and tracing a lazily opened corrupt file never panics.

mod common;

use std::mem::{offset_of, size_of};
use std::path::PathBuf;

use common::{fixture_bytes, hit_bits, temp_path, torus, tracer_variants};
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::TopNodes;
use reducem::format::reader::{FormatError, ReducemFile, Validation, EAGER_VALIDATION_BYTES};
use reducem::format::{FilePart, NodeRecord, SectionKind, TopSlot, WideNode, WIDE_WIDTH};
use reducem::trace::ray_file::encode_rays;
use reducem::trace::{unit_normal, Hit, Ray};

fn converted_bytes(mesh_size: (u32, u32), params: &BuildParams, name: &str) -> Vec<u8> {
    let path = temp_path(name);
    convert_mesh(&torus(mesh_size.0, mesh_size.1), params, &path).expect("convert");
    std::fs::read(&path).expect("read back")
}

fn written(name: &str, bytes: &[u8]) -> PathBuf {
    let path = temp_path(name);
    std::fs::write(&path, bytes).expect("write");
    path
}

fn grid_params() -> BuildParams {
    BuildParams {
        grid_bits: Some(16),
        ..BuildParams::default()
    }
}

/// A committed 3.1 torus (see `tests/fixtures/`): the older node layouts.
fn fixture(name: &str) -> Vec<u8> {
    fixture_bytes("tests/fixtures", name)
}

fn section_range(bytes: &[u8], kind: SectionKind) -> std::ops::Range<usize> {
    let entry = 104 + (kind as usize - 1) * 32;
    let field = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let offset = field(entry + 8);
    offset..offset + field(entry + 16)
}

/// The largest extent of the model's bounds.
fn scale(file: &ReducemFile) -> f32 {
    let header = file.header();
    (0..3)
        .map(|axis| header.bounds_max[axis] - header.bounds_min[axis])
        .fold(0.0f32, f32::max)
}

/// One ray per strip, from just off the centroid of the strip's first real triangle straight
/// at it and ending just beyond, so that the closest hit is in that strip and traversal enters
/// only the boxes near it.
fn rays_at_strips(file: &ReducemFile) -> Vec<Ray> {
    let scale = scale(file);
    (0..file.strip_count())
        .map(|strip| {
            let view = file.strip(strip);
            let corners = view
                .triangles()
                .first()
                .expect("a strip with a triangle")
                .map(|r| view.vertices.point(r as usize));
            let normal = unit_normal(&corners);
            let centroid: [f32; 3] =
                std::array::from_fn(|i| (corners[0][i] + corners[1][i] + corners[2][i]) / 3.0);
            Ray {
                origin: std::array::from_fn(|i| centroid[i] + normal[i] * scale * 1e-3),
                direction: normal.map(|x| -x),
                tmin: 0.0,
                tmax: scale * 2e-3,
            }
        })
        .collect()
}

/// The strips of the top-level leaf that holds `strip`.
fn leaf_of(file: &ReducemFile, strip: usize) -> std::ops::Range<usize> {
    fn find<N: NodeRecord>(nodes: &[N], strip: usize) -> Option<std::ops::Range<usize>> {
        nodes.iter().find_map(|node| {
            (0..N::WIDTH).find_map(|slot| match node.slot(slot) {
                TopSlot::Leaf { first, count } => {
                    let leaf = first as usize..(first + count) as usize;
                    leaf.contains(&strip).then_some(leaf)
                }
                _ => None,
            })
        })
    }
    match file.top_nodes() {
        TopNodes::F32(nodes) => find(nodes, strip),
        TopNodes::Grid(nodes, _) => find(nodes, strip),
        TopNodes::Wide(nodes) => find(nodes, strip),
    }
    .expect("every strip is in a leaf")
}

/// The rays whose segments pass well clear of every vertex box of `strip`'s leaf: traversal
/// never enters that leaf for them, so they never view `strip`.
fn rays_clear_of(file: &ReducemFile, rays: &[Ray], strip: usize) -> Vec<Ray> {
    rays_clear_of_strips(file, rays, leaf_of(file, strip))
}

/// The rays whose segments pass well clear of every vertex box of `strips`.
fn rays_clear_of_strips(
    file: &ReducemFile,
    rays: &[Ray],
    strips: impl IntoIterator<Item = usize>,
) -> Vec<Ray> {
    let margin = f64::from(scale(file)) * 0.02;
    let (mut min, mut max) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for s in strips {
        for point in file.strip(s).vertices.iter() {
            for axis in 0..3 {
                min[axis] = min[axis].min(f64::from(point[axis]) - margin);
                max[axis] = max[axis].max(f64::from(point[axis]) + margin);
            }
        }
    }
    let misses = |ray: &Ray| {
        let (mut near, mut far) = (f64::from(ray.tmin), f64::from(ray.tmax));
        for axis in 0..3 {
            let (origin, direction) = (f64::from(ray.origin[axis]), f64::from(ray.direction[axis]));
            if direction == 0.0 {
                if origin < min[axis] || origin > max[axis] {
                    return true;
                }
                continue;
            }
            let (a, b) = (
                (min[axis] - origin) / direction,
                (max[axis] - origin) / direction,
            );
            near = near.max(a.min(b));
            far = far.min(a.max(b));
        }
        near > far
    };
    rays.iter().copied().filter(misses).collect()
}

/// One tracer configuration's closest hits (as bits) and occlusion answers.
type Answers = (Vec<Option<[u32; 8]>>, Vec<bool>);

/// Closest hits and occlusion answers of `rays` for every tracer configuration.
fn answers(file: &ReducemFile, rays: &[Ray]) -> Vec<Answers> {
    tracer_variants(file)
        .iter()
        .map(|(_, tracer)| {
            let hits: Vec<Option<Hit>> = tracer.intersect_chunk(rays);
            (
                hits.iter().map(hit_bits).collect(),
                tracer.occluded_chunk(rays),
            )
        })
        .collect()
}

/// `bytes` with strip `strip`'s record made invalid: it claims one vertex (a strip has at
/// least three). (Format 3 packs every file's references at the strip's bits, so an all-ones
/// reference is in range when the vertex count is a power of two; the record is corrupt in
/// every encoding.)
fn with_corrupt_strip(bytes: &[u8], strip: usize) -> Vec<u8> {
    let records = section_range(bytes, SectionKind::StripRecords).start + strip * 8;
    let mut corrupt = bytes.to_vec();
    corrupt[records + 4..records + 6].copy_from_slice(&1u16.to_le_bytes());
    corrupt
}

#[test]
fn a_strip_corrupt_file_opens_and_fails_only_when_a_ray_reaches_the_strip() {
    for (name, params) in [("f32", BuildParams::default()), ("grid", grid_params())] {
        let bytes = converted_bytes((24, 12), &params, &format!("lazy-one-{name}.rdm"));
        let intact = ReducemFile::open_with(&written("lazy-intact.rdm", &bytes), Validation::Full)
            .expect("intact");
        let strips = intact.strip_count();
        let corrupt_strip = strips / 2;
        let rays = rays_at_strips(&intact);
        let path = written(
            &format!("lazy-corrupt-{name}.rdm"),
            &with_corrupt_strip(&bytes, corrupt_strip),
        );
        let full = ReducemFile::open_with(&path, Validation::Full)
            .err()
            .expect("full validation rejects the corrupt strip");
        let full_error = full.to_string();
        assert!(
            full_error.contains(&format!("strip {corrupt_strip}:")),
            "{full_error}"
        );

        let lazy = ReducemFile::open_with(&path, Validation::Lazy).expect("opens lazily");
        let elsewhere = rays_clear_of(&intact, &rays, corrupt_strip);
        assert!(
            elsewhere.len() > rays.len() / 2,
            "{name}: {}",
            elsewhere.len()
        );
        assert_eq!(
            answers(&lazy, &elsewhere),
            answers(&intact, &elsewhere),
            "{name}"
        );
        assert!(lazy.defect().is_none(), "{name}: no ray reached the strip");

        let at_strip = &rays[corrupt_strip..corrupt_strip + 1];
        for (variant, tracer) in tracer_variants(&lazy) {
            let hit = tracer.intersect_chunk(at_strip)[0];
            assert_ne!(
                hit.map(|h| h.strip),
                Some(corrupt_strip as u32),
                "{name} {variant}: a hit in the corrupt strip"
            );
        }
        let lazy_defect = lazy.defect().expect("the ray reached the strip");
        assert_eq!(lazy_defect.defect(), full.defect(), "{name}: the same kind");
        let lazy_error = lazy_defect.to_string();
        assert_eq!(
            lazy_error, full_error,
            "{name}: the same file, byte and defect"
        );
        assert_eq!(
            lazy.validate_all().err().map(|e| e.to_string()),
            Some(full_error),
            "{name}"
        );
    }
}

/// `bytes` with `new` written at byte `field` of format 4 node `node`.
fn with_node_bytes(bytes: &[u8], node: usize, field: usize, new: &[u8]) -> Vec<u8> {
    let at =
        section_range(bytes, SectionKind::TopNodes).start + node * size_of::<WideNode>() + field;
    let mut corrupt = bytes.to_vec();
    corrupt[at..at + new.len()].copy_from_slice(new);
    corrupt
}

/// A format 4 file with a crafted node (its reserved byte set, or a link of tag 0 with an
/// index) opens lazily, answers the rays that do not enter that node exactly as the intact file
/// does, and reports the defect a full validation reports once a ray enters it.
#[test]
fn a_node_corrupt_file_opens_and_fails_only_when_a_ray_reaches_the_node() {
    let bytes = converted_bytes((24, 12), &BuildParams::default(), "lazy-node.rdm");
    let intact = ReducemFile::open_with(&written("lazy-node-intact.rdm", &bytes), Validation::Full)
        .expect("intact");
    let TopNodes::Wide(nodes) = intact.top_nodes() else {
        panic!("a format 4 file has wide nodes");
    };
    // The last node in depth-first preorder has no node children: only leaves.
    let last = nodes.len() - 1;
    assert!(last > 0, "a root with node children");
    let strips: Vec<usize> = (0..WIDE_WIDTH)
        .flat_map(|slot| match nodes[last].slot(slot) {
            TopSlot::Leaf { first, count } => first as usize..(first + count) as usize,
            TopSlot::Empty => 0..0,
            other => panic!("{other:?} in the last node"),
        })
        .collect();
    let rays = rays_at_strips(&intact);
    let elsewhere = rays_clear_of_strips(&intact, &rays, strips.iter().copied());
    assert!(elsewhere.len() > rays.len() / 2, "{}", elsewhere.len());
    let crafted = [
        ("reserved", offset_of!(WideNode, reserved), vec![1]),
        (
            "link",
            offset_of!(WideNode, link),
            5u32.to_le_bytes().to_vec(),
        ),
    ];
    for (name, field, value) in crafted {
        let path = written(
            &format!("lazy-node-{name}.rdm"),
            &with_node_bytes(&bytes, last, field, &value),
        );
        let full = ReducemFile::open_with(&path, Validation::Full)
            .err()
            .expect("full validation rejects the node");
        let full_error = full.to_string();
        assert!(
            full_error.contains(&format!("node {last}:")),
            "{full_error}"
        );

        let lazy = ReducemFile::open_with(&path, Validation::Lazy).expect("opens lazily");
        assert_eq!(
            answers(&lazy, &elsewhere),
            answers(&intact, &elsewhere),
            "{name}"
        );
        assert!(lazy.defect().is_none(), "{name}: no ray entered the node");

        let at_node = &rays[strips[0]..strips[0] + 1];
        for (variant, tracer) in tracer_variants(&lazy) {
            tracer.intersect_chunk(at_node);
            let defect = lazy
                .defect()
                .unwrap_or_else(|| panic!("{name} {variant}: entered"));
            assert_eq!(defect.to_string(), full_error, "{name} {variant}");
            assert_eq!(defect.defect(), full.defect(), "{name} {variant}");
        }
        assert_eq!(
            lazy.validate_all().err().map(|e| e.to_string()),
            Some(full_error),
            "{name}"
        );
    }
}

fn reducem(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(args)
        .output()
        .expect("run reducem")
}

#[test]
fn query_fails_on_reaching_a_corrupt_strip_and_inspect_verify_finds_it() {
    let bytes = converted_bytes((240, 150), &BuildParams::default(), "lazy-large.rdm");
    assert!(bytes.len() as u64 > EAGER_VALIDATION_BYTES, "opened lazily");
    let intact = ReducemFile::open(&written("lazy-large-intact.rdm", &bytes)).expect("intact");
    let rays = rays_at_strips(&intact);
    let corrupt_strip = intact.strip_count() / 3;
    let path = written(
        "lazy-large-corrupt.rdm",
        &with_corrupt_strip(&bytes, corrupt_strip),
    );
    let full_error = ReducemFile::open_with(&path, Validation::Full)
        .err()
        .expect("corrupt")
        .to_string();
    let byte = full_error
        .split(" at byte ")
        .nth(1)
        .and_then(|rest| rest.split(':').next())
        .expect("a byte offset")
        .to_string();
    let model = path.to_str().unwrap();

    let elsewhere = written(
        "lazy-elsewhere.rays",
        &encode_rays(&rays_clear_of(&intact, &rays, corrupt_strip)),
    );
    let output = temp_path("lazy-elsewhere.hits");
    let answered = reducem(&[
        "query",
        model,
        "--rays",
        elsewhere.to_str().unwrap(),
        "-o",
        output.to_str().unwrap(),
    ]);
    assert!(
        answered.status.success(),
        "{}",
        String::from_utf8_lossy(&answered.stderr)
    );

    for occluded in [false, true] {
        let at_strip = written("lazy-at-strip.rays", &encode_rays(&[rays[corrupt_strip]]));
        let output = temp_path(&format!("lazy-at-strip-{occluded}.hits"));
        let _ = std::fs::remove_file(&output);
        let mut args = vec![
            "query",
            model,
            "--rays",
            at_strip.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
        ];
        if occluded {
            args.push("--occluded");
        }
        let failed = reducem(&args);
        let stderr = String::from_utf8_lossy(&failed.stderr);
        assert_eq!(failed.status.code(), Some(65), "{stderr}");
        assert!(
            stderr.contains(model) && stderr.contains(&format!("at byte {byte}")),
            "{stderr}"
        );
        assert!(
            !output.exists(),
            "no answers written for incomplete results"
        );
    }

    let verified = reducem(&["inspect", model, "--verify"]);
    let stderr = String::from_utf8_lossy(&verified.stderr);
    assert_eq!(verified.status.code(), Some(65), "{stderr}");
    assert!(stderr.contains(&format!("at byte {byte}")), "{stderr}");
}

/// Every `step`-th byte of the strip records, strip data and top-level nodes, XORed with a
/// mask that walks through the bits.
fn corruptions(bytes: &[u8], step: usize) -> impl Iterator<Item = Vec<u8>> + '_ {
    let sections = [
        SectionKind::StripRecords,
        SectionKind::StripData,
        SectionKind::TopNodes,
    ];
    sections
        .into_iter()
        .flat_map(move |kind| section_range(bytes, kind).step_by(step))
        .enumerate()
        .map(|(case, at)| {
            let mut corrupt = bytes.to_vec();
            corrupt[at] ^= 1 << (case % 8);
            corrupt
        })
}

#[test]
fn lazy_and_full_validation_agree_on_every_corruption() {
    for (name, bytes) in [
        (
            "f32",
            converted_bytes((24, 12), &BuildParams::default(), "lazy-agree-f32.rdm"),
        ),
        (
            "grid",
            converted_bytes((24, 12), &grid_params(), "lazy-agree-grid.rdm"),
        ),
        ("f32-nodes-3.1", fixture("torus-format-3.1.rdm")),
        ("grid-nodes-3.1", fixture("torus-grid-nodes-format-3.1.rdm")),
        ("grid-3.1", fixture("torus-grid-format-3.1.rdm")),
    ] {
        let intact = ReducemFile::open_with(&written("lazy-agree.rdm", &bytes), Validation::Full)
            .expect("intact");
        let rays = rays_at_strips(&intact);
        let (mut rejected, mut found_by_tracing, mut sound) = (0, 0, 0);
        for corrupt in corruptions(&bytes, 3) {
            let path = written("lazy-agree-case.rdm", &corrupt);
            let full = ReducemFile::open_with(&path, Validation::Full);
            let lazy = ReducemFile::open_with(&path, Validation::Lazy)
                .expect("the header and section table are intact");
            let traced = answers(&lazy, &rays);
            match (&full, lazy.defect()) {
                (Ok(full), None) => {
                    assert_eq!(traced, answers(full, &rays), "{name}");
                    sound += 1;
                }
                (Ok(_), Some(defect)) => panic!("{name}: a sound file traced to {defect}"),
                (Err(_), defect) => {
                    rejected += 1;
                    found_by_tracing += usize::from(defect.is_some());
                }
            }
            let validated = lazy.validate_all().err();
            assert_eq!(
                validated.as_ref().map(|e| e.to_string()),
                full.as_ref().err().map(|e| e.to_string()),
                "{name}: validate_all and a full open disagree"
            );
            assert_eq!(
                validated.and_then(|e| e.defect()),
                full.err().and_then(|e| e.defect()),
                "{name}: validate_all and a full open disagree on the kind"
            );
        }
        // Every path ran: corruptions a full open rejects, among them some the rays reached,
        // and sound ones (box and position changes) traced exactly as a full open traces them.
        assert!(
            found_by_tracing > 0 && rejected > found_by_tracing && sound > 0,
            "{name}: {rejected} rejected, {found_by_tracing} found by tracing, {sound} sound"
        );
    }
}

/// A strip's first view decides as a full validation does: for every second byte of the strip
/// records and strip data corrupted, viewing each strip of the lazily opened file in order
/// reports the defect a full open names (file, byte and words), and none when a full open finds
/// no strip defect. What ties the checks that only decide, which pass a sound f32 or grid
/// strip on its first view, to those that name a defect.
#[test]
fn first_views_report_the_defect_a_full_open_names() {
    for (name, bytes) in [
        (
            "f32",
            converted_bytes((24, 12), &BuildParams::default(), "first-views-f32.rdm"),
        ),
        (
            "grid",
            converted_bytes((24, 12), &grid_params(), "first-views-grid.rdm"),
        ),
        ("f32-nodes-3.1", fixture("torus-format-3.1.rdm")),
        ("grid-3.1", fixture("torus-grid-format-3.1.rdm")),
    ] {
        let strips = [SectionKind::StripRecords, SectionKind::StripData]
            .into_iter()
            .flat_map(|kind| section_range(&bytes, kind).step_by(2));
        let mut reported = 0;
        for (case, at) in strips.enumerate() {
            let mut corrupt = bytes.clone();
            corrupt[at] ^= 1 << (case % 8);
            let path = written("first-views-case.rdm", &corrupt);
            let expected = match ReducemFile::open_with(&path, Validation::Full) {
                Ok(_)
                | Err(FormatError::Invalid {
                    section: FilePart::Header,
                    ..
                }) => None,
                Err(error) => Some(error.to_string()),
            };
            let lazy = ReducemFile::open_with(&path, Validation::Lazy)
                .expect("the header and section table are intact");
            for strip in 0..lazy.strip_count() {
                lazy.strip(strip);
            }
            let found = lazy.defect().map(|error| error.to_string());
            assert_eq!(found, expected, "{name}: byte {at}");
            reported += usize::from(found.is_some());
        }
        assert!(reported > 100, "{name}: only {reported} defects reported");
    }
}

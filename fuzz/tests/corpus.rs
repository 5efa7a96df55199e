//! Every seed and every saved finding runs through its target without a panic.
//!
//! `fuzz/regressions/<target>/` holds inputs that once panicked or hung (moved there from
//! `fuzz/crashes/` when fixed); a panic here fails the test with the code's own message.

use std::path::Path;

use reducem_fuzz::runner::read_corpus;
use reducem_fuzz::targets::{Outcome, Target, Workspace};

fn run_directory(kind: &str) -> usize {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scratch =
        std::env::temp_dir().join(format!("reducem-fuzz-{kind}-test-{}", std::process::id()));
    let workspace = Workspace::new(&scratch).expect("scratch workspace");
    let mut cases = 0;
    for target in Target::ALL {
        for input in read_corpus(&root.join(kind).join(target.name())).expect("read inputs") {
            let outcome = workspace.run(target, &input);
            if kind == "corpus" {
                assert_eq!(
                    outcome,
                    Outcome::Accepted,
                    "a {} seed is rejected",
                    target.name()
                );
            }
            cases += 1;
        }
    }
    cases
}

#[test]
fn every_seed_is_accepted() {
    assert!(run_directory("corpus") >= 10);
}

#[test]
fn saved_findings_no_longer_panic() {
    run_directory("regressions");
}

/// Found by the `rays` target (seed 11): a subnormal direction component's reciprocal overflows
/// to infinity, so the tracer treated the ray as parallel to x = 0 although it crosses that
/// split plane at t = 0.33, and missed the sphere the reference hits at t = 2.
#[test]
fn subnormal_direction_components_are_traced() {
    let ray = reducem::trace::Ray {
        origin: [-8.8e-44, 9e-44, -9e-44],
        direction: [2.68e-43, -0.0, 0.5000114],
        tmin: 1.0,
        tmax: f32::INFINITY,
    };
    let scratch =
        std::env::temp_dir().join(format!("reducem-fuzz-subnormal-{}", std::process::id()));
    let workspace = Workspace::new(&scratch).expect("scratch workspace");
    let bytes = reducem::trace::ray_file::encode_rays(&[ray]);
    assert_eq!(workspace.run(Target::Rays, &bytes), Outcome::Accepted);
}

/// Format 2 files are read as before: each kept 2.x seed gives the hits and occlusion answers,
/// bit for bit, of the same mesh converted now (format 3, with block boxes and packed
/// references; the strips and their order are the same, only their blocks' layout differs).
#[test]
fn format_2_seeds_trace_as_their_mesh_converted_as_format_3() {
    use reducem::conversion::{convert_mesh, BuildParams};
    use reducem::format::reader::ReducemFile;
    use reducem::trace::{Kernel, Ray, TraceOptions, Tracer};
    use reducem_fuzz::targets::octahedron_sphere;

    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("corpus/reducem");
    let scratch = std::env::temp_dir().join(format!("reducem-fuzz-v2-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).expect("scratch");
    let seeds = [
        ("sphere-format-2.1.rdm", 2, BuildParams::default()),
        (
            "leaf1-format-2.1.rdm",
            1,
            BuildParams {
                leaf_windows: 1,
                ..BuildParams::default()
            },
        ),
        (
            "sphere-grid-nodes-format-2.4.rdm",
            2,
            BuildParams {
                grid_nodes: true,
                ..BuildParams::default()
            },
        ),
        (
            "grid-format-2.3.rdm",
            2,
            BuildParams {
                grid_bits: Some(12),
                ..BuildParams::default()
            },
        ),
    ];
    // Rays from around the unit sphere towards points inside it, and from inside outwards.
    let rays: Vec<Ray> = (0..400)
        .map(|k| {
            let a = k as f32 * 0.731;
            let b = k as f32 * 0.377;
            let from = [
                3.0 * a.cos() * b.sin(),
                3.0 * a.sin() * b.sin(),
                3.0 * b.cos(),
            ];
            let to = [0.3 * b.cos(), 0.2 * a.sin(), 0.1 * (a + b).cos()];
            let inside = k % 5 == 0;
            let origin = if inside { to } else { from };
            let direction: [f32; 3] = std::array::from_fn(|i| {
                if inside {
                    from[i] - to[i]
                } else {
                    to[i] - from[i]
                }
            });
            Ray {
                origin,
                direction,
                tmin: 0.0,
                tmax: f32::INFINITY,
            }
        })
        .collect();
    for (name, levels, params) in seeds {
        let old = ReducemFile::open(&root.join(name)).expect("open the 2.x seed");
        assert_eq!(old.header().version_major, 2, "{name}");
        let converted = scratch.join(name);
        convert_mesh(&octahedron_sphere(levels), &params, &converted).expect("convert");
        let new = ReducemFile::open(&converted).expect("open the 3.0 file");
        assert_eq!(new.header().version_major, 3, "{name}");
        assert!(new.strip_records().iter().any(|r| r.reference_count > 10));
        for kernel in Kernel::supported() {
            let options = TraceOptions {
                kernel,
                ..TraceOptions::default()
            };
            let (old, new) = (Tracer::new(&old, options), Tracer::new(&new, options));
            assert_eq!(
                old.intersect_batch(&rays),
                new.intersect_batch(&rays),
                "{name}"
            );
            assert_eq!(
                old.occluded_batch(&rays),
                new.occluded_batch(&rays),
                "{name}"
            );
            assert!(old.intersect_batch(&rays).iter().any(Option::is_some));
        }
    }
    let _ = std::fs::remove_dir_all(&scratch);
}

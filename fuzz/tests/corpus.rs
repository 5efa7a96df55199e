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

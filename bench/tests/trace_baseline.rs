//! The benchmark's baseline BVH finds the same closest hits as the brute-force reference.

#[path = "../../tests/common/mod.rs"]
mod common;

use common::*;
use reducem::geometry::Point;
use reducem_bench::baseline::TriangleBvh;

#[test]
fn baseline_agrees_with_brute_force() {
    let mesh = torus(24, 12);
    let file = open_with_long_strips(&mesh, "baseline-torus.rdm", 60);
    let bvh = TriangleBvh::build(&mesh);
    assert!(bvh.memory_bytes() > 0);
    let mut rng = SplitMix64::new(5);
    let mut hits = 0;
    for _ in 0..2000 {
        let origin: Point = [
            rng.range(-6.0, 6.0),
            rng.range(-6.0, 6.0),
            rng.range(-3.0, 3.0),
        ];
        let target: Point = [
            rng.range(-4.0, 4.0),
            rng.range(-4.0, 4.0),
            rng.range(-1.0, 1.0),
        ];
        let ray = ray_towards(origin, target);
        let expected = brute_force(&file, &ray).map(|(t, _)| t);
        assert_eq!(bvh.intersect(&ray).map(|h| h.t), expected, "{ray:?}");
        assert_eq!(bvh.occluded(&ray), expected.is_some());
        hits += expected.is_some() as usize;
    }
    assert!(hits > 300);
}

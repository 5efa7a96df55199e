//! The benchmarks' rays ([`RaySet`]) are the renderer's, and their AO rays leave surfaces
//! without hitting them.

#[path = "../../tests/common/mod.rs"]
mod common;

use common::*;
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::mesh::Mesh;
use reducem::render::render;
use reducem::trace::{TraceOptions, Tracer};
use reducem_bench::workload::{ao_scene, RaySet};

/// `cad`'s base slab: a 60 × 60 × 0.5 box with its top at z = 0, turned by `yaw` about the
/// vertical through its corner as the generator places it.
fn slab(yaw: f32) -> Mesh {
    let (sin, cos) = yaw.sin_cos();
    let positions = (0..8)
        .map(|corner| {
            let local = [
                60.0 * (corner & 1) as f32,
                60.0 * (corner >> 1 & 1) as f32,
                0.5 * (corner >> 2 & 1) as f32,
            ];
            [
                cos * local[0] - sin * local[1] - 30.0,
                sin * local[0] + cos * local[1] - 30.0,
                local[2] - 0.5,
            ]
        })
        .collect();
    // Counter-clockwise seen from outside; corner bits are x = 1, y = 2, z = 4.
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    Mesh {
        positions,
        triangles: quads
            .iter()
            .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
            .collect(),
        face_ids: None,
        normals: None,
        colors: None,
    }
}

fn slab_file(yaw: f32) -> ReducemFile {
    let path = temp_path(&format!("slab-{yaw}.rdm"));
    convert_mesh(&slab(yaw), &BuildParams::default(), &path).expect("convert");
    ReducemFile::open(&path).expect("open")
}

/// The top of the slab lies at z = 0, where the AO origin is pushed up by 2^-16, and the camera
/// is 120 to 170 units away, where the z of `origin + t * direction` steps by 2^-17 or 2^-16:
/// hit points computed that way put many AO origins on or under the top, and their rays hit it.
#[test]
fn ao_rays_leaving_a_lone_box_are_never_occluded() {
    for yaw in [0.0, 0.4, 1.1, 2.3] {
        let file = slab_file(yaw);
        let rays = RaySet::new(&file, 64, 8);
        assert!(rays.ambient_occlusion.len() > 8 * 500, "yaw {yaw}");
        let tracer = Tracer::new(&file, TraceOptions::default());
        let occluded = tracer.occluded_batch(&rays.ambient_occlusion);
        assert_eq!(occluded.iter().filter(|&&o| o).count(), 0, "yaw {yaw}");
        for ray in &rays.ambient_occlusion {
            assert_eq!(brute_force(&file, ray), None, "yaw {yaw}: {ray:?}");
        }
    }
}

#[test]
fn the_rays_are_the_ones_the_renderer_traces() {
    let file = slab_file(0.7);
    let (size, samples) = (40, 3);
    let rays = RaySet::new(&file, size, samples);
    let tracer = Tracer::new(&file, TraceOptions::default());
    let (_, report) = render(&tracer, &ao_scene(size, samples));
    assert_eq!(rays.primary.len() as u64, report.rays_of("primary"));
    assert_eq!(
        rays.ambient_occlusion.len() as u64,
        report.rays_of("ambient_occlusion")
    );
}

//! The renderer shades with stored normals and vertex colours when a file has them, and renders
//! files without them exactly as before.

mod common;

use std::path::Path;

use common::*;
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::mesh::Mesh;
use reducem::render::image::srgb_bytes;
use reducem::render::scene::Scene;
use reducem::render::{render, Frame};
use reducem::trace::{TraceOptions, Tracer};

/// Everything the renderer does: two lights (one casting shadows), ambient occlusion.
const FULL_SCENE: &str = "[image]\nwidth = 48\nheight = 40\n\
    [camera]\nauto = true\ndirection = [0.3, -0.5, 1.0]\n\
    [[directional_light]]\ndirection = [0.2, 0.1, -1.0]\ncast_shadows = true\n\
    [[point_light]]\nposition = [0.0, 0.0, 8.0]\nintensity = 40.0\n\
    [ambient_occlusion]\nsamples = 4\n";

fn convert(mesh: &Mesh, params: &BuildParams, name: &str) -> ReducemFile {
    let path = temp_path(name);
    convert_mesh(mesh, params, &path).expect("convert");
    ReducemFile::open(&path).expect("open")
}

fn render_scene(file: &ReducemFile, scene: &str) -> Frame {
    let scene = Scene::parse(Path::new("test.toml"), scene).expect("scene");
    render(&Tracer::new(file, TraceOptions::default()), &scene).0
}

/// FNV-1a, 64 bits: a digest of image bytes to compare against a recorded one.
fn digest(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &byte| {
        (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The linear pixels (what `.pfm` stores) and the sRGB bytes (what `.png` stores) of a frame.
fn frame_digests(frame: &Frame) -> [u64; 2] {
    let linear: Vec<u8> = frame
        .pixels
        .iter()
        .flatten()
        .flat_map(|channel| channel.to_le_bytes())
        .collect();
    [digest(&linear), digest(&srgb_bytes(frame))]
}

/// The digests of [`FULL_SCENE`] rendered on the torus and the icosphere without attributes, as
/// the renderer made them before it knew attributes (commit 50403b3).
#[test]
fn files_without_attributes_render_as_before() {
    let torus = convert(&torus(40, 16), &BuildParams::default(), "plain-torus.rdm");
    let sphere = convert(&icosphere(3), &BuildParams::default(), "plain-sphere.rdm");
    let digests = [&torus, &sphere].map(|file| frame_digests(&render_scene(file, FULL_SCENE)));
    let before = [
        [0x24af_c06b_c633_485b, 0x7c7f_7172_f90f_fe12],
        [0x1277_8a38_4a6c_13db, 0x6524_1853_4b3a_f463],
    ];
    assert_eq!(digests, before, "{digests:#x?}");
}

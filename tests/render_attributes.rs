//! The renderer shades with stored normals and vertex colours when a file has them, and renders
//! files without them exactly as before.

mod common;

use std::path::Path;

use common::*;
use glam::Vec3;
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::attributes::{AttributeSet, NormalEncoding};
use reducem::format::reader::ReducemFile;
use reducem::mesh::Mesh;
use reducem::render::attributes::srgb_to_linear;
use reducem::render::camera::Camera;
use reducem::render::image::srgb_bytes;
use reducem::render::scene::Scene;
use reducem::render::{render, Frame};
use reducem::trace::{Ray, TraceOptions, Tracer};

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

const NORMALS: AttributeSet = AttributeSet {
    face_ids: false,
    normals: NormalEncoding::Oct16,
    colors: false,
};

const COLORS: AttributeSet = AttributeSet {
    face_ids: false,
    normals: NormalEncoding::None,
    colors: true,
};

fn with_attributes(attributes: AttributeSet) -> BuildParams {
    BuildParams {
        attributes,
        ..BuildParams::default()
    }
}

/// Looking down the z axis at the origin from `height`, lit from above with nothing else: a
/// pixel's value is `albedo × colour × cos θ` between the shading normal and +z.
fn from_above(height: f32, extra: &str) -> String {
    format!(
        "[image]\nwidth = 64\nheight = 64\n\
         [camera]\nposition = [0.0, 0.0, {height}]\nlook_at = [0.0, 0.0, 0.0]\n\
         up = [0.0, 1.0, 0.0]\nfov_degrees = 40.0\n\
         [[directional_light]]\ndirection = [0.0, 0.0, -1.0]\n\
         [shading]\nambient = 0.0\nalbedo = [1.0, 1.0, 1.0]\n{extra}"
    )
}

/// The primary ray of every pixel of `scene` on `file`, as the renderer traces it.
fn primary_rays(file: &ReducemFile, scene: &str) -> Vec<Ray> {
    let scene = Scene::parse(Path::new("test.toml"), scene).expect("scene");
    let (width, height) = (scene.image.width, scene.image.height);
    let tracer = Tracer::new(file, TraceOptions::default());
    let camera = Camera::new(&tracer, &scene.camera, width, height);
    (0..width * height)
        .map(|p| camera.primary_ray(p % width, p / width))
        .collect()
}

/// A unit sphere whose stored normals are its exact ones: each vertex's position.
fn sphere_with_normals(levels: u32) -> Mesh {
    let mut sphere = icosphere(levels);
    sphere.normals = Some(sphere.positions.clone());
    sphere
}

/// Where all three vertex normals are the vertices' positions on a unit sphere, the interpolated
/// normal at a hit point `p` is `p / |p|`: the image from above must show exactly its z.
#[test]
fn stored_normals_shade_smoothly() {
    let sphere = sphere_with_normals(2);
    let file = convert(&sphere, &with_attributes(NORMALS), "smooth-sphere.rdm");
    let scene = from_above(4.0, "");
    let smooth = render_scene(&file, &scene);
    let faceted = render_scene(&file, &from_above(4.0, "smooth = false\n"));
    let tracer = Tracer::new(&file, TraceOptions::default());
    let (mut smooth_error, mut faceted_error, mut hits) = (0.0f32, 0.0f32, 0);
    for (pixel, ray) in primary_rays(&file, &scene).iter().enumerate() {
        let Some(hit) = tracer.intersect(ray) else {
            continue;
        };
        let point = Vec3::from(ray.origin) + Vec3::from(ray.direction) * hit.t;
        let expected = point.normalize().z;
        smooth_error = smooth_error.max((smooth.pixels[pixel][0] - expected).abs());
        faceted_error = faceted_error.max((faceted.pixels[pixel][0] - expected).abs());
        hits += 1;
    }
    assert!(hits > 1000, "{hits} hit pixels");
    assert!(
        smooth_error < 1e-3,
        "smooth shading is off by {smooth_error}"
    );
    assert!(
        faceted_error > 0.03,
        "faceted is off by only {faceted_error}"
    );
}

/// Seen from inside, every triangle is seen from its back: the stored (outward) normal turns
/// to the viewer like the geometric one, and a light at the centre lights every pixel head-on.
#[test]
fn smooth_normals_are_two_sided() {
    let sphere = sphere_with_normals(2);
    let file = convert(&sphere, &with_attributes(NORMALS), "inside-sphere.rdm");
    let scene = "[image]\nwidth = 32\nheight = 32\n\
         [camera]\nposition = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, 1.0]\nup = [0.0, 1.0, 0.0]\n\
         [[point_light]]\nposition = [0.0, 0.0, 0.0]\ncast_shadows = true\n\
         [shading]\nambient = 0.0\nalbedo = [1.0, 1.0, 1.0]\n";
    let frame = render_scene(&file, scene);
    // cos θ = 1 and the distance at most 1, so every pixel is at least fully lit.
    let darkest = frame.pixels.iter().map(|p| p[0]).fold(f32::MAX, f32::min);
    assert!(darkest >= 0.999, "darkest pixel {darkest}");
}

/// Turning smooth shading off, a file with normals renders as the same mesh without them.
#[test]
fn smooth_off_renders_the_geometric_normal() {
    let sphere = sphere_with_normals(3);
    let with_normals = convert(&sphere, &with_attributes(NORMALS), "off-normals.rdm");
    let plain = convert(&icosphere(3), &BuildParams::default(), "off-plain.rdm");
    let scene = FULL_SCENE.replace(
        "[ambient_occlusion]",
        "[shading]\nsmooth = false\n[ambient_occlusion]",
    );
    assert_eq!(
        render_scene(&with_normals, &scene),
        render_scene(&plain, FULL_SCENE)
    );
    assert_ne!(
        render_scene(&with_normals, FULL_SCENE),
        render_scene(&plain, FULL_SCENE)
    );
}

const RED: [u8; 4] = [255, 0, 0, 255];
const SKY: [u8; 4] = [0, 128, 255, 255];

/// A flat 8 × 8 square centred on the origin at z = 0: red for x < -1, sky blue for x > 1 (the
/// quads between blend the two).
fn two_coloured_square() -> Mesh {
    let mut mesh = grid(8, 8);
    for p in &mut mesh.positions {
        *p = [p[0] - 4.0, p[1] - 4.0, 0.0];
    }
    let colors = mesh
        .positions
        .iter()
        .map(|p| if p[0] < 0.0 { RED } else { SKY })
        .collect();
    mesh.colors = Some(colors);
    mesh
}

/// The x where the ray meets the plane z = 0.
fn x_on_the_ground(ray: &Ray) -> f32 {
    let t = -ray.origin[2] / ray.direction[2];
    ray.origin[0] + t * ray.direction[0]
}

/// Pixels over each half of the square have that half's colour, decoded from sRGB and times the
/// albedo; with `vertex_colors = false`, the albedo alone.
#[test]
fn vertex_colours_multiply_the_albedo() {
    let file = convert(
        &two_coloured_square(),
        &with_attributes(COLORS),
        "colours.rdm",
    );
    let albedo = "albedo = [0.5, 1.0, 1.0]\n";
    let scene = from_above(12.0, "").replace("albedo = [1.0, 1.0, 1.0]\n", albedo);
    let coloured = render_scene(&file, &scene);
    let grey = render_scene(&file, &format!("{scene}vertex_colors = false\n"));
    let sky = [0.0, srgb_to_linear(128), 1.0];
    let (mut red_pixels, mut sky_pixels) = (0, 0);
    for (pixel, ray) in primary_rays(&file, &scene).iter().enumerate() {
        let x = x_on_the_ground(ray);
        if !(-3.9..3.9).contains(&x) || coloured.pixels[pixel] == [0.05, 0.06, 0.08] {
            continue;
        }
        if x < -1.1 {
            assert_eq!(
                coloured.pixels[pixel],
                [0.5, 0.0, 0.0],
                "pixel {pixel} at x = {x}"
            );
            red_pixels += 1;
        } else if x > 1.1 {
            assert_eq!(coloured.pixels[pixel], sky, "pixel {pixel} at x = {x}");
            sky_pixels += 1;
        }
        assert_eq!(grey.pixels[pixel], [0.5, 1.0, 1.0], "pixel {pixel}");
    }
    assert!(
        red_pixels > 300 && sky_pixels > 300,
        "{red_pixels} red, {sky_pixels} sky"
    );
}

/// The normals view shows the flat square's geometric normal, +z, as the sRGB codes 128, 128,
/// 255 at every pixel it covers, with stored normals and colours or without, and the background
/// elsewhere.
#[test]
fn the_normals_view_shows_the_geometric_normal() {
    let square = two_coloured_square();
    let plain = convert(&square, &BuildParams::default(), "normals-view.rdm");
    let coloured = convert(
        &square,
        &with_attributes(COLORS),
        "normals-view-colours.rdm",
    );
    let scene = from_above(12.0, "mode = \"normals\"\n");
    for file in [&plain, &coloured] {
        let frame = render_scene(file, &scene);
        let background = srgb_bytes(&Frame {
            width: 1,
            height: 1,
            pixels: vec![[0.05, 0.06, 0.08]],
        });
        let bytes = srgb_bytes(&frame);
        let mut covered = 0;
        for pixel in bytes.chunks_exact(3) {
            if pixel != background.as_slice() {
                assert_eq!(pixel, [128, 128, 255]);
                covered += 1;
            }
        }
        assert!(covered > 1000, "{covered} pixels show the square");
    }
}

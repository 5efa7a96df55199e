//! The first picture: an automatic camera without a direction sees the model from the side
//! most of its area faces, slightly above the horizon of its up axis, the model covering about
//! 70% of the pixels; `reducem render` turns the scene for the up axis the file stores.

mod common;

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::temp_path;
use glam::Vec3;
use reducem::conversion::{encode_chunk, write_chunk_counted, BuildParams};
use reducem::format::model::UpAxis;
use reducem::format::reader::ReducemFile;
use reducem::mesh::Mesh;
use reducem::render::camera::{placement, Camera};
use reducem::render::scene::Scene;
use reducem::trace::{Ray, TraceOptions, Tracer};

/// Quads along each side of a face of the box.
const FACE_QUADS: u32 = 8;

/// A box 2 long (x), 1 deep (y) and 1.5 high (z) without its back (+y) face, every face wound
/// outwards: its front (-y) face holds more area than any other side, so the front view is
/// from -y.
fn open_box() -> Mesh {
    let mut mesh = Mesh::default();
    let (size_x, size_y, size_z) = (2.0, 1.0, 1.5);
    let mut face = |corner: Vec3, along: Vec3, across: Vec3| {
        let first = mesh.positions.len() as u32;
        for j in 0..=FACE_QUADS {
            for i in 0..=FACE_QUADS {
                let (u, v) = (i as f32 / FACE_QUADS as f32, j as f32 / FACE_QUADS as f32);
                mesh.positions
                    .push((corner + along * u + across * v).into());
            }
        }
        let row = FACE_QUADS + 1;
        for j in 0..FACE_QUADS {
            for i in 0..FACE_QUADS {
                let at = first + j * row + i;
                mesh.triangles.push([at, at + 1, at + row + 1]);
                mesh.triangles.push([at, at + row + 1, at + row]);
            }
        }
    };
    let (x, y, z) = (Vec3::X * size_x, Vec3::Y * size_y, Vec3::Z * size_z);
    face(Vec3::ZERO, x, z); // front, -y
    face(x, y, z); // right, +x
    face(y, -y, z); // left, -x
    face(z, x, y); // top, +z
    face(y, x, -y); // bottom, -z
    mesh
}

/// `mesh` with its z axis turned to y, as a y-up model stands.
fn turned_to_y_up(mesh: &Mesh) -> Mesh {
    let mut turned = mesh.clone();
    for position in &mut turned.positions {
        let [x, y, z] = *position;
        *position = [x, z, -y];
    }
    turned
}

/// `mesh` converted to the temporary file `name`, its model record storing `up`.
fn converted_with_up(mesh: &Mesh, up: UpAxis, name: &str) -> PathBuf {
    let params = BuildParams::default();
    let path = temp_path(name);
    write_chunk_counted(
        Cow::Owned(encode_chunk(mesh, &params)),
        &params,
        None,
        Some(up),
        &path,
    )
    .expect("write");
    path
}

/// An automatic camera without a direction, `up` being the model's up axis.
fn front_scene(up: Vec3, width: u32, height: u32) -> Scene {
    let text = format!(
        "[image]\nwidth = {width}\nheight = {height}\n\
         [camera]\nauto = true\nup = [{}, {}, {}]\nfov_degrees = 40.0\n",
        up.x, up.y, up.z
    );
    Scene::parse(Path::new("front.toml"), &text).expect("scene")
}

/// The fraction of `scene`'s pixels whose primary ray hits the model.
fn fill(tracer: &Tracer, scene: &Scene) -> f64 {
    let (width, height) = (scene.image.width, scene.image.height);
    let camera = Camera::new(tracer, &scene.camera, width, height);
    let rays: Vec<Ray> = (0..width * height)
        .map(|p| camera.primary_ray(p % width, p / width))
        .collect();
    let hits = tracer.intersect_batch(&rays).iter().flatten().count();
    hits as f64 / rays.len() as f64
}

/// The front view of the open box, z-up and turned y-up: from the front face's side, 20°
/// above the horizon, the box covering 60-80% of the pixels, in square and wide images.
#[test]
fn the_automatic_camera_sees_the_front_and_fills_about_seventy_percent() {
    let z_up = open_box();
    let cases = [
        (z_up.clone(), Vec3::Z, Vec3::NEG_Y, "front-z.rdm"),
        (turned_to_y_up(&z_up), Vec3::Y, Vec3::Z, "front-y.rdm"),
    ];
    for (mesh, up, front, name) in cases {
        let path = converted_with_up(&mesh, UpAxis::Z, name);
        let file = ReducemFile::open(&path).expect("open");
        let tracer = Tracer::new(&file, TraceOptions::default());
        for (width, height) in [(120, 120), (160, 100)] {
            let scene = front_scene(up, width, height);
            let (position, look_at) = placement(&tracer, &scene.camera, width, height);
            let toward_camera = (position - look_at).normalize();
            let horizontal = (toward_camera - up * toward_camera.dot(up)).normalize();
            let case = format!("{name} {width}x{height}: towards the camera {toward_camera}");
            assert!(horizontal.dot(front) > 0.99, "{case}");
            let elevation = toward_camera.dot(up).asin().to_degrees();
            assert!(
                (elevation - 20.0).abs() < 0.01,
                "{case}: elevation {elevation}"
            );
            let fill = fill(&tracer, &scene);
            assert!((0.6..=0.8).contains(&fill), "{case}: fill {fill}");
        }
        std::fs::remove_file(&path).expect("remove");
    }
}

fn render_png(model: &Path, scene: &Path, up: Option<&str>, name: &str) -> Vec<u8> {
    let out = temp_path(name);
    let mut command = Command::new(env!("CARGO_BIN_EXE_reducem"));
    command.arg("render").arg(model).arg("--scene").arg(scene);
    command.arg("-o").arg(&out);
    if let Some(up) = up {
        command.args(["--up", up]);
    }
    let output = command.output().expect("run reducem");
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let png = std::fs::read(&out).expect("read the image");
    std::fs::remove_file(&out).expect("remove");
    png
}

/// A file that stores y as its up axis renders without `--up` as with `--up y`, byte for byte,
/// and differently with `--up z`.
#[test]
fn render_turns_the_scene_for_the_stored_up_axis() {
    let model = converted_with_up(&turned_to_y_up(&open_box()), UpAxis::Y, "stored-y.rdm");
    let scene = temp_path("stored-y.toml");
    let text = "[image]\nwidth = 48\nheight = 40\n[camera]\nauto = true\n\
                [[directional_light]]\ndirection = [-0.4, -0.3, -1.0]\n";
    std::fs::write(&scene, text).expect("write the scene");
    let stored = render_png(&model, &scene, None, "stored-y-default.png");
    let y_up = render_png(&model, &scene, Some("y"), "stored-y-y.png");
    let z_up = render_png(&model, &scene, Some("z"), "stored-y-z.png");
    assert!(stored == y_up, "the default differs from --up y");
    assert!(stored != z_up, "--up z renders the y-up view");
    std::fs::remove_file(&model).expect("remove");
    std::fs::remove_file(&scene).expect("remove");
}

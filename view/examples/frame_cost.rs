//! The viewer's work per camera change without the browser: a coarse frame of a quarter of the
//! pixels, then the full primary frame, each turned into sRGB and JPEG as the viewer sends it,
//! FRAMES times over, and the primary rays traced; in bands of BAND_ROWS rows (default 8, the
//! viewer's). For comparing the ways of making the coarse frame, or of making none, by
//! instruction counts (valgrind --tool=callgrind), which a shared machine's load does not
//! change:
//!
//!   cargo build --release -p reducem-view --example frame_cost
//!   valgrind --tool=callgrind target/release/examples/frame_cost MODEL 512 4 own
//!   valgrind --tool=callgrind target/release/examples/frame_cost MODEL 512 4 reused
//!   valgrind --tool=callgrind target/release/examples/frame_cost MODEL 512 4 none
//!
//! `own`: the coarse frame is an image of its own (its pixel centres fall between the full
//! image's) and the full frame traces every pixel; `reused`: the coarse frame is the full image's
//! preview (`render::Progressive::preview`) and the full frame reuses its surfaces; `none`: no
//! coarse frame, the full frame traces every pixel (as the viewer does when full frames come
//! fast).

use std::path::Path;
use std::time::Instant;

use reducem::format::reader::ReducemFile;
use reducem::render::camera::placement;
use reducem::render::image::srgb_bytes;
use reducem::render::scene::Scene;
use reducem::render::Progressive;
use reducem::trace::{TraceOptions, Tracer};

fn main() -> anyhow::Result<()> {
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    let (arguments, band_rows) = match arguments.as_slice() {
        [rest @ .., rows] if rest.len() == 4 => (rest, rows.parse()?),
        rest => (rest, 8),
    };
    let [model, side, frames, mode] = arguments else {
        anyhow::bail!("usage: frame_cost MODEL SIDE FRAMES own|reused|none [BAND_ROWS]");
    };
    let (side, frames): (u32, u32) = (side.parse()?, frames.parse()?);
    let bands = side * band_rows;
    let file = ReducemFile::open(Path::new(model))?;
    let tracer = Tracer::new(&file, TraceOptions::default());
    let scene = primary_view(&tracer, side)?;
    let started = Instant::now();
    let mut rays = 0;
    for _ in 0..frames {
        rays += match mode.as_str() {
            "own" => own_coarse_frame(&tracer, &scene, bands),
            "reused" => reused_coarse_frame(&tracer, &scene, bands),
            "none" => refined(&mut Progressive::new(&tracer, &scene, bands)),
            other => anyhow::bail!("unknown mode {other}"),
        };
    }
    let seconds = started.elapsed().as_secs_f64();
    println!(
        "{mode}: {frames} camera changes at {side}x{side}, {rays} primary rays, {:.3} s per change",
        seconds / f64::from(frames)
    );
    Ok(())
}

/// The shipped primary scene at `side`², its automatic camera placed once.
fn primary_view(tracer: &Tracer, side: u32) -> anyhow::Result<Scene> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/scenes/primary.toml");
    let mut scene = Scene::load(&path)?;
    (scene.image.width, scene.image.height) = (side, side);
    let (position, look_at) = placement(tracer, &scene.camera, side, side);
    scene.camera.auto = false;
    scene.camera.position = Some(position.into());
    scene.camera.look_at = Some(look_at.into());
    Ok(scene)
}

/// Rays of a coarse frame of its own at half the size, then of the full frame.
fn own_coarse_frame(tracer: &Tracer, scene: &Scene, bands: u32) -> u64 {
    let mut coarse = scene.primary_only();
    coarse.image.width = scene.image.width.div_ceil(2);
    coarse.image.height = scene.image.height.div_ceil(2);
    let mut coarse_image = Progressive::new(tracer, &coarse, bands / 4);
    let mut image = Progressive::new(tracer, scene, bands);
    refined(&mut coarse_image) + refined(&mut image)
}

/// Rays of the full image's preview, then of the full frame reusing it.
fn reused_coarse_frame(tracer: &Tracer, scene: &Scene, bands: u32) -> u64 {
    let mut preview = Progressive::preview(tracer, scene, 2, bands / 4);
    let rays = refined(&mut preview);
    let mut image = Progressive::reusing(tracer, scene, bands, &preview);
    rays + refined(&mut image)
}

/// The image's first round, encoded as the viewer sends it, and the rays it traced.
fn refined(image: &mut Progressive) -> u64 {
    if let Ok(frame) = image.refine(1, || Ok::<(), ()>(())) {
        let mut jpeg = Vec::new();
        let (width, height) = (frame.width as u16, frame.height as u16);
        let encoder = jpeg_encoder::Encoder::new(&mut jpeg, 85);
        let srgb = srgb_bytes(&frame);
        encoder
            .encode(&srgb, width, height, jpeg_encoder::ColorType::Rgb)
            .expect("a frame encodes");
    }
    image.rays_traced().0
}

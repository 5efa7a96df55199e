//! The viewer's work per camera change without the browser: a coarse frame, then the full
//! primary frame, each turned into sRGB and JPEG as the viewer sends it, FRAMES times over; in
//! bands of BAND_ROWS rows (default 8, the viewer's). Prints the time per change and of each
//! frame, and the primary rays traced. For comparing the ways of making the coarse frame, or of
//! making none, by instruction counts (valgrind --tool=callgrind), which a shared machine's load
//! does not change:
//!
//!   cargo build --release -p reducem-view --example frame_cost
//!   valgrind --tool=callgrind target/release/examples/frame_cost MODEL 512 4 preview4
//!   valgrind --tool=callgrind target/release/examples/frame_cost MODEL 512 4 none
//!
//! `own`: the coarse frame is an image of its own at half the size (its pixel centres fall
//! between the full image's); `previewN`: the coarse frame is the full image's preview of every
//! Nth pixel each way (`render::Progressive::preview`), as the viewer makes it (N = 4 at 512²);
//! `none`: no coarse frame. The full frame traces every pixel.

use std::path::Path;
use std::time::{Duration, Instant};

use reducem::format::reader::ReducemFile;
use reducem::render::camera::placement;
use reducem::render::image::srgb_bytes_of;
use reducem::render::scene::Scene;
use reducem::render::Progressive;
use reducem::trace::{TraceOptions, Tracer};

#[path = "../src/jpeg.rs"]
mod jpeg;

fn main() -> anyhow::Result<()> {
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    let (arguments, band_rows) = match arguments.as_slice() {
        [rest @ .., rows] if rest.len() == 4 => (rest, rows.parse()?),
        rest => (rest, 8),
    };
    let [model, side, frames, mode] = arguments else {
        anyhow::bail!("usage: frame_cost MODEL SIDE FRAMES own|previewN|none [BAND_ROWS]");
    };
    let (side, frames): (u32, u32) = (side.parse()?, frames.parse()?);
    let bands = side * band_rows;
    let file = ReducemFile::open(Path::new(model))?;
    let tracer = Tracer::new(&file, TraceOptions::default());
    let scene = primary_view(&tracer, side)?;
    let name = mode.trim_end_matches(|c: char| c.is_ascii_digit());
    let mut cost = Cost::default();
    for _ in 0..frames {
        match name {
            "own" => own_coarse_frame(&tracer, &scene, bands, &mut cost),
            "preview" => {
                let step: u32 = mode[name.len()..].parse()?;
                let coarse_bands = bands / (step * step);
                cost.coarse += refined(&mut Progressive::preview(
                    &tracer,
                    &scene,
                    step,
                    coarse_bands,
                ));
                cost.full += refined(&mut Progressive::new(&tracer, &scene, bands));
            }
            "none" => cost.full += refined(&mut Progressive::new(&tracer, &scene, bands)),
            other => anyhow::bail!("unknown mode {other}"),
        }
    }
    let per_change = |phase: Phase| phase.time.as_secs_f64() * 1e3 / f64::from(frames);
    println!(
        "{mode}: {frames} camera changes at {side}x{side}, {} primary rays; ms per change: \
         {:.1} (coarse frame {:.1}, full frame {:.1})",
        cost.coarse.rays + cost.full.rays,
        per_change(cost.coarse) + per_change(cost.full),
        per_change(cost.coarse),
        per_change(cost.full),
    );
    Ok(())
}

/// Primary rays traced and the time taken, by the coarse frames and by the full ones.
#[derive(Default)]
struct Cost {
    coarse: Phase,
    full: Phase,
}

#[derive(Clone, Copy, Default)]
struct Phase {
    rays: u64,
    time: Duration,
}

impl std::ops::AddAssign for Phase {
    fn add_assign(&mut self, other: Phase) {
        self.rays += other.rays;
        self.time += other.time;
    }
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

/// A coarse frame of its own at half the size, then the full frame.
fn own_coarse_frame(tracer: &Tracer, scene: &Scene, bands: u32, cost: &mut Cost) {
    let mut coarse = scene.primary_only();
    coarse.image.width = scene.image.width.div_ceil(2);
    coarse.image.height = scene.image.height.div_ceil(2);
    cost.coarse += refined(&mut Progressive::new(tracer, &coarse, bands / 4));
    cost.full += refined(&mut Progressive::new(tracer, scene, bands));
}

/// The image's first round, encoded as the viewer sends it: the rays it traced and the time.
fn refined(image: &mut Progressive) -> Phase {
    let started = Instant::now();
    if let Ok(srgb) = image.refine_with(1, || Ok::<(), ()>(()), |rows| srgb_bytes_of(&rows)) {
        let (width, height) = image.size();
        jpeg::encode(&srgb, width as u16, height as u16, 85).expect("a frame encodes");
    }
    Phase {
        rays: image.rays_traced().0,
        time: started.elapsed(),
    }
}

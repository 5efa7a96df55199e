//! What the page asks to see, rendered with `reducem render`'s own shading: the scene of a view,
//! its progressive frames, its images and its picks.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::Vec3;
use reducem::format::attributes::NormalEncoding;
use reducem::render::camera::{placement, Camera};
use reducem::render::image::srgb_bytes_of;
use reducem::render::scene::{Scene, ShadingMode};
use reducem::render::Progressive;
use reducem::trace::ray_file::{trace_hits_as, HitFormat};
use reducem::trace::Tracer;
use serde::{Deserialize, Serialize};

use crate::jpeg;
use crate::resident::ResidentBytes;
use crate::stages::Stages;

/// The largest image side the page may ask for, as `reducem render` allows.
const MAX_SIDE: u32 = 16384;

/// JPEG quality of the frames: smooth shading shows no blocking at 85. JPEG rather than WebP:
/// the pure-Rust WebP encoder (image-webp) is lossless only, so lossy WebP would mean a C
/// library; jpeg-encoder is pure Rust and every browser decodes JPEG.
const JPEG_QUALITY: u8 = 85;
// The strips of `jpeg::encode` are whole 16-row MCUs, which needs 2 × 2 chroma (below 90).
const _: () = assert!(JPEG_QUALITY < 90);

/// The camera as the page holds it and `data-camera` shows it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraView {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    pub up: [f32; 3],
    pub fov: f32,
}

/// A view the page asks for: a camera, the image size in pixels, the effects switched on (the
/// scene's when the page names none).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
pub struct View {
    pub camera: CameraView,
    pub width: u32,
    pub height: u32,
    #[serde(default)]
    pub effects: Option<Effects>,
    /// The model's up axis; the command line's when the page names none.
    #[serde(default)]
    pub up: Option<UpAxis>,
}

/// The model's up axis: scenes are written for z-up models and turned for y-up ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// Up is y (scans, glTF).
    Y,
    /// Up is z, as scenes are written.
    Z,
}

/// The page's effect switches.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Effects {
    /// Shade with the stored normals, when the file has them.
    pub stored_normals: bool,
    /// Multiply by the stored colours, when the file has them.
    pub colors: bool,
    pub ambient_occlusion: bool,
    pub shadows: bool,
    /// Show the geometric normals as colours instead of the lit model.
    #[serde(default)]
    pub normals_view: bool,
}

/// What every connection shares: the file's tracer, the scene that shades it (as written for a
/// z-up model, and turned for a y-up one), the command line's up axis, the token.
pub struct Viewer {
    pub tracer: &'static Tracer<'static>,
    z_up_scene: Scene,
    y_up_scene: Scene,
    pub up: UpAxis,
    pub token: String,
    resident: ResidentBytes,
}

/// One image of a view, encoded, with what the page shows about it.
pub struct EncodedFrame {
    pub header: FrameHeader,
    pub jpeg: Vec<u8>,
    pub stages: Stages,
}

#[derive(Debug, Serialize)]
pub struct FrameHeader {
    pub generation: u64,
    pub width: u32,
    pub height: u32,
    /// Samples per pixel of the image (a quarter or less for the coarse frame).
    pub spp: f32,
    pub camera: CameraView,
    pub rays: u64,
    pub seconds: f64,
    pub triangles: u64,
    pub resident_bytes: Option<u64>,
}

/// Pixels a coarse frame has at most: the full frame traces every pixel again (reusing the
/// coarse frame's rays left holes in its packets that cost more than the rays saved), so the
/// coarse frame is kept small; a 128² frame shows a view well enough while it moves.
const COARSE_FRAME_PIXELS: u64 = 1 << 14;

/// The densest coarse frame takes every 2nd pixel each way (a quarter of them).
const DENSEST_COARSE_STEP: u32 = 2;

/// The sparsest coarse frame takes every 64th pixel each way.
const SPARSEST_COARSE_STEP: u32 = 64;

/// A coarse frame later than this after its view arrived makes the next one sparser (every
/// second pixel of it each way), so that coarse frames still come within 100 ms while the
/// model's pages are read from disk; one within half of it makes the next one denser again
/// (not a quarter: a small frame's time is mostly not its rays', and under load a sparser
/// frame would then stay).
const COARSE_FRAME_BUDGET: Duration = Duration::from_millis(70);

/// Pixels of `view`'s coarse frame of every `step`-th pixel each way.
fn coarse_pixels(view: &View, step: u32) -> u64 {
    u64::from(view.width.div_ceil(step)) * u64::from(view.height.div_ceil(step))
}

/// The step of `view`'s densest coarse frame between the full image's pixels:
/// [`DENSEST_COARSE_STEP`], or the power of two that leaves at most [`COARSE_FRAME_PIXELS`].
fn densest_coarse_step(view: &View) -> u32 {
    let mut step = DENSEST_COARSE_STEP;
    while coarse_pixels(view, step) > COARSE_FRAME_PIXELS && step < SPARSEST_COARSE_STEP {
        step *= 2;
    }
    step
}

/// How long after its view arrived a page's last full frame was ready (without the time of a
/// coarse frame before it), and of how many pixels, and how much sparser than the densest its
/// coarse frames are: a coarse frame comes first only when the next full frame is expected
/// later than [`COARSE_FRAME_AFTER`], since it delays the full frame, and it is made sparser
/// while coarse frames come later than [`COARSE_FRAME_BUDGET`].
#[derive(Default)]
pub struct Pace {
    last_full_frame: Option<(u64, Duration)>,
    /// Doublings of the coarse frame's step beyond [`densest_coarse_step`]: at most
    /// log2([`SPARSEST_COARSE_STEP`] / 2).
    coarse_doublings: u32,
}

/// A full frame expected later than this after its view gets a coarse frame first: the page
/// should show something of a new camera within 100 ms, and it takes up, decodes and draws a
/// frame about 10 ms after the server has it ready (docs/VIEWER.md, "Frames").
const COARSE_FRAME_AFTER: Duration = Duration::from_millis(80);

impl Pace {
    /// A full frame of `pixels` is expected later than [`COARSE_FRAME_AFTER`]: the last one,
    /// scaled by the pixels, was (or none came yet).
    fn needs_coarse_frame(&self, pixels: u64) -> bool {
        self.last_full_frame.is_none_or(|(last_pixels, took)| {
            let scale = pixels as f64 / last_pixels.max(1) as f64;
            took.mul_f64(scale) > COARSE_FRAME_AFTER
        })
    }

    /// The step of `view`'s coarse frame: [`densest_coarse_step`] doubled as the last coarse
    /// frames' times asked, at most [`SPARSEST_COARSE_STEP`].
    fn coarse_step(&self, view: &View) -> u32 {
        (densest_coarse_step(view) << self.coarse_doublings).min(SPARSEST_COARSE_STEP)
    }

    /// A coarse frame of `view` was ready `took` after its view arrived.
    fn coarse_frame(&mut self, view: &View, took: Duration) {
        if took > COARSE_FRAME_BUDGET {
            let most = (SPARSEST_COARSE_STEP / densest_coarse_step(view))
                .max(1)
                .ilog2();
            self.coarse_doublings = (self.coarse_doublings + 1).min(most);
        } else if took < COARSE_FRAME_BUDGET / 2 {
            self.coarse_doublings = self.coarse_doublings.saturating_sub(1);
        }
    }

    /// A full frame of `pixels` was ready `took` after its view arrived, less the time of the
    /// coarse frame made before it.
    fn full_frame(&mut self, pixels: u64, took: Duration) {
        self.last_full_frame = Some((pixels, took));
    }
}

/// A view's image was abandoned: the page asked for another view meanwhile.
pub struct Stale;

/// The rays a frame took and their tracing time.
#[derive(Clone, Copy, Default)]
struct Rays {
    rays: u64,
    seconds: f64,
}

impl Rays {
    fn of(image: &Progressive) -> Rays {
        let (rays, seconds) = image.rays_traced();
        Rays { rays, seconds }
    }

    /// These rays less those counted `before`.
    fn since(self, before: Rays) -> Rays {
        Rays {
            rays: self.rays - before.rays,
            seconds: self.seconds - before.seconds,
        }
    }
}

/// Fine pixels of a band of `scene`'s image: eight rows, so that a stale camera's leftover work
/// is a few milliseconds.
fn band_pixels(scene: &Scene) -> u32 {
    let image = &scene.image;
    image.width.saturating_mul(image.antialiasing.pow(2) * 8)
}

impl Viewer {
    /// The viewer of `tracer`'s file with `scene`, as written (for a z-up model).
    pub fn new(
        tracer: &'static Tracer<'static>,
        scene: Scene,
        up: UpAxis,
        token: String,
    ) -> Viewer {
        let mut y_up_scene = scene.clone();
        y_up_scene.turn_to_y_up();
        Viewer {
            tracer,
            z_up_scene: scene,
            y_up_scene,
            up,
            token,
            resident: ResidentBytes::of(tracer.file().path().to_path_buf()),
        }
    }

    /// The scene for a model whose up axis is `up`.
    fn scene(&self, up: UpAxis) -> &Scene {
        match up {
            UpAxis::Y => &self.y_up_scene,
            UpAxis::Z => &self.z_up_scene,
        }
    }

    /// The scene's camera for a model whose up axis is `up`, framed for a `width` × `height`
    /// image (the page's canvas) as `reducem render` frames its own image.
    pub fn framed_camera(&self, up: UpAxis, width: u32, height: u32) -> CameraView {
        let settings = &self.scene(up).camera;
        let (width, height) = (width.clamp(1, MAX_SIDE), height.clamp(1, MAX_SIDE));
        let (position, look_at) = placement(self.tracer, settings, width, height);
        CameraView {
            position: position.into(),
            look_at: look_at.into(),
            up: settings.up,
            fov: settings.fov_degrees,
        }
    }

    /// The effects the scene shades with, and which of them the file can show.
    pub fn scene_effects(&self) -> (Effects, Effects) {
        let scene = &self.z_up_scene;
        let shadows = casts_shadows(scene);
        let stored = self.tracer.file().attributes();
        let on = Effects {
            stored_normals: scene.shading.smooth,
            colors: scene.shading.vertex_colors,
            ambient_occlusion: scene.ambient_occlusion.is_some(),
            shadows,
            normals_view: scene.shading.mode == ShadingMode::Normals,
        };
        let available = Effects {
            stored_normals: stored.normals != NormalEncoding::None,
            colors: stored.colors,
            ambient_occlusion: true,
            shadows: !(scene.directional_light.is_empty() && scene.point_light.is_empty()),
            normals_view: true,
        };
        (on, available)
    }

    /// The scene of `view`: the viewer's scene with the view's camera and size; `None` for a
    /// view no scene could hold (a camera with no direction or roll, a size out of range).
    pub fn scene_of(&self, view: &View) -> Option<Scene> {
        let mut scene = self.scene(view.up.unwrap_or(self.up)).clone();
        let camera = &mut scene.camera;
        (camera.auto, camera.direction) = (false, None);
        camera.position = Some(view.camera.position);
        camera.look_at = Some(view.camera.look_at);
        camera.up = view.camera.up;
        camera.fov_degrees = view.camera.fov;
        (scene.image.width, scene.image.height) = (view.width, view.height);
        if let Some(effects) = view.effects {
            switch_effects(&mut scene, effects);
        }
        let sized = (1..=MAX_SIDE).contains(&view.width) && (1..=MAX_SIDE).contains(&view.height);
        (sized && scene.check().is_ok()).then_some(scene)
    }

    /// The frames of `view` in the order the page shows them: when `pace` expects a slow full
    /// frame, a coarse one of a quarter of the pixels or fewer ([`Pace::coarse_step`]) with
    /// primary shading (the rays of some of the full image's pixels); then the
    /// full-size image in rounds, as `reducem render` makes it: the first with primary shading
    /// and shadows, each further one with twice the AO samples, until the scene's count. Each
    /// goes to `deliver` as soon as it is ready; work stops when `generation` leaves `current`.
    pub fn render_progressively(
        &self,
        view: &View,
        received: Instant,
        (current, generation): (u64, &AtomicU64),
        pace: &mut Pace,
        mut deliver: impl FnMut(EncodedFrame),
    ) -> Result<(), Stale> {
        let Some(scene) = self.scene_of(view) else {
            return Ok(());
        };
        let is_current = || match generation.load(Ordering::Acquire) == current {
            true => Ok(()),
            false => Err(Stale),
        };
        let bands = band_pixels(&scene);
        let pixels = u64::from(view.width) * u64::from(view.height);
        let mut coarse_took = Duration::ZERO;
        if pace.needs_coarse_frame(pixels) {
            let started = Instant::now();
            let every = pace.coarse_step(view);
            // Bands of as many rows as the full image's.
            let coarse_bands = bands / (every * every);
            let mut coarse = Progressive::preview(self.tracer, &scene, every, coarse_bands);
            let mut stages = Stages::since(received);
            let srgb = coarse.refine_with(1, is_current, |rows| srgb_bytes_of(&rows))?;
            stages.end("traced");
            let rays = Rays::of(&coarse);
            let spp = 1.0 / (every * every) as f32;
            let image = (srgb, coarse.size());
            let encoded = self.encode(image, rays, view.camera, current, spp, stages);
            pace.coarse_frame(view, received.elapsed());
            deliver(encoded);
            coarse_took = started.elapsed();
        }
        let mut image = Progressive::new(self.tracer, &scene, bands);
        let (mut ao_samples, mut before) = (1, Rays::default());
        loop {
            let mut stages = Stages::since(received);
            let srgb = image.refine_with(ao_samples, is_current, |rows| srgb_bytes_of(&rows))?;
            stages.end("traced");
            let rays = Rays::of(&image).since(before);
            let spp = image.samples_per_pixel() as f32;
            let frame = (srgb, image.size());
            deliver(self.encode(frame, rays, view.camera, current, spp, stages));
            if ao_samples == 1 {
                // Without the coarse frame: whether the next view's full frame comes late
                // enough to need one.
                pace.full_frame(pixels, received.elapsed().saturating_sub(coarse_took));
            }
            self.resident.refresh_when_due();
            if image.is_complete() {
                return Ok(());
            }
            (ao_samples, before) = (ao_samples * 2, Rays::of(&image));
        }
    }

    /// The JPEG of an image's sRGB bytes and its width and height, with its header.
    fn encode(
        &self,
        (srgb, (width, height)): (Vec<u8>, (u32, u32)),
        rays: Rays,
        camera: CameraView,
        generation: u64,
        spp: f32,
        mut stages: Stages,
    ) -> EncodedFrame {
        let jpeg = jpeg::encode(&srgb, width as u16, height as u16, JPEG_QUALITY).unwrap_or_else(
            |error| {
                eprintln!("reducem view: encoding a frame: {error}");
                Vec::new()
            },
        );
        stages.end("jpeg");
        EncodedFrame {
            header: FrameHeader {
                generation,
                width,
                height,
                spp,
                camera,
                rays: rays.rays,
                seconds: rays.seconds,
                triangles: self.tracer.file().header().triangle_count,
                resident_bytes: self.resident.last(),
            },
            jpeg,
            stages,
        }
    }

    /// What the primary ray through pixel `(x, y)` of `view` hits, answered as `reducem query
    /// --format full` answers that ray.
    pub fn pick(&self, view: &View, x: u32, y: u32) -> Option<Pick> {
        let scene = self.scene_of(view)?;
        if x >= view.width || y >= view.height {
            return None;
        }
        let camera = Camera::new(self.tracer, &scene.camera, view.width, view.height);
        let ray = camera.primary_ray(x, y);
        let record = trace_hits_as(self.tracer, &[ray], HitFormat::Full);
        let f32_at =
            |index: usize| f32::from_le_bytes(record[index * 4..][..4].try_into().unwrap());
        let vector_at = |index: usize| [f32_at(index), f32_at(index + 1), f32_at(index + 2)];
        let distance = f32_at(0);
        let hit = distance.is_finite();
        let face_id = u32::from_le_bytes(record[12..16].try_into().unwrap());
        let attributes = self.tracer.file().attributes();
        let position = Vec3::from(ray.origin) + Vec3::from(ray.direction) * distance;
        Some(Pick {
            x,
            y,
            ray_origin: ray.origin,
            ray_direction: ray.direction,
            hit,
            distance: hit.then_some(distance),
            position: hit.then_some(position.into()),
            face_id: (hit && face_id != u32::MAX).then_some(face_id),
            normal: hit.then(|| vector_at(4)),
            stored_normal: (hit && attributes.normals != NormalEncoding::None)
                .then(|| vector_at(7)),
            color: (hit && attributes.colors).then(|| record[40..44].try_into().unwrap()),
        })
    }

    /// The scene file of `view` for `reducem render --up z` (its positions and directions are
    /// already the model's, turned for the up axis when the viewer's scene was).
    pub fn scene_toml(&self, view: &View) -> Option<String> {
        let scene = self.scene_of(view)?;
        let text = toml::to_string(&scene).ok()?;
        Some(format!(
            "# reducem render FILE --scene THIS.toml --up z -o image.png: the viewer's image\n{text}"
        ))
    }

    /// The PNG `reducem render` writes of `view` with the viewer's scene.
    pub fn png(&self, view: &View) -> Option<Vec<u8>> {
        let scene = self.scene_of(view)?;
        let mut png = Vec::new();
        let format = reducem::render::image::ImageFormat::Png;
        reducem::render::image::render_into(self.tracer, &scene, format, &mut png).ok()?;
        Some(png)
    }
}

/// What a click on the page shows: the ray through the pixel and what it hits.
#[derive(Debug, Serialize)]
pub struct Pick {
    pub x: u32,
    pub y: u32,
    pub ray_origin: [f32; 3],
    pub ray_direction: [f32; 3],
    pub hit: bool,
    pub distance: Option<f32>,
    pub position: Option<[f32; 3]>,
    /// The input face id, when the file stores face ids.
    pub face_id: Option<u32>,
    /// The geometric normal.
    pub normal: Option<[f32; 3]>,
    /// The interpolated stored normal, when the file has normals.
    pub stored_normal: Option<[f32; 3]>,
    /// The interpolated stored colour (RGBA), when the file has colours.
    pub color: Option<[u8; 4]>,
}

/// `scene` with the page's switches: an effect switched off is left out, one switched on that
/// the scene lacks is added (AO with its defaults, shadows from every light); the normals view
/// leaves out both.
fn switch_effects(scene: &mut Scene, effects: Effects) {
    scene.shading.smooth = effects.stored_normals;
    scene.shading.vertex_colors = effects.colors;
    scene.shading.mode = match effects.normals_view {
        true => ShadingMode::Normals,
        false => ShadingMode::Lit,
    };
    match effects.ambient_occlusion {
        false => scene.ambient_occlusion = None,
        true => _ = scene.ambient_occlusion.get_or_insert_default(),
    }
    if casts_shadows(scene) != effects.shadows {
        scene
            .directional_light
            .iter_mut()
            .for_each(|l| l.cast_shadows = effects.shadows);
        scene
            .point_light
            .iter_mut()
            .for_each(|l| l.cast_shadows = effects.shadows);
    }
    // The normals view shows no light: its image is the primary one, with no samples to add.
    if effects.normals_view {
        *scene = scene.primary_only();
    }
}

/// Some light of `scene` casts shadows.
fn casts_shadows(scene: &Scene) -> bool {
    let directional = scene.directional_light.iter().map(|l| l.cast_shadows);
    let point = scene.point_light.iter().map(|l| l.cast_shadows);
    directional.chain(point).any(|casts| casts)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(width: u32, height: u32) -> View {
        View {
            camera: CameraView {
                position: [0.0, -1.0, 0.0],
                look_at: [0.0; 3],
                up: [0.0, 0.0, 1.0],
                fov: 40.0,
            },
            width,
            height,
            effects: None,
            up: None,
        }
    }

    #[test]
    fn a_coarse_frame_has_a_quarter_of_the_pixels_or_at_most_128_squared() {
        let steps = [
            (64, 48),
            (512, 512),
            (513, 512),
            (1024, 768),
            (1024, 1024),
            (4096, 16),
            (16384, 16384),
        ];
        let steps = steps.map(|(width, height)| densest_coarse_step(&view(width, height)));
        assert_eq!(steps, [2, 4, 8, 8, 8, 2, 64]);
    }

    #[test]
    fn a_coarse_frame_is_made_sparser_while_coarse_frames_come_late_and_denser_when_fast() {
        let mut pace = Pace::default();
        let (full, quarter) = (view(512, 512), view(256, 256));
        let steps = |pace: &Pace| (pace.coarse_step(&full), pace.coarse_step(&quarter));
        assert_eq!(steps(&pace), (4, 2), "no coarse frame yet");
        let ms = Duration::from_millis;
        pace.coarse_frame(&full, ms(70));
        assert_eq!(steps(&pace), (4, 2));
        pace.coarse_frame(&full, ms(71));
        assert_eq!(steps(&pace), (8, 4));
        pace.coarse_frame(&full, ms(35));
        assert_eq!(steps(&pace), (8, 4), "neither late nor fast");
        pace.coarse_frame(&full, ms(34));
        assert_eq!(steps(&pace), (4, 2));
        pace.coarse_frame(&full, ms(34));
        assert_eq!(steps(&pace), (4, 2), "the densest");
        for _ in 0..10 {
            pace.coarse_frame(&full, ms(900));
        }
        assert_eq!(steps(&pace), (64, 32), "the sparsest");
        pace.coarse_frame(&full, ms(1));
        assert_eq!(steps(&pace), (32, 16));
    }

    #[test]
    fn a_coarse_frame_comes_first_unless_the_last_full_frame_scaled_to_the_view_came_fast() {
        let mut pace = Pace::default();
        let side = |pixels: u64| pixels * pixels;
        assert!(pace.needs_coarse_frame(side(512)), "no full frame yet");
        pace.full_frame(side(512), Duration::from_millis(80));
        assert!(!pace.needs_coarse_frame(side(512)));
        assert!(!pace.needs_coarse_frame(side(256)));
        assert!(pace.needs_coarse_frame(side(1024)), "four times the pixels");
        pace.full_frame(side(512), Duration::from_millis(81));
        assert!(pace.needs_coarse_frame(side(512)));
        pace.full_frame(side(1024), Duration::from_millis(200));
        assert!(
            !pace.needs_coarse_frame(side(256)),
            "a sixteenth of the pixels"
        );
    }
}

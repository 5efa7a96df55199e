//! `reducem render`: images of a ReduceM file with primary shading, shadows and ambient occlusion.
//!
//! The scene ([`scene`]) is turned into a [`plan::Plan`] and each planned effect is one pass over
//! the image, timed and counted on its own: primary rays (packets: they are coherent), shadow
//! rays per shadow-casting light (packets: rays towards one light are coherent too), then AO rays
//! (single rays: random hemisphere directions are incoherent, as the paper notes for secondary
//! effects). Passes run over 8×8-pixel tiles with rayon; every pixel's value depends only on its
//! own rays and stateless samples, so the image is identical for any thread count.
//!
//! The image is rendered in bands of whole tile rows, each band through every pass and handed
//! on as finished rows ([`render_rows`]) before the next begins: the passes' per-pixel state
//! (about 110 bytes a pixel) is held for one band, never for the whole image, and the image is
//! the same as rendered whole. The viewer refines an image in rounds instead ([`Progressive`]):
//! the same passes and per-pixel accumulation, AO samples added a round at a time.
//!
//! Shading is Lambertian with a two-sided normal: `albedo × colour × (ambient × AO + Σ lights
//! intensity × cos θ × visibility / falloff)`, point lights falling off with squared distance,
//! times the exposure through the scene's tone curve, then sRGB-encoded to 8-bit PNG
//! ([`image`]). The normal is the geometric one, or the stored vertex normals interpolated when
//! the file has them; the colour is white, or the stored vertex colours interpolated
//! ([`attributes`]). An automatic camera without a direction is framed by [`framing`].

pub mod attributes;
pub mod camera;
pub mod framing;
pub mod image;
pub mod memory;
pub mod plan;
pub mod rays;
pub mod residency;
pub mod sampling;
pub mod scene;

use std::fmt;
use std::ops::Range;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::geometry::Aabb;
use crate::trace::{Ray, Tracer};
use attributes::AttributeUse;
use camera::Camera;
use plan::{AoPlan, Light, LightSource, Plan};
use residency::Residency;
use sampling::Surface;
use scene::{Scene, Shading, ShadingMode};

/// Tile edge in pixels: 64 rays, eight packets of [`PACKET_COLUMNS`] × [`PACKET_ROWS`] pixels.
const TILE: u32 = 8;

/// A packet's pixels across: consecutive rays form packets, so a tile lists its pixels in
/// blocks of `PACKET_COLUMNS` × [`PACKET_ROWS`], blocks in row-major order. Compact blocks keep
/// a packet's rays together deeper in the hierarchy than a row of eight: with 4 × 2 blocks,
/// 1,048,576 camera rays on the 10M scan took 3.9% of `reducem query`'s CPU time less than with
/// 2 × 4 blocks and 7.4% less than with rows of eight (`perf stat` task-clock, 1 thread,
/// medians of 3 runs of the rays four times over: 763, 777 and 825 ms).
const PACKET_COLUMNS: u32 = 4;

/// A packet's pixels down (see [`PACKET_COLUMNS`]).
const PACKET_ROWS: u32 = 2;

/// A rendered image in linear RGB, row-major from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

/// Rays and time of one effect.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EffectReport {
    pub effect: &'static str,
    pub rays: u64,
    pub seconds: f64,
}

/// What `reducem render` prints.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RenderReport {
    pub width: u32,
    pub height: u32,
    pub effects: Vec<EffectReport>,
    /// Shadow rays per light (directional lights first, then point lights, in scene order).
    pub shadow_rays_per_light: Vec<u64>,
    pub total_rays: u64,
    pub trace_seconds: f64,
    pub mrays_per_second: f64,
    /// The tracer's SIMD kernel (`sse2`, `avx2`).
    pub kernel: String,
    pub memory: Residency,
}

impl RenderReport {
    pub fn rays_of(&self, effect: &str) -> u64 {
        self.effects
            .iter()
            .filter(|e| e.effect == effect)
            .map(|e| e.rays)
            .sum()
    }
}

/// Renders `scene` with `tracer`; also measures residency of the file afterwards. With
/// `[image] antialiasing = n`, renders n × n samples per pixel on a finer image and averages
/// them (an ordered grid: every sample is an ordinary pixel of the finer image, so the result is
/// as reproducible as one sample).
pub fn render(tracer: &Tracer, scene: &Scene) -> (Frame, RenderReport) {
    let (width, height) = (scene.image.width, scene.image.height);
    let mut pixels = Vec::with_capacity(width as usize * height as usize);
    let report = render_rows(tracer, scene, RowOrder::TopDown, |rows| {
        pixels.extend_from_slice(rows);
        Ok::<(), std::convert::Infallible>(())
    });
    let frame = Frame {
        width,
        height,
        pixels,
    };
    (frame, report.unwrap_or_else(|never| match never {}))
}

/// The order [`render_rows`] hands on the image's rows in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowOrder {
    /// Bands from the top, each band's rows from the top.
    TopDown,
    /// Bands from the bottom, each band's rows still from the top (as PFM writes them, bottom
    /// up, a band's rows are then reversed by the writer).
    BandsBottomUp,
}

/// Renders `scene` with `tracer` band by band, handing each band's finished pixels (whole rows,
/// row-major from the band's top) to `rows` before the next band is rendered, bands in `order`;
/// the report, with residency measured afterwards. With `[image] antialiasing = n`, renders n ×
/// n samples per pixel on a finer image and averages them (an ordered grid: every sample is an
/// ordinary pixel of the finer image, so the result is as reproducible as one sample).
pub fn render_rows<E>(
    tracer: &Tracer,
    scene: &Scene,
    order: RowOrder,
    rows: impl FnMut(&[[f32; 3]]) -> Result<(), E>,
) -> Result<RenderReport, E> {
    render_in_bands(tracer, scene, order, BAND_PIXELS, rows)
}

/// [`render_rows`] in bands of about `band_pixels` fine pixels: smaller bands let a caller
/// abandon an image sooner, by returning an error from `rows`.
pub fn render_in_bands<E>(
    tracer: &Tracer,
    scene: &Scene,
    order: RowOrder,
    band_pixels: u32,
    mut rows: impl FnMut(&[[f32; 3]]) -> Result<(), E>,
) -> Result<RenderReport, E> {
    let factor = scene.image.antialiasing.max(1);
    let renderer = BandRenderer::new(tracer, &fine_scene(scene));
    let mut effects = renderer.effects();
    let (fine_width, fine_height) = (renderer.plan.width, renderer.plan.height);
    let mut bands = bands(fine_width, fine_height, factor, band_pixels);
    if order == RowOrder::BandsBottomUp {
        bands.reverse();
    }
    for band in bands {
        let mut samples = BandSamples::untraced(fine_width, band);
        renderer.trace_band(&mut samples, &mut effects);
        renderer.add_ao_samples(&mut samples, renderer.ao_samples(), &mut effects);
        rows(&renderer.finished_rows(&samples, factor))?;
    }
    Ok(renderer.report(scene, effects))
}

/// `scene` on its finer image of `[image] antialiasing` × as many pixels each way.
fn fine_scene(scene: &Scene) -> Scene {
    let factor = scene.image.antialiasing.max(1);
    let mut fine = scene.clone();
    fine.image.width *= factor;
    fine.image.height *= factor;
    fine
}

/// An image refined in rounds, as the viewer shows it: the first round traces the primary rays
/// and shadows and each round adds ambient-occlusion samples, until the scene's count. The
/// passes and the per-pixel accumulation are [`render_in_bands`]'s, so the last round's image is
/// `reducem render`'s, bit for bit (a pixel's open AO rays are counted, and divided by the
/// samples traced only when shading).
pub struct Progressive<'a, 'f> {
    renderer: BandRenderer<'a, 'f>,
    scene: Scene,
    bands: Vec<BandSamples>,
    effects: Vec<EffectReport>,
}

impl<'a, 'f> Progressive<'a, 'f> {
    /// `scene`'s image with nothing traced yet, in bands of about `band_pixels` fine pixels
    /// (between bands a round may be abandoned).
    pub fn new(tracer: &'a Tracer<'f>, scene: &Scene, band_pixels: u32) -> Progressive<'a, 'f> {
        Progressive::of(
            BandRenderer::new(tracer, &fine_scene(scene)),
            scene,
            band_pixels,
        )
    }

    /// A preview of `scene`'s image: every `every`-th pixel each way (2: half its width and
    /// height), primary shading, each pixel `(x, y)` the ray and shade of pixel `(every x, every
    /// y)` of the image (of its finer image's pixel `(every n x, every n y)` with `antialiasing
    /// = n`): a coarse frame that shows the image's own pixels.
    pub fn preview(
        tracer: &'a Tracer<'f>,
        scene: &Scene,
        every: u32,
        band_pixels: u32,
    ) -> Progressive<'a, 'f> {
        let fine = fine_scene(scene);
        let (width, height) = (fine.image.width, fine.image.height);
        let every = every.max(1);
        let step = every * scene.image.antialiasing.max(1);
        let camera = Camera::new(tracer, &fine.camera, width, height).every_nth_pixel(step);
        let mut preview = scene.primary_only();
        preview.image.width = scene.image.width.div_ceil(every);
        preview.image.height = scene.image.height.div_ceil(every);
        let renderer = BandRenderer::with_camera(tracer, &preview, camera);
        Progressive::of(renderer, &preview, band_pixels)
    }

    /// The image `renderer` renders of `scene`, with nothing traced yet.
    fn of(renderer: BandRenderer<'a, 'f>, scene: &Scene, band_pixels: u32) -> Progressive<'a, 'f> {
        let effects = renderer.effects();
        let (width, height) = (renderer.plan.width, renderer.plan.height);
        let factor = scene.image.antialiasing.max(1);
        // Listed on the tracing threads: a 512² image's 4,096 tiles are thousands of small lists.
        let bands = bands(width, height, factor, band_pixels)
            .into_par_iter()
            .map(|rows| BandSamples::untraced(width, rows))
            .collect();
        Progressive {
            renderer,
            scene: scene.clone(),
            bands,
            effects,
        }
    }

    /// Samples per pixel of the image so far: the antialiasing samples, times the AO samples
    /// traced when the scene has AO; 0 before the first round.
    pub fn samples_per_pixel(&self) -> u32 {
        let ao = match self.renderer.plan.ambient_occlusion {
            Some(_) => self.ao_samples_done(),
            None => u32::from(self.traced()),
        };
        self.scene.image.antialiasing.max(1).pow(2) * ao
    }

    /// Every band's primary and shadow passes ran.
    fn traced(&self) -> bool {
        self.bands.iter().all(|band| band.traced)
    }

    /// The AO samples every band has (a round abandoned midway leaves some bands ahead).
    fn ao_samples_done(&self) -> u32 {
        let done = self.bands.iter().map(|band| band.ao_samples.end).min();
        done.unwrap_or(0)
    }

    /// Every sample the scene declares is in the image.
    pub fn is_complete(&self) -> bool {
        self.traced() && self.ao_samples_done() == self.renderer.ao_samples().end
    }

    /// The image's width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.scene.image.width, self.scene.image.height)
    }

    /// One more round: the primary rays and shadows when not yet traced, and AO samples up to
    /// `ao_samples_until` (at most the scene's); `before_band` is asked before each band and
    /// its error abandons the round (the bands already begun are finished). The image after the
    /// round.
    pub fn refine<E: Send>(
        &mut self,
        ao_samples_until: u32,
        before_band: impl Fn() -> Result<(), E> + Sync,
    ) -> Result<Frame, E> {
        let pixels = self.refine_with(ao_samples_until, before_band, |rows| rows)?;
        let (width, height) = self.size();
        Ok(Frame {
            width,
            height,
            pixels,
        })
    }

    /// [`Progressive::refine`], each band's finished rows turned by `finish` on the band's
    /// thread (the viewer's sRGB bytes), the bands' results in the image's order.
    ///
    /// The bands run side by side, each band's passes one after another, so that a round joins
    /// its threads once: a join per pass and band (two a band for the viewer's primary frame)
    /// left one core idle at each while the other finished its last tiles.
    pub fn refine_with<E: Send, T: Send>(
        &mut self,
        ao_samples_until: u32,
        before_band: impl Fn() -> Result<(), E> + Sync,
        finish: impl Fn(Vec<[f32; 3]>) -> Vec<T> + Sync,
    ) -> Result<Vec<T>, E> {
        let renderer = &self.renderer;
        let until = ao_samples_until.min(renderer.ao_samples().end);
        let factor = self.scene.image.antialiasing.max(1);
        let started = Instant::now();
        let bands: Vec<Result<FinishedBand<T>, E>> = self
            .bands
            .par_iter_mut()
            .map(|band| {
                before_band()?;
                let band_started = Instant::now();
                let mut effects = renderer.effects();
                if !band.traced {
                    renderer.trace_band(band, &mut effects);
                }
                let samples = band.ao_samples.end..until.max(band.ao_samples.end);
                renderer.add_ao_samples(band, samples, &mut effects);
                let values = finish(renderer.finished_rows(band, factor));
                let seconds = band_started.elapsed().as_secs_f64();
                Ok(FinishedBand {
                    values,
                    effects,
                    seconds,
                })
            })
            .collect();
        let mut round = Round {
            effects: renderer.effects(),
            band_seconds: 0.0,
            wall_seconds: 0.0,
        };
        let mut values = Vec::new();
        let mut abandoned = None;
        for band in bands {
            match band {
                Ok(band) => {
                    values.extend(band.values);
                    round.add(band.effects, band.seconds);
                }
                Err(error) => abandoned = abandoned.or(Some(error)),
            }
        }
        round.wall_seconds = started.elapsed().as_secs_f64();
        round.add_to(&mut self.effects);
        match abandoned {
            Some(error) => Err(error),
            None => Ok(values),
        }
    }

    /// The rays of every round so far and their tracing time in seconds: [`Progressive::report`]
    /// without its residency, whose measure reads the process's whole memory map.
    pub fn rays_traced(&self) -> (u64, f64) {
        let rays = self.effects.iter().map(|e| e.rays).sum();
        (rays, self.effects.iter().map(|e| e.seconds).sum())
    }

    /// The rays and times of every round so far, with residency measured now.
    pub fn report(&self) -> RenderReport {
        self.renderer.report(&self.scene, self.effects.clone())
    }
}

/// A band of a round, done: its finished rows as the caller asked, its passes' rays and times,
/// and the seconds it took in all.
struct FinishedBand<T> {
    values: Vec<T>,
    effects: Vec<EffectReport>,
    seconds: f64,
}

/// A round's passes summed over its bands, with the bands' seconds in all and the round's.
struct Round {
    effects: Vec<EffectReport>,
    band_seconds: f64,
    wall_seconds: f64,
}

impl Round {
    fn add(&mut self, effects: Vec<EffectReport>, band_seconds: f64) {
        for (sum, effect) in self.effects.iter_mut().zip(effects) {
            sum.rays += effect.rays;
            sum.seconds += effect.seconds;
        }
        self.band_seconds += band_seconds;
    }

    /// The round's rays added to `effects`, and its wall time as the passes' share of it: bands
    /// ran side by side, so their summed times are the threads', not the round's.
    fn add_to(self, effects: &mut [EffectReport]) {
        let scale = match self.band_seconds > 0.0 {
            true => self.wall_seconds / self.band_seconds,
            false => 0.0,
        };
        for (sum, effect) in effects.iter_mut().zip(self.effects) {
            sum.rays += effect.rays;
            sum.seconds += effect.seconds * scale;
        }
    }
}

/// Fine pixels a band holds, unless its fewest rows are more: about 40 MB of per-pixel state,
/// and thousands of tiles to share among the cores.
const BAND_PIXELS: u32 = 1 << 18;

/// Bytes of the passes' buffers per pixel of a band, at most: surfaces and their tile copies,
/// visibility and occlusion with their ray counts, the shaded pixels.
pub(crate) const PIXEL_STATE_BYTES: u64 = 160;

/// The bands of a `width` × `height` (fine) image, about `pixels` each: whole tile rows, each a
/// whole number of `factor` rows so that antialiasing averages within a band, and tiles the
/// same as in one band.
fn bands(width: u32, height: u32, factor: u32, pixels: u32) -> Vec<Range<u32>> {
    let rows = band_rows(width, factor, pixels);
    (0..height)
        .step_by(rows as usize)
        .map(|top| top..(top + rows).min(height))
        .collect()
}

/// Rows of a band of a `width` (fine) image: about `pixels`, a multiple of the tile and of the
/// antialiasing factor.
fn band_rows(width: u32, factor: u32, pixels: u32) -> u32 {
    let step = lcm(TILE, factor);
    (pixels / width.max(1)).max(1).div_ceil(step) * step
}

/// Pixels of the largest band [`render_rows`] renders of a `width` × `height` (fine) image.
pub(crate) fn band_pixels(width: u32, height: u32, factor: u32) -> u64 {
    u64::from(band_rows(width, factor, BAND_PIXELS).min(height)) * u64::from(width)
}

fn lcm(a: u32, b: u32) -> u32 {
    let gcd = |mut a: u32, mut b: u32| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    a / gcd(a, b) * b
}

/// Each `factor` × `factor` block of the rows `samples` (`fine_width` across) averaged into one
/// pixel.
fn averaged(samples: &[[f32; 3]], fine_width: u32, factor: u32) -> Vec<[f32; 3]> {
    let fine_height = samples.len() as u32 / fine_width;
    let (width, height) = (fine_width / factor, fine_height / factor);
    let weight = 1.0 / (factor * factor) as f32;
    (0..width * height)
        .map(|index| {
            let (x, y) = (index % width * factor, index / width * factor);
            let mut sum = [0.0f32; 3];
            for sample_y in y..y + factor {
                for sample_x in x..x + factor {
                    let sample = samples[(sample_y * fine_width + sample_x) as usize];
                    sum = std::array::from_fn(|c| sum[c] + sample[c]);
                }
            }
            sum.map(|channel| channel * weight)
        })
        .collect()
}

/// What every band of one image shares: the scene, the plan, the camera, the attributes the
/// shading uses.
struct BandRenderer<'a, 'f> {
    tracer: &'a Tracer<'f>,
    scene: Scene,
    plan: Plan,
    camera: Camera,
    used: AttributeUse,
}

/// A band's per-pixel state after its passes: surfaces, visibility per light, and the AO rays
/// of the samples traced so far that found the hemisphere open.
struct BandSamples {
    band: Band,
    /// The primary and shadow passes ran.
    traced: bool,
    surfaces: Vec<Option<Surface>>,
    visibility: Vec<Vec<f32>>,
    open_rays: Vec<u32>,
    ao_samples: Range<u32>,
}

impl BandSamples {
    fn untraced(width: u32, rows: Range<u32>) -> BandSamples {
        BandSamples {
            band: Band::new(width, rows),
            traced: false,
            surfaces: Vec::new(),
            visibility: Vec::new(),
            open_rays: Vec::new(),
            ao_samples: 0..0,
        }
    }
}

impl<'a, 'f> BandRenderer<'a, 'f> {
    /// The renderer of one sample per pixel of `scene`'s image.
    fn new(tracer: &'a Tracer<'f>, scene: &Scene) -> BandRenderer<'a, 'f> {
        let (width, height) = (scene.image.width, scene.image.height);
        let camera = Camera::new(tracer, &scene.camera, width, height);
        BandRenderer::with_camera(tracer, scene, camera)
    }

    /// The renderer of `scene`'s image seen by `camera`.
    fn with_camera(tracer: &'a Tracer<'f>, scene: &Scene, camera: Camera) -> BandRenderer<'a, 'f> {
        let file = tracer.file();
        let header = file.header();
        let bounds = Aabb {
            min: header.bounds_min,
            max: header.bounds_max,
        };
        let plan = Plan::new(scene, &bounds, &camera);
        let used = AttributeUse::new(file.attributes(), &scene.shading);
        BandRenderer {
            tracer,
            scene: scene.clone(),
            plan,
            camera,
            used,
        }
    }

    /// The passes the plan asks for, in order, with nothing traced yet.
    fn effects(&self) -> Vec<EffectReport> {
        let effect = |effect: &'static str| EffectReport {
            effect,
            rays: 0,
            seconds: 0.0,
        };
        let shadows = self.plan.shadow_lights.iter().map(|_| effect("shadows"));
        std::iter::once(effect("primary"))
            .chain(shadows)
            .chain(
                self.plan
                    .ambient_occlusion
                    .map(|_| effect("ambient_occlusion")),
            )
            .collect()
    }

    /// The AO sample indices the scene declares (none without AO).
    fn ao_samples(&self) -> Range<u32> {
        0..self.plan.ambient_occlusion.map_or(0, |ao| ao.samples)
    }

    /// The primary and shadow passes over `samples`' band, each pass's rays and time added to
    /// `effects` (in the order of [`BandRenderer::effects`]); the band's AO samples start again.
    fn trace_band(&self, samples: &mut BandSamples, effects: &mut [EffectReport]) {
        let (tracer, plan) = (self.tracer, &self.plan);
        let band = &samples.band;
        let started = Instant::now();
        let points = plan.needs_hit_points();
        let (surfaces, rays) = primary_pass(tracer, &self.camera, band, self.used, points);
        account(&mut effects[0], rays, started);

        let mut visibility = vec![Vec::new(); plan.lights.len()];
        for (pass, &light) in plan.shadow_lights.iter().enumerate() {
            let started = Instant::now();
            let (visible, rays) = shadow_pass(tracer, &plan.lights[light], &surfaces, band);
            visibility[light] = visible;
            account(&mut effects[1 + pass], rays, started);
        }
        samples.open_rays = vec![0; band.pixel_count()];
        samples.traced = true;
        samples.surfaces = surfaces;
        samples.visibility = visibility;
        samples.ao_samples = 0..0;
    }

    /// The AO rays of sample indices `samples` (following those traced) added to `band`'s.
    fn add_ao_samples(
        &self,
        band: &mut BandSamples,
        samples: Range<u32>,
        effects: &mut [EffectReport],
    ) {
        let Some(ao) = self.plan.ambient_occlusion.filter(|_| !samples.is_empty()) else {
            return;
        };
        debug_assert_eq!(band.ao_samples.end, samples.start);
        let started = Instant::now();
        let seed = self.scene.shading.seed;
        let (open, rays) = ao_pass(self.tracer, &ao, seed, samples.clone(), band);
        for (sum, open) in band.open_rays.iter_mut().zip(open) {
            *sum += open;
        }
        band.ao_samples.end = samples.end;
        let last = effects.len() - 1;
        account(&mut effects[last], rays, started);
    }

    /// The shaded pixels of `band` with the samples traced so far, each `factor` × `factor`
    /// block of them averaged into one.
    fn finished_rows(&self, band: &BandSamples, factor: u32) -> Vec<[f32; 3]> {
        let samples = self.shade_band(band);
        match factor {
            1 => samples,
            _ => averaged(&samples, self.plan.width, factor),
        }
    }

    fn shade_band(&self, band: &BandSamples) -> Vec<[f32; 3]> {
        let shading = &self.scene.shading;
        if shading.mode == ShadingMode::Normals {
            return normal_colors(shading, &band.surfaces);
        }
        let traced = band.ao_samples.len() as f32;
        let open_fraction: Option<Vec<f32>> = (!band.ao_samples.is_empty())
            .then(|| band.open_rays.iter().map(|&o| o as f32 / traced).collect());
        let lights = &band.visibility;
        shade(
            &self.scene,
            &self.plan,
            &band.surfaces,
            lights,
            open_fraction.as_deref(),
        )
    }

    /// The report of the whole image of `scene` (the scene as asked for, before antialiasing's
    /// finer image), its passes' `effects` summed over the bands.
    fn report(&self, scene: &Scene, effects: Vec<EffectReport>) -> RenderReport {
        let file = self.tracer.file();
        let mut shadow_rays_per_light = vec![0; self.plan.lights.len()];
        for (&light, effect) in self.plan.shadow_lights.iter().zip(&effects[1..]) {
            shadow_rays_per_light[light] = effect.rays;
        }
        let total_rays = effects.iter().map(|e| e.rays).sum();
        let trace_seconds = effects.iter().map(|e| e.seconds).sum::<f64>();
        RenderReport {
            width: scene.image.width,
            height: scene.image.height,
            effects,
            shadow_rays_per_light,
            total_rays,
            trace_seconds,
            mrays_per_second: total_rays as f64 / trace_seconds.max(1e-9) / 1e6,
            kernel: self.tracer.options().kernel.to_string(),
            memory: residency::measure(file.path(), file.file_bytes()),
        }
    }
}

/// `rays` traced since `started` added to `effect`.
fn account(effect: &mut EffectReport, rays: u64, started: Instant) {
    effect.rays += rays;
    effect.seconds += started.elapsed().as_secs_f64();
}

/// A band of whole image rows: its tiles, by the image's pixel indices, and where its pixels
/// start in the image.
struct Band {
    width: u32,
    tiles: Vec<Vec<u32>>,
    first_pixel: u32,
    pixel_count: usize,
}

impl Band {
    fn new(width: u32, rows: Range<u32>) -> Band {
        Band {
            width,
            tiles: tiles_of_rows(width, rows.clone()),
            first_pixel: rows.start * width,
            pixel_count: rows.len() * width as usize,
        }
    }

    fn pixel_count(&self) -> usize {
        self.pixel_count
    }

    /// The index in the band's buffers of the image's pixel `pixel`.
    fn local(&self, pixel: u32) -> usize {
        (pixel - self.first_pixel) as usize
    }
}

/// Pixel indices of each 8×8 tile, tiles in row-major order, each tile's pixels in packet
/// blocks ([`PACKET_COLUMNS`]): the order passes trace pixels in.
pub fn tiles(width: u32, height: u32) -> Vec<Vec<u32>> {
    tiles_of_rows(width, 0..height)
}

/// [`tiles`] of the image's `rows` (the first a multiple of [`TILE`]), by the image's pixel
/// indices.
fn tiles_of_rows(width: u32, rows: Range<u32>) -> Vec<Vec<u32>> {
    let mut tiles = Vec::new();
    for tile_y in rows.clone().step_by(TILE as usize) {
        for tile_x in (0..width).step_by(TILE as usize) {
            let tile_rows = tile_y..(tile_y + TILE).min(rows.end);
            let columns = tile_x..(tile_x + TILE).min(width);
            tiles.push(tile_pixels(width, tile_rows, columns));
        }
    }
    tiles
}

/// The pixels of the tile spanning `rows` and `columns`, block after block
/// ([`PACKET_COLUMNS`]); blocks cut by the image's edge keep the pixels inside it.
fn tile_pixels(width: u32, rows: Range<u32>, columns: Range<u32>) -> Vec<u32> {
    let mut pixels = Vec::with_capacity((TILE * TILE) as usize);
    for band in rows.clone().step_by(PACKET_ROWS as usize) {
        for block in columns.clone().step_by(PACKET_COLUMNS as usize) {
            for y in band..(band + PACKET_ROWS).min(rows.end) {
                for x in block..(block + PACKET_COLUMNS).min(columns.end) {
                    pixels.push(y * width + x);
                }
            }
        }
    }
    pixels
}

/// Runs `per_tile` over every tile of `band` in parallel and scatters its per-pixel results into
/// the band's buffer; the placement depends only on pixel indices, never on scheduling.
fn over_tiles<T, F>(band: &Band, per_tile: F) -> Vec<T>
where
    T: Clone + Default + Send,
    F: Fn(&[u32]) -> Vec<T> + Sync,
{
    let results: Vec<Vec<T>> = band.tiles.par_iter().map(|tile| per_tile(tile)).collect();
    let mut pixels = vec![T::default(); band.pixel_count()];
    for (tile, values) in band.tiles.iter().zip(results) {
        for (&pixel, value) in tile.iter().zip(values) {
            pixels[band.local(pixel)] = value;
        }
    }
    pixels
}

/// The surface each pixel of `band` sees, and the rays traced: every pixel's ray, tile by tile
/// in the tile's order (packets of neighbouring pixels); with the hits' points when `points`
/// (else [`Surface::facing`]).
fn primary_pass(
    tracer: &Tracer,
    camera: &Camera,
    band: &Band,
    used: AttributeUse,
    points: bool,
) -> (Vec<Option<Surface>>, u64) {
    let (file, width) = (tracer.file(), band.width);
    let surfaces = over_tiles(band, |tile| {
        let rays: Vec<Ray> = tile
            .iter()
            .map(|&p| camera.primary_ray(p % width, p / width))
            .collect();
        let hits = tracer.intersect_chunk(&rays);
        rays.iter()
            .zip(hits)
            .map(|(ray, hit)| {
                let hit = hit?;
                let surface = match points {
                    true => Surface::at_hit(file, ray, &hit)?,
                    false => Surface::facing(ray, &hit),
                };
                Some(surface.with_attributes(file, &hit, used))
            })
            .collect()
    });
    (surfaces, band.pixel_count() as u64)
}

/// The shadow ray from a surface to a light, if the surface faces the light by its geometric
/// normal (a ray below the triangle's plane would only hit the triangle itself).
fn shadow_ray(light: &Light, surface: &Surface) -> Option<Ray> {
    let (direction, tmax) = match light.source {
        LightSource::Directional { toward_light } => (toward_light, f32::INFINITY),
        // Unnormalised: t = 1 is the light itself.
        LightSource::Point { position } => (position - surface.origin, 1.0),
    };
    (direction.dot(surface.normal) > 0.0).then(|| Ray {
        origin: surface.origin.into(),
        direction: direction.into(),
        tmin: 0.0,
        tmax,
    })
}

/// Visibility of `light` per pixel (1 lit, 0 shadowed) and the rays traced.
fn shadow_pass(
    tracer: &Tracer,
    light: &Light,
    surfaces: &[Option<Surface>],
    band: &Band,
) -> (Vec<f32>, u64) {
    let per_pixel: Vec<(f32, u64)> = over_tiles(band, |tile| {
        let rays: Vec<Option<Ray>> = tile
            .iter()
            .map(|&p| surfaces[band.local(p)].and_then(|s| shadow_ray(light, &s)))
            .collect();
        let traced: Vec<Ray> = rays.iter().flatten().copied().collect();
        let mut occluded = tracer.occluded_chunk(&traced).into_iter();
        rays.iter()
            .map(|ray| match ray {
                Some(_) => (
                    if occluded.next() == Some(true) {
                        0.0
                    } else {
                        1.0
                    },
                    1,
                ),
                None => (0.0, 0),
            })
            .collect()
    });
    let rays = per_pixel.iter().map(|&(_, r)| r).sum();
    (per_pixel.into_iter().map(|(v, _)| v).collect(), rays)
}

/// Per pixel of `band`, its AO rays of sample indices `samples` that found the hemisphere open,
/// and the rays traced. A tile's AO rays are traced as one batch ([`Tracer::occluded_chunk`]:
/// grouped by octant into packets), which answers exactly as ray by ray.
fn ao_pass(
    tracer: &Tracer,
    ao: &AoPlan,
    seed: u32,
    samples: Range<u32>,
    band: &BandSamples,
) -> (Vec<u32>, u64) {
    let surfaces = &band.surfaces;
    let band = &band.band;
    let per_pixel: Vec<(u32, u64)> = over_tiles(band, |tile| {
        let rays: Vec<Ray> = tile
            .iter()
            .filter_map(|&pixel| surfaces[band.local(pixel)].map(|surface| (pixel, surface)))
            .flat_map(|(pixel, surface)| {
                samples
                    .clone()
                    .map(move |s| surface.ao_ray(seed, pixel, s, ao.max_distance))
            })
            .collect();
        let mut occluded = tracer.occluded_chunk(&rays).into_iter();
        tile.iter()
            .map(|&pixel| match surfaces[band.local(pixel)] {
                Some(_) => {
                    let traced = samples.len();
                    let open = occluded.by_ref().take(traced).filter(|&o| !o).count();
                    (open as u32, traced as u64)
                }
                None => (0, 0),
            })
            .collect()
    });
    let rays = per_pixel.iter().map(|&(_, r)| r).sum();
    (per_pixel.into_iter().map(|(open, _)| open).collect(), rays)
}

/// The pixels' linear RGB: each surface lit, times the exposure through the tone curve (the
/// background too).
fn shade(
    scene: &Scene,
    plan: &Plan,
    surfaces: &[Option<Surface>],
    visibility: &[Vec<f32>],
    ambient_open: Option<&[f32]>,
) -> Vec<[f32; 3]> {
    let shading = &scene.shading;
    let (exposure, tone_curve) = (shading.exposure, shading.tone_curve);
    let toned = |pixel: [f32; 3]| pixel.map(|channel| tone_curve.apply(channel * exposure));
    let albedo = Vec3::from(shading.albedo);
    (0..surfaces.len())
        .into_par_iter()
        .map(|pixel| {
            let Some(surface) = surfaces[pixel] else {
                return toned(shading.background);
            };
            let open = ambient_open.map_or(1.0, |a| a[pixel]);
            let mut light_sum = shading.ambient * open;
            for (index, light) in plan.lights.iter().enumerate() {
                let lit = visibility[index].get(pixel).copied().unwrap_or(1.0);
                light_sum += lit * irradiance(light, &surface);
            }
            toned((albedo * surface.color * light_sum).into())
        })
        .collect()
}

/// The normals view: each pixel's geometric normal as the linear RGB whose sRGB codes are the
/// components mapped from [-1, 1] to [0, 255]; the background as the scene gives it.
fn normal_colors(shading: &Shading, surfaces: &[Option<Surface>]) -> Vec<[f32; 3]> {
    surfaces
        .iter()
        .map(|surface| match surface {
            Some(surface) => surface.normal.to_array().map(|component| {
                let code = ((component.clamp(-1.0, 1.0) * 0.5 + 0.5) * 255.0 + 0.5) as u8;
                attributes::srgb_to_linear(code)
            }),
            None => shading.background,
        })
        .collect()
}

/// Unshadowed irradiance of `light` at a surface, by its shading normal.
fn irradiance(light: &Light, surface: &Surface) -> f32 {
    let normal = surface.shading_normal;
    match light.source {
        LightSource::Directional { toward_light } => {
            light.intensity * toward_light.dot(normal).max(0.0)
        }
        LightSource::Point { position } => {
            let offset = position - surface.origin;
            let distance_squared = offset.length_squared().max(f32::MIN_POSITIVE);
            let cosine = offset.normalize_or_zero().dot(normal).max(0.0);
            light.intensity * cosine / distance_squared
        }
    }
}

impl fmt::Display for RenderReport {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        writeln!(f, "rendered {}x{}", self.width, self.height)?;
        for effect in &self.effects {
            writeln!(
                f,
                "  {:<18} {:>12} rays  {:>8.3} s  {:>8.2} Mrays/s",
                effect.effect,
                effect.rays,
                effect.seconds,
                effect.rays as f64 / effect.seconds.max(1e-9) / 1e6
            )?;
        }
        writeln!(
            f,
            "  {:<18} {:>12} rays  {:>8.3} s  {:>8.2} Mrays/s",
            "total", self.total_rays, self.trace_seconds, self.mrays_per_second
        )?;
        writeln!(f, "  kernel             {}", self.kernel)?;
        let mib = |bytes: u64| bytes as f64 / (1024.0 * 1024.0);
        let optional = |bytes: Option<u64>| {
            bytes.map_or("unknown".to_string(), |b| format!("{:.1} MiB", mib(b)))
        };
        writeln!(
            f,
            "  memory: file {:.1} MiB, mapping resident {}, process RSS {}",
            mib(self.memory.file_bytes),
            optional(self.memory.mapped_resident_bytes),
            optional(self.memory.process_rss_bytes)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conversion::{convert_mesh, BuildParams};
    use crate::format::reader::ReducemFile;
    use crate::mesh::Mesh;
    use crate::trace::TraceOptions;
    use std::sync::atomic::Ordering;

    /// A bumpy 24 × 24 quad grid, two triangles per quad.
    fn bumpy_grid() -> Mesh {
        let mut mesh = Mesh::default();
        for y in 0..=24u32 {
            for x in 0..=24u32 {
                let height = ((x * 7 + y * 3) % 5) as f32 * 0.1;
                mesh.positions
                    .push([x as f32 * 0.1, y as f32 * 0.1, height]);
            }
        }
        for y in 0..24 {
            for x in 0..24 {
                let corner = y * 25 + x;
                mesh.triangles.push([corner, corner + 1, corner + 26]);
                mesh.triangles.push([corner, corner + 26, corner + 25]);
            }
        }
        mesh
    }

    /// `bumpy_grid` converted into a temporary file named after `test`, and opened.
    fn bumpy_file(test: &str) -> (std::path::PathBuf, ReducemFile) {
        let path = std::env::temp_dir().join(format!("render-{test}-{}.rdm", std::process::id()));
        convert_mesh(&bumpy_grid(), &BuildParams::default(), &path).expect("convert");
        let file = ReducemFile::open(&path).expect("open");
        (path, file)
    }

    /// An automatic camera, a light and AO samples over an image of `width` × `height`;
    /// `shadows` lets the light cast shadows.
    fn lit_scene(size: (u32, u32), antialiasing: u32, shadows: bool, samples: u32) -> Scene {
        let (width, height) = size;
        let text = format!(
            "[image]\nwidth = {width}\nheight = {height}\nantialiasing = {antialiasing}\n\
             [camera]\nauto = true\n[[directional_light]]\ndirection = [-1.0, -0.5, -1.0]\n\
             cast_shadows = {shadows}\n[ambient_occlusion]\nsamples = {samples}\n"
        );
        Scene::parse(std::path::Path::new("s.toml"), &text).expect("scene")
    }

    /// Bands of a few tile rows give the very pixels and ray counts of one band for the whole
    /// image, in either order, with antialiasing, shadows and ambient occlusion.
    #[test]
    fn an_image_rendered_in_bands_is_the_image_rendered_whole() {
        let (path, file) = bumpy_file("bands");
        let tracer = Tracer::new(&file, TraceOptions::default());
        for antialiasing in [1u32, 3] {
            let scene = lit_scene((37, 29), antialiasing, true, 3);
            let render = |order, band_pixels| {
                let mut bands = Vec::new();
                let report = render_in_bands(&tracer, &scene, order, band_pixels, |rows| {
                    bands.push(rows.to_vec());
                    Ok::<(), ()>(())
                })
                .expect("rendered");
                (bands, report)
            };
            let (whole, whole_report) = render(RowOrder::TopDown, u32::MAX);
            let (top_down, report) = render(RowOrder::TopDown, 1);
            let (mut bottom_up, _) = render(RowOrder::BandsBottomUp, 1);
            assert_eq!(whole.len(), 1);
            assert_eq!(
                top_down.len(),
                (29 * antialiasing).div_ceil(lcm(8, antialiasing)) as usize
            );
            bottom_up.reverse();
            let bits = |bands: &[Vec<[f32; 3]>]| -> Vec<u32> {
                bands
                    .iter()
                    .flatten()
                    .flatten()
                    .map(|c| c.to_bits())
                    .collect()
            };
            assert_eq!(bits(&top_down), bits(&whole), "antialiasing {antialiasing}");
            assert_eq!(
                bits(&bottom_up),
                bits(&whole),
                "antialiasing {antialiasing}"
            );
            let rays = |report: &RenderReport| {
                let effects = report
                    .effects
                    .iter()
                    .map(|e| (e.effect, e.rays))
                    .collect::<Vec<_>>();
                (
                    effects,
                    report.shadow_rays_per_light.clone(),
                    report.total_rays,
                )
            };
            assert_eq!(rays(&report), rays(&whole_report));
            assert!(whole_report.rays_of("ambient_occlusion") > 0);
            assert!(whole_report.rays_of("shadows") > 0);
        }
        std::fs::remove_file(&path).expect("remove");
    }

    /// Rounds of AO samples end with the very pixels and ray counts of the image rendered at
    /// once, the samples per pixel growing with each round, with antialiasing or without.
    #[test]
    fn an_image_refined_in_rounds_ends_as_the_image_rendered_at_once() {
        let (path, file) = bumpy_file("rounds");
        let tracer = Tracer::new(&file, TraceOptions::default());
        for antialiasing in [1u32, 2] {
            let scene = lit_scene((37, 29), antialiasing, true, 5);
            let (whole, whole_report) = render(&tracer, &scene);
            let mut progressive = Progressive::new(&tracer, &scene, 1);
            assert_eq!(progressive.samples_per_pixel(), 0);
            let mut spp = Vec::new();
            let mut frames = Vec::new();
            for until in [1, 2, 4, 8] {
                let frame = progressive
                    .refine(until, || Ok::<(), ()>(()))
                    .expect("refined");
                spp.push(progressive.samples_per_pixel());
                frames.push(frame);
            }
            let square = antialiasing * antialiasing;
            assert_eq!(spp, [1, 2, 4, 5].map(|s| s * square));
            assert!(progressive.is_complete());
            let bits = |frame: &Frame| -> Vec<u32> {
                frame.pixels.iter().flatten().map(|c| c.to_bits()).collect()
            };
            assert_eq!(
                bits(&frames[3]),
                bits(&whole),
                "antialiasing {antialiasing}"
            );
            assert_ne!(bits(&frames[0]), bits(&whole), "one AO sample of five");
            let report = progressive.report();
            assert_eq!(report.total_rays, whole_report.total_rays);
            assert_eq!(report.effects.len(), whole_report.effects.len());
        }
        std::fs::remove_file(&path).expect("remove");
    }

    /// A preview's pixels are the full image's every second (or fourth) pixels shaded with
    /// primary shading, bit for bit; with antialiasing or without, even and odd sizes.
    #[test]
    fn a_preview_shows_every_nth_pixel_of_the_primary_image() {
        let (path, file) = bumpy_file("preview");
        let tracer = Tracer::new(&file, TraceOptions::default());
        let cases = [
            ((37, 29), 1u32, 2u32),
            ((36, 30), 2, 2),
            ((37, 29), 1, 4),
            ((36, 30), 2, 4),
        ];
        for (size, antialiasing, every) in cases {
            let scene = lit_scene(size, antialiasing, true, 2);
            let mut preview = Progressive::preview(&tracer, &scene, every, 1);
            let shown = preview.refine(1, || Ok::<(), ()>(())).expect("preview");
            let (width, height) = (size.0.div_ceil(every), size.1.div_ceil(every));
            assert_eq!((shown.width, shown.height), (width, height));
            assert_eq!(preview.rays_traced().0, u64::from(width * height));

            let mut primary = scene.primary_only();
            let fine = antialiasing as usize;
            (primary.image.width, primary.image.height) =
                (size.0 * antialiasing, size.1 * antialiasing);
            let (primary_frame, _) = render(&tracer, &primary);
            let fine_width = primary.image.width as usize;
            for (index, pixel) in shown.pixels.iter().enumerate() {
                let (x, y) = (index % width as usize, index / width as usize);
                let expected = primary_frame.pixels[every as usize * fine * (y * fine_width + x)];
                assert_eq!(pixel, &expected, "preview pixel {x},{y}");
            }
        }
        std::fs::remove_file(&path).expect("remove");
    }

    /// A round abandoned between bands leaves the image to be finished by the next round.
    #[test]
    fn an_abandoned_round_is_finished_by_the_next() {
        let (path, file) = bumpy_file("abandon");
        let tracer = Tracer::new(&file, TraceOptions::default());
        let scene = lit_scene((16, 24), 1, false, 3);
        let (whole, _) = render(&tracer, &scene);
        let mut progressive = Progressive::new(&tracer, &scene, 1);
        let bands_left = std::sync::atomic::AtomicU32::new(2);
        let abandoned = progressive.refine(3, || {
            let taken = bands_left.fetch_update(Ordering::AcqRel, Ordering::Acquire, |left| {
                left.checked_sub(1)
            });
            taken.map(|_| ()).map_err(|_| "stale")
        });
        assert_eq!(abandoned, Err("stale"));
        assert!(!progressive.is_complete());
        let frame = progressive.refine(3, || Ok::<(), ()>(())).expect("refined");
        assert!(progressive.is_complete());
        assert_eq!(frame, whole);
        std::fs::remove_file(&path).expect("remove");
    }

    /// Every pixel comes once, and a full tile's first eight pixels are its top-left 4 × 2 block.
    #[test]
    fn tiles_list_every_pixel_once_in_packet_blocks() {
        let (width, height) = (21, 11);
        let mut seen: Vec<u32> = tiles(width, height).concat();
        seen.sort_unstable();
        assert_eq!(seen, (0..width * height).collect::<Vec<_>>());
        let first = &tiles(width, height)[0][..8];
        assert_eq!(first, &[0, 1, 2, 3, 21, 22, 23, 24]);
        let corner = tiles(width, height).pop().unwrap();
        // The last tile spans columns 16..21 and rows 8..11: blocks of 4 and 1 columns.
        let row = |y: u32, xs: Range<u32>| xs.map(move |x| y * width + x);
        let expected: Vec<u32> = row(8, 16..20)
            .chain(row(9, 16..20))
            .chain(row(8, 20..21))
            .chain(row(9, 20..21))
            .chain(row(10, 16..20))
            .chain(row(10, 20..21))
            .collect();
        assert_eq!(corner, expected);
    }
}

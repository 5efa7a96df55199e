//! `reducem render`: images of a ReduceM file with primary shading, shadows and ambient occlusion.
//!
//! The scene ([`scene`]) is turned into a [`plan::Plan`] and each planned effect is one pass over
//! the image, timed and counted on its own: primary rays (packets: they are coherent), shadow
//! rays per shadow-casting light (packets: rays towards one light are coherent too), then AO rays
//! (single rays: random hemisphere directions are incoherent, as the paper notes for secondary
//! effects). Passes run over 8×8-pixel tiles with rayon; every pixel's value depends only on its
//! own rays and stateless samples, so the image is identical for any thread count.
//!
//! Shading is Lambertian with a two-sided normal: `albedo × colour × (ambient × AO + Σ lights
//! intensity × cos θ × visibility / falloff)`, point lights falling off with squared distance,
//! then sRGB-encoded to 8-bit PNG ([`image`]). The normal is the geometric one, or the stored
//! vertex normals interpolated when the file has them; the colour is white, or the stored vertex
//! colours interpolated ([`attributes`]).

pub mod attributes;
pub mod camera;
pub mod image;
pub mod plan;
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
use scene::Scene;

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
    let factor = scene.image.antialiasing;
    if factor <= 1 {
        return render_samples(tracer, scene);
    }
    let mut fine = scene.clone();
    fine.image.width *= factor;
    fine.image.height *= factor;
    let (frame, mut report) = render_samples(tracer, &fine);
    (report.width, report.height) = (scene.image.width, scene.image.height);
    (frame.averaged(factor), report)
}

impl Frame {
    /// Each `factor` × `factor` block of pixels averaged into one.
    fn averaged(&self, factor: u32) -> Frame {
        let (width, height) = (self.width / factor, self.height / factor);
        let weight = 1.0 / (factor * factor) as f32;
        let pixels = (0..width * height)
            .map(|index| {
                let (x, y) = (index % width * factor, index / width * factor);
                let mut sum = [0.0f32; 3];
                for sample_y in y..y + factor {
                    for sample_x in x..x + factor {
                        let sample = self.pixels[(sample_y * self.width + sample_x) as usize];
                        sum = std::array::from_fn(|c| sum[c] + sample[c]);
                    }
                }
                sum.map(|channel| channel * weight)
            })
            .collect();
        Frame {
            width,
            height,
            pixels,
        }
    }
}

/// One sample per pixel of `scene`'s image.
fn render_samples(tracer: &Tracer, scene: &Scene) -> (Frame, RenderReport) {
    let file = tracer.file();
    let header = file.header();
    let bounds = Aabb {
        min: header.bounds_min,
        max: header.bounds_max,
    };
    let plan = Plan::new(scene, &bounds);
    let camera = Camera::new(&scene.camera, &bounds, plan.width, plan.height);
    let tiles = tiles(plan.width, plan.height);
    let mut effects = Vec::new();

    let started = Instant::now();
    let used = AttributeUse::new(file.attributes(), &scene.shading);
    let surfaces = primary_pass(tracer, &camera, &tiles, plan.width, used);
    effects.push(EffectReport {
        effect: "primary",
        rays: tiles.iter().map(|t| t.len() as u64).sum(),
        seconds: started.elapsed().as_secs_f64(),
    });

    let mut visibility = vec![Vec::new(); plan.lights.len()];
    let mut shadow_rays_per_light = vec![0; plan.lights.len()];
    for &light in &plan.shadow_lights {
        let started = Instant::now();
        let (visible, rays) = shadow_pass(tracer, &plan.lights[light], &surfaces, &tiles);
        visibility[light] = visible;
        shadow_rays_per_light[light] = rays;
        effects.push(EffectReport {
            effect: "shadows",
            rays,
            seconds: started.elapsed().as_secs_f64(),
        });
    }

    let ambient = plan.ambient_occlusion.map(|ao| {
        let started = Instant::now();
        let (unoccluded, rays) = ao_pass(tracer, &ao, scene.shading.seed, &surfaces, &tiles);
        effects.push(EffectReport {
            effect: "ambient_occlusion",
            rays,
            seconds: started.elapsed().as_secs_f64(),
        });
        unoccluded
    });

    let exposure = scene.shading.exposure;
    let pixels = shade(scene, &plan, &surfaces, &visibility, ambient.as_deref())
        .into_iter()
        .map(|pixel| pixel.map(|channel| channel * exposure))
        .collect();
    let total_rays = effects.iter().map(|e| e.rays).sum();
    let trace_seconds = effects.iter().map(|e| e.seconds).sum::<f64>();
    let report = RenderReport {
        width: plan.width,
        height: plan.height,
        effects,
        shadow_rays_per_light,
        total_rays,
        trace_seconds,
        mrays_per_second: total_rays as f64 / trace_seconds.max(1e-9) / 1e6,
        kernel: tracer.options().kernel.to_string(),
        memory: residency::measure(file.path(), file.file_bytes()),
    };
    let frame = Frame {
        width: plan.width,
        height: plan.height,
        pixels,
    };
    (frame, report)
}

/// Pixel indices of each 8×8 tile, tiles in row-major order, each tile's pixels in packet
/// blocks ([`PACKET_COLUMNS`]): the order passes trace pixels in.
pub fn tiles(width: u32, height: u32) -> Vec<Vec<u32>> {
    let mut tiles = Vec::new();
    for tile_y in (0..height).step_by(TILE as usize) {
        for tile_x in (0..width).step_by(TILE as usize) {
            let rows = tile_y..(tile_y + TILE).min(height);
            let columns = tile_x..(tile_x + TILE).min(width);
            tiles.push(tile_pixels(width, rows, columns));
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

/// Runs `per_tile` over every tile in parallel and scatters its per-pixel results into an image
/// buffer; the placement depends only on pixel indices, never on scheduling.
fn over_tiles<T, F>(tiles: &[Vec<u32>], pixel_count: usize, per_tile: F) -> Vec<T>
where
    T: Clone + Default + Send,
    F: Fn(&[u32]) -> Vec<T> + Sync,
{
    let results: Vec<Vec<T>> = tiles.par_iter().map(|tile| per_tile(tile)).collect();
    let mut image = vec![T::default(); pixel_count];
    for (tile, values) in tiles.iter().zip(results) {
        for (&pixel, value) in tile.iter().zip(values) {
            image[pixel as usize] = value;
        }
    }
    image
}

fn pixel_count(tiles: &[Vec<u32>]) -> usize {
    tiles.iter().map(Vec::len).sum()
}

fn primary_pass(
    tracer: &Tracer,
    camera: &Camera,
    tiles: &[Vec<u32>],
    width: u32,
    used: AttributeUse,
) -> Vec<Option<Surface>> {
    let file = tracer.file();
    over_tiles(tiles, pixel_count(tiles), |tile| {
        let rays: Vec<Ray> = tile
            .iter()
            .map(|&p| camera.primary_ray(p % width, p / width))
            .collect();
        let hits = tracer.intersect_chunk(&rays);
        rays.iter()
            .zip(hits)
            .map(|(ray, hit)| {
                let hit = hit?;
                Some(Surface::at_hit(file, ray, &hit)?.with_attributes(file, &hit, used))
            })
            .collect()
    })
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
    tiles: &[Vec<u32>],
) -> (Vec<f32>, u64) {
    let per_pixel: Vec<(f32, u64)> = over_tiles(tiles, surfaces.len(), |tile| {
        let rays: Vec<Option<Ray>> = tile
            .iter()
            .map(|&p| surfaces[p as usize].and_then(|s| shadow_ray(light, &s)))
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

/// Unoccluded fraction of the hemisphere per pixel and the rays traced. A tile's AO rays are
/// traced as one batch ([`Tracer::occluded_chunk`]: grouped by octant into packets), which
/// answers exactly as ray by ray.
fn ao_pass(
    tracer: &Tracer,
    ao: &AoPlan,
    seed: u32,
    surfaces: &[Option<Surface>],
    tiles: &[Vec<u32>],
) -> (Vec<f32>, u64) {
    let per_pixel: Vec<(f32, u64)> = over_tiles(tiles, surfaces.len(), |tile| {
        let rays: Vec<Ray> = tile
            .iter()
            .filter_map(|&pixel| surfaces[pixel as usize].map(|surface| (pixel, surface)))
            .flat_map(|(pixel, surface)| {
                (0..ao.samples).map(move |s| surface.ao_ray(seed, pixel, s, ao.max_distance))
            })
            .collect();
        let mut occluded = tracer.occluded_chunk(&rays).into_iter();
        tile.iter()
            .map(|&pixel| match surfaces[pixel as usize] {
                Some(_) => {
                    let open = occluded
                        .by_ref()
                        .take(ao.samples as usize)
                        .filter(|&o| !o)
                        .count();
                    (open as f32 / ao.samples as f32, ao.samples as u64)
                }
                None => (1.0, 0),
            })
            .collect()
    });
    let rays = per_pixel.iter().map(|&(_, r)| r).sum();
    (per_pixel.into_iter().map(|(v, _)| v).collect(), rays)
}

fn shade(
    scene: &Scene,
    plan: &Plan,
    surfaces: &[Option<Surface>],
    visibility: &[Vec<f32>],
    ambient_open: Option<&[f32]>,
) -> Vec<[f32; 3]> {
    let shading = &scene.shading;
    let albedo = Vec3::from(shading.albedo);
    (0..surfaces.len())
        .into_par_iter()
        .map(|pixel| {
            let Some(surface) = surfaces[pixel] else {
                return shading.background;
            };
            let open = ambient_open.map_or(1.0, |a| a[pixel]);
            let mut light_sum = shading.ambient * open;
            for (index, light) in plan.lights.iter().enumerate() {
                let lit = visibility[index].get(pixel).copied().unwrap_or(1.0);
                light_sum += lit * irradiance(light, &surface);
            }
            (albedo * surface.color * light_sum).into()
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

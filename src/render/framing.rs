//! The first picture of a model: seen from the front, slightly above the horizon of its up axis,
//! from the side most of its area faces, and near enough that it fills about
//! [`TARGET_FILL`] of the image. `reducem render` frames an automatic camera without a
//! `direction` so, and the viewer starts (and resets) there.
//!
//! The side comes from a sample of whole strips spread evenly over the file, never every
//! triangle, so a 300M-triangle file costs the same few thousand block reads as a small one
//! (read page by page where the file is large: read-around windows would pull it all in). The
//! distance comes from low-resolution hit masks: the model's true silhouette, not its bounding
//! box, decides how much of the image it fills; the image's own border pixels then check that
//! the model stays inside it.

use glam::Vec3;

use super::camera::{enclosing_view, Camera};
use crate::geometry::Aabb;
use crate::trace::{Ray, Tracer};

/// The fraction of the image's pixels the model should cover.
pub const TARGET_FILL: f32 = 0.7;

/// How far above the horizon the camera looks down at the model, in degrees.
const ELEVATION_DEGREES: f32 = 20.0;

/// Strips read for the side the model faces: enough triangles to tell its sides apart.
const SAMPLED_STRIPS: usize = 4096;

/// Candidate sides around the horizon (every 5°).
const SIDES: u32 = 72;

/// Hit-mask pixels along the image's longer side.
const MASK_SIDE: u32 = 64;

/// The largest the covered box may be, as a fraction of the image's width and height: a margin
/// so that no part of the model touches the image's edge.
const MAX_EXTENT: f32 = 0.95;

/// Refinements of the distance and aim by hit mask: each brings the fill close to the target,
/// the later ones correct the perspective the earlier ones ignore.
const REFINEMENTS: usize = 3;

/// Camera position and look-at point of the front view of `tracer`'s model for a `width` ×
/// `height` image with vertical field of view `fov_degrees`, `up` being the model's up axis.
pub fn front_view(
    tracer: &Tracer,
    up: Vec3,
    fov_degrees: f32,
    width: u32,
    height: u32,
) -> (Vec3, Vec3) {
    let up = up.normalize();
    let toward_camera = toward_camera(tracer, up);
    let header = tracer.file().header();
    let bounds = Aabb {
        min: header.bounds_min,
        max: header.bounds_max,
    };
    let (mut position, mut look_at) =
        enclosing_view(&bounds, toward_camera, fov_degrees, width, height);
    let (mask_width, mask_height) = mask_size(width, height);
    for _ in 0..REFINEMENTS {
        let camera = Camera::looking(position, look_at, up, fov_degrees, mask_width, mask_height);
        let Some(mask) = HitMask::traced(tracer, &camera, mask_width, mask_height) else {
            break;
        };
        let distance = (look_at - position).length();
        let shift = camera.image_plane_offset(mask.center()) * distance;
        let zoom = (TARGET_FILL / mask.fill())
            .sqrt()
            .min(MAX_EXTENT / mask.extent());
        look_at += shift;
        position = look_at + toward_camera * (distance / zoom);
    }
    let camera = |position| Camera::looking(position, look_at, up, fov_degrees, width, height);
    for _ in 0..STEPS_BACK {
        if !touches_border(tracer, &camera(position), width, height) {
            break;
        }
        position = look_at + (position - look_at) * STEP_BACK;
    }
    (position, look_at)
}

/// The factor of the distance of a step back from a model that reaches the image's border: the
/// hit masks see the model only within the image, so a model that leaves the image (in an image
/// much wider than tall, or by perspective) is measured too small.
const STEP_BACK: f32 = 1.05;

/// The most steps back: enough to double the distance.
const STEPS_BACK: usize = 15;

/// The model covers a pixel on the border of `camera`'s `width` × `height` image.
fn touches_border(tracer: &Tracer, camera: &Camera, width: u32, height: u32) -> bool {
    let rows = [0, height.saturating_sub(1)].map(|y| (0..width).map(move |x| (x, y)));
    let columns = [0, width.saturating_sub(1)].map(|x| (0..height).map(move |y| (x, y)));
    let rays: Vec<Ray> = rows
        .into_iter()
        .flatten()
        .chain(columns.into_iter().flatten())
        .map(|(x, y)| camera.primary_ray(x, y))
        .collect();
    tracer.intersect_batch(&rays).iter().any(Option::is_some)
}

/// Unit vector from the model towards the camera: the side most of the model's area faces,
/// raised [`ELEVATION_DEGREES`] above the horizon. A side's score is its [`facing`] area.
fn toward_camera(tracer: &Tracer, up: Vec3) -> Vec3 {
    let normals = sampled_area_normals(tracer);
    let reference = up.any_orthonormal_vector();
    let side = up.cross(reference);
    let mut best = (reference, f32::NEG_INFINITY);
    for step in 0..SIDES {
        let angle = (step as f32 / SIDES as f32) * std::f32::consts::TAU;
        let direction = reference * angle.cos() + side * angle.sin();
        let facing: f32 = normals.iter().map(|&n| facing(n, direction)).sum();
        if facing > best.1 {
            best = (direction, facing);
        }
    }
    let elevation = ELEVATION_DEGREES.to_radians();
    (best.0 * elevation.cos() + up * elevation.sin()).normalize()
}

/// How much of the area of a triangle with area-weighted normal `normal` faces `direction`:
/// its area times the fourth power of the cosine between them. A lobe that narrow makes a
/// model's largest face win over the three-quarter view that shows most projected area.
fn facing(normal: Vec3, direction: Vec3) -> f32 {
    let area = normal.length();
    if area == 0.0 {
        return 0.0;
    }
    let cosine = (normal.dot(direction) / area).max(0.0);
    let squared = cosine * cosine;
    area * squared * squared
}

/// The area-weighted normals (cross products of the edges, in input winding) of every triangle
/// of [`SAMPLED_STRIPS`] strips spread evenly over the file.
fn sampled_area_normals(tracer: &Tracer) -> Vec<Vec3> {
    let file = tracer.file();
    let strips = file.strip_count();
    let sampled = strips.min(SAMPLED_STRIPS);
    file.with_scattered_reads(sampled, || {
        let mut normals = Vec::new();
        for index in (0..sampled).map(|i| i * strips / sampled) {
            let strip = file.strip(index);
            for window in 0..strip.window_count() {
                if let Some([a, b, c]) = strip.window_points(window) {
                    let (a, b, c) = (Vec3::from(a), Vec3::from(b), Vec3::from(c));
                    normals.push((b - a).cross(c - a));
                }
            }
        }
        normals
    })
}

/// The hit mask's size: [`MASK_SIDE`] along the image's longer side, the image's aspect.
fn mask_size(width: u32, height: u32) -> (u32, u32) {
    let longer = width.max(height).max(1) as f32;
    let scaled = |side: u32| ((side as f32 / longer * MASK_SIDE as f32).round() as u32).max(1);
    (scaled(width), scaled(height))
}

/// Which pixels of a small image the model covers, as image-plane coordinates in [-1, 1].
struct HitMask {
    hits: usize,
    pixels: usize,
    /// Smallest and largest image-plane x and y of the covered pixels' centres.
    min: [f32; 2],
    max: [f32; 2],
}

impl HitMask {
    /// The mask of `camera`'s `width` × `height` image; `None` when the model covers no pixel.
    fn traced(tracer: &Tracer, camera: &Camera, width: u32, height: u32) -> Option<HitMask> {
        let pixels: Vec<(u32, u32)> = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .collect();
        let rays: Vec<Ray> = pixels
            .iter()
            .map(|&(x, y)| camera.primary_ray(x, y))
            .collect();
        let hits = tracer.intersect_batch(&rays);
        let mut mask = HitMask {
            hits: 0,
            pixels: pixels.len(),
            min: [f32::INFINITY; 2],
            max: [f32::NEG_INFINITY; 2],
        };
        for (&(x, y), hit) in pixels.iter().zip(hits) {
            if hit.is_some() {
                let plane = [
                    2.0 * (x as f32 + 0.5) / width as f32 - 1.0,
                    1.0 - 2.0 * (y as f32 + 0.5) / height as f32,
                ];
                mask.hits += 1;
                mask.min = [mask.min[0].min(plane[0]), mask.min[1].min(plane[1])];
                mask.max = [mask.max[0].max(plane[0]), mask.max[1].max(plane[1])];
            }
        }
        (mask.hits > 0).then_some(mask)
    }

    fn fill(&self) -> f32 {
        self.hits as f32 / self.pixels as f32
    }

    /// The centre of the covered pixels' box in the image plane.
    fn center(&self) -> [f32; 2] {
        [
            (self.min[0] + self.max[0]) * 0.5,
            (self.min[1] + self.max[1]) * 0.5,
        ]
    }

    /// Half the covered box's larger side in image-plane units (1 spans the image), at least one
    /// pixel: how far the model may be enlarged before it leaves the image.
    fn extent(&self) -> f32 {
        let half = |axis: usize| (self.max[axis] - self.min[axis]) * 0.5;
        half(0).max(half(1)).max(1.0 / MASK_SIDE as f32)
    }
}

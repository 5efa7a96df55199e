//! A pinhole camera: placed by the scene, or framing the model's bounds from a direction.
//!
//! Automatic framing puts the bounding sphere of the model's box exactly inside the narrower
//! field of view, so any model fills the image whatever its size or position.

use glam::Vec3;

use super::scene::{CameraSettings, MIN_ROLL_SINE_SQUARED};
use crate::geometry::Aabb;
use crate::trace::Ray;

/// Default viewing side for `auto = true`: above and to the front right of the model.
const DEFAULT_AUTO_DIRECTION: [f32; 3] = [1.0, 0.8, 1.2];

#[derive(Clone, Copy, Debug)]
pub struct Camera {
    position: Vec3,
    /// Direction through the image centre.
    forward: Vec3,
    /// Image-plane vector from the centre to the right edge, at unit distance.
    right: Vec3,
    /// Image-plane vector from the centre to the top edge, at unit distance.
    up: Vec3,
    width: u32,
    height: u32,
}

impl Camera {
    pub fn new(settings: &CameraSettings, bounds: &Aabb, width: u32, height: u32) -> Camera {
        let up_hint = Vec3::from(settings.up).normalize();
        let (position, look_at) = placement(settings, bounds, width, height);
        let forward = (look_at - position).normalize_or(Vec3::NEG_Z);
        let side = forward.cross(up_hint);
        // A view along the up hint has no defined roll (scenes refuse it; a camera built
        // otherwise picks any perpendicular).
        let side = if side.length_squared() > MIN_ROLL_SINE_SQUARED {
            side.normalize()
        } else {
            forward.any_orthonormal_vector()
        };
        let true_up = side.cross(forward);
        let half_height = (settings.fov_degrees.to_radians() * 0.5).tan();
        let half_width = half_height * width as f32 / height as f32;
        Camera {
            position,
            forward,
            right: side * half_width,
            up: true_up * half_height,
            width,
            height,
        }
    }

    /// The primary ray through the centre of pixel `(x, y)`, row 0 at the top.
    pub fn primary_ray(&self, x: u32, y: u32) -> Ray {
        let sx = (2.0 * (x as f32 + 0.5) / self.width as f32) - 1.0;
        let sy = 1.0 - (2.0 * (y as f32 + 0.5) / self.height as f32);
        let direction = (self.forward + self.right * sx + self.up * sy).normalize();
        Ray {
            origin: self.position.into(),
            direction: direction.into(),
            tmin: 0.0,
            tmax: f32::INFINITY,
        }
    }
}

/// The camera's position and the point it looks at: as the settings place it, else framing
/// `bounds` (the viewer starts from this and moves the camera as placed).
pub fn placement(
    settings: &CameraSettings,
    bounds: &Aabb,
    width: u32,
    height: u32,
) -> (Vec3, Vec3) {
    match (settings.position, settings.look_at) {
        (Some(position), Some(look_at)) => (Vec3::from(position), Vec3::from(look_at)),
        _ => auto_placement(settings, bounds, width, height),
    }
}

/// Camera position and target that frame `bounds` (its bounding sphere) from the settings'
/// direction.
fn auto_placement(
    settings: &CameraSettings,
    bounds: &Aabb,
    width: u32,
    height: u32,
) -> (Vec3, Vec3) {
    let (min, max) = if bounds.is_empty() {
        (Vec3::splat(-1.0), Vec3::splat(1.0))
    } else {
        (Vec3::from(bounds.min), Vec3::from(bounds.max))
    };
    let center = (min + max) * 0.5;
    let radius = ((max - min).length() * 0.5).max(f32::MIN_POSITIVE);
    let toward_camera =
        Vec3::from(settings.direction.unwrap_or(DEFAULT_AUTO_DIRECTION)).normalize();
    let half_vertical = settings.fov_degrees.to_radians() * 0.5;
    let half_horizontal = (half_vertical.tan() * width as f32 / height as f32).atan();
    let distance = radius / half_vertical.min(half_horizontal).sin();
    (center + toward_camera * distance, center)
}

//! A pinhole camera: placed by the scene, or framing the model automatically.
//!
//! An automatic camera with a `direction` puts the bounding sphere of the model's box exactly
//! inside the narrower field of view; one without is framed from the model's front
//! ([`super::framing`]).

use glam::Vec3;

use super::framing::front_view;
use super::scene::{CameraSettings, MIN_ROLL_SINE_SQUARED};
use crate::geometry::Aabb;
use crate::trace::{Ray, Tracer};

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
    /// Image pixels from one of this camera's pixels to the next: 1, or n for a preview whose
    /// pixel `(x, y)` is the image's pixel `(nx, ny)`, its ray through that pixel's centre.
    pixel_step: u32,
}

impl Camera {
    /// The camera of `settings` for a `width` × `height` image of `tracer`'s model.
    pub fn new(tracer: &Tracer, settings: &CameraSettings, width: u32, height: u32) -> Camera {
        let (position, look_at) = placement(tracer, settings, width, height);
        let (up, fov) = (Vec3::from(settings.up), settings.fov_degrees);
        Camera::looking(position, look_at, up, fov, width, height)
    }

    /// The camera at `position` looking at `look_at`, rolled so that `up_hint` is upwards.
    pub fn looking(
        position: Vec3,
        look_at: Vec3,
        up_hint: Vec3,
        fov_degrees: f32,
        width: u32,
        height: u32,
    ) -> Camera {
        let up_hint = up_hint.normalize();
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
        let half_height = (fov_degrees.to_radians() * 0.5).tan();
        let half_width = half_height * width as f32 / height as f32;
        Camera {
            position,
            forward,
            right: side * half_width,
            up: true_up * half_height,
            width,
            height,
            pixel_step: 1,
        }
    }

    /// This camera's image seen at every `step`-th pixel each way: pixel `(x, y)` of the
    /// sparser image has the ray of pixel `(step x, step y)` of this one, so a preview's rays
    /// are some of the full image's.
    pub fn every_nth_pixel(self, step: u32) -> Camera {
        Camera {
            pixel_step: self.pixel_step * step,
            ..self
        }
    }

    /// The offset, at unit distance along the view, of image-plane point `[x, y]` (-1 to 1 from
    /// the left and bottom edges to the right and top ones) from the image centre.
    pub fn image_plane_offset(&self, [x, y]: [f32; 2]) -> Vec3 {
        self.right * x + self.up * y
    }

    /// `direction` given in the camera's frame (x right, y up, z towards the viewer), in the
    /// model's coordinates.
    pub fn to_model(&self, direction: Vec3) -> Vec3 {
        self.right.normalize() * direction.x + self.up.normalize() * direction.y
            - self.forward * direction.z
    }

    /// The primary ray through the centre of pixel `(x, y)`, row 0 at the top (of the image
    /// [`Camera::every_nth_pixel`] sees).
    pub fn primary_ray(&self, x: u32, y: u32) -> Ray {
        let (x, y) = (x * self.pixel_step, y * self.pixel_step);
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

/// The camera's position and the point it looks at: as the settings place it, else framing the
/// model (the viewer starts from this and moves the camera as placed).
pub fn placement(
    tracer: &Tracer,
    settings: &CameraSettings,
    width: u32,
    height: u32,
) -> (Vec3, Vec3) {
    match (settings.position, settings.look_at, settings.direction) {
        (Some(position), Some(look_at), _) => (Vec3::from(position), Vec3::from(look_at)),
        (_, _, Some(direction)) => {
            let header = tracer.file().header();
            let bounds = Aabb {
                min: header.bounds_min,
                max: header.bounds_max,
            };
            let toward_camera = Vec3::from(direction).normalize();
            enclosing_view(&bounds, toward_camera, settings.fov_degrees, width, height)
        }
        _ => front_view(
            tracer,
            Vec3::from(settings.up),
            settings.fov_degrees,
            width,
            height,
        ),
    }
}

/// Camera position and target from `toward_camera` (a unit vector from the model's centre) that
/// see the whole bounding sphere of `bounds`.
pub(crate) fn enclosing_view(
    bounds: &Aabb,
    toward_camera: Vec3,
    fov_degrees: f32,
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
    let half_vertical = fov_degrees.to_radians() * 0.5;
    let half_horizontal = (half_vertical.tan() * width as f32 / height as f32).atan();
    let distance = radius / half_vertical.min(half_horizontal).sin();
    (center + toward_camera * distance, center)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The camera's frame: x to the image's right, y to its top, z back towards the viewer.
    #[test]
    fn directions_in_the_camera_frame_turn_into_the_model() {
        let (position, look_at) = (Vec3::new(0.0, -5.0, 0.0), Vec3::ZERO);
        let camera = Camera::looking(position, look_at, Vec3::Z, 40.0, 64, 48);
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
        assert!(close(camera.to_model(Vec3::X), Vec3::X));
        assert!(close(camera.to_model(Vec3::Y), Vec3::Z));
        assert!(close(camera.to_model(Vec3::Z), Vec3::NEG_Y));
    }
}

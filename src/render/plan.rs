//! The render plan: what a scene asks to be traced, decided once before any ray is cast.
//!
//! The renderer runs one pass per planned effect and nothing else: primary rays always (they make
//! the image), one shadow pass per light that casts shadows, and an ambient-occlusion pass only
//! when the scene has an `[ambient_occlusion]` table. A light without shadows is still shaded,
//! with full visibility, at no ray cost.

use glam::Vec3;

use super::camera::Camera;
use super::scene::{Scene, ShadingMode};
use crate::geometry::Aabb;

/// AO distance when the scene gives none, as a fraction of the model's bounds diagonal.
const DEFAULT_AO_DISTANCE_FRACTION: f32 = 0.05;

/// A light in the form shading needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightSource {
    /// Unit vector from a surface towards the light.
    Directional {
        toward_light: Vec3,
    },
    Point {
        position: Vec3,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub source: LightSource,
    pub intensity: f32,
    pub cast_shadows: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AoPlan {
    pub samples: u32,
    pub max_distance: f32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub width: u32,
    pub height: u32,
    /// Directional lights first, then point lights, in scene order.
    pub lights: Vec<Light>,
    /// Indices into `lights` of the lights that need shadow rays.
    pub shadow_lights: Vec<usize>,
    pub ambient_occlusion: Option<AoPlan>,
}

impl Plan {
    /// Some pass or light reads where the primary rays hit, not only the surfaces' normals and
    /// colours: shadow and AO rays leave from there, point lights fall off with the distance.
    pub fn needs_hit_points(&self) -> bool {
        let point_light = |light: &Light| matches!(light.source, LightSource::Point { .. });
        !self.shadow_lights.is_empty()
            || self.ambient_occlusion.is_some()
            || self.lights.iter().any(point_light)
    }

    /// The plan of `scene` on a model within `bounds`, seen by `camera` (which turns the lights
    /// given relative to it).
    pub fn new(scene: &Scene, bounds: &Aabb, camera: &Camera) -> Plan {
        let directional = scene.directional_light.iter().map(|l| Light {
            source: LightSource::Directional {
                toward_light: -match l.relative_to_camera {
                    true => camera.to_model(Vec3::from(l.direction)),
                    false => Vec3::from(l.direction),
                }
                .normalize(),
            },
            intensity: l.intensity,
            cast_shadows: l.cast_shadows,
        });
        let point = scene.point_light.iter().map(|l| Light {
            source: LightSource::Point {
                position: Vec3::from(l.position),
            },
            intensity: l.intensity,
            cast_shadows: l.cast_shadows,
        });
        let lights: Vec<Light> = directional.chain(point).collect();
        // The normals view shows no light: nothing to trace for shadows or AO.
        let lit = scene.shading.mode == ShadingMode::Lit;
        let shadow_lights = (0..lights.len())
            .filter(|&i| lit && lights[i].cast_shadows)
            .collect();
        let diagonal = if bounds.is_empty() {
            1.0
        } else {
            (Vec3::from(bounds.max) - Vec3::from(bounds.min)).length()
        };
        let ambient_occlusion = scene
            .ambient_occlusion
            .as_ref()
            .filter(|_| lit)
            .map(|ao| AoPlan {
                samples: ao.samples,
                max_distance: ao.max_distance.unwrap_or_else(|| {
                    ao.distance_fraction.unwrap_or(DEFAULT_AO_DISTANCE_FRACTION) * diagonal
                }),
            });
        Plan {
            width: scene.image.width,
            height: scene.image.height,
            lights,
            shadow_lights,
            ambient_occlusion,
        }
    }
}

//! The scene file of `reducem render`: camera, image, lights and effects, in TOML.
//!
//! Every key, its default and unit: `docs/SCENES.md`. Every table denies unknown keys, so a misspelt key is an error with its line and column (the
//! `toml` crate's span) rather than a silently ignored setting. Semantic checks (positive sizes,
//! a camera that is either placed or automatic) follow parsing and name the offending key.
//!
//! ```toml
//! [image]
//! width = 1024
//! height = 1024
//!
//! [camera]
//! auto = true                  # frame the model's bounds ...
//! direction = [1.0, 0.7, 0.9]  # ... seen from this side (model centre → camera)
//! up = [0.0, 0.0, 1.0]
//! fov_degrees = 40.0
//!
//! [[directional_light]]
//! direction = [-1.0, -0.5, -1.0]  # the way the light travels
//! intensity = 1.0
//! cast_shadows = true
//!
//! [[point_light]]
//! position = [0.0, 0.0, 10.0]
//! intensity = 50.0                # falls off with the squared distance
//! cast_shadows = false
//!
//! [ambient_occlusion]
//! samples = 16
//! max_distance = 0.5              # model units; default 5% of the bounds' diagonal
//! ```

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::geometry::Point;

/// A parsed, checked scene.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    pub image: ImageSettings,
    pub camera: CameraSettings,
    #[serde(default)]
    pub shading: Shading,
    #[serde(default)]
    pub directional_light: Vec<DirectionalLight>,
    #[serde(default)]
    pub point_light: Vec<PointLight>,
    pub ambient_occlusion: Option<AmbientOcclusion>,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ImageSettings {
    pub width: u32,
    pub height: u32,
}

/// Either `position` + `look_at`, or `auto = true` with an optional viewing `direction`.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraSettings {
    #[serde(default)]
    pub auto: bool,
    pub position: Option<Point>,
    pub look_at: Option<Point>,
    /// With `auto`: from the model's centre towards the camera.
    pub direction: Option<Point>,
    #[serde(default = "default_up")]
    pub up: Point,
    #[serde(default = "default_fov")]
    pub fov_degrees: f32,
}

/// Surface and environment terms of the shading; a key the table omits takes its default.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Shading {
    /// Diffuse reflectance of every surface.
    pub albedo: Point,
    /// Uniform ambient light, scaled by ambient occlusion when that is on.
    pub ambient: f32,
    /// Colour of pixels whose ray hits nothing.
    pub background: Point,
    /// Seed of the stateless sample hash; the same seed gives the same image.
    pub seed: u32,
}

impl Default for Shading {
    fn default() -> Self {
        Shading {
            albedo: [0.8, 0.8, 0.8],
            ambient: 0.25,
            background: [0.05, 0.06, 0.08],
            seed: 1,
        }
    }
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DirectionalLight {
    /// The direction the light travels, from the light into the scene.
    pub direction: Point,
    #[serde(default = "default_intensity")]
    pub intensity: f32,
    #[serde(default)]
    pub cast_shadows: bool,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PointLight {
    pub position: Point,
    #[serde(default = "default_intensity")]
    pub intensity: f32,
    #[serde(default)]
    pub cast_shadows: bool,
}

#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AmbientOcclusion {
    pub samples: u32,
    /// Occluders farther than this do not count; default 5% of the model's bounds diagonal.
    pub max_distance: Option<f32>,
}

fn default_up() -> Point {
    [0.0, 1.0, 0.0]
}

fn default_fov() -> f32 {
    45.0
}

fn default_intensity() -> f32 {
    1.0
}

/// A scene file that could not be read, parsed or checked.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: {message}", path.display())]
    Parse { path: PathBuf, message: String },
    #[error("{}: {key}: {detail}", path.display())]
    Invalid {
        path: PathBuf,
        key: &'static str,
        detail: String,
    },
}

impl Scene {
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Scene::parse(path, &text)
    }

    /// Parses and checks scene text; `path` only names the file in errors.
    pub fn parse(path: &Path, text: &str) -> Result<Scene, SceneError> {
        let scene: Scene = toml::from_str(text).map_err(|e| SceneError::Parse {
            path: path.to_path_buf(),
            message: e.to_string().trim_end().to_string(),
        })?;
        scene.check().map_err(|(key, detail)| SceneError::Invalid {
            path: path.to_path_buf(),
            key,
            detail,
        })?;
        Ok(scene)
    }

    fn check(&self) -> Result<(), (&'static str, String)> {
        let image = &self.image;
        if image.width == 0 || image.height == 0 || image.width > 16384 || image.height > 16384 {
            return Err((
                "image",
                format!("{}x{} is outside 1..=16384", image.width, image.height),
            ));
        }
        let camera = &self.camera;
        if !(camera.fov_degrees > 0.0 && camera.fov_degrees < 180.0) {
            return Err((
                "camera.fov_degrees",
                format!("{} is outside (0, 180)", camera.fov_degrees),
            ));
        }
        let placed = camera.position.is_some() || camera.look_at.is_some();
        if camera.auto && placed {
            return Err((
                "camera.auto",
                "give either auto = true or position and look_at, not both".into(),
            ));
        }
        if !camera.auto && (camera.position.is_none() || camera.look_at.is_none()) {
            return Err((
                "camera",
                "needs position and look_at, or auto = true".into(),
            ));
        }
        if camera.direction.is_some() && !camera.auto {
            return Err(("camera.direction", "only applies with auto = true".into()));
        }
        check_vector("camera.up", &camera.up)?;
        if let Some(direction) = &camera.direction {
            check_vector("camera.direction", direction)?;
        }
        for light in &self.directional_light {
            check_vector("directional_light.direction", &light.direction)?;
        }
        if let Some(ao) = &self.ambient_occlusion {
            if ao.samples == 0 || ao.samples > 4096 {
                return Err((
                    "ambient_occlusion.samples",
                    format!(
                        "{} is outside 1..=4096 (omit the table to turn AO off)",
                        ao.samples
                    ),
                ));
            }
            if ao.max_distance.is_some_and(|d| !(d > 0.0 && d.is_finite())) {
                return Err((
                    "ambient_occlusion.max_distance",
                    "must be positive and finite".into(),
                ));
            }
        }
        Ok(())
    }
}

fn check_vector(key: &'static str, v: &Point) -> Result<(), (&'static str, String)> {
    let finite = v.iter().all(|x| x.is_finite());
    if !finite || *v == [0.0; 3] {
        return Err((key, format!("{v:?} must be finite and non-zero")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "[image]\nwidth = 4\nheight = 3\n[camera]\nauto = true\n";

    #[test]
    fn minimal_scene_has_no_lights_and_no_ao() {
        let scene = Scene::parse(Path::new("s.toml"), MINIMAL).expect("parse");
        assert!(scene.directional_light.is_empty() && scene.point_light.is_empty());
        assert_eq!(scene.ambient_occlusion, None);
    }

    #[test]
    fn unknown_key_is_an_error_with_its_position() {
        let text = format!("{MINIMAL}fov = 3\n");
        let error = Scene::parse(Path::new("s.toml"), &text)
            .unwrap_err()
            .to_string();
        assert!(error.contains("s.toml"), "{error}");
        assert!(error.contains("unknown field `fov`"), "{error}");
        assert!(error.contains("line 6"), "{error}");
    }

    #[test]
    fn a_partial_shading_table_takes_defaults_for_what_it_omits() {
        let text = format!("{MINIMAL}[shading]\nambient = 0.5\n");
        let scene = Scene::parse(Path::new("s.toml"), &text).expect("parse");
        let expected = Shading {
            ambient: 0.5,
            ..Shading::default()
        };
        assert_eq!(scene.shading, expected);
    }

    #[test]
    fn camera_needs_a_placement() {
        let text = "[image]\nwidth = 4\nheight = 3\n[camera]\nposition = [0.0, 0.0, 1.0]\n";
        let error = Scene::parse(Path::new("s.toml"), text)
            .unwrap_err()
            .to_string();
        assert!(error.contains("look_at"), "{error}");
    }
}

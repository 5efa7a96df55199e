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
//!
//! [shading]
//! smooth = true                   # stored vertex normals, when the file has them
//! vertex_colors = true            # stored vertex colours times the albedo, likewise
//! ```

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::geometry::Point;

/// A parsed, checked scene.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    #[serde(default)]
    pub image: ImageSettings,
    #[serde(default)]
    pub camera: CameraSettings,
    #[serde(default)]
    pub shading: Shading,
    #[serde(default)]
    pub directional_light: Vec<DirectionalLight>,
    #[serde(default)]
    pub point_light: Vec<PointLight>,
    pub ambient_occlusion: Option<AmbientOcclusion>,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ImageSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel along each axis: `n` traces an n × n grid of primary rays per pixel
    /// (and the shadow and AO rays of each) and averages them.
    pub antialiasing: u32,
}

impl Default for ImageSettings {
    fn default() -> Self {
        ImageSettings {
            width: 1024,
            height: 1024,
            antialiasing: 1,
        }
    }
}

/// Either `position` + `look_at`, or automatic framing (`auto = true`, or neither of them
/// given) with an optional viewing `direction`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSettings {
    pub auto: bool,
    pub position: Option<Point>,
    pub look_at: Option<Point>,
    /// Automatic framing: from the model's centre towards the camera.
    pub direction: Option<Point>,
    /// Scenes are written for z-up models (`reducem render --up y` turns them for y-up ones).
    pub up: Point,
    pub fov_degrees: f32,
}

impl Default for CameraSettings {
    fn default() -> Self {
        CameraSettings {
            auto: false,
            position: None,
            look_at: None,
            direction: None,
            up: [0.0, 0.0, 1.0],
            fov_degrees: 45.0,
        }
    }
}

impl CameraSettings {
    /// Framed automatically: `auto = true`, or placed by neither `position` nor `look_at`.
    pub fn is_automatic(&self) -> bool {
        self.auto || (self.position.is_none() && self.look_at.is_none())
    }

    /// Refuses a camera with no view direction (position at look_at) or no roll (up along the
    /// view direction): either would render an image no one asked for. The tests are the ones
    /// the camera itself makes, so every camera accepted here renders as before.
    fn check_view(&self) -> Result<(), (&'static str, String)> {
        let view = match (self.position, self.look_at, self.direction) {
            (Some(position), Some(look_at), _) => {
                let view = Vec3::from(look_at) - Vec3::from(position);
                if view.normalize_or_zero() == Vec3::ZERO {
                    return Err((
                        "camera.look_at",
                        format!(
                            "{look_at:?} is the camera position {position:?}: the camera looks \
                             nowhere"
                        ),
                    ));
                }
                view
            }
            (_, _, Some(direction)) => -Vec3::from(direction),
            _ => return Ok(()),
        };
        let up = Vec3::from(self.up).normalize();
        if view.normalize().cross(up).length_squared() <= MIN_ROLL_SINE_SQUARED {
            return Err((
                "camera.up",
                format!(
                    "{:?} is parallel to the view direction {:?}: which way is up in the image \
                     is undefined",
                    self.up,
                    <[f32; 3]>::from(view)
                ),
            ));
        }
        Ok(())
    }
}

/// The squared sine below which the camera's up hint counts as parallel to its view direction
/// (the camera then has no defined roll).
pub const MIN_ROLL_SINE_SQUARED: f32 = 1e-12;

/// Surface and environment terms of the shading; a key the table omits takes its default.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
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
    /// Multiplies the linear radiance before the image is encoded.
    pub exposure: f32,
    /// Maps the exposed radiance to the image's values.
    pub tone_curve: ToneCurve,
    /// Light the model, or show its geometric normals as colours.
    pub mode: ShadingMode,
    /// Shade with the file's stored vertex normals, interpolated, when it has them.
    pub smooth: bool,
    /// Multiply the albedo by the file's stored vertex colours, interpolated, when it has them.
    pub vertex_colors: bool,
}

impl Default for Shading {
    fn default() -> Self {
        Shading {
            albedo: [0.8, 0.8, 0.8],
            ambient: 0.25,
            background: [0.05, 0.06, 0.08],
            seed: 1,
            exposure: 1.0,
            tone_curve: ToneCurve::Linear,
            mode: ShadingMode::Lit,
            smooth: true,
            vertex_colors: true,
        }
    }
}

/// What a pixel of the model shows.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ShadingMode {
    /// The lights, ambient light and effects of the scene.
    #[default]
    Lit,
    /// The geometric normal (turned towards the camera) as a colour: each component from -1 to
    /// 1 as the sRGB code from 0 to 255 of red, green and blue; no light, shadow or AO.
    Normals,
}

/// How exposed linear radiance becomes the image's value, channel by channel.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ToneCurve {
    /// The radiance itself, clipped at 1 when encoded.
    #[default]
    Linear,
    /// A shoulder that reaches 1 at [`FILMIC_WHITE`] instead of clipping at 1, so that bright
    /// lit faces keep their shading while exposure brightens the rest.
    Filmic,
}

/// The exposed radiance the filmic curve maps to 1.
pub const FILMIC_WHITE: f32 = 2.0;

impl ToneCurve {
    pub fn apply(self, value: f32) -> f32 {
        match self {
            ToneCurve::Linear => value,
            // Reinhard's curve with a white point: x (1 + x / w²) / (1 + x).
            ToneCurve::Filmic => {
                let value = value.max(0.0);
                value * (1.0 + value / (FILMIC_WHITE * FILMIC_WHITE)) / (1.0 + value)
            }
        }
    }
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DirectionalLight {
    /// The direction the light travels, from the light into the scene.
    pub direction: Point,
    #[serde(default = "default_intensity")]
    pub intensity: f32,
    #[serde(default)]
    pub cast_shadows: bool,
    /// `direction` is in the camera's frame (x right, y up, z towards the viewer), so the light
    /// keeps its place in the image from any side: a key light from the upper left stays there.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub relative_to_camera: bool,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PointLight {
    pub position: Point,
    #[serde(default = "default_intensity")]
    pub intensity: f32,
    #[serde(default)]
    pub cast_shadows: bool,
}

#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct AmbientOcclusion {
    pub samples: u32,
    /// Occluders farther than this (model units) do not count; default `distance_fraction` of
    /// the model's bounds diagonal.
    pub max_distance: Option<f32>,
    /// The AO distance as a fraction of the bounds diagonal when `max_distance` is not given,
    /// so that one scene suits models of any size; default 0.05.
    pub distance_fraction: Option<f32>,
}

impl Default for AmbientOcclusion {
    fn default() -> Self {
        AmbientOcclusion {
            samples: 16,
            max_distance: None,
            distance_fraction: None,
        }
    }
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
    /// Reads, parses and checks the scene file at `path`; `-` reads standard input (named so in
    /// errors).
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let (path, text) = match path.as_os_str() == "-" {
            true => {
                let mut text = String::new();
                let read = std::io::Read::read_to_string(&mut std::io::stdin(), &mut text);
                (Path::new("standard input"), read.map(|_| text))
            }
            false => (path, std::fs::read_to_string(path)),
        };
        let text = text.map_err(|source| SceneError::Io {
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

    /// Turns a scene written for a z-up model into one for a y-up model: every position and
    /// direction is rotated by -90° about x, so that the scene's z axis becomes y.
    pub fn turn_to_y_up(&mut self) {
        let turn = |[x, y, z]: Point| [x, z, -y];
        let camera = &mut self.camera;
        camera.position = camera.position.map(turn);
        camera.look_at = camera.look_at.map(turn);
        camera.direction = camera.direction.map(turn);
        camera.up = turn(camera.up);
        for light in &mut self.directional_light {
            if !light.relative_to_camera {
                light.direction = turn(light.direction);
            }
        }
        for light in &mut self.point_light {
            light.position = turn(light.position);
        }
    }

    /// This scene with its primary shading only: no shadows, no AO, one sample per pixel.
    pub fn primary_only(&self) -> Scene {
        let mut primary = self.clone();
        primary.ambient_occlusion = None;
        primary.image.antialiasing = 1;
        for light in &mut primary.directional_light {
            light.cast_shadows = false;
        }
        for light in &mut primary.point_light {
            light.cast_shadows = false;
        }
        primary
    }

    /// The semantic checks, for a scene changed after parsing: the offending key and why.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        let image = &self.image;
        if image.width == 0 || image.height == 0 || image.width > 16384 || image.height > 16384 {
            return Err((
                "image",
                format!("{}x{} is outside 1..=16384", image.width, image.height),
            ));
        }
        let factor = image.antialiasing;
        let fine_size = |size: u32| size.checked_mul(factor).is_some_and(|s| s <= 16384);
        if factor == 0 || !fine_size(image.width) || !fine_size(image.height) {
            return Err((
                "image.antialiasing",
                format!(
                    "{factor} must be at least 1, with {}x{} samples within 16384x16384",
                    u64::from(image.width) * u64::from(factor),
                    u64::from(image.height) * u64::from(factor)
                ),
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
        if placed && (camera.position.is_none() || camera.look_at.is_none()) {
            return Err((
                "camera",
                "needs both position and look_at (or neither, for automatic framing)".into(),
            ));
        }
        if camera.direction.is_some() && !camera.is_automatic() {
            return Err((
                "camera.direction",
                "only applies to automatic framing, not with position and look_at".into(),
            ));
        }
        check_vector("camera.up", &camera.up)?;
        if let Some(direction) = &camera.direction {
            check_vector("camera.direction", direction)?;
        }
        camera.check_view()?;
        for light in &self.directional_light {
            check_vector("directional_light.direction", &light.direction)?;
        }
        if !(self.shading.exposure.is_finite() && self.shading.exposure > 0.0) {
            return Err((
                "shading.exposure",
                format!("{} must be positive and finite", self.shading.exposure),
            ));
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
            if ao.distance_fraction.is_some_and(|f| !(f > 0.0 && f <= 1.0)) {
                return Err((
                    "ambient_occlusion.distance_fraction",
                    "must be within (0, 1]".into(),
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
    fn stored_attributes_are_used_unless_the_scene_turns_them_off() {
        let default = Scene::parse(Path::new("s.toml"), MINIMAL).expect("parse");
        assert!(default.shading.smooth && default.shading.vertex_colors);
        let text = format!("{MINIMAL}[shading]\nsmooth = false\nvertex_colors = false\n");
        let off = Scene::parse(Path::new("s.toml"), &text).expect("parse");
        assert!(!off.shading.smooth && !off.shading.vertex_colors);
    }

    #[test]
    fn every_table_may_be_left_out_or_partial() {
        let scene = Scene::parse(
            Path::new("s.toml"),
            "[image]\nwidth = 64\n[ambient_occlusion]\n",
        )
        .expect("parse");
        assert_eq!((scene.image.width, scene.image.height), (64, 1024));
        assert!(scene.camera.is_automatic());
        assert_eq!(scene.camera.up, [0.0, 0.0, 1.0]);
        assert_eq!(scene.ambient_occlusion, Some(AmbientOcclusion::default()));
        assert_eq!(scene.ambient_occlusion.map(|ao| ao.samples), Some(16));
        assert!(Scene::parse(Path::new("s.toml"), "").is_ok());
    }

    #[test]
    fn turning_to_y_up_maps_the_z_axis_to_y() {
        let text = "[camera]\nposition = [1.0, 2.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\n\
                    [[directional_light]]\ndirection = [0.0, 0.0, -1.0]\n";
        let mut scene = Scene::parse(Path::new("s.toml"), text).expect("parse");
        scene.turn_to_y_up();
        assert_eq!(scene.camera.position, Some([1.0, 3.0, -2.0]));
        assert_eq!(scene.camera.up, [0.0, 1.0, 0.0]);
        assert_eq!(scene.directional_light[0].direction, [0.0, -1.0, 0.0]);
    }

    #[test]
    fn lights_relative_to_the_camera_are_not_turned_for_y_up() {
        let text = "[[directional_light]]\ndirection = [0.5, -0.6, -0.6]\n\
                    relative_to_camera = true\n\
                    [[directional_light]]\ndirection = [0.0, 0.0, -1.0]\n";
        let mut scene = Scene::parse(Path::new("s.toml"), text).expect("parse");
        scene.turn_to_y_up();
        assert_eq!(scene.directional_light[0].direction, [0.5, -0.6, -0.6]);
        assert_eq!(scene.directional_light[1].direction, [0.0, -1.0, 0.0]);
    }

    #[test]
    fn the_filmic_curve_reaches_one_at_its_white_and_keeps_the_order() {
        let filmic = |x: f32| ToneCurve::Filmic.apply(x);
        assert_eq!(filmic(FILMIC_WHITE), 1.0);
        assert_eq!(filmic(0.0), 0.0);
        assert_eq!(ToneCurve::Linear.apply(1.5), 1.5);
        let values: Vec<f32> = (0..=40).map(|i| filmic(i as f32 * 0.05)).collect();
        assert!(
            values.windows(2).all(|pair| pair[0] < pair[1]),
            "{values:?}"
        );
        let text = format!("{MINIMAL}[shading]\ntone_curve = \"filmic\"\n");
        let scene = Scene::parse(Path::new("s.toml"), &text).expect("parse");
        assert_eq!(scene.shading.tone_curve, ToneCurve::Filmic);
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

//! The scene of `Scene.render`: a scene TOML path or a dict with its tables, and keyword
//! overrides named and applied like the flags of `reducem render`.

use std::path::PathBuf;

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use reducem::geometry::Point;
use reducem::render::scene::{Scene, SceneError};

use crate::errors::{io_error, ReducemError};

/// The overrides `Scene.render` takes, as `reducem render` names its flags.
const OVERRIDES: [&str; 11] = [
    "up",
    "width",
    "height",
    "antialiasing",
    "camera_position",
    "look_at",
    "camera_up",
    "fov",
    "ao_samples",
    "ao_distance",
    "exposure",
];

/// The scene `spec` describes, with `overrides` applied and checked.
pub fn load(spec: &Bound<'_, PyAny>, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<Scene> {
    let mut scene = match spec.cast::<PyDict>() {
        Ok(dict) => from_dict(dict)?,
        Err(_) => {
            let path: PathBuf = spec.extract().map_err(|_| {
                PyTypeError::new_err("scene must be a scene TOML path or a dict of its tables")
            })?;
            Scene::load(&path).map_err(scene_error)?
        }
    };
    if let Some(overrides) = overrides {
        apply(&mut scene, overrides)?;
    }
    scene
        .check()
        .map_err(|(key, detail)| PyValueError::new_err(format!("scene {key}: {detail}")))?;
    Ok(scene)
}

/// A scene dict (the TOML tables as dicts, light arrays as lists of dicts), parsed by the same
/// deserializer that reads scene files, so unknown keys are refused the same way.
fn from_dict(dict: &Bound<'_, PyDict>) -> PyResult<Scene> {
    let json: String = dict
        .py()
        .import("json")?
        .call_method1("dumps", (dict,))?
        .extract()?;
    let scene: Scene = serde_json::from_str(&json)
        .map_err(|error| PyValueError::new_err(format!("scene dict: {error}")))?;
    Ok(scene)
}

fn scene_error(error: SceneError) -> PyErr {
    match &error {
        SceneError::Io { source, .. } => io_error(source.kind(), error.to_string()),
        SceneError::Parse { .. } | SceneError::Invalid { .. } => {
            ReducemError::new_err(error.to_string())
        }
    }
}

/// Applies the overrides as `reducem render` applies its flags (`up` first).
fn apply(scene: &mut Scene, overrides: &Bound<'_, PyDict>) -> PyResult<()> {
    for key in overrides.keys() {
        let key: String = key.extract()?;
        if !OVERRIDES.contains(&key.as_str()) {
            return Err(PyTypeError::new_err(format!(
                "render() got an unexpected keyword argument {key:?} (overrides: {})",
                OVERRIDES.join(", ")
            )));
        }
    }
    let get = |key: &str| overrides.get_item(key);
    if let Some(up) = get("up")? {
        match up.extract::<String>()?.as_str() {
            "y" => scene.turn_to_y_up(),
            "z" => {}
            other => {
                return Err(PyValueError::new_err(format!(
                    "up={other:?}: expected \"y\" or \"z\""
                )))
            }
        }
    }
    let point = |key: &str| -> PyResult<Option<Point>> {
        get(key)?
            .map(|value| value.extract::<[f32; 3]>())
            .transpose()
    };
    let camera = &mut scene.camera;
    match (point("camera_position")?, point("look_at")?) {
        (Some(position), Some(look_at)) => {
            (camera.auto, camera.direction) = (false, None);
            (camera.position, camera.look_at) = (Some(position), Some(look_at));
        }
        (None, None) => {}
        _ => {
            return Err(PyValueError::new_err(
                "camera_position and look_at go together",
            ))
        }
    }
    if let Some(up) = point("camera_up")? {
        camera.up = up;
    }
    let number = |key: &str| -> PyResult<Option<f32>> {
        get(key)?.map(|value| value.extract::<f32>()).transpose()
    };
    let count = |key: &str| -> PyResult<Option<u32>> {
        get(key)?.map(|value| value.extract::<u32>()).transpose()
    };
    camera.fov_degrees = number("fov")?.unwrap_or(camera.fov_degrees);
    let image = &mut scene.image;
    image.width = count("width")?.unwrap_or(image.width);
    image.height = count("height")?.unwrap_or(image.height);
    image.antialiasing = count("antialiasing")?.unwrap_or(image.antialiasing);
    scene.shading.exposure = number("exposure")?.unwrap_or(scene.shading.exposure);
    match count("ao_samples")? {
        Some(0) => scene.ambient_occlusion = None,
        Some(samples) => scene.ambient_occlusion.get_or_insert_default().samples = samples,
        None => {}
    }
    if let Some(distance) = number("ao_distance")? {
        scene.ambient_occlusion.get_or_insert_default().max_distance = Some(distance);
    }
    Ok(())
}

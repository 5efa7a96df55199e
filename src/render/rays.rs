//! The rays the renderer traces for a scene with ambient occlusion, as plain ray lists, so that
//! benchmarks and tests trace exactly the renderer's workload without rendering an image.

use crate::format::reader::ReducemFile;
use crate::geometry::Aabb;
use crate::render::camera::Camera;
use crate::render::plan::Plan;
use crate::render::sampling::Surface;
use crate::render::scene::Scene;
use crate::render::tiles;
use crate::trace::{Ray, TraceOptions, Tracer};

/// Camera rays in the renderer's tile order and, per primary hit, its AO rays (same
/// secondary-ray frame and per-pixel seeds); lights are left out.
pub struct RendererRays {
    pub primary: Vec<Ray>,
    /// The scene's AO samples per primary hit, in the order of `primary`.
    pub ambient_occlusion: Vec<Ray>,
}

impl RendererRays {
    /// The rays of a square `scene` (width used for both sides) that declares ambient occlusion;
    /// `None` when it declares none.
    pub fn of(file: &ReducemFile, scene: &Scene) -> Option<RendererRays> {
        let size = scene.image.width;
        let bounds = Aabb {
            min: file.header().bounds_min,
            max: file.header().bounds_max,
        };
        let tracer = Tracer::new(file, TraceOptions::default());
        let camera = Camera::new(&tracer, &scene.camera, size, size);
        let ao = Plan::new(scene, &bounds, &camera).ambient_occlusion?;
        let pixels = tiles(size, size).concat();
        let primary: Vec<Ray> = pixels
            .iter()
            .map(|&p| camera.primary_ray(p % size, p / size))
            .collect();
        let hits = tracer.intersect_batch(&primary);
        let seed = scene.shading.seed;
        let ambient_occlusion = pixels
            .iter()
            .zip(&primary)
            .zip(hits)
            .filter_map(|((&pixel, ray), hit)| Some((pixel, Surface::at_hit(file, ray, &hit?)?)))
            .flat_map(|(pixel, surface)| {
                (0..ao.samples).map(move |s| surface.ao_ray(seed, pixel, s, ao.max_distance))
            })
            .collect();
        Some(RendererRays {
            primary,
            ambient_occlusion,
        })
    }
}

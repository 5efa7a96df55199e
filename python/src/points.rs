//! Closest-point queries of numpy points `(..., 3)`: validated (finite components), computed in
//! f32 from float64 as Open3D does, answered by the core's closest-point search in its spatial
//! order and written once into the flat buffers that become the returned arrays.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use reducem_core::format::reader::ReducemFile;
use reducem_core::geometry::Point;
use reducem_core::query::occupancy::point_inside;
use reducem_core::query::{closest_points as closest_in_spatial_order, signed_closest_points};
use reducem_core::trace::unit_normal;

use crate::primitive_ids::{PrimitiveIds, NO_PRIMITIVE};
use crate::rays::{self, Components};

/// Points answered by one task: enough to amortize scheduling, few enough to balance.
const CHUNK: usize = 1024;

/// Calls `read` with the leading shape and the components of `points` (any array-like shaped
/// `(..., 3)`, float32 or float64), after refusing a point with a NaN or infinite component.
pub fn with_points<T>(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    read: impl FnOnce(Vec<usize>, Components<'_>) -> PyResult<T>,
) -> PyResult<T> {
    rays::with_floats(
        points,
        "query_points",
        (3, "(..., 3)"),
        |shape, components| {
            let first_invalid = py.detach(|| {
                (0..components.points())
                    .into_par_iter()
                    .position_first(|i| !components.point(i).iter().all(|x| x.is_finite()))
            });
            if let Some(i) = first_invalid {
                let point = components.point(i);
                return Err(PyValueError::new_err(format!(
                    "query point {i} is not finite: {point:?}"
                )));
            }
            read(shape, components)
        },
    )
}

/// The answers of `compute_closest_points`, flat, in point order.
pub struct ClosestAnswers {
    pub distances: Vec<f32>,
    pub points: Vec<f32>,
    pub ids: Vec<u32>,
    pub uvs: Vec<f32>,
    pub normals: Vec<f32>,
}

/// The closest point of the surface to every point (rayon's current pool). A point with no
/// answer (an empty file) gets an infinite distance, NaN point and weights, and
/// [`NO_PRIMITIVE`], as `reducem closest` writes it.
pub fn closest_points(
    file: &ReducemFile,
    ids: &PrimitiveIds,
    points: Components<'_>,
) -> ClosestAnswers {
    let count = points.points();
    let found = closest_in_spatial_order(file, &gathered(points), f32::INFINITY);
    let mut answers = ClosestAnswers {
        distances: vec![0.0; count],
        points: vec![0.0; 3 * count],
        ids: vec![0; count],
        uvs: vec![0.0; 2 * count],
        normals: vec![0.0; 3 * count],
    };
    answers
        .distances
        .par_chunks_mut(CHUNK)
        .zip(answers.points.par_chunks_mut(3 * CHUNK))
        .zip(answers.ids.par_chunks_mut(CHUNK))
        .zip(answers.uvs.par_chunks_mut(2 * CHUNK))
        .zip(answers.normals.par_chunks_mut(3 * CHUNK))
        .enumerate()
        .for_each(|(chunk, ((((distances, at), id), uv), normal))| {
            for (k, distance) in distances.iter_mut().enumerate() {
                let Some(found) = found[chunk * CHUNK + k] else {
                    *distance = f32::INFINITY;
                    at[3 * k..3 * k + 3].fill(f32::NAN);
                    id[k] = NO_PRIMITIVE;
                    uv[2 * k..2 * k + 2].fill(f32::NAN);
                    continue;
                };
                *distance = found.distance;
                at[3 * k..3 * k + 3].copy_from_slice(&found.point);
                id[k] = ids.id(file, found.strip, found.window);
                uv[2 * k..2 * k + 2].copy_from_slice(&[found.u, found.v]);
                let corners = file
                    .strip(found.strip as usize)
                    .window_points(found.window as usize);
                normal[3 * k..3 * k + 3]
                    .copy_from_slice(&corners.map_or([0.0; 3], |c| unit_normal(&c)));
            }
        });
    answers
}

/// 1.0 for each point inside the surface, 0.0 outside, decided by `rays` rays
/// ([`point_inside`]).
pub fn occupancy(file: &ReducemFile, points: Components<'_>, rays: u32) -> Vec<f32> {
    (0..points.points())
        .into_par_iter()
        .map(|i| f32::from(u8::from(point_inside(file, &points.point(i), rays))))
        .collect()
}

/// The distance from each point to the surface, negative inside (decided by `rays` rays).
pub fn signed_distances(file: &ReducemFile, points: Components<'_>, rays: u32) -> Vec<f32> {
    let signed = signed_closest_points(file, &gathered(points), f32::INFINITY, rays);
    (0..points.points())
        .map(|i| signed.signed_distance(i))
        .collect()
}

/// The points of `points`, for the core's queries that answer them in a spatial order.
fn gathered(points: Components<'_>) -> Vec<Point> {
    (0..points.points())
        .into_par_iter()
        .map(|i| points.point(i))
        .collect()
}

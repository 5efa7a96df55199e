//! Signed distance: the closest point ([`super::closest`]) with the sign of inside/outside
//! ([`super::occupancy`]), negative inside.

use super::closest::{ClosestPoint, ClosestPointSearch};
use super::occupancy::{inside_rays, point_inside};
use super::point_order::answer_in_spatial_order;
use crate::format::reader::ReducemFile;
use crate::geometry::Point;

/// Closest points with their side of the surface.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SignedClosest {
    /// The closest point within the maximum distance, as [`super::closest_points`].
    pub closest: Vec<Option<ClosestPoint>>,
    pub inside: Vec<bool>,
    /// The file is closed, so every side is exact ([`super::occupancy::Occupancy::exact`]).
    pub exact: bool,
}

impl SignedClosest {
    /// Point `i`'s distance, negative inside; `+inf` when no triangle lies within the maximum
    /// distance.
    pub fn signed_distance(&self, i: usize) -> f32 {
        match (self.closest[i], self.inside[i]) {
            (None, _) => f32::INFINITY,
            (Some(found), true) => -found.distance,
            (Some(found), false) => found.distance,
        }
    }
}

/// The closest point within `max_distance` of every point and whether it is inside (one ray on a
/// closed file, else the majority of `samples`), in parallel (rayon's current pool), in a spatial
/// order.
pub fn signed_closest_points(
    file: &ReducemFile,
    points: &[Point],
    max_distance: f32,
    samples: u32,
) -> SignedClosest {
    let rays = inside_rays(file, samples);
    let (closest, inside) = answer_in_spatial_order(
        points,
        || ClosestPointSearch::new(file),
        |search, point| {
            let found = search.closest(point, max_distance);
            (found, point_inside(file, point, rays))
        },
    )
    .into_iter()
    .unzip();
    SignedClosest {
        closest,
        inside,
        exact: file.closed(),
    }
}

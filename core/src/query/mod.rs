//! Queries beyond the closest hit of a ray: the closest point of the surface to a point
//! ([`closest`], exact point-triangle distance in [`triangle_distance`]), every crossing of a
//! ray counted or listed with an exact tie rule ([`crossings`]), inside/outside
//! ([`occupancy`]) and signed distance ([`signed`]).
//!
//! Like the tracer, the queries read the mapped file in place through the reader's views and
//! page in only what they visit; on a lazily validated file a corrupt part they reach is kept
//! for [`ReducemFile::defect`], which callers report instead of an incomplete answer.

mod child_box;
pub mod closest;
mod crossing_packet;
mod crossing_stream;
mod crossing_walk;
pub mod crossings;
pub mod occupancy;
mod point_order;
pub mod signed;
mod top_walk;
pub mod triangle_distance;

use crate::format::reader::ReducemFile;
use crate::geometry::Point;
use crate::triangle_index::TriangleIndex;
pub use closest::{ClosestPoint, ClosestPointSearch};
pub use crossings::{
    all_hits, all_hits_on, count_crossings, count_crossings_on, AllHits, RayHit, NO_FACE,
};
pub use occupancy::{occupancy, points_inside, Occupancy};
pub use signed::{signed_closest_points, SignedClosest};

/// How a query names the triangle it answers with: the input face id when the file stores face
/// ids, else the triangle's row in `decode` order (as `cast_rays` does).
pub enum FaceIds {
    /// The file's input face ids.
    Stored,
    /// Rows in `decode` order, by each strip's first row.
    Positions(TriangleIndex),
}

impl FaceIds {
    /// The naming `file` supports; counts every strip's triangles when it has no face ids.
    pub fn of(file: &ReducemFile) -> FaceIds {
        match file.attributes().face_ids {
            true => FaceIds::Stored,
            false => FaceIds::Positions(TriangleIndex::new(file)),
        }
    }

    /// The id of `window` of strip `strip`; `None` when it does not fit in a u32 or its stored
    /// id is corrupt (kept for [`ReducemFile::defect`]).
    pub fn id(&self, file: &ReducemFile, strip: u32, window: u16) -> Option<u32> {
        match self {
            FaceIds::Stored => file.face_id(strip as usize, window as usize),
            FaceIds::Positions(index) => index
                .position(file, strip, window)
                .and_then(|position| u32::try_from(position).ok()),
        }
    }
}

/// [`ClosestPointSearch::closest`] for every point, in parallel (rayon's current pool), in a
/// spatial order ([`point_order`]).
pub fn closest_points(
    file: &ReducemFile,
    points: &[Point],
    max_distance: f32,
) -> Vec<Option<ClosestPoint>> {
    point_order::answer_in_spatial_order(
        points,
        || ClosestPointSearch::new(file),
        |search, point| search.closest(point, max_distance),
    )
}

//! OBJ input through `tobj`, keeping positions and each triangle's face.
//!
//! OBJ meshes of the sizes ReduceM targets are rare (the format is slow to write and parse),
//! so the robust parser of `tobj` is preferred over a hand-written fast path. Polygons are
//! fanned here exactly like the PLY reader does (`v0, vi, vi+1`), so winding is kept and every
//! triangle carries its polygon's face id (`f` statement order across groups). Each object or
//! group becomes a separate `tobj` model with its own vertex list; the models are
//! concatenated with index offsets, and the shared welding step reconnects vertices that
//! models duplicated.
//!
//! `tobj` reports errors without positions, so a survey of the file ([`super::obj_survey`])
//! runs first: it rejects defective statements with their element, index, line and byte offset
//! (and keeps absurd indices from overflowing `tobj`'s arithmetic), and when `tobj` or a later
//! check still fails, a second survey that knows the vertex total places the error. Statements
//! `tobj` would drop without a word (free-form geometry, unknown keywords) are counted and
//! reported once on stderr.

use std::path::Path;

use crate::input::error::{InputError, InputErrorKind, Location};
use crate::input::obj_survey::survey;
use crate::mesh::Mesh;

pub fn read_obj(path: &Path) -> Result<Mesh, InputError> {
    let options = tobj::LoadOptions {
        // Polygons are fanned here rather than by `tobj`, to know each triangle's face.
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    // The survey comes first: statements it rejects would only make `tobj` fail without a
    // position, or overflow its index arithmetic.
    let surveyed = survey(path, None).map_err(|error| {
        InputError::new(path, Location::File, InputErrorKind::Io(error.to_string()))
    })?;
    if let Some((location, kind)) = surveyed.defect {
        return Err(InputError::new(path, location, kind));
    }
    // Materials are irrelevant to geometry; a missing .mtl file must not fail the read.
    let (models, _materials) = tobj::load_obj(path, &options).map_err(|error| {
        let kind = InputErrorKind::Obj(error.to_string());
        located(
            path,
            surveyed.vertices,
            InputError::new(path, Location::File, kind),
        )
    })?;
    let mut mesh = Mesh {
        face_ids: Some(Vec::new()),
        ..Mesh::default()
    };
    let mut faces = 0;
    for model in &models {
        append_model(path, &mut mesh, &model.mesh, &mut faces)
            .map_err(|error| located(path, surveyed.vertices, error))?;
    }
    if let Some(summary) = surveyed.unknown_summary() {
        eprintln!("reducem: {}: {summary}", path.display());
    }
    Ok(mesh)
}

/// `error` placed at the first statement that a second survey, knowing the file's vertex total,
/// finds defective (a face vertex beyond it); as it is otherwise.
fn located(path: &Path, vertex_total: u64, error: InputError) -> InputError {
    match survey(path, Some(vertex_total)).ok().and_then(|s| s.defect) {
        Some((location, kind)) => InputError::new(path, location, kind),
        None => error,
    }
}

/// Appends `model`'s vertices and its faces' fan triangles, numbering the faces on from
/// `faces` (the faces of the models before it).
fn append_model(
    path: &Path,
    mesh: &mut Mesh,
    model: &tobj::Mesh,
    faces: &mut u64,
) -> Result<(), InputError> {
    let offset = mesh.positions.len();
    let vertex_count = offset + model.positions.len() / 3;
    if vertex_count as u64 > 1 << 32 {
        let kind = InputErrorKind::TooManyVertices {
            vertex_count: vertex_count as u64,
        };
        return Err(InputError::new(path, Location::File, kind));
    }
    // Every index, offset included, is below `vertex_count` ≤ 2^32.
    let offset = offset as u32;
    for point in model.positions.chunks_exact(3) {
        let point = [point[0], point[1], point[2]];
        check_finite(path, point)?;
        mesh.positions.push(point);
    }
    let polygons = polygons(model);
    let face_count = *faces + polygons.len() as u64;
    if face_count > 1 << 32 {
        let kind = InputErrorKind::TooManyFaces { face_count };
        return Err(InputError::new(path, Location::File, kind));
    }
    let face_ids = mesh.face_ids.get_or_insert_with(Vec::new);
    for (face, polygon) in (*faces..).zip(polygons) {
        let Some((&first, rest)) = polygon.split_first() else {
            continue;
        };
        for edge in rest.windows(2) {
            mesh.triangles
                .push([first, edge[0], edge[1]].map(|corner| corner + offset));
            // Below `face_count` ≤ 2^32.
            face_ids.push(face as u32);
        }
    }
    *faces = face_count;
    Ok(())
}

/// The model's faces as vertex index lists (`tobj` leaves `face_arities` empty when every face
/// is a triangle).
fn polygons(model: &tobj::Mesh) -> Vec<&[u32]> {
    if model.face_arities.is_empty() {
        return model.indices.chunks_exact(3).collect();
    }
    let mut start = 0;
    model
        .face_arities
        .iter()
        .map(|&arity| {
            let polygon = &model.indices[start..start + arity as usize];
            start += arity as usize;
            polygon
        })
        .collect()
}

/// Rejects NaN, infinities and coordinates beyond [`crate::geometry::MAX_COORDINATE`].
fn check_finite(path: &Path, point: [f32; 3]) -> Result<(), InputError> {
    let bad = |c: &f32| !c.is_finite() || c.abs() > crate::geometry::MAX_COORDINATE;
    match point.iter().position(bad) {
        None => Ok(()),
        Some(index) => {
            let (axis, value) = (['x', 'y', 'z'][index], point[index].into());
            let kind = if point[index].is_finite() {
                InputErrorKind::CoordinateOutOfRange { axis, value }
            } else {
                InputErrorKind::NonFiniteCoordinate { axis, value }
            };
            Err(InputError::new(path, Location::File, kind))
        }
    }
}

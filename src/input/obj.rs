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
//!
//! Normals, when asked for, come through each face corner's `vn` index: a vertex is then a
//! (position, normal) pair, so a `v` whose corners name different normals (a crease) becomes
//! one vertex per normal, at bit-identical positions. Colours come from `v x y z r g b`.
//! The survey checks, only when they are asked for, that the attributes are there for every
//! vertex and corner and that their values are usable, so `tobj`'s silent fallbacks (the
//! previous corner's normal for a corner without one, colours shifted onto the wrong vertices
//! when only some have one) never reach the mesh.

use std::collections::HashMap;
use std::path::Path;

use crate::input::error::{InputError, InputErrorKind, Location};
use crate::input::obj_survey::{survey, Totals};
use crate::input::ply::elements::unit_to_u8;
use crate::input::AttributeRequest;
use crate::mesh::Mesh;

/// Reads positions and triangles with each triangle's face.
pub fn read_obj(path: &Path) -> Result<Mesh, InputError> {
    read_obj_with(path, AttributeRequest::default())
}

/// Fails, naming the file and where, when it cannot give the attributes `request` asks for.
pub(crate) fn check_attributes(path: &Path, request: AttributeRequest) -> Result<(), InputError> {
    let surveyed = survey(path, None, request).map_err(|error| {
        InputError::new(path, Location::File, InputErrorKind::Io(error.to_string()))
    })?;
    match surveyed.defect_with(request) {
        Some((location, kind)) => Err(InputError::new(path, location, kind)),
        None => Ok(()),
    }
}

/// [`read_obj`] with the vertex attributes `request` asks for.
pub fn read_obj_with(path: &Path, request: AttributeRequest) -> Result<Mesh, InputError> {
    let options = tobj::LoadOptions {
        // Polygons are fanned here rather than by `tobj`, to know each triangle's face.
        triangulate: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    // The survey comes first: statements it rejects would only make `tobj` fail without a
    // position, or overflow its index arithmetic.
    let surveyed = survey(path, None, request).map_err(|error| {
        InputError::new(path, Location::File, InputErrorKind::Io(error.to_string()))
    })?;
    let (totals, unknown_summary) = (surveyed.totals(), surveyed.unknown_summary());
    if let Some((location, kind)) = surveyed.defect_with(request) {
        return Err(InputError::new(path, location, kind));
    }
    // Materials are irrelevant to geometry; a missing .mtl file must not fail the read.
    let (models, _materials) = tobj::load_obj(path, &options).map_err(|error| {
        let kind = InputErrorKind::Obj(error.to_string());
        located(path, totals, InputError::new(path, Location::File, kind))
    })?;
    let mut mesh = Mesh {
        face_ids: Some(Vec::new()),
        normals: request.normals.then(Vec::new),
        colors: request.colors.then(Vec::new),
        ..Mesh::default()
    };
    let mut faces = 0;
    for model in &models {
        append_model(path, &mut mesh, &model.mesh, &mut faces)
            .map_err(|error| located(path, totals, error))?;
    }
    if let Some(summary) = unknown_summary {
        eprintln!("reducem: {}: {summary}", path.display());
    }
    Ok(mesh)
}

/// `error` placed at the first statement that a second survey, knowing the file's totals,
/// finds defective (a face vertex or normal beyond them); as it is otherwise.
fn located(path: &Path, totals: Totals, error: InputError) -> InputError {
    let request = AttributeRequest::default();
    match survey(path, Some(totals), request)
        .ok()
        .and_then(|s| s.defect)
    {
        Some((location, kind)) => InputError::new(path, location, kind),
        None => error,
    }
}

/// Appends `model`'s vertices and its faces' fan triangles, numbering the faces on from
/// `faces` (the faces of the models before it). The attributes `mesh` has room for are
/// appended with the vertices.
fn append_model(
    path: &Path,
    mesh: &mut Mesh,
    model: &tobj::Mesh,
    faces: &mut u64,
) -> Result<(), InputError> {
    let offset = mesh.positions.len();
    let (sources, corners) = model_vertices(path, model, mesh.normals.is_some())?;
    let vertex_count = offset + sources.len();
    if vertex_count as u64 > 1 << 32 {
        let kind = InputErrorKind::TooManyVertices {
            vertex_count: vertex_count as u64,
        };
        return Err(InputError::new(path, Location::File, kind));
    }
    for source in &sources {
        append_vertex(path, mesh, model, source)?;
    }
    // Every index, offset included, is below `vertex_count` ≤ 2^32.
    let offset = offset as u32;
    let polygons = polygons(model, &corners);
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

/// Where a vertex of the mesh comes from in a `tobj` model: a position and, with normals, the
/// normal of the corners that use it.
#[derive(Clone, Copy)]
struct VertexSource {
    position: usize,
    normal: Option<usize>,
}

/// The model's vertices and, for each of its corners, the vertex it uses. Without normals
/// these are `tobj`'s positions and indices; with normals, one vertex per distinct (position,
/// normal) pair, in order of first use.
fn model_vertices(
    path: &Path,
    model: &tobj::Mesh,
    with_normals: bool,
) -> Result<(Vec<VertexSource>, Vec<u32>), InputError> {
    if !with_normals {
        let sources = (0..model.positions.len() / 3)
            .map(|position| VertexSource {
                position,
                normal: None,
            })
            .collect();
        return Ok((sources, model.indices.clone()));
    }
    if model.normal_indices.len() != model.indices.len() {
        let kind = InputErrorKind::Obj("some face corners have no normal index".into());
        return Err(InputError::new(path, Location::File, kind));
    }
    let mut sources = Vec::new();
    let mut vertex_of: HashMap<(u32, u32), u32> = HashMap::new();
    let corners = model
        .indices
        .iter()
        .zip(&model.normal_indices)
        .map(|(&position, &normal)| {
            *vertex_of.entry((position, normal)).or_insert_with(|| {
                sources.push(VertexSource {
                    position: position as usize,
                    normal: Some(normal as usize),
                });
                // Fewer distinct pairs than corners, which `tobj` indexes with u32.
                (sources.len() - 1) as u32
            })
        })
        .collect();
    Ok((sources, corners))
}

/// Appends one vertex: its position, checked, and the attributes `mesh` has room for.
fn append_vertex(
    path: &Path,
    mesh: &mut Mesh,
    model: &tobj::Mesh,
    source: &VertexSource,
) -> Result<(), InputError> {
    let triple = |values: &[f32], index: usize| -> Option<[f32; 3]> {
        values
            .get(3 * index..3 * index + 3)
            .map(|v| [v[0], v[1], v[2]])
    };
    let missing = |what: &str| {
        let kind = InputErrorKind::Obj(format!("a face corner refers to a missing {what}"));
        InputError::new(path, Location::File, kind)
    };
    let point = triple(&model.positions, source.position).ok_or_else(|| missing("vertex"))?;
    check_finite(path, point)?;
    mesh.positions.push(point);
    if let Some(normals) = &mut mesh.normals {
        let normal = source
            .normal
            .and_then(|index| triple(&model.normals, index))
            .ok_or_else(|| missing("normal"))?;
        normals.push(normal);
    }
    if let Some(colors) = &mut mesh.colors {
        let color = triple(&model.vertex_color, source.position)
            .and_then(|rgb| {
                let [r, g, b] = rgb.map(|c| unit_to_u8(c.into()));
                Some([r?, g?, b?, u8::MAX])
            })
            .ok_or_else(|| missing("colour"))?;
        colors.push(color);
    }
    Ok(())
}

/// The model's faces as lists of `corners` (`tobj` leaves `face_arities` empty when every face
/// is a triangle).
fn polygons<'a>(model: &tobj::Mesh, corners: &'a [u32]) -> Vec<&'a [u32]> {
    if model.face_arities.is_empty() {
        return corners.chunks_exact(3).collect();
    }
    let mut start = 0;
    model
        .face_arities
        .iter()
        .map(|&arity| {
            let polygon = &corners[start..start + arity as usize];
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

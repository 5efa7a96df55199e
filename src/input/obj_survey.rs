//! One streaming pass over an OBJ file's lines, beside `tobj`: it counts the statements `tobj`
//! drops without a word (free-form curves and surfaces, anything unknown) and, when `tobj`
//! rejected the file, finds the first defective statement, so that errors name the line and
//! byte offset that `tobj` does not report.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufRead, BufReader};
use std::path::Path;

use crate::input::error::{InputErrorKind, Location};
use crate::input::ply::elements::unit_to_u8;
use crate::input::AttributeRequest;

/// Statements that carry the geometry, or are known and irrelevant to it (`s`: smoothing
/// groups, `p`: points, `l`: lines, materials).
const KNOWN: [&str; 12] = [
    "v", "vt", "vn", "f", "l", "p", "o", "g", "s", "mtllib", "usemtl", "vp",
];

/// What a pass over the file found.
#[derive(Debug, Default)]
pub(crate) struct Survey {
    /// `v` statements.
    pub vertices: u64,
    /// Statements of unknown keywords, by keyword.
    pub unknown: BTreeMap<String, u64>,
    /// The first unknown statement: 1-based line and byte offset.
    pub first_unknown: Option<(u64, u64)>,
    /// The first defective statement: where it is and what is wrong.
    pub defect: Option<(Location, InputErrorKind)>,
    /// `vn` statements.
    pub normals: u64,
    /// `v` statements with a colour (`v x y z r g b`).
    pub colored_vertices: u64,
    /// With normals asked for: the first face corner without a normal index.
    pub first_corner_without_normal: Option<Location>,
    /// With colours asked for: the first vertex without a colour.
    pub first_vertex_without_color: Option<Location>,
}

impl Survey {
    pub(crate) fn totals(&self) -> Totals {
        Totals {
            vertices: self.vertices,
            normals: self.normals,
        }
    }

    /// The first defect, counting as defects what makes the attributes in `request` unusable:
    /// a file without any of them (reported at the file), or some faces or vertices without
    /// them while others have them (reported at the first such statement).
    pub(crate) fn defect_with(
        mut self,
        request: AttributeRequest,
    ) -> Option<(Location, InputErrorKind)> {
        if let Some(defect) = self.defect.take() {
            return Some(defect);
        }
        if request.normals {
            if self.normals == 0 {
                let kind = InputErrorKind::MissingAttribute {
                    attribute: "normals",
                    reason: "the file has no 'vn' statements".into(),
                };
                return Some((Location::File, kind));
            }
            if let Some(location) = self.first_corner_without_normal.take() {
                let kind = InputErrorKind::Obj(
                    "face corner without a normal index (normals were asked for)".into(),
                );
                return Some((location, kind));
            }
        }
        if request.colors {
            if self.colored_vertices == 0 {
                let kind = InputErrorKind::MissingAttribute {
                    attribute: "colours",
                    reason: "no vertex has a colour ('v x y z r g b')".into(),
                };
                return Some((Location::File, kind));
            }
            if let Some(location) = self.first_vertex_without_color.take() {
                let kind = InputErrorKind::Obj(
                    "vertex without a colour while others have one (colours were asked for)".into(),
                );
                return Some((location, kind));
            }
        }
        None
    }

    pub(crate) fn unknown_count(&self) -> u64 {
        self.unknown.values().sum()
    }

    /// One line for the user: how many statements were ignored, the first one, by keyword.
    pub(crate) fn unknown_summary(&self) -> Option<String> {
        let (line, offset) = self.first_unknown?;
        let by_keyword: Vec<String> = self
            .unknown
            .iter()
            .map(|(keyword, count)| format!("'{keyword}' {count}"))
            .collect();
        Some(format!(
            "{} unknown OBJ statements ignored (first at line {line}, byte {offset}; {})",
            self.unknown_count(),
            by_keyword.join(", ")
        ))
    }
}

/// The file's counts of the elements faces refer to, from a first survey.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Totals {
    pub vertices: u64,
    pub normals: u64,
}

/// Reads `path` line by line. With `totals` (from a first survey), face vertex and normal
/// indices beyond them are defects too; without it only statements that are wrong on their
/// own are. Attribute values are checked only when `request` asks for them.
pub(crate) fn survey(
    path: &Path,
    totals: Option<Totals>,
    request: AttributeRequest,
) -> io::Result<Survey> {
    let file = File::open(path)?;
    let limits = Limits {
        totals,
        file_length: file.metadata()?.len(),
        request,
    };
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let mut survey = Survey::default();
    let mut counts = Counts::default();
    let mut bytes = Vec::new();
    let mut place = Place { line: 0, offset: 0 };
    loop {
        bytes.clear();
        let read = reader.read_until(b'\n', &mut bytes)? as u64;
        if read == 0 {
            survey.vertices = counts.vertices;
            survey.normals = counts.normals;
            return Ok(survey);
        }
        place.line += 1;
        survey.take_line(&mut counts, place, &bytes, limits);
        place.offset += read;
    }
}

impl Survey {
    /// Counts one line starting at `place`, and records its defect if it is the first one.
    fn take_line(&mut self, counts: &mut Counts, place: Place, bytes: &[u8], limits: Limits) {
        let Ok(text) = std::str::from_utf8(bytes) else {
            let kind = InputErrorKind::Obj("the line is not UTF-8 text".into());
            let location = place.at("line", place.line - 1, 0);
            self.defect.get_or_insert((location, kind));
            return;
        };
        let Some((keyword, fields)) = statement(text) else {
            return;
        };
        if !KNOWN.contains(&keyword) {
            *self.unknown.entry(keyword.to_string()).or_default() += 1;
            self.first_unknown.get_or_insert((place.line, place.offset));
            return;
        }
        if self.defect.is_none() {
            self.defect = counts.check(keyword, &fields, place, text, limits);
        }
        self.note_attributes(counts, keyword, &fields, place, limits.request);
        counts.count(keyword);
    }

    /// Counts coloured vertices and notes the first statement without an attribute asked for.
    fn note_attributes(
        &mut self,
        counts: &Counts,
        keyword: &str,
        fields: &[Field],
        place: Place,
        request: AttributeRequest,
    ) {
        match keyword {
            "v" if fields.len() == 6 => self.colored_vertices += 1,
            "v" if request.colors && self.first_vertex_without_color.is_none() => {
                self.first_vertex_without_color = Some(place.at("vertex", counts.vertices, 0));
            }
            "f" if request.normals && self.first_corner_without_normal.is_none() => {
                let without_normal = fields.iter().find(|corner| {
                    corner_indices(corner.token).is_some_and(|(_, _, normal)| normal.is_none())
                });
                if let Some(corner) = without_normal {
                    let location = place.at("face", counts.faces, corner.column);
                    self.first_corner_without_normal = Some(location);
                }
            }
            _ => {}
        }
    }
}

/// A token of a statement and where it starts in its line, for the byte offset of a defect.
#[derive(Clone, Copy)]
struct Field<'a> {
    column: usize,
    token: &'a str,
}

/// The keyword and the fields of a statement, `None` for a blank line or a comment.
fn statement(text: &str) -> Option<(&str, Vec<Field<'_>>)> {
    let mut fields = text.split_ascii_whitespace().map(|token| Field {
        column: token.as_ptr() as usize - text.as_ptr() as usize,
        token,
    });
    let keyword = fields.next()?.token;
    (!keyword.starts_with('#')).then(|| (keyword, fields.collect()))
}

/// Where a line starts.
#[derive(Clone, Copy)]
struct Place {
    line: u64,
    offset: u64,
}

impl Place {
    fn at(&self, element: &str, index: u64, column: usize) -> Location {
        Location::Element {
            element: element.to_string(),
            index,
            byte_offset: self.offset + column as u64,
            line: Some(self.line),
        }
    }
}

/// Statements seen so far, for element indices and relative face indices.
#[derive(Default)]
struct Counts {
    vertices: u64,
    texture_coordinates: u64,
    normals: u64,
    faces: u64,
}

impl Counts {
    fn count(&mut self, keyword: &str) {
        match keyword {
            "v" => self.vertices += 1,
            "vt" => self.texture_coordinates += 1,
            "vn" => self.normals += 1,
            "f" => self.faces += 1,
            _ => {}
        }
    }

    /// The defect of one statement, if it has one.
    fn check(
        &self,
        keyword: &str,
        fields: &[Field],
        place: Place,
        text: &str,
        limits: Limits,
    ) -> Option<(Location, InputErrorKind)> {
        let (element, index, defect) = match keyword {
            "v" => (
                "vertex",
                self.vertices,
                check_vertex(fields, limits.request),
            ),
            "vt" => (
                "texture coordinate",
                self.texture_coordinates,
                check_floats(fields, 2, "texture coordinate"),
            ),
            "vn" => ("normal", self.normals, check_normal(fields, limits.request)),
            "f" => ("face", self.faces, self.check_face(fields, limits)),
            _ => return None,
        };
        let (column, kind) = defect?;
        let column = column.unwrap_or(text.trim_end().len());
        Some((place.at(element, index, column), kind))
    }

    /// The first corner that is malformed or names no element.
    fn check_face(
        &self,
        fields: &[Field],
        limits: Limits,
    ) -> Option<(Option<usize>, InputErrorKind)> {
        for corner in fields {
            let defect = match corner_indices(corner.token) {
                None => format!("malformed face corner '{}'", corner.token),
                Some((vertex, texture, normal)) => {
                    let references = [
                        (
                            Some(vertex),
                            self.vertices,
                            limits.totals.map(|totals| totals.vertices),
                            "vertex",
                            "vertices",
                        ),
                        (
                            texture,
                            self.texture_coordinates,
                            None,
                            "texture coordinate",
                            "texture coordinates",
                        ),
                        (
                            normal,
                            self.normals,
                            limits.totals.map(|totals| totals.normals),
                            "normal",
                            "normals",
                        ),
                    ];
                    let out_of_range =
                        references
                            .into_iter()
                            .find_map(|(index, seen, total, one, many)| {
                                let reference = Reference {
                                    seen,
                                    total,
                                    one,
                                    many,
                                };
                                index.and_then(|index| {
                                    reference.out_of_range(index, limits.file_length)
                                })
                            });
                    match out_of_range {
                        Some(defect) => defect,
                        None => continue,
                    }
                }
            };
            return Some((Some(corner.column), InputErrorKind::Obj(defect)));
        }
        None
    }
}

/// What the survey knows of the file when it checks a face.
#[derive(Clone, Copy)]
struct Limits {
    /// The file's totals, on the second survey.
    totals: Option<Totals>,
    /// No index can exceed the file's length in bytes; this bound also keeps `tobj`'s index
    /// arithmetic from overflowing on absurd indices, so they are rejected here first.
    file_length: u64,
    /// Attributes whose values are checked.
    request: AttributeRequest,
}

/// The elements a face corner can refer to: how many came before it, the total when known, and
/// their names.
struct Reference {
    seen: u64,
    total: Option<u64>,
    one: &'static str,
    many: &'static str,
}

impl Reference {
    /// Why `index` (1-based, or negative for relative) names no element, if it names none.
    fn out_of_range(&self, index: i64, file_length: u64) -> Option<String> {
        let resolved = if index < 0 {
            self.seen as i64 + index
        } else {
            index - 1
        };
        let limit = self.total.unwrap_or(file_length);
        (resolved < 0 || resolved as u64 >= limit).then(|| {
            let count = match self.total {
                Some(total) => format!("{total} {}", self.many),
                None => format!("{} {} before it", self.seen, self.many),
            };
            format!("face {} index {index} out of range ({count})", self.one)
        })
    }
}

/// The vertex, texture-coordinate and normal references of a face corner `v`, `v/vt`, `v//vn`
/// or `v/vt/vn`; `None` when it is malformed.
fn corner_indices(corner: &str) -> Option<(i64, Option<i64>, Option<i64>)> {
    let mut parts = corner.split('/');
    let vertex = parts.next()?.parse().ok()?;
    let mut optional = || match parts.next() {
        None | Some("") => Some(None),
        Some(part) => part.parse().ok().map(Some),
    };
    let (texture, normal) = (optional()?, optional()?);
    parts.next().is_none().then_some((vertex, texture, normal))
}

/// `vn x y z`: three numbers, finite when normals are asked for.
fn check_normal(
    fields: &[Field],
    request: AttributeRequest,
) -> Option<(Option<usize>, InputErrorKind)> {
    if let Some(defect) = check_floats(fields, 3, "normal") {
        return Some(defect);
    }
    if !request.normals {
        return None;
    }
    ['x', 'y', 'z']
        .iter()
        .zip(fields)
        .find_map(|(&axis, &Field { column, token })| {
            let value: f32 = token.parse().ok()?;
            let kind = InputErrorKind::NonFiniteNormal {
                axis,
                value: value.into(),
            };
            (!value.is_finite()).then_some((Some(column), kind))
        })
}

/// The colour of `v x y z r g b`, each in 0..1, when colours are asked for.
fn check_color(fields: &[Field]) -> Option<(Option<usize>, InputErrorKind)> {
    ["red", "green", "blue"].iter().zip(&fields[3..]).find_map(
        |(&channel, &Field { column, token })| {
            let kind = match token.parse::<f64>() {
                Err(_) => InputErrorKind::MalformedToken {
                    token: token.to_string(),
                    expected: "number",
                },
                Ok(value) if unit_to_u8(value).is_none() => {
                    InputErrorKind::ColorOutOfRange { channel, value }
                }
                Ok(_) => return None,
            };
            Some((Some(column), kind))
        },
    )
}

/// `v x y z [w | r g b]`: three coordinates in range, then nothing, a non-zero w or a colour
/// (checked when colours are asked for).
fn check_vertex(
    fields: &[Field],
    request: AttributeRequest,
) -> Option<(Option<usize>, InputErrorKind)> {
    if let Some(defect) = check_floats(fields, 3, "vertex position") {
        return Some(defect);
    }
    for (axis, &Field { column, token }) in fields.iter().enumerate().take(3) {
        let value: f32 = token.parse().ok()?;
        let Some(kind) = InputErrorKind::of_coordinate(axis, value) else {
            continue;
        };
        return Some((Some(column), kind));
    }
    match fields.len() {
        3 => None,
        6 if request.colors => check_color(fields),
        6 => None,
        4 if fields[3].token.parse::<f32>().is_ok_and(|w| w != 0.0) => None,
        4 => Some((
            Some(fields[3].column),
            InputErrorKind::Obj(format!("w '{}' is zero or not a number", fields[3].token)),
        )),
        _ => Some((
            None,
            InputErrorKind::Obj(format!(
                "a vertex has 3, 4 (x y z w) or 6 (x y z r g b) values, not {}",
                fields.len()
            )),
        )),
    }
}

/// The first `count` fields must be numbers.
fn check_floats(
    fields: &[Field],
    count: usize,
    what: &str,
) -> Option<(Option<usize>, InputErrorKind)> {
    if fields.len() < count {
        let kind = InputErrorKind::Obj(format!(
            "a {what} needs {count} numbers, found {}",
            fields.len()
        ));
        return Some((None, kind));
    }
    let field = fields[..count]
        .iter()
        .find(|field| field.token.parse::<f32>().is_err())?;
    let kind = InputErrorKind::MalformedToken {
        token: field.token.to_string(),
        expected: "number",
    };
    Some((Some(field.column), kind))
}

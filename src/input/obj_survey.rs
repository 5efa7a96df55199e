//! One streaming pass over an OBJ file's lines, beside `tobj`: it counts the statements `tobj`
//! drops without a word (free-form curves and surfaces, anything unknown) and, when `tobj`
//! rejected the file, finds the first defective statement, so that errors name the line and
//! byte offset that `tobj` does not report.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufRead, BufReader};
use std::path::Path;

use crate::input::error::{InputErrorKind, Location};

/// Statements that carry the geometry, or are known and irrelevant to it (`s`: smoothing
/// groups, `p`: points, `l`: lines, materials).
const KNOWN: [&str; 12] = [
    "v", "vt", "vn", "f", "l", "p", "o", "g", "s", "mtllib", "usemtl", "vp",
];

/// What a pass over the file found.
#[derive(Debug, Default)]
pub struct Survey {
    /// `v` statements.
    pub vertices: u64,
    /// Statements of unknown keywords, by keyword.
    pub unknown: BTreeMap<String, u64>,
    /// The first unknown statement: 1-based line and byte offset.
    pub first_unknown: Option<(u64, u64)>,
    /// The first defective statement: where it is and what is wrong.
    pub defect: Option<(Location, InputErrorKind)>,
}

impl Survey {
    pub fn unknown_count(&self) -> u64 {
        self.unknown.values().sum()
    }

    /// One line for the user: how many statements were ignored, the first one, by keyword.
    pub fn unknown_summary(&self) -> Option<String> {
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

/// Reads `path` line by line. With `vertex_count` (the file's total, from a first survey), face
/// vertex indices beyond it are defects too; without it only statements that are wrong on their
/// own are.
pub fn survey(path: &Path, vertex_count: Option<u64>) -> io::Result<Survey> {
    let file = File::open(path)?;
    let limits = Limits {
        vertices: vertex_count,
        file_length: file.metadata()?.len(),
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
        counts.count(keyword);
    }
}

/// The keyword and the fields of a statement, `None` for a blank line or a comment.
fn statement(text: &str) -> Option<(&str, Vec<(usize, &str)>)> {
    let mut tokens = text
        .split_ascii_whitespace()
        .map(|token| (token.as_ptr() as usize - text.as_ptr() as usize, token));
    let (_, keyword) = tokens.next()?;
    (!keyword.starts_with('#')).then(|| (keyword, tokens.collect()))
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
        fields: &[(usize, &str)],
        place: Place,
        text: &str,
        limits: Limits,
    ) -> Option<(Location, InputErrorKind)> {
        let (element, index, defect) = match keyword {
            "v" => ("vertex", self.vertices, check_vertex(fields)),
            "vt" => (
                "texture coordinate",
                self.texture_coordinates,
                check_floats(fields, 2, "texture coordinate"),
            ),
            "vn" => ("normal", self.normals, check_floats(fields, 3, "normal")),
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
        fields: &[(usize, &str)],
        limits: Limits,
    ) -> Option<(Option<usize>, InputErrorKind)> {
        for &(column, corner) in fields {
            let defect = match corner_indices(corner) {
                None => format!("malformed face corner '{corner}'"),
                Some((vertex, texture, normal)) => {
                    let references = [
                        (
                            Some(vertex),
                            self.vertices,
                            limits.vertices,
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
                        (normal, self.normals, None, "normal", "normals"),
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
            return Some((Some(column), InputErrorKind::Obj(defect)));
        }
        None
    }
}

/// What the survey knows of the file when it checks a face.
#[derive(Clone, Copy)]
struct Limits {
    /// The file's vertex total, on the second survey.
    vertices: Option<u64>,
    /// No index can exceed the file's length in bytes; this bound also keeps `tobj`'s index
    /// arithmetic from overflowing on absurd indices, so they are rejected here first.
    file_length: u64,
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

/// `v x y z [w | r g b]`: three coordinates in range, then nothing, a non-zero w or a colour.
fn check_vertex(fields: &[(usize, &str)]) -> Option<(Option<usize>, InputErrorKind)> {
    if let Some(defect) = check_floats(fields, 3, "vertex position") {
        return Some(defect);
    }
    for (axis, &(column, token)) in ['x', 'y', 'z'].iter().zip(fields) {
        let value: f32 = token.parse().ok()?;
        let kind = if !value.is_finite() {
            InputErrorKind::NonFiniteCoordinate {
                axis: *axis,
                value: value.into(),
            }
        } else if value.abs() > crate::geometry::MAX_COORDINATE {
            InputErrorKind::CoordinateOutOfRange {
                axis: *axis,
                value: value.into(),
            }
        } else {
            continue;
        };
        return Some((Some(column), kind));
    }
    match fields.len() {
        3 | 6 => None,
        4 if fields[3].1.parse::<f32>().is_ok_and(|w| w != 0.0) => None,
        4 => Some((
            Some(fields[3].0),
            InputErrorKind::Obj(format!("w '{}' is zero or not a number", fields[3].1)),
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
    fields: &[(usize, &str)],
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
    let (column, token) = fields[..count]
        .iter()
        .find(|(_, t)| t.parse::<f32>().is_err())?;
    let kind = InputErrorKind::MalformedToken {
        token: token.to_string(),
        expected: "number",
    };
    Some((Some(*column), kind))
}

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

/// Reads `path` line by line. With `vertex_count` (the file's total), face indices beyond it are
/// defects too; without it only statements that are wrong on their own are.
pub fn survey(path: &Path, vertex_count: Option<u64>) -> io::Result<Survey> {
    let mut reader = BufReader::with_capacity(1 << 20, File::open(path)?);
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
        survey.take_line(&mut counts, place, &bytes, vertex_count.unwrap_or(u64::MAX));
        place.offset += read;
    }
}

impl Survey {
    /// Counts one line starting at `place`, and records its defect if it is the first one.
    fn take_line(&mut self, counts: &mut Counts, place: Place, bytes: &[u8], vertex_total: u64) {
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
            self.defect = counts.check(keyword, &fields, place, text, vertex_total);
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
        vertex_total: u64,
    ) -> Option<(Location, InputErrorKind)> {
        let (element, index, defect) = match keyword {
            "v" => ("vertex", self.vertices, check_vertex(fields)),
            "vt" => (
                "texture coordinate",
                self.texture_coordinates,
                check_floats(fields, 2, "texture coordinate"),
            ),
            "vn" => ("normal", self.normals, check_floats(fields, 3, "normal")),
            "f" => ("face", self.faces, self.check_face(fields, vertex_total)),
            _ => return None,
        };
        let (column, kind) = defect?;
        let column = column.unwrap_or(text.trim_end().len());
        Some((place.at(element, index, column), kind))
    }

    /// The first corner that is malformed or names no vertex.
    fn check_face(
        &self,
        fields: &[(usize, &str)],
        vertex_total: u64,
    ) -> Option<(Option<usize>, InputErrorKind)> {
        for &(column, corner) in fields {
            let Some(index) = corner_vertex(corner) else {
                let kind = InputErrorKind::Obj(format!("malformed face corner '{corner}'"));
                return Some((Some(column), kind));
            };
            let resolved = if index < 0 {
                self.vertices as i64 + index
            } else {
                index - 1
            };
            if resolved < 0 || resolved as u64 >= vertex_total {
                let total = if vertex_total == u64::MAX {
                    self.vertices
                } else {
                    vertex_total
                };
                let kind = InputErrorKind::Obj(format!(
                    "face vertex index {index} out of range ({total} vertices)"
                ));
                return Some((Some(column), kind));
            }
        }
        None
    }
}

/// The vertex index of a face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`.
fn corner_vertex(corner: &str) -> Option<i64> {
    let parts: Vec<&str> = corner.split('/').collect();
    let references_ok = parts[1..]
        .iter()
        .all(|part| part.is_empty() || part.parse::<i64>().is_ok());
    (parts.len() <= 3 && references_ok)
        .then(|| parts[0].parse().ok())
        .flatten()
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

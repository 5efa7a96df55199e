//! STL, binary and ASCII, read through a buffer and welded as it is read (the chunker's
//! bounded-memory weld of the same mesh is [`super::stl_stream`]).
//!
//! STL repeats every corner in every facet; a map from position bits to vertex welds
//! bit-identical positions (so `-0.0` and `0.0` stay apart, as in [`super::weld`]) in order of
//! first occurrence, which is exactly what welding the triangle soup afterwards would give, at a
//! third of its memory. The facet normal is skipped: geometry comes from the corners, and the
//! face id of a triangle is its facet's index.
//!
//! Binary or ASCII is decided by the size: a file of exactly 84 + 50 × (its declared facet
//! count) bytes is binary, even when its 80-byte header begins with `solid`, as many
//! exporters' do. Otherwise a file starting with `solid` followed by text is ASCII, and any
//! other file is a binary one whose count disagrees with its size, an error naming both.

use std::collections::HashMap;
use std::fs::File;
use std::hash::BuildHasherDefault;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::error::{InputError, InputErrorKind, Location};
use super::ply::io_error;
use super::AttributeRequest;
use crate::geometry::Point;
use crate::mesh::Mesh;
use crate::splitmix::WordHasher;

const HEADER_BYTES: u64 = 80;
const FACET_BYTES: u64 = 50;
/// Bytes of a file looked at to tell ASCII from a binary header that begins with `solid`.
const TEXT_PROBE_BYTES: usize = 512;

/// True when `head` and `length` (when known) are an STL file's.
pub(crate) fn looks_like_stl(head: &[u8], length: Option<u64>) -> bool {
    is_ascii(head) || length.is_some_and(|length| binary_size_matches(head, length))
}

fn is_ascii(head: &[u8]) -> bool {
    let text = head.trim_ascii_start();
    let probe = &head[..head.len().min(TEXT_PROBE_BYTES)];
    text.len() >= 5
        && text[..5].eq_ignore_ascii_case(b"solid")
        && probe
            .iter()
            .all(|&byte| !byte.is_ascii_control() || byte.is_ascii_whitespace())
}

fn binary_size_matches(head: &[u8], length: u64) -> bool {
    declared_facets(head).is_some_and(|count| expected_size(count) == length)
}

fn declared_facets(head: &[u8]) -> Option<u32> {
    let bytes = head.get(HEADER_BYTES as usize..HEADER_BYTES as usize + 4)?;
    Some(u32::from_le_bytes(bytes.try_into().ok()?))
}

fn expected_size(facets: u32) -> u64 {
    HEADER_BYTES + 4 + FACET_BYTES * u64::from(facets)
}

/// STL has one normal per facet and no colours, so it gives no vertex attributes.
pub(crate) fn check_attributes(path: &Path, request: AttributeRequest) -> Result<(), InputError> {
    let (attribute, reason) = if request.normals {
        (
            "normals",
            "STL stores one normal per facet, none per vertex",
        )
    } else if request.colors {
        ("colours", "STL has no colours")
    } else {
        return Ok(());
    };
    let kind = InputErrorKind::MissingAttribute {
        attribute,
        reason: reason.into(),
    };
    Err(InputError::new(path, Location::File, kind))
}

/// How an STL file is laid out, told by its size and first bytes.
pub(crate) enum StlLayout {
    Binary { facets: u64 },
    Ascii,
}

/// Tells binary from ASCII, or fails naming the declared facet count and the size when the
/// file is neither.
pub(crate) fn layout(path: &Path) -> Result<StlLayout, InputError> {
    let mut file = File::open(path).map_err(|error| io_error(path, &error))?;
    let length = file
        .metadata()
        .map_err(|error| io_error(path, &error))?
        .len();
    let mut head = Vec::with_capacity(TEXT_PROBE_BYTES);
    (&mut file)
        .take(TEXT_PROBE_BYTES as u64)
        .read_to_end(&mut head)
        .map_err(|error| io_error(path, &error))?;
    if binary_size_matches(&head, length) {
        let facets = (length - HEADER_BYTES - 4) / FACET_BYTES;
        return Ok(StlLayout::Binary { facets });
    }
    if is_ascii(&head) {
        return Ok(StlLayout::Ascii);
    }
    let Some(declared) = declared_facets(&head) else {
        let kind = InputErrorKind::Truncated {
            needed: HEADER_BYTES + 4 - length,
        };
        return Err(InputError::new(path, Location::File, kind));
    };
    let kind = InputErrorKind::StlFacetCount {
        declared,
        expected_bytes: expected_size(declared),
        bytes: length,
        whole_facets: (length - HEADER_BYTES - 4) / FACET_BYTES,
    };
    Err(InputError::new(path, Location::File, kind))
}

/// Reads a binary or ASCII STL file, welded.
pub(crate) fn read_stl(path: &Path) -> Result<Mesh, InputError> {
    let mut welder;
    match layout(path)? {
        StlLayout::Binary { facets } => {
            welder = Welder::with_capacity(facets as usize);
            for_each_binary_facet(path, facets, |facet, corners| {
                welder.polygon(path, facet, &corners)
            })?;
        }
        StlLayout::Ascii => {
            welder = Welder::with_capacity(0);
            read_ascii(path, &mut welder)?;
        }
    }
    Ok(welder.into_mesh())
}

/// Visits the corners of every facet of a binary STL of `facets` facets, in file order, as
/// `visit(facet, corners)`, checking each coordinate.
pub(crate) fn for_each_binary_facet(
    path: &Path,
    facets: u64,
    mut visit: impl FnMut(u64, [Point; 3]) -> Result<(), InputError>,
) -> Result<(), InputError> {
    let file = File::open(path).map_err(|error| io_error(path, &error))?;
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let mut skipped = [0u8; HEADER_BYTES as usize + 4];
    reader
        .read_exact(&mut skipped)
        .map_err(|error| io_error(path, &error))?;
    let mut facet = [0u8; FACET_BYTES as usize];
    for index in 0..facets {
        reader
            .read_exact(&mut facet)
            .map_err(|error| io_error(path, &error))?;
        let start = HEADER_BYTES + 4 + index * FACET_BYTES;
        let mut corners = [[0f32; 3]; 3];
        for (corner, point) in corners.iter_mut().enumerate() {
            for (axis, coordinate) in point.iter_mut().enumerate() {
                let offset = 12 + 12 * corner + 4 * axis;
                let bytes = facet[offset..offset + 4].try_into().expect("4 bytes");
                let value = f32::from_le_bytes(bytes);
                let location = || facet_location(index, start + offset as u64, None);
                *coordinate = checked_coordinate(path, axis, value, location)?;
            }
        }
        visit(index, corners)?;
    }
    Ok(())
}

/// Reads the ASCII STL at `path`, handing every facet's corners to `facets`.
pub(crate) fn read_ascii(path: &Path, facets: &mut dyn FacetSink) -> Result<(), InputError> {
    let file = File::open(path).map_err(|error| io_error(path, &error))?;
    AsciiReader::new(path, BufReader::with_capacity(1 << 20, file), facets).read()
}

/// Where an ASCII STL's facets go: welded in memory, or written out for the streamed weld.
pub(crate) trait FacetSink {
    /// The corners of facet `facet` (three, or more for a polygon facet, which becomes a fan).
    fn polygon(&mut self, path: &Path, facet: u64, corners: &[Point]) -> Result<(), InputError>;
}

fn facet_location(index: u64, byte_offset: u64, line: Option<u64>) -> Location {
    Location::Element {
        element: "facet".into(),
        index,
        byte_offset,
        line,
    }
}

fn checked_coordinate(
    path: &Path,
    axis: usize,
    value: f32,
    location: impl FnOnce() -> Location,
) -> Result<f32, InputError> {
    match InputErrorKind::of_coordinate(axis, value) {
        None => Ok(value),
        Some(kind) => Err(InputError::new(path, location(), kind)),
    }
}

/// Vertices by position bits, in order of first occurrence, and the triangles over them.
struct Welder {
    index: HashMap<[u32; 3], u32, BuildHasherDefault<WordHasher>>,
    positions: Vec<Point>,
    triangles: Vec<[u32; 3]>,
}

impl Welder {
    fn with_capacity(facets: usize) -> Welder {
        // Closed surfaces have about half as many vertices as triangles.
        let vertices = facets / 2 + 3;
        Welder {
            index: HashMap::with_capacity_and_hasher(vertices, Default::default()),
            positions: Vec::with_capacity(vertices),
            triangles: Vec::with_capacity(facets),
        }
    }

    fn vertex(&mut self, path: &Path, point: Point, facet: u64) -> Result<u32, InputError> {
        if facet > u64::from(u32::MAX) {
            let kind = InputErrorKind::TooManyFaces {
                face_count: facet + 1,
            };
            return Err(InputError::new(path, Location::File, kind));
        }
        let next = self.positions.len();
        let vertex = *self
            .index
            .entry(point.map(f32::to_bits))
            .or_insert_with(|| {
                self.positions.push(point);
                next as u32
            });
        if next == u32::MAX as usize {
            let kind = InputErrorKind::TooManyVertices {
                vertex_count: next as u64 + 1,
            };
            return Err(InputError::new(path, Location::File, kind));
        }
        Ok(vertex)
    }

    fn into_mesh(self) -> Mesh {
        Mesh {
            positions: self.positions,
            triangles: self.triangles,
            face_ids: None,
            normals: None,
            colors: None,
        }
    }
}

impl FacetSink for Welder {
    fn polygon(&mut self, path: &Path, facet: u64, corners: &[Point]) -> Result<(), InputError> {
        let mut vertices = Vec::with_capacity(corners.len());
        for &point in corners {
            vertices.push(self.vertex(path, point, facet)?);
        }
        self.triangles.extend(fan(&vertices));
        Ok(())
    }
}

/// The triangles `(v0, vi, vi+1)` of a polygon, as PLY and OBJ faces are split.
pub(crate) fn fan<T: Copy>(corners: &[T]) -> impl Iterator<Item = [T; 3]> + '_ {
    corners[1..]
        .windows(2)
        .map(|pair| [corners[0], pair[0], pair[1]])
}

/// A reader of ASCII STL that knows the line and byte of every token.
struct AsciiReader<'a, R> {
    path: &'a Path,
    reader: R,
    line: String,
    /// 1-based number of the line in `line`.
    line_number: u64,
    /// File offset of `line`'s first byte.
    line_start: u64,
    /// Offset within `line` of the next token.
    cursor: usize,
    /// The facet being read (the count read so far, between facets).
    facet: u64,
    facets: &'a mut dyn FacetSink,
}

impl<'a, R: BufRead> AsciiReader<'a, R> {
    fn new(path: &'a Path, reader: R, facets: &'a mut dyn FacetSink) -> Self {
        AsciiReader {
            path,
            reader,
            line: String::new(),
            line_number: 0,
            line_start: 0,
            cursor: 0,
            facet: 0,
            facets,
        }
    }

    /// `solid` blocks, each of facets up to its `endsolid`, until the end of the file.
    fn read(mut self) -> Result<(), InputError> {
        while let Some((keyword, _)) = self.token()? {
            if !keyword.eq_ignore_ascii_case("solid") {
                return Err(self.unexpected("solid", &keyword));
            }
            self.skip_rest_of_line();
            while self.facet()? {}
        }
        if self.facet == 0 {
            let kind = InputErrorKind::UnexpectedEndOfText;
            return Err(InputError::new(self.path, Location::File, kind));
        }
        Ok(())
    }

    /// One facet; false at the `endsolid` that closes the block.
    fn facet(&mut self) -> Result<bool, InputError> {
        let keyword = self.required_token()?.0;
        if keyword.eq_ignore_ascii_case("endsolid") {
            self.skip_rest_of_line();
            return Ok(false);
        }
        if !keyword.eq_ignore_ascii_case("facet") {
            return Err(self.unexpected("facet' or 'endsolid", &keyword));
        }
        // The normal is ignored for geometry, but its line still has to be well formed text.
        self.skip_rest_of_line();
        self.keyword("outer")?;
        self.keyword("loop")?;
        let mut corners: Vec<Point> = Vec::with_capacity(3);
        loop {
            let keyword = self.required_token()?.0;
            if keyword.eq_ignore_ascii_case("endloop") {
                break;
            }
            if !keyword.eq_ignore_ascii_case("vertex") {
                return Err(self.unexpected("vertex' or 'endloop", &keyword));
            }
            corners.push(self.point()?);
        }
        self.keyword("endfacet")?;
        if corners.len() < 3 {
            let kind = InputErrorKind::TooFewFaceVertices(corners.len() as u64);
            return Err(InputError::new(self.path, self.location(0), kind));
        }
        // A polygon facet (some exporters write them) becomes a fan, like PLY and OBJ faces.
        self.facets.polygon(self.path, self.facet, &corners)?;
        self.facet += 1;
        Ok(true)
    }

    fn point(&mut self) -> Result<Point, InputError> {
        let mut point = [0f32; 3];
        for (axis, coordinate) in point.iter_mut().enumerate() {
            let (token, at) = self.required_token()?;
            // `str::parse::<f32>` rounds the decimal once, correctly, to the nearest f32;
            // parsing as f64 and narrowing would round twice.
            let Ok(value) = token.parse::<f32>() else {
                let kind = InputErrorKind::MalformedToken {
                    token,
                    expected: "float",
                };
                return Err(InputError::new(self.path, self.location(at), kind));
            };
            *coordinate = checked_coordinate(self.path, axis, value, || self.location(at))?;
        }
        Ok(point)
    }

    fn keyword(&mut self, expected: &'static str) -> Result<(), InputError> {
        let keyword = self.required_token()?.0;
        if keyword.eq_ignore_ascii_case(expected) {
            Ok(())
        } else {
            Err(self.unexpected(expected, &keyword))
        }
    }

    fn unexpected(&self, expected: &'static str, found: &str) -> InputError {
        let kind = InputErrorKind::StlSyntax {
            expected,
            found: found.chars().take(40).collect::<String>().into(),
        };
        let at = self.cursor.saturating_sub(found.len());
        InputError::new(self.path, self.location(at), kind)
    }

    fn location(&self, at: usize) -> Location {
        facet_location(
            self.facet,
            self.line_start + at as u64,
            Some(self.line_number),
        )
    }

    fn skip_rest_of_line(&mut self) {
        self.cursor = self.line.len();
    }

    fn required_token(&mut self) -> Result<(String, usize), InputError> {
        match self.token()? {
            Some(token) => Ok(token),
            None => {
                let kind = InputErrorKind::UnexpectedEndOfText;
                let at = self.line.len();
                Err(InputError::new(self.path, self.location(at), kind))
            }
        }
    }

    /// The next whitespace-separated token and its offset in the line, reading lines as
    /// needed; `None` at the end of the file.
    fn token(&mut self) -> Result<Option<(String, usize)>, InputError> {
        loop {
            let rest = &self.line[self.cursor..];
            let trimmed = rest.trim_start();
            if !trimmed.is_empty() {
                let start = self.cursor + rest.len() - trimmed.len();
                let end = trimmed
                    .find(|c: char| c.is_ascii_whitespace())
                    .map_or(self.line.len(), |length| start + length);
                self.cursor = end;
                return Ok(Some((self.line[start..end].to_string(), start)));
            }
            if !self.next_line()? {
                return Ok(None);
            }
        }
    }

    fn next_line(&mut self) -> Result<bool, InputError> {
        self.line_start += self.line.len() as u64;
        self.line.clear();
        self.cursor = 0;
        let mut bytes = Vec::new();
        let read = self
            .reader
            .read_until(b'\n', &mut bytes)
            .map_err(|error| io_error(self.path, &error))?;
        if read == 0 {
            return Ok(false);
        }
        self.line_number += 1;
        match String::from_utf8(bytes) {
            Ok(line) => {
                self.line = line;
                Ok(true)
            }
            Err(error) => {
                let at = error.utf8_error().valid_up_to();
                let kind = InputErrorKind::NotText;
                Err(InputError::new(self.path, self.location(at), kind))
            }
        }
    }
}

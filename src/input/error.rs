//! The one error type of mesh input: what is wrong, in which file, and exactly where.
//!
//! An error is a typed [`InputErrorKind`] plus a [`Location`], so callers can match on the
//! defect while users get a message that points into the file, e.g.
//! `model.ply: element 'face' #1234 at byte 5678: vertex index 99 out of range (5 vertices)`.
//! Locations inside a PLY body always carry the element name, the element's index and the
//! byte offset of the offending value (for ASCII bodies also the line), because on a
//! multi-gigabyte file "somewhere in the faces" is useless. Header errors come from ply-rs,
//! which only knows lines; we keep its message verbatim rather than re-deriving it.

use std::fmt;
use std::path::{Path, PathBuf};

/// A defect found while reading a mesh file.
#[derive(Debug, thiserror::Error)]
#[error("{}: {location}{kind}", path.display())]
pub struct InputError {
    pub path: PathBuf,
    pub location: Location,
    pub kind: InputErrorKind,
}

impl InputError {
    pub fn new(path: &Path, location: Location, kind: InputErrorKind) -> InputError {
        InputError {
            path: path.to_path_buf(),
            location,
            kind,
        }
    }
}

/// Where in the file a defect is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Location {
    /// The file as a whole (opening it, its extension, its overall structure).
    File,
    /// A header line (1-based).
    Header { line: u64 },
    /// A value inside the body: the element instance it belongs to and the byte offset in
    /// the file where the offending value starts (or would start, for truncation).
    Element {
        element: String,
        index: u64,
        byte_offset: u64,
        /// 1-based line for ASCII bodies; `None` for binary ones.
        line: Option<u64>,
    },
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::File => Ok(()),
            Location::Header { line } => write!(f, "header line {line}: "),
            Location::Element {
                element,
                index,
                byte_offset,
                line,
            } => {
                write!(f, "element '{element}' #{index} at byte {byte_offset}")?;
                if let Some(line) = line {
                    write!(f, " (line {line})")?;
                }
                f.write_str(": ")
            }
        }
    }
}

/// What is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InputErrorKind {
    #[error("cannot read file: {0}")]
    Io(String),
    /// Neither the content nor the extension names a format read (the list of them).
    #[error("not a mesh format reducem reads (it reads {0})")]
    UnsupportedFormat(String),
    /// `detail` says after how many decompressed bytes, and what the decoder found.
    #[error("the {compression} stream is corrupt {detail}")]
    Decompression {
        compression: &'static str,
        detail: Box<str>,
    },
    /// A binary STL whose size is not 84 + 50 × its declared facet count; read neither way,
    /// since either number may be the wrong one.
    #[error(
        "the binary STL header declares {declared} facets ({expected_bytes} bytes), \
         but the file has {bytes} bytes (room for {whole_facets} whole facets)"
    )]
    StlFacetCount {
        declared: u32,
        expected_bytes: u64,
        bytes: u64,
        whole_facets: u64,
    },
    #[error("expected '{expected}', found '{found}'")]
    StlSyntax {
        expected: &'static str,
        found: Box<str>,
    },
    #[error("the text is not UTF-8")]
    NotText,
    #[error("not a PLY file (it does not start with the line 'ply')")]
    NotPly,
    #[error("invalid PLY header: {0}")]
    Header(String),
    #[error("the header declares no '{0}' element")]
    MissingElement(&'static str),
    #[error("unsupported property: {0}")]
    UnsupportedProperty(String),
    /// Reported at the element's first instance (index 0, its start offset), before any of
    /// it is read.
    #[error(
        "the header declares {count} elements of at least {min_bytes_each} bytes each, \
         but only {remaining} bytes remain in the file"
    )]
    CountExceedsFile {
        count: u64,
        min_bytes_each: u64,
        remaining: u64,
    },
    /// Windowed reading (`input::stream`) needs a binary body, and a fixed vertex size for
    /// positions; other files are read whole.
    #[error("the body cannot be read window by window: {0}")]
    NotStreamable(&'static str),
    #[error("{vertex_count} vertices cannot be indexed with 32 bits")]
    TooManyVertices { vertex_count: u64 },
    #[error("{face_count} faces cannot be numbered with 32-bit face ids")]
    TooManyFaces { face_count: u64 },
    #[error("file ends in the middle of the element ({needed} more bytes needed)")]
    Truncated { needed: u64 },
    #[error("file ends in the middle of the element")]
    UnexpectedEndOfText,
    #[error("malformed {expected} token '{token}'")]
    MalformedToken {
        token: String,
        expected: &'static str,
    },
    #[error("list length {0} is negative")]
    NegativeListLength(i64),
    #[error("vertex index {index} out of range ({vertex_count} vertices)")]
    IndexOutOfRange { index: i64, vertex_count: u64 },
    #[error("face has {0} vertices; at least 3 are needed")]
    TooFewFaceVertices(u64),
    #[error("coordinate {axis} is {value}, not a finite number")]
    NonFiniteCoordinate { axis: char, value: f64 },
    #[error("coordinate {axis} = {value:e} is outside the supported range ±{max:e}", max = crate::geometry::MAX_COORDINATE)]
    CoordinateOutOfRange { axis: char, value: f64 },
    #[error("normal {axis} is {value}, not a finite number")]
    NonFiniteNormal { axis: char, value: f64 },
    #[error("colour {channel} = {value} is outside 0..1")]
    ColorOutOfRange { channel: &'static str, value: f64 },
    /// The attribute was asked for (`[attributes]`), but the file does not have it. (The
    /// reason is boxed to keep the error as small as before the variant existed.)
    #[error("{attribute} were asked for, but {reason}")]
    MissingAttribute {
        attribute: &'static str,
        reason: Box<str>,
    },
    #[error("OBJ: {0}")]
    Obj(String),
    /// A glTF defect; the location names the accessor, bufferView, node or mesh.
    #[error("glTF: {0}")]
    Gltf(Box<str>),
}

impl InputErrorKind {
    /// What is wrong with `value` as coordinate `axis` (0, 1, 2) of a position: not finite, or
    /// beyond the supported range; `None` when it is fine.
    pub fn of_coordinate(axis: usize, value: f32) -> Option<InputErrorKind> {
        let axis = ['x', 'y', 'z'][axis];
        let value_wide = f64::from(value);
        if !value.is_finite() {
            Some(InputErrorKind::NonFiniteCoordinate {
                axis,
                value: value_wide,
            })
        } else if value.abs() > crate::geometry::MAX_COORDINATE {
            Some(InputErrorKind::CoordinateOutOfRange {
                axis,
                value: value_wide,
            })
        } else {
            None
        }
    }
}

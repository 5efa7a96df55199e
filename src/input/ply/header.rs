//! PLY header: parsed by ply-rs-bw, then reduced to the layout our own body decoders need.
//!
//! ply-rs does the grammar (formats, `comment`/`obj_info` lines, CRLF, type aliases such as
//! `float32`), so we do not maintain a second header parser. We only use its header API,
//! never its body decoding: its per-element property maps cost several times more than
//! decoding the mapped bytes directly. The body start is the position of the `Cursor` after
//! `read_header`, which consumes exactly through the `end_header` line break.
//!
//! The magic is checked before ply-rs sees the bytes: given a large non-PLY file without line
//! breaks, its line reader would otherwise copy the whole file into a `String`.

use std::io::Cursor;
use std::path::Path;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, ElementDef, Encoding, PropertyType, ScalarType};

use crate::input::error::{InputError, InputErrorKind, Location};
use crate::input::AttributeRequest;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Endian {
    Little,
    Big,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BodyEncoding {
    Ascii,
    Binary(Endian),
}

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_ply(scalar: &ScalarType) -> Scalar {
        match scalar {
            ScalarType::Char => Scalar::I8,
            ScalarType::UChar => Scalar::U8,
            ScalarType::Short => Scalar::I16,
            ScalarType::UShort => Scalar::U16,
            ScalarType::Int => Scalar::I32,
            ScalarType::UInt => Scalar::U32,
            ScalarType::Float => Scalar::F32,
            ScalarType::Double => Scalar::F64,
        }
    }

    pub(crate) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    pub(crate) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Property {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

impl Property {
    fn binary_min_size(self) -> u64 {
        match self {
            Property::Scalar(scalar) => scalar.size() as u64,
            Property::List { count, .. } => count.size() as u64,
        }
    }
}

/// One `element` declaration with its properties in file order.
#[derive(Clone, Debug)]
pub(crate) struct Element {
    pub name: String,
    pub count: u64,
    pub properties: Vec<Property>,
}

impl Element {
    /// Size of one binary instance when it has no lists.
    pub(crate) fn fixed_size(&self) -> Option<usize> {
        self.properties
            .iter()
            .map(|property| match property {
                Property::Scalar(scalar) => Some(scalar.size()),
                Property::List { .. } => None,
            })
            .sum()
    }

    /// The fewest bytes one instance can occupy: lists empty in binary, and in ASCII one
    /// character per token (deliberately generous so that no valid file is rejected).
    pub(crate) fn min_size(&self, encoding: BodyEncoding) -> u64 {
        match encoding {
            BodyEncoding::Binary(_) => self.properties.iter().map(|p| p.binary_min_size()).sum(),
            BodyEncoding::Ascii => self.properties.len() as u64,
        }
    }
}

/// What to do with one vertex property. Normals and colours are read only when asked for
/// and skipped otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum VertexRole {
    Coordinate {
        axis: usize,
        scalar: Scalar,
    },
    /// `nx`, `ny`, `nz` as float or double.
    Normal {
        axis: usize,
        scalar: Scalar,
    },
    /// `red`, `green`, `blue`, `alpha` as uchar, float or double (0..1).
    Color {
        channel: usize,
        scalar: Scalar,
    },
    Skip(Property),
}

impl VertexRole {
    /// The property as stored, for skipping it.
    pub(crate) fn property(self) -> Property {
        match self {
            VertexRole::Coordinate { scalar, .. }
            | VertexRole::Normal { scalar, .. }
            | VertexRole::Color { scalar, .. } => Property::Scalar(scalar),
            VertexRole::Skip(property) => property,
        }
    }
}

/// "element 'vertex' has no `types` properties `names`".
fn lacking(types: &str, names: &[&str]) -> Box<str> {
    let plural = if names.len() == 1 {
        "property"
    } else {
        "properties"
    };
    format!(
        "element 'vertex' has no {types} {plural} {}",
        names.join(", ")
    )
    .into()
}

pub(crate) const NORMAL_NAMES: [&str; 3] = ["nx", "ny", "nz"];
pub(crate) const COLOR_NAMES: [&str; 4] = ["red", "green", "blue", "alpha"];

/// The vertex element and the role of each of its properties, in file order.
#[derive(Clone, Debug)]
pub(crate) struct VertexLayout {
    pub element: usize,
    pub roles: Vec<VertexRole>,
}

impl VertexLayout {
    /// Why the vertices cannot give what `request` asks for, if they cannot: the first
    /// attribute asked for and missing, and which properties it lacks.
    pub(crate) fn missing(&self, request: AttributeRequest) -> Option<InputErrorKind> {
        let has_normal = |axis| {
            self.roles
                .iter()
                .any(|role| matches!(role, VertexRole::Normal { axis: a, .. } if *a == axis))
        };
        let has_color = |channel| {
            self.roles
                .iter()
                .any(|role| matches!(role, VertexRole::Color { channel: c, .. } if *c == channel))
        };
        let missing_normals: Vec<&str> = (0..3)
            .filter(|&axis| !has_normal(axis))
            .map(|axis| NORMAL_NAMES[axis])
            .collect();
        let missing_colors: Vec<&str> = (0..3)
            .filter(|&channel| !has_color(channel))
            .map(|channel| COLOR_NAMES[channel])
            .collect();
        if request.normals && !missing_normals.is_empty() {
            return Some(InputErrorKind::MissingAttribute {
                attribute: "normals",
                reason: lacking("float or double", &missing_normals),
            });
        }
        if request.colors && !missing_colors.is_empty() {
            return Some(InputErrorKind::MissingAttribute {
                attribute: "colours",
                reason: lacking("uchar, float or double", &missing_colors),
            });
        }
        None
    }
}

/// The face element split around its index list: properties before it and after it are
/// skipped.
#[derive(Clone, Debug)]
pub(crate) struct FaceLayout {
    pub element: usize,
    pub before: Vec<Property>,
    pub length: Scalar,
    pub index: Scalar,
    pub after: Vec<Property>,
}

#[derive(Clone, Debug)]
pub(crate) struct Header {
    pub encoding: BodyEncoding,
    pub elements: Vec<Element>,
    pub body_start: usize,
    /// 1-based line number of the first body line (meaningful for ASCII).
    pub body_first_line: u64,
    pub vertex: VertexLayout,
    pub face: FaceLayout,
}

impl Header {
    /// The fewest bytes one instance of element `position` can occupy. A face needs at least
    /// three indices to be valid, so counting them keeps a lying face count from reserving
    /// more triangles than the file could describe.
    pub(crate) fn min_instance_size(&self, position: usize) -> u64 {
        let element = &self.elements[position];
        let generic = element.min_size(self.encoding);
        if position != self.face.element {
            return generic;
        }
        let three_indices = match self.encoding {
            BodyEncoding::Binary(_) => 3 * self.face.index.size() as u64,
            BodyEncoding::Ascii => 3,
        };
        generic + three_indices
    }
}

const AXIS_NAMES: [&str; 3] = ["x", "y", "z"];
const FACE_LIST_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];

pub(crate) fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, InputError> {
    if !starts_with_magic(bytes) {
        return Err(InputError::new(
            path,
            Location::File,
            InputErrorKind::NotPly,
        ));
    }
    let mut reader = Reader::new(Cursor::new(bytes));
    let parsed = Parser::<DefaultElement>::new()
        .read_header(&mut reader)
        .map_err(|error| ply_rs_error(path, &error))?;
    let body_start = reader.get_ref().position() as usize;
    let header_text = &bytes[..body_start];
    let definitions: Vec<&ElementDef> = parsed.elements.values().collect();
    let layout_error = |name: &str, kind: InputErrorKind| {
        InputError::new(
            path,
            element_location(header_text, &definitions, name),
            kind,
        )
    };

    let vertex = vertex_layout(&definitions).map_err(|kind| layout_error("vertex", kind))?;
    let face = face_layout(&definitions).map_err(|kind| layout_error("face", kind))?;
    let elements: Vec<Element> = definitions.iter().map(|d| element_from_ply(d)).collect();
    if let Some(element) = elements.iter().find(|e| has_non_integer_list_count(e)) {
        let kind = InputErrorKind::UnsupportedProperty(format!(
            "element '{}' has a list whose length type is not an integer",
            element.name
        ));
        return Err(layout_error(&element.name, kind));
    }
    Ok(Header {
        encoding: body_encoding(parsed.encoding),
        elements,
        body_start,
        body_first_line: line_count(header_text) + 1,
        vertex,
        face,
    })
}

fn starts_with_magic(bytes: &[u8]) -> bool {
    let first_line = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
    first_line.trim_ascii() == b"ply" && first_line.len() < bytes.len()
}

/// ply-rs prefixes its own messages with "Line N: " and spreads details over tab-indented
/// lines; we move the line into our location and keep the message on one line.
fn ply_rs_error(path: &Path, error: &ply_rs_bw::parser::ParseError) -> InputError {
    let text = error.to_string();
    let (location, message) = match error.line() {
        Some(line) => {
            let prefix = format!("Line {line}: ");
            let message = text.strip_prefix(&prefix).unwrap_or(&text).to_string();
            (Location::Header { line: line as u64 }, message)
        }
        None => (Location::File, text),
    };
    let message = message.replace("\n\t", "; ");
    InputError::new(path, location, InputErrorKind::Header(message))
}

fn property_from_ply(data_type: &PropertyType) -> Property {
    match data_type {
        PropertyType::Scalar(scalar) => Property::Scalar(Scalar::from_ply(scalar)),
        PropertyType::List(count, item) => Property::List {
            count: Scalar::from_ply(count),
            item: Scalar::from_ply(item),
        },
    }
}

fn element_from_ply(definition: &ElementDef) -> Element {
    let properties = definition
        .properties
        .values()
        .map(|property| property_from_ply(&property.data_type))
        .collect();
    Element {
        name: definition.name.clone(),
        count: definition.count as u64,
        properties,
    }
}

fn body_encoding(encoding: Encoding) -> BodyEncoding {
    match encoding {
        Encoding::Ascii => BodyEncoding::Ascii,
        Encoding::BinaryLittleEndian => BodyEncoding::Binary(Endian::Little),
        Encoding::BinaryBigEndian => BodyEncoding::Binary(Endian::Big),
    }
}

/// Where the element named `name` is among the ply-rs definitions (kept in declaration order).
fn find_element(definitions: &[&ElementDef], name: &'static str) -> Result<usize, InputErrorKind> {
    definitions
        .iter()
        .position(|definition| definition.name == name)
        .ok_or(InputErrorKind::MissingElement(name))
}

fn vertex_layout(definitions: &[&ElementDef]) -> Result<VertexLayout, InputErrorKind> {
    let element = find_element(definitions, "vertex")?;
    let definition = definitions[element];
    for axis in AXIS_NAMES {
        if !definition.properties.contains_key(axis) {
            return Err(InputErrorKind::UnsupportedProperty(format!(
                "element 'vertex' has no property '{axis}'"
            )));
        }
    }
    let roles = definition
        .properties
        .values()
        .map(|property| {
            let axis = AXIS_NAMES.iter().position(|name| *name == property.name);
            match (axis, &property.data_type) {
                (None, data_type) => Ok(attribute_role(&property.name, data_type)),
                (
                    Some(axis),
                    PropertyType::Scalar(scalar @ (ScalarType::Float | ScalarType::Double)),
                ) => Ok(VertexRole::Coordinate {
                    axis,
                    scalar: Scalar::from_ply(scalar),
                }),
                (Some(_), other) => Err(InputErrorKind::UnsupportedProperty(format!(
                    "vertex coordinate '{}' is {other:?}; only float or double are supported",
                    property.name
                ))),
            }
        })
        .collect::<Result<_, _>>()?;
    Ok(VertexLayout { element, roles })
}

/// The role of a vertex property that is not a coordinate: a normal or colour component
/// when its name and type say so, else skipped (a colour stored as, say, ushort is no colour
/// we read; asking for colours then reports it missing).
fn attribute_role(name: &str, data_type: &PropertyType) -> VertexRole {
    let property = property_from_ply(data_type);
    let Property::Scalar(scalar) = property else {
        return VertexRole::Skip(property);
    };
    let float = matches!(scalar, Scalar::F32 | Scalar::F64);
    if let Some(axis) = NORMAL_NAMES.iter().position(|n| *n == name) {
        if float {
            return VertexRole::Normal { axis, scalar };
        }
    }
    if let Some(channel) = COLOR_NAMES.iter().position(|n| *n == name) {
        if float || scalar == Scalar::U8 {
            return VertexRole::Color { channel, scalar };
        }
    }
    VertexRole::Skip(property)
}

fn face_layout(definitions: &[&ElementDef]) -> Result<FaceLayout, InputErrorKind> {
    let element = find_element(definitions, "face")?;
    let properties = &definitions[element].properties;
    let (list_position, _, list) = FACE_LIST_NAMES
        .iter()
        .find_map(|name| properties.get_full(*name))
        .ok_or_else(|| {
            InputErrorKind::UnsupportedProperty(
                "element 'face' has no list property 'vertex_indices' or 'vertex_index'".into(),
            )
        })?;
    let (length, index) = match &list.data_type {
        PropertyType::List(length, index)
            if Scalar::from_ply(length).is_integer() && Scalar::from_ply(index).is_integer() =>
        {
            (Scalar::from_ply(length), Scalar::from_ply(index))
        }
        other => {
            return Err(InputErrorKind::UnsupportedProperty(format!(
                "face property '{}' is {other:?}; a list of integers is required",
                list.name
            )))
        }
    };
    let others: Vec<Property> = properties
        .values()
        .map(|property| property_from_ply(&property.data_type))
        .collect();
    Ok(FaceLayout {
        element,
        before: others[..list_position].to_vec(),
        length,
        index,
        after: others[list_position + 1..].to_vec(),
    })
}

fn has_non_integer_list_count(element: &Element) -> bool {
    element
        .properties
        .iter()
        .any(|property| matches!(property, Property::List { count, .. } if !count.is_integer()))
}

/// Header defects about a declared element point at its `element` line; a missing element
/// has no line to point at.
fn element_location(header_text: &[u8], definitions: &[&ElementDef], name: &str) -> Location {
    if definitions.iter().all(|definition| definition.name != name) {
        return Location::File;
    }
    let declaration = header_text.split(|&b| b == b'\n').position(|line| {
        let mut words = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|w| !w.is_empty());
        words.next() == Some(b"element") && words.next() == Some(name.as_bytes())
    });
    match declaration {
        Some(index) => Location::Header {
            line: index as u64 + 1,
        },
        None => Location::File,
    }
}

fn line_count(text: &[u8]) -> u64 {
    text.iter().filter(|&&b| b == b'\n').count() as u64
}

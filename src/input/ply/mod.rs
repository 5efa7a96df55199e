//! PLY input: a mapped file plus its parsed layout, from which positions and triangles are
//! decoded on demand.
//!
//! [`PlyFile`] deliberately does not build a [`Mesh`] by itself being opened: the out-of-core
//! chunker reads positions and streams triangles through [`PlyFile::for_each_triangle`]
//! without ever holding every triangle. Opening only parses the header and finds where the
//! `vertex` and `face` elements start, skipping any elements declared before them; elements
//! declared after both are never touched, since nothing in them matters to us.
//!
//! Before any element is read or skipped, its declared count is checked against the bytes
//! left in the file (`count × smallest possible instance ≤ remaining`), so a corrupt header
//! claiming 2^40 faces fails at once instead of looping or allocating. That check also bounds
//! every allocation made later by the file size.
//!
//! The decoders (`binary`, `elements`, `parallel`, `header`, `values`) are crate-visible so
//! that `input::stream` can run them over bounded windows of the file instead of one
//! whole-file mapping; [`PlyFile::into_layout`] hands it the parsed layout without the mapping.

mod ascii;
pub(crate) mod binary;
pub(crate) mod elements;
pub(crate) mod header;
pub(crate) mod parallel;
pub(crate) mod values;

use std::fs::File;
use std::path::{Path, PathBuf};

use memmap2::Mmap;

use crate::geometry::Point;
use crate::input::error::{InputError, InputErrorKind, Location};
use crate::input::{AttributeRequest, Vertices};
use crate::mapping::map_file;
use crate::mesh::Mesh;

use ascii::AsciiReader;
use binary::BinaryReader;
use header::{BodyEncoding, Element, Endian, Header};
use parallel::{FixedStrideElement, FixedVertex, TriangleFaces};
use values::ValueReader;

/// Where an element's first instance starts.
#[derive(Clone, Copy, Debug)]
struct ElementStart {
    offset: usize,
    line: u64,
}

/// A PLY file's parsed header and where its mesh elements start, without the mapping.
pub(crate) struct PlyLayout {
    pub header: Header,
    pub file_length: u64,
    pub vertex_start: u64,
    pub face_start: u64,
}

/// An opened PLY file, ready to decode.
pub struct PlyFile {
    path: PathBuf,
    bytes: Mmap,
    header: Header,
    vertex_start: ElementStart,
    face_start: ElementStart,
}

impl PlyFile {
    pub fn open(path: &Path) -> Result<PlyFile, InputError> {
        let file = File::open(path).map_err(|error| io_error(path, &error))?;
        PlyFile::open_file(path, &file)
    }

    /// Opens an already open `file`, naming it `path` in errors.
    pub(crate) fn open_file(path: &Path, file: &File) -> Result<PlyFile, InputError> {
        let bytes = map_file(file).map_err(|error| io_error(path, &error))?;
        let header = header::parse_header(path, &bytes)?;
        let vertex_count = header.elements[header.vertex.element].count;
        if vertex_count > 1 << 32 {
            let kind = InputErrorKind::TooManyVertices { vertex_count };
            return Err(InputError::new(path, Location::File, kind));
        }
        let starts = locate_elements(path, &bytes, &header)?;
        Ok(PlyFile {
            path: path.to_path_buf(),
            vertex_start: starts[header.vertex.element],
            face_start: starts[header.face.element],
            bytes,
            header,
        })
    }

    /// Drops the mapping, keeping what is needed to map the elements again window by window.
    pub(crate) fn into_layout(self) -> PlyLayout {
        PlyLayout {
            file_length: self.bytes.len() as u64,
            vertex_start: self.vertex_start.offset as u64,
            face_start: self.face_start.offset as u64,
            header: self.header,
        }
    }

    pub fn vertex_count(&self) -> u64 {
        self.vertex_element().count
    }

    pub fn face_count(&self) -> u64 {
        self.face_element().count
    }

    /// All vertex positions, in file order.
    pub fn read_positions(&self) -> Result<Vec<Point>, InputError> {
        Ok(self.read_vertices(AttributeRequest::default())?.positions)
    }

    /// Fails naming the properties the vertices lack, if they cannot give what `request` asks.
    pub fn check_attributes(&self, request: AttributeRequest) -> Result<(), InputError> {
        match self.header.vertex.missing(request) {
            None => Ok(()),
            Some(kind) => Err(InputError::new(&self.path, Location::File, kind)),
        }
    }

    /// All vertices in file order: positions, and the attributes `request` asks for (which
    /// must have passed [`PlyFile::check_attributes`]).
    pub fn read_vertices(&self, request: AttributeRequest) -> Result<Vertices, InputError> {
        let element = self.vertex_element();
        let start = self.vertex_start;
        match self.header.encoding {
            BodyEncoding::Binary(endian) => match FixedVertex::from_layout(&self.header.vertex) {
                Some(vertex) if self.fits(start, element.count, vertex.stride()) => {
                    let fixed = self.fixed_stride(element, start, endian);
                    parallel_vertices(&fixed, &vertex, request)
                }
                _ => self.read_vertices_with(
                    &mut BinaryReader::new(&self.bytes, start.offset, endian),
                    request,
                ),
            },
            BodyEncoding::Ascii => self.read_vertices_with(
                &mut AsciiReader::new(&self.bytes, start.offset, start.line),
                request,
            ),
        }
    }

    /// Calls `visit(face_index, triangle)` for every fan triangle of every face, in file order.
    /// On a defect, triangles of faces before it (and of the defective face up to the defect)
    /// have already been visited.
    pub fn for_each_triangle(&self, visit: impl FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        let start = self.face_start;
        match self.header.encoding {
            BodyEncoding::Binary(endian) => self.visit_triangles_with(
                &mut BinaryReader::new(&self.bytes, start.offset, endian),
                visit,
            ),
            BodyEncoding::Ascii => self.visit_triangles_with(
                &mut AsciiReader::new(&self.bytes, start.offset, start.line),
                visit,
            ),
        }
    }

    /// All fan triangles, in file order. Binary all-triangle meshes are decoded in parallel.
    pub fn read_triangles(&self) -> Result<Vec<[u32; 3]>, InputError> {
        if let Some(triangles) = self.read_uniform_triangles() {
            return triangles;
        }
        // Triangles are at least as many as faces; the count was checked against the file size.
        let mut triangles = Vec::with_capacity(self.face_count() as usize);
        self.for_each_triangle(|_, triangle| triangles.push(triangle))?;
        Ok(triangles)
    }

    /// Positions and triangles as stored, without welding, with each triangle's face.
    pub fn read_mesh(&self) -> Result<Mesh, InputError> {
        self.read_mesh_with(AttributeRequest::default())
    }

    /// [`PlyFile::read_mesh`] with the vertex attributes `request` asks for; fails before
    /// reading anything when the file lacks them.
    pub fn read_mesh_with(&self, request: AttributeRequest) -> Result<Mesh, InputError> {
        self.check_attributes(request)?;
        let Vertices {
            positions,
            normals,
            colors,
        } = self.read_vertices(request)?;
        if let Some(triangles) = self.read_uniform_triangles() {
            // Every face is one triangle: triangle `i` is face `i`.
            let triangles = triangles?;
            return Ok(Mesh {
                positions,
                triangles,
                face_ids: None,
                normals,
                colors,
            });
        }
        let face_count = self.face_count();
        if face_count > 1 << 32 {
            let kind = InputErrorKind::TooManyFaces { face_count };
            return Err(InputError::new(&self.path, Location::File, kind));
        }
        let mut triangles = Vec::with_capacity(face_count as usize);
        let mut face_ids = Vec::with_capacity(face_count as usize);
        self.for_each_triangle(|face, triangle| {
            triangles.push(triangle);
            face_ids.push(face as u32);
        })?;
        Ok(Mesh {
            positions,
            triangles,
            face_ids: Some(face_ids),
            normals,
            colors,
        })
    }

    fn vertex_element(&self) -> &Element {
        &self.header.elements[self.header.vertex.element]
    }

    fn face_element(&self) -> &Element {
        &self.header.elements[self.header.face.element]
    }

    fn fits(&self, start: ElementStart, count: u64, stride: usize) -> bool {
        let remaining = self.bytes.len().saturating_sub(start.offset) as u64;
        count
            .checked_mul(stride as u64)
            .is_some_and(|needed| needed <= remaining)
    }

    fn fixed_stride<'a>(
        &'a self,
        element: &'a Element,
        start: ElementStart,
        endian: Endian,
    ) -> FixedStrideElement<'a> {
        FixedStrideElement {
            path: &self.path,
            name: &element.name,
            bytes: &self.bytes,
            origin: 0,
            start: start.offset,
            first_index: 0,
            // Fits in memory: `fits` bounded count × stride by the mapped length.
            count: element.count as usize,
            endian,
        }
    }

    fn read_uniform_triangles(&self) -> Option<Result<Vec<[u32; 3]>, InputError>> {
        let BodyEncoding::Binary(endian) = self.header.encoding else {
            return None;
        };
        let faces = TriangleFaces::from_layout(&self.header.face)?;
        let element = self.face_element();
        if !self.fits(self.face_start, element.count, faces.stride()) {
            return None;
        }
        let fixed = self.fixed_stride(element, self.face_start, endian);
        parallel::read_triangles(&fixed, &faces, self.vertex_count())
    }

    fn read_vertices_with<R: ValueReader>(
        &self,
        reader: &mut R,
        request: AttributeRequest,
    ) -> Result<Vertices, InputError> {
        let element = self.vertex_element();
        let count = element.count as usize;
        let mut vertices = Vertices {
            positions: Vec::with_capacity(count),
            normals: request.normals.then(|| Vec::with_capacity(count)),
            colors: request.colors.then(|| Vec::with_capacity(count)),
        };
        for index in 0..element.count {
            let values = elements::read_vertex(reader, &self.header.vertex, request)
                .map_err(|defect| defect.at_element(&self.path, &element.name, index))?;
            vertices.positions.push(values.position);
            if let Some(normals) = &mut vertices.normals {
                normals.push(values.normal);
            }
            if let Some(colors) = &mut vertices.colors {
                colors.push(values.color);
            }
        }
        Ok(vertices)
    }

    fn visit_triangles_with<R: ValueReader>(
        &self,
        reader: &mut R,
        mut visit: impl FnMut(u64, [u32; 3]),
    ) -> Result<(), InputError> {
        let element = self.face_element();
        let vertex_count = self.vertex_count();
        for index in 0..element.count {
            elements::read_face(reader, &self.header.face, vertex_count, |triangle| {
                visit(index, triangle)
            })
            .map_err(|defect| defect.at_element(&self.path, &element.name, index))?;
        }
        Ok(())
    }
}

/// Vertices of a fixed size, decoded in parallel: positions, then each attribute asked for.
fn parallel_vertices(
    element: &FixedStrideElement,
    vertex: &FixedVertex,
    request: AttributeRequest,
) -> Result<Vertices, InputError> {
    let positions = parallel::read_positions(element, vertex)?;
    let normals = request
        .normals
        .then(|| parallel::decode_all(element, |e, i| parallel::decode_normal(e, vertex, i)))
        .transpose()?;
    let colors = request
        .colors
        .then(|| parallel::decode_all(element, |e, i| parallel::decode_color(e, vertex, i)))
        .transpose()?;
    Ok(Vertices {
        positions,
        normals,
        colors,
    })
}

pub(crate) fn io_error(path: &Path, error: &std::io::Error) -> InputError {
    InputError::new(path, Location::File, InputErrorKind::Io(error.to_string()))
}

/// Finds the start of every element up to the later of `vertex` and `face`, checking each
/// declared count against the remaining bytes before skipping its instances.
fn locate_elements(
    path: &Path,
    bytes: &[u8],
    header: &Header,
) -> Result<Vec<ElementStart>, InputError> {
    let last_needed = header.vertex.element.max(header.face.element);
    let mut starts = Vec::with_capacity(last_needed + 1);
    let mut start = ElementStart {
        offset: header.body_start,
        line: header.body_first_line,
    };
    for (position, element) in header.elements[..=last_needed].iter().enumerate() {
        let min_bytes_each = header.min_instance_size(position);
        check_count_fits(
            path,
            bytes.len(),
            element,
            min_bytes_each,
            start,
            header.encoding,
        )?;
        starts.push(start);
        if position < last_needed {
            start = skip_element(path, bytes, element, start, header.encoding)?;
        }
    }
    Ok(starts)
}

fn check_count_fits(
    path: &Path,
    file_length: usize,
    element: &Element,
    min_bytes_each: u64,
    start: ElementStart,
    encoding: BodyEncoding,
) -> Result<(), InputError> {
    let remaining = file_length.saturating_sub(start.offset) as u64;
    let fits = element
        .count
        .checked_mul(min_bytes_each)
        .is_some_and(|needed| needed <= remaining);
    if fits {
        return Ok(());
    }
    let location = Location::Element {
        element: element.name.clone(),
        index: 0,
        byte_offset: start.offset as u64,
        line: (encoding == BodyEncoding::Ascii).then_some(start.line),
    };
    let kind = InputErrorKind::CountExceedsFile {
        count: element.count,
        min_bytes_each,
        remaining,
    };
    Err(InputError::new(path, location, kind))
}

/// Returns where the element after `element` starts.
fn skip_element(
    path: &Path,
    bytes: &[u8],
    element: &Element,
    start: ElementStart,
    encoding: BodyEncoding,
) -> Result<ElementStart, InputError> {
    match encoding {
        BodyEncoding::Binary(endian) => {
            if let Some(size) = element.fixed_size() {
                // The count check guaranteed count × size ≤ remaining bytes.
                let offset = start.offset + element.count as usize * size;
                return Ok(ElementStart { offset, ..start });
            }
            let mut reader = BinaryReader::new(bytes, start.offset, endian);
            skip_instances(path, &mut reader, element)?;
            Ok(ElementStart {
                offset: reader.position(),
                ..start
            })
        }
        BodyEncoding::Ascii => {
            let mut reader = AsciiReader::new(bytes, start.offset, start.line);
            skip_instances(path, &mut reader, element)?;
            Ok(ElementStart {
                offset: reader.position(),
                line: reader.line(),
            })
        }
    }
}

fn skip_instances<R: ValueReader>(
    path: &Path,
    reader: &mut R,
    element: &Element,
) -> Result<(), InputError> {
    for index in 0..element.count {
        elements::skip_properties(reader, &element.properties)
            .map_err(|defect| defect.at_element(path, &element.name, index))?;
    }
    Ok(())
}

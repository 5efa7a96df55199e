//! Windowed, bounded-memory reading of binary PLY files for the out-of-core chunker.
//!
//! [`PlyFile`] decodes from one whole-file mapping; touching all of it makes the resident set
//! grow to the file size (5.7 GB for a 300M-triangle model), which breaks the 4 GiB budget.
//! [`PlyStream`] keeps only the parsed layout and maps one bounded window at a time, decodes
//! it with the same decoders as [`PlyFile`] (`ply::parallel` for fixed-size instances,
//! `ply::elements` for everything else) and drops it before mapping the next, so resident
//! memory follows the window size. The price is one `mmap`/`munmap` per window and, for
//! faces, decoding again any face that straddles a window end.
//!
//! Windows start at arbitrary (not page-aligned) offsets; memmap2 maps from the enclosing page
//! and hides the difference. Readers over a window know the window's file offset, so every
//! error names the same element index and absolute byte offset as [`PlyFile`] would.
//!
//! Vertices with a fixed size are windowed by whole vertices. Faces are variable-length: a
//! face that runs past the end of a window is decoded again from its own start in a fresh
//! window, and if it does not fit a fresh window either (a tiny window or a huge polygon),
//! the window doubles until it does or reaches the end of the file, where a shortfall is a
//! real truncation. Because a face may be decoded twice, its triangles are buffered and only
//! handed to the caller once the face is known not to be cut by the window. Windows of
//! all-triangle faces are first tried in parallel under `ply::parallel`'s stride guess.
//!
//! Opening goes through [`PlyFile::open_file`] and drops its mapping: that touches the header
//! and, only when a variable-size element is declared before the later of `vertex` and
//! `face`, the pages of that element (which must be read through to find where the next one
//! starts). Ordinary files declare `vertex` then `face` and touch nothing else.

use std::fs::File;
use std::path::{Path, PathBuf};

use memmap2::Mmap;

use super::error::{InputError, InputErrorKind, Location};
use super::ply::binary::BinaryReader;
use super::ply::header::{BodyEncoding, Element, Endian};
use super::ply::parallel::{self, FixedStrideElement, FixedVertex, TriangleFaces};
use super::ply::{elements, io_error, PlyFile, PlyLayout};
use super::{AttributeRequest, VertexAttributes};
use crate::geometry::Point;
use crate::mapping::map_range;

/// A PLY file's parsed layout without a live whole-file mapping.
pub struct PlyStream {
    path: PathBuf,
    file: File,
    layout: PlyLayout,
    /// Present for binary files whose vertices have no list property.
    fixed_vertex: Option<FixedVertex>,
    /// Present for binary files whose faces have no list besides the indices.
    triangle_faces: Option<TriangleFaces>,
}

/// A mapped range of the file.
struct Window {
    bytes: Mmap,
    /// File offset of `bytes[0]`.
    origin: u64,
    reaches_end_of_file: bool,
}

/// How far decoding one window of faces got: whole faces and the bytes they occupy.
#[derive(Clone, Copy, Default)]
struct FaceProgress {
    faces: u64,
    bytes: usize,
}

impl PlyStream {
    /// Parses the header and locates the vertex and face elements.
    pub fn open(path: &Path) -> Result<PlyStream, InputError> {
        let file = File::open(path).map_err(|error| io_error(path, &error))?;
        let layout = PlyFile::open_file(path, &file)?.into_layout();
        let (fixed_vertex, triangle_faces) = match layout.header.encoding {
            BodyEncoding::Binary(_) => (
                FixedVertex::from_layout(&layout.header.vertex),
                TriangleFaces::from_layout(&layout.header.face),
            ),
            BodyEncoding::Ascii => (None, None),
        };
        Ok(PlyStream {
            path: path.to_path_buf(),
            file,
            layout,
            fixed_vertex,
            triangle_faces,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn vertex_count(&self) -> u64 {
        self.vertex_element().count
    }

    pub fn face_count(&self) -> u64 {
        self.face_element().count
    }

    /// True for binary files whose vertex element has a fixed stride (the out-of-core case);
    /// ASCII inputs are not streamable (callers read them whole with `read_mesh`).
    /// Triangles of binary files can be streamed either way.
    pub fn is_streamable(&self) -> bool {
        self.fixed_vertex.is_some()
    }

    /// Visits all positions in file order, one window of at most `window_bytes` (but at least
    /// one vertex) at a time: `visit(first_vertex_index, positions_of_this_window)`.
    pub fn for_each_position_window(
        &self,
        window_bytes: usize,
        mut visit: impl FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        let (endian, vertex) = self.streamable_vertices()?;
        let per_window = vertices_per_window(window_bytes, vertex);
        let mut first = 0;
        while first < self.vertex_count() {
            let count = per_window.min(self.vertex_count() - first);
            let window = self.map_vertices(vertex, first, count)?;
            let element = self.vertex_window(&window, first, count, endian);
            visit(first, &parallel::read_positions(&element, vertex)?);
            first += count;
        }
        Ok(())
    }

    /// Positions of `sorted_ids` in the same order, mapping only windows of the vertex element
    /// that contain some of them, one at a time. Ids should be strictly ascending; others are
    /// still answered correctly, just with more windows. An id beyond the vertex count is an
    /// `IndexOutOfRange` error located at the file.
    pub fn positions_of(
        &self,
        sorted_ids: &[u32],
        window_bytes: usize,
    ) -> Result<Vec<Point>, InputError> {
        self.gather(sorted_ids, window_bytes, parallel::decode_vertex)
    }

    /// Fails naming the properties the vertices lack, if they cannot give what `request` asks.
    pub fn check_attributes(&self, request: AttributeRequest) -> Result<(), InputError> {
        match self.layout.header.vertex.missing(request) {
            None => Ok(()),
            Some(kind) => Err(InputError::new(&self.path, Location::File, kind)),
        }
    }

    /// The attributes `request` asks for (which must have passed
    /// [`PlyStream::check_attributes`]) of `sorted_ids`, windowed as [`PlyStream::positions_of`].
    pub fn attributes_of(
        &self,
        sorted_ids: &[u32],
        window_bytes: usize,
        request: AttributeRequest,
    ) -> Result<VertexAttributes, InputError> {
        let normals = request
            .normals
            .then(|| self.gather(sorted_ids, window_bytes, parallel::decode_normal))
            .transpose()?;
        let colors = request
            .colors
            .then(|| self.gather(sorted_ids, window_bytes, parallel::decode_color))
            .transpose()?;
        Ok(VertexAttributes { normals, colors })
    }

    /// `decode` of each of `sorted_ids`, in that order, one window of vertices at a time.
    fn gather<T>(
        &self,
        sorted_ids: &[u32],
        window_bytes: usize,
        decode: impl Fn(&FixedStrideElement, &FixedVertex, usize) -> Result<T, InputError>,
    ) -> Result<Vec<T>, InputError> {
        let (endian, vertex) = self.streamable_vertices()?;
        let per_window = vertices_per_window(window_bytes, vertex);
        let mut values = Vec::with_capacity(sorted_ids.len());
        let mut pending = sorted_ids;
        while let Some(&first) = pending.first() {
            let first = u64::from(first);
            self.check_vertex_id(first)?;
            let count = per_window.min(self.vertex_count() - first);
            let in_window = pending
                .iter()
                .take_while(|&&id| (first..first + count).contains(&u64::from(id)))
                .count();
            let window = self.map_vertices(vertex, first, count)?;
            let element = self.vertex_window(&window, first, count, endian);
            for &id in &pending[..in_window] {
                let index_in_window = (u64::from(id) - first) as usize;
                values.push(decode(&element, vertex, index_in_window)?);
            }
            pending = &pending[in_window..];
        }
        Ok(values)
    }

    /// Visits every fan triangle `(v0, vi, vi+1)` of every face in file order as
    /// `visit(face_index, triangle)`, reading the face element window by window, with the same
    /// checks and error locations as [`PlyFile::for_each_triangle`]. On a defect, triangles of
    /// faces before it (and of the defective face up to the defect) have already been visited.
    pub fn for_each_triangle(
        &self,
        window_bytes: usize,
        mut visit: impl FnMut(u64, [u32; 3]),
    ) -> Result<(), InputError> {
        let endian = self.binary_endian()?;
        let mut window_length = window_bytes.max(1);
        let mut next_face = 0;
        let mut offset = self.layout.face_start;
        let mut face_triangles = Vec::new();
        while next_face < self.face_count() {
            let window = self.map_window(offset, window_length)?;
            let progress = match self.uniform_triangles(&window, next_face, endian, &mut visit) {
                Some(progress) => progress,
                None => {
                    let buffer = &mut face_triangles;
                    self.faces_in_order(&window, next_face, endian, buffer, &mut visit)?
                }
            };
            if progress.faces == 0 {
                // The face does not fit a window starting at it; the window cannot end at the
                // end of the file, or the shortfall would have been reported as truncation.
                window_length = window_length.saturating_mul(2);
            }
            next_face += progress.faces;
            offset += progress.bytes as u64;
        }
        Ok(())
    }

    /// Decodes the whole faces of `window` in parallel if they are all triangles and free of
    /// defects; `None` otherwise, leaving the window (and any error) to `faces_in_order`.
    fn uniform_triangles(
        &self,
        window: &Window,
        first_face: u64,
        endian: Endian,
        visit: &mut impl FnMut(u64, [u32; 3]),
    ) -> Option<FaceProgress> {
        let faces = self.triangle_faces.as_ref()?;
        let remaining_faces = self.face_count() - first_face;
        let count = remaining_faces.min((window.bytes.len() / faces.stride()) as u64);
        if count == 0 {
            return None;
        }
        let element = FixedStrideElement {
            path: &self.path,
            name: &self.face_element().name,
            bytes: &window.bytes,
            origin: window.origin,
            start: 0,
            first_index: first_face,
            count: count as usize,
            endian,
        };
        let triangles = parallel::read_triangles(&element, faces, self.vertex_count())?.ok()?;
        for (face, &triangle) in (first_face..).zip(&triangles) {
            visit(face, triangle);
        }
        Some(FaceProgress {
            faces: count,
            bytes: count as usize * faces.stride(),
        })
    }

    /// Decodes faces one by one until the face element or the window ends, stopping before a
    /// face that the window cuts off. `face_triangles` is a reusable per-face buffer.
    fn faces_in_order(
        &self,
        window: &Window,
        first_face: u64,
        endian: Endian,
        face_triangles: &mut Vec<[u32; 3]>,
        visit: &mut impl FnMut(u64, [u32; 3]),
    ) -> Result<FaceProgress, InputError> {
        let mut reader = BinaryReader::new(&window.bytes, 0, endian).with_origin(window.origin);
        let mut progress = FaceProgress::default();
        for face in first_face..self.face_count() {
            face_triangles.clear();
            let decoded = elements::read_face(
                &mut reader,
                &self.layout.header.face,
                self.vertex_count(),
                |triangle| face_triangles.push(triangle),
            );
            let cut_by_window = decoded.as_ref().is_err_and(|defect| {
                matches!(defect.kind, InputErrorKind::Truncated { .. })
                    && !window.reaches_end_of_file
            });
            if cut_by_window {
                return Ok(progress);
            }
            for &triangle in face_triangles.iter() {
                visit(face, triangle);
            }
            decoded
                .map_err(|defect| defect.at_element(&self.path, &self.face_element().name, face))?;
            progress = FaceProgress {
                faces: progress.faces + 1,
                bytes: reader.position(),
            };
        }
        Ok(progress)
    }

    fn vertex_element(&self) -> &Element {
        &self.layout.header.elements[self.layout.header.vertex.element]
    }

    fn face_element(&self) -> &Element {
        &self.layout.header.elements[self.layout.header.face.element]
    }

    fn binary_endian(&self) -> Result<Endian, InputError> {
        match self.layout.header.encoding {
            BodyEncoding::Binary(endian) => Ok(endian),
            BodyEncoding::Ascii => Err(self.not_streamable("the body is ASCII")),
        }
    }

    fn streamable_vertices(&self) -> Result<(Endian, &FixedVertex), InputError> {
        let endian = self.binary_endian()?;
        let vertex = self
            .fixed_vertex
            .as_ref()
            .ok_or_else(|| self.not_streamable("vertices have a list property"))?;
        Ok((endian, vertex))
    }

    fn not_streamable(&self, reason: &'static str) -> InputError {
        let kind = InputErrorKind::NotStreamable(reason);
        InputError::new(&self.path, Location::File, kind)
    }

    fn check_vertex_id(&self, id: u64) -> Result<(), InputError> {
        if id < self.vertex_count() {
            return Ok(());
        }
        let kind = InputErrorKind::IndexOutOfRange {
            index: id as i64,
            vertex_count: self.vertex_count(),
        };
        Err(InputError::new(&self.path, Location::File, kind))
    }

    /// Maps vertices `first..first + count`, which the count check at opening guaranteed to
    /// lie inside the file.
    fn map_vertices(
        &self,
        vertex: &FixedVertex,
        first: u64,
        count: u64,
    ) -> Result<Window, InputError> {
        let stride = vertex.stride() as u64;
        let offset = self.layout.vertex_start + first * stride;
        self.map_window(offset, (count * stride) as usize)
    }

    fn vertex_window<'a>(
        &'a self,
        window: &'a Window,
        first: u64,
        count: u64,
        endian: Endian,
    ) -> FixedStrideElement<'a> {
        FixedStrideElement {
            path: &self.path,
            name: &self.vertex_element().name,
            bytes: &window.bytes,
            origin: window.origin,
            start: 0,
            first_index: first,
            count: count as usize,
            endian,
        }
    }

    /// Maps `length` bytes from `offset`, or fewer where the file ends first.
    fn map_window(&self, offset: u64, length: usize) -> Result<Window, InputError> {
        let remaining = self.layout.file_length.saturating_sub(offset);
        let length = length.min(usize::try_from(remaining).unwrap_or(usize::MAX));
        let bytes =
            map_range(&self.file, offset, length).map_err(|error| io_error(&self.path, &error))?;
        Ok(Window {
            bytes,
            origin: offset,
            reaches_end_of_file: length as u64 == remaining,
        })
    }
}

/// Whole vertices per window: as many as fit in `window_bytes`, but at least one.
fn vertices_per_window(window_bytes: usize, vertex: &FixedVertex) -> u64 {
    (window_bytes / vertex.stride()).max(1) as u64
}

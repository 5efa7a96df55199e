//! The table of mesh formats: how each is recognised, read and opened for the chunker.
//!
//! A file is recognised by its content first (PLY's `ply` line, GLB's `glTF` magic, an STL
//! whose facet count matches its size or whose text starts with `solid`), then by its extension, so a misnamed
//! file still reads and an extension never overrides what the bytes say. gzip and zstd
//! compression is recognised by magic bytes, below the format, whatever the name says.
//! `pipeline`, the Python `convert` (through `pipeline`) and `reducem` all come through here.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use super::compressed::{self, Compression};
use super::error::{InputError, InputErrorKind, Location};
use super::ply::io_error;
use super::source::WindowedPly;
use super::temporary::TemporarySource;
use super::{
    gltf, obj, stl, stl_stream, weld_identical_positions, AttributeRequest, MeshSource, PlyFile,
    PlyStream,
};
use crate::mesh::Mesh;
pub use reducem_core::format::model::UpAxis;

/// One mesh format of the table.
pub trait MeshFormat: Sync {
    /// The name used in messages, e.g. "binary or ASCII STL".
    fn name(&self) -> &'static str;
    /// Lower-case extensions without the dot.
    fn extensions(&self) -> &'static [&'static str];
    /// True when `head` (the first bytes of the content) and `length` (the content's size,
    /// when known without decompressing) are this format's.
    fn detect(&self, head: &[u8], length: Option<u64>) -> bool;
    /// STL comes from CAD and printing, which put z up; the other formats put y up.
    fn default_up(&self) -> UpAxis;
    /// Fails, naming what the file lacks, when it cannot give what `request` asks for.
    fn check_attributes(&self, path: &Path, request: AttributeRequest) -> Result<(), InputError>;
    /// The whole mesh, triangulated, with bit-identical positions welded.
    fn read_mesh(&self, path: &Path, request: AttributeRequest) -> Result<Mesh, InputError>;
    /// The mesh as the chunker reads it; in memory unless the format can do better.
    fn open(
        &self,
        path: &Path,
        request: AttributeRequest,
        _window_bytes: usize,
    ) -> Result<Box<dyn MeshSource>, InputError> {
        self.check_attributes(path, request)?;
        Ok(Box::new(self.read_mesh(path, request)?))
    }
}

/// Every format reducem reads, in detection order.
pub static FORMATS: [&dyn MeshFormat; 4] = [&Ply, &Gltf, &Stl, &Obj];

/// A recognised input: its format and the compression around it.
#[derive(Clone, Copy)]
pub struct Detected {
    pub format: &'static dyn MeshFormat,
    pub compression: Option<Compression>,
}

/// Bytes of content looked at to recognise a format.
const HEAD_BYTES: usize = 1024;

/// Recognises `path`'s compression by magic bytes, then its format by content, then by the
/// extension (after `.gz` or `.zst`).
pub fn detect(path: &Path) -> Result<Detected, InputError> {
    let file = File::open(path).map_err(|error| io_error(path, &error))?;
    let length = file
        .metadata()
        .map_err(|error| io_error(path, &error))?
        .len();
    let mut head = Vec::with_capacity(HEAD_BYTES);
    let read = |reader: &mut dyn Read, head: &mut Vec<u8>| {
        reader
            .take(HEAD_BYTES as u64)
            .read_to_end(head)
            .map_err(|error| io_error(path, &error))
    };
    read(&mut &file, &mut head)?;
    let compression = Compression::of(&head);
    if let Some(compression) = compression {
        head = compressed::head(path, compression, HEAD_BYTES)?;
    }
    let content_length = compression.is_none().then_some(length);
    let by_content = FORMATS
        .iter()
        .find(|format| format.detect(&head, content_length));
    let by_extension = || {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        let name = compression.map_or(name.as_str(), |c| {
            name.strip_suffix(c.extension()).unwrap_or(&name)
        });
        let extension = Path::new(name).extension()?.to_str()?;
        FORMATS
            .iter()
            .find(|format| format.extensions().contains(&extension))
    };
    match by_content.or_else(by_extension) {
        Some(&format) => Ok(Detected {
            format,
            compression,
        }),
        None => Err(InputError::new(
            path,
            Location::File,
            InputErrorKind::UnsupportedFormat(supported_formats()),
        )),
    }
}

/// The formats and compressions read, for messages.
pub fn supported_formats() -> String {
    let extensions: Vec<String> = FORMATS
        .iter()
        .flat_map(|format| format.extensions())
        .map(|extension| format!(".{extension}"))
        .collect();
    format!(
        "{}, optionally compressed with gzip (.gz) or zstd (.zst)",
        extensions.join(", ")
    )
}

/// The formats' names as a list for help texts: "PLY, glTF 2.0 / GLB, STL or OBJ".
pub fn format_names() -> String {
    let names: Vec<&str> = FORMATS.iter().map(|format| format.name()).collect();
    match names.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, others)) => format!("{} or {last}", others.join(", ")),
        None => String::new(),
    }
}

/// Reads the mesh at `path`, whatever its format and compression.
pub fn read_mesh_with(path: &Path, request: AttributeRequest) -> Result<Mesh, InputError> {
    let detected = detect(path)?;
    with_content(path, detected, |content| {
        detected.format.read_mesh(content, request)
    })
}

/// Fails, naming the file and what it lacks, when it cannot give what `request` asks for.
pub fn check_attributes(path: &Path, request: AttributeRequest) -> Result<(), InputError> {
    if !request.any() {
        return Ok(());
    }
    let detected = detect(path)?;
    with_content(path, detected, |content| {
        detected.format.check_attributes(content, request)
    })
}

/// Opens `path` as a [`MeshSource`] with the vertex attributes `request` asks for, failing
/// before any body is read when the file lacks them. Binary PLY with fixed-size vertices
/// streams through windows of `window_bytes`; a compressed input is decompressed to a
/// temporary file first, which the source deletes when dropped.
pub fn open_source(
    path: &Path,
    request: AttributeRequest,
    window_bytes: usize,
) -> Result<Box<dyn MeshSource>, InputError> {
    let detected = detect(path)?;
    let Some(compression) = detected.compression else {
        return detected.format.open(path, request, window_bytes);
    };
    let decompressed = compressed::decompress(path, compression)?;
    let source = detected
        .format
        .open(decompressed.path(), request, window_bytes)
        .map_err(|error| decompressed.rename(error))?;
    Ok(Box::new(TemporarySource::new(source, decompressed)))
}

/// Runs `read` on the plain content of `path`: the file itself, or its decompressed copy
/// (errors then still name `path`).
fn with_content<T>(
    path: &Path,
    detected: Detected,
    read: impl FnOnce(&Path) -> Result<T, InputError>,
) -> Result<T, InputError> {
    match detected.compression {
        None => read(path),
        Some(compression) => {
            let decompressed = compressed::decompress(path, compression)?;
            read(decompressed.path()).map_err(|error| decompressed.rename(error))
        }
    }
}

struct Ply;

impl MeshFormat for Ply {
    fn name(&self) -> &'static str {
        "PLY"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["ply"]
    }

    fn detect(&self, head: &[u8], _length: Option<u64>) -> bool {
        head.starts_with(b"ply\n") || head.starts_with(b"ply\r\n")
    }

    fn default_up(&self) -> UpAxis {
        UpAxis::Y
    }

    fn check_attributes(&self, path: &Path, request: AttributeRequest) -> Result<(), InputError> {
        PlyFile::open(path)?.check_attributes(request)
    }

    fn read_mesh(&self, path: &Path, request: AttributeRequest) -> Result<Mesh, InputError> {
        let mesh = PlyFile::open(path)?.read_mesh_with(request)?;
        Ok(weld_identical_positions(mesh))
    }

    fn open(
        &self,
        path: &Path,
        request: AttributeRequest,
        window_bytes: usize,
    ) -> Result<Box<dyn MeshSource>, InputError> {
        let stream = PlyStream::open(path)?;
        stream.check_attributes(request)?;
        if !stream.is_streamable() {
            return Ok(Box::new(self.read_mesh(path, request)?));
        }
        Ok(Box::new(WindowedPly {
            stream,
            request,
            window_bytes,
        }))
    }
}

struct Obj;

impl MeshFormat for Obj {
    fn name(&self) -> &'static str {
        "OBJ"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["obj"]
    }

    /// OBJ has no signature; only its extension names it.
    fn detect(&self, _head: &[u8], _length: Option<u64>) -> bool {
        false
    }

    fn default_up(&self) -> UpAxis {
        UpAxis::Y
    }

    fn check_attributes(&self, path: &Path, request: AttributeRequest) -> Result<(), InputError> {
        obj::check_attributes(path, request)
    }

    fn read_mesh(&self, path: &Path, request: AttributeRequest) -> Result<Mesh, InputError> {
        Ok(weld_identical_positions(obj::read_obj_with(path, request)?))
    }
}

struct Stl;

impl MeshFormat for Stl {
    fn name(&self) -> &'static str {
        "STL"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["stl"]
    }

    fn detect(&self, head: &[u8], length: Option<u64>) -> bool {
        stl::looks_like_stl(head, length)
    }

    fn default_up(&self) -> UpAxis {
        UpAxis::Z
    }

    fn check_attributes(&self, path: &Path, request: AttributeRequest) -> Result<(), InputError> {
        stl::check_attributes(path, request)
    }

    /// The reader welds as it goes.
    fn read_mesh(&self, path: &Path, request: AttributeRequest) -> Result<Mesh, InputError> {
        stl::check_attributes(path, request)?;
        stl::read_stl(path)
    }

    /// Welded in passes through temporary files, so memory follows `window_bytes`.
    fn open(
        &self,
        path: &Path,
        request: AttributeRequest,
        window_bytes: usize,
    ) -> Result<Box<dyn MeshSource>, InputError> {
        stl::check_attributes(path, request)?;
        stl_stream::open_streamed(path, window_bytes)
    }
}

struct Gltf;

impl MeshFormat for Gltf {
    fn name(&self) -> &'static str {
        "glTF 2.0 / GLB"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["gltf", "glb"]
    }

    /// GLB by its magic; `.gltf` JSON only by its extension.
    fn detect(&self, head: &[u8], _length: Option<u64>) -> bool {
        gltf::is_glb(head)
    }

    fn default_up(&self) -> UpAxis {
        UpAxis::Y
    }

    fn check_attributes(&self, path: &Path, request: AttributeRequest) -> Result<(), InputError> {
        gltf::check_attributes(path, request)
    }

    fn read_mesh(&self, path: &Path, request: AttributeRequest) -> Result<Mesh, InputError> {
        gltf::read_gltf(path, request)
    }

    /// The reader checks the attributes as it goes, so the file is read once.
    fn open(
        &self,
        path: &Path,
        request: AttributeRequest,
        _window_bytes: usize,
    ) -> Result<Box<dyn MeshSource>, InputError> {
        Ok(Box::new(self.read_mesh(path, request)?))
    }
}

//! The glTF container: a `.gltf` JSON file or a GLB (12-byte header, a JSON chunk, an optional
//! BIN chunk), its JSON parsed and validated by the `gltf` crate, and its buffers loaded.
//!
//! The GLB chunks are split here rather than by `gltf::Glb::from_slice`, which subtracts the
//! header size from the declared length unchecked and gives no offsets for messages.
//!
//! The GLB and external `.bin` files are mapped rather than read: the accessors read each byte
//! once, so only the page cache needs to hold them, not a copy in the process's heap.

use std::fs::File;
use std::ops::{Deref, Range};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use memmap2::Mmap;

use gltf::json::mesh::Semantic;
use gltf::json::validation::{Checked, Error as ValidationError, Validate};
use gltf::json::{Path as JsonPath, Root};

use super::{defect, json_defect};
use crate::input::error::{InputError, InputErrorKind, Location};
use crate::input::ply::io_error;
use crate::mapping::map_file;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const GLB_HEADER_BYTES: usize = 12;
const CHUNK_HEADER_BYTES: usize = 8;
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// Extensions whose data the reader decodes; any other required extension is refused.
const DECODED_EXTENSIONS: [&str; 2] = ["KHR_mesh_quantization", "EXT_meshopt_compression"];
const DRACO: &str = "KHR_draco_mesh_compression";

/// True when `head` starts a GLB file.
pub(crate) fn is_glb(head: &[u8]) -> bool {
    head.starts_with(GLB_MAGIC)
}

/// The bytes of one buffer and where they are, for messages.
pub(super) struct BufferData {
    pub bytes: BufferBytes,
    /// The file the bytes are in (the GLB or `.gltf` for embedded ones).
    pub file: PathBuf,
    /// Offset of the buffer's first byte in `file`; `None` for a data URI, whose bytes are
    /// decoded base64.
    pub file_offset: Option<u64>,
}

/// A buffer's bytes: a range of a mapped file, or decoded base64.
pub(super) enum BufferBytes {
    Mapped { map: Arc<Mmap>, range: Range<usize> },
    Decoded(Vec<u8>),
}

impl Deref for BufferBytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            BufferBytes::Mapped { map, range } => &map[range.clone()],
            BufferBytes::Decoded(bytes) => bytes,
        }
    }
}

/// The whole file at `path`, mapped.
fn mapped(path: &Path) -> std::io::Result<Arc<Mmap>> {
    Ok(Arc::new(map_file(&File::open(path)?)?))
}

/// A parsed and validated document and its buffers (`None` where a buffer has no data, as
/// the fallback buffers of `EXT_meshopt_compression` may).
pub(super) struct Container {
    pub root: Root,
    pub buffers: Vec<Option<BufferData>>,
    /// Offset of the JSON text in the file (20 in a GLB).
    pub json_offset: u64,
}

/// Reads, parses and validates `path`, and loads every buffer.
pub(super) fn open(path: &Path) -> Result<Container, InputError> {
    let bytes = mapped(path).map_err(|error| io_error(path, &error))?;
    let (json_range, bin_range) = if is_glb(&bytes) {
        split_glb(path, &bytes)?
    } else {
        (0..bytes.len(), None)
    };
    let json_offset = json_range.start as u64;
    let root = parse_json(path, &bytes[json_range.clone()], json_offset)?;
    check_extensions(path, &root, json_offset)?;
    validate(path, &root, json_offset)?;
    let mut bin = bin_range.map(|range| {
        let offset = range.start as u64;
        let map = Arc::clone(&bytes);
        (BufferBytes::Mapped { map, range }, offset)
    });
    let buffers = root
        .buffers
        .iter()
        .enumerate()
        .map(|(index, buffer)| load_buffer(path, index, buffer, &mut bin, json_offset))
        .collect::<Result<_, _>>()?;
    Ok(Container {
        root,
        buffers,
        json_offset,
    })
}

fn split_glb(
    path: &Path,
    bytes: &[u8],
) -> Result<(Range<usize>, Option<Range<usize>>), InputError> {
    let word = |at: usize| -> Result<u32, InputError> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
            .ok_or_else(|| glb_defect(path, at, format!("file ends at byte {}", bytes.len())))
    };
    let version = word(4)?;
    if version != 2 {
        return Err(glb_defect(path, 4, format!("GLB version {version}, not 2")));
    }
    let declared = word(8)? as usize;
    if declared != bytes.len() {
        let message = format!(
            "the header declares {declared} bytes, the file has {}",
            bytes.len()
        );
        return Err(glb_defect(path, 8, message));
    }
    let mut chunks = Vec::new();
    let mut at = GLB_HEADER_BYTES;
    while at < bytes.len() {
        let length = word(at)? as usize;
        let kind = word(at + 4)?;
        let start = at + CHUNK_HEADER_BYTES;
        let end = start.checked_add(length).filter(|&end| end <= bytes.len());
        let Some(end) = end else {
            let message = format!(
                "chunk of {length} bytes, but {} remain",
                bytes.len().saturating_sub(start)
            );
            return Err(glb_defect(path, at, message));
        };
        chunks.push((kind, start..end, at));
        at = end;
    }
    let Some((CHUNK_JSON, json, _)) = chunks.first().cloned() else {
        let message = "the first chunk is not JSON".to_string();
        return Err(glb_defect(path, GLB_HEADER_BYTES, message));
    };
    let bin = match chunks.get(1) {
        Some((CHUNK_BIN, range, _)) => Some(range.clone()),
        Some((_, _, at)) => {
            return Err(glb_defect(path, *at, "the second chunk is not BIN".into()))
        }
        None => None,
    };
    Ok((json, bin))
}

fn glb_defect(path: &Path, byte_offset: usize, message: String) -> InputError {
    defect(path, "GLB header", 0, byte_offset as u64, message)
}

fn parse_json(path: &Path, text: &[u8], json_offset: u64) -> Result<Root, InputError> {
    Root::from_slice(text).map_err(|error| {
        let line = error.line() as u64;
        let byte_offset =
            json_offset + line_start(text, error.line()) + error.column().saturating_sub(1) as u64;
        let location = Location::Element {
            element: "JSON".into(),
            index: 0,
            byte_offset,
            line: Some(line),
        };
        InputError::new(
            path,
            location,
            InputErrorKind::Gltf(error.to_string().into()),
        )
    })
}

/// Offset of the 1-based line `line` in `text`.
fn line_start(text: &[u8], line: usize) -> u64 {
    let mut newlines = text.iter().enumerate().filter(|(_, &b)| b == b'\n');
    match line {
        0 | 1 => 0,
        _ => newlines.nth(line - 2).map_or(text.len(), |(at, _)| at + 1) as u64,
    }
}

/// Draco is refused by name; other required extensions the reader does not decode are
/// refused as unsupported, since skipping them would misread the data.
fn check_extensions(path: &Path, root: &Root, json_offset: u64) -> Result<(), InputError> {
    for (index, name) in root.extensions_required.iter().enumerate() {
        let message = if name == DRACO {
            format!(
                "{DRACO} (Draco-compressed meshes) is not supported, decompress with \
                 gltf-transform or gltfpack"
            )
        } else if DECODED_EXTENSIONS.contains(&name.as_str()) {
            continue;
        } else {
            format!("the required extension {name} is not supported")
        };
        return Err(json_defect(
            path,
            "extensionsRequired",
            index,
            json_offset,
            message,
        ));
    }
    Ok(())
}

/// The `gltf` crate's validation, less what the reader handles itself: required extensions
/// (checked above) and the POSITION accessor's `min`/`max`, which are not used.
fn validate(path: &Path, root: &Root, json_offset: u64) -> Result<(), InputError> {
    check_position_accessors(path, root, json_offset)?;
    let mut first: Option<(String, ValidationError)> = None;
    root.validate(root, JsonPath::new, &mut |where_, error| {
        let where_ = where_().to_string();
        let bounds = where_.ends_with(".min") || where_.ends_with(".max");
        let ignored =
            where_.starts_with("extensionsRequired") || (bounds && where_.contains("POSITION"));
        if first.is_none() && !ignored {
            first = Some((where_, error));
        }
    });
    match first {
        None => Ok(()),
        Some((where_, error)) => {
            let message = format!("{where_}: {error}");
            Err(json_defect(path, "JSON", 0, json_offset, message))
        }
    }
}

/// The crate's validation indexes the accessors by each POSITION attribute unchecked (a panic
/// on a forged index), so those indices are checked first.
fn check_position_accessors(path: &Path, root: &Root, json_offset: u64) -> Result<(), InputError> {
    let position = Checked::Valid(Semantic::Positions);
    for (index, mesh) in root.meshes.iter().enumerate() {
        let accessors = mesh
            .primitives
            .iter()
            .filter_map(|p| p.attributes.get(&position));
        if let Some(accessor) = accessors
            .map(|a| a.value())
            .find(|&a| a >= root.accessors.len())
        {
            let message = format!("POSITION accessor {accessor} does not exist");
            return Err(json_defect(path, "mesh", index, json_offset, message));
        }
    }
    Ok(())
}

fn load_buffer(
    path: &Path,
    index: usize,
    buffer: &gltf::json::Buffer,
    bin: &mut Option<(BufferBytes, u64)>,
    json_offset: u64,
) -> Result<Option<BufferData>, InputError> {
    let declared = buffer.byte_length.0;
    let data = match buffer.uri.as_deref() {
        None if index == 0 && bin.is_some() => {
            let (bytes, offset) = bin.take().expect("checked");
            BufferData {
                bytes,
                file: path.to_path_buf(),
                file_offset: Some(offset),
            }
        }
        None => return Ok(None),
        Some(uri) if uri.starts_with("data:") => BufferData {
            bytes: BufferBytes::Decoded(data_uri(uri).ok_or_else(|| {
                let message = "the data URI is not base64 data".to_string();
                json_defect(path, "buffer", index, json_offset, message)
            })?),
            file: path.to_path_buf(),
            file_offset: None,
        },
        Some(uri) => {
            let file = path
                .parent()
                .unwrap_or(Path::new(""))
                .join(percent_decoded(uri));
            let map = mapped(&file).map_err(|error| {
                let message = format!("cannot read {}: {error}", file.display());
                json_defect(path, "buffer", index, json_offset, message)
            })?;
            let range = 0..map.len();
            BufferData {
                bytes: BufferBytes::Mapped { map, range },
                file,
                file_offset: Some(0),
            }
        }
    };
    if (data.bytes.len() as u64) < declared {
        let message = format!(
            "byteLength {declared}, but {} bytes of data",
            data.bytes.len()
        );
        return Err(json_defect(path, "buffer", index, json_offset, message));
    }
    Ok(Some(data))
}

/// The bytes of a `data:[<type>];base64,<data>` URI.
fn data_uri(uri: &str) -> Option<Vec<u8>> {
    let (header, data) = uri.split_once(',')?;
    if !header.ends_with(";base64") {
        return None;
    }
    base64_decoded(data.as_bytes())
}

fn base64_decoded(text: &[u8]) -> Option<Vec<u8>> {
    let text = text
        .strip_suffix(b"==")
        .or_else(|| text.strip_suffix(b"="))
        .unwrap_or(text);
    let mut bytes = Vec::with_capacity(text.len() / 4 * 3 + 2);
    let mut bits = 0u32;
    let mut count = 0;
    for &symbol in text {
        let value = match symbol {
            b'A'..=b'Z' => symbol - b'A',
            b'a'..=b'z' => symbol - b'a' + 26,
            b'0'..=b'9' => symbol - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        };
        bits = (bits << 6) | u32::from(value);
        count += 6;
        if count >= 8 {
            count -= 8;
            bytes.push((bits >> count) as u8);
        }
    }
    Some(bytes)
}

/// A relative URI as a file name: `%XX` escapes decoded (exporters escape spaces).
fn percent_decoded(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut at = 0;
    while at < bytes.len() {
        let escaped = (bytes[at] == b'%')
            .then(|| uri.get(at + 1..at + 3))
            .flatten()
            .and_then(|hex| u8::from_str_radix(hex, 16).ok());
        match escaped {
            Some(byte) => {
                decoded.push(byte);
                at += 3;
            }
            None => {
                decoded.push(bytes[at]);
                at += 1;
            }
        }
    }
    String::from_utf8_lossy(&decoded).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_decodes_every_padding() {
        assert_eq!(base64_decoded(b"TWFu").unwrap(), b"Man");
        assert_eq!(base64_decoded(b"TWE=").unwrap(), b"Ma");
        assert_eq!(base64_decoded(b"TQ==").unwrap(), b"M");
        assert_eq!(base64_decoded(b"T?=="), None);
    }

    #[test]
    fn percent_escapes_are_decoded() {
        assert_eq!(percent_decoded("my%20mesh.bin"), "my mesh.bin");
        assert_eq!(percent_decoded("100%"), "100%");
    }
}

//! Accessors read to numbers: float, `KHR_mesh_quantization`'s normalized and plain integer
//! components, sparse substitutions, and views compressed with `EXT_meshopt_compression`.
//!
//! The `gltf` crate's accessor reader is not used: it reads slices of buffers, so it cannot
//! read a meshopt-decoded view, and it cannot say at which byte an accessor overruns its
//! view. Every component is read to `f64` (exact for every component type) and dequantized
//! as the glTF specification says: `max(c / 127, -1)` for a normalized byte and so on.

use std::collections::HashMap;
use std::path::Path;

use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;
use gltf::json::Accessor;

use super::container::Container;
use super::meshopt;
use crate::input::error::{InputError, InputErrorKind, Location};

/// The bytes of a buffer view and where they are, for messages.
struct ViewBytes<'a> {
    bytes: &'a [u8],
    stride: Option<usize>,
    /// Offset of `bytes[0]` in the file named by `place` (or in the decoded data).
    offset: u64,
    place: String,
}

/// Reads accessors of one document, decoding each compressed view once.
pub(super) struct Accessors<'a> {
    path: &'a Path,
    container: &'a Container,
    decoded: HashMap<usize, Vec<u8>>,
}

/// One accessor's elements, flat: `components` numbers each.
pub(super) struct Values {
    pub numbers: Vec<f64>,
    pub count: usize,
    /// Where element 0 is and how far apart elements are, for messages (within the JSON for
    /// an accessor without a view).
    first_byte: u64,
    stride: u64,
}

impl Values {
    /// The byte offset of element `element`, for messages.
    pub(super) fn byte_of(&self, element: usize) -> u64 {
        self.first_byte + element as u64 * self.stride
    }
}

impl<'a> Accessors<'a> {
    pub(super) fn new(path: &'a Path, container: &'a Container) -> Self {
        Accessors {
            path,
            container,
            decoded: HashMap::new(),
        }
    }

    /// Accessor `index`'s elements, which must be of one of `types`.
    pub(super) fn read(&mut self, index: usize, types: &[Type]) -> Result<Values, InputError> {
        let accessor = self.accessor(index)?;
        let (Checked::Valid(kind), Checked::Valid(component)) =
            (accessor.type_, accessor.component_type)
        else {
            return Err(self.defect(index, "invalid type or componentType".into()));
        };
        if !types.contains(&kind) {
            return Err(self.defect(index, format!("type {kind:?}, expected one of {types:?}")));
        }
        let layout = Layout {
            components: kind.multiplicity(),
            component: component.0,
            normalized: accessor.normalized,
        };
        let count = usize::try_from(accessor.count.0).unwrap_or(usize::MAX);
        let (mut numbers, first_byte, stride) = match accessor.buffer_view {
            Some(view) => {
                let offset = accessor.byte_offset.map_or(0, |o| o.0);
                self.read_view(index, view.value(), offset, count, layout)?
            }
            None => (
                self.zeros(index, count, layout)?,
                self.container.json_offset,
                0,
            ),
        };
        if let Some(sparse) = &accessor.sparse {
            self.substitute(index, sparse, layout, &mut numbers)?;
        }
        Ok(Values {
            numbers,
            count,
            first_byte,
            stride,
        })
    }

    fn accessor(&self, index: usize) -> Result<&'a Accessor, InputError> {
        self.container
            .root
            .accessors
            .get(index)
            .ok_or_else(|| self.defect(index, "no such accessor".into()))
    }

    /// An accessor without a view is all zeros; one with more elements than all buffers hold
    /// bytes is refused as implausible rather than allocated.
    fn zeros(&self, index: usize, count: usize, layout: Layout) -> Result<Vec<f64>, InputError> {
        let buffered: usize = self
            .container
            .buffers
            .iter()
            .flatten()
            .map(|b| b.bytes.len())
            .sum();
        if count > buffered.max(1) {
            let message =
                format!("{count} elements without a bufferView, more than the buffers hold bytes");
            return Err(self.defect(index, message));
        }
        Ok(vec![0.0; count * layout.components])
    }

    fn read_view(
        &mut self,
        index: usize,
        view: usize,
        offset: u64,
        count: usize,
        layout: Layout,
    ) -> Result<(Vec<f64>, u64, u64), InputError> {
        let path = self.path;
        let bytes = self.view_bytes(index, view)?;
        let element = layout.element_bytes();
        let stride = bytes.stride.unwrap_or(element);
        let end = (count as u128).checked_sub(1).map_or(0, |last| {
            u128::from(offset) + last * stride as u128 + element as u128
        });
        if stride < element || end > bytes.bytes.len() as u128 {
            let message = format!(
                "{count} elements of {element} bytes every {stride} from byte {offset} of \
                 bufferView {view} ({} bytes, {})",
                bytes.bytes.len(),
                bytes.place
            );
            return Err(defect_at(path, index, bytes.offset + offset, message));
        }
        let start = offset as usize;
        let mut numbers = Vec::with_capacity(count * layout.components);
        for element_start in (0..count).map(|i| start + i * stride) {
            layout.push_element(
                &bytes.bytes[element_start..element_start + element],
                &mut numbers,
            );
        }
        Ok((numbers, bytes.offset + offset, stride as u64))
    }

    /// `sparse`'s values replace the elements at its indices.
    fn substitute(
        &mut self,
        index: usize,
        sparse: &gltf::json::accessor::sparse::Sparse,
        layout: Layout,
        numbers: &mut [f64],
    ) -> Result<(), InputError> {
        let count = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
        let Checked::Valid(index_type) = sparse.indices.component_type else {
            return Err(self.defect(index, "invalid sparse.indices.componentType".into()));
        };
        let index_layout = Layout {
            components: 1,
            component: index_type.0,
            normalized: false,
        };
        let indices = self
            .read_view(
                index,
                sparse.indices.buffer_view.value(),
                sparse.indices.byte_offset.0,
                count,
                index_layout,
            )?
            .0;
        let values = self
            .read_view(
                index,
                sparse.values.buffer_view.value(),
                sparse.values.byte_offset.0,
                count,
                layout,
            )?
            .0;
        let elements = numbers.len() / layout.components.max(1);
        for (&target, value) in indices.iter().zip(values.chunks_exact(layout.components)) {
            if target >= elements as f64 {
                let message = format!("sparse index {target} out of range ({elements} elements)");
                return Err(self.defect(index, message));
            }
            let at = target as usize * layout.components;
            numbers[at..at + layout.components].copy_from_slice(value);
        }
        Ok(())
    }

    fn view_bytes(&mut self, accessor: usize, index: usize) -> Result<ViewBytes<'_>, InputError> {
        let path = self.path;
        let container = self.container;
        let Some(view) = container.root.buffer_views.get(index) else {
            return Err(self.defect(accessor, format!("no bufferView {index}")));
        };
        let stride = view.byte_stride.map(|s| s.0);
        if let Some(compressed) = meshopt::compressed(view) {
            let compressed = compressed.map_err(|m| {
                super::json_defect(path, "bufferView", index, container.json_offset, m)
            })?;
            if !self.decoded.contains_key(&index) {
                let decoded = self.decode(index, &compressed)?;
                self.decoded.insert(index, decoded);
            }
            return Ok(ViewBytes {
                bytes: &self.decoded[&index],
                stride: Some(compressed.byte_stride),
                offset: 0,
                place: format!("decoded EXT_meshopt_compression bufferView {index}"),
            });
        }
        let buffer = view.buffer.value();
        let offset = view.byte_offset.map_or(0, |o| o.0);
        let length = view.byte_length.0;
        let (bytes, file_offset, place) = self.buffer_range(index, buffer, offset, length)?;
        Ok(ViewBytes {
            bytes,
            stride,
            offset: file_offset,
            place,
        })
    }

    fn decode(&self, view: usize, compressed: &meshopt::Compressed) -> Result<Vec<u8>, InputError> {
        let (encoded, file_offset, _) = self.buffer_range(
            view,
            compressed.buffer,
            compressed.byte_offset,
            compressed.byte_length,
        )?;
        meshopt::decode(compressed, encoded).map_err(|message| {
            let location = Location::Element {
                element: "bufferView".into(),
                index: view as u64,
                byte_offset: file_offset,
                line: None,
            };
            InputError::new(self.path, location, InputErrorKind::Gltf(message.into()))
        })
    }

    /// Bytes `offset..offset + length` of buffer `buffer`, as bufferView `view` names them,
    /// with their offset in their file and a phrase saying where they are.
    fn buffer_range(
        &self,
        view: usize,
        buffer: usize,
        offset: u64,
        length: u64,
    ) -> Result<(&'a [u8], u64, String), InputError> {
        let path = self.path;
        let json_offset = self.container.json_offset;
        let view_defect =
            |message: String| super::json_defect(path, "bufferView", view, json_offset, message);
        let Some(Some(data)) = self.container.buffers.get(buffer) else {
            return Err(view_defect(format!("buffer {buffer} has no data")));
        };
        let range = usize::try_from(offset)
            .ok()
            .zip(usize::try_from(length).ok())
            .and_then(|(start, length)| Some(start..start.checked_add(length)?))
            .filter(|range| range.end <= data.bytes.len());
        let Some(range) = range else {
            let message = format!(
                "bytes {offset}..+{length} of buffer {buffer}, which has {} bytes",
                data.bytes.len()
            );
            return Err(view_defect(message));
        };
        let (file_offset, place) = match data.file_offset {
            Some(start) if data.file == path => (start + offset, "in this file".to_string()),
            Some(start) => (start + offset, format!("in {}", data.file.display())),
            None => (offset, format!("in buffer {buffer}'s decoded data URI")),
        };
        Ok((&data.bytes[range], file_offset, place))
    }

    /// A defect of the accessor's description, placed at the JSON.
    fn defect(&self, accessor: usize, message: String) -> InputError {
        defect_at(self.path, accessor, self.container.json_offset, message)
    }
}

fn defect_at(path: &Path, accessor: usize, byte_offset: u64, message: String) -> InputError {
    let location = Location::Element {
        element: "accessor".into(),
        index: accessor as u64,
        byte_offset,
        line: None,
    };
    InputError::new(path, location, InputErrorKind::Gltf(message.into()))
}

/// How one element is stored.
#[derive(Clone, Copy)]
struct Layout {
    components: usize,
    component: ComponentType,
    normalized: bool,
}

impl Layout {
    fn element_bytes(self) -> usize {
        self.components * self.component.size()
    }

    fn push_element(self, bytes: &[u8], numbers: &mut Vec<f64>) {
        let size = self.component.size();
        for component in bytes.chunks_exact(size) {
            numbers.push(self.number(component));
        }
    }

    fn number(self, bytes: &[u8]) -> f64 {
        let word =
            |n: usize| -> [u8; 4] { std::array::from_fn(|i| if i < n { bytes[i] } else { 0 }) };
        let (value, scale, signed) = match self.component {
            ComponentType::I8 => (f64::from(bytes[0] as i8), 127.0, true),
            ComponentType::U8 => (f64::from(bytes[0]), 255.0, false),
            ComponentType::I16 => (
                f64::from(i16::from_le_bytes([bytes[0], bytes[1]])),
                32767.0,
                true,
            ),
            ComponentType::U16 => (
                f64::from(u16::from_le_bytes([bytes[0], bytes[1]])),
                65535.0,
                false,
            ),
            ComponentType::U32 => (f64::from(u32::from_le_bytes(word(4))), 4294967295.0, false),
            ComponentType::F32 => return f64::from(f32::from_le_bytes(word(4))),
        };
        match (self.normalized, signed) {
            (false, _) => value,
            (true, true) => (value / scale).max(-1.0),
            (true, false) => value / scale,
        }
    }
}

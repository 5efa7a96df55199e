//! `EXT_meshopt_compression` buffer views, decoded with meshoptimizer's decoder (the `meshopt`
//! crate). The `gltf` crate knows nothing of the extension: its object is read here from the
//! buffer view's extension map.
//!
//! meshoptimizer asserts on strides and counts it cannot take, so each is checked first; a
//! decoded size is also capped at [`MAX_EXPANSION`] times the encoded bytes, above what the
//! codecs can reach, so a forged count cannot make the reader allocate without bound.

use serde::Deserialize;

/// Largest ratio of decoded to encoded bytes accepted (the vertex codec's best is about 32:1
/// for constant data, the index codecs' about 12:1).
const MAX_EXPANSION: usize = 256;
/// Decoded bytes always accepted, whatever the encoded size, for tiny views.
const MIN_CAP: usize = 1 << 16;
const MAX_VERTEX_STRIDE: usize = 256;

/// The extension's object on a buffer view.
#[derive(Debug, Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Compressed {
    pub buffer: usize,
    #[serde(default)]
    pub byte_offset: u64,
    pub byte_length: u64,
    pub byte_stride: usize,
    pub count: usize,
    pub mode: String,
    #[serde(default)]
    pub filter: Option<String>,
}

/// The extension's object on `view`, `None` when it has none; an error message when it is
/// malformed.
pub(super) fn compressed(view: &gltf::json::buffer::View) -> Option<Result<Compressed, String>> {
    let value = view
        .extensions
        .as_ref()?
        .others
        .get("EXT_meshopt_compression")?;
    Some(
        Compressed::deserialize(value)
            .map_err(|error| format!("malformed EXT_meshopt_compression: {error}")),
    )
}

/// Decodes `encoded` as `compressed` says, or says why not.
pub(super) fn decode(compressed: &Compressed, encoded: &[u8]) -> Result<Vec<u8>, String> {
    let Compressed {
        byte_stride: stride,
        count,
        ..
    } = *compressed;
    let decoded_bytes = count
        .checked_mul(stride)
        .filter(|&bytes| bytes <= encoded.len().saturating_mul(MAX_EXPANSION).max(MIN_CAP))
        .ok_or_else(|| {
            format!(
                "{count} elements of {stride} bytes cannot come from {} encoded bytes",
                encoded.len()
            )
        })?;
    let decoded = match compressed.mode.as_str() {
        "ATTRIBUTES" => decode_attributes(encoded, count, stride)?,
        "TRIANGLES" if !count.is_multiple_of(3) => {
            return Err(format!(
                "TRIANGLES mode with {count} indices, not a multiple of 3"
            ))
        }
        "TRIANGLES" | "INDICES" => decode_indices(&compressed.mode, encoded, count, stride)?,
        mode => return Err(format!("unknown mode {mode}")),
    };
    debug_assert_eq!(decoded.len(), decoded_bytes);
    match compressed.filter.as_deref() {
        None | Some("NONE") => Ok(decoded),
        Some(_) if compressed.mode != "ATTRIBUTES" => {
            Err("a filter on a view that is not ATTRIBUTES".into())
        }
        Some(filter) => unfiltered(filter, decoded, stride),
    }
}

fn decode_attributes(encoded: &[u8], count: usize, stride: usize) -> Result<Vec<u8>, String> {
    if stride == 0 || !stride.is_multiple_of(4) || stride > MAX_VERTEX_STRIDE {
        return Err(format!(
            "ATTRIBUTES stride {stride}: must be 4 to 256, a multiple of 4"
        ));
    }
    let decoded = decode_vertices_by_stride(encoded, count, stride);
    decoded.map_err(|error| format!("meshoptimizer cannot decode the vertices: {error}"))
}

/// One vertex of `N` bytes, so meshoptimizer's decoder (generic over the element type) can be
/// given the stride the file declares.
#[derive(Clone, Copy)]
struct Element<const N: usize>([u8; N]);

impl<const N: usize> Default for Element<N> {
    fn default() -> Self {
        Element([0; N])
    }
}

fn decode_vertices<const N: usize>(encoded: &[u8], count: usize) -> meshopt::Result<Vec<u8>> {
    let elements = meshopt::decode_vertex_buffer::<Element<N>>(encoded, count)?;
    Ok(elements.into_iter().flat_map(|element| element.0).collect())
}

macro_rules! by_stride {
    ($encoded:expr, $count:expr, $stride:expr; $($n:literal)*) => {
        match $stride {
            $($n => decode_vertices::<$n>($encoded, $count),)*
            _ => unreachable!("strides are checked to be 4 to 256, multiples of 4"),
        }
    };
}

fn decode_vertices_by_stride(
    encoded: &[u8],
    count: usize,
    stride: usize,
) -> meshopt::Result<Vec<u8>> {
    by_stride!(encoded, count, stride;
        4 8 12 16 20 24 28 32 36 40 44 48 52 56 60 64 68 72 76 80 84 88 92 96 100 104 108 112
        116 120 124 128 132 136 140 144 148 152 156 160 164 168 172 176 180 184 188 192 196 200
        204 208 212 216 220 224 228 232 236 240 244 248 252 256)
}

fn decode_indices(
    mode: &str,
    encoded: &[u8],
    count: usize,
    stride: usize,
) -> Result<Vec<u8>, String> {
    let cannot =
        |error: meshopt::Error| format!("meshoptimizer cannot decode the indices: {error}");
    match (mode, stride) {
        ("TRIANGLES", 2) => meshopt::decode_index_buffer::<u16>(encoded, count)
            .map(|indices| indices.iter().flat_map(|i| i.to_le_bytes()).collect()),
        ("TRIANGLES", 4) => meshopt::decode_index_buffer::<u32>(encoded, count)
            .map(|indices| indices.iter().flat_map(|i| i.to_le_bytes()).collect()),
        (_, 2) => meshopt::decode_index_sequence::<u16>(encoded, count)
            .map(|indices| indices.iter().flat_map(|i| i.to_le_bytes()).collect()),
        (_, 4) => meshopt::decode_index_sequence::<u32>(encoded, count)
            .map(|indices| indices.iter().flat_map(|i| i.to_le_bytes()).collect()),
        _ => return Err(format!("{mode} stride {stride}: must be 2 or 4")),
    }
    .map_err(cannot)
}

/// Undoes the filter of a decoded ATTRIBUTES view; meshoptimizer's filters work in place on
/// native-endian components, so the bytes go through typed arrays.
fn unfiltered(filter: &str, bytes: Vec<u8>, stride: usize) -> Result<Vec<u8>, String> {
    match (filter, stride) {
        ("OCTAHEDRAL", 4) => Ok(through_i8(bytes, meshopt::decode_filter_oct::<i8>)),
        ("OCTAHEDRAL", 8) => Ok(through_i16(bytes, meshopt::decode_filter_oct::<i16>)),
        ("QUATERNION", 8) => Ok(through_i16(bytes, meshopt::decode_filter_quat)),
        ("EXPONENTIAL", _) => {
            let mut words: Vec<[u32; 1]> = bytes
                .chunks_exact(4)
                .map(|w| [u32::from_le_bytes(w.try_into().expect("4 bytes"))])
                .collect();
            meshopt::decode_filter_exp(&mut words);
            Ok(words.iter().flat_map(|w| w[0].to_le_bytes()).collect())
        }
        (filter, stride) => Err(format!("filter {filter} with stride {stride}")),
    }
}

fn through_i8(bytes: Vec<u8>, filter: fn(&mut [[i8; 4]])) -> Vec<u8> {
    let mut values: Vec<[i8; 4]> = bytes
        .chunks_exact(4)
        .map(|v| [v[0], v[1], v[2], v[3]].map(|b| b as i8))
        .collect();
    filter(&mut values);
    values.iter().flatten().map(|&v| v as u8).collect()
}

fn through_i16(bytes: Vec<u8>, filter: fn(&mut [[i16; 4]])) -> Vec<u8> {
    let mut values: Vec<[i16; 4]> = bytes
        .chunks_exact(8)
        .map(|v| std::array::from_fn(|i| i16::from_le_bytes([v[2 * i], v[2 * i + 1]])))
        .collect();
    filter(&mut values);
    values
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

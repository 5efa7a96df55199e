//! Frames as baseline JPEG, encoded in horizontal strips on the tracing threads and joined into
//! one image by restart markers: each strip is a whole number of MCU rows, encoded as an image
//! of its own (its DC predictions start from zero, as after a restart marker), and the joined
//! file declares the strip's MCUs as its restart interval. The bytes are those of encoding the
//! whole image with that restart interval.

use jpeg_encoder::{ColorType, Encoder, EncodingError};
use rayon::prelude::*;

/// Rows of an MCU: quality below 90 subsamples chroma 2 × 2 (jpeg-encoder's default).
const MCU_SIDE: usize = 16;

/// Strips per thread: a few, so that a strip of sky and one of model even out.
const STRIPS_PER_THREAD: usize = 2;

/// The JPEG of a `width` × `height` image of 8-bit sRGB bytes, three per pixel, at `quality`
/// (below 90: strips of whole 16-row MCUs assume 2 × 2 chroma subsampling).
pub fn encode(srgb: &[u8], width: u16, height: u16, quality: u8) -> Result<Vec<u8>, EncodingError> {
    let strips = rayon::current_num_threads() * STRIPS_PER_THREAD;
    let rows = strip_rows(usize::from(width), usize::from(height), strips);
    let interval = restart_interval(usize::from(width), rows);
    let row_bytes = usize::from(width) * 3;
    let strips: Vec<Vec<u8>> = srgb
        .par_chunks(rows * row_bytes)
        .map(|strip| {
            let strip_height = (strip.len() / row_bytes) as u16;
            let mut jpeg = Vec::new();
            Encoder::new(&mut jpeg, quality).encode(strip, width, strip_height, ColorType::Rgb)?;
            Ok(jpeg)
        })
        .collect::<Result<_, EncodingError>>()?;
    Ok(joined(&strips, height, interval))
}

/// Rows of each strip but the last: a whole number of MCU rows, about `height / strips`, and
/// few enough MCUs for a restart interval (at most 65,535).
fn strip_rows(width: usize, height: usize, strips: usize) -> usize {
    let mcu_rows = height.div_ceil(MCU_SIDE).div_ceil(strips.max(1)).max(1);
    let most = usize::from(u16::MAX) / width.div_ceil(MCU_SIDE).max(1);
    mcu_rows.min(most.max(1)) * MCU_SIDE
}

/// The MCUs of a strip of `rows` rows of a `width`-pixel image.
fn restart_interval(width: usize, rows: usize) -> u16 {
    (width.div_ceil(MCU_SIDE) * rows / MCU_SIDE) as u16
}

/// The strips' JPEGs as one of `height` rows: the first strip's headers with the height and a
/// restart interval, then each strip's entropy-coded data, restart markers between them.
fn joined(strips: &[Vec<u8>], height: u16, interval: u16) -> Vec<u8> {
    let first = &strips[0];
    let mut jpeg = Vec::with_capacity(strips.iter().map(Vec::len).sum::<usize>() + 16);
    jpeg.extend_from_slice(&first[..2]);
    let mut at = 2;
    while at < entropy_data(first).start {
        let marker = first[at + 1];
        let segment = &first[at..at + 2 + segment_length(first, at)];
        if marker == SOS && strips.len() > 1 {
            jpeg.extend_from_slice(&[0xFF, DRI, 0, 4]);
            jpeg.extend_from_slice(&interval.to_be_bytes());
        }
        let segment_start = jpeg.len();
        jpeg.extend_from_slice(segment);
        if marker == SOF0 {
            // The frame header: marker, length, precision, then the height.
            jpeg[segment_start + 5..segment_start + 7].copy_from_slice(&height.to_be_bytes());
        }
        at += segment.len();
    }
    for (index, strip) in strips.iter().enumerate() {
        if index > 0 {
            jpeg.extend_from_slice(&[0xFF, RST0 + ((index - 1) % 8) as u8]);
        }
        jpeg.extend_from_slice(&strip[entropy_data(strip)]);
    }
    jpeg.extend_from_slice(&[0xFF, EOI]);
    jpeg
}

const SOF0: u8 = 0xC0;
const RST0: u8 = 0xD0;
const EOI: u8 = 0xD9;
const SOS: u8 = 0xDA;
const DRI: u8 = 0xDD;

/// The length field of the marker segment at `at` (its bytes after the marker).
fn segment_length(jpeg: &[u8], at: usize) -> usize {
    usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]]))
}

/// A JPEG's entropy-coded data: from after its scan header to before its end-of-image marker.
fn entropy_data(jpeg: &[u8]) -> std::ops::Range<usize> {
    let mut at = 2;
    while jpeg[at + 1] != SOS {
        at += 2 + segment_length(jpeg, at);
    }
    at + 2 + segment_length(jpeg, at)..jpeg.len() - 2
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth gradient with a sharp-edged square: varied blocks, as a frame has.
    fn image(width: usize, height: usize) -> Vec<u8> {
        (0..width * height)
            .flat_map(|index| {
                let (x, y) = (index % width, index / width);
                let inside =
                    (width / 4..width / 2).contains(&x) && (height / 3..height).contains(&y);
                let shade = if inside { 230 } else { (x * 255 / width) as u8 };
                [shade, (y * 255 / height) as u8, ((x + y) % 256) as u8]
            })
            .collect()
    }

    /// The strips joined are, byte for byte, the whole image encoded with the strips' restart
    /// interval; and one strip is the plain encoding.
    #[test]
    fn strips_joined_are_the_image_encoded_with_restart_markers() {
        for (width, height, strips) in [(512, 512, 4), (100, 70, 3), (33, 200, 20), (64, 40, 1)] {
            let srgb = image(width, height);
            let rows = strip_rows(width, height, strips);
            let mut parts = Vec::new();
            for strip in srgb.chunks(rows * width * 3) {
                let mut jpeg = Vec::new();
                let strip_height = (strip.len() / (width * 3)) as u16;
                Encoder::new(&mut jpeg, 85)
                    .encode(strip, width as u16, strip_height, ColorType::Rgb)
                    .expect("encoded");
                parts.push(jpeg);
            }
            let interval = restart_interval(width, rows);
            let mut whole = Vec::new();
            let mut encoder = Encoder::new(&mut whole, 85);
            if parts.len() > 1 {
                encoder.set_restart_interval(interval);
            }
            encoder
                .encode(&srgb, width as u16, height as u16, ColorType::Rgb)
                .expect("encoded");
            let joined = joined(&parts, height as u16, interval);
            assert_eq!(joined, whole, "{width}x{height} in {} strips", parts.len());
        }
    }
}

//! Image output of a linear-RGB frame, written atomically (temporary file + rename) so a failed
//! render never leaves a truncated image behind: 8-bit sRGB PNG, or the linear values themselves
//! as a portable float map (PFM), the format chosen by the file's extension. An image rendered
//! straight into its output ([`render_into`]) is written as PFM band by band as it is rendered,
//! and as PNG from its 8-bit pixels once they are all there (the encoder compresses the whole
//! image at once).

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::scene::Scene;
use super::{render_rows, Frame, RenderReport, RowOrder};
use crate::atomic;
use crate::trace::Tracer;

#[derive(Debug, thiserror::Error)]
#[error("writing {}: {source}", path.display())]
pub struct ImageError {
    pub path: PathBuf,
    #[source]
    pub source: io::Error,
}

/// The frame as 8-bit sRGB bytes, three per pixel; in parallel (a pixel's bytes depend only on
/// the pixel), for a whole frame that nothing else is working on (PNG output, Python).
pub fn srgb_bytes(frame: &Frame) -> Vec<u8> {
    let values = frame.pixels.as_flattened();
    let mut bytes = vec![0; values.len()];
    // Chunks written in place: collecting them byte by byte cost more than the encoding.
    bytes
        .par_chunks_mut(SRGB_CHUNK_VALUES)
        .zip(values.par_chunks(SRGB_CHUNK_VALUES))
        .for_each(|(bytes, values)| write_srgb(bytes, values));
    bytes
}

/// Channel values one thread encodes to sRGB at a time: enough to outweigh the hand-over.
const SRGB_CHUNK_VALUES: usize = 3 << 14;

/// The 8-bit sRGB code of each linear value of `values` into the byte beside it in `bytes`.
fn write_srgb(bytes: &mut [u8], values: &[f32]) {
    for (byte, &value) in bytes.iter_mut().zip(values) {
        *byte = encode_srgb(value);
    }
}

/// The 8-bit sRGB bytes of `pixels`, three per pixel, on the calling thread (the viewer's bands
/// are encoded each on its own thread).
pub fn srgb_bytes_of(pixels: &[[f32; 3]]) -> Vec<u8> {
    let mut bytes = Vec::new();
    extend_srgb(&mut bytes, pixels);
    bytes
}

/// Appends the 8-bit sRGB bytes of `pixels` to `bytes`.
fn extend_srgb(bytes: &mut Vec<u8>, pixels: &[[f32; 3]]) {
    let start = bytes.len();
    let values = pixels.as_flattened();
    bytes.resize(start + values.len(), 0);
    write_srgb(&mut bytes[start..], values);
}

/// Linear value in `[0, 1]` (clamped; NaN as 0) to an 8-bit sRGB code: [`srgb_formula`]'s
/// code, looked up (its `powf` was a tenth of a viewer frame's instructions).
fn encode_srgb(linear: f32) -> u8 {
    // -0.0 too, whose bits would fall outside the table.
    if linear.is_nan() || linear <= 0.0 {
        return 0;
    }
    SrgbCodes::get().code(linear.min(1.0))
}

/// The sRGB curve's 8-bit code of a linear value in `[0, 1]`.
fn srgb_formula(x: f32) -> u8 {
    let encoded = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (encoded * 255.0 + 0.5) as u8
}

/// [`srgb_formula`] as a table: where each code starts, and the code at the start of each
/// bucket of consecutive `f32` bit patterns, from which a value's code is at most a step or
/// two up (the curve rises less than one code over a bucket).
struct SrgbCodes {
    /// `starts[c]`: the smallest value whose code is `c` or more.
    starts: [f32; 256],
    bucket_codes: Vec<u8>,
}

/// Bits of an `f32` below its bucket number: buckets of 2^16 bit patterns, 16,257 of them up
/// to 1.0.
const SRGB_BUCKET_SHIFT: u32 = 16;

impl SrgbCodes {
    fn get() -> &'static SrgbCodes {
        static CODES: std::sync::OnceLock<SrgbCodes> = std::sync::OnceLock::new();
        CODES.get_or_init(SrgbCodes::new)
    }

    fn new() -> SrgbCodes {
        let one = 1.0f32.to_bits();
        let mut starts = [0.0f32; 256];
        for (code, start) in starts.iter_mut().enumerate().skip(1) {
            // The formula rises with its value, and the bit patterns of positive floats with it.
            let (mut below, mut at) = (0, one);
            while at - below > 1 {
                let middle = below + (at - below) / 2;
                match usize::from(srgb_formula(f32::from_bits(middle))) >= code {
                    true => at = middle,
                    false => below = middle,
                }
            }
            *start = f32::from_bits(at);
        }
        let buckets = (one >> SRGB_BUCKET_SHIFT) + 1;
        let bucket_codes = (0..buckets)
            .map(|bucket| {
                let first = f32::from_bits(bucket << SRGB_BUCKET_SHIFT);
                (starts[1..].partition_point(|&start| start <= first)) as u8
            })
            .collect();
        SrgbCodes {
            starts,
            bucket_codes,
        }
    }

    /// The code of `x` in `(0, 1]`.
    fn code(&self, x: f32) -> u8 {
        let mut code = self.bucket_codes[(x.to_bits() >> SRGB_BUCKET_SHIFT) as usize];
        while code < 255 && x >= self.starts[usize::from(code) + 1] {
            code += 1;
        }
        code
    }
}

pub fn write_png(frame: &Frame, out: &Path) -> Result<(), ImageError> {
    atomic::write_atomically(out, |writer| {
        encode_png(frame.width, frame.height, &srgb_bytes(frame), writer)
    })
    .map_err(|source| ImageError {
        path: out.to_path_buf(),
        source,
    })
}

/// The PNG of a `width` × `height` image of 8-bit sRGB bytes.
fn encode_png(width: u32, height: u32, srgb: &[u8], out: &mut dyn Write) -> io::Result<()> {
    let mut encoder = png::Encoder::new(out, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut png = encoder.write_header().map_err(io::Error::other)?;
    png.write_image_data(srgb).map_err(io::Error::other)?;
    png.finish().map_err(io::Error::other)
}

/// The image formats, by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// `.png`: 8-bit sRGB.
    Png,
    /// `.pfm`: linear RGB as 32-bit floats, for measurements and tone mapping elsewhere.
    Pfm,
}

impl ImageFormat {
    /// The format of `path` by its extension (any case), `None` for any other extension.
    pub fn of(path: &Path) -> Option<ImageFormat> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "png" => Some(ImageFormat::Png),
            "pfm" => Some(ImageFormat::Pfm),
            _ => None,
        }
    }
}

/// Writes `frame` to `out` in `format`.
pub fn write_image(frame: &Frame, out: &Path, format: ImageFormat) -> Result<(), ImageError> {
    match format {
        ImageFormat::Png => write_png(frame, out),
        ImageFormat::Pfm => write_pfm(frame, out),
    }
}

/// The portable float map: a text header, then little-endian f32 RGB (the negative scale says
/// little-endian), rows from the bottom up as the format orders them.
pub fn write_pfm(frame: &Frame, out: &Path) -> Result<(), ImageError> {
    atomic::write_atomically(out, |writer| {
        write_pfm_header(frame.width, frame.height, writer)?;
        write_pfm_rows(&frame.pixels, frame.width, writer)
    })
    .map_err(|source| ImageError {
        path: out.to_path_buf(),
        source,
    })
}

fn write_pfm_header(width: u32, height: u32, out: &mut dyn Write) -> io::Result<()> {
    write!(out, "PF\n{width} {height}\n-1.0\n")
}

/// The rows of `pixels` (`width` across, from the top), bottom up as PFM orders them.
fn write_pfm_rows(pixels: &[[f32; 3]], width: u32, out: &mut dyn Write) -> io::Result<()> {
    for row in pixels.chunks_exact(width as usize).rev() {
        for channel in row.iter().flatten() {
            out.write_all(&channel.to_le_bytes())?;
        }
    }
    Ok(())
}

/// Renders `scene` with `tracer` into `out` in `format`, the same bytes as [`write_image`]
/// writes of the rendered frame: PFM band by band as the bands are rendered (from the bottom,
/// as PFM orders its rows), PNG once its 8-bit pixels are complete.
pub fn render_into(
    tracer: &Tracer,
    scene: &Scene,
    format: ImageFormat,
    out: &mut dyn Write,
) -> io::Result<RenderReport> {
    let (width, height) = (scene.image.width, scene.image.height);
    match format {
        ImageFormat::Png => {
            let mut srgb = Vec::with_capacity(width as usize * height as usize * 3);
            let report = render_rows(tracer, scene, RowOrder::TopDown, |rows| {
                extend_srgb(&mut srgb, rows);
                Ok::<(), io::Error>(())
            })?;
            encode_png(width, height, &srgb, out)?;
            Ok(report)
        }
        ImageFormat::Pfm => {
            write_pfm_header(width, height, out)?;
            render_rows(tracer, scene, RowOrder::BandsBottomUp, |rows| {
                write_pfm_rows(rows, width, &mut *out)
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The formula's code of any value, as `encode_srgb` takes it.
    fn formula_of(linear: f32) -> u8 {
        srgb_formula(if linear.is_nan() {
            0.0
        } else {
            linear.clamp(0.0, 1.0)
        })
    }

    #[test]
    fn srgb_codes_are_the_formulas_around_every_code_start_and_across_the_range() {
        let codes = SrgbCodes::get();
        let one = 1.0f32.to_bits();
        let near_starts = codes.starts[1..].iter().flat_map(|start| {
            let bits = start.to_bits();
            bits.saturating_sub(2048)..(bits + 2048).min(one + 1)
        });
        let across = (0..=one).step_by(4093).chain([one]);
        for bits in near_starts.chain(across) {
            let x = f32::from_bits(bits);
            assert_eq!(encode_srgb(x), srgb_formula(x), "{x:e} ({bits:#x})");
        }
        for x in [
            f32::NAN,
            -0.0,
            -1.0,
            f32::NEG_INFINITY,
            1.5,
            f32::INFINITY,
            f32::MIN_POSITIVE,
        ] {
            assert_eq!(encode_srgb(x), formula_of(x), "{x}");
        }
    }
}

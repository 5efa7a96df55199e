//! Image output of a linear-RGB frame, written atomically (temporary file + rename) so a failed
//! render never leaves a truncated image behind: 8-bit sRGB PNG, or the linear values themselves
//! as a portable float map (PFM), the format chosen by the file's extension.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::Frame;
use crate::atomic;

#[derive(Debug, thiserror::Error)]
#[error("writing {}: {source}", path.display())]
pub struct ImageError {
    pub path: PathBuf,
    #[source]
    pub source: io::Error,
}

/// The frame as 8-bit sRGB bytes, three per pixel.
pub fn srgb_bytes(frame: &Frame) -> Vec<u8> {
    frame
        .pixels
        .iter()
        .flat_map(|pixel| pixel.map(encode_srgb))
        .collect()
}

/// Linear value in `[0, 1]` (clamped) to an 8-bit sRGB code.
fn encode_srgb(linear: f32) -> u8 {
    let x = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    let encoded = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (encoded * 255.0 + 0.5) as u8
}

pub fn write_png(frame: &Frame, out: &Path) -> Result<(), ImageError> {
    atomic::write_atomically(out, |writer| {
        let mut encoder = png::Encoder::new(writer, frame.width, frame.height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut png = encoder.write_header().map_err(io::Error::other)?;
        png.write_image_data(&srgb_bytes(frame))
            .map_err(io::Error::other)?;
        png.finish().map_err(io::Error::other)
    })
    .map_err(|source| ImageError {
        path: out.to_path_buf(),
        source,
    })
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
        write!(writer, "PF\n{} {}\n-1.0\n", frame.width, frame.height)?;
        for row in frame.pixels.chunks_exact(frame.width as usize).rev() {
            for channel in row.iter().flatten() {
                writer.write_all(&channel.to_le_bytes())?;
            }
        }
        Ok(())
    })
    .map_err(|source| ImageError {
        path: out.to_path_buf(),
        source,
    })
}

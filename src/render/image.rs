//! 8-bit sRGB PNG output of a linear-RGB frame, written atomically (temporary file + rename) so
//! a failed render never leaves a truncated image behind.

use std::fs::{self, File};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use super::Frame;
use crate::format::writer::temporary_path;

#[derive(Debug, thiserror::Error)]
#[error("writing {}: {source}", path.display())]
pub struct ImageError {
    pub path: PathBuf,
    #[source]
    pub source: png::EncodingError,
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
    let temporary = temporary_path(out);
    let result = encode(frame, &temporary)
        .and_then(|()| fs::rename(&temporary, out).map_err(png::EncodingError::from));
    if result.is_err() {
        let _ = fs::remove_file(&temporary);
    }
    result.map_err(|source| ImageError {
        path: out.to_path_buf(),
        source,
    })
}

fn encode(frame: &Frame, path: &Path) -> Result<(), png::EncodingError> {
    let writer = BufWriter::new(File::create(path)?);
    let mut encoder = png::Encoder::new(writer, frame.width, frame.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&srgb_bytes(frame))?;
    writer.finish()
}

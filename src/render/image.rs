//! 8-bit sRGB PNG output of a linear-RGB frame, written atomically (temporary file + rename) so
//! a failed render never leaves a truncated image behind.

use std::io;
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

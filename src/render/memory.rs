//! The memory an image needs, checked before anything is traced: a render the machine cannot
//! hold is refused with the figure up front instead of being killed by the kernel hours later.

use super::image::ImageFormat;
use super::scene::Scene;
use super::{band_pixels, PIXEL_STATE_BYTES};

/// Bytes per pixel the PNG encoder may hold at once: the 8-bit image, its compressed copy and,
/// when compression does not pay, the stored copy made beside it.
const PNG_BYTES_PER_PIXEL: u64 = 3 * 3;

/// The most memory rendering `scene` into `format` needs, in bytes: one band's per-pixel state
/// and, for PNG, the whole image the encoder compresses.
pub fn needed_bytes(scene: &Scene, format: ImageFormat) -> u64 {
    let image = &scene.image;
    let factor = image.antialiasing.max(1);
    let (fine_width, fine_height) = (image.width * factor, image.height * factor);
    let band = band_pixels(fine_width, fine_height, factor) * PIXEL_STATE_BYTES;
    let encoder = match format {
        ImageFormat::Png => u64::from(image.width) * u64::from(image.height) * PNG_BYTES_PER_PIXEL,
        ImageFormat::Pfm => 0,
    };
    band + encoder
}

/// The memory the kernel reports available for new allocations without swapping
/// (`MemAvailable` of `/proc/meminfo`), or `None` where it does not say.
pub fn available_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = meminfo
        .lines()
        .find(|line| line.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses, with the figures, a render that needs more memory than is available.
pub fn check(scene: &Scene, format: ImageFormat) -> Result<(), String> {
    let needed = needed_bytes(scene, format);
    match available_bytes() {
        Some(available) if needed > available => Err(format!(
            "rendering {}x{} as {format:?} needs about {:.1} GiB of memory and {:.1} GiB are \
             available: render a smaller image{}",
            scene.image.width,
            scene.image.height,
            gib(needed),
            gib(available),
            match format {
                ImageFormat::Png => ", or a .pfm (written band by band as it is rendered)",
                ImageFormat::Pfm => "",
            }
        )),
        _ => Ok(()),
    }
}

fn gib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 30) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_png_needs_its_encoder_and_one_band_and_a_pfm_only_the_band() {
        let text = "[image]\nwidth = 16384\nheight = 16384\n[camera]\nauto = true\n";
        let scene = Scene::parse(std::path::Path::new("s.toml"), text).expect("scene");
        let band = 16 * 16384 * PIXEL_STATE_BYTES;
        assert_eq!(needed_bytes(&scene, ImageFormat::Pfm), band);
        assert_eq!(
            needed_bytes(&scene, ImageFormat::Png),
            band + 16384 * 16384 * 9
        );
    }
}

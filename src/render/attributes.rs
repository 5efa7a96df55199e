//! Stored attributes in the shading (format 2.5): the interpolated vertex normal makes smooth
//! shading, the interpolated vertex colour multiplies the scene's albedo. Both are read for each
//! primary ray's final hit only ([`surface_attributes`]: no face id), never during traversal.
//!
//! Secondary rays ignore them: shadow and AO rays leave from the point pushed off the surface
//! along the geometric normal, around the geometric normal, exactly as without attributes. So
//! the rays traced do not change, and a smooth normal that bends below the triangle cannot send a
//! ray into its own surface. The price is the usual shadow terminator of coarse meshes: where the
//! geometric normal turns away from a casting light, the pixel is in shadow even if its smooth
//! normal still faces the light.

use glam::Vec3;

use super::sampling::Surface;
use super::scene::Shading;
use crate::format::attributes::{AttributeSet, NormalEncoding};
use crate::format::reader::ReducemFile;
use crate::trace::{surface_attributes, Hit};

/// Which stored attributes the shading uses: those the file has and the scene leaves on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AttributeUse {
    /// Shade with the interpolated stored normal (`[shading] smooth`).
    pub normals: bool,
    /// Multiply the albedo by the interpolated vertex colour (`[shading] vertex_colors`).
    pub colors: bool,
}

impl AttributeUse {
    pub fn new(stored: AttributeSet, shading: &Shading) -> AttributeUse {
        AttributeUse {
            normals: shading.smooth && stored.normals != NormalEncoding::None,
            colors: shading.vertex_colors && stored.colors,
        }
    }

    /// Whether a hit's attributes are read at all.
    pub fn any(self) -> bool {
        self.normals || self.colors
    }
}

impl Surface {
    /// This surface with the shading normal and colour that `hit` (the hit it was made from)
    /// interpolates, as far as `used` asks; unchanged when it asks for nothing.
    pub fn with_attributes(self, file: &ReducemFile, hit: &Hit, used: AttributeUse) -> Surface {
        if !used.any() {
            return self;
        }
        let attributes = surface_attributes(file, hit);
        let mut surface = self;
        if used.normals {
            // Two-sided like the geometric normal: turned to the side the ray came from, which
            // is the side `self.normal` was turned to.
            let normal = Vec3::from(attributes.shading_normal);
            surface.shading_normal = if normal.dot(self.normal) < 0.0 {
                -normal
            } else {
                normal
            };
        }
        if let Some(color) = attributes.color.filter(|_| used.colors) {
            surface.color = Vec3::new(
                srgb_to_linear(color[0]),
                srgb_to_linear(color[1]),
                srgb_to_linear(color[2]),
            );
        }
        surface
    }
}

/// An 8-bit sRGB code as a linear value in `[0, 1]` (IEC 61966-2-1's decoding curve); computed
/// in f64 so that 255 decodes to exactly 1.0 and a white vertex leaves the albedo unchanged.
pub fn srgb_to_linear(code: u8) -> f32 {
    let encoded = f64::from(code) / 255.0;
    let linear = if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    };
    linear as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::image::srgb_bytes;
    use crate::render::Frame;

    #[test]
    fn srgb_decoding_ends_exactly_and_inverts_the_encoding() {
        assert_eq!(srgb_to_linear(0), 0.0);
        assert_eq!(srgb_to_linear(255), 1.0);
        let frame = |value: f32| Frame {
            width: 1,
            height: 1,
            pixels: vec![[value; 3]],
        };
        for code in 0..=255u8 {
            let encoded = srgb_bytes(&frame(srgb_to_linear(code)));
            assert_eq!(encoded[0], code);
        }
    }
}

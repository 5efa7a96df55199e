//! Stateless sampling and robust secondary-ray origins.
//!
//! Random numbers come from a hash of (seed, pixel, sample, dimension) rather than a generator
//! with state, so a pixel's samples do not depend on which thread renders it or in what order:
//! the image is reproducible for any thread count. The hash is a 32-bit integer finaliser
//! (xorshift-multiply rounds in the style of Wang / "lowbias32"), ample for AO directions.
//!
//! Secondary rays leave a surface from a point pushed off it along the geometric normal, after
//! Wächter and Binder, "A Fast and Robust Method for Avoiding Self-Intersection" (Ray Tracing
//! Gems, ch. 6): the offset is a fixed number of units in the last place of each coordinate, so it
//! scales with the coordinate's magnitude and stays sufficient far from the origin (where a fixed
//! epsilon is too small), with a small absolute offset for coordinates near zero (where ULPs
//! vanish). Trade-off: near large coordinates the push is larger in model units, so contact
//! shadows of very thin features far from the origin may be lost; acne never appears.

use glam::{DVec3, Vec3};

use crate::format::reader::ReducemFile;
use crate::trace::{Hit, Ray};

/// Integer ULPs added along the normal, per unit of normal component.
const ULP_OFFSET: f32 = 256.0;
/// Below this magnitude a coordinate moves by an absolute amount instead.
const NEAR_ORIGIN: f32 = 1.0 / 32.0;
/// The absolute push, per unit of normal component, near the origin.
const ABSOLUTE_OFFSET: f32 = 1.0 / 65536.0;

/// `p` moved off its surface to the side `normal` points to.
pub fn offset_origin(p: Vec3, normal: Vec3) -> Vec3 {
    let moved = |coordinate: f32, n: f32| {
        if coordinate.abs() < NEAR_ORIGIN {
            return coordinate + ABSOLUTE_OFFSET * n;
        }
        let ulps = (ULP_OFFSET * n) as i32;
        // Moving the bit pattern away from zero grows the magnitude; the sign of the step
        // follows the sign of the coordinate so that `n > 0` always moves towards +inf.
        let step = if coordinate < 0.0 { -ulps } else { ulps };
        f32::from_bits((coordinate.to_bits() as i32).wrapping_add(step) as u32)
    };
    Vec3::new(
        moved(p.x, normal.x),
        moved(p.y, normal.y),
        moved(p.z, normal.z),
    )
}

/// Where secondary rays leave a primary hit, and the side of the surface they leave to.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Surface {
    /// The hit point pushed off the surface towards the viewer.
    pub origin: Vec3,
    /// Unit geometric normal turned towards the viewer: secondary rays leave around it.
    pub normal: Vec3,
    /// Unit normal the shading uses: the geometric one, or the interpolated stored normal
    /// ([`Surface::with_attributes`]) on the same side.
    pub shading_normal: Vec3,
    /// Linear RGB the scene's albedo is multiplied by: white, or the interpolated vertex colour.
    pub color: Vec3,
}

impl Surface {
    /// The frame at `hit`, the closest hit of `ray` in `file`, shaded with its geometric normal
    /// and white; `None` only for a hit on a swap window, which the tracer never reports.
    ///
    /// The point is interpolated from the triangle's corners with the hit's weights in f64 and
    /// rounded once, so it is off the plane by at most half a ULP per coordinate, the error the
    /// offset is sized for (Wächter and Binder compute it the same way). `origin + t * direction`
    /// is not: its error scales with the ray origin's magnitude, and with a camera 64 to 128
    /// units away its z steps by 2^-17 or 2^-16, as much as [`ABSOLUTE_OFFSET`], so on a plane
    /// at z = 0 the pushed origins landed on or under it. That was acne on `cad`, whose base
    /// slab's top is at z = 0: in the 256² benchmark image 733 of 4420 primary hits at 300k
    /// triangles (316 of 3448 at 1M) had their AO origin on or behind the surface, and the
    /// engines counted 1.7 to 3.7 times the true number of occluded AO rays (`bench_trace
    /// --check-ao`).
    pub fn at_hit(file: &ReducemFile, ray: &Ray, hit: &Hit) -> Option<Surface> {
        let corners = file
            .strip(hit.strip as usize)
            .window_points(hit.window as usize)?;
        let [a, b, c] = corners.map(|p| DVec3::from(Vec3::from(p)));
        let point = a + (b - a) * f64::from(hit.u) + (c - a) * f64::from(hit.v);
        let facing = Surface::facing(ray, hit);
        Some(Surface {
            origin: offset_origin(point.as_vec3(), facing.normal),
            ..facing
        })
    }

    /// [`Surface::at_hit`] without the point secondary rays leave from, for an image that
    /// traces none and has no point light: its shading reads only the normals and colour, so
    /// the triangle's corners are not read. The origin is NaN: a ray from it would hit nothing.
    pub fn facing(ray: &Ray, hit: &Hit) -> Surface {
        let normal = Vec3::from(hit.normal);
        let normal = if normal.dot(Vec3::from(ray.direction)) > 0.0 {
            -normal
        } else {
            normal
        };
        Surface {
            origin: Vec3::NAN,
            normal,
            shading_normal: normal,
            color: Vec3::ONE,
        }
    }

    /// AO sample `sample_index` of `pixel`: a cosine-weighted direction around the normal, at
    /// most `max_distance` long.
    pub fn ao_ray(&self, seed: u32, pixel: u32, sample_index: u32, max_distance: f32) -> Ray {
        let u1 = sample(seed, pixel, sample_index, 0);
        let u2 = sample(seed, pixel, sample_index, 1);
        Ray {
            origin: self.origin.into(),
            direction: cosine_hemisphere(self.normal, u1, u2).into(),
            tmin: 0.0,
            tmax: max_distance,
        }
    }
}

/// A well-mixed 32-bit hash.
fn mix(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// Uniform number in `[0, 1)` for (seed, pixel, sample, dimension).
pub fn sample(seed: u32, pixel: u32, sample: u32, dimension: u32) -> f32 {
    let h = mix(mix(mix(mix(seed) ^ pixel) ^ sample) ^ dimension);
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Cosine-weighted direction on the hemisphere around unit `normal` from two uniform numbers.
pub fn cosine_hemisphere(normal: Vec3, u1: f32, u2: f32) -> Vec3 {
    let radius = u1.sqrt();
    let angle = std::f32::consts::TAU * u2;
    let height = (1.0 - u1).max(0.0).sqrt();
    let (tangent, bitangent) = normal.any_orthonormal_pair();
    tangent * (radius * angle.cos()) + bitangent * (radius * angle.sin()) + normal * height
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offset_moves_towards_the_normal_at_any_magnitude() {
        for base in [0.0f32, 0.01, 1.0, -3.0, 1e5, -1e5, 1e-20] {
            let p = Vec3::splat(base);
            let up = offset_origin(p, Vec3::Z);
            let down = offset_origin(p, Vec3::NEG_Z);
            assert!(up.z > p.z && down.z < p.z, "at {base}");
            assert_eq!((up.x, up.y), (p.x, p.y));
        }
    }

    #[test]
    fn samples_are_in_range_and_distinct() {
        let values: Vec<f32> = (0..100).map(|i| sample(1, 7, i, 0)).collect();
        assert!(values.iter().all(|v| (0.0..1.0).contains(v)));
        let mut sorted = values.clone();
        sorted.sort_by(f32::total_cmp);
        sorted.dedup();
        assert_eq!(sorted.len(), values.len());
    }

    #[test]
    fn hemisphere_directions_face_the_normal() {
        let normal = Vec3::new(0.3, -0.5, 0.8).normalize();
        for i in 0..64 {
            let d = cosine_hemisphere(normal, sample(2, 0, i, 0), sample(2, 0, i, 1));
            assert!(d.dot(normal) >= 0.0 && (d.length() - 1.0).abs() < 1e-4);
        }
    }
}

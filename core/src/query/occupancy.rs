//! Inside or outside: on a closed mesh the parity of one ray's crossings, exact by the tie
//! rule of [`super::crossings`]; on a mesh that is not closed (or whose closedness is unknown)
//! the majority of `samples` rays in fixed directions, which the answer says is not exact.

use super::crossings::for_each_crossing;
use super::point_order::answer_in_spatial_order;
use crate::format::reader::ReducemFile;
use crate::geometry::Point;
use crate::trace::Ray;

/// Inside/outside of many points.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Occupancy {
    pub inside: Vec<bool>,
    /// The file is closed, so every answer is the exact parity of one ray.
    pub exact: bool,
}

/// Whether each point is inside the surface, in parallel (rayon's current pool): the parity of
/// one ray on a closed file, else the majority of `samples` rays (at least one; a tie is
/// outside). Points are answered in spatial order, so that neighbours' rays share the nodes
/// and strips in cache.
pub fn occupancy(file: &ReducemFile, points: &[Point], samples: u32) -> Occupancy {
    let rays = inside_rays(file, samples);
    let inside = answer_in_spatial_order(points, || (), |_, point| point_inside(file, point, rays));
    Occupancy {
        inside,
        exact: file.closed(),
    }
}

/// The rays that decide inside/outside: one on a closed file (its parity is exact), else
/// `samples` (at least one).
pub fn inside_rays(file: &ReducemFile, samples: u32) -> u32 {
    match file.closed() {
        true => 1,
        false => samples.max(1),
    }
}

/// Whether more than half of `rays` rays from `point` in [`direction`]s `0..rays` cross the
/// surface an odd number of times.
pub fn point_inside(file: &ReducemFile, point: &Point, rays: u32) -> bool {
    let odd = (0..rays)
        .filter(|&sample| {
            let ray = Ray {
                origin: *point,
                direction: direction(sample),
                tmin: 0.0,
                tmax: f32::INFINITY,
            };
            let mut crossings = 0u32;
            for_each_crossing(file, &ray, |_, _, _| crossings += 1);
            crossings % 2 == 1
        })
        .count();
    odd * 2 > rays as usize
}

/// The fixed direction of sample ray `sample`: components from an integer hash, so the same on
/// every machine, and off the axes and diagonals that grids and scans are aligned with.
pub fn direction(sample: u32) -> Point {
    let mut state = u64::from(sample).wrapping_add(0x5eed_0c0c_0bad_cafe);
    loop {
        let bits = splitmix64(&mut state);
        // Three 21-bit integers, each exactly an f32, mapped onto -1..1.
        let component = |shift: u32| ((bits >> shift) & 0x1f_ffff) as f32 / 1_048_576.0 - 1.0;
        let candidate = [component(0), component(21), component(42)];
        let length: f32 = candidate.iter().map(|x| x * x).sum();
        if length > 0.25 && candidate.iter().all(|x| x.abs() > 1.0 / 64.0) {
            return candidate;
        }
    }
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_are_fixed_and_off_the_axes() {
        for sample in 0..64 {
            let d = direction(sample);
            assert_eq!(d, direction(sample));
            assert!(d.iter().all(|x| x.abs() > 1.0 / 64.0 && x.abs() <= 1.0));
        }
        assert_ne!(direction(0), direction(1));
    }
}

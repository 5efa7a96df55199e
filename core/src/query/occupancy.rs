//! Inside or outside: on a closed mesh the parity of one ray's crossings, exact by the tie
//! rule of [`super::crossings`]; on a mesh that is not closed (or whose closedness is unknown)
//! the majority of `samples` rays in fixed directions, which the answer says is not exact.

use arrayvec::ArrayVec;

use super::crossings::{for_each_crossing, for_each_crossing_of_packet, PACKET_RAYS};
use super::point_order::answer_groups_in_spatial_order;
use crate::format::reader::ReducemFile;
use crate::geometry::Point;
use crate::trace::kernel::Kernel;
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
/// outside). Points are answered in spatial order, [`PACKET_RAYS`] neighbours together
/// ([`points_inside`]).
pub fn occupancy(file: &ReducemFile, points: &[Point], samples: u32) -> Occupancy {
    let rays = inside_rays(file, samples);
    let inside = answer_groups_in_spatial_order(points, PACKET_RAYS, |group, inside| {
        points_inside(file, group, rays, inside)
    });
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
                direction: ray_direction(file, point, sample),
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

/// [`point_inside`] of each of `points` (at most [`PACKET_RAYS`]) into `inside`: the rays of
/// one direction walked together, which pays when the points are near one another.
pub fn points_inside(file: &ReducemFile, points: &[Point], rays: u32, inside: &mut [bool]) {
    let kernel = Kernel::configured();
    let mut odd = [0usize; PACKET_RAYS];
    for sample in 0..rays {
        let packet: ArrayVec<Ray, PACKET_RAYS> = points
            .iter()
            .take(PACKET_RAYS)
            .map(|&origin| Ray {
                origin,
                direction: ray_direction(file, &origin, sample),
                tmin: 0.0,
                tmax: f32::INFINITY,
            })
            .collect();
        let mut crossings = [0u32; PACKET_RAYS];
        for_each_crossing_of_packet(file, &packet, kernel, |lane, _, _, _| crossings[lane] += 1);
        for (odd, crossings) in odd.iter_mut().zip(crossings) {
            *odd += (crossings % 2) as usize;
        }
    }
    for (inside, odd) in inside.iter_mut().zip(odd) {
        *inside = odd * 2 > rays as usize;
    }
}

/// The direction of ray `sample` from `point`: on a closed file, whose parity is exact in any
/// direction, the one of [`EXIT_CHOICES`] fixed directions and their opposites that leaves the
/// model's bounds soonest (a shorter ray walks fewer nodes and strips); else
/// [`direction`]`(sample)`.
pub fn ray_direction(file: &ReducemFile, point: &Point, sample: u32) -> Point {
    if !file.closed() {
        return direction(sample);
    }
    let header = file.header();
    let exit = |d: &Point| -> f32 {
        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        (0..3)
            .map(|axis| {
                let plane = match d[axis] > 0.0 {
                    true => header.bounds_max[axis],
                    false => header.bounds_min[axis],
                };
                ((plane - point[axis]) / d[axis]).max(0.0)
            })
            .fold(f32::INFINITY, f32::min)
            * length
    };
    let mut best = direction(0);
    let mut shortest = exit(&best);
    for candidate in (0..EXIT_CHOICES).flat_map(|k| {
        let d = direction(k);
        [d, d.map(|x| -x)]
    }) {
        let reach = exit(&candidate);
        if reach < shortest {
            (best, shortest) = (candidate, reach);
        }
    }
    best
}

/// Fixed directions (each also reversed) a closed file's ray may take: more make rays shorter
/// but less often shared by a packet's lanes, and cost more to choose.
const EXIT_CHOICES: u32 = 2;

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

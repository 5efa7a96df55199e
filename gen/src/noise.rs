//! Deterministic, stateless noise and random numbers for the generators.
//!
//! Everything is derived by hashing `(seed, integer coordinates)`, so any
//! chunk can be regenerated independently and identically on any thread.
//! The noise is value noise (random values at lattice nodes, blended with a
//! quintic fade so the surface has continuous curvature) summed over octaves.
//!
//! Surface generators sample noise on regular grids row by row, so `Fbm2`
//! hashes each octave once per row (`Fbm2::row`) and leaves a cheap 1D blend
//! per vertex: hashing per vertex would dominate the generation time.

use reducem::splitmix::{mix, SplitMix64, GAMMA};

/// A 64-bit hash of a seed and a sequence of integer keys.
pub fn hash(seed: u64, keys: &[i64]) -> u64 {
    keys.iter()
        .fold(mix(seed ^ GAMMA), |h, &key| mix(h ^ key as u64))
}

/// A uniform value in [-1, 1) for a lattice node.
pub fn lattice_value(seed: u64, node: &[i64]) -> f32 {
    (hash(seed, node) >> 40) as f32 * (2.0 / (1u64 << 24) as f32) - 1.0
}

/// Quintic fade: zero first and second derivative at 0 and 1.
pub fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// A small deterministic random stream for sequential decisions.
pub struct Rng(SplitMix64);

impl Rng {
    pub fn new(seed: u64, stream: u64) -> Self {
        Rng(SplitMix64::new(hash(seed, &[stream as i64])))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.unit()
    }

    /// Log-uniform in [low, high]: every order of magnitude equally likely.
    pub fn log_range(&mut self, low: f64, high: f64) -> f64 {
        (low.ln() + (high.ln() - low.ln()) * self.unit()).exp()
    }
}

/// Fractal value noise over the unit square, periodic in both directions so
/// it wraps seamlessly around a torus (and tiles for a heightfield).
pub struct Fbm2 {
    seed: u64,
    /// Lattice cells across the square at the coarsest octave, per axis.
    base_cells: [i64; 2],
    octaves: u32,
}

/// The noise restricted to one value of the first coordinate.
pub struct Fbm2Row {
    octaves: Vec<OctaveRow>,
}

struct OctaveRow {
    /// Node values along the second axis, already blended along the first.
    nodes: Vec<f32>,
    amplitude: f64,
}

impl Fbm2 {
    pub fn new(seed: u64, base_cells: [i64; 2], octaves: u32) -> Self {
        Fbm2 {
            seed,
            base_cells,
            octaves,
        }
    }

    /// Precomputes the row at `u` in [0, 1].
    pub fn row(&self, u: f64) -> Fbm2Row {
        // Amplitudes halve per octave; normalising keeps the sum in [-1, 1].
        let total_amplitude: f64 = (0..self.octaves).map(|o| 0.5f64.powi(o as i32)).sum();
        let octaves = (0..self.octaves)
            .map(|octave| {
                let [cells_u, cells_v] = self.base_cells.map(|cells| cells << octave);
                let x = u * cells_u as f64;
                let column = x.floor().min(cells_u as f64 - 1.0);
                let weight = fade(x - column) as f32;
                let column = column as i64;
                let seed = self.seed.wrapping_add(octave as u64);
                let nodes = (0..=cells_v)
                    .map(|node| {
                        let wrapped = node % cells_v;
                        let low = lattice_value(seed, &[column, wrapped]);
                        let high = lattice_value(seed, &[(column + 1) % cells_u, wrapped]);
                        low + (high - low) * weight
                    })
                    .collect();
                OctaveRow {
                    nodes,
                    amplitude: 0.5f64.powi(octave as i32) / total_amplitude,
                }
            })
            .collect();
        Fbm2Row { octaves }
    }
}

impl Fbm2Row {
    /// The noise at `v` in [0, 1], in [-1, 1].
    pub fn at(&self, v: f64) -> f64 {
        self.octaves
            .iter()
            .map(|octave| {
                let cells = (octave.nodes.len() - 1) as f64;
                let y = v * cells;
                let node = y.floor().min(cells - 1.0);
                let weight = fade(y - node);
                let node = node as usize;
                let low = octave.nodes[node] as f64;
                let high = octave.nodes[node + 1] as f64;
                octave.amplitude * (low + (high - low) * weight)
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periodic_noise_wraps_and_stays_in_range() {
        let noise = Fbm2::new(5, [3, 2], 5);
        for u in [0.0, 0.13, 0.5, 0.999] {
            let row = noise.row(u);
            assert!((row.at(0.0) - row.at(1.0)).abs() < 1e-6);
            for step in 0..100 {
                assert!(row.at(step as f64 / 100.0).abs() <= 1.0);
            }
        }
        let (first, last) = (noise.row(0.0), noise.row(1.0));
        assert!((first.at(0.3) - last.at(0.3)).abs() < 1e-6);
    }

    #[test]
    fn seeds_change_the_noise() {
        let (a, b) = (Fbm2::new(1, [4, 4], 3), Fbm2::new(2, [4, 4], 3));
        assert_ne!(a.row(0.4).at(0.6), b.row(0.4).at(0.6));
    }
}

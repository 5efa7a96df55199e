//! SplitMix64 (Steele, Lea and Flood, 2014): the project's one small deterministic generator,
//! behind the mesh generators' streams, the tests' random inputs and the fuzzer's mutations.
//! One `u64` of state, so a stream is reproduced from its seed alone and failures replay.

/// The SplitMix64 output function: a 64-bit avalanche finaliser, also a good hash of one word.
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A hash of a few words: each pair of them folded in with one multiply, the sum finished by
/// [`mix`]. The one hash of positions (as their bit patterns) and of edges between them, in
/// tables, sets, partitions and maps alike.
pub fn hash_words(words: &[u32]) -> u64 {
    let pairs = words.chunks(2).map(|pair| {
        let high = pair.get(1).copied().unwrap_or(0);
        u64::from(pair[0]) | u64::from(high) << 32
    });
    mix(pairs.fold(0, fold_pair))
}

fn fold_pair(state: u64, pair: u64) -> u64 {
    (state.rotate_left(5) ^ pair).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95)
}

/// [`hash_words`] for hash maps: a key is hashed as its little-endian bytes read as 32-bit words,
/// the last padded with zeros. SipHash, the default, costs more than the rest of reading a
/// binary STL facet.
#[derive(Default)]
pub struct WordHasher(u64);

impl std::hash::Hasher for WordHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut pair = [0u8; 8];
            pair[..chunk.len()].copy_from_slice(chunk);
            self.0 = fold_pair(self.0, u64::from_le_bytes(pair));
        }
    }

    fn finish(&self) -> u64 {
        mix(self.0)
    }
}

/// The golden-ratio increment of the state.
pub const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GAMMA);
        mix(self.0)
    }

    /// Uniform in `0..n` (`n > 0`), up to the modulo bias, negligible for small `n`.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// True once in `one_in` draws on average.
    pub fn chance(&mut self, one_in: usize) -> bool {
        self.below(one_in) == 0
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    /// Uniform in `[0, 1)` on a grid of 2^-24, so every value is an exact `f32`.
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hasher_folds_bytes_as_hash_words_folds_their_words() {
        use std::hash::Hasher;
        let words = [0x3f80_0000u32, 0x8000_0000, 0x0100_0007];
        let mut hasher = WordHasher::default();
        hasher.write(&bytemuck::cast_slice::<u32, u8>(&words)[..11]);
        assert_eq!(hasher.finish(), hash_words(&[words[0], words[1], 7]));
        assert_ne!(
            hash_words(&words),
            hash_words(&[words[1], words[0], words[2]])
        );
    }

    #[test]
    fn first_outputs_match_the_reference_implementation() {
        // Seed 0 of Vigna's splitmix64.c.
        let mut rng = SplitMix64::new(0);
        assert_eq!(rng.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(rng.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }
}

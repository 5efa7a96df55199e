//! Strip-RT step 3, ordering (paper 4.1, "Ordering"): greedy, hierarchy-guided merging of
//! triangle sequences.
//!
//! Representation: a sequence is a path of triangles. Every triangle stores up to two path
//! links; the two end triangles of a sequence also store the other end, the sequence length and
//! the sequence's hierarchy node (values at interior triangles are stale and never read). Merging
//! two sequences is then O(1): link the two touching ends and update the two outer ends. The
//! paper's explicit per-sequence triangle lists, four open-edge pointers and triangle → sequence
//! pointers are all implied by this: an end's open edges are its edges to a neighbour that is
//! not already a path link, and "same sequence" is `other_end` equality. Memory is 28 bytes per
//! triangle (links, other end, length, node, merge stamp, option count), plus each round's
//! candidate list.
//!
//! Each round collects all candidate pairs (end `t`, neighbouring end `u` of another sequence,
//! combined length within the maximum) in parallel, sorts them by `(urgency, score, t, edge)`
//! and accepts them greedily when neither sequence has merged yet in this round. The paper's
//! part of the score weighs its two criteria equally (lower is better):
//! `0.5 * relative tree distance + 0.5 * (1 - balance)`, where the relative tree distance is
//! the path length between the sequences' nodes through their lowest common ancestor divided by
//! the sum of their depths, and balance is the harmonic mean of the two lengths relative to
//! their arithmetic mean, `4ab / (a + b)^2`, which is 1 for equal lengths.
//!
//! Deviations from the paper, which ranks each sequence's options by the score but does not say
//! how conflicts between sequences (two wanting the same partner) are resolved:
//! - Conflicts are resolved by one globally sorted candidate list per round, which is
//!   deterministic and independent of thread scheduling.
//! - The sort puts urgency first: the number of options (candidates over both ends) of the more
//!   constrained of the two sequences, in levels 1, 2, 3 and more. A merge turns both touching
//!   ends into interior triangles, so a sequence whose only option is taken by someone else is
//!   stuck at its length forever; serving the most constrained sequences first is the classic
//!   min-degree heuristic for greedy matchings; it nearly removes single-triangle strips on
//!   curved meshes (docs/BENCHMARKS.md, "Strip ordering"). The price is that a sequence may
//!   take a worse-scored partner that would otherwise be stranded.
//! - The score has a third criterion, swaps: `(paper score + w * new swaps / 3) / (1 + w)`
//!   with `w` = [`SWAP_WEIGHT`]. Every swap costs a window in the strip, so a bound slot in its
//!   implicit kd-tree (often a duplicated vertex) and a wasted window test in the tracer. A
//!   link makes `t` and `u` interior triangles (those whose sequence is longer than one) and so
//!   fixes their turns, and the output needs a swap between two consecutive interior triangles
//!   with equal turns (see `output`); a link therefore adds 0 to 3 swaps, known from `t`, `u`
//!   and their path neighbours alone. `w` = 1 weighs swaps like the paper's two criteria
//!   together, where the gain in fewer swaps stops growing (docs/BENCHMARKS.md, "Strip
//!   ordering").
//!
//! Memory: candidates are packed into 8 bytes (see [`Candidate`]), written in place into a
//! list counted beforehand, and sorted in place by an unstable sort (keys are unique, so the
//! order is deterministic); the lowest common ancestor is recomputed when a merge is accepted
//! instead of being stored, so the first round's list is the smallest part of the peak
//! (docs/BENCHMARKS.md, "Stripifier memory"). A radix sort of the packed keys would need a
//! buffer as large as the list and was no faster.
//!
//! Candidates only ever disappear (merging shortens nothing and only removes ends), so an end
//! without candidates is final and leaves the active set for good; rounds shrink quickly.

use rayon::prelude::*;

use super::adjacency::{Adjacency, NO_NEIGHBOUR};
use super::partition::TriangleTree;

/// Marks an unused path link slot.
pub(crate) const NO_LINK: u32 = u32::MAX;

/// The sequences found by the ordering step, as paths over local triangles.
#[derive(Clone, Debug, Default)]
pub(crate) struct Paths {
    /// Up to two path neighbours per triangle, [`NO_LINK`] for unused slots.
    pub links: Vec<[u32; 2]>,
    /// For a path end, the triangle at the path's other end (itself for a single triangle).
    /// Meaningless for interior triangles.
    pub other_end: Vec<u32>,
}

impl Paths {
    pub(crate) fn is_end(&self, triangle: u32) -> bool {
        self.links[triangle as usize][1] == NO_LINK
    }
}

/// A possible merge of the sequences ending at `t` and at its neighbour `u` across edge
/// `edge` of `t`, packed into one integer whose order is the acceptance order
/// `(urgency, score, t, edge)`: bits 62–63 urgency, 33–61 score, 2–32 `t`, 0–1 `edge`. `t < u`,
/// so each pair is listed once. Eight bytes instead of four `u32` fields halve the round's
/// candidate list, and unique keys let an in-place unstable sort give a deterministic order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Candidate(u64);

/// Urgency levels: the option count of the more constrained sequence, 1, 2, 3 or more.
const URGENCY_LEVELS: u32 = 4;
const URGENCY_SHIFT: u32 = 62;
const SCORE_SHIFT: u32 = 33;
const TRIANGLE_SHIFT: u32 = 2;
const EDGE_MASK: u64 = (1 << TRIANGLE_SHIFT) - 1;
const TRIANGLE_MASK: u64 = (1 << (SCORE_SHIFT - TRIANGLE_SHIFT)) - 1;

impl Candidate {
    /// Scores lie in `[0, 1]`, so their bit patterns order like the values and stay below
    /// `1 << 30`; the lowest mantissa bit is dropped to fit 29 bits (ties then fall to `t`).
    /// Local triangle ids fit 31 bits because [`super::adjacency::MAX_TRIANGLES`] is below
    /// `1 << 31`.
    fn new(score: f32, t: u32, edge: usize) -> Candidate {
        let score_bits = u64::from(score.to_bits() >> 1);
        Candidate((score_bits << SCORE_SHIFT) | (u64::from(t) << TRIANGLE_SHIFT) | edge as u64)
    }

    fn with_urgency(self, urgency: u32) -> Candidate {
        let without = self.0 & !(u64::MAX << URGENCY_SHIFT);
        Candidate(without | (u64::from(urgency) << URGENCY_SHIFT))
    }

    fn t(self) -> u32 {
        ((self.0 >> TRIANGLE_SHIFT) & TRIANGLE_MASK) as u32
    }

    fn edge(self) -> usize {
        (self.0 & EDGE_MASK) as usize
    }
}

/// The ordering state; see the module docs for the representation.
struct Sequences<'a> {
    adjacency: &'a Adjacency,
    hierarchy: &'a TriangleTree,
    max_length: u32,
    paths: Paths,
    /// Sequence length, valid at sequence ends.
    length: Vec<u32>,
    /// Sequence hierarchy node, valid at sequence ends.
    node: Vec<u32>,
    /// Round stamp of the last round in which a triangle's sequence merged.
    merged_in_round: Vec<u32>,
    /// Number of candidates of each active end in the current round.
    options: Vec<u32>,
}

/// Greedily merges all triangles into sequences of at most `max_length` (at least 1) triangles.
pub(crate) fn order(adjacency: &Adjacency, hierarchy: &TriangleTree, max_length: usize) -> Paths {
    let mut sequences = Sequences::new(adjacency, hierarchy, max_length);
    // Ascending, which `retain` preserves; candidate collection relies on it.
    let mut active: Vec<u32> = (0..adjacency.kept.len() as u32).collect();
    let mut round = 0;
    while !active.is_empty() {
        round += 1;
        let mut candidates = sequences.collect_candidates(&active);
        sequences.count_options(&active, &candidates);
        sequences.set_urgencies(&mut candidates);
        candidates.par_sort_unstable();
        sequences.merge_greedily(&candidates, round);
        active.retain(|&t| sequences.options[t as usize] > 0 && sequences.paths.is_end(t));
    }
    sequences.paths
}

/// Weight of the swap criterion relative to the paper's two criteria together; see the module
/// docs for the measurements behind it.
const SWAP_WEIGHT: f64 = 1.0;
/// A link fixes at most two turns and so decides at most three consecutive pairs.
const MAX_NEW_SWAPS: f64 = 3.0;

/// Active ends per block of candidate collection: large enough to amortise task overhead.
const COLLECTION_BLOCK: usize = 4096;

impl<'a> Sequences<'a> {
    /// Every triangle a sequence of its own.
    fn new(adjacency: &'a Adjacency, hierarchy: &'a TriangleTree, max_length: usize) -> Self {
        let n = adjacency.kept.len();
        Sequences {
            adjacency,
            hierarchy,
            max_length: max_length.clamp(1, u32::MAX as usize) as u32,
            paths: Paths {
                links: vec![[NO_LINK; 2]; n],
                other_end: (0..n as u32).collect(),
            },
            length: vec![1; n],
            node: (0..n as u32).map(|t| hierarchy.leaf_of(t)).collect(),
            merged_in_round: vec![0; n],
            options: vec![0; n],
        }
    }
}

impl Sequences<'_> {
    /// All candidates of the (ascending) `active` ends. Blocks are counted first and then
    /// filled in place, so the list is allocated once at its final size: collecting an
    /// iterator of unknown length in parallel would hold every candidate twice while the
    /// per-thread pieces are concatenated.
    fn collect_candidates(&self, active: &[u32]) -> Vec<Candidate> {
        let blocks: Vec<&[u32]> = active.chunks(COLLECTION_BLOCK).collect();
        let counts: Vec<usize> = blocks
            .par_iter()
            .map(|block| block.iter().map(|&t| self.partners_at(t).count()).sum())
            .collect();
        let mut candidates = vec![Candidate(0); counts.iter().sum()];
        let mut rest = candidates.as_mut_slice();
        let mut outputs = Vec::with_capacity(blocks.len());
        for count in counts {
            let (block_output, tail) = std::mem::take(&mut rest).split_at_mut(count);
            outputs.push(block_output);
            rest = tail;
        }
        blocks.par_iter().zip(outputs).for_each(|(block, output)| {
            let block_candidates = block.iter().flat_map(|&t| self.candidates_at(t));
            for (slot, candidate) in output.iter_mut().zip(block_candidates) {
                *slot = candidate;
            }
        });
        candidates
    }

    /// Edges of end `t` toward a larger partner `u` it can merge with (the smaller end lists
    /// the pair), as `(edge, u)`.
    fn partners_at(&self, t: u32) -> impl Iterator<Item = (usize, u32)> + '_ {
        let links = self.paths.links[t as usize];
        self.adjacency.neighbours[t as usize]
            .into_iter()
            .enumerate()
            .filter(move |&(_, u)| u != NO_NEIGHBOUR && u > t && !links.contains(&u))
            .filter(move |&(_, u)| self.can_merge(t, u))
    }

    fn candidates_at(&self, t: u32) -> impl Iterator<Item = Candidate> + '_ {
        self.partners_at(t)
            .map(move |(edge, u)| Candidate::new(self.score(t, u), t, edge))
    }

    /// Whether the ends `t` and its neighbour `u` belong to different sequences that fit
    /// together within the maximum length.
    fn can_merge(&self, t: u32, u: u32) -> bool {
        let (t, u) = (t as usize, u as usize);
        self.paths.links[u][1] == NO_LINK
            && self.paths.other_end[t] != u as u32
            && self.length[t] + self.length[u] <= self.max_length
    }

    /// The merge score in `[0, 1]`, lower is better; see the module docs.
    fn score(&self, t: u32, u: u32) -> f32 {
        let hierarchy_score =
            0.5 * self.relative_tree_distance(t, u) + 0.5 * (1.0 - self.balance(t, u));
        let swap_score = f64::from(self.new_swaps(t, u)) / MAX_NEW_SWAPS;
        let score = (hierarchy_score + SWAP_WEIGHT * swap_score) / (1.0 + SWAP_WEIGHT);
        score.clamp(0.0, 1.0) as f32
    }

    /// Path length between the sequences' nodes through their lowest common ancestor, divided
    /// by the sum of their depths.
    fn relative_tree_distance(&self, t: u32, u: u32) -> f64 {
        let (a, b) = (self.node[t as usize], self.node[u as usize]);
        let common = self.hierarchy.lowest_common_ancestor(a, b);
        let depth_sum = (self.hierarchy.depth(a) + self.hierarchy.depth(b)) as f64;
        let tree_distance = depth_sum - 2.0 * self.hierarchy.depth(common) as f64;
        if depth_sum == 0.0 {
            0.0
        } else {
            tree_distance / depth_sum
        }
    }

    /// Harmonic mean of the two lengths relative to their arithmetic mean, 1 for equal lengths.
    fn balance(&self, t: u32, u: u32) -> f64 {
        let (a, b) = (
            self.length[t as usize] as f64,
            self.length[u as usize] as f64,
        );
        4.0 * a * b / ((a + b) * (a + b))
    }

    /// Number of swaps that linking `t` to `u` adds to the strip output. The link fixes the
    /// turns of `t` and `u` (of those that become interior triangles), and the strip needs a
    /// swap between two consecutive interior triangles exactly when their turns are equal
    /// (see `output`). Turns are taken along the direction `t`'s sequence → `u`'s sequence.
    fn new_swaps(&self, t: u32, u: u32) -> u32 {
        let before_t = self.path_neighbour(t);
        let after_u = self.path_neighbour(u);
        let turns = [
            before_t.and_then(|p| {
                Some(
                    self.adjacency
                        .turn(self.path_neighbour_besides(p, t)?, p, t),
                )
            }),
            before_t.map(|p| self.adjacency.turn(p, t, u)),
            after_u.map(|n| self.adjacency.turn(t, u, n)),
            after_u.and_then(|n| {
                Some(
                    self.adjacency
                        .turn(u, n, self.path_neighbour_besides(n, u)?),
                )
            }),
        ];
        turns
            .windows(2)
            .filter(|pair| pair[0].is_some() && pair[0] == pair[1])
            .count() as u32
    }

    /// The path neighbour of the end `t`, if its sequence is longer than one triangle.
    fn path_neighbour(&self, t: u32) -> Option<u32> {
        let first = self.paths.links[t as usize][0];
        (first != NO_LINK).then_some(first)
    }

    /// The path neighbour of `triangle` other than `neighbour`, if any.
    fn path_neighbour_besides(&self, triangle: u32, neighbour: u32) -> Option<u32> {
        let [first, second] = self.paths.links[triangle as usize];
        let other = if first == neighbour { second } else { first };
        (other != NO_LINK).then_some(other)
    }

    /// Counts the candidates of every active end. Both ends of every candidate are active: an
    /// end leaves the active set only once it has no candidates, and candidates never reappear.
    fn count_options(&mut self, active: &[u32], candidates: &[Candidate]) {
        for &t in active {
            self.options[t as usize] = 0;
        }
        for &candidate in candidates {
            let (t, u) = self.ends(candidate);
            self.options[t as usize] += 1;
            self.options[u as usize] += 1;
        }
    }

    fn ends(&self, candidate: Candidate) -> (u32, u32) {
        let t = candidate.t();
        (t, self.adjacency.neighbours[t as usize][candidate.edge()])
    }

    /// Options of the whole sequence ending at `t`, over both of its ends. An end that left the
    /// active set still counts zero from the round it left.
    fn sequence_options(&self, t: u32) -> u32 {
        let other = self.paths.other_end[t as usize];
        let other_options = if other == t {
            0
        } else {
            self.options[other as usize]
        };
        self.options[t as usize] + other_options
    }

    /// Ranks each candidate by the option count of its more constrained sequence.
    fn set_urgencies(&self, candidates: &mut [Candidate]) {
        candidates.par_iter_mut().for_each(|candidate| {
            let (t, u) = self.ends(*candidate);
            let fewest = self.sequence_options(t).min(self.sequence_options(u));
            *candidate = candidate.with_urgency(fewest.min(URGENCY_LEVELS) - 1);
        });
    }

    /// Accepts sorted candidates whose sequences have not merged yet in this `round`.
    fn merge_greedily(&mut self, sorted: &[Candidate], round: u32) {
        for &candidate in sorted {
            let (t, u) = self.ends(candidate);
            if self.merged_in_round[t as usize] != round
                && self.merged_in_round[u as usize] != round
            {
                self.merge(t, u, round);
            }
        }
    }

    /// Links end `t` to end `u`; the outer ends of both sequences become the new sequence's
    /// ends, and its node is the lowest common ancestor of theirs (paper 4.1). The ancestor is
    /// recomputed here rather than kept from scoring, which would take another four bytes per
    /// candidate; only accepted candidates pay for the walk.
    fn merge(&mut self, t: u32, u: u32, round: u32) {
        let (outer_t, outer_u) = (
            self.paths.other_end[t as usize],
            self.paths.other_end[u as usize],
        );
        for triangle in [t, u, outer_t, outer_u] {
            self.merged_in_round[triangle as usize] = round;
        }
        self.add_link(t, u);
        self.add_link(u, t);
        let length = self.length[t as usize] + self.length[u as usize];
        let node = self
            .hierarchy
            .lowest_common_ancestor(self.node[t as usize], self.node[u as usize]);
        for (end, other) in [(outer_t, outer_u), (outer_u, outer_t)] {
            self.paths.other_end[end as usize] = other;
            self.length[end as usize] = length;
            self.node[end as usize] = node;
        }
    }

    fn add_link(&mut self, from: u32, to: u32) {
        let links = &mut self.paths.links[from as usize];
        let free = if links[0] == NO_LINK { 0 } else { 1 };
        links[free] = to;
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::mesh::Mesh;

    /// Deterministic xorshift generator.
    pub struct XorShift(pub u64);

    impl XorShift {
        pub fn below(&mut self, bound: u64) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0 % bound
        }
    }

    /// A `side` × `side` quad grid, consistently wound, each quad split along a random diagonal
    /// and a few quads left out, so paths turn irregularly and meet holes.
    pub fn random_grid(side: u32, seed: u64) -> Mesh {
        let mut rng = XorShift(seed);
        let vertex = |x: u32, y: u32| y * (side + 1) + x;
        let mut mesh = Mesh::default();
        for y in 0..=side {
            for x in 0..=side {
                mesh.positions.push([x as f32, y as f32, 0.0]);
            }
        }
        for y in 0..side {
            for x in 0..side {
                let [a, b, c, d] = [
                    vertex(x, y),
                    vertex(x + 1, y),
                    vertex(x + 1, y + 1),
                    vertex(x, y + 1),
                ];
                match rng.below(10) {
                    0 => {}
                    1..5 => mesh.triangles.extend([[a, b, c], [a, c, d]]),
                    _ => mesh.triangles.extend([[a, b, d], [b, c, d]]),
                }
            }
        }
        mesh
    }

    /// Swaps between consecutive interior triangles with equal turns, over all paths.
    fn interior_swaps(adjacency: &Adjacency, paths: &Paths) -> u32 {
        let is_interior = |t: u32| paths.links[t as usize][1] != NO_LINK;
        let other_link =
            |t: u32, link: u32| paths.links[t as usize].into_iter().find(|&n| n != link);
        let mut swaps = 0;
        for middle in (0..paths.links.len() as u32).filter(|&t| is_interior(t)) {
            // Each pair of interior neighbours is seen from its smaller triangle.
            for next in paths.links[middle as usize] {
                if next > middle && is_interior(next) {
                    let before = other_link(middle, next).unwrap();
                    let after = other_link(next, middle).unwrap();
                    let turns = (
                        adjacency.turn(before, middle, next),
                        adjacency.turn(middle, next, after),
                    );
                    swaps += u32::from(turns.0 == turns.1);
                }
            }
        }
        swaps
    }

    /// The local count of `new_swaps` at every merge adds up to the swaps of the final paths.
    #[test]
    fn new_swaps_add_up_to_the_swaps_of_the_paths() {
        for seed in 1..6 {
            let mesh = random_grid(24, seed);
            let adjacency = Adjacency::build(&mesh);
            let hierarchy = TriangleTree::build(&mesh, &adjacency.kept, 8);
            let mut sequences = Sequences::new(&adjacency, &hierarchy, 40);
            let mut rng = XorShift(seed * 7919);
            let (mut predicted, mut round) = (0, 0);
            loop {
                let ends: Vec<u32> = (0..adjacency.kept.len() as u32)
                    .filter(|&t| sequences.paths.is_end(t))
                    .collect();
                let candidates = sequences.collect_candidates(&ends);
                if candidates.is_empty() {
                    break;
                }
                let chosen = candidates[rng.below(candidates.len() as u64) as usize];
                let (t, u) = sequences.ends(chosen);
                predicted += sequences.new_swaps(t, u);
                round += 1;
                sequences.merge(t, u, round);
            }
            assert!(predicted > 0, "random merges should create swaps");
            assert_eq!(predicted, interior_swaps(&adjacency, &sequences.paths));
        }
    }

    #[test]
    fn candidates_sort_by_urgency_score_triangle_edge() {
        let mut rng = XorShift(0x2545_f491_4f6c_dd1d);
        let mut fields: Vec<(u32, f32, u32, usize)> = (0..5000)
            .map(|_| {
                let score = (rng.below(7) as f32 / 6.0) * 0.37f32.powi(rng.below(3) as i32);
                let t = rng.below(super::super::adjacency::MAX_TRIANGLES as u64) as u32;
                (rng.below(4) as u32, score, t, rng.below(3) as usize)
            })
            .collect();
        let mut candidates: Vec<Candidate> = fields
            .iter()
            .map(|&(urgency, score, t, edge)| Candidate::new(score, t, edge).with_urgency(urgency))
            .collect();
        for (candidate, &(_, _, t, edge)) in candidates.iter().zip(&fields) {
            assert_eq!((candidate.t(), candidate.edge()), (t, edge));
        }
        candidates.sort_unstable();
        fields.sort_by(|a, b| {
            (a.0, a.1, a.2, a.3)
                .partial_cmp(&(b.0, b.1, b.2, b.3))
                .unwrap()
        });
        let unpacked: Vec<(u32, usize)> = candidates.iter().map(|c| (c.t(), c.edge())).collect();
        let expected: Vec<(u32, usize)> = fields.iter().map(|f| (f.2, f.3)).collect();
        assert_eq!(unpacked, expected);
    }
}

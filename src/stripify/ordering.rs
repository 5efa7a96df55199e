//! Strip-RT step 3, ordering (paper 4.1, "Ordering"): greedy, hierarchy-guided merging of
//! triangle sequences.
//!
//! Representation: a sequence is a path of triangles. Every triangle stores up to two path
//! links; the two end triangles of a sequence also store the other end, the sequence length and
//! the sequence's hierarchy node (values at interior triangles are stale and never read). Merging
//! two sequences is then O(1): link the two touching ends and update the two outer ends. The
//! paper's explicit per-sequence triangle lists, four open-edge pointers and triangle → sequence
//! pointers are all implied by this: an end's open edges are its edges to a neighbour that is
//! not already a path link, and "same sequence" is `other_end` equality. Memory is 20 bytes per
//! triangle.
//!
//! Each round collects all candidate pairs (end `t`, neighbouring end `u` of another sequence,
//! combined length within the maximum) in parallel, sorts them by `(score, t, u)` and accepts
//! them greedily when neither sequence has merged yet in this round. The score weighs the
//! paper's two criteria equally (lower is better):
//! `0.5 * relative tree distance + 0.5 * (1 - balance)`, where the relative tree distance is
//! the path length between the sequences' nodes through their lowest common ancestor divided by
//! the sum of their depths, and balance is the harmonic mean of the two lengths relative to
//! their arithmetic mean, `4ab / (a + b)^2`, which is 1 for equal lengths.
//!
//! Deviation from the paper: the paper lets each sequence pick its best partner; accepting a
//! globally sorted candidate list per round resolves conflicts (two sequences wanting the same
//! partner) deterministically and independently of thread scheduling. Candidates only ever
//! disappear (merging shortens nothing and only removes ends), so an end without candidates is
//! final and leaves the active set for good; rounds shrink quickly.

use rayon::prelude::*;

use super::adjacency::{Adjacency, NO_NEIGHBOUR};
use super::partition::Hierarchy;

/// Marks an unused path link slot.
pub const NO_LINK: u32 = u32::MAX;

/// The sequences found by the ordering step, as paths over local triangles.
#[derive(Clone, Debug, Default)]
pub struct Paths {
    /// Up to two path neighbours per triangle, [`NO_LINK`] for unused slots.
    pub links: Vec<[u32; 2]>,
    /// For a path end, the triangle at the path's other end (itself for a single triangle).
    /// Meaningless for interior triangles.
    pub other_end: Vec<u32>,
}

impl Paths {
    pub fn is_end(&self, triangle: u32) -> bool {
        self.links[triangle as usize][1] == NO_LINK
    }
}

/// A possible merge of the sequences ending at `t` and `u`; `t < u` so each pair is listed once.
/// Field order gives the acceptance order `(score, t, u)`; scores are non-negative, so their
/// bit patterns order like the values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Candidate {
    score_bits: u32,
    t: u32,
    u: u32,
}

struct Sequences<'a> {
    adjacency: &'a Adjacency,
    hierarchy: &'a Hierarchy,
    max_length: u32,
    paths: Paths,
    length: Vec<u32>,
    node: Vec<u32>,
    /// Round stamp of the last round in which a triangle's sequence merged.
    merged_in_round: Vec<u32>,
    /// Round stamp of the last round in which a triangle was part of a candidate.
    candidate_in_round: Vec<u32>,
}

/// Greedily merges all triangles into sequences of at most `max_length` (at least 1) triangles.
pub fn order(adjacency: &Adjacency, hierarchy: &Hierarchy, max_length: usize) -> Paths {
    let n = adjacency.kept.len();
    let mut sequences = Sequences {
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
        candidate_in_round: vec![0; n],
    };
    let mut active: Vec<u32> = (0..n as u32).collect();
    let mut round = 0;
    while !active.is_empty() {
        round += 1;
        let mut candidates = sequences.collect_candidates(&active);
        candidates.par_sort_unstable();
        sequences.merge_greedily(&candidates, round);
        active.retain(|&t| {
            sequences.candidate_in_round[t as usize] == round && sequences.paths.is_end(t)
        });
    }
    sequences.paths
}

impl Sequences<'_> {
    fn collect_candidates(&self, active: &[u32]) -> Vec<Candidate> {
        active
            .par_iter()
            .flat_map_iter(|&t| self.candidates_at(t))
            .collect()
    }

    /// Candidates of end `t` with a larger partner `u` (the smaller end lists the pair).
    fn candidates_at(&self, t: u32) -> impl Iterator<Item = Candidate> + '_ {
        let links = self.paths.links[t as usize];
        self.adjacency.neighbours[t as usize]
            .into_iter()
            .filter(move |&u| u != NO_NEIGHBOUR && u > t && !links.contains(&u))
            .filter(move |&u| self.can_merge(t, u))
            .map(move |u| Candidate {
                score_bits: self.score(t, u).to_bits(),
                t,
                u,
            })
    }

    /// Whether the ends `t` and its neighbour `u` belong to different sequences that fit
    /// together within the maximum length.
    fn can_merge(&self, t: u32, u: u32) -> bool {
        let (t, u) = (t as usize, u as usize);
        self.paths.links[u][1] == NO_LINK
            && self.paths.other_end[t] != u as u32
            && self.length[t] + self.length[u] <= self.max_length
    }

    fn score(&self, t: u32, u: u32) -> f32 {
        let (a, b) = (self.node[t as usize], self.node[u as usize]);
        let common = self.hierarchy.lowest_common_ancestor(a, b);
        let depth_sum = (self.hierarchy.depth(a) + self.hierarchy.depth(b)) as f64;
        let tree_distance = depth_sum - 2.0 * self.hierarchy.depth(common) as f64;
        let relative_tree_distance = if depth_sum == 0.0 {
            0.0
        } else {
            tree_distance / depth_sum
        };
        let (a_len, b_len) = (
            self.length[t as usize] as f64,
            self.length[u as usize] as f64,
        );
        let balance = 4.0 * a_len * b_len / ((a_len + b_len) * (a_len + b_len));
        (0.5 * relative_tree_distance + 0.5 * (1.0 - balance)).max(0.0) as f32
    }

    /// Accepts sorted candidates whose sequences have not merged yet in this `round`.
    fn merge_greedily(&mut self, sorted: &[Candidate], round: u32) {
        for candidate in sorted {
            let (t, u) = (candidate.t as usize, candidate.u as usize);
            self.candidate_in_round[t] = round;
            self.candidate_in_round[u] = round;
            if self.merged_in_round[t] != round && self.merged_in_round[u] != round {
                self.merge(candidate.t, candidate.u, round);
            }
        }
    }

    /// Links end `t` to end `u`; the outer ends of both sequences become the new sequence's ends.
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

//! Step one of the build: a binary bounding volume hierarchy over strip bounds, SAH (binned
//! for large subtrees, every position for small ones) down to one strip per leaf (the collapse
//! chooses which subtrees become leaves), median splits below a depth limit.

use super::TopLevelParams;
use crate::geometry::Aabb;

/// A node of the binary SAH hierarchy, before it is collapsed into wide nodes.
#[derive(Clone, Copy, Debug)]
pub(super) struct BinaryNode {
    pub(super) bounds: Aabb,
    pub(super) kind: BinaryKind,
}

#[derive(Clone, Copy, Debug)]
pub(super) enum BinaryKind {
    /// Strips `first .. first + count` in leaf order.
    Leaf {
        first: u32,
        count: u32,
    },
    Internal {
        left: usize,
        right: usize,
    },
}

/// The binary hierarchy in preorder (empty without strips) and the strips in leaf order.
pub(super) fn build_binary(
    bounds: &[Aabb],
    params: &TopLevelParams,
) -> (Vec<BinaryNode>, Vec<u32>) {
    let mut builder = Builder {
        bounds,
        params,
        centroids: bounds
            .iter()
            .map(|b| [0, 1, 2].map(|a| b.centroid(a)))
            .collect(),
        nodes: Vec::with_capacity(bounds.len() * 2),
    };
    let mut order: Vec<u32> = (0..bounds.len() as u32).collect();
    if !order.is_empty() {
        builder.subtree(&mut order, 0, 0);
    }
    (builder.nodes, order)
}

struct Builder<'a> {
    bounds: &'a [Aabb],
    params: &'a TopLevelParams,
    centroids: Vec<[f32; 3]>,
    nodes: Vec<BinaryNode>,
}

/// Subtrees of at most this many strips try every split position instead of binning: the
/// exact sweep's tighter boxes cost a sort per axis, cheap on a subtree this small.
pub(super) const SWEEP_STRIPS: usize = 4096;
/// Below this depth splits are SAH; deeper ones are median splits, which bound the depth at
/// `SAH_DEPTH_LIMIT + log2(strips)`, well inside the reader's [`crate::format::MAX_TOP_DEPTH`].
const SAH_DEPTH_LIMIT: usize = 48;

struct Split {
    axis: usize,
    cut: Cut,
    cost: f64,
}

/// Which strips of a split go left.
#[derive(Clone, Copy)]
enum Cut {
    /// Those with a centroid bin below this.
    Bin(usize),
    /// The first this many in centroid order along the axis.
    Sorted(usize),
    /// The lower half in centroid order along the axis.
    Median,
}

impl Builder<'_> {
    /// Emits the subtree over `strips` (whose file positions start at `first`) in preorder.
    fn subtree(&mut self, strips: &mut [u32], first: usize, depth: usize) {
        let bounds = strips
            .iter()
            .fold(Aabb::EMPTY, |b, &s| b.union(&self.bounds[s as usize]));
        let node_index = self.nodes.len();
        let split = if depth < SAH_DEPTH_LIMIT {
            self.best_split(strips, &bounds)
        } else {
            self.median_split(strips)
        };
        let leaf = BinaryKind::Leaf {
            first: first as u32,
            count: strips.len() as u32,
        };
        self.nodes.push(BinaryNode { bounds, kind: leaf });
        let Some(left_count) = split.as_ref().map(|s| self.partition(strips, s)) else {
            return;
        };
        let (left, right) = strips.split_at_mut(left_count);
        self.subtree(left, first, depth + 1);
        let right_index = self.nodes.len();
        self.subtree(right, first + left_count, depth + 1);
        self.nodes[node_index].kind = BinaryKind::Internal {
            left: node_index + 1,
            right: right_index,
        };
    }

    /// The cheapest SAH split, or a median split when all centroids share a bin.
    fn best_split(&self, strips: &[u32], bounds: &Aabb) -> Option<Split> {
        if strips.len() < 2 {
            return None;
        }
        let centroid_bounds =
            Aabb::from_points(strips.iter().map(|&s| &self.centroids[s as usize]));
        let sweep = strips.len() <= SWEEP_STRIPS;
        let best = (0..3)
            .filter(|&axis| centroid_bounds.extent(axis) > 0.0)
            .filter_map(|axis| {
                if sweep {
                    self.best_sweep_on_axis(strips, axis, bounds)
                } else {
                    self.best_split_on_axis(strips, axis, &centroid_bounds, bounds)
                }
            })
            .min_by(|a, b| a.cost.total_cmp(&b.cost));
        best.or_else(|| self.median_split(strips))
    }

    fn median_split(&self, strips: &[u32]) -> Option<Split> {
        let centroid_bounds =
            Aabb::from_points(strips.iter().map(|&s| &self.centroids[s as usize]));
        (strips.len() >= 2).then(|| Split {
            axis: centroid_bounds.longest_axis(),
            cut: Cut::Median,
            cost: f64::INFINITY,
        })
    }

    fn best_split_on_axis(
        &self,
        strips: &[u32],
        axis: usize,
        centroids: &Aabb,
        bounds: &Aabb,
    ) -> Option<Split> {
        let bins = self.params.bins.max(2);
        let mut bin_bounds = vec![Aabb::EMPTY; bins];
        let mut bin_counts = vec![0usize; bins];
        for &s in strips {
            let bin = self.bin_of(s, axis, centroids, bins);
            bin_bounds[bin].grow(&self.bounds[s as usize]);
            bin_counts[bin] += 1;
        }
        let mut right_area = vec![0.0; bins];
        let mut right_count = vec![0usize; bins];
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        for bin in (1..bins).rev() {
            acc.grow(&bin_bounds[bin]);
            count += bin_counts[bin];
            right_area[bin] = acc.surface_area();
            right_count[bin] = count;
        }
        let parent_area = bounds.surface_area().max(f64::MIN_POSITIVE);
        let (mut acc, mut count) = (Aabb::EMPTY, 0);
        let mut best: Option<Split> = None;
        for bin in 1..bins {
            acc.grow(&bin_bounds[bin - 1]);
            count += bin_counts[bin - 1];
            if count == 0 || right_count[bin] == 0 {
                continue;
            }
            let cost = (acc.surface_area() * count as f64
                + right_area[bin] * right_count[bin] as f64)
                / parent_area;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(Split {
                    axis,
                    cut: Cut::Bin(bin),
                    cost,
                });
            }
        }
        best
    }

    /// The cheapest split of `strips` in centroid order along `axis`, every position tried.
    fn best_sweep_on_axis(&self, strips: &[u32], axis: usize, bounds: &Aabb) -> Option<Split> {
        let mut sorted = strips.to_vec();
        self.sort_along(&mut sorted, axis);
        let mut right_area = vec![0.0; sorted.len()];
        let mut acc = Aabb::EMPTY;
        for i in (1..sorted.len()).rev() {
            acc.grow(&self.bounds[sorted[i] as usize]);
            right_area[i] = acc.surface_area();
        }
        let parent_area = bounds.surface_area().max(f64::MIN_POSITIVE);
        let mut acc = Aabb::EMPTY;
        let mut best: Option<Split> = None;
        for left in 1..sorted.len() {
            acc.grow(&self.bounds[sorted[left - 1] as usize]);
            let right = sorted.len() - left;
            let cost =
                (acc.surface_area() * left as f64 + right_area[left] * right as f64) / parent_area;
            if best.as_ref().is_none_or(|b| cost < b.cost) {
                best = Some(Split {
                    axis,
                    cut: Cut::Sorted(left),
                    cost,
                });
            }
        }
        best
    }

    /// Sorts by centroid along `axis`, ties broken by strip id.
    fn sort_along(&self, strips: &mut [u32], axis: usize) {
        strips.sort_unstable_by(|&a, &b| {
            let (ca, cb) = (
                self.centroids[a as usize][axis],
                self.centroids[b as usize][axis],
            );
            ca.total_cmp(&cb).then(a.cmp(&b))
        });
    }

    fn bin_of(&self, strip: u32, axis: usize, centroids: &Aabb, bins: usize) -> usize {
        let scale = bins as f32 / centroids.extent(axis);
        let offset = self.centroids[strip as usize][axis] - centroids.min[axis];
        ((offset * scale) as usize).min(bins - 1)
    }

    /// Reorders `strips` so the left side comes first and returns its length.
    fn partition(&self, strips: &mut [u32], split: &Split) -> usize {
        let bin = match split.cut {
            Cut::Median => return self.median_partition(strips, split.axis),
            Cut::Sorted(left) => {
                self.sort_along(strips, split.axis);
                return left;
            }
            Cut::Bin(bin) => bin,
        };
        let centroids = Aabb::from_points(strips.iter().map(|&s| &self.centroids[s as usize]));
        let bins = self.params.bins.max(2);
        let mut left = 0;
        for i in 0..strips.len() {
            if self.bin_of(strips[i], split.axis, &centroids, bins) < bin {
                strips.swap(i, left);
                left += 1;
            }
        }
        left
    }

    /// Splits at the median centroid, ties broken by strip id, so that equal centroids still
    /// separate deterministically.
    fn median_partition(&self, strips: &mut [u32], axis: usize) -> usize {
        let mid = strips.len() / 2;
        strips.select_nth_unstable_by(mid, |&a, &b| {
            let (ca, cb) = (
                self.centroids[a as usize][axis],
                self.centroids[b as usize][axis],
            );
            ca.total_cmp(&cb).then(a.cmp(&b))
        });
        mid
    }
}

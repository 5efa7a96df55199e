//! Shape of the implicit, left-balanced kd-tree of one strip (paper 3.2, Fig. 2).
//!
//! The tree is never stored: its shape follows from the strip's window count `w` and the leaf
//! size `L`. The windows are cut into `ceil(w / L)` buckets of `L` consecutive windows (the last
//! may be shorter); the tree is the left-balanced binary tree over the buckets: a node over
//! buckets `[b0, b1)` with more than one bucket splits after `ceil((b1 - b0) / 2)` buckets. So
//! there are exactly `buckets - 1` internal nodes, every leaf but the last holds exactly `L`
//! windows, and internal nodes numbered in preorder have their left child at `i + 1` and their
//! right child at `i + left_buckets`. Internal node `i` owns stored vertices `2i` (the left
//! child's upper bound on the split axis) and `2i + 1` (the right child's lower bound).
//!
//! Deviation from the paper: the tree is over windows (real triangles and swaps alike) rather
//! than real triangles only, so that the active interval of the traversal is a plain range of
//! strip positions with no index table. Full buckets matter for compactness: a halving split
//! leaves many one-window leaves, up to twice as many nodes, and every node costs two stored
//! bound vertices.

/// Number of internal nodes of the tree over `windows` windows.
#[inline]
pub fn internal_nodes(windows: usize, leaf_windows: usize) -> usize {
    buckets(windows, leaf_windows).saturating_sub(1)
}

/// Number of buckets (leaves) of the tree over `windows` windows, `windows.div_ceil(leaf)`.
/// Leaf sizes are powers of two in practice (4, 8), and then this is a shift: a few more
/// instructions than a division, but a division costs tens of cycles, and this runs twice per
/// strip a ray enters (to find the strip's split axes and to start its traversal).
#[inline]
pub fn buckets(windows: usize, leaf_windows: usize) -> usize {
    if !leaf_windows.is_power_of_two() {
        return windows.div_ceil(leaf_windows);
    }
    let whole = windows >> leaf_windows.trailing_zeros();
    whole + usize::from(windows & (leaf_windows - 1) != 0)
}

/// Whether the node over windows `[lo, hi)` is a leaf.
#[inline]
pub fn is_leaf(lo: usize, hi: usize, leaf_windows: usize) -> bool {
    hi - lo <= leaf_windows
}

/// Where the internal node over windows `[lo, hi)` splits (`lo` is a bucket boundary).
#[inline]
pub fn split_point(lo: usize, hi: usize, leaf_windows: usize) -> usize {
    let buckets = (hi - lo).div_ceil(leaf_windows);
    lo + buckets.div_ceil(2) * leaf_windows
}

/// Preorder index of the right child of internal node `node` over `[lo, hi)` split at `mid`.
#[inline]
pub fn right_child(node: usize, lo: usize, mid: usize, leaf_windows: usize) -> usize {
    node + (mid - lo) / leaf_windows
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Walks the tree recursively, checking preorder numbering against `right_child`.
    fn walk(
        node: usize,
        lo: usize,
        hi: usize,
        leaf: usize,
        next: &mut usize,
        leaves: &mut Vec<(usize, usize)>,
    ) {
        if is_leaf(lo, hi, leaf) {
            leaves.push((lo, hi));
            return;
        }
        assert_eq!(node, *next);
        *next += 1;
        let mid = split_point(lo, hi, leaf);
        assert!(lo < mid && mid < hi);
        walk(node + 1, lo, mid, leaf, next, leaves);
        walk(
            right_child(node, lo, mid, leaf),
            mid,
            hi,
            leaf,
            next,
            leaves,
        );
    }

    #[test]
    fn preorder_numbering_and_full_leaves() {
        for leaf in 1..6 {
            for windows in 1..200 {
                let (mut next, mut leaves) = (0, Vec::new());
                walk(0, 0, windows, leaf, &mut next, &mut leaves);
                assert_eq!(
                    next,
                    internal_nodes(windows, leaf),
                    "leaf {leaf} windows {windows}"
                );
                let covered: Vec<usize> = leaves.iter().flat_map(|&(lo, hi)| lo..hi).collect();
                assert_eq!(covered, (0..windows).collect::<Vec<_>>());
                let (last, full) = leaves.split_last().unwrap();
                assert!(full.iter().all(|&(lo, hi)| hi - lo == leaf));
                assert!(last.1 - last.0 <= leaf);
            }
        }
    }

    #[test]
    fn buckets_are_the_ceiling_of_the_quotient() {
        for leaf in 1..20 {
            for windows in 0..300 {
                assert_eq!(
                    buckets(windows, leaf),
                    windows.div_ceil(leaf),
                    "{windows} {leaf}"
                );
            }
        }
    }

    #[test]
    fn seven_windows_in_two_window_leaves() {
        // Buckets [0,2) [2,4) [4,6) [6,7): root splits after two buckets at window 4.
        assert_eq!(internal_nodes(7, 2), 3);
        assert_eq!(split_point(0, 7, 2), 4);
        assert_eq!(right_child(0, 0, 4, 2), 2);
        assert_eq!(split_point(4, 7, 2), 6);
    }
}

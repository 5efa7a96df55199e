//! Shape of the implicit, left-balanced kd-tree of one strip (paper 3.2, Fig. 2).
//!
//! The tree is never stored: its shape follows from the strip's window count and the leaf size.
//! A node covering windows `[lo, hi)` is a leaf when `hi - lo <= leaf_windows`; otherwise it
//! splits at `lo + ceil((hi - lo) / 2)` (the left half takes the odd window, hence
//! "left-balanced"). Internal nodes are numbered in preorder, so the left child of node `i` is
//! `i + 1` and the right child is `i + 1 + internal_nodes(left_len)`. Internal node `i` owns
//! stored vertices `2i` (the left child's upper bound on the split axis) and `2i + 1` (the right
//! child's lower bound); leaves own nothing.
//!
//! Deviation from the paper: the split is over windows (real triangles and swaps alike) rather
//! than over real triangles only, so that the active interval of the traversal is a plain range
//! of strip positions and needs no index table. Swap windows are rare and cost one compare each.

/// Number of internal nodes of the tree over `windows` windows.
pub fn internal_nodes(windows: usize, leaf_windows: usize) -> usize {
    if windows <= leaf_windows {
        return 0;
    }
    let left = windows.div_ceil(2);
    1 + internal_nodes(left, leaf_windows) + internal_nodes(windows - left, leaf_windows)
}

/// Where node `[lo, hi)` splits its windows.
#[inline]
pub fn split_point(lo: usize, hi: usize) -> usize {
    lo + (hi - lo).div_ceil(2)
}

/// Internal node counts for every window count a strip may have, so that traversal finds the
/// right child without recursion. Built once per file (the leaf size is in the header).
#[derive(Clone, Debug)]
pub struct NodeCountTable {
    leaf_windows: usize,
    counts: Vec<u16>,
}

impl NodeCountTable {
    /// Covers window counts `0..=max_windows`.
    pub fn new(leaf_windows: usize, max_windows: usize) -> NodeCountTable {
        let mut counts = vec![0u16; max_windows + 1];
        for windows in leaf_windows + 1..=max_windows {
            let left = windows.div_ceil(2);
            counts[windows] = 1 + counts[left] + counts[windows - left];
        }
        NodeCountTable {
            leaf_windows,
            counts,
        }
    }

    pub fn leaf_windows(&self) -> usize {
        self.leaf_windows
    }

    /// Internal nodes over `windows` windows; `windows` must be within the table.
    #[inline]
    pub fn internal_nodes(&self, windows: usize) -> usize {
        self.counts[windows] as usize
    }

    pub fn max_windows(&self) -> usize {
        self.counts.len() - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_recursive_definition() {
        for leaf in 1..5 {
            let table = NodeCountTable::new(leaf, 300);
            for windows in 0..=300 {
                assert_eq!(table.internal_nodes(windows), internal_nodes(windows, leaf));
            }
        }
    }

    #[test]
    fn two_window_leaves_over_seven_windows() {
        // [0,7) -> [0,4) [4,7); [0,4) -> [0,2) [2,4); [4,7) -> [4,6) [6,7): three internal nodes.
        assert_eq!(internal_nodes(7, 2), 3);
        assert_eq!(split_point(0, 7), 4);
        assert_eq!(split_point(4, 7), 6);
    }
}

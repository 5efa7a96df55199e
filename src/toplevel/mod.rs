//! The global hierarchy over strips (paper 3.2: "one global high-level hierarchy whose leaf nodes
//! contain the strip hierarchies").
//!
//! Built in two steps: a binned-SAH binary bounding volume hierarchy over strip bounds, then
//! collapsed into 4-wide nodes ([`TopNode`]). A wide node rooted at a binary node takes its two
//! children as slots and may open internal slots (replace one by its two children) up to four;
//! which ones each wide node opens is chosen bottom-up by dynamic programming so that the wide
//! nodes' total surface area, the SAH's expected number of node visits, is least (as in Ylitie
//! et al. 2017, with the binary tree's leaves kept). Unlike a greedy top-down collapse (open the
//! largest child until four), this fills the nodes near the leaves, where most of them are
//! (docs/BENCHMARKS.md, "Top-level nodes"). Opening a slot
//! in place keeps the leaves in the binary tree's order, so the strip numbering is the binary
//! tree's.
//!
//! Deviation from the paper: binary BVH → 4-wide for SIMD box tests and fewer bytes. A ray
//! tests four boxes with one set of vector operations per node fetch, and the top level takes
//! one 128-byte node per about 2.4 leaves instead of two 32-byte nodes per leaf
//! (docs/BENCHMARKS.md, "Top-level nodes").
//!
//! Nodes are emitted depth-first (a node's first internal child right after it) and the strips
//! are renumbered in leaf order, so the strips of a subtree are contiguous in the strip-data
//! section and a subtree's nodes are contiguous in the node section: a ray that stays in one
//! region of the model pages in few pages of either.
//!
//! One concept per file: `sah.rs` builds the binary tree, `collapse.rs` chooses the wide nodes,
//! `emit.rs` writes them, `validate.rs` checks a result, `splice.rs` joins chunk hierarchies and
//! `relocate.rs` renumbers a chunk's nodes into the joined file.

mod collapse;
mod emit;
mod relocate;
mod sah;
mod splice;
mod validate;

use crate::format::TopNode;
use crate::geometry::Aabb;
use collapse::Collapse;
use emit::{emit, NodeArray};
use sah::build_binary;

pub use relocate::relocate;
pub use splice::{splice, SpliceItem, Subtree};

/// Build parameters of the top-level hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct TopLevelParams {
    /// SAH bins per axis.
    pub bins: usize,
    /// Most strips in one leaf; the SAH may stop earlier.
    pub max_leaf_strips: usize,
    /// Cost of one node traversal relative to testing one strip, for the SAH termination.
    pub traversal_cost: f64,
}

impl Default for TopLevelParams {
    fn default() -> Self {
        TopLevelParams {
            bins: 16,
            max_leaf_strips: 4,
            traversal_cost: 0.5,
        }
    }
}

/// The built hierarchy: nodes in file order and, for each file strip position, the input strip.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TopLevel {
    pub nodes: Vec<TopNode>,
    pub strip_order: Vec<u32>,
}

/// Builds the hierarchy over `bounds` (one box per strip).
pub fn build(bounds: &[Aabb], params: &TopLevelParams) -> TopLevel {
    let (binary, strip_order) = build_binary(bounds, params);
    let mut nodes = NodeArray(Vec::with_capacity(binary.len() / 3 + 1));
    if binary.is_empty() {
        nodes.0.push(TopNode::EMPTY);
    } else {
        emit(&Collapse::new(&binary), 0, &mut nodes);
    }
    TopLevel {
        nodes: nodes.0,
        strip_order,
    }
}

#[cfg(test)]
mod tests {
    use super::sah::BinaryKind;
    use super::*;
    use crate::format::TopSlot;

    /// Boxes on a jittered grid, deterministic.
    fn boxes(count: usize) -> Vec<Aabb> {
        (0..count)
            .map(|i| {
                let x = (i % 17) as f32 + (i as f32 * 0.37).sin();
                let y = ((i / 17) % 13) as f32;
                let z = (i / 221) as f32 + (i as f32 * 0.11).cos();
                Aabb {
                    min: [x, y, z],
                    max: [x + 0.8, y + 0.5 + (i % 3) as f32, z + 0.3],
                }
            })
            .collect()
    }

    #[test]
    fn wide_tree_is_valid_and_keeps_the_binary_leaf_order() {
        for count in [0, 1, 2, 3, 5, 64, 1000] {
            let bounds = boxes(count);
            let params = TopLevelParams::default();
            let top = build(&bounds, &params);
            top.validate(&bounds).unwrap();
            assert_eq!(top.strip_order, build_binary(&bounds, &params).1);
        }
    }

    #[test]
    fn collapsing_fills_nodes() {
        let bounds = boxes(1000);
        let params = TopLevelParams::default();
        let binary_internal = build_binary(&bounds, &params)
            .0
            .iter()
            .filter(|n| matches!(n.kind, BinaryKind::Internal { .. }))
            .count();
        let top = build(&bounds, &params);
        // Every wide node absorbs at least one binary internal node, most three.
        assert!(top.nodes.len() * 2 < binary_internal, "{}", top.nodes.len());
    }

    #[test]
    fn empty_and_single_strip_roots() {
        assert_eq!(
            build(&[], &TopLevelParams::default()).nodes,
            [TopNode::EMPTY]
        );
        let one = build(&boxes(1), &TopLevelParams::default());
        assert_eq!(one.nodes.len(), 1);
        assert_eq!(one.nodes[0].slot(0), TopSlot::Leaf { first: 0, count: 1 });
        assert_eq!(one.nodes[0].occupied(), 1);
    }

    #[test]
    fn validate_rejects_broken_trees() {
        let bounds = boxes(200);
        let top = build(&bounds, &TopLevelParams::default());
        let mut loose = top.clone();
        loose.nodes[0].min[0][0] = 1e9;
        assert!(loose.validate(&bounds).is_err());
        let mut unpacked = top.clone();
        unpacked.nodes[1].kind[0] = 0;
        assert!(unpacked.validate(&bounds).is_err());
        let mut duplicated = top;
        duplicated.strip_order[1] = duplicated.strip_order[0];
        assert!(duplicated.validate(&bounds).is_err());
    }

    /// Splicing chunk hierarchies gives a tree whose every chunk root is an internal slot, and
    /// the spliced file nodes validate like one hierarchy.
    #[test]
    fn splice_places_chunks_under_wide_upper_nodes() {
        let all = boxes(900);
        let chunks: Vec<&[Aabb]> = all.chunks(100).collect();
        let built: Vec<TopLevel> = chunks
            .iter()
            .map(|c| build(c, &TopLevelParams::default()))
            .collect();
        let subtrees: Vec<Subtree> = built
            .iter()
            .zip(&chunks)
            .map(|(top, c)| Subtree {
                bounds: c.iter().fold(Aabb::EMPTY, |a, b| a.union(b)),
                node_count: top.nodes.len() as u32,
                strip_count: c.len() as u32,
            })
            .collect();
        let mut spliced = TopLevel::default();
        let mut spliced_bounds = Vec::new();
        for item in splice(&subtrees, &TopLevelParams::default()) {
            match item {
                SpliceItem::Node(node) => spliced.nodes.push(node),
                SpliceItem::Subtree {
                    index,
                    node_base,
                    strip_base,
                } => {
                    assert_eq!(node_base as usize, spliced.nodes.len());
                    assert_eq!(strip_base as usize, spliced.strip_order.len());
                    let chunk = &built[index];
                    spliced.nodes.extend(
                        chunk
                            .nodes
                            .iter()
                            .map(|n| relocate(n, node_base, strip_base)),
                    );
                    for &s in &chunk.strip_order {
                        spliced.strip_order.push(spliced_bounds.len() as u32);
                        spliced_bounds.push(chunks[index][s as usize]);
                    }
                }
            }
        }
        spliced.validate(&spliced_bounds).unwrap();
        // Nine chunks fit under three upper nodes at most.
        let upper = spliced.nodes.len() - built.iter().map(|t| t.nodes.len()).sum::<usize>();
        assert!((1..=4).contains(&upper), "{upper}");
    }

    #[test]
    fn splice_of_one_chunk_is_that_chunk() {
        let subtree = Subtree {
            bounds: boxes(1)[0],
            node_count: 3,
            strip_count: 7,
        };
        let empty = Subtree {
            strip_count: 0,
            ..subtree
        };
        assert_eq!(
            splice(&[empty, subtree], &TopLevelParams::default()),
            [SpliceItem::Subtree {
                index: 1,
                node_base: 0,
                strip_base: 0
            }]
        );
        assert_eq!(
            splice(&[empty], &TopLevelParams::default()),
            [SpliceItem::Node(TopNode::EMPTY)]
        );
    }
}

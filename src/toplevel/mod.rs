//! The global hierarchy over strips (paper 3.2: "one global high-level hierarchy whose leaf nodes
//! contain the strip hierarchies").
//!
//! Built in two steps: a binned-SAH binary bounding volume hierarchy over strip bounds down to
//! one strip per leaf, then collapsed into 8-wide compressed nodes ([`WideNode`]). Each wide
//! node is rooted at a binary internal node and takes as slots a cut of its subtree of at most
//! eight binary nodes, each slot a wide node or a leaf of at most
//! [`TopLevelParams::max_leaf_strips`] strips. The cuts are chosen by Ylitie et al. 2017's
//! dynamic programme, which gives each binary node the least SAH cost of covering its subtree
//! with 1 to 8 slots, combined from its children's costs bottom-up in O(nodes × 8²): a wide node
//! costs its surface area times [`TopLevelParams::traversal_cost`], a leaf its surface area
//! times its strip count (a strip test is the unit). A leaf of several strips saves a node where
//! slots run short, at the price of strips its box does not cull. The cut keeps the binary
//! tree's leaf order, so the strip numbering is the binary tree's.
//!
//! Deviation from the paper: binary BVH → 8-wide for SIMD box tests and fewer bytes. A ray
//! tests eight boxes with one set of vector operations per node fetch, and the top level takes
//! one 96-byte node per about six strips instead of two 32-byte nodes per leaf.
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

use crate::format::{TopSlot, WideNode, WIDE_WIDTH};
use crate::geometry::Aabb;
use collapse::Collapse;
use emit::{emit, NodeArray};
use sah::build_binary;

pub use relocate::relocate;
pub use splice::{splice, SpliceItem, Subtree};

/// Build parameters of the top-level hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct TopLevelParams {
    /// SAH bins per axis, for subtrees of more strips than `sah::SWEEP_STRIPS`.
    pub bins: usize,
    /// Most strips in one leaf; the collapse makes smaller leaves where the SAH prefers them.
    pub max_leaf_strips: usize,
    /// Cost of visiting one wide node relative to testing one strip, for the collapse's SAH.
    pub traversal_cost: f64,
}

impl Default for TopLevelParams {
    fn default() -> Self {
        TopLevelParams {
            bins: 32,
            max_leaf_strips: 4,
            traversal_cost: 1.0,
        }
    }
}

/// [`TopLevelParams::traversal_cost`] for pooled grid files: their strip data is about half a
/// lossless file's, so the top level's bytes weigh twice as much against its cost in rays.
pub const POOLED_TRAVERSAL_COST: f64 = 2.0;

/// The built hierarchy: nodes in file order and, for each file strip position, the input strip.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TopLevel {
    pub nodes: Vec<WideNode>,
    pub strip_order: Vec<u32>,
}

/// A wide node that no record can hold: a box that is not finite, or an index beyond a link's
/// 28 bits. Finite strip bounds and fewer than 2^28 nodes and strips never give one.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("top-level node {index}: {detail}")]
pub struct NodeError {
    pub index: u32,
    pub detail: String,
}

/// Builds the hierarchy over `bounds` (one box per strip).
pub fn build(bounds: &[Aabb], params: &TopLevelParams) -> Result<TopLevel, NodeError> {
    let (binary, strip_order) = build_binary(bounds, params);
    let mut nodes = NodeArray(Vec::with_capacity(binary.len() / 6 + 1));
    if binary.is_empty() {
        nodes.0.push(WideNode::EMPTY);
    } else {
        emit(&Collapse::new(&binary, params), 0, &mut nodes)?;
    }
    Ok(TopLevel {
        nodes: nodes.0,
        strip_order,
    })
}

/// The decoded box of a hierarchy's root: what an upper node's slot over it must hold
/// ([`Subtree::bounds`]).
pub fn root_bounds(root: &WideNode) -> Aabb {
    emit::decoded_bounds(root)
}

/// Occupied slots of `node`: those before the first empty one.
fn occupied(node: &WideNode) -> usize {
    (0..WIDE_WIDTH)
        .take_while(|&slot| node.slot(slot) != TopSlot::Empty)
        .count()
}

#[cfg(test)]
mod tests {
    use super::collapse::Slot;
    use super::sah::{BinaryKind, BinaryNode};
    use super::*;

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
        for count in [0, 1, 2, 3, 5, 9, 64, 1000] {
            let bounds = boxes(count);
            let params = TopLevelParams::default();
            let top = build(&bounds, &params).unwrap();
            top.validate(&bounds).unwrap();
            assert_eq!(top.strip_order, build_binary(&bounds, &params).1);
        }
    }

    /// The largest leaf of `top`, in strips.
    fn largest_leaf(top: &TopLevel) -> u32 {
        top.nodes
            .iter()
            .flat_map(|node| (0..WIDE_WIDTH).map(|slot| node.slot(slot)))
            .filter_map(|slot| match slot {
                TopSlot::Leaf { count, .. } => Some(count),
                _ => None,
            })
            .max()
            .unwrap_or(0)
    }

    #[test]
    fn costlier_node_visits_give_fewer_nodes_and_larger_leaves() {
        let bounds = boxes(10_000);
        let build_with = |max_leaf_strips, traversal_cost| {
            let params = TopLevelParams {
                max_leaf_strips,
                traversal_cost,
                ..TopLevelParams::default()
            };
            let top = build(&bounds, &params).unwrap();
            top.validate(&bounds).unwrap();
            top
        };
        let single = build_with(1, 1.0);
        assert_eq!(largest_leaf(&single), 1);
        // Fewest nodes any cut of single-strip leaves has: seven new slots per node.
        assert!(single.nodes.len() * 7 >= bounds.len());
        let tops = [0.5, 1.0, 2.0, 4.0].map(|cost| build_with(4, cost));
        for pair in tops.windows(2) {
            assert!(pair[1].nodes.len() < pair[0].nodes.len());
        }
        assert!(tops[0].nodes.len() <= single.nodes.len());
        assert_eq!(largest_leaf(&tops[3]), 4);
        // Node visits four times a strip test's cost fill nodes: one per more than 9 strips.
        assert!(
            tops[3].nodes.len() * 9 < bounds.len(),
            "{}",
            tops[3].nodes.len()
        );
    }

    /// The least total cost of the slots covering `frontier` and of any frontier of at most
    /// eight slots opened from it, given the least cost of each binary node as one slot.
    fn exhaustive_cost(tree: &[BinaryNode], costs: &[f64], frontier: &mut Vec<usize>) -> f64 {
        let mut best: f64 = frontier.iter().map(|&n| costs[n]).sum();
        if frontier.len() == WIDE_WIDTH {
            return best;
        }
        for i in 0..frontier.len() {
            if let BinaryKind::Internal { left, right } = tree[frontier[i]].kind {
                let opened = frontier[i];
                frontier.splice(i..=i, [left, right]);
                best = best.min(exhaustive_cost(tree, costs, frontier));
                frontier.splice(i..i + 2, [opened]);
            }
        }
        best
    }

    /// The SAH cost of the slot the collapse emits for binary node `index` as a wide node.
    fn emitted_cost(collapse: &Collapse, index: usize, params: &TopLevelParams) -> f64 {
        let area = |node: usize| collapse.tree[node].bounds.surface_area();
        let slots: f64 = collapse
            .slots(index)
            .into_iter()
            .map(|slot| match slot {
                Slot::Leaf { node, count, .. } => area(node) * count as f64,
                Slot::Wide(node) => emitted_cost(collapse, node, params),
            })
            .sum();
        area(index) * params.traversal_cost + slots
    }

    #[test]
    fn dynamic_programme_finds_the_exhaustive_optimum_and_emits_it() {
        for (count, max_leaf_strips, traversal_cost) in [
            (9, 1, 0.5),
            (17, 1, 1.0),
            (23, 2, 0.5),
            (40, 1, 2.0),
            (40, 4, 1.0),
            (40, 4, 4.0),
        ] {
            let params = TopLevelParams {
                max_leaf_strips,
                traversal_cost,
                ..TopLevelParams::default()
            };
            let tree = build_binary(&boxes(count), &params).0;
            let collapse = Collapse::new(&tree, &params);
            let mut costs = vec![0.0; tree.len()];
            let mut strips = vec![0; tree.len()];
            for index in (0..tree.len()).rev() {
                let area = tree[index].bounds.surface_area();
                costs[index] = match tree[index].kind {
                    BinaryKind::Leaf { count, .. } => {
                        strips[index] = count as usize;
                        area * count as f64
                    }
                    BinaryKind::Internal { left, right } => {
                        strips[index] = strips[left] + strips[right];
                        let children = exhaustive_cost(&tree, &costs, &mut vec![left, right]);
                        let wide = area * traversal_cost + children;
                        if strips[index] <= max_leaf_strips {
                            wide.min(area * strips[index] as f64)
                        } else {
                            wide
                        }
                    }
                };
            }
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.max(b);
            assert!(
                close(collapse.cost(0), costs[0]),
                "{count}: {} {}",
                collapse.cost(0),
                costs[0]
            );
            assert!(
                close(emitted_cost(&collapse, 0, &params), costs[0]),
                "{count}"
            );
        }
    }

    #[test]
    fn empty_and_single_strip_roots() {
        assert_eq!(
            build(&[], &TopLevelParams::default()).unwrap().nodes,
            [WideNode::EMPTY]
        );
        let one = build(&boxes(1), &TopLevelParams::default()).unwrap();
        assert_eq!(one.nodes.len(), 1);
        assert_eq!(one.nodes[0].slot(0), TopSlot::Leaf { first: 0, count: 1 });
        assert_eq!(occupied(&one.nodes[0]), 1);
    }

    #[test]
    fn validate_rejects_broken_trees() {
        let bounds = boxes(200);
        let top = build(&bounds, &TopLevelParams::default()).unwrap();
        let mut loose = top.clone();
        loose.nodes[0].max[0][0] = 0;
        assert!(loose.validate(&bounds).is_err());
        let mut unpacked = top.clone();
        unpacked.nodes[1].link[0] = 0;
        assert!(unpacked.validate(&bounds).is_err());
        let mut far = top.clone();
        far.nodes[0].exponent[2] = 255;
        assert!(far.validate(&bounds).is_err());
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
            .map(|c| build(c, &TopLevelParams::default()).unwrap())
            .collect();
        let subtrees: Vec<Subtree> = built
            .iter()
            .zip(&chunks)
            .map(|(top, c)| Subtree {
                bounds: root_bounds(&top.nodes[0]),
                node_count: top.nodes.len() as u32,
                strip_count: c.len() as u32,
            })
            .collect();
        let mut spliced = TopLevel::default();
        let mut spliced_bounds = Vec::new();
        for item in splice(&subtrees, &TopLevelParams::default()).unwrap() {
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
                    for node in &chunk.nodes {
                        spliced
                            .nodes
                            .push(relocate(node, node_base, strip_base).unwrap());
                    }
                    for &s in &chunk.strip_order {
                        spliced.strip_order.push(spliced_bounds.len() as u32);
                        spliced_bounds.push(chunks[index][s as usize]);
                    }
                }
            }
        }
        spliced.validate(&spliced_bounds).unwrap();
        // Nine chunks need two upper nodes of eight slots.
        let upper = spliced.nodes.len() - built.iter().map(|t| t.nodes.len()).sum::<usize>();
        assert_eq!(upper, 2);
    }

    #[test]
    fn relocation_beyond_a_link_is_an_error() {
        let child = |slot| crate::format::WideChild {
            min: [0.0; 3],
            max: [1.0; 3],
            slot,
        };
        let node = WideNode::encode(&[
            child(TopSlot::Leaf { first: 3, count: 2 }),
            child(TopSlot::Internal(2)),
        ])
        .unwrap();
        let limit = crate::format::GRID_LINK_INDEX;
        let moved = relocate(&node, limit - 2, limit - 3).unwrap();
        assert_eq!(
            moved.slot(0),
            TopSlot::Leaf {
                first: limit,
                count: 2
            }
        );
        assert_eq!(moved.slot(1), TopSlot::Internal(limit));
        assert_eq!(moved.slot(2), TopSlot::Empty);
        assert!(relocate(&node, limit - 1, 0).is_err());
        assert!(relocate(&node, 0, limit - 2).is_err());
        assert!(relocate(&node, u32::MAX, 0).is_err());
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
            splice(&[empty, subtree], &TopLevelParams::default()).unwrap(),
            [SpliceItem::Subtree {
                index: 1,
                node_base: 0,
                strip_base: 0
            }]
        );
        assert_eq!(
            splice(&[empty], &TopLevelParams::default()).unwrap(),
            [SpliceItem::Node(WideNode::EMPTY)]
        );
    }
}

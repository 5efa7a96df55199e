//! The merge of per-chunk hierarchies under one upper hierarchy (paper 4.2).

use super::collapse::Collapse;
use super::emit::{emit, WideOut};
use super::sah::build_binary;
use super::{NodeError, TopLevelParams};
use crate::format::{TopSlot, WideNode};
use crate::geometry::Aabb;

/// One chunk's finished hierarchy, as the splice sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Subtree {
    /// The decoded box of the chunk's root ([`root_bounds`](super::root_bounds)): the box of
    /// the upper slot pointing at it, which must hold the root's decoded boxes.
    pub bounds: Aabb,
    pub node_count: u32,
    pub strip_count: u32,
}

/// One step of the spliced hierarchy in final preorder: an upper node over chunks, or a whole
/// chunk subtree whose nodes and strips are renumbered from the given bases.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpliceItem {
    Node(WideNode),
    Subtree {
        index: usize,
        node_base: u32,
        strip_base: u32,
    },
}

/// Joins per-chunk hierarchies under an upper SAH hierarchy over their root boxes (paper 4.2:
/// chunks stripified separately, "with a merge operation at the end").
///
/// Each chunk's nodes and strips stay contiguous, so the final file can be written by streaming
/// chunk after chunk, and a subtree's nodes and strips sit together in the file. The upper
/// hierarchy is built like the per-chunk ones with one chunk per leaf and collapsed the same
/// way, except that a leaf becomes an internal slot pointing at the chunk's root. A single chunk
/// needs no upper node: its root is the file's. Chunks without strips are left out.
pub fn splice(subtrees: &[Subtree], params: &TopLevelParams) -> Result<Vec<SpliceItem>, NodeError> {
    let used: Vec<usize> = (0..subtrees.len())
        .filter(|&i| subtrees[i].strip_count > 0)
        .collect();
    let bounds: Vec<Aabb> = used.iter().map(|&i| subtrees[i].bounds).collect();
    let upper_params = TopLevelParams {
        max_leaf_strips: 1,
        ..params.clone()
    };
    let (upper, chunk_order) = build_binary(&bounds, &upper_params);
    let mut out = SpliceOut {
        chunk_order: chunk_order.iter().map(|&c| used[c as usize]).collect(),
        subtrees,
        items: Vec::new(),
        next_node: 0,
        next_strip: 0,
    };
    match upper.len() {
        0 => out.items.push(SpliceItem::Node(WideNode::EMPTY)),
        1 => {
            out.leaf(0, 1, &bounds[0]);
        }
        _ => {
            emit(&Collapse::new(&upper, &upper_params), 0, &mut out)?;
        }
    }
    Ok(out.items)
}

/// The splice's item list; an upper leaf is one chunk, placed whole.
struct SpliceOut<'a> {
    /// Chunk index at each upper leaf position.
    chunk_order: Vec<usize>,
    subtrees: &'a [Subtree],
    items: Vec<SpliceItem>,
    next_node: u32,
    next_strip: u32,
}

impl WideOut for SpliceOut<'_> {
    fn open(&mut self) -> (u32, usize) {
        self.items.push(SpliceItem::Node(WideNode::EMPTY));
        self.next_node += 1;
        (self.next_node - 1, self.items.len() - 1)
    }

    fn complete(&mut self, handle: usize, node: WideNode) {
        self.items[handle] = SpliceItem::Node(node);
    }

    fn leaf(&mut self, first: u32, _count: u32, bounds: &Aabb) -> (TopSlot, Aabb) {
        let index = self.chunk_order[first as usize];
        let root = self.next_node;
        self.items.push(SpliceItem::Subtree {
            index,
            node_base: root,
            strip_base: self.next_strip,
        });
        self.next_node += self.subtrees[index].node_count;
        self.next_strip += self.subtrees[index].strip_count;
        (TopSlot::Internal(root), *bounds)
    }
}

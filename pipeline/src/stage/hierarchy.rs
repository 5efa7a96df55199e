//! Stage *hierarchy*: the global hierarchy over all strips, as an upper SAH hierarchy over the
//! chunks' own hierarchies (`reducem::toplevel::splice`). Its output is the final node order:
//! upper nodes and, for each chunk, where its nodes and strips start.

use anyhow::Context;
use reducem::format::{TopSlot, WideChild, WideNode, WIDE_WIDTH};
use reducem::toplevel::{root_bounds, splice, SpliceItem, Subtree, TopLevelParams};
use serde::{Deserialize, Serialize};

use crate::chunk_io::StripChunk;
use crate::fingerprint::Fingerprint;
use crate::stage::merge::Merged;
use crate::stage::{fresh_output, write_json, Job, Stamped};

pub const UNIT: &str = "hierarchy";
const PLAN: &str = "hierarchy.json";

/// One step of the final node order (see [`SpliceItem`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Step {
    /// An upper node's occupied slots in order; the others are empty.
    Node { slots: Vec<Slot> },
    Chunk {
        index: usize,
        node_base: u32,
        strip_base: u32,
    },
}

/// One occupied slot of an upper node: its decoded box, which encodes again to the same
/// decoded box, and the node it points at (an upper node or a chunk's root: the splice puts
/// no strips in upper nodes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Slot {
    pub min: [f32; 3],
    pub max: [f32; 3],
    pub node: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hierarchy {
    pub digest: String,
    pub steps: Vec<Step>,
}

pub fn fingerprint(merged: &Merged) -> Fingerprint {
    Fingerprint::new()
        .with("merge_stage", &merged.digest)
        .with("top_level", format!("{:?}", TopLevelParams::default()))
}

pub fn fresh_result(job: &Job, fingerprint: &Fingerprint) -> Option<Hierarchy> {
    fresh_output(job, UNIT, PLAN, fingerprint)
}

impl Stamped for Hierarchy {
    fn digest(&self) -> &str {
        &self.digest
    }
}

pub fn run(job: &Job, merged: &Merged) -> anyhow::Result<Hierarchy> {
    let fingerprint = fingerprint(merged);
    job.note_rebuild(UNIT, &job.freshness(UNIT, &fingerprint), "it");
    if let Some(hierarchy) = fresh_result(job, &fingerprint) {
        job.progress.event(UNIT, "skip", "fresh");
        return Ok(hierarchy);
    }
    let progress = job
        .progress
        .stage(UNIT, merged.chunks.len() as u64, "chunks");
    let subtrees = merged
        .chunks
        .iter()
        .enumerate()
        .map(|(index, c)| {
            Ok(Subtree {
                bounds: root_bounds(&chunk_root(job, index)?),
                node_count: c.nodes,
                strip_count: c.strips,
            })
        })
        .collect::<anyhow::Result<Vec<Subtree>>>()?;
    let steps = splice(&subtrees, &TopLevelParams::default())?
        .into_iter()
        .map(step)
        .collect::<anyhow::Result<_>>()?;
    let hierarchy = Hierarchy {
        digest: fingerprint.digest(),
        steps,
    };
    let written = write_json(job, PLAN, &hierarchy)?;
    job.complete(UNIT, &fingerprint, &[written])?;
    progress.advance(merged.chunks.len() as u64);
    progress.finish("");
    Ok(hierarchy)
}

/// The root node of chunk `index`: the upper slot over the chunk must hold its decoded boxes,
/// which reach past the chunk's strip bounds.
fn chunk_root(job: &Job, index: usize) -> anyhow::Result<WideNode> {
    let path = job.work.file(&crate::workdir::strip_chunk(index));
    StripChunk::open(&path)
        .and_then(|mut chunk| chunk.root())
        .with_context(|| format!("reading the root node of {}", path.display()))
}

fn step(item: SpliceItem) -> anyhow::Result<Step> {
    Ok(match item {
        SpliceItem::Node(node) => Step::Node {
            slots: (0..WIDE_WIDTH)
                .map_while(|slot| match node.slot(slot) {
                    TopSlot::Empty => None,
                    link => Some((slot, link)),
                })
                .map(|(slot, link)| {
                    let TopSlot::Internal(child) = link else {
                        anyhow::bail!("upper node slot {slot} holds {link:?}, not a node");
                    };
                    let (min, max) = node.slot_box(slot);
                    Ok(Slot {
                        min,
                        max,
                        node: child,
                    })
                })
                .collect::<anyhow::Result<_>>()?,
        },
        SpliceItem::Subtree {
            index,
            node_base,
            strip_base,
        } => Step::Chunk {
            index,
            node_base,
            strip_base,
        },
    })
}

/// The node an upper step stands for.
pub fn node(slots: &[Slot]) -> Result<WideNode, String> {
    let children: Vec<WideChild> = slots
        .iter()
        .map(|slot| WideChild {
            min: slot.min,
            max: slot.max,
            slot: TopSlot::Internal(slot.node),
        })
        .collect();
    WideNode::encode(&children)
}

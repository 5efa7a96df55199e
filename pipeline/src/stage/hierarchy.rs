//! Stage *hierarchy*: the global hierarchy over all strips, as an upper SAH hierarchy over the
//! chunks' own hierarchies (`reducem::toplevel::splice`). Its output is the final node order:
//! upper nodes and, for each chunk, where its nodes and strips start.

use reducem::format::TopNode;
use reducem::toplevel::{splice, SpliceItem, Subtree, TopLevelParams};
use serde::{Deserialize, Serialize};

use crate::fingerprint::Fingerprint;
use crate::stage::merge::Merged;
use crate::stage::{fresh_output, write_json, Job, Stamped};

pub const UNIT: &str = "hierarchy";
const PLAN: &str = "hierarchy.json";

/// One step of the final node order (see [`SpliceItem`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Step {
    /// An upper node's occupied slots in order; the others are empty. (Only these: JSON has no
    /// infinities for the empty slots' boxes.)
    Node { slots: Vec<Slot> },
    Chunk {
        index: usize,
        node_base: u32,
        strip_base: u32,
    },
}

/// One occupied slot of an upper node, fields as in [`TopNode`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Slot {
    pub min: [f32; 3],
    pub max: [f32; 3],
    pub child: u32,
    pub kind: u32,
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
    let subtrees: Vec<Subtree> = merged
        .chunks
        .iter()
        .map(|c| Subtree {
            bounds: reducem::geometry::Aabb {
                min: c.bounds_min,
                max: c.bounds_max,
            },
            node_count: c.nodes,
            strip_count: c.strips,
        })
        .collect();
    let steps = splice(&subtrees, &TopLevelParams::default())
        .into_iter()
        .map(step)
        .collect();
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

fn step(item: SpliceItem) -> Step {
    match item {
        SpliceItem::Node(node) => Step::Node {
            slots: (0..node.occupied())
                .map(|slot| {
                    let (min, max) = node.slot_box(slot);
                    Slot {
                        min,
                        max,
                        child: node.child[slot],
                        kind: node.kind[slot],
                    }
                })
                .collect(),
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
    }
}

/// The node an upper step stands for.
pub fn node(slots: &[Slot]) -> TopNode {
    let mut node = TopNode::EMPTY;
    for (index, slot) in slots.iter().enumerate() {
        node.set(index, &slot.min, &slot.max, slot.child, slot.kind);
    }
    node
}

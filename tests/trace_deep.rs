//! A top level of the format's full depth, [`MAX_TOP_DEPTH`] levels: opened and traced like any
//! other (the traversal's stack of deferred children outgrows its inline part and spills to the
//! heap), and one level deeper rejected on open.

mod common;

use common::*;
use reducem::conversion::{encode_chunk, strip_bounds, BuildParams, EncodedChunk};
use reducem::format::reader::ReducemFile;
use reducem::format::{TopSlot, WideChild, WideNode, MAX_TOP_DEPTH, MAX_WIDE_LEAF_STRIPS};
use reducem::geometry::Aabb;
use reducem::stripify::StripifyParams;
use reducem::toplevel::TopLevel;
use reducem::trace::{TraceOptions, Tracer};

/// One triangle per strip, so there are more strips than levels, and few enough for the last
/// node's leaves.
fn single_triangle_strips() -> EncodedChunk {
    let params = BuildParams {
        stripify: StripifyParams {
            max_length: 1,
            ..StripifyParams::default()
        },
        ..BuildParams::default()
    };
    encode_chunk(&torus(12, 6), &params)
}

/// A chain of `levels + 1` nodes: node `i` holds leaf strip `i` and, for `i < levels`, node
/// `i + 1`; the last node holds the remaining strips in leaves of at most 14. Each internal box
/// is a little larger than the leaf box beside it, so a ray from outside enters the internal
/// child first and defers the leaf: one more deferred entry per level.
fn chain(levels: usize, bounds: &[Aabb]) -> TopLevel {
    let all = bounds.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
    let grown = |margin: f32| Aabb {
        min: all.min.map(|x| x - margin),
        max: all.max.map(|x| x + margin),
    };
    let child = |bounds: Aabb, slot| WideChild {
        min: bounds.min,
        max: bounds.max,
        slot,
    };
    let nodes = (0..=levels)
        .map(|i| {
            let children = if i < levels {
                let inner = grown(0.01 * (levels - i) as f32);
                let leaf = TopSlot::Leaf {
                    first: i as u32,
                    count: 1,
                };
                vec![
                    child(all, leaf),
                    child(inner, TopSlot::Internal(i as u32 + 1)),
                ]
            } else {
                (levels as u32..bounds.len() as u32)
                    .step_by(MAX_WIDE_LEAF_STRIPS as usize)
                    .map(|first| {
                        let count = MAX_WIDE_LEAF_STRIPS.min(bounds.len() as u32 - first);
                        child(all, TopSlot::Leaf { first, count })
                    })
                    .collect()
            };
            WideNode::encode(&children).expect("the last node's leaves fit its slots")
        })
        .collect();
    TopLevel {
        nodes,
        strip_order: (0..bounds.len() as u32).collect(),
    }
}

fn write_chain(chunk: &EncodedChunk, levels: usize, name: &str) -> std::path::PathBuf {
    let bounds = strip_bounds(&chunk.strips);
    let top = chain(levels, &bounds);
    let path = temp_path(name);
    write_chunk_under(chunk, &top, (2, 1), &path);
    path
}

#[test]
fn a_tree_of_full_depth_traces_like_brute_force() {
    let chunk = single_triangle_strips();
    assert!(chunk.strips.len() > MAX_TOP_DEPTH + 1);
    let path = write_chain(&chunk, MAX_TOP_DEPTH, "deep.rdm");
    let file = ReducemFile::open(&path).expect("a tree of full depth opens");
    let single = Tracer::new(
        &file,
        TraceOptions {
            packets: false,
            ..TraceOptions::default()
        },
    );
    let packets = Tracer::new(&file, TraceOptions::default());
    let mut rng = SplitMix64::new(5);
    let rays: Vec<_> = (0..64)
        .map(|_| {
            let origin = [rng.range(-6.0, 6.0), rng.range(-6.0, 6.0), 4.0];
            ray_towards(origin, [rng.range(-2.0, 2.0), rng.range(-2.0, 2.0), 0.0])
        })
        .collect();
    let hits = single.intersect_chunk(&rays);
    assert_eq!(
        packets
            .intersect_chunk(&rays)
            .iter()
            .map(hit_bits)
            .collect::<Vec<_>>(),
        hits.iter().map(hit_bits).collect::<Vec<_>>()
    );
    let mut found = 0;
    for (ray, hit) in rays.iter().zip(&hits) {
        let expected = brute_force(&file, ray);
        assert_eq!(
            hit.map(|h| h.t.to_bits()),
            expected.map(|(t, _)| t.to_bits())
        );
        assert_eq!(single.occluded(ray), expected.is_some());
        found += hit.is_some() as usize;
    }
    assert!(found > 10, "{found} hits");
}

#[test]
fn one_level_deeper_is_rejected() {
    let chunk = single_triangle_strips();
    let path = write_chain(&chunk, MAX_TOP_DEPTH + 1, "too-deep.rdm");
    let message = ReducemFile::open(&path)
        .err()
        .expect("too deep")
        .to_string();
    assert!(
        message.contains(&format!("node {MAX_TOP_DEPTH}:"))
            && message.contains(&format!("deeper than {MAX_TOP_DEPTH} levels")),
        "{message}"
    );
}

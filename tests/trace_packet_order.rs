//! Packets visit a node's children in the order single rays do, lane by lane, even on a file
//! whose boxes do not bound their strips (where the order decides which hits are culled) and
//! whose boxes reach far past the model on some axes: the packet walk sorts the children any
//! lane entered, and each lane must see the order it would sort its own children in.

mod common;

use common::*;
use reducem::conversion::{encode_chunk, strip_bounds, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::format::{TopSlot, WideChild, WideNode, TOP_WIDTH};
use reducem::geometry::Aabb;
use reducem::toplevel::TopLevel;
use reducem::trace::{Ray, TraceOptions, Tracer};

/// Leaf groups: the strips in `TOP_WIDTH * TOP_WIDTH` consecutive runs.
const GROUPS: usize = TOP_WIDTH * TOP_WIDTH;
/// A distorted box's bound far past the model.
const FAR: f32 = 1.0e30;

/// The node of `children`, boxes and links in slot order.
fn node(children: &[(Aabb, TopSlot)]) -> WideNode {
    let children: Vec<WideChild> = children
        .iter()
        .map(|&(bounds, slot)| WideChild {
            min: bounds.min,
            max: bounds.max,
            slot,
        })
        .collect();
    WideNode::encode(&children).expect("finite boxes and small links encode")
}

/// `bounds` distorted at random: shrunk or moved off its strips, or given far bounds on some
/// axes (format 4 boxes are finite), or left as it is.
fn distorted(bounds: Aabb, rng: &mut SplitMix64) -> Aabb {
    let mut min = bounds.min;
    let mut max = bounds.max;
    match (rng.unit() * 4.0) as u32 {
        0 => {
            for axis in 0..3 {
                let (centre, half) = (0.5 * (min[axis] + max[axis]), 0.5 * (max[axis] - min[axis]));
                let scale = rng.range(0.1, 0.9);
                let shift = rng.range(-1.0, 1.0) * half;
                min[axis] = centre + shift - scale * half;
                max[axis] = centre + shift + scale * half;
            }
        }
        1 | 2 => {
            for axis in 0..3 {
                if rng.unit() < 0.5 {
                    min[axis] = -FAR;
                }
                if rng.unit() < 0.5 {
                    max[axis] = FAR;
                }
            }
        }
        _ => {}
    }
    Aabb { min, max }
}

/// A root over `TOP_WIDTH` internal nodes over `TOP_WIDTH` leaves each, with distorted boxes
/// at both levels.
fn distorted_tree(bounds: &[Aabb], seed: u64) -> TopLevel {
    let mut rng = SplitMix64::new(seed);
    let per_group = bounds.len().div_ceil(GROUPS);
    let group_range = |group: usize| {
        let start = (group * per_group).min(bounds.len());
        start..((group + 1) * per_group).min(bounds.len())
    };
    let union =
        |range: std::ops::Range<usize>| bounds[range].iter().fold(Aabb::EMPTY, |a, b| a.union(b));
    let mut root = Vec::new();
    let mut inner = Vec::new();
    for i in 0..TOP_WIDTH {
        let mut leaves = Vec::new();
        for slot in 0..TOP_WIDTH {
            let group = i * TOP_WIDTH + slot;
            let range = group_range(group);
            let leaf = distorted(union(range.clone()), &mut rng);
            let link = TopSlot::Leaf {
                first: range.start as u32,
                count: range.len() as u32,
            };
            leaves.push((leaf, link));
        }
        let all = union(group_range(i * TOP_WIDTH).start..group_range(i * TOP_WIDTH + 3).end);
        let boxed = distorted(all, &mut rng);
        root.push((boxed, TopSlot::Internal(1 + i as u32)));
        inner.push(node(&leaves));
    }
    TopLevel {
        nodes: std::iter::once(node(&root)).chain(inner).collect(),
        strip_order: (0..bounds.len() as u32).collect(),
    }
}

fn distorted_file(name: &str, seed: u64) -> ReducemFile {
    let params = BuildParams::default();
    let chunk = encode_chunk(&torus(24, 12), &params);
    let bounds = strip_bounds(&chunk.strips);
    assert!(bounds.len() >= GROUPS, "every leaf holds a strip");
    let path = temp_path(name);
    let top = distorted_tree(&bounds, seed);
    let sizes = (params.leaf_windows, params.stripify.max_length);
    write_chunk_under(&chunk, &top, sizes, &path);
    ReducemFile::open(&path).expect("a file with distorted boxes opens")
}

/// Camera rays from several sides (one octant per run), then rays in every octant.
fn rays() -> Vec<Ray> {
    let mut rays = Vec::new();
    for eye in [[0.3, -0.2, 9.0], [-8.0, 1.0, -3.0], [2.0, 8.5, 1.0]] {
        for y in 0..24 {
            for x in 0..24 {
                let target = [x as f32 * 0.3 - 3.5, y as f32 * 0.3 - 3.5, 0.2];
                rays.push(ray_towards(eye, target));
            }
        }
    }
    let mut rng = SplitMix64::new(17);
    for _ in 0..3000 {
        rays.push(random_ray_in_the_slab(&mut rng));
    }
    rays
}

#[test]
fn packets_match_single_rays_on_boxes_that_do_not_bound_their_strips() {
    let rays = rays();
    for seed in 0..40 {
        let file = distorted_file(&format!("distorted-boxes-{seed}.rdm"), seed);
        let single = Tracer::new(
            &file,
            TraceOptions {
                packets: false,
                ..TraceOptions::default()
            },
        );
        let packets = Tracer::new(&file, TraceOptions::default());
        let alone = single.intersect_batch(&rays);
        let together = packets.intersect_batch(&rays);
        for (i, (a, b)) in alone.iter().zip(&together).enumerate() {
            assert_eq!(
                hit_bits(a),
                hit_bits(b),
                "seed {seed}, ray {i}: {:?}",
                rays[i]
            );
        }
        assert_eq!(single.occluded_batch(&rays), packets.occluded_batch(&rays));
    }
}

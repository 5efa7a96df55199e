//! The in-project baseline for the benchmark: a binned-SAH bounding volume hierarchy over an
//! indexed triangle list, the "standard representation" the paper compares ReduceM against
//! (section 5: an AABB BVH with the triangles in a separate list).
//!
//! Layout: 32-byte nodes (box, right child or first triangle, count), a triangle index array
//! reordered by leaf, and the shared vertex array; `memory_bytes` counts all three. Deviation
//! from the paper's comparison: triangles stay indexed (12 bytes plus shared vertices) rather
//! than in a 40-byte precomputed intersection format, so the baseline uses the same watertight
//! intersection as the tracer and the two are compared on traversal and memory layout alone.
//!
//! Traversal is the same as [`reducem::trace::top`]: conservative slab tests from
//! [`PreparedRay`], near child first by the split axis' direction sign, fixed stack.

use reducem::geometry::{Aabb, Point};
use reducem::mesh::Mesh;
use reducem::trace::prepared::PreparedRay;
use reducem::trace::watertight::intersect_triangle;
use reducem::trace::Ray;

/// Bins per axis of the SAH sweep.
const SAH_BINS: usize = 16;
/// Largest leaf.
const MAX_LEAF_TRIANGLES: usize = 4;
/// Cost of a node visit relative to one triangle test, for the SAH termination.
const TRAVERSAL_COST: f32 = 1.0;
/// Deep enough for any tree the median fallback can build over 2^32 triangles.
const STACK: usize = 96;

#[derive(Clone, Copy, Debug, Default)]
struct Node {
    min: Point,
    max: Point,
    /// Internal: right child. Leaf: first entry of `order`.
    payload: u32,
    /// Internal: `0x8000_0000 | axis`. Leaf: triangle count.
    kind: u32,
}

const INTERNAL: u32 = 1 << 31;

/// A SAH BVH over a mesh's triangles.
pub struct TriangleBvh {
    nodes: Vec<Node>,
    triangles: Vec<[u32; 3]>,
    positions: Vec<Point>,
}

/// A closest hit of the baseline: parameter and position of the triangle in the BVH's leaf order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaselineHit {
    pub t: f32,
    pub triangle: u32,
}

struct Builder<'a> {
    boxes: &'a [Aabb],
    centroids: &'a [Point],
    nodes: Vec<Node>,
}

impl TriangleBvh {
    /// Builds over every triangle of `mesh` (the triangles are copied in leaf order).
    pub fn build(mesh: &Mesh) -> TriangleBvh {
        let boxes: Vec<Aabb> = mesh
            .triangles
            .iter()
            .map(|t| Aabb::from_points(&mesh.triangle_points(t)))
            .collect();
        let centroids: Vec<Point> = boxes
            .iter()
            .map(|b| [0, 1, 2].map(|axis| b.centroid(axis)))
            .collect();
        let mut order: Vec<u32> = (0..mesh.triangles.len() as u32).collect();
        let mut builder = Builder {
            boxes: &boxes,
            centroids: &centroids,
            nodes: Vec::with_capacity(2 * order.len() / MAX_LEAF_TRIANGLES + 1),
        };
        builder.build(&mut order, 0);
        TriangleBvh {
            nodes: builder.nodes,
            triangles: order.iter().map(|&i| mesh.triangles[i as usize]).collect(),
            positions: mesh.positions.clone(),
        }
    }

    /// Bytes of nodes, triangle indices and vertices.
    pub fn memory_bytes(&self) -> u64 {
        (self.nodes.len() * std::mem::size_of::<Node>()
            + self.triangles.len() * 12
            + self.positions.len() * 12) as u64
    }

    pub fn intersect(&self, ray: &Ray) -> Option<BaselineHit> {
        let mut best = None;
        self.traverse(ray, |t, triangle| {
            best = Some(BaselineHit { t, triangle });
            false
        });
        best
    }

    pub fn occluded(&self, ray: &Ray) -> bool {
        let mut found = false;
        self.traverse(ray, |_, _| {
            found = true;
            true
        });
        found
    }

    /// Visits leaves front to back; `on_hit` is called with every hit nearer than the previous
    /// ones and returns whether to stop.
    fn traverse(&self, ray: &Ray, mut on_hit: impl FnMut(f32, u32) -> bool) {
        let prepared = PreparedRay::new(ray);
        let mut t_far = ray.tmax;
        let mut stack = [(0u32, 0f32); STACK];
        let mut depth = 0;
        let root = &self.nodes[0];
        let Some((t_near, _)) = prepared.clip_box(&root.min, &root.max, ray.tmin, t_far) else {
            return;
        };
        let mut current = (0u32, t_near);
        loop {
            let node = &self.nodes[current.0 as usize];
            if node.kind & INTERNAL != 0 {
                let axis = (node.kind & 3) as usize;
                let (left, right) = (current.0 + 1, node.payload);
                let (near, far) = if prepared.negative[axis] {
                    (right, left)
                } else {
                    (left, right)
                };
                let clip = |index: u32| {
                    let child = &self.nodes[index as usize];
                    prepared
                        .clip_box(&child.min, &child.max, ray.tmin, t_far)
                        .map(|(t, _)| (index, t))
                };
                match (clip(near), clip(far)) {
                    (Some(a), Some(b)) => {
                        stack[depth] = b;
                        depth += 1;
                        current = a;
                        continue;
                    }
                    (Some(only), None) | (None, Some(only)) => {
                        current = only;
                        continue;
                    }
                    (None, None) => {}
                }
            } else {
                let first = node.payload as usize;
                for index in first..first + node.kind as usize {
                    let corners = self.triangles[index].map(|v| self.positions[v as usize]);
                    if let Some(hit) =
                        intersect_triangle(&prepared.space, &corners, ray.tmin, t_far)
                    {
                        t_far = hit.t;
                        if on_hit(hit.t, index as u32) {
                            return;
                        }
                    }
                }
            }
            loop {
                if depth == 0 {
                    return;
                }
                depth -= 1;
                if stack[depth].1 <= t_far {
                    current = stack[depth];
                    break;
                }
            }
        }
    }
}

impl Builder<'_> {
    /// Builds the subtree over `items` (triangle indices) and returns its node index.
    fn build(&mut self, items: &mut [u32], first: u32) -> u32 {
        let index = self.nodes.len() as u32;
        let bounds = items
            .iter()
            .fold(Aabb::EMPTY, |b, &i| b.union(&self.boxes[i as usize]));
        self.nodes.push(Node {
            min: bounds.min,
            max: bounds.max,
            payload: first,
            kind: items.len() as u32,
        });
        if items.len() <= 1 {
            return index;
        }
        let split = self.sah_split(items, &bounds);
        let (axis, mid) = match split {
            Some(split) => split,
            None if items.len() <= MAX_LEAF_TRIANGLES => return index,
            None => self.median_split(items, &bounds),
        };
        let (left, right) = items.split_at_mut(mid);
        self.build(left, first);
        let right_index = self.build(right, first + mid as u32);
        self.nodes[index as usize].payload = right_index;
        self.nodes[index as usize].kind = INTERNAL | axis as u32;
        index
    }

    /// The best binned-SAH partition of `items`, applied in place, or `None` when a leaf is
    /// cheaper (and allowed).
    fn sah_split(&self, items: &mut [u32], bounds: &Aabb) -> Option<(usize, usize)> {
        let centroid_box = Aabb::from_points(items.iter().map(|&i| &self.centroids[i as usize]));
        let leaf_cost = items.len() as f32;
        let mut best: Option<(f32, usize, usize)> = None;
        for axis in 0..3 {
            let extent = centroid_box.extent(axis);
            if extent <= 0.0 {
                continue;
            }
            let bin_of = |i: u32| {
                let offset = (self.centroids[i as usize][axis] - centroid_box.min[axis]) / extent;
                ((offset * SAH_BINS as f32) as usize).min(SAH_BINS - 1)
            };
            let mut bins = [(Aabb::EMPTY, 0usize); SAH_BINS];
            for &i in items.iter() {
                let bin = &mut bins[bin_of(i)];
                bin.0.grow(&self.boxes[i as usize]);
                bin.1 += 1;
            }
            let mut right_area = [0.0f32; SAH_BINS];
            let mut right = (Aabb::EMPTY, 0usize);
            for b in (1..SAH_BINS).rev() {
                right.0.grow(&bins[b].0);
                right.1 += bins[b].1;
                right_area[b] = right.0.surface_area() as f32 * right.1 as f32;
            }
            let mut left = (Aabb::EMPTY, 0usize);
            for b in 0..SAH_BINS - 1 {
                left.0.grow(&bins[b].0);
                left.1 += bins[b].1;
                let cost = left.0.surface_area() as f32 * left.1 as f32 + right_area[b + 1];
                if left.1 > 0 && left.1 < items.len() && best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, axis, b));
                }
            }
        }
        let (cost, axis, last_left_bin) = best?;
        let area = bounds.surface_area() as f32;
        let split_cost = TRAVERSAL_COST + cost / area.max(f32::MIN_POSITIVE);
        if split_cost >= leaf_cost && items.len() <= MAX_LEAF_TRIANGLES {
            return None;
        }
        let extent = centroid_box.extent(axis);
        let in_left = |i: &u32| {
            let offset = (self.centroids[*i as usize][axis] - centroid_box.min[axis]) / extent;
            ((offset * SAH_BINS as f32) as usize).min(SAH_BINS - 1) <= last_left_bin
        };
        let mid = partition(items, in_left);
        Some((axis, mid))
    }

    /// Halves `items` by centroid on the longest axis: the fallback when all centroids coincide.
    fn median_split(&self, items: &mut [u32], bounds: &Aabb) -> (usize, usize) {
        let axis = bounds.longest_axis();
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |&a, &b| {
            self.centroids[a as usize][axis].total_cmp(&self.centroids[b as usize][axis])
        });
        (axis, mid)
    }
}

/// Moves the items satisfying `predicate` to the front; returns how many there are.
fn partition(items: &mut [u32], predicate: impl Fn(&u32) -> bool) -> usize {
    let mut boundary = 0;
    for i in 0..items.len() {
        if predicate(&items[i]) {
            items.swap(boundary, i);
            boundary += 1;
        }
    }
    boundary
}

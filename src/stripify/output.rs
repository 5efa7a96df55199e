//! Strip-RT step 4, strip output (paper 4.1, "Strip output"; the sequence → strip conversion
//! follows the classic approach the paper cites, [ESV96]).
//!
//! The first triangle is rotated (a rotation keeps its winding) so that its exit edge, the
//! edge shared with the next triangle, forms the last two references. Every following triangle
//! enters through the last two references `(p, q)` and adds its third vertex `v`. When it
//! leaves through `{q, v}`, appending `v` suffices; when it leaves through `{p, v}`, a swap is
//! needed first: appending `p` creates the degenerate window `(p, q, p)` and makes `(q, p)` the
//! last two references (paper 3.2, "ABA").
//!
//! Where the swaps fall: a triangle's turn (see [`Adjacency::turn`]) decides whether it sits
//! on an even or an odd window, and a swap-free strip alternates between the two. So a swap
//! falls between two consecutive interior triangles with equal turns, and before the second
//! triangle when its turn is [`TURN_TO_NEXT_EDGE`] (the first triangle, at window 0, acts like
//! an interior triangle with that turn). The rotation of the first triangle is forced by its
//! exit edge, so the only free choice is the end a path is walked from. Deviation from the
//! paper, which does not discuss swaps: each path is walked from the end with the smaller
//! local triangle id unless only the other end avoids that opening swap. Reversing a path
//! exchanges the two turns, so the swaps between interior triangles stay the same and the
//! opening swap is avoided whenever either end allows it. The ordering step minimises the
//! swaps between interior triangles.
//!
//! Winding needs no bookkeeping: adjacency only links neighbours that traverse their shared
//! edge in opposite directions, and under the parity rule of [`crate::strip_windows`] a new triangle
//! entering through the oppositely traversed edge decodes in its input winding, with or without
//! a swap (the swap shifts the window parity and reverses the edge at the same time).
//!
//! There is at most one swap per triangle, so a strip of `L` triangles has at most `2L + 1`
//! references: 121 for the paper's limit of 60, within its one-byte vertex indices.
//!
//! Strips come out in the order of their smaller end triangle, that is, roughly in input order,
//! and depend on nothing but the paths.

use rayon::prelude::*;

use super::adjacency::{Adjacency, TURN_TO_NEXT_EDGE};
use super::ordering::{Paths, NO_LINK};
use crate::mesh::Mesh;

/// One strip as mesh vertex indices, with the mesh triangle of each real window.
pub(crate) struct OutputStrip {
    pub references: Vec<u32>,
    pub triangles: Vec<u32>,
}

/// Converts every path (of at most `max_length` triangles) into a strip of mesh vertex indices.
pub(crate) fn strips(
    mesh: &Mesh,
    adjacency: &Adjacency,
    paths: &Paths,
    max_length: usize,
) -> Vec<OutputStrip> {
    let smaller_ends: Vec<u32> = (0..adjacency.kept.len() as u32)
        .filter(|&t| paths.is_end(t) && t <= paths.other_end[t as usize])
        .collect();
    let writer = StripWriter {
        mesh,
        adjacency,
        paths,
        capacity: max_length.clamp(1, 64),
    };
    smaller_ends
        .par_iter()
        .map(|&end| writer.strip_from(writer.start_of(end)))
        .collect()
}

struct StripWriter<'a> {
    mesh: &'a Mesh,
    adjacency: &'a Adjacency,
    paths: &'a Paths,
    /// Triangles to reserve room for per strip: a strip is allocated once, not grown.
    capacity: usize,
}

impl StripWriter<'_> {
    fn vertices(&self, local: u32) -> [u32; 3] {
        self.mesh.triangles[self.mesh_triangle(local) as usize]
    }

    /// The path triangle after `current` when coming from `previous` (or from outside the path).
    fn next_on_path(&self, previous: u32, current: u32) -> Option<u32> {
        let links = self.paths.links[current as usize];
        let next = if links[0] == previous {
            links[1]
        } else {
            links[0]
        };
        (next != NO_LINK).then_some(next)
    }

    /// The end to walk the path ending at `end` from: `end` unless only the other end avoids
    /// the opening swap.
    fn start_of(&self, end: u32) -> u32 {
        let other = self.paths.other_end[end as usize];
        if self.needs_opening_swap(end) && !self.needs_opening_swap(other) {
            other
        } else {
            end
        }
    }

    /// Whether a strip walked from `start` needs a swap before its second triangle.
    fn needs_opening_swap(&self, start: u32) -> bool {
        let Some(second) = self.next_on_path(NO_LINK, start) else {
            return false;
        };
        let Some(third) = self.next_on_path(start, second) else {
            return false;
        };
        self.adjacency.turn(start, second, third) == TURN_TO_NEXT_EDGE
    }

    /// The mesh triangle of path triangle `local`.
    fn mesh_triangle(&self, local: u32) -> u32 {
        self.adjacency.kept[local as usize]
    }

    fn strip_from(&self, start: u32) -> OutputStrip {
        let first = self.vertices(start);
        let mut triangles = Vec::with_capacity(self.capacity);
        triangles.push(self.mesh_triangle(start));
        let Some(mut current) = self.next_on_path(NO_LINK, start) else {
            return OutputStrip {
                references: first.to_vec(),
                triangles,
            };
        };
        let exit = self.adjacency.edge_towards(start, current);
        let mut strip = Vec::with_capacity(2 * self.capacity + 1);
        strip.extend([first[(exit + 2) % 3], first[exit], first[(exit + 1) % 3]]);
        let mut previous = start;
        loop {
            let following = self.next_on_path(previous, current);
            self.append_triangle(&mut strip, current, following);
            triangles.push(self.mesh_triangle(current));
            let Some(following) = following else {
                return OutputStrip {
                    references: strip,
                    triangles,
                };
            };
            previous = current;
            current = following;
        }
    }

    /// Appends `triangle`, which enters through the last two references, so that its exit edge
    /// toward `following` (if any) becomes the last two references.
    fn append_triangle(&self, strip: &mut Vec<u32>, triangle: u32, following: Option<u32>) {
        let [p, q] = [strip[strip.len() - 2], strip[strip.len() - 1]];
        let vertices = self.vertices(triangle);
        let new_vertex = vertices
            .into_iter()
            .find(|&v| v != p && v != q)
            .expect("a path triangle shares its entry edge with the strip end");
        if let Some(following) = following {
            let exit = self.adjacency.edge_towards(triangle, following);
            let exit_vertices = [vertices[exit], vertices[(exit + 1) % 3]];
            if exit_vertices.contains(&p) {
                strip.push(p);
            }
        }
        strip.push(new_vertex);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stripify::ordering::{order, tests::random_grid};
    use crate::stripify::partition::TriangleTree;

    /// The path from `start` as a triangle list.
    fn walk(writer: &StripWriter, start: u32) -> Vec<u32> {
        let mut path = vec![start];
        let mut previous = NO_LINK;
        while let Some(next) = writer.next_on_path(previous, *path.last().unwrap()) {
            previous = *path.last().unwrap();
            path.push(next);
        }
        path
    }

    /// Swaps predicted from turns alone: before the second triangle when it turns to the next
    /// edge, and between consecutive interior triangles with equal turns.
    fn predicted_swaps(adjacency: &Adjacency, path: &[u32]) -> usize {
        let turns: Vec<u8> = path
            .windows(3)
            .map(|w| adjacency.turn(w[0], w[1], w[2]))
            .collect();
        let opening = turns.first() == Some(&TURN_TO_NEXT_EDGE);
        usize::from(opening) + turns.windows(2).filter(|pair| pair[0] == pair[1]).count()
    }

    /// The turn rule of the module docs agrees with the swap windows the output really has, and
    /// the end choice leaves an opening swap only where both ends need one.
    #[test]
    fn swaps_follow_the_turns() {
        for seed in 1..8 {
            let mesh = random_grid(30, seed);
            let adjacency = Adjacency::build(&mesh);
            let hierarchy = TriangleTree::build(&mesh, &adjacency.kept, 8);
            let paths = order(&adjacency, &hierarchy, 60);
            let writer = StripWriter {
                mesh: &mesh,
                adjacency: &adjacency,
                paths: &paths,
                capacity: 60,
            };
            let (mut swaps, mut opening_swaps_avoided) = (0, 0);
            for end in (0..adjacency.kept.len() as u32).filter(|&t| paths.is_end(t)) {
                let start = writer.start_of(end);
                let strip = writer.strip_from(start).references;
                let real = crate::strip_windows::triangles(&strip).count();
                let path = walk(&writer, start);
                assert_eq!(strip.len() - 2 - real, predicted_swaps(&adjacency, &path));
                swaps += strip.len() - 2 - real;
                let reversed: Vec<u32> = path.iter().rev().copied().collect();
                let both_ends_need_it = [&path, &reversed]
                    .iter()
                    .all(|p| p.len() > 2 && adjacency.turn(p[0], p[1], p[2]) == TURN_TO_NEXT_EDGE);
                let opening = path.len() > 2
                    && adjacency.turn(path[0], path[1], path[2]) == TURN_TO_NEXT_EDGE;
                assert_eq!(opening, both_ends_need_it);
                opening_swaps_avoided += usize::from(start != end);
            }
            assert!(swaps > 0 && opening_swaps_avoided > 0);
        }
    }
}

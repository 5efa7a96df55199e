//! Strip-RT step 4, strip output (paper 4.1, "Strip output"; the sequence → strip conversion
//! follows the classic approach the paper cites, [ESV96]).
//!
//! Each path is walked from its end with the smaller local triangle id, so the output does not
//! depend on anything but the paths. The first triangle is rotated (a rotation keeps its
//! winding) so that its exit edge, the edge shared with the next triangle, forms the last two
//! references. Every following triangle enters through the last two references `(p, q)` and
//! adds its third vertex `v`. When it leaves through `{q, v}`, appending `v` suffices; when it
//! leaves through `{p, v}`, a swap is needed first: appending `p` creates the degenerate window
//! `(p, q, p)` and makes `(q, p)` the last two references (paper 3.2, "ABA").
//!
//! Winding needs no bookkeeping: adjacency only links neighbours that traverse their shared
//! edge in opposite directions, and under the parity rule of [`crate::strip`] a new triangle
//! entering through the oppositely traversed edge decodes in its input winding, with or without
//! a swap (the swap shifts the window parity and reverses the edge at the same time).
//!
//! There is at most one swap per triangle, so a strip of `L` triangles has at most `2L + 1`
//! references: 121 for the paper's limit of 60, within its one-byte vertex indices.
//!
//! Strips come out in the order of their starting triangle, that is, roughly in input order.

use rayon::prelude::*;

use super::adjacency::Adjacency;
use super::ordering::{Paths, NO_LINK};
use crate::mesh::Mesh;

/// Converts every path into a strip of mesh vertex indices.
pub fn strips(mesh: &Mesh, adjacency: &Adjacency, paths: &Paths) -> Vec<Vec<u32>> {
    let starts: Vec<u32> = (0..adjacency.kept.len() as u32)
        .filter(|&t| paths.is_end(t) && t <= paths.other_end[t as usize])
        .collect();
    let writer = StripWriter {
        mesh,
        adjacency,
        paths,
    };
    starts
        .par_iter()
        .map(|&start| writer.strip_from(start))
        .collect()
}

struct StripWriter<'a> {
    mesh: &'a Mesh,
    adjacency: &'a Adjacency,
    paths: &'a Paths,
}

impl StripWriter<'_> {
    fn vertices(&self, local: u32) -> [u32; 3] {
        self.mesh.triangles[self.adjacency.kept[local as usize] as usize]
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

    /// Index `i` of the edge `(v_i, v_{i+1})` of `triangle` shared with its path neighbour `next`.
    fn exit_edge_index(&self, triangle: u32, next: u32) -> usize {
        self.adjacency.neighbours[triangle as usize]
            .iter()
            .position(|&n| n == next)
            .expect("path links always join adjacent triangles")
    }

    fn strip_from(&self, start: u32) -> Vec<u32> {
        let first = self.vertices(start);
        let Some(mut current) = self.next_on_path(NO_LINK, start) else {
            return first.to_vec();
        };
        let exit = self.exit_edge_index(start, current);
        let mut strip = vec![first[(exit + 2) % 3], first[exit], first[(exit + 1) % 3]];
        let mut previous = start;
        loop {
            let following = self.next_on_path(previous, current);
            self.append_triangle(&mut strip, current, following);
            let Some(following) = following else {
                return strip;
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
            let exit = self.exit_edge_index(triangle, following);
            let exit_vertices = [vertices[exit], vertices[(exit + 1) % 3]];
            if exit_vertices.contains(&p) {
                strip.push(p);
            }
        }
        strip.push(new_vertex);
    }
}

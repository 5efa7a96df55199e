//! The marching-cubes case table, derived from first principles at start-up
//! instead of typed in, so that it is watertight by construction.
//!
//! For each of the 256 inside/outside patterns of a cube's corners, the
//! surface is traced on the cube's six faces: on every face, each run of
//! inside corners (in counter-clockwise order seen from outside) is cut off by
//! one segment joining the edge where the run starts to the edge where it
//! ends. On an ambiguous face (inside corners diagonal) the two runs get two
//! segments, i.e. inside corners are always separated. Because this rule
//! depends only on the face's four corners, the two cubes sharing a face
//! always cut it identically, which is what makes the surface crack-free; the
//! classic hand-written 256-entry table lacks that guarantee.
//!
//! Each crossing edge starts a segment on one of its two cube faces and ends
//! one on the other, so the segments chain into closed polygons. Segments
//! keep the inside on their right seen from outside, which winds the polygons
//! counter-clockwise seen from the outside of the solid (normals point from
//! inside to outside), and the shared face is traversed in opposite
//! directions by its two cubes.
//!
//! Polygons are fanned into triangles. A fan diagonal must not join two edges
//! on a common cube face, or the neighbouring cube might fan the same pair
//! and the diagonal would be shared by four triangles. Every polygon of the
//! 256 cases has an apex whose diagonals all cross the cube's interior (the
//! builder checks this), so no extra vertices are needed.

// Cube corner `c` sits at offset `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`.

/// The 12 cube edges as (lower corner, upper corner): four along x, then
/// four along y, then four along z, so `edge / 4` is the edge's axis.
pub const EDGE_CORNERS: [(u8, u8); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// The surface inside a cube with a given corner pattern: triangles whose
/// corners are the crossings on the given cube edges.
pub type Case = Vec<[u8; 3]>;

/// Cases indexed by the pattern whose bit `c` is set when corner `c` is
/// inside.
pub fn case_table() -> Vec<Case> {
    let faces = cube_faces();
    (0..=255u8)
        .map(|pattern| build_case(pattern, &faces))
        .collect()
}

/// The six faces' corners, counter-clockwise seen from outside the cube.
fn cube_faces() -> [[u8; 4]; 6] {
    let mut faces = [[0; 4]; 6];
    for (index, face) in faces.iter_mut().enumerate() {
        let (axis, side) = (index / 2, (index % 2) as u8);
        let (first, second) = ((axis + 1) % 3, (axis + 2) % 3);
        // (first, second) is right-handed about +axis, so the square
        // (0,0) (1,0) (1,1) (0,1) runs counter-clockwise seen from +axis.
        let mut square = [(0, 0), (1, 0), (1, 1), (0, 1)];
        if side == 0 {
            square.reverse();
        }
        *face = square.map(|(a, b)| (side << axis) | (a << first) | (b << second));
    }
    faces
}

fn edge_between(a: u8, b: u8) -> u8 {
    let key = (a.min(b), a.max(b));
    EDGE_CORNERS
        .iter()
        .position(|&edge| edge == key)
        .expect("adjacent corners") as u8
}

/// Bit `f` set when the edge lies on cube face `f`.
fn faces_of_edge(edge: u8, faces: &[[u8; 4]; 6]) -> u8 {
    let (a, b) = EDGE_CORNERS[edge as usize];
    (0..6)
        .filter(|&f| faces[f].contains(&a) && faces[f].contains(&b))
        .fold(0, |mask, f| mask | (1 << f))
}

fn build_case(pattern: u8, faces: &[[u8; 4]; 6]) -> Case {
    let inside = |corner: u8| pattern & (1 << corner) != 0;
    let mut next_edge = [None; 12];
    for face in faces {
        for start in 0..4 {
            let (before, first) = (face[start], face[(start + 1) % 4]);
            if inside(before) || !inside(first) {
                continue;
            }
            let run_end = (1..=4)
                .map(|step| (start + step) % 4)
                .find(|&k| !inside(face[(k + 1) % 4]))
                .expect("a run entered from outside also leaves");
            let entry = edge_between(before, first);
            let exit = edge_between(face[run_end], face[(run_end + 1) % 4]);
            next_edge[entry as usize] = Some(exit);
        }
    }
    let mut case = Case::new();
    let mut visited = [false; 12];
    for start in 0..12u8 {
        if visited[start as usize] || next_edge[start as usize].is_none() {
            continue;
        }
        let mut polygon = vec![start];
        visited[start as usize] = true;
        while let Some(edge) = next_edge[*polygon.last().unwrap() as usize].filter(|&e| e != start)
        {
            visited[edge as usize] = true;
            polygon.push(edge);
        }
        triangulate(&polygon, faces, &mut case);
    }
    case
}

fn triangulate(polygon: &[u8], faces: &[[u8; 4]; 6], case: &mut Case) {
    let n = polygon.len();
    let face_masks: Vec<u8> = polygon.iter().map(|&e| faces_of_edge(e, faces)).collect();
    // A fan from `apex` has diagonals to every polygon vertex but its two
    // neighbours; all of them must cross the cube's interior.
    let apex = (0..n)
        .find(|&apex| {
            (2..n - 1).all(|offset| face_masks[apex] & face_masks[(apex + offset) % n] == 0)
        })
        .expect("every marching-cubes polygon has an interior fan");
    let corner = |k: usize| polygon[(apex + k) % n];
    for offset in 1..n - 1 {
        case.push([corner(0), corner(offset), corner(offset + 1)]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_inside_corner_gives_one_triangle_facing_away_from_it() {
        let table = case_table();
        assert!(table[0].is_empty() && table[255].is_empty());
        // Corner 0 inside: the triangle on its x, y, z edges (0, 4, 8) must be
        // counter-clockwise seen from (1,1,1), i.e. x -> y -> z cyclically.
        let triangle = &table[1];
        assert_eq!(triangle.len(), 1);
        let rotations = [[0, 4, 8], [4, 8, 0], [8, 0, 4]];
        assert!(rotations.contains(&triangle[0]), "{triangle:?}");
    }

    #[test]
    fn every_crossing_edge_is_on_the_surface() {
        for (pattern, case) in case_table().iter().enumerate() {
            let crossing = (0..12).filter(|&e| {
                let (a, b) = EDGE_CORNERS[e];
                (pattern >> a & 1) != (pattern >> b & 1)
            });
            for edge in crossing {
                let used = case.iter().flatten().any(|&c| c == edge as u8);
                assert!(used, "pattern {pattern:#010b} misses edge {edge}");
            }
        }
    }
}

//! Spatial partition of a massive mesh into chunks that fit in memory (paper 4.2: "we first
//! decompose an input model into small chunks, each of which fits into main memory").
//!
//! The model bounds are cut into a grid of 32 × 32 × 32 cells numbered in Morton order, so that
//! consecutive cell numbers are spatially close. A triangle belongs to the cell of its first
//! vertex: that needs only a 2-byte cell number per vertex during the partition pass, not the
//! positions of all three corners (the one model-sized array of the pipeline, 2 bytes per
//! vertex). Cells are then taken in Morton order and packed greedily into chunks of at most
//! `max_triangles`; a cell that alone exceeds the limit is dealt out over several chunks of its
//! own in input order. Chunks are therefore compact regions of space, which keeps strips and the
//! per-chunk hierarchies local, and their boundaries are the only places where strips cannot
//! continue.
//!
//! Attributes travel with the triangles and vertices: every triangle carries its global input
//! face id through the partition, and a chunk's vertices get their normals and colours from
//! the source the way they get their positions, for the chosen vertices only, so memory stays
//! bounded by the chunk.

use crate::geometry::{Aabb, Point};
use crate::input::{
    pick, tolerance_representatives, AttributeRequest, InputError, VertexAttributes, Vertices,
    WeldStats,
};
use crate::mesh::Mesh;

/// The source trait and its opener live with the readers; these names stay for callers.
pub use crate::input::{open_source, MeshSource};

/// A source whose triangles refer to `representative[v]` instead of `v`: the result of a
/// tolerance weld over the whole model.
struct Remapped {
    source: Box<dyn MeshSource>,
    representative: Vec<u32>,
}

impl MeshSource for Remapped {
    fn vertex_count(&self) -> u64 {
        self.source.vertex_count()
    }

    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        self.source.for_each_position_window(visit)
    }

    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        self.source.for_each_triangle(&mut |index, triangle| {
            visit(index, triangle.map(|v| self.representative[v as usize]));
        })
    }

    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError> {
        self.source.positions_of(sorted_ids)
    }

    fn attributes_of(&self, sorted_ids: &[u32]) -> Result<VertexAttributes, InputError> {
        self.source.attributes_of(sorted_ids)
    }
}

/// A source whose vertices sit at `representative[v]`'s position but keep their own
/// attributes: the tolerance weld of a model with attributes. Triangles keep their vertices,
/// so a vertex whose attributes differ from its representative's stays a vertex of its own;
/// the chunk's exact weld then joins the vertices whose positions and attributes now match.
struct Snapped {
    source: Box<dyn MeshSource>,
    representative: Vec<u32>,
}

impl MeshSource for Snapped {
    fn vertex_count(&self) -> u64 {
        self.source.vertex_count()
    }

    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        self.source.for_each_position_window(visit)
    }

    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        self.source.for_each_triangle(visit)
    }

    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError> {
        let representatives: Vec<u32> = pick(&self.representative, sorted_ids);
        let mut distinct = representatives.clone();
        distinct.sort_unstable();
        distinct.dedup();
        let positions = self.source.positions_of(&distinct)?;
        Ok(representatives
            .iter()
            .map(|r| positions[distinct.partition_point(|d| d < r)])
            .collect())
    }

    fn attributes_of(&self, sorted_ids: &[u32]) -> Result<VertexAttributes, InputError> {
        self.source.attributes_of(sorted_ids)
    }
}

/// Merges vertices of the whole model within `tolerance` (the clustering of
/// [`weld_within_tolerance`](crate::input::weld_within_tolerance)), so that every chunk sees the
/// same merged vertices. With a positive tolerance this holds every position in memory while the
/// merge is computed (12 bytes per vertex) and keeps the map (4 bytes per vertex); a zero
/// tolerance returns the source as it is. With attributes
/// (`request`), vertices move to their representative's position and keep their attributes
/// ([`Snapped`]); without, triangles are remapped to the representatives, as before
/// attributes existed, so such files stay byte-identical.
pub fn weld_source(
    source: Box<dyn MeshSource>,
    tolerance: f32,
    request: AttributeRequest,
) -> Result<(Box<dyn MeshSource>, WeldStats), InputError> {
    if tolerance.is_nan() || tolerance <= 0.0 {
        return Ok((source, WeldStats::default()));
    }
    let mut positions = Vec::with_capacity(source.vertex_count() as usize);
    source.for_each_position_window(&mut |_, window| positions.extend_from_slice(window))?;
    let (representative, stats) = tolerance_representatives(&positions, tolerance);
    drop(positions);
    if request.any() {
        let snapped = Snapped {
            source,
            representative,
        };
        return Ok((Box::new(snapped), stats));
    }
    let welded = Remapped {
        source,
        representative,
    };
    Ok((Box::new(welded), stats))
}

/// The partition of a source: the plan, and each vertex's cell (which [`distribute`] needs).
pub struct Partition {
    pub plan: ChunkPlan,
    pub vertex_cells: Vec<u16>,
    pub bounds: Aabb,
}

/// Three passes: bounds, the cell of every vertex, the triangle count of every cell; then packs
/// cells into chunks of at most `max_triangles`.
pub fn partition(source: &dyn MeshSource, max_triangles: u64) -> Result<Partition, InputError> {
    let mut bounds = Aabb::EMPTY;
    source.for_each_position_window(&mut |_, positions| {
        bounds.grow(&Aabb::from_points(positions));
    })?;
    let grid = CellGrid::new(&bounds);
    let mut vertex_cells = Vec::with_capacity(source.vertex_count() as usize);
    source.for_each_position_window(&mut |_, positions| {
        vertex_cells.extend(positions.iter().map(|p| grid.cell(p)));
    })?;
    let mut triangles_per_cell = vec![0u64; CELL_COUNT];
    source.for_each_triangle(&mut |_, triangle| {
        triangles_per_cell[vertex_cells[triangle[0] as usize] as usize] += 1;
    })?;
    Ok(Partition {
        plan: ChunkPlan::new(&triangles_per_cell, max_triangles),
        vertex_cells,
        bounds,
    })
}

impl Partition {
    /// The cell of `point` on the partition's grid.
    pub fn cell_of(&self, point: &Point) -> u16 {
        CellGrid::new(&self.bounds).cell(point)
    }
}

/// One more pass handing every triangle, in input order, to `sink(chunk, face_id, triangle)`.
pub fn distribute(
    source: &dyn MeshSource,
    partition: &Partition,
    sink: &mut dyn FnMut(u32, u64, [u32; 3]),
) -> Result<(), InputError> {
    let mut seen_per_cell = vec![0u64; CELL_COUNT];
    source.for_each_triangle(&mut |face, triangle| {
        let cell = partition.vertex_cells[triangle[0] as usize];
        let ordinal = &mut seen_per_cell[cell as usize];
        sink(partition.plan.chunk_of(cell, *ordinal), face, triangle);
        *ordinal += 1;
    })
}

/// Morton bits per axis; 3 × 5 = 15 bits, so a cell number fits a u16.
const BITS_PER_AXIS: u32 = 5;
/// Number of cells of the grid.
const CELL_COUNT: usize = 1 << (3 * BITS_PER_AXIS);

/// The Morton-ordered cell grid over a model's bounds.
#[derive(Clone, Copy, Debug)]
struct CellGrid {
    min: Point,
    scale: [f32; 3],
}

impl CellGrid {
    fn new(bounds: &Aabb) -> CellGrid {
        let cells = (1u32 << BITS_PER_AXIS) as f32;
        let scale = [0, 1, 2].map(|axis| {
            let extent = bounds.extent(axis);
            if extent > 0.0 && extent.is_finite() {
                cells / extent
            } else {
                0.0
            }
        });
        CellGrid {
            min: bounds.min,
            scale,
        }
    }

    /// The Morton number of the cell containing `point`.
    fn cell(&self, point: &Point) -> u16 {
        let last = (1u32 << BITS_PER_AXIS) - 1;
        let coordinate = |axis: usize| {
            let offset = (point[axis] - self.min[axis]) * self.scale[axis];
            (offset.max(0.0) as u32).min(last)
        };
        interleave([coordinate(0), coordinate(1), coordinate(2)])
    }
}

fn interleave(coordinates: [u32; 3]) -> u16 {
    let mut code = 0u16;
    for bit in 0..BITS_PER_AXIS {
        for (axis, c) in coordinates.iter().enumerate() {
            code |= (((c >> bit) & 1) as u16) << (3 * bit + axis as u32);
        }
    }
    code
}

/// Which chunk each triangle goes to, given its cell and its ordinal among that cell's
/// triangles in input order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChunkPlan {
    first_chunk: Vec<u32>,
    oversized: Vec<bool>,
    max_triangles: u64,
    chunk_count: u32,
}

impl ChunkPlan {
    /// Packs cells in Morton order into chunks of at most `max_triangles` (≥ 1) triangles.
    pub fn new(triangles_per_cell: &[u64], max_triangles: u64) -> ChunkPlan {
        let max_triangles = max_triangles.max(1);
        let mut plan = ChunkPlan {
            first_chunk: vec![0; triangles_per_cell.len()],
            oversized: vec![false; triangles_per_cell.len()],
            max_triangles,
            chunk_count: 0,
        };
        let mut fill = 0u64;
        for (cell, &count) in triangles_per_cell.iter().enumerate() {
            if count == 0 {
                continue;
            }
            if count > max_triangles {
                plan.first_chunk[cell] = plan.chunk_count;
                plan.oversized[cell] = true;
                plan.chunk_count += count.div_ceil(max_triangles) as u32;
                fill = max_triangles;
                continue;
            }
            if plan.chunk_count == 0 || fill + count > max_triangles {
                plan.chunk_count += 1;
                fill = 0;
            }
            plan.first_chunk[cell] = plan.chunk_count - 1;
            fill += count;
        }
        plan
    }

    pub fn chunk_count(&self) -> usize {
        self.chunk_count as usize
    }

    /// The one chunk that holds every triangle of `cell`; `None` when the cell is dealt out
    /// over several.
    pub fn home_chunk(&self, cell: u16) -> Option<u32> {
        let cell = cell as usize;
        (!self.oversized[cell]).then_some(self.first_chunk[cell])
    }

    /// The chunk of the `ordinal`-th triangle (in input order) of `cell`.
    pub fn chunk_of(&self, cell: u16, ordinal: u64) -> u32 {
        let cell = cell as usize;
        let extra = if self.oversized[cell] {
            (ordinal / self.max_triangles) as u32
        } else {
            0
        };
        self.first_chunk[cell] + extra
    }
}

/// Builds a chunk's mesh from its triangles as global vertex indices: the distinct vertices,
/// ascending, become the chunk's local vertex array, with positions and attributes from
/// `vertices_of`. `face_ids` (the triangles' input faces, when kept) pass through.
///
/// One sort of (vertex, corner) keys finds the distinct vertices and every corner's local
/// index together, instead of a binary search per corner.
pub fn local_mesh<E>(
    triangles: &[[u32; 3]],
    face_ids: Option<Vec<u32>>,
    vertices_of: impl FnOnce(&[u32]) -> Result<Vertices, E>,
) -> Result<Mesh, E> {
    let corners = triangles.as_flattened();
    let mut keys: Vec<u64> = corners
        .iter()
        .enumerate()
        .map(|(corner, &vertex)| (vertex as u64) << 32 | corner as u64)
        .collect();
    keys.sort_unstable();
    let mut distinct: Vec<u32> = Vec::new();
    let mut local = vec![0u32; corners.len()];
    for key in keys {
        let vertex = (key >> 32) as u32;
        if distinct.last() != Some(&vertex) {
            distinct.push(vertex);
        }
        local[key as u32 as usize] = distinct.len() as u32 - 1;
    }
    let vertices = vertices_of(&distinct)?;
    Ok(Mesh {
        positions: vertices.positions,
        triangles: local.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        face_ids,
        normals: vertices.normals,
        colors: vertices.colors,
    })
}

/// Positions and attributes of `sorted_ids`, for [`local_mesh`].
pub fn vertices_of(source: &dyn MeshSource, sorted_ids: &[u32]) -> Result<Vertices, InputError> {
    let positions = source.positions_of(sorted_ids)?;
    let VertexAttributes { normals, colors } = source.attributes_of(sorted_ids)?;
    Ok(Vertices {
        positions,
        normals,
        colors,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_pack_in_order_and_big_cells_get_their_own_chunks() {
        let mut counts = vec![0u64; 8];
        counts[0] = 3;
        counts[1] = 4;
        counts[2] = 10;
        counts[5] = 2;
        let plan = ChunkPlan::new(&counts, 5);
        // [cell 0: 3] [cell 1: 4] [cell 2: 5 + 5] [cell 5: 2]
        assert_eq!(plan.chunk_count(), 5);
        assert_eq!(plan.chunk_of(0, 2), 0);
        assert_eq!(plan.chunk_of(1, 0), 1);
        assert_eq!(plan.chunk_of(2, 4), 2);
        assert_eq!(plan.chunk_of(2, 5), 3);
        assert_eq!(plan.chunk_of(5, 1), 4);
    }

    #[test]
    fn morton_cells_stay_in_range_and_order_corners() {
        let bounds = Aabb {
            min: [0.0; 3],
            max: [1.0; 3],
        };
        let grid = CellGrid::new(&bounds);
        assert_eq!(grid.cell(&[0.0; 3]), 0);
        assert_eq!(grid.cell(&[1.0; 3]) as usize, CELL_COUNT - 1);
        assert_eq!(grid.cell(&[-5.0, 9.0, 0.5]), grid.cell(&[0.0, 1.0, 0.5]));
    }

    #[test]
    fn local_mesh_renumbers_by_ascending_global_index() {
        let triangles = [[10, 4, 7], [7, 4, 2]];
        let mesh = local_mesh(&triangles, Some(vec![5, 9]), |distinct| {
            assert_eq!(distinct, [2, 4, 7, 10]);
            Ok::<_, ()>(Vertices {
                positions: distinct.iter().map(|&v| [v as f32; 3]).collect(),
                normals: None,
                colors: Some(distinct.iter().map(|&v| [v as u8; 4]).collect()),
            })
        })
        .unwrap();
        assert_eq!(mesh.face_ids, Some(vec![5, 9]));
        assert_eq!(mesh.colors.unwrap()[1], [4; 4]);
        assert_eq!(mesh.triangles, vec![[3, 1, 2], [2, 1, 0]]);
        assert_eq!(mesh.positions[3], [10.0; 3]);
    }
}

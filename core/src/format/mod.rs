//! The ReduceM file format, version 3 (and version 2, which it reads): on-disk records and
//! layout constants.
//!
//! `docs/FORMAT.md` is the specification; this module is its code form. A file is a 4096-byte
//! header page (magic, version, endianness marker, counts, a section table with offsets, lengths
//! and checksums, and a header checksum) followed by page-aligned sections. Every record here is
//! `#[repr(C)]`, little-endian, `Pod`, and has its size asserted at compile time, so the reader
//! views the mapping in place with no pointer fix-up.

pub mod attributes;
pub mod block_boxes;
pub mod counts;
pub mod face_ids;
pub mod grid;
pub mod implicit_tree;
pub mod model;
pub mod quantized;
pub mod reader;
pub mod references;
pub mod vertices;

use bytemuck::{Pod, Zeroable};
use wide::i32x4;

/// First eight bytes of every ReduceM file.
pub const MAGIC: [u8; 8] = *b"REDUCEM\0";
/// Incremented on any incompatible layout change; readers reject majors they do not know.
/// Version 2 replaced version 1's binary top-level nodes (32 bytes) with 4-wide ones
/// ([`TopNode`]); version 3 added per-block boxes to strip blocks ([`block_boxes`]) and packs
/// the references of every vertex encoding. Writers write version 3.
pub const VERSION_MAJOR: u16 = 3;
/// Incremented on compatible additions; readers accept any minor of a major they read.
pub const VERSION_MINOR: u16 = model::MODEL_MINOR;
/// The oldest major this reader reads (version 2 files are read as before).
pub const OLDEST_READ_MAJOR: u16 = 2;
/// Version 2's minors: minor 1 added the [`PrecisionRecord`] and the grid vertex encoding,
/// minor 2 grid top-level nodes ([`GridNode`], `vertex_encoding` 2), minor 3 packed references
/// in grid files (`vertex_encoding` 3), minor 4 grid top-level nodes in lossless files
/// (`vertex_encoding` 4), minor 5 attributes. Version 2 writers wrote the lowest minor that had
/// what the file used ([`VertexEncoding::minor`]).
pub const VERSION_2_LAST_MINOR: u16 = 5;
/// Written as a little-endian u32; a reader on a big-endian host sees `0x0403_0201`.
pub const ENDIAN_MARKER: u32 = 0x0102_0304;
/// Sections start at multiples of this, so each can be mapped and paged on its own.
pub const SECTION_ALIGN: u64 = 4096;
/// Bytes reserved for the header; the first section starts here.
pub const HEADER_PAGE: u64 = SECTION_ALIGN;
/// Deepest top-level node a valid file may have (root at depth 0); bounds the traversal stack.
pub const MAX_TOP_DEPTH: usize = 128;
/// The most vertices one strip can address with 1-byte local indices (paper 3.2).
pub const MAX_STRIP_VERTICES: usize = 256;

/// How vertex positions are stored in a strip block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum VertexEncoding {
    /// Three little-endian f32 per vertex, bit-exact copies of the input (lossless).
    F32 = 0,
    /// Points of the global grid of the [`PrecisionRecord`], per strip an anchor plus
    /// fixed-width offsets ([`quantized`]), with f32 top-level nodes ([`TopNode`]). Written by
    /// format 2.1 writers only; read since 2.1.
    Grid = 1,
    /// Grid vertices as [`VertexEncoding::Grid`], with top-level nodes on the node grid
    /// ([`GridNode`], 64 bytes). Written by format 2.2 writers only; read since 2.2.
    GridNodes = 2,
    /// As [`VertexEncoding::GridNodes`], with references packed at the bits each strip's vertex
    /// count needs ([`references`]). Since format 2.3; older readers reject the value.
    GridPackedReferences = 3,
    /// Lossless f32 vertices as [`VertexEncoding::F32`], with top-level nodes on a node grid
    /// over the model bounds ([`GridNode`], 64 bytes instead of [`TopNode`]'s 128: a node is one
    /// cache line, and the file 1 to 2 bytes per triangle smaller). Node boxes are bounds, not
    /// geometry, so rounding them outward loses nothing; decoding them costs speed, so writers
    /// write this encoding on request only. Since format 2.4.
    F32GridNodes = 4,
}

impl VertexEncoding {
    pub fn from_u32(value: u32) -> Option<VertexEncoding> {
        match value {
            0 => Some(VertexEncoding::F32),
            1 => Some(VertexEncoding::Grid),
            2 => Some(VertexEncoding::GridNodes),
            3 => Some(VertexEncoding::GridPackedReferences),
            4 => Some(VertexEncoding::F32GridNodes),
            _ => None,
        }
    }

    /// How the vertices are stored: the grid encodings differ in their nodes and references
    /// only.
    pub fn name(self) -> &'static str {
        match self {
            VertexEncoding::F32 | VertexEncoding::F32GridNodes => "f32",
            _ => "grid",
        }
    }

    /// Whether the top-level nodes are [`GridNode`]s.
    pub fn has_grid_nodes(self) -> bool {
        matches!(
            self,
            VertexEncoding::GridNodes
                | VertexEncoding::GridPackedReferences
                | VertexEncoding::F32GridNodes
        )
    }

    /// The first format minor with this encoding.
    pub fn minor(self) -> u16 {
        match self {
            VertexEncoding::F32 => 0,
            VertexEncoding::Grid => 1,
            VertexEncoding::GridNodes => 2,
            VertexEncoding::GridPackedReferences => 3,
            VertexEncoding::F32GridNodes => 4,
        }
    }
}

/// Bytes of one lossless vertex.
pub const F32_VERTEX_BYTES: usize = 12;

/// The sections of a version-2 file, in file order. The discriminant is the on-disk kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum SectionKind {
    /// [`TopNode`] array: the global hierarchy over strips, depth-first.
    TopNodes = 1,
    /// [`StripRecord`] array: where each strip's block starts and its sizes.
    StripRecords = 2,
    /// Strip blocks: vertices, packed split axes, vertex references (packed since 3.0), block
    /// boxes (since 3.0).
    StripData = 3,
}

impl SectionKind {
    pub const ALL: [SectionKind; 3] = [
        SectionKind::TopNodes,
        SectionKind::StripRecords,
        SectionKind::StripData,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SectionKind::TopNodes => "top_nodes",
            SectionKind::StripRecords => "strip_records",
            SectionKind::StripData => "strip_data",
        }
    }
}

/// One entry of the header's section table. 32 bytes.
///
/// | bytes | field |
/// |---|---|
/// | 0..4 | `kind` ([`SectionKind`]) |
/// | 4..8 | reserved, zero |
/// | 8..16 | `offset` from file start, multiple of 4096 |
/// | 16..24 | `length` in bytes |
/// | 24..32 | `checksum`: XXH3-64 of the section bytes |
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct SectionEntry {
    pub kind: u32,
    pub reserved: u32,
    pub offset: u64,
    pub length: u64,
    pub checksum: u64,
}
const _: () = assert!(std::mem::size_of::<SectionEntry>() == 32);

/// Number of entries in the section table.
pub const SECTION_COUNT: usize = SectionKind::ALL.len();

/// The file header at byte 0. 208 bytes; the rest of the first 4096-byte page is zero.
///
/// | bytes | field |
/// |---|---|
/// | 0..8 | `magic` = `REDUCEM\0` |
/// | 8..10 | `version_major`, 10..12 `version_minor` |
/// | 12..16 | `endian_marker` = 0x01020304 |
/// | 16..20 | `header_bytes` = 208 |
/// | 20..24 | `vertex_encoding` ([`VertexEncoding`]): 0 f32, 1 to 3 grid, 4 f32 with grid nodes |
/// | 24..28 | `leaf_windows`: strip kd-tree leaf size in windows (1..=255) |
/// | 28..32 | `max_strip_length` used by the build (informational) |
/// | 32..40 | `triangle_count`: real (non-swap) triangles |
/// | 40..48 | `strip_count` |
/// | 48..56 | `stored_vertex_count`: vertices stored over all strips |
/// | 56..64 | `input_vertex_count`: distinct vertices of the input after welding |
/// | 64..72 | `dropped_triangle_count`: degenerate input triangles not stored |
/// | 72..80 | `hierarchy_vertex_count`: stored copies that exist only to encode split bounds |
/// | 80..92 | `bounds_min` f32×3, 92..104 `bounds_max` f32×3 |
/// | 104..200 | section table: 3 × [`SectionEntry`] |
/// | 200..208 | `header_checksum`: XXH3-64 of bytes 0..200 |
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct Header {
    pub magic: [u8; 8],
    pub version_major: u16,
    pub version_minor: u16,
    pub endian_marker: u32,
    pub header_bytes: u32,
    pub vertex_encoding: u32,
    pub leaf_windows: u32,
    pub max_strip_length: u32,
    pub triangle_count: u64,
    pub strip_count: u64,
    pub stored_vertex_count: u64,
    pub input_vertex_count: u64,
    pub dropped_triangle_count: u64,
    pub hierarchy_vertex_count: u64,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub sections: [SectionEntry; SECTION_COUNT],
    pub header_checksum: u64,
}
const _: () = assert!(std::mem::size_of::<Header>() == 208);

impl Header {
    /// Whether the file has the precision record (since 2.1).
    pub fn has_precision_record(&self) -> bool {
        self.version_major > 2 || self.version_minor >= 1
    }

    /// Whether the file has the attribute record (since 2.5).
    pub fn has_attribute_record(&self) -> bool {
        self.version_major > 2 || self.version_minor >= attributes::ATTRIBUTES_MINOR
    }

    /// Whether strip blocks carry per-block boxes and packed references (since 3.0).
    pub fn has_block_boxes(&self) -> bool {
        self.version_major >= 3
    }
}

/// Byte length of the header prefix covered by `header_checksum`.
pub const HEADER_CHECKSUMMED_BYTES: usize = 200;

/// Where the [`PrecisionRecord`] starts in the header page: right after the [`Header`].
pub const PRECISION_OFFSET: usize = 208;

/// How positions were stored and how far they moved from the input. 80 bytes at byte 208 of
/// the header page, since format 2.1; a 2.0 file has zeros there (lossless, nothing moved), and
/// 2.0 readers ignore it, so they still read lossless 2.1 files (and reject grid files through
/// `vertex_encoding`).
///
/// | bytes | field |
/// |---|---|
/// | 208..212 | `grid_bits`: bits per axis of the grid (1..=24); 0 for f32 vertices |
/// | 212..216 | `node_shift`: the [`GridNode`] boxes' cell is `grid_cell * 2^node_shift` (vertex encodings 2 and 3); zero otherwise |
/// | 216..228 | `grid_origin` f32×3: the position of grid point (0, 0, 0); with vertex encoding 4, of the node grid's |
/// | 228..232 | `grid_cell` f32: grid step on every axis, a power of two; with vertex encoding 4 the node grid's step; 0 for other f32 files |
/// | 232..240 | `error_max` f64: largest distance from an input vertex (after welding) to its stored position |
/// | 240..248 | `error_rms` f64: root mean square of the same distances |
/// | 248..252 | `weld_tolerance` f32: input vertices closer than this were merged; 0 = bit-identical only |
/// | 252..256 | reserved, zero |
/// | 256..264 | `welded_vertex_count`: input vertices merged into another by the tolerance |
/// | 264..272 | `weld_displacement_max` f64: largest distance a welded vertex moved |
/// | 272..280 | `weld_displacement_rms` f64: root mean square over the welded vertices |
/// | 280..288 | `checksum`: XXH3-64 of bytes 208..280 |
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct PrecisionRecord {
    pub grid_bits: u32,
    pub node_shift: u32,
    pub grid_origin: [f32; 3],
    pub grid_cell: f32,
    pub error_max: f64,
    pub error_rms: f64,
    pub weld_tolerance: f32,
    pub reserved2: u32,
    pub welded_vertex_count: u64,
    pub weld_displacement_max: f64,
    pub weld_displacement_rms: f64,
    pub checksum: u64,
}
const _: () = assert!(std::mem::size_of::<PrecisionRecord>() == 80);

/// Byte length of the precision record prefix covered by its `checksum`.
pub const PRECISION_CHECKSUMMED_BYTES: usize = 72;

impl PrecisionRecord {
    /// The record with its checksum set.
    pub fn sealed(mut self) -> PrecisionRecord {
        self.checksum = self.computed_checksum();
        self
    }

    pub fn computed_checksum(&self) -> u64 {
        xxhash_rust::xxh3::xxh3_64(&bytemuck::bytes_of(self)[..PRECISION_CHECKSUMMED_BYTES])
    }

    /// The grid of a grid-encoded file.
    pub fn grid(&self) -> grid::Grid {
        grid::Grid {
            bits: self.grid_bits,
            origin: self.grid_origin,
            cell: self.grid_cell,
        }
    }
}

/// Child slots of a [`TopNode`].
pub const TOP_WIDTH: usize = 4;

/// `TopNode::kind` of an internal child; smaller non-zero values are leaf strip counts.
pub const INTERNAL_CHILD: u32 = 1 << 31;

/// A node of the global hierarchy over strips: the boxes and links of up to [`TOP_WIDTH`]
/// children. 128 bytes, depth-first preorder, root at index 0. A node has no box of its own:
/// its parent's slot holds it, and the root's is the whole model (traversal tests the root's
/// children directly).
///
/// | bytes | field |
/// |---|---|
/// | 0..48 | `min[axis][slot]`: f32 × 4 per axis (x at 0, y at 16, z at 32), one lane per child |
/// | 48..96 | `max[axis][slot]`, same layout |
/// | 96..112 | `child[slot]`: internal child → its node index, greater than this node's; leaf → its first strip |
/// | 112..128 | `kind[slot]`: 0 → empty slot; [`INTERNAL_CHILD`] → internal child; otherwise a leaf of that many strips (1..2^31) |
///
/// The boxes are stored axis by axis (structure of arrays) so that one 16-byte load gives one
/// plane of all four children and a ray tests them together. Occupied slots come first; an
/// empty slot is exactly `min = +inf`, `max = -inf` on every axis, `child = 0`, `kind = 0`, a
/// box every ray misses (its entry distance is `+inf` and its exit `-inf` whatever the
/// direction's sign), and as a leaf of zero strips it would hold nothing even if entered.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct TopNode {
    pub min: [[f32; TOP_WIDTH]; 3],
    pub max: [[f32; TOP_WIDTH]; 3],
    pub child: [u32; TOP_WIDTH],
    pub kind: [u32; TOP_WIDTH],
}
const _: () = assert!(std::mem::size_of::<TopNode>() == 128);

/// What one slot of a [`TopNode`] holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TopSlot {
    Empty,
    /// The child node's index.
    Internal(u32),
    /// Strips `first .. first + count` in file order.
    Leaf {
        first: u32,
        count: u32,
    },
    /// A kind above [`INTERNAL_CHILD`]: never written, rejected by the reader.
    Invalid(u32),
}

impl TopNode {
    /// A node with every slot empty: the root of a model without strips.
    pub const EMPTY: TopNode = TopNode {
        min: [[f32::INFINITY; TOP_WIDTH]; 3],
        max: [[f32::NEG_INFINITY; TOP_WIDTH]; 3],
        child: [0; TOP_WIDTH],
        kind: [0; TOP_WIDTH],
    };

    /// Fills `slot` with a child box and its link (`kind` as stored: [`INTERNAL_CHILD`] or a
    /// strip count).
    pub fn set(&mut self, slot: usize, min: &[f32; 3], max: &[f32; 3], child: u32, kind: u32) {
        for axis in 0..3 {
            self.min[axis][slot] = min[axis];
            self.max[axis][slot] = max[axis];
        }
        self.child[slot] = child;
        self.kind[slot] = kind;
    }

    pub fn slot(&self, slot: usize) -> TopSlot {
        match self.kind[slot] {
            0 => TopSlot::Empty,
            INTERNAL_CHILD => TopSlot::Internal(self.child[slot]),
            count if count < INTERNAL_CHILD => TopSlot::Leaf {
                first: self.child[slot],
                count,
            },
            kind => TopSlot::Invalid(kind),
        }
    }

    /// The box of `slot` as (min, max).
    pub fn slot_box(&self, slot: usize) -> ([f32; 3], [f32; 3]) {
        (
            [0, 1, 2].map(|axis| self.min[axis][slot]),
            [0, 1, 2].map(|axis| self.max[axis][slot]),
        )
    }

    /// Occupied slots: those before the first empty one.
    pub fn occupied(&self) -> usize {
        self.kind.iter().take_while(|&&kind| kind != 0).count()
    }

    /// Whether `slot` is bit for bit the empty slot of [`TopNode::EMPTY`].
    pub fn is_exactly_empty(&self, slot: usize) -> bool {
        let empty = &TopNode::EMPTY;
        (0..3).all(|axis| {
            self.min[axis][slot].to_bits() == empty.min[axis][slot].to_bits()
                && self.max[axis][slot].to_bits() == empty.max[axis][slot].to_bits()
        }) && self.child[slot] == 0
            && self.kind[slot] == 0
    }
}

/// Bits of a [`GridNode`] link below its tag: the node index or first strip.
pub const GRID_LINK_INDEX_BITS: u32 = 28;
/// Mask of a [`GridNode`] link's index.
pub const GRID_LINK_INDEX: u32 = (1 << GRID_LINK_INDEX_BITS) - 1;
/// [`GridNode`] link tag of an internal child; tags 1 to 14 are leaf strip counts.
pub const GRID_LINK_INTERNAL: u32 = 15;
/// Most strips in one leaf of a [`GridNode`] (the builder's leaves hold at most
/// `TopLevelParams::max_leaf_strips`, 4 by default).
pub const MAX_GRID_LEAF_STRIPS: u32 = GRID_LINK_INTERNAL - 1;

/// A top-level node of a grid file (`vertex_encoding` 2, format 2.2): [`TopNode`]'s boxes on
/// the node grid ([`grid::NodeGrid`]) as u16 and its `child`/`kind` pairs packed in one word.
/// 64 bytes, half a [`TopNode`], in the same tree order.
///
/// | bytes | field |
/// |---|---|
/// | 0..24 | `min[axis][slot]`: u16 × 4 per axis (x at 0, y at 8, z at 16), one lane per child |
/// | 24..48 | `max[axis][slot]`, same layout |
/// | 48..64 | `link[slot]`: bits 28..32 tag, bits 0..28 index: tag 0 → empty slot (the whole word 0); tags 1..=14 → a leaf of that many strips from strip `index`; tag 15 → internal child, node `index` |
///
/// Child `i` covers `node_grid.decode(min[·][i]) ..= node_grid.decode(max[·][i])`, rounded
/// outward from the f32 box when written. An empty slot is all zero bytes (box included):
/// traversal skips it by its link, since no u16 box is missed by every ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct GridNode {
    pub min: [[u16; TOP_WIDTH]; 3],
    pub max: [[u16; TOP_WIDTH]; 3],
    pub link: [u32; TOP_WIDTH],
}
const _: () = assert!(std::mem::size_of::<GridNode>() == 64);

impl GridNode {
    /// `node` with its boxes rounded outward to `grid` and its links packed; an error when a
    /// box lies outside the node grid or a link does not fit.
    pub fn encode(node: &TopNode, grid: &grid::NodeGrid) -> Result<GridNode, String> {
        let mut out = GridNode::zeroed();
        for slot in 0..node.occupied() {
            let (min, max) = node.slot_box(slot);
            for axis in 0..3 {
                let outside = || format!("box {min:?}..{max:?} outside the node grid {grid:?}");
                let low = grid.floor(min[axis], axis).ok_or_else(outside)?;
                let high = grid.ceil(max[axis], axis).ok_or_else(outside)?;
                // Where the cell is below the coordinates' ulp (a small model far from the
                // origin), several points decode to one value, and a flat box's floor may
                // pass its ceiling; both then decode to that value, so the ceiling serves.
                out.min[axis][slot] = low.min(high);
                out.max[axis][slot] = high;
            }
            let (tag, index) = match node.slot(slot) {
                TopSlot::Internal(child) => (GRID_LINK_INTERNAL, child),
                TopSlot::Leaf { first, count } if (1..=MAX_GRID_LEAF_STRIPS).contains(&count) => {
                    (count, first)
                }
                other => return Err(format!("slot {slot} holds {other:?}: no grid node link")),
            };
            if index > GRID_LINK_INDEX {
                return Err(format!(
                    "index {index} of slot {slot} needs more than 28 bits"
                ));
            }
            out.link[slot] = tag << GRID_LINK_INDEX_BITS | index;
        }
        Ok(out)
    }
}

/// The slot structure of a top-level node record, [`TopNode`] or [`GridNode`]: what the reader
/// validates and traversal follows.
pub trait NodeRecord: Pod {
    /// Byte offset of slot 0's link (child or first strip) within the record, for errors.
    const CHILD_FIELD: u64;
    /// Byte offset of slot 0's kind (or whole link), for errors.
    const KIND_FIELD: u64;
    /// Bytes from one slot's link word to the next.
    const LINK_STRIDE: u64 = 4;
    /// The exact empty slot, for errors.
    const EMPTY_SLOT: &'static str;

    fn slot(&self, slot: usize) -> TopSlot;

    /// Whether `slot` is bit for bit the record's empty slot.
    fn is_exactly_empty(&self, slot: usize) -> bool;

    /// Occupied slots: those before the first empty one.
    fn occupied(&self) -> usize {
        (0..TOP_WIDTH)
            .take_while(|&slot| self.slot(slot) != TopSlot::Empty)
            .count()
    }

    /// The first axis on which occupied `slot`'s box has `min > max`, with the byte offset of
    /// that `min` in the record; `None` when the box is well formed (or the record admits any).
    fn inverted_axis(&self, slot: usize) -> Option<(usize, u64)>;

    /// Whether node `index` passes the checks that need no other node, all slots at once in
    /// plain comparisons: occupied slots first (at least one unless `limits.empty_root`), each
    /// with a well-formed box and an internal child inside `index + 1..limits.nodes` or a leaf
    /// inside `0..limits.strips`; every slot after them exactly empty. The same decision as
    /// the per-slot checks through [`NodeRecord::slot`] that word a defect (but for limits
    /// beyond 32 bits, where it may reject what they accept: see `LinkBounds`), made without
    /// them: those cost about 270 instructions a node on its first visit, 2.6% of a 1M-ray
    /// query on the 10M scan (callgrind).
    fn passes_alone(&self, index: usize, limits: NodeLimits) -> bool;
}

/// What the checks of one top-level node alone compare its links with.
#[derive(Clone, Copy, Debug)]
pub struct NodeLimits {
    /// Nodes in the file.
    pub nodes: usize,
    /// Strips in the file.
    pub strips: u64,
    /// Whether the node may have no children: the root of a model without strips.
    pub empty_root: bool,
}

impl NodeRecord for TopNode {
    const CHILD_FIELD: u64 = 96;
    const KIND_FIELD: u64 = 112;
    const EMPTY_SLOT: &'static str = "min +inf, max -inf, child 0, kind 0";

    fn slot(&self, slot: usize) -> TopSlot {
        TopNode::slot(self, slot)
    }

    fn is_exactly_empty(&self, slot: usize) -> bool {
        TopNode::is_exactly_empty(self, slot)
    }

    fn occupied(&self) -> usize {
        TopNode::occupied(self)
    }

    /// An inverted f32 box is missed by every ray, like the empty slot's: harmless, admitted.
    fn inverted_axis(&self, _slot: usize) -> Option<(usize, u64)> {
        None
    }

    #[inline]
    fn passes_alone(&self, index: usize, limits: NodeLimits) -> bool {
        let words: &[[u32; TOP_WIDTH]; 8] = bytemuck::cast_ref(self);
        let empty: &[[u32; TOP_WIDTH]; 8] = bytemuck::cast_ref(&TopNode::EMPTY);
        let mut differ = [0u32; TOP_WIDTH];
        for (row, empty_row) in words.iter().zip(empty) {
            for lane in 0..TOP_WIDTH {
                differ[lane] |= row[lane] ^ empty_row[lane];
            }
        }
        let kinds = i32x4::new(self.kind.map(|kind| kind as i32));
        let internal = kinds.simd_eq(i32x4::splat(INTERNAL_CHILD as i32));
        let leaf = !kinds.simd_lt(i32x4::ZERO);
        let links = LinkBounds::new(index, limits).passes(self.child, internal, leaf, kinds);
        slots_pass(
            lanes(|slot| self.kind[slot] != 0),
            links,
            lanes(|slot| differ[slot] == 0),
            limits.empty_root,
        )
    }
}

/// [`NodeLimits`] around node `index` in 32-bit lanes, so that a node's slots compare at once:
/// unsigned values with their sign bit flipped, ordered as signed ones. Limits beyond 32 bits
/// (over 4G nodes or strips) are clamped, which only rejects links that
/// [`NodeRecord::slot`]'s checks then accept.
struct LinkBounds {
    /// The node itself: children come after it.
    node: i32x4,
    last_node: i32x4,
    strips: i32x4,
}

impl LinkBounds {
    #[inline(always)]
    fn new(index: usize, limits: NodeLimits) -> LinkBounds {
        let lane = |value: u64| i32x4::splat(flip_sign(value.min(u32::MAX as u64) as u32));
        LinkBounds {
            node: lane(index as u64),
            last_node: lane(limits.nodes.saturating_sub(1) as u64),
            strips: lane(limits.strips),
        }
    }

    /// The slots whose link passes, as bits: an `internal` slot's names a node after this one
    /// inside the array, a `leaf`'s strips `link..link + count` (`count < 2^31`) lie inside the
    /// record array.
    #[inline(always)]
    fn passes(&self, links: [u32; TOP_WIDTH], internal: i32x4, leaf: i32x4, count: i32x4) -> u32 {
        let links = i32x4::new(links.map(flip_sign));
        let child = links.simd_gt(self.node) & !links.simd_gt(self.last_node);
        let end = links + count;
        let strips = !end.simd_lt(links) & !end.simd_gt(self.strips);
        ((internal & child) | (leaf & strips)).to_bitmask()
    }
}

/// `value` with its sign bit flipped: unsigned order as signed order.
#[inline(always)]
fn flip_sign(value: u32) -> i32 {
    (value ^ 1 << 31) as i32
}

/// Bit `slot` set where `test(slot)` holds, over a node's slots.
#[inline(always)]
fn lanes(test: impl Fn(usize) -> bool) -> u32 {
    (0..TOP_WIDTH).fold(0, |bits, slot| bits | (test(slot) as u32) << slot)
}

/// [`NodeRecord::passes_alone`] from bit masks over the slots: `occupied` ones form a prefix
/// (non-empty unless `empty_root`), each with passing `links` (box included), and the others
/// are `exactly_empty`.
#[inline(always)]
fn slots_pass(occupied: u32, links: u32, exactly_empty: u32, empty_root: bool) -> bool {
    let all = (1 << TOP_WIDTH) - 1;
    (occupied & (occupied + 1) == 0)
        & ((occupied != 0) | empty_root)
        & (links & occupied == occupied)
        & (exactly_empty | occupied == all)
}

impl NodeRecord for GridNode {
    const CHILD_FIELD: u64 = 48;
    const KIND_FIELD: u64 = 48;
    const EMPTY_SLOT: &'static str = "all zero bytes";

    fn slot(&self, slot: usize) -> TopSlot {
        let link = self.link[slot];
        let index = link & GRID_LINK_INDEX;
        match link >> GRID_LINK_INDEX_BITS {
            0 if link == 0 => TopSlot::Empty,
            0 => TopSlot::Invalid(link),
            GRID_LINK_INTERNAL => TopSlot::Internal(index),
            count => TopSlot::Leaf {
                first: index,
                count,
            },
        }
    }

    fn is_exactly_empty(&self, slot: usize) -> bool {
        (0..3).all(|axis| self.min[axis][slot] == 0 && self.max[axis][slot] == 0)
            && self.link[slot] == 0
    }

    /// An inverted u16 box need not be missed (traversal relies on the link to skip empty
    /// slots only), and no writer rounds outward to one: rejected.
    fn inverted_axis(&self, slot: usize) -> Option<(usize, u64)> {
        (0..3)
            .find(|&axis| self.min[axis][slot] > self.max[axis][slot])
            .map(|axis| (axis, (axis * 8 + slot * 2) as u64))
    }

    #[inline]
    fn passes_alone(&self, index: usize, limits: NodeLimits) -> bool {
        let mut differ = [0u16; TOP_WIDTH];
        let mut inverted = [false; TOP_WIDTH];
        for (min, max) in self.min.iter().zip(&self.max) {
            for lane in 0..TOP_WIDTH {
                differ[lane] |= min[lane] | max[lane];
                inverted[lane] |= min[lane] > max[lane];
            }
        }
        let tags = i32x4::new(self.link.map(|word| (word >> GRID_LINK_INDEX_BITS) as i32));
        let internal = tags.simd_eq(i32x4::splat(GRID_LINK_INTERNAL as i32));
        let leaf = !tags.simd_eq(i32x4::ZERO) & !internal;
        let first = self.link.map(|word| word & GRID_LINK_INDEX);
        let links = LinkBounds::new(index, limits).passes(first, internal, leaf, tags)
            & !lanes(|slot| inverted[slot]);
        slots_pass(
            lanes(|slot| self.link[slot] != 0),
            links,
            lanes(|slot| (differ[slot] == 0) & (self.link[slot] == 0)),
            limits.empty_root,
        )
    }
}

/// Where a strip's block lives in the strip-data section. 8 bytes.
///
/// | bytes | field |
/// |---|---|
/// | 0..4 | `data_word`: block offset in the strip-data section, in 4-byte words |
/// | 4..6 | `vertex_count`: stored vertices (3..=256) |
/// | 6..8 | `reference_count`: 1-byte vertex references (≥ 3) |
///
/// A block is `vertex_count` vertices (12 bytes each, or packed grid offsets: see
/// [`quantized`]), then the split axes of the strip's kd-tree at 2 bits per node (4 per byte,
/// node `i` in bits `2*(i%4)..`), then `reference_count` references, padded with zeros to a
/// multiple of 4 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct StripRecord {
    pub data_word: u32,
    pub vertex_count: u16,
    pub reference_count: u16,
}
const _: () = assert!(std::mem::size_of::<StripRecord>() == 8);

/// Bytes of packed 2-bit split axes for `nodes` kd-tree nodes.
pub fn axis_bytes(nodes: usize) -> usize {
    nodes.div_ceil(4)
}

/// Rounds a byte count up to the next multiple of `align`.
pub fn align_up(value: u64, align: u64) -> u64 {
    value.div_ceil(align) * align
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-slot checks that word a node's defect (`reader::validate::TreeCheck::check` on
    /// a node alone), as a verdict.
    fn passes_slot_by_slot<N: NodeRecord>(node: &N, index: usize, limits: NodeLimits) -> bool {
        let occupied = node.occupied();
        if occupied == 0 && !limits.empty_root {
            return false;
        }
        (0..TOP_WIDTH).all(|slot| {
            if slot >= occupied {
                return node.is_exactly_empty(slot);
            }
            node.inverted_axis(slot).is_none()
                && match node.slot(slot) {
                    TopSlot::Internal(child) => {
                        child as usize > index && (child as usize) < limits.nodes
                    }
                    TopSlot::Leaf { first, count } => first as u64 + count as u64 <= limits.strips,
                    TopSlot::Empty | TopSlot::Invalid(_) => false,
                }
        })
    }

    /// A xorshift generator picking from small sets of edge values.
    struct Picker(u64);

    impl Picker {
        fn pick<T: Copy>(&mut self, values: &[T]) -> T {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            values[(self.0 % values.len() as u64) as usize]
        }
    }

    const INDEX: usize = 5;
    const NODES: usize = 9;
    const STRIPS: u64 = 20;

    /// How many generated nodes passed and failed, after checking that the fast check agrees
    /// with the per-slot checks on each.
    #[derive(Default)]
    struct Verdicts {
        passed: usize,
        failed: usize,
    }

    impl Verdicts {
        fn compare<N: NodeRecord + std::fmt::Debug>(&mut self, node: &N, picker: &mut Picker) {
            let (index, limits) = limits(picker);
            let expected = passes_slot_by_slot(node, index, limits);
            assert_eq!(
                node.passes_alone(index, limits),
                expected,
                "{node:?} {limits:?}"
            );
            match expected {
                true => self.passed += 1,
                false => self.failed += 1,
            }
        }

        /// Both verdicts came up often: the generated nodes exercised the check both ways.
        fn assert_both_seen(&self) {
            let Verdicts { passed, failed } = self;
            assert!(
                *passed > 10_000 && *failed > 10_000,
                "{passed} passed, {failed} failed"
            );
        }
    }

    fn limits(picker: &mut Picker) -> (usize, NodeLimits) {
        let index = picker.pick(&[0, INDEX]);
        let limits = NodeLimits {
            nodes: NODES,
            strips: STRIPS,
            empty_root: picker.pick(&[false, true]),
        };
        (index, limits)
    }

    /// Links around every bound the checks compare with.
    const LINKS: [u32; 10] = [0, 1, 4, 5, 6, 8, 9, 17, 19, 20];

    #[test]
    fn f32_nodes_pass_alone_exactly_when_every_slot_passes() {
        let mut picker = Picker(0x9e37_79b9_7f4a_7c15);
        let kinds = [
            0,
            0,
            1,
            3,
            INTERNAL_CHILD,
            INTERNAL_CHILD,
            INTERNAL_CHILD + 1,
            u32::MAX,
        ];
        let coordinates = [f32::INFINITY, f32::NEG_INFINITY, 0.0, -0.0, 1.0, f32::NAN];
        let mut verdicts = Verdicts::default();
        for round in 0..200_000 {
            let mut node = TopNode::EMPTY;
            let occupied = picker.pick(&[0, 1, 2, 3, 4]);
            for slot in 0..TOP_WIDTH {
                let kind = match slot < occupied {
                    true => picker.pick(&[1, 3, INTERNAL_CHILD]),
                    false => 0,
                };
                let child = picker.pick(&LINKS);
                node.set(slot, &[0.0; 3], &[1.0; 3], child, kind);
                if slot >= occupied && round % 2 == 0 {
                    node.set(slot, &[f32::INFINITY; 3], &[f32::NEG_INFINITY; 3], 0, 0);
                }
            }
            for _ in 0..picker.pick(&[0, 1, 2]) {
                let slot = picker.pick(&[0, 1, 2, 3]);
                let axis = picker.pick(&[0, 1, 2]);
                match picker.pick(&[0, 1, 2, 3]) {
                    0 => node.kind[slot] = picker.pick(&kinds),
                    1 => node.child[slot] = picker.pick(&LINKS),
                    2 => node.min[axis][slot] = picker.pick(&coordinates),
                    _ => node.max[axis][slot] = picker.pick(&coordinates),
                }
            }
            verdicts.compare(&node, &mut picker);
        }
        verdicts.assert_both_seen();
    }

    #[test]
    fn grid_nodes_pass_alone_exactly_when_every_slot_passes() {
        let mut picker = Picker(0x2545_f491_4f6c_dd1d);
        let tags = [0, 1, 3, 14, GRID_LINK_INTERNAL];
        let bounds = [0, 1, 2, u16::MAX];
        let mut verdicts = Verdicts::default();
        for _ in 0..200_000 {
            let mut node = GridNode::zeroed();
            let occupied = picker.pick(&[0, 1, 2, 3, 4]);
            for slot in 0..occupied {
                let tag = picker.pick(&[1, 3, GRID_LINK_INTERNAL]);
                node.link[slot] = tag << GRID_LINK_INDEX_BITS | picker.pick(&LINKS);
                for axis in 0..3 {
                    node.min[axis][slot] = 1;
                    node.max[axis][slot] = 2;
                }
            }
            for _ in 0..picker.pick(&[0, 1, 2]) {
                let slot = picker.pick(&[0, 1, 2, 3]);
                let axis = picker.pick(&[0, 1, 2]);
                match picker.pick(&[0, 1, 2, 3]) {
                    0 => {
                        let tag = picker.pick(&tags);
                        node.link[slot] = tag << GRID_LINK_INDEX_BITS | picker.pick(&LINKS);
                    }
                    1 => node.link[slot] = picker.pick(&[0, u32::MAX, GRID_LINK_INDEX]),
                    2 => node.min[axis][slot] = picker.pick(&bounds),
                    _ => node.max[axis][slot] = picker.pick(&bounds),
                }
            }
            verdicts.compare(&node, &mut picker);
        }
        verdicts.assert_both_seen();
    }
}

//! How strip blocks store vertex positions: the header's `vertex_encoding`.

#[cfg(doc)]
use super::{quantized, references, GridNode, PrecisionRecord, TopNode};

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
    /// Grid vertices in pools shared by consecutive strips ([`super::pool`]), references packed
    /// at each strip's bits, no strip kd-trees. Since format 4.1.
    GridPooled = 5,
}

impl VertexEncoding {
    pub fn from_u32(value: u32) -> Option<VertexEncoding> {
        match value {
            0 => Some(VertexEncoding::F32),
            1 => Some(VertexEncoding::Grid),
            2 => Some(VertexEncoding::GridNodes),
            3 => Some(VertexEncoding::GridPackedReferences),
            4 => Some(VertexEncoding::F32GridNodes),
            5 => Some(VertexEncoding::GridPooled),
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

    /// The first format 2 minor with this encoding; [`VertexEncoding::GridPooled`] is no part
    /// of format 2 (format 4.1).
    pub fn minor(self) -> u16 {
        match self {
            VertexEncoding::F32 => 0,
            VertexEncoding::Grid => 1,
            VertexEncoding::GridNodes => 2,
            VertexEncoding::GridPackedReferences => 3,
            VertexEncoding::F32GridNodes => 4,
            VertexEncoding::GridPooled => super::POOLED_MINOR,
        }
    }
}

/// Bytes of one lossless vertex.
pub const F32_VERTEX_BYTES: usize = 12;

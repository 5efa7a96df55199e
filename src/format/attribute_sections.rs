//! Writes the attribute sections of format 2.5 from each strip's payload, in file order:
//! `face_ids` (bit-packed per strip, see [`FaceIdGroup`]) then its group index, `normals`,
//! `colors`, then the vertex group index. The read side of the same layout is
//! `reducem_core::format::face_ids` and the reader's attribute lookups.

use std::io::{self, Write};

use crate::format::attributes::{
    push_normal, AttributeSection, AttributeSet, FaceIdGroup, OctCode, BASE_WIDTH_BITS,
    DELTA_WIDTH_BITS, GROUP_STRIPS, OFFSET_WIDTH_BITS,
};

/// Per-strip attributes, each empty when the file does not store it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StripAttributes {
    /// The input face id of each window, swaps included: a swap repeats the id of the window
    /// before it, or at the strip start that of the first triangle.
    pub face_ids: Vec<u32>,
    /// The octahedral code of each stored vertex's normal, in stored order.
    pub normals: Vec<OctCode>,
    /// The RGBA8 colour of each stored vertex, in stored order.
    pub colors: Vec<[u8; 4]>,
}

/// Hands every strip's attributes, in file order, to a visitor; called once per attribute
/// section written.
pub type AttributeVisit<'v> = dyn FnMut(&StripAttributes) -> io::Result<()> + 'v;

/// Writes the attribute section `kind` of a file storing `set`; `strips` visits the strips'
/// payloads in file order. The group indexes are computed from the same visits, so the
/// sections they index must be written first (which [`AttributeSection::ALL`] order does).
pub(crate) struct AttributeWriter {
    set: AttributeSet,
    face_id_groups: Vec<FaceIdGroup>,
    vertex_groups: Vec<u64>,
}

impl AttributeWriter {
    pub(crate) fn new(set: AttributeSet) -> AttributeWriter {
        AttributeWriter {
            set,
            face_id_groups: Vec::new(),
            vertex_groups: Vec::new(),
        }
    }

    pub(crate) fn write(
        &mut self,
        kind: AttributeSection,
        strips: &mut dyn FnMut(&mut AttributeVisit) -> io::Result<()>,
        out: &mut dyn Write,
    ) -> io::Result<()> {
        match kind {
            AttributeSection::FaceIds => {
                let mut encoder = FaceIdEncoder::new(out);
                strips(&mut |strip| encoder.push(&strip.face_ids))?;
                self.face_id_groups = encoder.finish()?;
                Ok(())
            }
            AttributeSection::FaceIdGroups => {
                out.write_all(bytemuck::cast_slice(&self.face_id_groups))
            }
            AttributeSection::Normals => {
                let (encoding, mut counter) = (self.set.normals, VertexGroups::default());
                let mut bytes = Vec::new();
                strips(&mut |strip| {
                    counter.push(strip.normals.len());
                    bytes.clear();
                    strip
                        .normals
                        .iter()
                        .for_each(|&code| push_normal(code, encoding, &mut bytes));
                    out.write_all(&bytes)
                })?;
                self.vertex_groups = counter.groups;
                Ok(())
            }
            AttributeSection::Colors => {
                let mut counter = VertexGroups::default();
                strips(&mut |strip| {
                    counter.push(strip.colors.len());
                    out.write_all(strip.colors.as_flattened())
                })?;
                self.vertex_groups = counter.groups;
                Ok(())
            }
            AttributeSection::VertexGroups => {
                let bytes: Vec<u8> = self
                    .vertex_groups
                    .iter()
                    .flat_map(|g| g.to_le_bytes())
                    .collect();
                out.write_all(&bytes)
            }
        }
    }
}

/// Counts stored vertices into the start of each group.
#[derive(Default)]
struct VertexGroups {
    groups: Vec<u64>,
    strips: usize,
    vertices: u64,
}

impl VertexGroups {
    fn push(&mut self, vertices: usize) {
        if self.strips.is_multiple_of(GROUP_STRIPS) {
            self.groups.push(self.vertices);
        }
        self.strips += 1;
        self.vertices += vertices as u64;
    }
}

/// Encodes strips' face ids into the `face_ids` stream, a group at a time (the group's base is
/// its smallest id, so its strips are buffered).
struct FaceIdEncoder<'o> {
    bits: BitWriter<'o>,
    pending: Vec<Vec<u32>>,
    groups: Vec<FaceIdGroup>,
}

impl<'o> FaceIdEncoder<'o> {
    fn new(out: &'o mut dyn Write) -> FaceIdEncoder<'o> {
        FaceIdEncoder {
            bits: BitWriter::new(out),
            pending: Vec::with_capacity(GROUP_STRIPS),
            groups: Vec::new(),
        }
    }

    fn push(&mut self, ids: &[u32]) -> io::Result<()> {
        self.pending.push(ids.to_vec());
        if self.pending.len() == GROUP_STRIPS {
            self.flush_group()?;
        }
        Ok(())
    }

    fn flush_group(&mut self) -> io::Result<()> {
        let base = self.pending.iter().flatten().min().copied().unwrap_or(0);
        self.groups.push(FaceIdGroup {
            bit_offset: self.bits.position,
            base,
            reserved: 0,
        });
        for ids in std::mem::take(&mut self.pending) {
            encode_entry(&ids, base, &mut self.bits)?;
        }
        Ok(())
    }

    fn finish(mut self) -> io::Result<Vec<FaceIdGroup>> {
        if !self.pending.is_empty() {
            self.flush_group()?;
        }
        self.bits.finish()?;
        Ok(self.groups)
    }
}

/// One strip's entry: header, flags, values (see [`FaceIdGroup`]). The delta width is the one
/// that makes the entry shortest.
fn encode_entry(ids: &[u32], group_base: u32, bits: &mut BitWriter) -> io::Result<()> {
    let smallest = ids.iter().min().copied().unwrap_or(group_base);
    let largest = ids.iter().max().copied().unwrap_or(group_base);
    let base_delta = (smallest - group_base) as u64;
    let offset_width = width(u64::from(largest - smallest));
    let deltas: Vec<u64> = ids.windows(2).map(|w| zigzag(w[1], w[0])).collect();
    let delta_width = (0..=offset_width.min(31))
        .min_by_key(|&w| entry_value_bits(&deltas, w, offset_width))
        .unwrap_or(0);
    let is_delta = |window: usize| window > 0 && width(deltas[window - 1]) <= delta_width;
    bits.push(width(base_delta) as u64, BASE_WIDTH_BITS)?;
    bits.push(base_delta, width(base_delta))?;
    bits.push(offset_width as u64, OFFSET_WIDTH_BITS)?;
    bits.push(delta_width as u64, DELTA_WIDTH_BITS)?;
    for window in 0..ids.len() {
        bits.push(u64::from(!is_delta(window)), 1)?;
    }
    for (window, &id) in ids.iter().enumerate() {
        match is_delta(window) {
            true => bits.push(deltas[window - 1], delta_width)?,
            false => bits.push(u64::from(id - smallest), offset_width)?,
        }
    }
    Ok(())
}

/// Value bits of an entry whose deltas take `delta_width` bits where they fit.
fn entry_value_bits(deltas: &[u64], delta_width: u32, offset_width: u32) -> u64 {
    let deltas_bits: u64 = deltas
        .iter()
        .map(|&d| match width(d) <= delta_width {
            true => delta_width as u64,
            false => offset_width as u64,
        })
        .sum();
    offset_width as u64 + deltas_bits
}

fn zigzag(id: u32, previous: u32) -> u64 {
    let delta = id as i64 - previous as i64;
    ((delta << 1) ^ (delta >> 63)) as u64
}

/// Bits needed for `value` (0 for 0).
fn width(value: u64) -> u32 {
    u64::BITS - value.leading_zeros()
}

/// A little-endian bit stream written to `out` a byte at a time.
struct BitWriter<'o> {
    out: &'o mut dyn Write,
    pending: u64,
    pending_bits: u32,
    position: u64,
    buffer: Vec<u8>,
}

impl<'o> BitWriter<'o> {
    fn new(out: &'o mut dyn Write) -> BitWriter<'o> {
        BitWriter {
            out,
            pending: 0,
            pending_bits: 0,
            position: 0,
            buffer: Vec::with_capacity(1 << 16),
        }
    }

    /// Appends the low `width` (at most 33) bits of `value`.
    fn push(&mut self, value: u64, width: u32) -> io::Result<()> {
        if width == 0 {
            return Ok(());
        }
        self.pending |= (value & ((1u64 << width) - 1)) << self.pending_bits;
        self.pending_bits += width;
        self.position += width as u64;
        while self.pending_bits >= 8 {
            self.buffer.push(self.pending as u8);
            self.pending >>= 8;
            self.pending_bits -= 8;
        }
        if self.buffer.len() >= 1 << 16 {
            self.out.write_all(&self.buffer)?;
            self.buffer.clear();
        }
        Ok(())
    }

    fn finish(mut self) -> io::Result<()> {
        if self.pending_bits > 0 {
            self.buffer.push(self.pending as u8);
        }
        self.out.write_all(&self.buffer)
    }
}

//! The pipeline's intermediate files: mesh chunks (zstd-compressed) and strip chunks (raw, so
//! the write stage can stream their sections into the final file).
//!
//! Both are private to a work directory and versioned by the format version in every stage
//! fingerprint, so they carry a magic number but no compatibility promises.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom, Write};
use std::path::Path;

use bytemuck::{Pod, Zeroable};
use reducem::conversion::ChunkStats;
use reducem::format::attribute_sections::{AttributeVisit, StripAttributes};
use reducem::format::attributes::OctCode;
use reducem::format::{StripRecord, WideNode};
use reducem::geometry::{Aabb, Displacement, Point};
use reducem::mesh::Mesh;
use reducem::strip_encoding::EncodedStrip;

/// Mesh chunks with attributes (version 2: a flags word after the counts).
const MESH_MAGIC: [u8; 8] = *b"RDMMESH2";
/// Strip chunks with 8-wide nodes (version 3; version 2 held 4-wide f32 nodes). The strip
/// stage's fingerprint names it, so work directories of other versions redo their chunks.
pub const STRIP_MAGIC: [u8; 8] = *b"RDMSTRP3";
/// zstd level: chunks are written once and read once, so speed matters more than ratio.
const ZSTD_LEVEL: i32 = 1;
/// Bytes before the arrays: magic, vertex count, triangle count, flags.
const MESH_HEADER_BYTES: usize = 32;

/// Which optional arrays follow the triangles, in this order.
const HAS_FACE_IDS: u64 = 1;
const HAS_NORMALS: u64 = 2;
const HAS_COLORS: u64 = 4;

/// Writes a mesh chunk, compressed: magic, vertex and triangle counts, flags, positions,
/// triangles, then the face ids, normals and colours the mesh has.
pub fn write_mesh(out: &mut impl Write, mesh: &Mesh) -> io::Result<()> {
    let flags = [
        (mesh.face_ids.is_some(), HAS_FACE_IDS),
        (mesh.normals.is_some(), HAS_NORMALS),
        (mesh.colors.is_some(), HAS_COLORS),
    ]
    .iter()
    .filter(|(present, _)| *present)
    .fold(0, |flags, (_, bit)| flags | bit);
    let mut encoder = zstd::Encoder::new(out, ZSTD_LEVEL)?;
    encoder.write_all(&MESH_MAGIC)?;
    encoder.write_all(&(mesh.positions.len() as u64).to_le_bytes())?;
    encoder.write_all(&(mesh.triangles.len() as u64).to_le_bytes())?;
    encoder.write_all(&flags.to_le_bytes())?;
    encoder.write_all(bytemuck::cast_slice(&mesh.positions))?;
    encoder.write_all(bytemuck::cast_slice(&mesh.triangles))?;
    if let Some(face_ids) = &mesh.face_ids {
        encoder.write_all(bytemuck::cast_slice(face_ids))?;
    }
    if let Some(normals) = &mesh.normals {
        encoder.write_all(bytemuck::cast_slice(normals))?;
    }
    if let Some(colors) = &mesh.colors {
        encoder.write_all(bytemuck::cast_slice(colors))?;
    }
    encoder.finish()?;
    Ok(())
}

pub fn read_mesh(path: &Path) -> io::Result<Mesh> {
    let mut bytes = Vec::new();
    zstd::Decoder::new(File::open(path)?)?.read_to_end(&mut bytes)?;
    let invalid = || {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{}: not a mesh chunk", path.display()),
        )
    };
    if bytes.len() < MESH_HEADER_BYTES || bytes[..8] != MESH_MAGIC {
        return Err(invalid());
    }
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap_or_default());
    let (vertices, triangles, flags) = (word(8) as usize, word(16) as usize, word(24));
    if flags & !(HAS_FACE_IDS | HAS_NORMALS | HAS_COLORS) != 0 {
        return Err(invalid());
    }
    let has = |bit: u64| flags & bit != 0;
    // (present, element count, bytes per element) of each array, in file order.
    let arrays = [
        (true, vertices, 12),
        (true, triangles, 12),
        (has(HAS_FACE_IDS), triangles, 4),
        (has(HAS_NORMALS), vertices, 12),
        (has(HAS_COLORS), vertices, 4),
    ];
    let mut sections: Vec<Option<&[u8]>> = Vec::with_capacity(arrays.len());
    let mut at = MESH_HEADER_BYTES;
    for (present, count, size) in arrays {
        if !present {
            sections.push(None);
            continue;
        }
        let end = count
            .checked_mul(size)
            .and_then(|bytes_of_array| at.checked_add(bytes_of_array))
            .filter(|&end| end <= bytes.len())
            .ok_or_else(invalid)?;
        sections.push(Some(&bytes[at..end]));
        at = end;
    }
    if at != bytes.len() {
        return Err(invalid());
    }
    let section = |index: usize| sections[index].unwrap_or_default();
    Ok(Mesh {
        positions: bytemuck::pod_collect_to_vec::<u8, Point>(section(0)),
        triangles: bytemuck::pod_collect_to_vec::<u8, [u32; 3]>(section(1)),
        face_ids: sections[2].map(bytemuck::pod_collect_to_vec::<u8, u32>),
        normals: sections[3].map(bytemuck::pod_collect_to_vec::<u8, [f32; 3]>),
        colors: sections[4].map(bytemuck::pod_collect_to_vec::<u8, [u8; 4]>),
    })
}

/// Header of a strip chunk. 160 bytes, followed by `node_count` [`WideNode`]s (96 bytes each,
/// chunk-local links), `strip_count` [`StripRecord`]s (chunk-local data words), `data_bytes` strip blocks,
/// then the strips' attributes in file order: `face_id_count` u32 face ids (one per window),
/// `normal_count` octahedral codes (2 × i16 per stored vertex) and `color_count` RGBA8 colours.
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct StripChunkHeader {
    pub magic: [u8; 8],
    pub strip_count: u64,
    pub node_count: u64,
    pub data_bytes: u64,
    /// triangles, dropped, input vertices, stored vertices, hierarchy vertices, max strip length.
    pub stats: [u64; 6],
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    /// Quantization error of the chunk's vertices: count, then max and sum of squares as f64.
    pub error_count: u64,
    pub error: [f64; 2],
    pub face_id_count: u64,
    pub normal_count: u64,
    pub color_count: u64,
    pub normal_error_degrees: f64,
}
const _: () = assert!(std::mem::size_of::<StripChunkHeader>() == 160);

impl StripChunkHeader {
    /// The header of a chunk of `strips` (in file order) under `nodes`.
    pub fn new(stats: &ChunkStats, bounds: &Aabb, nodes: usize, strips: &[&EncodedStrip]) -> Self {
        let count = |field: fn(&StripAttributes) -> usize| {
            strips.iter().map(|s| field(&s.attributes) as u64).sum()
        };
        StripChunkHeader {
            face_id_count: count(|a| a.face_ids.len()),
            normal_count: count(|a| a.normals.len()),
            color_count: count(|a| a.colors.len()),
            normal_error_degrees: stats.normal_error_degrees,
            magic: STRIP_MAGIC,
            strip_count: strips.len() as u64,
            node_count: nodes as u64,
            data_bytes: strips.iter().map(|s| s.block.len() as u64).sum(),
            stats: [
                stats.triangles,
                stats.dropped_triangles,
                stats.input_vertices,
                stats.stored_vertices,
                stats.hierarchy_vertices,
                stats.max_strip_length,
            ],
            bounds_min: bounds.min,
            bounds_max: bounds.max,
            error_count: stats.quantization.count,
            error: [stats.quantization.max, stats.quantization.squared_sum],
        }
    }

    /// The chunk's counts, as [`StripChunkHeader::new`] stored them.
    pub fn chunk_stats(&self) -> ChunkStats {
        let [triangles, dropped_triangles, input_vertices, stored_vertices, hierarchy_vertices, max_strip_length] =
            self.stats;
        ChunkStats {
            triangles,
            dropped_triangles,
            input_vertices,
            stored_vertices,
            hierarchy_vertices,
            max_strip_length,
            quantization: self.quantization(),
            normal_error_degrees: self.normal_error_degrees,
        }
    }

    fn quantization(&self) -> Displacement {
        Displacement {
            count: self.error_count,
            max: self.error[0],
            squared_sum: self.error[1],
        }
    }

    fn nodes_offset(&self) -> u64 {
        std::mem::size_of::<StripChunkHeader>() as u64
    }

    fn records_offset(&self) -> u64 {
        self.nodes_offset() + self.node_count * std::mem::size_of::<WideNode>() as u64
    }

    fn data_offset(&self) -> u64 {
        self.records_offset() + self.strip_count * std::mem::size_of::<StripRecord>() as u64
    }

    fn attributes_offset(&self) -> u64 {
        self.data_offset() + self.data_bytes
    }

    fn end(&self) -> u64 {
        self.attributes_offset() + (self.face_id_count + self.normal_count + self.color_count) * 4
    }
}

/// Writes a strip chunk of `strips` in file order.
pub fn write_strips(
    out: &mut impl Write,
    header: &StripChunkHeader,
    nodes: &[WideNode],
    records: &[StripRecord],
    strips: &[&EncodedStrip],
) -> io::Result<()> {
    out.write_all(bytemuck::bytes_of(header))?;
    out.write_all(bytemuck::cast_slice(nodes))?;
    out.write_all(bytemuck::cast_slice(records))?;
    strips.iter().try_for_each(|s| out.write_all(&s.block))?;
    for s in strips {
        out.write_all(bytemuck::cast_slice(&s.attributes.face_ids))?;
    }
    for s in strips {
        out.write_all(bytemuck::cast_slice(&s.attributes.normals))?;
    }
    strips
        .iter()
        .try_for_each(|s| out.write_all(s.attributes.colors.as_flattened()))
}

/// A strip chunk opened for reading one section at a time.
pub struct StripChunk {
    file: BufReader<File>,
    pub header: StripChunkHeader,
}

impl StripChunk {
    pub fn open(path: &Path) -> io::Result<StripChunk> {
        let mut file = BufReader::with_capacity(1 << 20, File::open(path)?);
        let mut header = StripChunkHeader::zeroed();
        file.read_exact(bytemuck::bytes_of_mut(&mut header))?;
        let expected = header.end();
        if header.magic != STRIP_MAGIC || file.get_ref().metadata()?.len() != expected {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!("{}: not a complete strip chunk", path.display()),
            ));
        }
        Ok(StripChunk { file, header })
    }

    pub fn nodes(&mut self) -> io::Result<Vec<WideNode>> {
        self.read_records(self.header.nodes_offset(), self.header.node_count as usize)
    }

    /// The chunk's root node (every chunk has one, [`WideNode::EMPTY`] without strips).
    pub fn root(&mut self) -> io::Result<WideNode> {
        let root = self.read_records(self.header.nodes_offset(), 1)?;
        Ok(root[0])
    }

    pub fn records(&mut self) -> io::Result<Vec<StripRecord>> {
        self.read_records(
            self.header.records_offset(),
            self.header.strip_count as usize,
        )
    }

    /// Copies the strip blocks to `out`.
    pub fn copy_data(&mut self, out: &mut dyn Write) -> io::Result<()> {
        self.file.seek(SeekFrom::Start(self.header.data_offset()))?;
        let copied = io::copy(&mut (&mut self.file).take(self.header.data_bytes), out)?;
        if copied != self.header.data_bytes {
            return Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "strip chunk data is short",
            ));
        }
        Ok(())
    }

    /// Hands each strip's attributes to `visit`, in file order.
    pub fn visit_attributes(&mut self, visit: &mut AttributeVisit) -> io::Result<()> {
        let records = self.records()?;
        let header = self.header;
        let face_ids: Vec<u32> =
            self.read_records(header.attributes_offset(), header.face_id_count as usize)?;
        let normals: Vec<OctCode> = self.read_records(
            header.attributes_offset() + header.face_id_count * 4,
            header.normal_count as usize,
        )?;
        let colors: Vec<[u8; 4]> = self.read_records(
            header.attributes_offset() + (header.face_id_count + header.normal_count) * 4,
            header.color_count as usize,
        )?;
        let (mut face_ids, mut normals, mut colors) = (&face_ids[..], &normals[..], &colors[..]);
        for record in &records {
            let windows = record.reference_count as usize - 2;
            let vertices = record.vertex_count as usize;
            let attributes = StripAttributes {
                face_ids: take(&mut face_ids, windows)?.to_vec(),
                normals: take(&mut normals, vertices)?.to_vec(),
                colors: take(&mut colors, vertices)?.to_vec(),
            };
            visit(&attributes)?;
        }
        Ok(())
    }

    fn read_records<T: Pod>(&mut self, offset: u64, count: usize) -> io::Result<Vec<T>> {
        self.file.seek(SeekFrom::Start(offset))?;
        let mut records = vec![T::zeroed(); count];
        self.file
            .read_exact(bytemuck::cast_slice_mut(&mut records))?;
        Ok(records)
    }
}

/// The first `count` items of `items` (all of them when it is empty: an attribute the chunk
/// does not store), which then start after them.
fn take<'a, T>(items: &mut &'a [T], count: usize) -> io::Result<&'a [T]> {
    if items.is_empty() {
        return Ok(items);
    }
    if items.len() < count {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            "strip chunk attributes are short",
        ));
    }
    let (first, rest) = items.split_at(count);
    *items = rest;
    Ok(first)
}

#[cfg(test)]
mod tests {
    use super::*;
    use reducem::toplevel::{build, TopLevelParams};

    /// The nodes of a strip chunk come back as written, 96 bytes each, and a chunk cut short
    /// by one byte is refused.
    #[test]
    fn strip_chunk_nodes_round_trip() {
        let bounds: Vec<Aabb> = (0..300)
            .map(|i| {
                let at = [i as f32 * 0.5, (i % 7) as f32, (i % 11) as f32 * 0.25];
                Aabb {
                    min: at,
                    max: at.map(|c| c + 0.75),
                }
            })
            .collect();
        let nodes = build(&bounds, &TopLevelParams::default()).unwrap().nodes;
        assert!(nodes.len() > 1);
        let header = StripChunkHeader::new(&ChunkStats::default(), &bounds[0], nodes.len(), &[]);
        let dir = std::env::temp_dir().join(format!("strip-chunk-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("chunk.strips");
        let mut bytes = Vec::new();
        write_strips(&mut bytes, &header, &nodes, &[], &[]).unwrap();
        assert_eq!(bytes.len(), 160 + 96 * nodes.len());
        std::fs::write(&path, &bytes).unwrap();
        let mut chunk = StripChunk::open(&path).unwrap();
        assert_eq!(chunk.nodes().unwrap(), nodes);
        assert_eq!(chunk.root().unwrap(), nodes[0]);
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(StripChunk::open(&path).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

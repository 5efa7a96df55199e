//! STL streamed into the chunker: welded with memory bounded by the window, not the model.
//!
//! The weld must give every corner the vertex id [`super::stl::read_stl`] gives it: distinct
//! positions (by bits) numbered in order of their first corner. Three passes over the facets
//! find those ids without holding the model:
//!
//! 1. The facets are cut into windows. Within a window a hash map finds the positions seen
//!    there first, and each of those is spilled, with its corner number, to one of several
//!    bucket files chosen by a hash of the position, so that every occurrence of a position
//!    lands in the same bucket, in corner order.
//! 2. Each bucket in turn is sorted by position: the first corner of each group is the
//!    position's first corner in the whole file. It is marked in a bit set over all corners
//!    (1 bit a corner), and every record's answer (that first corner) is written back in the
//!    bucket's order.
//! 3. The windows are read again with the same hash map, now to vertex ids; a position new to
//!    the window takes the next answer of its bucket, and its id is the number of first
//!    corners before that answer (a rank in the bit set). A corner that is its own answer
//!    brings a new vertex, in id order.
//!
//! Pass 3 writes the welded mesh as a binary PLY in the temporary directory, which is then read
//! like any binary PLY (windows of `window_bytes`). An ASCII STL is first rewritten as a binary
//! one (a polygon facet as its fan, which keeps the order of first occurrences), so both
//! flavours share the weld; errors are found while reading the input and name it.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::hash::{BuildHasher, BuildHasherDefault};
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

use rayon::prelude::*;

use super::error::{InputError, InputErrorKind, Location};
use super::ply::io_error;
use super::source::WindowedPly;
use super::stl::{self, fan, FacetSink, StlLayout};
use super::temporary::{TemporaryFile, TemporarySource};
use super::{AttributeRequest, MeshSource, PlyStream};
use crate::geometry::Point;
use crate::splitmix::WordHasher;

type PositionBuild = BuildHasherDefault<WordHasher>;

/// Bytes a corner costs in a window's hash map (its 16-byte entry, the map's control byte and
/// its spare capacity).
const WINDOW_BYTES_PER_CORNER: usize = 32;
/// Bytes a spilled record costs while its bucket is sorted: the record (position and corner),
/// its sort key and its answer.
const BUCKET_BYTES_PER_RECORD: usize = RECORD_BYTES + 16 + 8;
const RECORD_BYTES: usize = 12 + 8;
/// Open bucket files at most; a larger model makes larger buckets.
const MAX_BUCKETS: u64 = 256;
const IO_BUFFER_BYTES: usize = 64 << 10;

/// Opens the STL at `path` as a source of its welded mesh, with memory bounded by
/// `window_bytes` plus one bit a corner.
pub(crate) fn open_streamed(
    path: &Path,
    window_bytes: usize,
) -> Result<Box<dyn MeshSource>, InputError> {
    match stl::layout(path)? {
        StlLayout::Binary { facets } => weld(path, path, facets, window_bytes),
        StlLayout::Ascii => {
            let (binary, triangles) = ascii_as_binary(path)?;
            weld(binary.path(), path, triangles, window_bytes).map_err(|e| binary.rename(e))
        }
    }
}

/// Welds the binary STL `stl` of `facets` facets (read for the input `input`) into a temporary
/// binary PLY and opens that.
fn weld(
    stl: &Path,
    input: &Path,
    facets: u64,
    window_bytes: usize,
) -> Result<Box<dyn MeshSource>, InputError> {
    let windows = Windows::new(facets, window_bytes);
    let buckets = spill_window_firsts(stl, input, &windows)?;
    let (answers, firsts) = resolve_buckets(input, 3 * facets, buckets)?;
    let ply = write_welded_ply(stl, input, &windows, answers, &firsts)?;
    let stream = PlyStream::open(ply.path()).map_err(|error| ply.rename(error))?;
    let source = WindowedPly {
        stream,
        request: AttributeRequest::default(),
        window_bytes,
    };
    Ok(Box::new(TemporarySource::new(Box::new(source), ply)))
}

/// How the facets are cut into windows and positions into buckets.
struct Windows {
    facets: u64,
    facets_per_window: u64,
    buckets: u64,
}

impl Windows {
    fn new(facets: u64, window_bytes: usize) -> Windows {
        let corners = 3 * facets;
        let records_per_bucket = (window_bytes / BUCKET_BYTES_PER_RECORD).max(1) as u64;
        Windows {
            facets,
            facets_per_window: (window_bytes / (3 * WINDOW_BYTES_PER_CORNER)).max(1) as u64,
            buckets: corners.div_ceil(records_per_bucket).clamp(1, MAX_BUCKETS),
        }
    }

    fn bucket_of(&self, bits: &[u32; 3]) -> usize {
        let hash = PositionBuild::default().hash_one(bits);
        ((u128::from(hash) * u128::from(self.buckets)) >> 64) as usize
    }

    /// Visits every corner of `stl` as `visit(corner, position_bits, known)`, where `known` is
    /// what `visit` returned for the position's earlier corner in the same window, if any.
    fn for_each_corner(
        &self,
        stl: &Path,
        mut visit: impl FnMut(u64, [u32; 3], Option<u32>) -> Result<u32, InputError>,
    ) -> Result<(), InputError> {
        let corners = (3 * self.facets_per_window.min(self.facets)) as usize;
        let mut seen: HashMap<[u32; 3], u32, PositionBuild> =
            HashMap::with_capacity_and_hasher(corners, PositionBuild::default());
        stl::for_each_binary_facet(stl, self.facets, |facet, points| {
            if facet % self.facets_per_window == 0 {
                seen.clear();
            }
            for (corner, point) in (3 * facet..).zip(points) {
                let bits = point.map(f32::to_bits);
                match seen.get(&bits) {
                    Some(&value) => {
                        visit(corner, bits, Some(value))?;
                    }
                    None => {
                        let value = visit(corner, bits, None)?;
                        seen.insert(bits, value);
                    }
                }
            }
            Ok(())
        })
    }
}

/// A temporary file written through a buffer.
struct Spill {
    file: TemporaryFile,
    writer: BufWriter<File>,
}

impl Spill {
    fn create(input: &Path, name: &str) -> Result<Spill, InputError> {
        let (file, handle) = TemporaryFile::create(input, name)?;
        let writer = BufWriter::with_capacity(IO_BUFFER_BYTES, handle);
        Ok(Spill { file, writer })
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), InputError> {
        let path = self.file.path();
        self.writer
            .write_all(bytes)
            .map_err(|error| io_error(path, &error))
    }

    /// The file, written out and rewound for reading.
    fn finish(self) -> Result<(TemporaryFile, File), InputError> {
        let path = self.file.path();
        let mut handle = self
            .writer
            .into_inner()
            .map_err(|error| io_error(path, error.error()))?;
        handle
            .seek(SeekFrom::Start(0))
            .map_err(|error| io_error(path, &error))?;
        Ok((self.file, handle))
    }
}

/// Pass 1: each position new to its window, with its corner, into its bucket.
fn spill_window_firsts(
    stl: &Path,
    input: &Path,
    windows: &Windows,
) -> Result<Vec<Spill>, InputError> {
    let mut buckets = (0..windows.buckets)
        .map(|bucket| Spill::create(input, &format!("stl-bucket-{bucket}")))
        .collect::<Result<Vec<_>, _>>()?;
    windows.for_each_corner(stl, |corner, bits, known| {
        if known.is_some() {
            return Ok(0);
        }
        let mut record = [0u8; RECORD_BYTES];
        for (axis, value) in bits.iter().enumerate() {
            record[4 * axis..4 * axis + 4].copy_from_slice(&value.to_le_bytes());
        }
        record[12..].copy_from_slice(&corner.to_le_bytes());
        buckets[windows.bucket_of(&bits)].write(&record)?;
        Ok(0)
    })?;
    Ok(buckets)
}

/// A bucket's answers, read back in the order its records were spilled.
struct Answers {
    file: TemporaryFile,
    reader: BufReader<File>,
}

impl Answers {
    fn next(&mut self) -> Result<u64, InputError> {
        let mut bytes = [0u8; 8];
        let path = self.file.path();
        self.reader
            .read_exact(&mut bytes)
            .map_err(|error| io_error(path, &error))?;
        Ok(u64::from_le_bytes(bytes))
    }
}

/// Pass 2: every bucket's answers (the first corner of each record's position), and the set
/// of first corners.
fn resolve_buckets(
    input: &Path,
    corners: u64,
    buckets: Vec<Spill>,
) -> Result<(Vec<Answers>, FirstCorners), InputError> {
    let mut firsts = FirstCorners::new(corners);
    let mut answers = Vec::with_capacity(buckets.len());
    for bucket in buckets {
        let (records_file, mut records) = bucket.finish()?;
        let mut bytes = Vec::new();
        records
            .read_to_end(&mut bytes)
            .map_err(|error| io_error(records_file.path(), &error))?;
        drop((records, records_file));
        let mut spill = Spill::create(input, "stl-answers")?;
        for first in first_corners(&bytes, &mut firsts) {
            spill.write(&first.to_le_bytes())?;
        }
        let (file, handle) = spill.finish()?;
        let reader = BufReader::with_capacity(IO_BUFFER_BYTES, handle);
        answers.push(Answers { file, reader });
    }
    firsts.count_ranks();
    Ok((answers, firsts))
}

/// The first corner of each record's position among the records (which are in corner order,
/// as spilled), marking each in `firsts`.
fn first_corners(records: &[u8], firsts: &mut FirstCorners) -> Vec<u64> {
    let record = |index: usize| &records[RECORD_BYTES * index..RECORD_BYTES * (index + 1)];
    let count = records.len() / RECORD_BYTES;
    // Position bits above the record's index: equal positions sort together, earliest first.
    let mut keys: Vec<u128> = (0..count)
        .into_par_iter()
        .map(|index| {
            let bits = u128::from_le_bytes({
                let mut key = [0u8; 16];
                key[4..].copy_from_slice(&record(index)[..12]);
                key
            });
            bits | index as u128
        })
        .collect();
    keys.par_sort_unstable();
    let corner = |index: usize| u64::from_le_bytes(record(index)[12..].try_into().expect("8"));
    let mut answers = vec![0u64; count];
    for group in keys.chunk_by(|a, b| a >> 32 == b >> 32) {
        let first = corner(group[0] as u32 as usize);
        firsts.mark(first);
        for &key in group {
            answers[key as u32 as usize] = first;
        }
    }
    answers
}

/// The corners that are their position's first, with the rank of each.
struct FirstCorners {
    bits: Vec<u64>,
    /// Marked corners before each block of `WORDS_PER_BLOCK` words.
    before_block: Vec<u64>,
}

const WORDS_PER_BLOCK: usize = 8;

impl FirstCorners {
    fn new(corners: u64) -> FirstCorners {
        FirstCorners {
            bits: vec![0; corners.div_ceil(64) as usize],
            before_block: Vec::new(),
        }
    }

    fn mark(&mut self, corner: u64) {
        self.bits[(corner / 64) as usize] |= 1 << (corner % 64);
    }

    fn count_ranks(&mut self) {
        let mut count = 0;
        self.before_block = self
            .bits
            .chunks(WORDS_PER_BLOCK)
            .map(|block| {
                let before = count;
                count += block
                    .iter()
                    .map(|word| u64::from(word.count_ones()))
                    .sum::<u64>();
                before
            })
            .collect();
        self.before_block.push(count);
    }

    /// Marked corners in all.
    fn count(&self) -> u64 {
        self.before_block.last().copied().unwrap_or(0)
    }

    /// Marked corners before `corner`: the vertex id of the position first seen there.
    fn rank(&self, corner: u64) -> u64 {
        let word = (corner / 64) as usize;
        let block = word / WORDS_PER_BLOCK;
        let whole_words = &self.bits[block * WORDS_PER_BLOCK..word];
        let below = self.bits[word] & ((1u64 << (corner % 64)) - 1);
        self.before_block[block]
            + whole_words
                .iter()
                .map(|word| u64::from(word.count_ones()))
                .sum::<u64>()
            + u64::from(below.count_ones())
    }
}

/// Pass 3: the welded mesh as a binary PLY, vertices in id order, one triangle a facet.
fn write_welded_ply(
    stl: &Path,
    input: &Path,
    windows: &Windows,
    mut answers: Vec<Answers>,
    firsts: &FirstCorners,
) -> Result<TemporaryFile, InputError> {
    let vertices = firsts.count();
    if vertices >= u64::from(u32::MAX) {
        let kind = InputErrorKind::TooManyVertices {
            vertex_count: vertices,
        };
        return Err(InputError::new(input, Location::File, kind));
    }
    let header = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\n\
         property float x\nproperty float y\nproperty float z\nelement face {}\n\
         property list uchar uint vertex_indices\nend_header\n",
        windows.facets
    );
    let (ply, mut file) = TemporaryFile::create(input, "stl-welded.ply")?;
    let path = ply.path();
    file.write_all(header.as_bytes())
        .map_err(|error| io_error(path, &error))?;
    let vertex_start = header.len() as u64;
    let mut positions = PlyWriter::at(path, vertex_start)?;
    let mut faces = PlyWriter::at(path, vertex_start + 12 * vertices)?;
    // A face: its corner count (3), then the corners' vertex ids.
    let mut face = [3u8; 13];
    windows.for_each_corner(stl, |corner, bits, known| {
        let id = match known {
            Some(id) => id,
            None => {
                let first = answers[windows.bucket_of(&bits)].next()?;
                if first == corner {
                    positions.write(&bits.map(u32::to_le_bytes).concat())?;
                }
                firsts.rank(first) as u32
            }
        };
        let slot = 1 + 4 * (corner % 3) as usize;
        face[slot..slot + 4].copy_from_slice(&id.to_le_bytes());
        if corner % 3 == 2 {
            faces.write(&face)?;
        }
        Ok(id)
    })?;
    positions.finish()?;
    faces.finish()?;
    Ok(ply)
}

/// A buffered writer at an offset of the welded PLY.
struct PlyWriter<'a> {
    path: &'a Path,
    writer: BufWriter<File>,
}

impl<'a> PlyWriter<'a> {
    fn at(path: &'a Path, offset: u64) -> Result<PlyWriter<'a>, InputError> {
        let mut handle = OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(|error| io_error(path, &error))?;
        handle
            .seek(SeekFrom::Start(offset))
            .map_err(|error| io_error(path, &error))?;
        let writer = BufWriter::with_capacity(IO_BUFFER_BYTES, handle);
        Ok(PlyWriter { path, writer })
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), InputError> {
        let path = self.path;
        self.writer
            .write_all(bytes)
            .map_err(|error| io_error(path, &error))
    }

    fn finish(mut self) -> Result<(), InputError> {
        let path = self.path;
        self.writer.flush().map_err(|error| io_error(path, &error))
    }
}

/// An ASCII STL rewritten as a binary one in the temporary directory, a polygon facet as its
/// fan; and its triangle count.
fn ascii_as_binary(path: &Path) -> Result<(TemporaryFile, u64), InputError> {
    let spill = Spill::create(path, "stl-binary.stl")?;
    let mut writer = BinaryFacets {
        spill,
        triangles: 0,
    };
    writer.spill.write(&[0; 84])?;
    stl::read_ascii(path, &mut writer)?;
    let triangles = writer.triangles;
    let (binary, mut handle) = writer.spill.finish()?;
    let count = u32::try_from(triangles).map_err(|_| {
        let kind = InputErrorKind::TooManyFaces {
            face_count: triangles,
        };
        InputError::new(path, Location::File, kind)
    })?;
    handle
        .seek(SeekFrom::Start(80))
        .and_then(|_| handle.write_all(&count.to_le_bytes()))
        .map_err(|error| io_error(binary.path(), &error))?;
    Ok((binary, triangles))
}

/// Facets written as binary STL triangles, counted.
struct BinaryFacets {
    spill: Spill,
    triangles: u64,
}

impl FacetSink for BinaryFacets {
    fn polygon(&mut self, _path: &Path, _facet: u64, corners: &[Point]) -> Result<(), InputError> {
        for triangle in fan(corners) {
            let mut record = [0u8; 50];
            for (value, bytes) in triangle
                .as_flattened()
                .iter()
                .zip(record[12..48].chunks_mut(4))
            {
                bytes.copy_from_slice(&value.to_le_bytes());
            }
            self.spill.write(&record)?;
            self.triangles += 1;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;
    use crate::splitmix::SplitMix64;

    /// Facets over few positions, so that positions recur within and across windows and
    /// buckets; `0.0` and `-0.0` among them, which must stay apart.
    fn facets(count: usize) -> Vec<[Point; 3]> {
        let mut random = SplitMix64::new(7);
        let values = [0.0, -0.0, 1.5, -2.25, 3.0e-3];
        let mut point = || [0; 3].map(|_| *random.pick(&values));
        (0..count).map(|_| [point(), point(), point()]).collect()
    }

    fn binary_stl(facets: &[[Point; 3]]) -> Vec<u8> {
        let mut bytes = b"solid but binary".to_vec();
        bytes.resize(80, b' ');
        bytes.extend_from_slice(&(facets.len() as u32).to_le_bytes());
        for facet in facets {
            bytes.extend_from_slice(&[0; 12]);
            for value in facet.as_flattened() {
                bytes.extend_from_slice(&value.to_le_bytes());
            }
            bytes.extend_from_slice(&[0; 2]);
        }
        bytes
    }

    /// The facets as ASCII, each followed by a quadrilateral over its corners and the first
    /// corner moved, which the reader splits as a fan.
    fn ascii_stl(facets: &[[Point; 3]]) -> Vec<u8> {
        let mut text = String::from("solid test\n");
        for facet in facets {
            let moved = facet[0].map(|value| value + 8.0);
            for polygon in [facet.to_vec(), [facet.as_slice(), &[moved]].concat()] {
                text.push_str("facet normal 0 0 0\nouter loop\n");
                for point in polygon {
                    text.push_str(&format!(
                        "vertex {:?} {:?} {:?}\n",
                        point[0], point[1], point[2]
                    ));
                }
                text.push_str("endloop\nendfacet\n");
            }
        }
        text.push_str("endsolid test\n");
        text.into_bytes()
    }

    /// The source's mesh, gathered through its passes.
    fn gathered(source: &dyn MeshSource) -> Mesh {
        let mut positions = Vec::new();
        source
            .for_each_position_window(&mut |first, window| {
                assert_eq!(first, positions.len() as u64);
                positions.extend_from_slice(window);
            })
            .unwrap();
        let mut triangles = Vec::new();
        source
            .for_each_triangle(&mut |face, triangle| {
                assert_eq!(face, triangles.len() as u64);
                triangles.push(triangle);
            })
            .unwrap();
        let ids: Vec<u32> = (0..positions.len() as u32).step_by(3).collect();
        let picked: Vec<Point> = ids.iter().map(|&id| positions[id as usize]).collect();
        assert_eq!(source.positions_of(&ids).unwrap(), picked);
        Mesh {
            positions,
            triangles,
            face_ids: None,
            normals: None,
            colors: None,
        }
    }

    fn bits(mesh: &Mesh) -> (Vec<[u32; 3]>, &[[u32; 3]]) {
        let positions = mesh.positions.iter().map(|p| p.map(f32::to_bits)).collect();
        (positions, &mesh.triangles)
    }

    #[test]
    fn streamed_weld_gives_the_in_memory_weld_through_many_windows_and_buckets() {
        let directory = std::env::temp_dir().join(format!("stl-stream-{}", std::process::id()));
        std::fs::create_dir_all(&directory).unwrap();
        let facets = facets(3000);
        for (name, bytes) in [
            ("binary.stl", binary_stl(&facets)),
            ("ascii.stl", ascii_stl(&facets)),
        ] {
            let path = directory.join(name);
            std::fs::write(&path, bytes).unwrap();
            let expected = stl::read_stl(&path).unwrap();
            assert!(expected.positions.len() > 100 && expected.positions.len() < 3000);
            // 960 bytes: windows of 10 facets, buckets of 22 records (256 buckets).
            for window_bytes in [960, 64 << 20] {
                let streamed = gathered(&*open_streamed(&path, window_bytes).unwrap());
                assert_eq!(bits(&streamed), bits(&expected), "{name}, {window_bytes}");
            }
        }
        std::fs::remove_dir_all(&directory).unwrap();
    }
}

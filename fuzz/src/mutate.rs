//! Seeded mutators: deterministic byte, text and ReduceM-structure edits of valid inputs.
//!
//! Without coverage feedback (cargo-fuzz is not available on this machine), blind byte flips
//! rarely get past the first check of a format: a ReduceM header checksum or a PLY magic line.
//! So besides generic edits (bit flips, interesting integers and floats, inserts, deletes,
//! duplicated ranges, splices with other corpus inputs, truncation) each format gets edits that
//! keep its outer shell intact: dictionary tokens and number rewrites for the text formats,
//! field writes, section swaps and a re-sealed header checksum for ReduceM files, whole-field
//! float writes for ray files. Everything derives from one seed, so a run is reproducible.

use reducem::format::{
    PrecisionRecord, HEADER_CHECKSUMMED_BYTES, PRECISION_CHECKSUMMED_BYTES, PRECISION_OFFSET,
    SECTION_ALIGN,
};
use reducem::splitmix::SplitMix64;

/// Which format-aware edits apply on top of the generic ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Structure {
    /// PLY headers and ASCII bodies, OBJ files.
    Text(&'static [&'static str]),
    /// ReduceM files: header, section table, records and nodes.
    Reducem,
    /// `reducem query` ray files: records of 8 f32.
    Rays,
}

/// Tokens that steer PLY parsing into its less travelled paths.
pub const PLY_DICTIONARY: &[&str] = &[
    "ply\n",
    "format ascii 1.0\n",
    "format binary_little_endian 1.0\n",
    "format binary_big_endian 1.0\n",
    "element vertex ",
    "element face ",
    "element edge 1\n",
    "property float x\n",
    "property double y\n",
    "property uchar red\n",
    "property list uchar int vertex_indices\n",
    "property list uint uint vertex_index\n",
    "property list int float weights\n",
    "end_header\n",
    "comment hostile\n",
    "obj_info scanner\n",
    "\r\n",
    "\n",
    " ",
    "-1",
    "255",
    "256",
    "4294967295",
    "4294967296",
    "1099511627776",
    "18446744073709551615",
    "nan",
    "inf",
    "-inf",
    "1e39",
    "-3.4028235e38",
    "1e-45",
    "-0",
];

/// Tokens for ASCII STL keywords and numbers, and the bytes that decide binary or ASCII.
pub const STL_DICTIONARY: &[&str] = &[
    "solid ",
    "endsolid\n",
    "facet normal 0 0 1\n",
    "outer loop\n",
    "vertex 0 0 0\n",
    "vertex ",
    "endloop\n",
    "endfacet\n",
    "\r\n",
    "\n",
    " ",
    "\u{0}\u{0}\u{0}\u{0}",
    "\u{1}\u{0}\u{0}\u{0}",
    "\u{1f}\u{8b}",
    "nan",
    "inf",
    "1e39",
    "-0",
    "1.0000000596046447753906250001",
];

/// Tokens for glTF JSON: the keys and values that steer the reader, and GLB chunk words.
pub const GLTF_DICTIONARY: &[&str] = &[
    "\"mode\":5,",
    "\"mode\":6,",
    "\"mode\":1,",
    "\"componentType\":5120,",
    "\"componentType\":5123,",
    "\"componentType\":5125,",
    "\"normalized\":true,",
    "\"byteStride\":4,",
    "\"byteStride\":255,",
    "\"byteOffset\":4294967295,",
    "\"count\":1000000000,",
    "\"type\":\"VEC4\",",
    "\"children\":[0],",
    "\"scale\":[-1,1,1],",
    "\"matrix\":[0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0],",
    "\"sparse\":{\"count\":1,\"indices\":{\"bufferView\":0,\"componentType\":5121},\"values\":{\"bufferView\":0}},",
    "\"extensionsRequired\":[\"KHR_draco_mesh_compression\"],",
    "\"extensions\":{\"EXT_meshopt_compression\":{\"buffer\":0,\"byteLength\":8,\"byteStride\":4,\"count\":3,\"mode\":\"TRIANGLES\"}},",
    "data:application/octet-stream;base64,",
    "JSON",
    "BIN\u{0}",
    "glTF",
    "\u{2}\u{0}\u{0}\u{0}",
    "\u{ff}\u{ff}\u{ff}\u{ff}",
    "0",
    "-1",
    "1e39",
    "null",
];

/// Tokens for OBJ statements, references and numbers.
pub const OBJ_DICTIONARY: &[&str] = &[
    "v ",
    "vt ",
    "vn ",
    "f ",
    "f 1 2 3\n",
    "f -1 -2 -3\n",
    "f 1/1/1 2/2/2 3/3/3\n",
    "f 1//1 2//2 3//3 4//4\n",
    "f 0 1 2\n",
    "l 1 2\n",
    "p 1\n",
    "o part\n",
    "g group\n",
    "s off\n",
    "mtllib missing.mtl\n",
    "usemtl none\n",
    "# comment\n",
    "\\\n",
    "\r\n",
    "\n",
    " ",
    "/",
    "-1",
    "4294967296",
    "99999999999",
    "nan",
    "inf",
    "1e39",
    "-0",
    "3.4028235e38",
];

const INTERESTING_INTEGERS: &[u64] = &[
    0,
    1,
    2,
    3,
    7,
    0x7F,
    0x80,
    0xFF,
    0x100,
    0xFFFF,
    0x1_0000,
    4096,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    1 << 32,
    1 << 40,
    i64::MAX as u64,
    u64::MAX,
];

const INTERESTING_FLOATS: &[f32] = &[
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    1e-6,
    1e6,
    f32::MIN_POSITIVE,
    1e-45,
    f32::MAX,
    f32::MIN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::NAN,
    f32::EPSILON,
];

/// Byte ranges of the ReduceM header's fields: (offset, size).
const HEADER_FIELDS: &[(usize, usize)] = &[
    (8, 2),
    (10, 2),
    (12, 4),
    (16, 4),
    (20, 4),
    (24, 4),
    (28, 4),
    (32, 8),
    (40, 8),
    (48, 8),
    (80, 4),
    (92, 4),
    // The precision record: grid bits, origin, cell.
    (208, 4),
    (216, 4),
    (224, 4),
    (228, 4),
];

/// One way of corrupting a ReduceM file, as the corruption campaign counts them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corruption {
    BitFlips,
    Truncation,
    SectionSwap,
}

impl Corruption {
    pub const ALL: [Corruption; 3] = [
        Corruption::BitFlips,
        Corruption::Truncation,
        Corruption::SectionSwap,
    ];
}

pub struct Mutator {
    rng: SplitMix64,
    structure: Structure,
}

impl Mutator {
    pub fn new(seed: u64, structure: Structure) -> Mutator {
        Mutator {
            rng: SplitMix64::new(seed),
            structure,
        }
    }

    /// A mutant of `input`: one to four edits, `corpus` supplying splice material.
    pub fn mutate(&mut self, input: &[u8], corpus: &[Vec<u8>]) -> Vec<u8> {
        let mut data = input.to_vec();
        for _ in 0..1 + self.rng.below(4) {
            if self.rng.chance(2) {
                self.generic_edit(&mut data, corpus);
            } else {
                self.structured_edit(&mut data);
            }
        }
        // A stale header checksum stops the opener at byte 200; re-sealing most mutants lets
        // them reach the section, record and node checks.
        if self.structure == Structure::Reducem && !self.rng.chance(4) {
            seal_header(&mut data);
        }
        data
    }

    /// `valid` corrupted in one of the ways the corruption campaign counts.
    pub fn corrupt(&mut self, valid: &[u8], kind: Corruption) -> Vec<u8> {
        let mut data = valid.to_vec();
        match kind {
            Corruption::BitFlips => {
                for _ in 0..1 + self.rng.below(8) {
                    flip_bit(&mut self.rng, &mut data);
                }
                if self.rng.chance(2) {
                    seal_header(&mut data);
                }
            }
            Corruption::Truncation => {
                let length = self.rng.below(data.len());
                data.truncate(length);
            }
            Corruption::SectionSwap => {
                self.swap_sections(&mut data);
                seal_header(&mut data);
            }
        }
        data
    }

    fn generic_edit(&mut self, data: &mut Vec<u8>, corpus: &[Vec<u8>]) {
        let rng = &mut self.rng;
        if data.is_empty() {
            data.push(rng.next_u64() as u8);
            return;
        }
        match rng.below(8) {
            0 => flip_bit(rng, data),
            1 => {
                let value = *rng.pick(INTERESTING_INTEGERS);
                let width = *rng.pick(&[1usize, 2, 4, 8]);
                let at = rng.below(data.len());
                let bytes = if rng.chance(2) {
                    value.to_le_bytes()
                } else {
                    (value << (64 - 8 * width as u32).min(63)).to_be_bytes()
                };
                overwrite(data, at, &bytes[..width]);
            }
            2 => {
                let at = rng.below(data.len() + 1);
                let length = 1 + rng.below(16);
                let bytes: Vec<u8> = (0..length).map(|_| rng.next_u64() as u8).collect();
                data.splice(at..at, bytes);
            }
            3 => {
                let start = rng.below(data.len());
                let end = start + 1 + rng.below((data.len() - start).min(64));
                data.drain(start..end);
            }
            4 => {
                let start = rng.below(data.len());
                let end = start + 1 + rng.below((data.len() - start).min(256));
                let chunk = data[start..end].to_vec();
                let at = rng.below(data.len() + 1);
                data.splice(at..at, chunk);
            }
            5 => {
                let other = rng.pick(corpus);
                let cut = rng.below(data.len() + 1);
                let from = rng.below(other.len() + 1);
                data.truncate(cut);
                data.extend_from_slice(&other[from..]);
            }
            6 => {
                let length = rng.below(data.len());
                data.truncate(length);
            }
            _ => {
                let value = *rng.pick(INTERESTING_FLOATS);
                let at = rng.below(data.len());
                overwrite(data, at, &value.to_le_bytes());
            }
        }
    }

    fn structured_edit(&mut self, data: &mut Vec<u8>) {
        match self.structure {
            Structure::Text(dictionary) => self.text_edit(data, dictionary),
            Structure::Reducem => self.reducem_edit(data),
            Structure::Rays => {
                if data.len() >= 4 {
                    let field = self.rng.below(data.len() / 4);
                    let value = *self.rng.pick(INTERESTING_FLOATS);
                    overwrite(data, 4 * field, &value.to_le_bytes());
                }
            }
        }
    }

    fn text_edit(&mut self, data: &mut Vec<u8>, dictionary: &[&str]) {
        let rng = &mut self.rng;
        match rng.below(4) {
            0 => {
                let token = rng.pick(dictionary).as_bytes();
                let at = rng.below(data.len() + 1);
                data.splice(at..at, token.iter().copied());
            }
            1 => {
                // Counts, indices and coordinates are digit runs: rewriting one reaches the
                // header-count and index checks without breaking the grammar around it.
                let runs = digit_runs(data);
                if !runs.is_empty() {
                    let (start, end) = *rng.pick(&runs);
                    let number = rng.pick(dictionary);
                    let replacement = if number.bytes().all(|b| b.is_ascii_digit() || b == b'-') {
                        number.to_string()
                    } else {
                        rng.pick(INTERESTING_INTEGERS).to_string()
                    };
                    data.splice(start..end, replacement.into_bytes());
                }
            }
            2 => {
                let lines = line_starts(data);
                let start = *rng.pick(&lines);
                let end = data[start..]
                    .iter()
                    .position(|&b| b == b'\n')
                    .map_or(data.len(), |p| start + p + 1);
                if rng.chance(2) {
                    data.drain(start..end);
                } else {
                    let line = data[start..end].to_vec();
                    data.splice(start..start, line);
                }
            }
            _ => {
                let newlines: Vec<usize> = (0..data.len()).filter(|&i| data[i] == b'\n').collect();
                if !newlines.is_empty() {
                    let at = *rng.pick(&newlines);
                    data.insert(at, b'\r');
                }
            }
        }
    }

    fn reducem_edit(&mut self, data: &mut [u8]) {
        if data.len() < SECTION_ALIGN as usize {
            return;
        }
        match self.rng.below(5) {
            0 => {
                let (offset, size) = *self.rng.pick(HEADER_FIELDS);
                self.write_integer(data, offset, size);
            }
            1 => {
                let slot = self.rng.below(3);
                let field = *self.rng.pick(&[0usize, 8, 16]);
                let size = if field == 0 { 4 } else { 8 };
                self.write_integer(data, 104 + 32 * slot + field, size);
            }
            2 => self.edit_record(data, 1, 8, &[(0, 4), (4, 2), (6, 2)]),
            3 => self.edit_record(data, 0, 128, TOP_NODE_FIELDS),
            _ => self.swap_sections(data),
        }
    }

    /// Writes an interesting value into one field of a random record of section `slot`.
    fn edit_record(
        &mut self,
        data: &mut [u8],
        slot: usize,
        record: u64,
        fields: &[(usize, usize)],
    ) {
        let (offset, length) = section_entry(data, slot);
        if length < record || offset.saturating_add(length) > data.len() as u64 {
            return;
        }
        let index = self.rng.below((length / record) as usize) as u64;
        let (field, size) = *self.rng.pick(fields);
        let at = (offset + index * record) as usize + field;
        if self.rng.chance(3) {
            let value = *self.rng.pick(INTERESTING_FLOATS);
            overwrite(data, at, &value.to_le_bytes()[..size.min(4)]);
        } else {
            self.write_integer(data, at, size);
        }
    }

    fn write_integer(&mut self, data: &mut [u8], at: usize, size: usize) {
        let value = if self.rng.chance(2) {
            *self.rng.pick(INTERESTING_INTEGERS)
        } else {
            let current = read_le(data, at, size);
            current
                .wrapping_add(self.rng.below(9) as u64)
                .wrapping_sub(4)
        };
        overwrite(data, at, &value.to_le_bytes()[..size]);
    }

    /// Swaps two section table entries, or the leading bytes of two sections' contents.
    fn swap_sections(&mut self, data: &mut [u8]) {
        if data.len() < HEADER_CHECKSUMMED_BYTES {
            return;
        }
        let a = self.rng.below(3);
        let b = (a + 1 + self.rng.below(2)) % 3;
        if self.rng.chance(2) {
            let (first, second) = (104 + 32 * a.min(b), 104 + 32 * a.max(b));
            let (head, tail) = data.split_at_mut(second);
            head[first..first + 32].swap_with_slice(&mut tail[..32]);
            return;
        }
        let (offset_a, length_a) = section_entry(data, a);
        let (offset_b, length_b) = section_entry(data, b);
        let length = length_a.min(length_b);
        let end_a = offset_a.saturating_add(length);
        let end_b = offset_b.saturating_add(length);
        let file = data.len() as u64;
        if length == 0 || end_a > file || end_b > file || end_a > offset_b && end_b > offset_a {
            return;
        }
        let (low, high) = (
            offset_a.min(offset_b) as usize,
            offset_a.max(offset_b) as usize,
        );
        let (head, tail) = data.split_at_mut(high);
        head[low..low + length as usize].swap_with_slice(&mut tail[..length as usize]);
    }
}

/// Recomputes the header and precision record checksums so their own checks pass.
pub fn seal_header(data: &mut [u8]) {
    if data.len() >= HEADER_CHECKSUMMED_BYTES + 8 {
        let checksum = xxhash_rust::xxh3::xxh3_64(&data[..HEADER_CHECKSUMMED_BYTES]);
        data[HEADER_CHECKSUMMED_BYTES..HEADER_CHECKSUMMED_BYTES + 8]
            .copy_from_slice(&checksum.to_le_bytes());
    }
    let record_end = PRECISION_OFFSET + size_of::<PrecisionRecord>();
    if data.len() >= record_end {
        let checksummed = PRECISION_OFFSET..PRECISION_OFFSET + PRECISION_CHECKSUMMED_BYTES;
        let checksum = xxhash_rust::xxh3::xxh3_64(&data[checksummed.clone()]);
        data[checksummed.end..record_end].copy_from_slice(&checksum.to_le_bytes());
    }
}

/// Fields of a 128-byte top-level node worth corrupting: box planes of the first and last slot
/// (the last is usually empty, and must stay exactly so), every child link and every kind.
const TOP_NODE_FIELDS: &[(usize, usize)] = &[
    (0, 4),
    (12, 4),
    (48, 4),
    (60, 4),
    (96, 4),
    (100, 4),
    (104, 4),
    (108, 4),
    (112, 4),
    (116, 4),
    (120, 4),
    (124, 4),
];

/// Offset and length of section table entry `slot`.
fn section_entry(data: &[u8], slot: usize) -> (u64, u64) {
    let entry = 104 + 32 * slot;
    (read_le(data, entry + 8, 8), read_le(data, entry + 16, 8))
}

fn read_le(data: &[u8], at: usize, size: usize) -> u64 {
    let mut bytes = [0u8; 8];
    let available = data.len().saturating_sub(at).min(size);
    bytes[..available].copy_from_slice(&data[at..at + available]);
    u64::from_le_bytes(bytes)
}

/// Writes `bytes` at `at`, clipped to the end of `data`.
fn overwrite(data: &mut [u8], at: usize, bytes: &[u8]) {
    let length = bytes.len().min(data.len().saturating_sub(at));
    data[at..at + length].copy_from_slice(&bytes[..length]);
}

fn flip_bit(rng: &mut SplitMix64, data: &mut [u8]) {
    if !data.is_empty() {
        let at = rng.below(data.len());
        data[at] ^= 1 << rng.below(8);
    }
}

fn digit_runs(data: &[u8]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut start = None;
    for (i, byte) in data.iter().enumerate().chain([(data.len(), &b' ')]) {
        match (byte.is_ascii_digit(), start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                runs.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    runs
}

fn line_starts(data: &[u8]) -> Vec<usize> {
    std::iter::once(0)
        .chain((0..data.len()).filter(|&i| data[i] == b'\n').map(|i| i + 1))
        .filter(|&start| start < data.len().max(1))
        .collect()
}

//! The binary ray and hit files of `reducem query`.
//!
//! Rays: little-endian f32 × 8 per ray (`ox oy oz dx dy dz tmin tmax`), 32 bytes, no header.
//! Hits: f32 × 4 per ray (`t nx ny nz`), `t = +inf` and a zero normal on a miss. Occlusion: one
//! byte per ray, 1 when occluded. A ray file is validated whole before anything is traced, or
//! ([`RayFile::open_checked_while_traced`]) chunk by chunk just before each is traced; either
//! way every defect names the file, the first invalid ray and the byte offset of the offending
//! field. Output is written to a temporary file and renamed, so a failed run leaves no partial
//! output.
//!
//! Rays may also come from a stream (`-` for standard input, a pipe, a FIFO, a device): a stream
//! cannot be mapped (a pipe maps as empty), so it is read to its end and decoded. Answers may go
//! to a stream too ([`write_answers_streamed`]), in input order.
//!
//! A batch job spends much of its time outside the tracer unless the files are handled without
//! copies and in parallel: the ray file is mapped and, on a little-endian machine, its records
//! are the rays themselves ([`RayFile`]: validated in place on every core, never copied), and
//! each chunk of rays is traced on every core and encoded into a small buffer, which a writing
//! thread writes at its place in the output file and hands back for reuse ([`write_answers`]),
//! with no per-ray `Hit` vector and no output-sized buffer in between. Fresh memory costs a
//! page fault per 4 KiB page (about 0.75 ms per MB on the 2-core test machine: a copy of 122
//! MB of AO rays took 110 ms before tracing began), so the rays and answers of a batch are
//! never held in it.

use std::fs::File;
use std::io::{self, Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use bytemuck::Zeroable;
use memmap2::Mmap;
use rayon::prelude::*;

use super::attributes::{hit_attributes, HitAttributes};
use super::ray::{Hit, Ray};
use super::ray_order;
use super::Tracer;
use crate::format::reader::ReducemFile;
use crate::{atomic, mapping};

/// Bytes per ray record.
pub const RAY_BYTES: usize = 32;

/// The ray file argument that names standard input.
pub const STDIN_ARGUMENT: &str = "-";

/// How messages name standard input.
const STDIN_NAME: &str = "standard input";

/// Bytes read from a ray stream at a time (a whole number of records), decoded before the next
/// read: the stream is held once, as rays.
const STREAM_BLOCK_BYTES: usize = RAY_BYTES << 15;

const FIELD_NAMES: [&str; 8] = ["ox", "oy", "oz", "dx", "dy", "dz", "tmin", "tmax"];

/// Why a ray file was rejected.
#[derive(Debug, thiserror::Error)]
pub enum RayFileError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error(
        "{}: {size} bytes is not a multiple of {RAY_BYTES} (8 little-endian f32 per ray): \
         ray {ray} at byte {offset} is incomplete",
        path.display()
    )]
    Truncated {
        path: PathBuf,
        size: usize,
        ray: usize,
        offset: usize,
    },
    #[error("{}: ray {ray} at byte {offset}: {detail}", path.display())]
    Invalid {
        path: PathBuf,
        ray: usize,
        offset: usize,
        detail: String,
    },
}

/// Reads and validates the ray file at `path` into a vector (mapped, validated on every core).
pub fn read_rays(path: &Path) -> Result<Vec<Ray>, RayFileError> {
    Ok(RayFile::open(path, InvalidRays::Reject)?.records().to_vec())
}

/// Validates `bytes` as a ray file (`path` is only for messages). The error names the first
/// invalid ray, whatever the thread count.
pub fn parse_rays(path: &Path, bytes: &[u8]) -> Result<Vec<Ray>, RayFileError> {
    check_length(path, bytes)?;
    let rays = decode_records(bytes);
    match all_valid(&rays) {
        true => Ok(rays),
        false => Err(first_defect(path, &rays)),
    }
}

/// The records of `bytes` (a whole number of them) as rays, unchecked; on every core.
fn decode_records(bytes: &[u8]) -> Vec<Ray> {
    // Decoded in place into one vector, chunk by chunk: a collect builds and joins a vector
    // per task.
    let mut rays = vec![Ray::zeroed(); bytes.len() / RAY_BYTES];
    rays.par_chunks_mut(PARSE_CHUNK)
        .zip(bytes.par_chunks(PARSE_CHUNK * RAY_BYTES))
        .for_each(|(rays, records)| {
            for (ray, record) in rays.iter_mut().zip(records.chunks_exact(RAY_BYTES)) {
                *ray = decode_record(record);
            }
        });
    rays
}

/// Whether every ray of `rays` is valid ([`is_valid`]), on every core.
fn all_valid(rays: &[Ray]) -> bool {
    rays.par_chunks(PARSE_CHUNK)
        .all(|rays| rays.iter().fold(true, |all, ray| all & is_valid(ray)))
}

/// Rays validated by one task.
const PARSE_CHUNK: usize = 16 * 1024;

/// What a query does with an invalid ray (NaN, infinite origin or direction, zero direction,
/// `tmin` negative or above `tmax`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InvalidRays {
    /// The first one rejects the whole file.
    Reject,
    /// Each is answered as a miss (not occluded).
    Miss,
}

/// A validated ray file: its records read in place from the file's mapping where a record is
/// the in-memory [`Ray`] (a little-endian machine), else decoded into a vector; with
/// [`InvalidRays::Miss`], which records are valid.
pub struct RayFile {
    records: Records,
    /// The file's name in messages.
    path: PathBuf,
    /// Whether the records are yet to be checked, as they are traced
    /// ([`RayFile::open_checked_while_traced`]).
    unchecked: bool,
    /// Whether each record is valid, when one is not.
    valid: Option<Vec<bool>>,
    invalid: usize,
    first_invalid: Option<RayFileError>,
}

enum Records {
    Mapped(Mmap),
    Decoded(Vec<Ray>),
}

impl RayFile {
    /// Maps and validates the ray file at `path` (on every core); a truncated file is always
    /// an error, an invalid ray only with [`InvalidRays::Reject`]. The error names the first
    /// invalid ray, whatever the thread count.
    ///
    /// `-` reads standard input; a path that is not a regular file (a pipe, a FIFO, a device) is
    /// read as a stream to its end; the error of a stream names it and its byte count.
    pub fn open(path: &Path, invalid_rays: InvalidRays) -> Result<RayFile, RayFileError> {
        let mut file = RayFile::open_unchecked(path)?;
        file.check(invalid_rays)?;
        Ok(file)
    }

    /// [`RayFile::open`] that leaves the records to be checked by [`write_answers`], each chunk
    /// just before it is traced, when invalid rays are rejected: the rays are then read once,
    /// by the tracing threads, instead of in a pass of their own before any is traced. An
    /// invalid ray is the same error, from [`write_answers`] (before any output is renamed into
    /// place). With [`InvalidRays::Miss`] the records are checked here, as [`RayFile::open`]
    /// does: the answers need to know which are valid.
    pub fn open_checked_while_traced(
        path: &Path,
        invalid_rays: InvalidRays,
    ) -> Result<RayFile, RayFileError> {
        let mut file = RayFile::open_unchecked(path)?;
        match invalid_rays {
            InvalidRays::Reject => file.unchecked = true,
            InvalidRays::Miss => file.check(invalid_rays)?,
        }
        Ok(file)
    }

    /// The records of the ray file at `path` (standard input for `-`), checked for length only.
    fn open_unchecked(path: &Path) -> Result<RayFile, RayFileError> {
        let (records, path) = match path.as_os_str() == STDIN_ARGUMENT {
            true => {
                let name = Path::new(STDIN_NAME);
                (read_stream(name, io::stdin().lock())?, name)
            }
            false => (open_records(path)?, path),
        };
        Ok(RayFile {
            records,
            path: path.to_path_buf(),
            unchecked: false,
            valid: None,
            invalid: 0,
            first_invalid: None,
        })
    }

    /// Checks every record, on every core: an invalid one is an error with
    /// [`InvalidRays::Reject`], else noted as one to answer as a miss.
    fn check(&mut self, invalid_rays: InvalidRays) -> Result<(), RayFileError> {
        if all_valid(self.records()) {
            return Ok(());
        }
        let first = first_defect(&self.path, self.records());
        if invalid_rays == InvalidRays::Reject {
            return Err(first);
        }
        let valid: Vec<bool> = self.records().par_iter().map(is_valid).collect();
        self.invalid = valid.iter().filter(|&&valid| !valid).count();
        self.valid = Some(valid);
        self.first_invalid = Some(first);
        Ok(())
    }

    /// Checks `records`, some of the file's, if the file's records are yet to be checked: the
    /// error of the file's first invalid ray if one of them is invalid.
    fn check_chunk(&self, records: &[Ray]) -> io::Result<()> {
        // A branch-free fold: the common all-valid chunk costs no mispredictions.
        match !self.unchecked || records.iter().fold(true, |all, ray| all & is_valid(ray)) {
            true => Ok(()),
            false => Err(self.first_defect()),
        }
    }

    /// Checks every record, on every core, if they are yet to be checked: the error of the
    /// first invalid ray, if any.
    fn check_all(&self) -> io::Result<()> {
        match !self.unchecked || all_valid(self.records()) {
            true => Ok(()),
            false => Err(self.first_defect()),
        }
    }

    /// The error of the file's first invalid ray (it has one), as an I/O error whose inner
    /// error is the [`RayFileError`] (see [`invalid_ray`]).
    fn first_defect(&self) -> io::Error {
        let defect = first_defect(&self.path, self.records());
        io::Error::new(io::ErrorKind::InvalidData, defect)
    }

    /// Every record: the rays, with [`InvalidRays::Reject`]; with [`InvalidRays::Miss`] invalid
    /// records too, which [`write_answers`] answers as misses without tracing them.
    pub fn records(&self) -> &[Ray] {
        match &self.records {
            // Never fails: `map_records` keeps a mapping only when it casts.
            Records::Mapped(map) => bytemuck::try_cast_slice(map).unwrap_or_default(),
            Records::Decoded(rays) => rays,
        }
    }

    /// Releases the mapped pages of the records in `range`, which are no longer read
    /// ([`mapping::release_pages`]).
    fn release(&self, range: Range<usize>) {
        if let Records::Mapped(map) = &self.records {
            mapping::release_pages(map, range.start * RAY_BYTES..range.end * RAY_BYTES);
        }
    }

    /// Which records of `range` are valid, when one of the file's is not.
    fn valid_in(&self, range: Range<usize>) -> Option<&[bool]> {
        self.valid.as_ref().map(|valid| &valid[range])
    }

    /// Records.
    pub fn len(&self) -> usize {
        self.records().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Invalid records (only with [`InvalidRays::Miss`]).
    pub fn invalid(&self) -> usize {
        self.invalid
    }

    /// The defect of the first invalid record, if any.
    pub fn first_invalid(&self) -> Option<&RayFileError> {
        self.first_invalid.as_ref()
    }
}

/// The invalid ray behind an error of [`write_answers`] or [`write_answers_streamed`], if it is
/// one (else the error as it was): reported as when the ray file is opened.
pub fn invalid_ray(error: io::Error) -> Result<RayFileError, io::Error> {
    error.downcast::<RayFileError>()
}

/// The records of the ray file at `path`, checked for length: the mapping itself when it can
/// be read as rays, else decoded (an empty file is not mapped); a stream read to its end.
fn open_records(path: &Path) -> Result<Records, RayFileError> {
    let io_error = |source| RayFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io_error)?;
    let metadata = file.metadata().map_err(io_error)?;
    if !metadata.is_file() {
        return read_stream(path, file);
    }
    if metadata.len() == 0 {
        return Ok(Records::Decoded(Vec::new()));
    }
    let map = mapping::map_file(&file).map_err(io_error)?;
    check_length(path, &map)?;
    // A record is the in-memory ray on a little-endian machine (`Ray` is `repr(C)` f32 × 8);
    // the mapping is page aligned, so the cast cannot fail there.
    let in_place =
        cfg!(target_endian = "little") && bytemuck::try_cast_slice::<u8, Ray>(&map).is_ok();
    Ok(match in_place {
        true => Records::Mapped(map),
        false => Records::Decoded(decode_records(&map)),
    })
}

/// The records of the stream `reader` (named `path` in messages), read to its end and decoded
/// block by block; a length that is not a whole number of records is an error.
fn read_stream(path: &Path, mut reader: impl Read) -> Result<Records, RayFileError> {
    let mut rays = Vec::new();
    let mut block = vec![0; STREAM_BLOCK_BYTES];
    let (mut filled, mut size) = (0, 0);
    loop {
        let read = match reader.read(&mut block[filled..]) {
            Ok(0) => break,
            Ok(read) => read,
            Err(error) if error.kind() == io::ErrorKind::Interrupted => continue,
            Err(source) => {
                let path = path.to_path_buf();
                return Err(RayFileError::Io { path, source });
            }
        };
        (filled, size) = (filled + read, size + read);
        let whole = filled - filled % RAY_BYTES;
        rays.extend(block[..whole].chunks_exact(RAY_BYTES).map(decode_record));
        block.copy_within(whole..filled, 0);
        filled -= whole;
    }
    match filled {
        0 => Ok(Records::Decoded(rays)),
        _ => Err(truncated(path, size)),
    }
}

fn check_length(path: &Path, bytes: &[u8]) -> Result<(), RayFileError> {
    match bytes.len().is_multiple_of(RAY_BYTES) {
        true => Ok(()),
        false => Err(truncated(path, bytes.len())),
    }
}

/// The error of a ray file of `size` bytes, not a whole number of records.
fn truncated(path: &Path, size: usize) -> RayFileError {
    let ray = size / RAY_BYTES;
    RayFileError::Truncated {
        path: path.to_path_buf(),
        size,
        ray,
        offset: ray * RAY_BYTES,
    }
}

/// One record's fields as a ray, unchecked.
fn decode_record(record: &[u8]) -> Ray {
    let record: &[u8; RAY_BYTES] = record.first_chunk().expect("a whole ray record");
    let fields: [f32; 8] = std::array::from_fn(|i| {
        let field: &[u8; 4] = record[4 * i..].first_chunk().expect("four bytes");
        f32::from_le_bytes(*field)
    });
    let [ox, oy, oz, dx, dy, dz, tmin, tmax] = fields;
    Ray {
        origin: [ox, oy, oz],
        direction: [dx, dy, dz],
        tmin,
        tmax,
    }
}

/// What is wrong with a record read as `ray`, if anything: the offending field and why.
fn ray_defect(ray: &Ray) -> Option<(usize, String)> {
    let fields = bytemuck::cast::<Ray, [f32; 8]>(*ray);
    if let Some(field) = fields.iter().position(|x| x.is_nan()) {
        return Some((field, format!("{} is NaN", FIELD_NAMES[field])));
    }
    if let Some(field) = fields[..6].iter().position(|x| x.is_infinite()) {
        return Some((field, format!("{} is infinite", FIELD_NAMES[field])));
    }
    let [.., tmin, tmax] = fields;
    if ray.direction == [0.0; 3] {
        return Some((3, "direction is zero".into()));
    }
    if tmin < 0.0 {
        return Some((6, format!("tmin {tmin} is negative")));
    }
    if tmin > tmax {
        return Some((6, format!("tmin {tmin} is greater than tmax {tmax}")));
    }
    None
}

/// The exponent bits of an f32, all set in an infinity or a NaN.
const EXPONENT: u32 = 0x7f80_0000;

/// Per field of a record, a mask and the masked value that makes the field invalid: an
/// exponent with every bit set in the origin and the direction, which must be finite; never
/// for `tmin` and `tmax` (no bits never equal 1), which their comparisons check.
const NOT_FINITE_BITS: [(u32, u32); 8] = [
    (EXPONENT, EXPONENT),
    (EXPONENT, EXPONENT),
    (EXPONENT, EXPONENT),
    (EXPONENT, EXPONENT),
    (EXPONENT, EXPONENT),
    (EXPONENT, EXPONENT),
    (0, 1),
    (0, 1),
];

/// Whether [`ray_defect`] finds nothing wrong with `ray`, without branches per field: the
/// validation pass over a whole batch. The finiteness tests are on the fields' bits, the same
/// test in every field, so that the compiler makes them a few vector operations per ray.
fn is_valid(ray: &Ray) -> bool {
    let fields = bytemuck::cast::<Ray, [u32; 8]>(*ray);
    let not_finite = fields
        .iter()
        .zip(NOT_FINITE_BITS)
        .fold(false, |any, (&x, (mask, all_set))| {
            any | (x & mask == all_set)
        });
    // Zero in every bit but the sign.
    let zero_direction = (fields[3] | fields[4] | fields[5]) << 1 == 0;
    // `tmin >= 0` and `tmin <= tmax` are false when either is NaN; infinities are allowed.
    !not_finite & !zero_direction & (ray.tmin >= 0.0) & (ray.tmin <= ray.tmax)
}

/// The error of the first invalid ray of `rays`, the records of the file at `path`, which has
/// one (found in file order: a parallel search stops at any invalid ray, not necessarily the
/// first).
fn first_defect(path: &Path, rays: &[Ray]) -> RayFileError {
    rays.iter()
        .enumerate()
        .find_map(|(index, ray)| {
            ray_defect(ray).map(|(field, detail)| RayFileError::Invalid {
                path: path.to_path_buf(),
                ray: index,
                offset: index * RAY_BYTES + field * 4,
                detail,
            })
        })
        .expect("a ray file that failed validation has an invalid ray")
}

/// Encodes rays in the ray-file layout (for tools and tests that produce ray files).
pub fn encode_rays(rays: &[Ray]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(rays.len() * RAY_BYTES);
    for ray in rays {
        let fields = [
            ray.origin[0],
            ray.origin[1],
            ray.origin[2],
            ray.direction[0],
            ray.direction[1],
            ray.direction[2],
            ray.tmin,
            ray.tmax,
        ];
        bytes.extend(fields.iter().flat_map(|x| x.to_le_bytes()));
    }
    bytes
}

/// Bytes per hit record.
pub const HIT_BYTES: usize = 16;

/// Rays traced and encoded by one task of [`trace_hits`] and [`trace_occlusion`]: large enough
/// to amortize scheduling and keep packets of consecutive rays, small enough to balance.
const QUERY_CHUNK: usize = 4096;

/// Bytes per ray of a hit file in the full format ([`HitFormat::Full`]).
pub const FULL_HIT_BYTES: usize = 48;

/// The face id of a miss, or of a hit in a file without face ids, in the full format.
pub const NO_FACE_ID: u32 = u32::MAX;

/// The record a hit file has per ray.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HitFormat {
    /// [`HIT_BYTES`]: f32 t (infinity on a miss), f32 × 3 geometric normal.
    #[default]
    Compact,
    /// [`FULL_HIT_BYTES`], little endian: f32 t, f32 u, f32 v, u32 face id ([`NO_FACE_ID`] on
    /// a miss or without face ids), f32 × 3 geometric normal, f32 × 3 shading normal (the
    /// interpolated stored normal, else the geometric one), u8 × 4 RGBA colour interpolated
    /// (zeros without colours), u32 reserved zero. A miss has t infinity and zeros elsewhere.
    Full,
}

impl HitFormat {
    pub fn record_bytes(self) -> usize {
        match self {
            HitFormat::Compact => HIT_BYTES,
            HitFormat::Full => FULL_HIT_BYTES,
        }
    }
}

/// The full-format record of `hit` in `file` ([`HitFormat::Full`]); reads the hit's
/// attributes.
fn encode_full_hit(file: &ReducemFile, hit: Option<&Hit>, record: &mut [u8]) {
    encode_full_record(hit.map(|hit| (hit, hit_attributes(file, hit))), record);
}

/// The full-format record of a hit with its attributes, or of a miss.
fn encode_full_record(hit: Option<(&Hit, HitAttributes)>, record: &mut [u8]) {
    record.fill(0);
    let Some((hit, attributes)) = hit else {
        record[..4].copy_from_slice(&f32::INFINITY.to_le_bytes());
        record[12..16].copy_from_slice(&NO_FACE_ID.to_le_bytes());
        return;
    };
    let floats = [hit.t, hit.u, hit.v];
    let normals = [hit.normal, attributes.shading_normal];
    let words = floats
        .iter()
        .map(|f| f.to_le_bytes())
        .chain([attributes.face_id.unwrap_or(NO_FACE_ID).to_le_bytes()])
        .chain(normals.iter().flatten().map(|f| f.to_le_bytes()))
        .chain([attributes.color.unwrap_or([0; 4])]);
    for (word, out) in words.zip(record.chunks_exact_mut(4)) {
        out.copy_from_slice(&word);
    }
}

/// The compact records of `hits` into `bytes` (`HIT_BYTES` per hit): `t nx ny nz`, a miss
/// `+inf 0 0 0`.
fn encode_hits_into(hits: &[Option<Hit>], bytes: &mut [u8]) {
    for (hit, record) in hits.iter().zip(bytes.chunks_exact_mut(HIT_BYTES)) {
        encode_hit(hit.as_ref(), record);
    }
}

/// Traces `rays` and encodes each closest hit into its record of `bytes` as it is found,
/// without collecting the hits first; the hits among them.
fn encode_hits_traced(tracer: &Tracer, rays: &[Ray], bytes: &mut [u8]) -> usize {
    let mut hits = 0;
    tracer.intersect_each(rays, |index, hit| {
        hits += hit.is_some() as usize;
        let start = index * HIT_BYTES;
        if let Some(record) = bytes.get_mut(start..start + HIT_BYTES) {
            encode_hit(hit.as_ref(), record);
        }
    });
    hits
}

/// One compact hit record (`HIT_BYTES`): `t` and the normal, or `t = inf` on a miss.
fn encode_hit(hit: Option<&Hit>, record: &mut [u8]) {
    let fields = match hit {
        Some(hit) => [hit.t, hit.normal[0], hit.normal[1], hit.normal[2]],
        None => [f32::INFINITY, 0.0, 0.0, 0.0],
    };
    // The record as one 16-byte store rather than a copy per field.
    let bytes: [u8; HIT_BYTES] = bytemuck::cast(fields.map(|field| field.to_bits().to_le()));
    if let Some(record) = record.first_chunk_mut::<HIT_BYTES>() {
        *record = bytes;
    }
}

/// What a query answers per ray, and so the output file's record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    /// One byte per ray, 1 when occluded.
    Occlusion,
    /// The closest hit in `format`.
    Hits(HitFormat),
}

impl Answer {
    /// Bytes per ray of the output file.
    pub fn record_bytes(self) -> usize {
        match self {
            Answer::Occlusion => 1,
            Answer::Hits(format) => format.record_bytes(),
        }
    }
}

/// One chunk's answers, in its rays' order.
enum Answers {
    Occluded(Vec<bool>),
    Hits(Vec<Option<Hit>>),
}

impl Answers {
    /// The answers of `rays`, traced on the calling thread.
    fn trace(tracer: &Tracer, rays: &[Ray], answer: Answer) -> Answers {
        match answer {
            Answer::Occlusion => Answers::Occluded(tracer.occluded_chunk(rays)),
            Answer::Hits(_) => Answers::Hits(tracer.intersect_chunk(rays)),
        }
    }

    /// The answers of the records `rays` of which only those marked in `valid` are traced; the
    /// others are misses.
    fn trace_valid(tracer: &Tracer, rays: &[Ray], valid: &[bool], answer: Answer) -> Answers {
        let traced: Vec<Ray> = rays
            .iter()
            .zip(valid)
            .filter_map(|(ray, &valid)| valid.then_some(*ray))
            .collect();
        // The answers of the traced rays, in order, spread back over the records.
        fn spread<T: Copy>(answers: Vec<T>, valid: &[bool], miss: T) -> Vec<T> {
            let mut answers = answers.into_iter();
            valid
                .iter()
                .map(|&valid| match valid {
                    true => answers.next().unwrap_or(miss),
                    false => miss,
                })
                .collect()
        }
        match Answers::trace(tracer, &traced, answer) {
            Answers::Occluded(occluded) => Answers::Occluded(spread(occluded, valid, false)),
            Answers::Hits(hits) => Answers::Hits(spread(hits, valid, None)),
        }
    }

    /// Encodes the answers into `out` (`answer`'s record per ray); the hits (occluded rays)
    /// among them.
    fn encode(&self, file: &ReducemFile, answer: Answer, out: &mut [u8]) -> usize {
        match (self, answer) {
            (Answers::Occluded(occluded), _) => {
                for (byte, &occluded) in out.iter_mut().zip(occluded) {
                    *byte = occluded as u8;
                }
                occluded.iter().filter(|&&occluded| occluded).count()
            }
            (Answers::Hits(hits), Answer::Hits(HitFormat::Full)) => {
                for (hit, record) in hits.iter().zip(out.chunks_exact_mut(FULL_HIT_BYTES)) {
                    encode_full_hit(file, hit.as_ref(), record);
                }
                hits.iter().flatten().count()
            }
            (Answers::Hits(hits), _) => {
                encode_hits_into(hits, out);
                hits.iter().flatten().count()
            }
        }
    }
}

/// Traces `rays` (those marked in `valid` when given; the others are misses) and encodes their
/// answers into `out`; the hits (occluded rays) among them.
fn answer_chunk(
    tracer: &Tracer,
    rays: &[Ray],
    valid: Option<&[bool]>,
    answer: Answer,
    out: &mut [u8],
) -> usize {
    if let (None, Answer::Hits(HitFormat::Compact)) = (valid, answer) {
        return encode_hits_traced(tracer, rays, out);
    }
    let answers = match valid {
        None => Answers::trace(tracer, rays, answer),
        Some(valid) => Answers::trace_valid(tracer, rays, valid, answer),
    };
    answers.encode(tracer.file(), answer, out)
}

/// The hit file's bytes for `rays`: traced and encoded chunk by chunk on every core.
pub fn trace_hits(tracer: &Tracer, rays: &[Ray]) -> Vec<u8> {
    trace_hits_as(tracer, rays, HitFormat::Compact)
}

/// The hit file's bytes for `rays` in `format`; the full format reads each final hit's
/// attributes after its chunk is traced.
pub fn trace_hits_as(tracer: &Tracer, rays: &[Ray], format: HitFormat) -> Vec<u8> {
    answer_all(tracer, rays, Answer::Hits(format))
}

/// The occlusion file's bytes for `rays`, as [`trace_hits`] makes the hit file's.
pub fn trace_occlusion(tracer: &Tracer, rays: &[Ray]) -> Vec<u8> {
    answer_all(tracer, rays, Answer::Occlusion)
}

/// The output bytes of `rays` answered as `answer` says, chunk by chunk on every core.
fn answer_all(tracer: &Tracer, rays: &[Ray], answer: Answer) -> Vec<u8> {
    let size = answer.record_bytes();
    let mut bytes = vec![0; rays.len() * size];
    bytes
        .par_chunks_mut(QUERY_CHUNK * size)
        .zip(rays.par_chunks(QUERY_CHUNK))
        .for_each(|(out, rays)| {
            answer_chunk(tracer, rays, None, answer, out);
        });
    bytes
}

/// Traces every record of `rays` (an invalid one is answered as a miss) and writes the
/// answers to `out`, record `i` at byte `i * answer.record_bytes()`, in input order; the hits
/// (occluded rays) among them. Chunk by chunk on every core, each chunk encoded into a buffer
/// that [`atomic::write_behind`]'s thread writes at its place (in whatever order the chunks
/// finish) and hands back: no output-sized buffer, writing overlaps tracing, and the tracing
/// threads never wait on the file system's locks. An incoherent batch is
/// traced in a coherent order instead ([`ray_order`]) and its answers put back in input order.
/// Records yet to be checked are checked each chunk before it is traced (all of them first for
/// an incoherent batch): an invalid one fails with the file's first invalid ray ([`invalid_ray`]).
pub fn write_answers(
    tracer: &Tracer,
    rays: &RayFile,
    answer: Answer,
    out: &File,
) -> io::Result<usize> {
    if let Some(order) = ray_order::coherent_order(rays.records()) {
        rays.check_all()?;
        return write_answers_in_order(tracer, rays, &order, answer, out);
    }
    let size = answer.record_bytes();
    let records = rays.records();
    let chunks = records.len().div_ceil(QUERY_CHUNK);
    let traced = TracedRegions::new(chunks);
    atomic::write_behind(out, (records.len() * size) as u64, |behind| {
        (0..chunks)
            .into_par_iter()
            .map(|chunk| {
                let range = chunk * QUERY_CHUNK..records.len().min((chunk + 1) * QUERY_CHUNK);
                rays.check_chunk(&records[range.clone()])?;
                // Every record of the chunk is written over, so a reused buffer's bytes stay.
                let mut buffer = behind.buffer();
                buffer.resize(range.len() * size);
                let valid = rays.valid_in(range.clone());
                let hits =
                    answer_chunk(tracer, &records[range.clone()], valid, answer, &mut buffer);
                if let Some(region) = traced.chunk_done(chunk) {
                    rays.release(region.start * QUERY_CHUNK..region.end * QUERY_CHUNK);
                }
                behind.write_at(buffer, (range.start * size) as u64)?;
                Ok(hits)
            })
            .try_reduce(|| 0, |a, b| Ok(a + b))
    })
}

/// Chunks of [`write_answers`] whose rays' pages are released together, once all are traced:
/// 8 MiB of rays, so that releasing them interrupts the other tracing threads rarely (each
/// release flushes their address translations).
const RELEASE_CHUNKS: usize = 64;

/// Counts the traced chunks of each region of [`RELEASE_CHUNKS`] chunks of [`write_answers`].
struct TracedRegions {
    traced: Vec<AtomicUsize>,
    chunks: usize,
}

impl TracedRegions {
    fn new(chunks: usize) -> TracedRegions {
        let regions = chunks.div_ceil(RELEASE_CHUNKS);
        TracedRegions {
            traced: (0..regions).map(|_| AtomicUsize::new(0)).collect(),
            chunks,
        }
    }

    /// Counts `chunk` as traced; the chunks of its region when it was the region's last.
    fn chunk_done(&self, chunk: usize) -> Option<Range<usize>> {
        let region = chunk / RELEASE_CHUNKS;
        let chunks = region * RELEASE_CHUNKS..self.chunks.min((region + 1) * RELEASE_CHUNKS);
        let traced = self.traced[region].fetch_add(1, Ordering::AcqRel) + 1;
        (traced == chunks.len()).then_some(chunks)
    }
}

/// [`write_answers`] tracing the records in `order` (a permutation of their indices): the
/// answers are encoded in that order into one buffer, then gathered back into input order
/// block by block and written.
fn write_answers_in_order(
    tracer: &Tracer,
    rays: &RayFile,
    order: &[u32],
    answer: Answer,
    out: &File,
) -> io::Result<usize> {
    let size = answer.record_bytes();
    let (answers, hits) = answer_in_order(tracer, rays, order, answer);
    let places = input_places(order);
    atomic::write_behind(out, answers.len() as u64, |behind| {
        places
            .par_chunks(QUERY_CHUNK)
            .enumerate()
            .try_for_each(|(chunk, places)| {
                let mut buffer = behind.buffer();
                buffer.resize(places.len() * size);
                gather(&answers, places, size, &mut buffer);
                behind.write_at(buffer, (chunk * QUERY_CHUNK * size) as u64)
            })
    })?;
    Ok(hits)
}

/// The answers of the records in `order`, encoded in that order, and the hits among them.
fn answer_in_order(
    tracer: &Tracer,
    rays: &RayFile,
    order: &[u32],
    answer: Answer,
) -> (Vec<u8>, usize) {
    let size = answer.record_bytes();
    let records = rays.records();
    let mut answers = vec![0; order.len() * size];
    let hits = answers
        .par_chunks_mut(QUERY_CHUNK * size)
        .zip(order.par_chunks(QUERY_CHUNK))
        .map_init(
            || (Vec::new(), Vec::new()),
            |(gathered, valid), (answers, indices)| {
                gathered.clear();
                gathered.extend(indices.iter().map(|&index| records[index as usize]));
                let valid = rays.valid.as_ref().map(|all| {
                    valid.clear();
                    valid.extend(indices.iter().map(|&index| all[index as usize]));
                    &valid[..]
                });
                answer_chunk(tracer, gathered, valid, answer, answers)
            },
        )
        .sum();
    (answers, hits)
}

/// For each record, its position in `order`.
fn input_places(order: &[u32]) -> Vec<u32> {
    let mut places = vec![0u32; order.len()];
    for (position, &index) in order.iter().enumerate() {
        places[index as usize] = position as u32;
    }
    places
}

/// Fills `buffer` (`places.len() * size` bytes) with the records of `answers` (`size` bytes
/// each) at `places`, in turn.
fn gather(answers: &[u8], places: &[u32], size: usize, buffer: &mut [u8]) {
    for (out, &position) in buffer.chunks_exact_mut(size).zip(places) {
        let start = position as usize * size;
        out.copy_from_slice(&answers[start..start + size]);
    }
}

/// Rays traced at once between two writes of [`write_answers_streamed`]: enough chunks to keep
/// every core busy, few enough that a reader gets answers while the rest are traced.
const STREAM_BATCH: usize = 64 * QUERY_CHUNK;

/// [`write_answers`] for an output that is a stream (standard output, a pipe, a device): the
/// answers are written in input order, one batch of chunks after another; the same bytes.
/// Records yet to be checked are all checked first: nothing is written when one is invalid.
pub fn write_answers_streamed(
    tracer: &Tracer,
    rays: &RayFile,
    answer: Answer,
    out: &mut dyn Write,
) -> io::Result<usize> {
    rays.check_all()?;
    let size = answer.record_bytes();
    if let Some(order) = ray_order::coherent_order(rays.records()) {
        let (answers, hits) = answer_in_order(tracer, rays, &order, answer);
        let mut buffer = Vec::new();
        for places in input_places(&order).chunks(QUERY_CHUNK) {
            buffer.resize(places.len() * size, 0);
            gather(&answers, places, size, &mut buffer);
            out.write_all(&buffer)?;
        }
        return Ok(hits);
    }
    let records = rays.records();
    let mut buffer = Vec::new();
    let mut hits = 0;
    for batch_start in (0..records.len()).step_by(STREAM_BATCH) {
        let batch = batch_start..records.len().min(batch_start + STREAM_BATCH);
        buffer.resize(batch.len() * size, 0);
        hits += buffer
            .par_chunks_mut(QUERY_CHUNK * size)
            .enumerate()
            .map(|(chunk, out)| {
                let start = batch.start + chunk * QUERY_CHUNK;
                let range = start..batch.end.min(start + QUERY_CHUNK);
                let valid = rays.valid_in(range.clone());
                answer_chunk(tracer, &records[range], valid, answer, out)
            })
            .sum::<usize>();
        out.write_all(&buffer)?;
    }
    Ok(hits)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Field values on every side of each check: signed zeros, subnormals, extremes,
    /// infinities and NaN.
    const SPECIAL: [f32; 10] = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        1e-45,
        -1e-45,
        f32::MAX,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
    ];

    fn ray_of(fields: [f32; 8]) -> Ray {
        bytemuck::cast(fields)
    }

    /// The batch check accepts exactly the rays the per-ray check finds nothing wrong with:
    /// every combination of special values in the direction and in the interval, and each
    /// special value in each field of an otherwise valid ray.
    #[test]
    fn the_batch_check_agrees_with_the_per_ray_check() {
        let mut rays = Vec::new();
        for (&dx, &dy, &dz) in triples(&SPECIAL) {
            rays.push(ray_of([0.5, -2.0, 3.0, dx, dy, dz, 0.0, 1.0]));
        }
        for &tmin in &SPECIAL {
            for &tmax in &SPECIAL {
                rays.push(ray_of([0.5, -2.0, 3.0, 0.0, 0.0, 1.0, tmin, tmax]));
            }
        }
        for field in 0..8 {
            for &value in &SPECIAL {
                let mut fields = [0.5, -2.0, 3.0, 0.0, 1.0, -1.0, 0.25, 4.0];
                fields[field] = value;
                rays.push(ray_of(fields));
            }
        }
        let mut accepted = 0;
        for ray in &rays {
            assert_eq!(is_valid(ray), ray_defect(ray).is_none(), "{ray:?}");
            accepted += is_valid(ray) as usize;
        }
        assert!(accepted > 100 && accepted < rays.len() - 100);
    }

    fn triples(values: &[f32]) -> impl Iterator<Item = (&f32, &f32, &f32)> {
        values.iter().flat_map(move |a| {
            values
                .iter()
                .flat_map(move |b| values.iter().map(move |c| (a, b, c)))
        })
    }

    /// A ray file is read in place as the rays it encodes.
    #[test]
    fn a_mapped_ray_file_reads_as_its_rays() {
        let rays: Vec<Ray> = (0..1000)
            .map(|i| {
                let x = i as f32;
                ray_of([x, -x, 0.5 * x, 1.0, -0.0, x + 1.0, 0.0, f32::INFINITY])
            })
            .collect();
        let path = std::env::temp_dir().join(format!("ray-file-{}.rays", std::process::id()));
        std::fs::write(&path, encode_rays(&rays)).expect("write rays");
        let file = RayFile::open(&path, InvalidRays::Reject).expect("valid rays");
        assert!(matches!(file.records, Records::Mapped(_)));
        assert_eq!(file.records(), rays);
        std::fs::remove_file(&path).expect("remove");
    }
}

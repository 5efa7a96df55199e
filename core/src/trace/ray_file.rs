//! The binary ray and hit files of `reducem query`.
//!
//! Rays: little-endian f32 × 8 per ray (`ox oy oz dx dy dz tmin tmax`), 32 bytes, no header.
//! Hits: f32 × 4 per ray (`t nx ny nz`), `t = +inf` and a zero normal on a miss. Occlusion: one
//! byte per ray, 1 when occluded. A ray file is validated whole before anything is traced, and
//! every defect names the file, the ray and the byte offset of the offending field. Output is
//! written to a temporary file and renamed, so a failed run leaves no partial output.
//!
//! A batch job spends much of its time outside the tracer unless the files are handled in
//! parallel too: the ray file is mapped and parsed on every core, and the answers are traced
//! straight into the output bytes, chunk by chunk, on every core, with no per-ray `Hit` vector
//! in between; the output is then written with one call.

use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::attributes::{hit_attributes, HitAttributes};
use super::ray::{Hit, Ray};
use super::Tracer;
use crate::format::reader::ReducemFile;
use crate::{atomic, mapping};

/// Bytes per ray record.
pub const RAY_BYTES: usize = 32;

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

/// Reads and validates the ray file at `path` (mapped, parsed on every core).
pub fn read_rays(path: &Path) -> Result<Vec<Ray>, RayFileError> {
    with_ray_bytes(path, |bytes| parse_rays(path, bytes))
}

/// Calls `read` with the bytes of the file at `path`, mapped (an empty file is not mapped).
fn with_ray_bytes<T>(
    path: &Path,
    read: impl FnOnce(&[u8]) -> Result<T, RayFileError>,
) -> Result<T, RayFileError> {
    let io_error = |source| RayFileError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io_error)?;
    if file.metadata().map_err(io_error)?.len() == 0 {
        return read(&[]);
    }
    let bytes = mapping::map_file(&file).map_err(io_error)?;
    read(&bytes)
}

/// Validates `bytes` as a ray file (`path` is only for messages). The error names the first
/// invalid ray, whatever the thread count.
pub fn parse_rays(path: &Path, bytes: &[u8]) -> Result<Vec<Ray>, RayFileError> {
    check_length(path, bytes)?;
    // Parsed in place into one vector, chunk by chunk on every core: a collect of `Result`s
    // builds and joins a vector per task, three times the instructions per ray.
    let mut rays = vec![UNPARSED; bytes.len() / RAY_BYTES];
    let all_valid = rays
        .par_chunks_mut(PARSE_CHUNK)
        .zip(bytes.par_chunks(PARSE_CHUNK * RAY_BYTES))
        .all(|(rays, records)| {
            rays.iter_mut()
                .zip(records.chunks_exact(RAY_BYTES))
                .all(|(ray, record)| parse_ray(record).map(|parsed| *ray = parsed).is_ok())
        });
    if all_valid {
        Ok(rays)
    } else {
        Err(first_invalid_ray(path, bytes))
    }
}

/// Rays parsed by one task of [`parse_rays`].
const PARSE_CHUNK: usize = 16 * 1024;

/// What [`parse_rays`] fills its vector with before parsing into it.
const UNPARSED: Ray = Ray {
    origin: [0.0; 3],
    direction: [0.0; 3],
    tmin: 0.0,
    tmax: 0.0,
};

/// A ray file read with invalid rays allowed (`reducem query --invalid-rays miss`).
#[derive(Debug)]
pub struct RaysWithInvalid {
    /// Every record in order, `None` for an invalid one.
    pub rays: Vec<Option<Ray>>,
    pub invalid: usize,
    /// The defect of the first invalid ray, for the report.
    pub first_invalid: Option<RayFileError>,
}

/// Reads the ray file at `path` like [`read_rays`], except that an invalid ray (NaN, zero
/// direction, bad interval) does not reject the file; a truncated file still does.
pub fn read_rays_allowing_invalid(path: &Path) -> Result<RaysWithInvalid, RayFileError> {
    with_ray_bytes(path, |bytes| {
        check_length(path, bytes)?;
        let rays: Vec<Option<Ray>> = bytes
            .par_chunks_exact(RAY_BYTES)
            .map(|record| parse_ray(record).ok())
            .collect();
        let invalid = rays.iter().filter(|ray| ray.is_none()).count();
        Ok(RaysWithInvalid {
            rays,
            invalid,
            first_invalid: (invalid > 0).then(|| first_invalid_ray(path, bytes)),
        })
    })
}

/// The error of the first invalid ray of `bytes`, which has one (found again in file order:
/// a parallel collect stops at any invalid ray, not necessarily the first).
fn first_invalid_ray(path: &Path, bytes: &[u8]) -> RayFileError {
    bytes
        .chunks_exact(RAY_BYTES)
        .enumerate()
        .find_map(|(index, record)| parse_record(path, index, record).err())
        .expect("a ray file that failed to parse has an invalid ray")
}

fn check_length(path: &Path, bytes: &[u8]) -> Result<(), RayFileError> {
    if bytes.len().is_multiple_of(RAY_BYTES) {
        return Ok(());
    }
    let ray = bytes.len() / RAY_BYTES;
    Err(RayFileError::Truncated {
        path: path.to_path_buf(),
        size: bytes.len(),
        ray,
        offset: ray * RAY_BYTES,
    })
}

fn parse_record(path: &Path, index: usize, record: &[u8]) -> Result<Ray, RayFileError> {
    parse_ray(record).map_err(|(field, detail)| RayFileError::Invalid {
        path: path.to_path_buf(),
        ray: index,
        offset: index * RAY_BYTES + field * 4,
        detail,
    })
}

/// One record; on error, the offending field and what is wrong with it.
fn parse_ray(record: &[u8]) -> Result<Ray, (usize, String)> {
    let record: &[u8; RAY_BYTES] = record.first_chunk().expect("a whole ray record");
    let fields: [f32; 8] = std::array::from_fn(|i| {
        let field: &[u8; 4] = record[4 * i..].first_chunk().expect("four bytes");
        f32::from_le_bytes(*field)
    });
    if let Some(field) = fields.iter().position(|x| x.is_nan()) {
        return Err((field, format!("{} is NaN", FIELD_NAMES[field])));
    }
    if let Some(field) = fields[..6].iter().position(|x| x.is_infinite()) {
        return Err((field, format!("{} is infinite", FIELD_NAMES[field])));
    }
    let [ox, oy, oz, dx, dy, dz, tmin, tmax] = fields;
    if [dx, dy, dz] == [0.0; 3] {
        return Err((3, "direction is zero".into()));
    }
    if tmin < 0.0 {
        return Err((6, format!("tmin {tmin} is negative")));
    }
    if tmin > tmax {
        return Err((6, format!("tmin {tmin} is greater than tmax {tmax}")));
    }
    Ok(Ray {
        origin: [ox, oy, oz],
        direction: [dx, dy, dz],
        tmin,
        tmax,
    })
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

/// `t nx ny nz` per ray; a miss is `+inf 0 0 0`.
pub fn encode_hits(hits: &[Option<Hit>]) -> Vec<u8> {
    let mut bytes = vec![0; hits.len() * HIT_BYTES];
    encode_hits_into(hits, &mut bytes);
    bytes
}

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

/// A miss's record in the full format.
pub fn encode_full_miss() -> Vec<u8> {
    let mut record = vec![0; FULL_HIT_BYTES];
    encode_full_record(None, &mut record);
    record
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

/// [`encode_hits`] into `bytes` (`HIT_BYTES` per hit).
fn encode_hits_into(hits: &[Option<Hit>], bytes: &mut [u8]) {
    for (hit, record) in hits.iter().zip(bytes.chunks_exact_mut(HIT_BYTES)) {
        let fields = match hit {
            Some(hit) => [hit.t, hit.normal[0], hit.normal[1], hit.normal[2]],
            None => [f32::INFINITY, 0.0, 0.0, 0.0],
        };
        for (field, out) in fields.iter().zip(record.chunks_exact_mut(4)) {
            out.copy_from_slice(&field.to_le_bytes());
        }
    }
}

/// One byte per ray, 1 when occluded.
pub fn encode_occlusion(occluded: &[bool]) -> Vec<u8> {
    occluded.iter().map(|&o| o as u8).collect()
}

/// The hit file's bytes for `rays`: traced and encoded chunk by chunk on every core.
pub fn trace_hits(tracer: &Tracer, rays: &[Ray]) -> Vec<u8> {
    trace_hits_as(tracer, rays, HitFormat::Compact)
}

/// The hit file's bytes for `rays` in `format`; the full format reads each final hit's
/// attributes after its chunk is traced.
pub fn trace_hits_as(tracer: &Tracer, rays: &[Ray], format: HitFormat) -> Vec<u8> {
    let size = format.record_bytes();
    let mut bytes = vec![0; rays.len() * size];
    bytes
        .par_chunks_mut(QUERY_CHUNK * size)
        .zip(rays.par_chunks(QUERY_CHUNK))
        .for_each(|(out, rays)| {
            let hits = tracer.intersect_chunk(rays);
            match format {
                HitFormat::Compact => encode_hits_into(&hits, out),
                HitFormat::Full => {
                    for (hit, record) in hits.iter().zip(out.chunks_exact_mut(size)) {
                        encode_full_hit(tracer.file(), hit.as_ref(), record);
                    }
                }
            }
        });
    bytes
}

/// The occlusion file's bytes for `rays`, as [`trace_hits`] makes the hit file's.
pub fn trace_occlusion(tracer: &Tracer, rays: &[Ray]) -> Vec<u8> {
    let mut bytes = vec![0; rays.len()];
    bytes
        .par_chunks_mut(QUERY_CHUNK)
        .zip(rays.par_chunks(QUERY_CHUNK))
        .for_each(|(out, rays)| {
            for (byte, occluded) in out.iter_mut().zip(tracer.occluded_chunk(rays)) {
                *byte = occluded as u8;
            }
        });
    bytes
}

/// Writes `bytes` to a temporary file beside `path` and renames it into place.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    atomic::write_atomically(path, |out| out.write_all(bytes))
}

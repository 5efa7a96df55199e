//! `reducem closest`: the closest surface point to every point of a binary point file.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use rayon::prelude::*;

use reducem::exit_code::UsageError;
use reducem::format::reader::ReducemFile;
use reducem::geometry::Point;
use reducem::output::Destination;
use reducem::query::{closest_points, signed_closest_points, ClosestPoint, FaceIds};
use reducem::trace::Kernel;

/// Bytes of one point of a point file: f32 x, y, z.
const POINT_BYTES: usize = 12;
/// Bytes of one answer: distance, point, face id, u, v, flags.
const ANSWER_BYTES: usize = 32;
/// The face id of an answer without a triangle.
const NO_FACE: u32 = u32::MAX;

#[derive(Clone, Debug, clap::Args)]
pub struct ClosestArgs {
    /// The ReduceM file.
    pub file: PathBuf,
    /// The point file: f32 x 3 per point (x, y, z), little endian; `-` reads standard input.
    #[arg(long)]
    points: PathBuf,
    /// The answer file (replaced atomically; `-` or a device or FIFO written directly; never an
    /// input): 32 bytes per point, little
    /// endian: f32 distance (inf when no surface point lies within --max-distance); f32 x 3 the
    /// closest point (NaN when none); u32 face id (the input face id when the file stores face ids, else the
    /// triangle's row in `reducem decode` order; 0xFFFFFFFF when none); f32 u, v, the closest
    /// point's barycentric weights of the triangle's second and third corners in input winding
    /// (NaN when none); u32 flags: 0 without --signed, else bit 0 the point is inside, bit 1 the
    /// mesh is closed so the side is exact.
    #[arg(short, long)]
    output: PathBuf,
    /// Only surface points at most this far from a point count (model units, inclusive).
    #[arg(long, value_name = "D", default_value_t = f32::INFINITY, value_parser = parse_max_distance)]
    max_distance: f32,
    /// Signed distance: negative inside the surface, with the side in the flags. Exact on a
    /// closed mesh (one ray's parity), else the majority of --samples rays.
    #[arg(long)]
    signed: bool,
    /// With --signed, rays per point on a mesh that is not closed.
    #[arg(long, value_name = "N", default_value_t = 1, requires = "signed",
        value_parser = clap::value_parser!(u32).range(1..))]
    samples: u32,
    /// Worker threads; 0 uses one per core.
    #[arg(long, value_name = "N", default_value_t = 0)]
    threads: usize,
}

/// The sides of the points with `--signed`: inside or not, and whether that is exact.
struct Sides {
    inside: Vec<bool>,
    exact: bool,
}

/// A point file that cannot be used, naming the file and where.
#[derive(Debug, thiserror::Error)]
pub enum PointFileError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "{}: {bytes} bytes is not a whole number of points (12 bytes each: f32 x, y, z)",
        path.display()
    )]
    Length { path: PathBuf, bytes: usize },
    #[error(
        "{}: point {index} (byte {offset}): coordinate {axis} is {value}, not a finite number",
        path.display()
    )]
    NotFinite {
        path: PathBuf,
        index: usize,
        offset: usize,
        axis: char,
        value: f32,
    },
}

fn parse_max_distance(text: &str) -> Result<f32, String> {
    let value: f32 = text.parse().map_err(|error| format!("{text:?}: {error}"))?;
    match value >= 0.0 {
        true => Ok(value),
        false => Err(format!("{text:?} is not a distance (zero or more)")),
    }
}

pub fn run(args: ClosestArgs) -> anyhow::Result<()> {
    let output = Destination::prepare(&args.output, &[&args.file, &args.points])?;
    in_pool(args.threads, || answer(&args, &output))
}

/// Runs `work` on a pool of `threads` workers (0: one per core), as `--threads` asks.
pub(crate) fn in_pool<T: Send>(
    threads: usize,
    work: impl FnOnce() -> anyhow::Result<T> + Send,
) -> anyhow::Result<T> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|error| UsageError(format!("--threads {threads}: {error}")))?;
    pool.install(work)
}

/// The points of `points` and the file at `file`, read and opened side by side, the file told
/// how many queries come; a `REDUCEM_KERNEL` this CPU cannot run is refused first.
pub(crate) fn points_and_file(
    points: &Path,
    file: &Path,
) -> anyhow::Result<(Vec<Point>, ReducemFile)> {
    Kernel::from_env()?;
    let (points, file) = rayon::join(|| read_points(points), || ReducemFile::open(file));
    let (points, file) = (points?, file?);
    file.advise_batch(points.len());
    Ok((points, file))
}

fn answer(args: &ClosestArgs, output: &Destination) -> anyhow::Result<()> {
    let (points, file) = points_and_file(&args.points, &args.file)?;
    let started = Instant::now();
    let (answers, sides) = match args.signed {
        false => (closest_points(&file, &points, args.max_distance), None),
        true => {
            let signed = signed_closest_points(&file, &points, args.max_distance, args.samples);
            let sides = Sides {
                inside: signed.inside,
                exact: signed.exact,
            };
            (signed.closest, Some(sides))
        }
    };
    let face_ids = FaceIds::of(&file);
    let records = encode(&file, &face_ids, &answers, sides.as_ref());
    let seconds = started.elapsed().as_secs_f64();
    // Answers that met a corrupt part of a lazily validated file are incomplete.
    super::complete(&file)?;
    output
        .write(|out| out.write_all(&records))
        .with_context(|| format!("writing {}", output.name()))?;
    let found = answers.iter().filter(|answer| answer.is_some()).count();
    let rate = points.len() as f64 / seconds.max(f64::MIN_POSITIVE) / 1e6;
    eprintln!(
        "reducem: closest: points={} found={found} seconds={seconds:.6} mpoints_per_s={rate:.3} \
         threads={}",
        points.len(),
        rayon::current_num_threads()
    );
    Ok(())
}

fn read_all(path: &Path) -> std::io::Result<Vec<u8>> {
    if path.as_os_str() != "-" {
        return std::fs::read(path);
    }
    let mut bytes = Vec::new();
    std::io::stdin().lock().read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// The points of a point file; every coordinate finite.
fn read_points(path: &Path) -> Result<Vec<Point>, PointFileError> {
    // Read to the end rather than mapped, so a pipe or `-` (standard input) gives every point.
    let bytes = read_all(path).map_err(|source| PointFileError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if !bytes.len().is_multiple_of(POINT_BYTES) {
        return Err(PointFileError::Length {
            path: path.to_path_buf(),
            bytes: bytes.len(),
        });
    }
    let points: Vec<Point> = bytes
        .chunks_exact(POINT_BYTES)
        .map(|record| std::array::from_fn(|axis| f32_at(record, 4 * axis)))
        .collect();
    for (index, point) in points.iter().enumerate() {
        if let Some(axis) = point.iter().position(|c| !c.is_finite()) {
            return Err(PointFileError::NotFinite {
                path: path.to_path_buf(),
                index,
                offset: index * POINT_BYTES + 4 * axis,
                axis: ['x', 'y', 'z'][axis],
                value: point[axis],
            });
        }
    }
    Ok(points)
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

/// The answer records of `answers`, in order.
fn encode(
    file: &ReducemFile,
    face_ids: &FaceIds,
    answers: &[Option<ClosestPoint>],
    sides: Option<&Sides>,
) -> Vec<u8> {
    let mut records = vec![0u8; answers.len() * ANSWER_BYTES];
    records
        .par_chunks_mut(ANSWER_BYTES)
        .zip(answers)
        .enumerate()
        .for_each(|(index, (record, answer))| {
            let inside = sides.is_some_and(|sides| sides.inside[index]);
            let flags = match sides {
                None => 0,
                Some(sides) => u32::from(inside) | u32::from(sides.exact) << 1,
            };
            let words: [u32; 8] = match answer {
                None => {
                    let nan = f32::NAN.to_bits();
                    [
                        f32::INFINITY.to_bits(),
                        nan,
                        nan,
                        nan,
                        NO_FACE,
                        nan,
                        nan,
                        flags,
                    ]
                }
                Some(found) => [
                    match inside {
                        true => (-found.distance).to_bits(),
                        false => found.distance.to_bits(),
                    },
                    found.point[0].to_bits(),
                    found.point[1].to_bits(),
                    found.point[2].to_bits(),
                    face_ids
                        .id(file, found.strip, found.window)
                        .unwrap_or(NO_FACE),
                    found.u.to_bits(),
                    found.v.to_bits(),
                    flags,
                ],
            };
            for (bytes, word) in record.chunks_exact_mut(4).zip(words) {
                bytes.copy_from_slice(&word.to_le_bytes());
            }
        });
    records
}

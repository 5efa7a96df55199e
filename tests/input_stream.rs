//! Windowed PLY reading (`PlyStream`) against the whole-file reader (`PlyFile`).
//!
//! `PlyFile` is the reference: for every fixture and window size, streaming must produce
//! exactly its positions, face indices and triangles, and on defective files exactly its
//! error (kind, element, index, absolute byte offset). Fixtures are small but window sizes
//! go down to one byte, so every vertex and face straddles windows somewhere and windows start
//! at offsets that are not page-aligned. The ignored test at the end measures throughput and
//! peak resident memory on a generated 10M-triangle file.

use std::io::Write;
use std::time::Instant;

use reducem::geometry::Point;
use reducem::input::{InputError, InputErrorKind, Location, PlyFile, PlyStream};
use reducem::splitmix::SplitMix64;

const WINDOW_SIZES: [usize; 8] = [1, 7, 13, 100, 1000, 4096, 65_536, 1 << 26];

// ---------------------------------------------------------------------------------------------
// Fixtures

/// A coordinate on a grid of 2^-10 within ±977.
fn coordinate(random: &mut SplitMix64) -> f64 {
    (random.below(2_000_001) as f64 - 1_000_000.0) / 1024.0
}

/// Binary body values in one byte order.
struct Body {
    big_endian: bool,
    bytes: Vec<u8>,
}

impl Body {
    fn push<const N: usize>(&mut self, mut little_endian: [u8; N]) -> &mut Body {
        if self.big_endian {
            little_endian.reverse();
        }
        self.bytes.extend_from_slice(&little_endian);
        self
    }

    fn uchar(&mut self, value: u8) -> &mut Body {
        self.push(value.to_le_bytes())
    }

    fn short(&mut self, value: i16) -> &mut Body {
        self.push(value.to_le_bytes())
    }

    fn int(&mut self, value: i32) -> &mut Body {
        self.push(value.to_le_bytes())
    }

    fn float(&mut self, value: f64) -> &mut Body {
        self.push((value as f32).to_le_bytes())
    }

    fn double(&mut self, value: f64) -> &mut Body {
        self.push(value.to_le_bytes())
    }
}

/// What surrounds the plain `x y z` vertices and index lists.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Decoration {
    /// Exactly what the generators write: float x y z, list uchar int.
    Plain,
    /// Extra scalar vertex and face properties and extra elements (with lists) before and
    /// after; faces still have a fixed size when they are all triangles.
    Extras,
    /// As `Extras`, plus a list after the indices, so faces never have a fixed size.
    ExtrasWithFaceList,
}

const DECORATIONS: [Decoration; 3] = [
    Decoration::Plain,
    Decoration::Extras,
    Decoration::ExtrasWithFaceList,
];

struct Fixture {
    bytes: Vec<u8>,
    /// Absolute offset of each face's first byte.
    face_offsets: Vec<usize>,
    /// Absolute offset of each vertex's y coordinate.
    y_offsets: Vec<usize>,
}

fn header(big_endian: bool, decoration: Decoration, vertices: usize, faces: usize) -> String {
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut text = format!("ply\nformat {format} 1.0\ncomment windowed reading fixture\n");
    if decoration == Decoration::Plain {
        text += &format!(
            "element vertex {vertices}\nproperty float x\nproperty float y\nproperty float z\n\
             element face {faces}\nproperty list uchar int vertex_indices\nend_header\n"
        );
        return text;
    }
    text += &format!(
        "element camera 2\nproperty list uchar float params\nproperty short id\n\
         element vertex {vertices}\nproperty uchar red\nproperty float x\n\
         property double confidence\nproperty double y\nproperty float z\nproperty int label\n\
         element face {faces}\nproperty uchar flags\nproperty list uchar int vertex_indices\n"
    );
    if decoration == Decoration::ExtrasWithFaceList {
        text += "property list uchar float texcoord\n";
    }
    text + "property float quality\n\
            element edge 2\nproperty int vertex1\nproperty list uchar int more\nend_header\n"
}

fn build(
    big_endian: bool,
    decoration: Decoration,
    positions: &[[f64; 3]],
    faces: &[Vec<i64>],
) -> Fixture {
    let header = header(big_endian, decoration, positions.len(), faces.len());
    let mut body = Body {
        big_endian,
        bytes: header.into_bytes(),
    };
    let extras = decoration != Decoration::Plain;
    if extras {
        for camera in 0..2 {
            body.uchar(3)
                .float(1.5)
                .float(-2.5)
                .float(0.25)
                .short(camera);
        }
    }
    let mut y_offsets = Vec::new();
    for &[x, y, z] in positions {
        if extras {
            body.uchar(200).float(x).double(0.75);
            y_offsets.push(body.bytes.len());
            body.double(y).float(z).int(-7);
        } else {
            body.float(x);
            y_offsets.push(body.bytes.len());
            body.float(y).float(z);
        }
    }
    let mut face_offsets = Vec::new();
    for face in faces {
        face_offsets.push(body.bytes.len());
        if extras {
            body.uchar(1);
        }
        body.uchar(face.len() as u8);
        for &index in face {
            body.int(index as i32);
        }
        if decoration == Decoration::ExtrasWithFaceList {
            body.uchar(2).float(0.5).float(0.125);
        }
        if extras {
            body.float(9.0);
        }
    }
    if extras {
        for edge in 0..2 {
            body.int(edge).uchar(1).int(5);
        }
    }
    Fixture {
        bytes: body.bytes,
        face_offsets,
        y_offsets,
    }
}

fn random_positions(random: &mut SplitMix64, count: usize) -> Vec<[f64; 3]> {
    (0..count)
        .map(|_| [coordinate(random), coordinate(random), coordinate(random)])
        .collect()
}

/// Face lengths drawn from `lengths`, indices uniform over the vertices.
fn random_faces(
    random: &mut SplitMix64,
    count: usize,
    vertices: usize,
    lengths: &[usize],
) -> Vec<Vec<i64>> {
    (0..count)
        .map(|_| {
            let length = lengths[random.below(lengths.len())];
            (0..length).map(|_| random.below(vertices) as i64).collect()
        })
        .collect()
}

const TRIANGLES: &[usize] = &[3];
const MIXED: &[usize] = &[3, 3, 3, 4, 4, 5, 255];

fn write_temp(bytes: &[u8]) -> tempfile::NamedTempFile {
    let mut file = tempfile::Builder::new()
        .suffix(".ply")
        .tempfile()
        .expect("create fixture");
    file.write_all(bytes).expect("write fixture");
    file
}

// ---------------------------------------------------------------------------------------------
// Readers under comparison

fn streamed_positions(stream: &PlyStream, window_bytes: usize) -> Result<Vec<Point>, InputError> {
    let mut positions = Vec::new();
    stream.for_each_position_window(window_bytes, |first, window| {
        assert_eq!(first, positions.len() as u64, "windows arrive in order");
        assert!(!window.is_empty());
        positions.extend_from_slice(window);
    })?;
    Ok(positions)
}

type FaceTriangle = (u64, [u32; 3]);

/// Triangles visited (also those visited before an error) and the outcome.
fn streamed_triangles(
    stream: &PlyStream,
    window_bytes: usize,
) -> (Vec<FaceTriangle>, Result<(), InputError>) {
    let mut triangles = Vec::new();
    let outcome = stream.for_each_triangle(window_bytes, |face, triangle| {
        triangles.push((face, triangle))
    });
    (triangles, outcome)
}

fn whole_file_triangles(file: &PlyFile) -> (Vec<FaceTriangle>, Result<(), InputError>) {
    let mut triangles = Vec::new();
    let outcome = file.for_each_triangle(|face, triangle| triangles.push((face, triangle)));
    (triangles, outcome)
}

/// Kinds are compared by their debug form because NaN coordinates are not equal to themselves.
fn assert_same_error(streamed: &InputError, whole: &InputError, context: &str) {
    let kind = |error: &InputError| format!("{:?}", error.kind);
    assert_eq!(kind(streamed), kind(whole), "{context}");
    assert_eq!(streamed.location, whole.location, "{context}");
    assert_eq!(streamed.to_string(), whole.to_string(), "{context}");
}

fn random_sorted_ids(random: &mut SplitMix64, vertices: usize, wanted: usize) -> Vec<u32> {
    let mut ids: Vec<u32> = (0..wanted).map(|_| random.below(vertices) as u32).collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

// ---------------------------------------------------------------------------------------------
// Agreement on valid files

#[test]
fn streaming_matches_the_whole_file_reader() {
    let mut random = SplitMix64::new(7);
    for big_endian in [false, true] {
        for decoration in DECORATIONS {
            for lengths in [TRIANGLES, MIXED] {
                let positions = random_positions(&mut random, 300);
                let faces = random_faces(&mut random, 400, positions.len(), lengths);
                let fixture = build(big_endian, decoration, &positions, &faces);
                let file = write_temp(&fixture.bytes);
                let context = format!("big {big_endian} {decoration:?} lengths {lengths:?}");
                check_agreement(file.path(), &mut random, &context);
            }
        }
    }
}

fn check_agreement(path: &std::path::Path, random: &mut SplitMix64, context: &str) {
    let whole = PlyFile::open(path).unwrap_or_else(|e| panic!("{context}: {e}"));
    let stream = PlyStream::open(path).unwrap_or_else(|e| panic!("{context}: {e}"));
    assert!(stream.is_streamable(), "{context}");
    assert_eq!(stream.path(), path);
    assert_eq!(stream.vertex_count(), whole.vertex_count());
    assert_eq!(stream.face_count(), whole.face_count());
    let positions = whole.read_positions().unwrap();
    let (triangles, outcome) = whole_file_triangles(&whole);
    outcome.unwrap();
    for window_bytes in WINDOW_SIZES {
        let context = format!("{context}, window {window_bytes}");
        let streamed = streamed_positions(&stream, window_bytes).unwrap();
        assert_eq!(streamed, positions, "{context}");
        let (streamed, outcome) = streamed_triangles(&stream, window_bytes);
        outcome.unwrap_or_else(|e| panic!("{context}: {e}"));
        assert_eq!(streamed, triangles, "{context}");
        for wanted in [1, 5, 60, 1000] {
            let ids = random_sorted_ids(random, positions.len(), wanted);
            let expected: Vec<Point> = ids.iter().map(|&id| positions[id as usize]).collect();
            let found = stream.positions_of(&ids, window_bytes).unwrap();
            assert_eq!(found, expected, "{context}, ids {ids:?}");
        }
    }
}

#[test]
fn generated_file_streams_like_the_whole_file_reader() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("scan.ply");
    reducem_gen::generate(reducem_gen::Kind::Scan, 20_000, 1, &path).unwrap();
    check_agreement(&path, &mut SplitMix64::new(3), "generated scan");
}

#[test]
fn empty_elements_stream_nothing() {
    let fixture = build(false, Decoration::Extras, &[], &[]);
    let file = write_temp(&fixture.bytes);
    let stream = PlyStream::open(file.path()).unwrap();
    let positions = streamed_positions(&stream, 100).unwrap();
    let (triangles, outcome) = streamed_triangles(&stream, 100);
    outcome.unwrap();
    assert!(positions.is_empty() && triangles.is_empty());
    assert_eq!(stream.positions_of(&[], 100).unwrap(), Vec::<Point>::new());
}

#[test]
fn unsorted_and_repeated_ids_are_still_answered() {
    let mut random = SplitMix64::new(11);
    let positions = random_positions(&mut random, 50);
    let fixture = build(true, Decoration::Extras, &positions, &[vec![0, 1, 2]]);
    let file = write_temp(&fixture.bytes);
    let all = PlyFile::open(file.path())
        .unwrap()
        .read_positions()
        .unwrap();
    let stream = PlyStream::open(file.path()).unwrap();
    let ids = [40, 3, 3, 49, 0, 17];
    let expected: Vec<Point> = ids.iter().map(|&id| all[id as usize]).collect();
    for window_bytes in WINDOW_SIZES {
        assert_eq!(stream.positions_of(&ids, window_bytes).unwrap(), expected);
    }
}

#[test]
fn ids_beyond_the_vertex_count_are_rejected() {
    let positions = random_positions(&mut SplitMix64::new(5), 10);
    let fixture = build(false, Decoration::Plain, &positions, &[vec![0, 1, 2]]);
    let file = write_temp(&fixture.bytes);
    let stream = PlyStream::open(file.path()).unwrap();
    let error = stream.positions_of(&[2, 9, 10], 64).unwrap_err();
    assert_eq!(error.location, Location::File);
    assert_eq!(
        error.kind,
        InputErrorKind::IndexOutOfRange {
            index: 10,
            vertex_count: 10
        }
    );
}

// ---------------------------------------------------------------------------------------------
// Agreement on defective files

/// For every window size, the streamed error (and what was visited before it) equals the whole
/// file reader's, and that error is of the `expected` kind at `expected_offset`.
fn check_same_triangle_error(
    bytes: &[u8],
    expected_offset: usize,
    is_expected: fn(&InputErrorKind) -> bool,
) {
    let file = write_temp(bytes);
    let whole = PlyFile::open(file.path()).unwrap();
    let (whole_triangles, whole_outcome) = whole_file_triangles(&whole);
    let whole_error = whole_outcome.expect_err("fixture must be defective");
    assert!(is_expected(&whole_error.kind), "{whole_error}");
    let Location::Element { byte_offset, .. } = whole_error.location else {
        panic!("{whole_error}");
    };
    assert_eq!(byte_offset, expected_offset as u64, "{whole_error}");
    let stream = PlyStream::open(file.path()).unwrap();
    for window_bytes in WINDOW_SIZES {
        let (triangles, outcome) = streamed_triangles(&stream, window_bytes);
        let context = format!("window {window_bytes}");
        assert_same_error(&outcome.unwrap_err(), &whole_error, &context);
        assert_eq!(triangles, whole_triangles, "{context}");
    }
}

/// A valid file's positions and faces, and a face index deep enough into the file that the
/// defect is in a later window for all but the largest windows.
fn defect_base(lengths: &[usize]) -> (Vec<[f64; 3]>, Vec<Vec<i64>>, usize) {
    let mut random = SplitMix64::new(13);
    let positions = random_positions(&mut random, 200);
    let faces = random_faces(&mut random, 300, positions.len(), lengths);
    (positions, faces, 211)
}

#[test]
fn index_out_of_range_matches_the_whole_file_reader() {
    for big_endian in [false, true] {
        for decoration in DECORATIONS {
            for lengths in [TRIANGLES, MIXED] {
                let (positions, mut faces, bad) = defect_base(lengths);
                faces[bad][2] = positions.len() as i64 + 3;
                let fixture = build(big_endian, decoration, &positions, &faces);
                let flags = usize::from(decoration != Decoration::Plain);
                let third_index = fixture.face_offsets[bad] + flags + 1 + 2 * 4;
                check_same_triangle_error(&fixture.bytes, third_index, |kind| {
                    matches!(kind, InputErrorKind::IndexOutOfRange { index: 203, .. })
                });
            }
        }
    }
}

#[test]
fn face_with_two_vertices_matches_the_whole_file_reader() {
    for big_endian in [false, true] {
        for decoration in DECORATIONS {
            for lengths in [TRIANGLES, MIXED] {
                let (positions, mut faces, bad) = defect_base(lengths);
                faces[bad].truncate(2);
                // Keeps all-triangle files long enough for the face count check.
                faces.last_mut().unwrap().push(0);
                let fixture = build(big_endian, decoration, &positions, &faces);
                let flags = usize::from(decoration != Decoration::Plain);
                let length = fixture.face_offsets[bad] + flags;
                check_same_triangle_error(&fixture.bytes, length, |kind| {
                    matches!(kind, InputErrorKind::TooFewFaceVertices(2))
                });
            }
        }
    }
}

#[test]
fn truncated_face_matches_the_whole_file_reader() {
    for big_endian in [false, true] {
        for decoration in DECORATIONS {
            let (positions, mut faces, _) = defect_base(MIXED);
            let last = faces.len() - 1;
            faces[last] = (0..255).map(|corner| corner % 200).collect();
            let fixture = build(big_endian, decoration, &positions, &faces);
            let flags = usize::from(decoration != Decoration::Plain);
            // Cut after 100 whole indices and 2 bytes of the next one.
            let cut_index = fixture.face_offsets[last] + flags + 1 + 100 * 4;
            check_same_triangle_error(&fixture.bytes[..cut_index + 2], cut_index, |kind| {
                *kind == InputErrorKind::Truncated { needed: 2 }
            });
        }
    }
}

#[test]
fn non_finite_coordinate_matches_the_whole_file_reader() {
    for big_endian in [false, true] {
        for decoration in DECORATIONS {
            let (mut positions, faces, _) = defect_base(TRIANGLES);
            let bad = 157;
            positions[bad][1] = f64::NAN;
            let fixture = build(big_endian, decoration, &positions, &faces);
            let file = write_temp(&fixture.bytes);
            let whole_error = PlyFile::open(file.path())
                .unwrap()
                .read_positions()
                .unwrap_err();
            assert!(matches!(
                whole_error.kind,
                InputErrorKind::NonFiniteCoordinate { axis: 'y', .. }
            ));
            assert_eq!(
                whole_error.location,
                Location::Element {
                    element: "vertex".into(),
                    index: bad as u64,
                    byte_offset: fixture.y_offsets[bad] as u64,
                    line: None,
                }
            );
            let stream = PlyStream::open(file.path()).unwrap();
            for window_bytes in WINDOW_SIZES {
                let context = format!("{decoration:?}, window {window_bytes}");
                let error = streamed_positions(&stream, window_bytes).unwrap_err();
                assert_same_error(&error, &whole_error, &context);
                let error = stream.positions_of(&[3, 156, 157, 199], window_bytes);
                assert_same_error(&error.unwrap_err(), &whole_error, &context);
                let clean = stream.positions_of(&[3, 156, 158, 199], window_bytes);
                assert_eq!(clean.unwrap().len(), 4, "{context}");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Files that are not streamed

#[test]
fn ascii_files_are_not_streamable() {
    let bytes = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                  property float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                  end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let file = write_temp(bytes);
    let stream = PlyStream::open(file.path()).unwrap();
    assert!(!stream.is_streamable());
    assert_eq!((stream.vertex_count(), stream.face_count()), (3, 1));
    let not_streamable = |error: InputError| {
        assert_eq!(error.location, Location::File);
        assert!(
            matches!(error.kind, InputErrorKind::NotStreamable(_)),
            "{error}"
        );
    };
    not_streamable(streamed_positions(&stream, 64).unwrap_err());
    not_streamable(streamed_triangles(&stream, 64).1.unwrap_err());
    not_streamable(stream.positions_of(&[0], 64).unwrap_err());
}

#[test]
fn vertices_with_lists_are_not_streamable_but_their_triangles_are() {
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
                  property float y\nproperty float z\nproperty list uchar float extra\n\
                  element face 2\nproperty list uchar int vertex_indices\nend_header\n";
    let mut body = Body {
        big_endian: false,
        bytes: header.as_bytes().to_vec(),
    };
    for vertex in 0..3u8 {
        body.float(f64::from(vertex)).float(1.0).float(2.0);
        body.uchar(vertex);
        for _ in 0..vertex {
            body.float(0.5);
        }
    }
    body.uchar(3).int(0).int(1).int(2);
    body.uchar(4).int(2).int(1).int(0).int(1);
    let file = write_temp(&body.bytes);
    let stream = PlyStream::open(file.path()).unwrap();
    assert!(!stream.is_streamable());
    let error = streamed_positions(&stream, 64).unwrap_err();
    assert!(
        matches!(error.kind, InputErrorKind::NotStreamable(_)),
        "{error}"
    );
    let (whole, outcome) = whole_file_triangles(&PlyFile::open(file.path()).unwrap());
    outcome.unwrap();
    for window_bytes in WINDOW_SIZES {
        let (streamed, outcome) = streamed_triangles(&stream, window_bytes);
        outcome.unwrap();
        assert_eq!(streamed, whole);
    }
}

// ---------------------------------------------------------------------------------------------
// Resident memory on a large file

/// A `/proc/self/status` field in bytes (Linux).
fn status_bytes(field: &str) -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("read /proc/self/status");
    let line = status.lines().find(|line| line.starts_with(field));
    let kibibytes = line.and_then(|line| line.split_whitespace().nth(1));
    kibibytes.and_then(|k| k.parse::<u64>().ok()).expect(field) * 1024
}

const MIB: f64 = (1 << 20) as f64;

/// Runs `work` and prints its time, throughput over `file_bytes`, and peak resident memory
/// (`VmHWM`, restarted just before through `clear_refs`, Linux ≥ 4.0) next to the resident
/// memory it started from. Returns the peak.
fn measure(label: &str, file_bytes: u64, work: impl FnOnce()) -> u64 {
    std::fs::write("/proc/self/clear_refs", "5").expect("restart VmHWM");
    let before = status_bytes("VmRSS:");
    let start = Instant::now();
    work();
    let seconds = start.elapsed().as_secs_f64();
    let peak = status_bytes("VmHWM:");
    println!(
        "{label}: {seconds:.2} s ({:.0} MiB/s), peak RSS {:.0} MiB (from {:.0} MiB)",
        file_bytes as f64 / MIB / seconds,
        peak as f64 / MIB,
        before as f64 / MIB
    );
    peak
}

/// Streams positions and triangles, returning vertex count, triangle count and index sum.
fn stream_all(path: &std::path::Path, window_bytes: usize) -> (u64, u64, u64) {
    let stream = PlyStream::open(path).unwrap();
    let mut vertices = 0u64;
    stream
        .for_each_position_window(window_bytes, |_, window| vertices += window.len() as u64)
        .unwrap();
    let (mut triangles, mut index_sum) = (0u64, 0u64);
    stream
        .for_each_triangle(window_bytes, |_, triangle| {
            triangles += 1;
            index_sum += u64::from(triangle[0]);
        })
        .unwrap();
    (vertices, triangles, index_sum)
}

#[test]
#[ignore = "generates a ~10M-triangle file and measures memory; run with --ignored --nocapture"]
fn streaming_10m_triangles_keeps_resident_memory_near_the_window_size() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("scan-10m.ply");
    reducem_gen::generate(reducem_gen::Kind::Scan, 10_000_000, 1, &path).unwrap();
    let file_bytes = std::fs::metadata(&path).unwrap().len();
    println!("file {:.0} MiB", file_bytes as f64 / MIB);

    let mut whole_counts = (0, 0, 0);
    let whole_peak = measure("PlyFile (whole mapping)", file_bytes, || {
        let whole = PlyFile::open(&path).unwrap();
        let (mut triangles, mut index_sum) = (0u64, 0u64);
        whole
            .for_each_triangle(|_, triangle| {
                triangles += 1;
                index_sum += u64::from(triangle[0]);
            })
            .unwrap();
        whole_counts = (
            whole.read_positions().unwrap().len() as u64,
            triangles,
            index_sum,
        );
    });
    for window_mib in [64, 16] {
        let mut counts = (0, 0, 0);
        let label = format!("PlyStream ({window_mib} MiB windows)");
        let peak = measure(&label, file_bytes, || {
            counts = stream_all(&path, window_mib << 20)
        });
        assert_eq!(counts, whole_counts);
        assert!(
            peak < whole_peak,
            "windows must not touch the whole file at once"
        );
    }
    println!("{} vertices, {} triangles", whole_counts.0, whole_counts.1);
}

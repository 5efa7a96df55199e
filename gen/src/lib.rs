//! Synthetic mesh generators behind `pipeline gen KIND --triangles N -o OUT.ply` and the
//! pipeline's `[input.generate]`.
//!
//! Every generator is a [`Generator`]: its counts are computed up front (in
//! closed form, or for the isosurface by a counting pass), then vertices and
//! faces are produced in independent chunks (rows of a grid, slabs of a
//! volume, groups of parts). Chunks are pure functions of
//! `(kind, N, seed, chunk index)`, so the mesh is identical for the same inputs
//! regardless of thread scheduling, and memory is bounded by a few chunks in
//! flight rather than by N. [`generate`] writes the chunks, produced in
//! parallel, strictly in order to a binary PLY; [`GeneratedSource`] hands them
//! to the out-of-core chunker directly, so a job needs no input file at all.
//!
//! The triangle count is the count nearest N that each construction allows;
//! the rule is documented on each kind's module.

mod cad;
mod glb;
mod isosurface;
mod marching_cubes;
mod noise;
mod perturb;
mod ply;
mod scan;
mod soup;
mod source;
mod sphere;
mod stl;
mod terrain;
#[cfg(test)]
mod test_mesh;

use std::ops::Range;
use std::path::Path;

use anyhow::Result;

pub use glb::GlbFlavour;
pub use perturb::perturbed_copies;
pub use source::GeneratedSource;
pub use stl::StlFlavour;

/// Changes whenever any kind's mesh changes for the same `(kind, N, seed)`: the pipeline's
/// fingerprint of a generated input is its parameters and this version, since no file is
/// hashed.
pub const GENERATOR_VERSION: u32 = 1;

/// A synthetic mesh as independent, deterministic chunks of vertices and of faces, in file
/// order: concatenating the chunks gives the mesh's vertex and face arrays.
pub trait Generator: Sync {
    /// The mesh's counts, known before any chunk is produced.
    fn summary(&self) -> GenSummary;
    fn vertex_chunks(&self) -> usize;
    /// Appends the positions of vertex chunk `chunk` to `out`.
    fn vertex_chunk(&self, chunk: usize, out: &mut Vec<[f32; 3]>);
    fn face_chunks(&self) -> usize;
    /// Appends the triangles of face chunk `chunk` to `out`.
    fn face_chunk(&self, chunk: usize, out: &mut Vec<[u32; 3]>);
    /// The positions of `sorted_ids` (strictly ascending), bit-identical to theirs in the
    /// chunks, for kinds that can compute a vertex without the rest of its chunk; `None`
    /// makes the caller regenerate the chunks holding them.
    fn positions_of(&self, _sorted_ids: &[u32]) -> Option<Vec<[f32; 3]>> {
        None
    }
}

/// The generator of a mesh of `kind` with about `triangles` triangles.
pub fn generator(kind: Kind, triangles: u64, seed: u64) -> Box<dyn Generator> {
    match kind {
        Kind::Scan => Box::new(scan::ScanSurface::for_triangles(triangles, seed)),
        Kind::Terrain => Box::new(terrain::Heightfield::for_triangles(triangles, seed)),
        Kind::Isosurface => Box::new(isosurface::Isosurface::for_triangles(triangles, seed)),
        Kind::Cad => Box::new(cad::Assembly::for_triangles(triangles, seed)),
        Kind::Soup => Box::new(soup::Soup::for_triangles(triangles, seed)),
        Kind::Sphere => Box::new(sphere::Icosphere::new(triangles, seed)),
    }
}

/// The family of synthetic mesh to generate ([`Kind::description`] says what each looks like).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Scan,
    Terrain,
    Isosurface,
    Cad,
    Soup,
    Sphere,
}

impl Kind {
    /// Every kind, in `--help` order.
    pub const ALL: [Kind; 6] = [
        Kind::Scan,
        Kind::Terrain,
        Kind::Isosurface,
        Kind::Cad,
        Kind::Soup,
        Kind::Sphere,
    ];

    /// The kind's name on command lines and in configurations.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Scan => "scan",
            Kind::Terrain => "terrain",
            Kind::Isosurface => "isosurface",
            Kind::Cad => "cad",
            Kind::Soup => "soup",
            Kind::Sphere => "sphere",
        }
    }

    /// One line saying what the kind's meshes look like.
    pub fn description(self) -> &'static str {
        match self {
            Kind::Scan => "Closed noisy torus that looks like a scanned statue surface",
            Kind::Terrain => "Open fractal heightfield",
            Kind::Isosurface => "Closed marching-cubes surface of a 3D noise field",
            Kind::Cad => "Many disconnected parts with wildly varying triangle sizes",
            Kind::Soup => "Unindexed triangles (every triangle owns its three vertices)",
            Kind::Sphere => "Closed subdivided icosahedron on the unit sphere",
        }
    }

    /// Every kind's name, comma separated, for messages.
    pub fn names() -> String {
        Kind::ALL.map(Kind::name).join(", ")
    }

    /// The triangles of the kind's smallest mesh, which any request below it would also get:
    /// `pipeline` refuses such requests rather than return many times what was asked.
    pub fn smallest_triangles(self) -> u64 {
        match self {
            Kind::Scan | Kind::Soup => 18,
            Kind::Terrain | Kind::Cad => 2,
            Kind::Isosurface => 96,
            Kind::Sphere => 20,
        }
    }
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not a kind's (case is ignored).
#[derive(Debug, thiserror::Error)]
#[error("{given:?} is not a mesh kind: one of {}", Kind::names())]
pub struct UnknownKind {
    pub given: String,
}

impl std::str::FromStr for Kind {
    type Err = UnknownKind;

    fn from_str(given: &str) -> Result<Kind, UnknownKind> {
        Kind::ALL
            .into_iter()
            .find(|kind| kind.name().eq_ignore_ascii_case(given))
            .ok_or_else(|| UnknownKind {
                given: given.to_string(),
            })
    }
}

/// Element counts of a written mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GenSummary {
    pub vertices: u64,
    pub triangles: u64,
}

/// The file formats [`generate_as`] writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// Binary little-endian PLY.
    Ply,
    Stl(StlFlavour),
    Glb(GlbFlavour),
}

impl OutputFormat {
    /// Binary STL for a `.stl` name, float GLB for a `.glb` one (any case), PLY otherwise.
    pub fn for_path(path: &Path) -> OutputFormat {
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("stl") => OutputFormat::Stl(StlFlavour::Binary),
            Some("glb") => OutputFormat::Glb(GlbFlavour::Float),
            _ => OutputFormat::Ply,
        }
    }
}

/// Generates a mesh of `kind` with about `triangles` triangles and writes it
/// atomically to `out` in the format its name says ([`OutputFormat::for_path`]).
pub fn generate(kind: Kind, triangles: u64, seed: u64, out: &Path) -> Result<GenSummary> {
    generate_as(kind, triangles, seed, out, OutputFormat::for_path(out))
}

/// [`generate`] in the file format `format`.
pub fn generate_as(
    kind: Kind,
    triangles: u64,
    seed: u64,
    out: &Path,
    format: OutputFormat,
) -> Result<GenSummary> {
    let comment =
        format!("reducem pipeline gen kind={kind} seed={seed} requested_triangles={triangles}");
    let generator = generator(kind, triangles, seed);
    match format {
        OutputFormat::Ply => {
            let target = ply::Target {
                path: out,
                comment: &comment,
            };
            ply::write(&*generator, &target)
        }
        OutputFormat::Stl(flavour) => stl::write(&*generator, flavour, out, &comment),
        OutputFormat::Glb(flavour) => glb::write(&*generator, flavour, out, &comment),
    }
}

/// Splits `0..items` into consecutive chunks of `per_chunk` items (the last
/// one possibly shorter), the unit of parallel work for grid generators.
#[derive(Clone, Copy, Debug)]
struct Chunking {
    items: u64,
    per_chunk: u64,
}

impl Chunking {
    /// Chunks of roughly `target_work` work units where one item costs
    /// `work_per_item`; keeps chunks big enough to amortise task overhead and
    /// small enough that a few in flight stay within a few megabytes.
    fn by_work(items: u64, work_per_item: u64, target_work: u64) -> Self {
        let per_chunk = (target_work / work_per_item.max(1)).max(1);
        Chunking { items, per_chunk }
    }

    fn count(&self) -> usize {
        self.items.div_ceil(self.per_chunk) as usize
    }

    fn range(&self, chunk: usize) -> Range<u64> {
        let start = chunk as u64 * self.per_chunk;
        start..(start + self.per_chunk).min(self.items)
    }
}

/// Triangles per parallel chunk: about 1.3 MB of face records.
const TRIANGLES_PER_CHUNK: u64 = 100_000;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_parses_from_its_name_in_any_case() {
        for kind in Kind::ALL {
            assert_eq!(kind.name().parse::<Kind>().unwrap(), kind);
            assert_eq!(kind.name().to_uppercase().parse::<Kind>().unwrap(), kind);
        }
        let unknown = "blob".parse::<Kind>().unwrap_err();
        assert_eq!(
            unknown.to_string(),
            "\"blob\" is not a mesh kind: one of scan, terrain, isosurface, cad, soup, sphere"
        );
    }

    fn bytes_of(kind: Kind, triangles: u64, seed: u64) -> Vec<u8> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mesh.ply");
        generate(kind, triangles, seed, &path).unwrap();
        std::fs::read(&path).unwrap()
    }

    #[test]
    fn same_seed_gives_identical_bytes_and_different_seed_differs() {
        for kind in Kind::ALL {
            let first = bytes_of(kind, 3000, 7);
            assert_eq!(
                first,
                bytes_of(kind, 3000, 7),
                "{kind:?} is not deterministic"
            );
            let other = bytes_of(kind, 3000, 8);
            let header_end = |b: &[u8]| b.windows(11).position(|w| w == b"end_header\n").unwrap();
            assert_ne!(
                first[header_end(&first)..],
                other[header_end(&other)..],
                "{kind:?} ignores the seed"
            );
        }
    }

    #[test]
    fn tiny_requests_still_produce_triangles() {
        for kind in Kind::ALL {
            for requested in [1, 2, 100] {
                let dir = tempfile::tempdir().unwrap();
                let summary = generate(kind, requested, 1, &dir.path().join("m.ply")).unwrap();
                assert!(summary.triangles > 0, "{kind:?} with N={requested}");
            }
        }
    }

    #[test]
    fn the_smallest_mesh_is_what_a_request_of_zero_or_of_its_size_gets() {
        for kind in Kind::ALL {
            let dir = tempfile::tempdir().unwrap();
            let smallest = kind.smallest_triangles();
            for requested in [0, smallest] {
                let summary = generate(kind, requested, 1, &dir.path().join("m.ply")).unwrap();
                assert_eq!(summary.triangles, smallest, "{kind:?} with N={requested}");
            }
        }
    }

    #[test]
    fn missing_directory_is_a_clean_error() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("no/such/dir/mesh.ply");
        let error = generate(Kind::Sphere, 100, 1, &out).unwrap_err();
        assert!(format!("{error:#}").contains("no/such/dir"), "{error:#}");
        assert!(!out.exists());
    }

    #[test]
    fn success_replaces_output_and_leaves_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("mesh.ply");
        std::fs::write(&out, b"old").unwrap();
        generate(Kind::Terrain, 500, 3, &out).unwrap();
        assert!(std::fs::read(&out).unwrap().starts_with(b"ply\n"));
        let entries = std::fs::read_dir(dir.path()).unwrap().count();
        assert_eq!(entries, 1);
    }
}

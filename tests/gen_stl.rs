//! `pipeline gen`'s STL writers: every kind written as binary and ASCII STL reads back, through
//! a parser written here, as exactly the facets of the same mesh written as PLY.

use std::path::PathBuf;

use reducem_gen::{generate_as, Kind, OutputFormat, StlFlavour};

type Facet = [[f32; 3]; 3];

fn temp_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reducem-gen-stl-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn binary_facets(bytes: &[u8]) -> Vec<Facet> {
    let count = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
    assert_eq!(bytes.len(), 84 + 50 * count);
    assert!(!bytes.starts_with(b"solid"));
    let float = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    (0..count)
        .map(|facet| {
            let start = 84 + 50 * facet + 12;
            [0, 1, 2].map(|corner| [0, 1, 2].map(|axis| float(start + 12 * corner + 4 * axis)))
        })
        .collect()
}

fn ascii_facets(text: &str) -> Vec<Facet> {
    let corners: Vec<[f32; 3]> = text
        .lines()
        .filter_map(|line| line.trim().strip_prefix("vertex "))
        .map(|rest| {
            let values: Vec<f32> = rest.split(' ').map(|v| v.parse().unwrap()).collect();
            [values[0], values[1], values[2]]
        })
        .collect();
    assert!(text.starts_with("solid ") && text.trim_end().ends_with("endsolid"));
    corners
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}

#[test]
fn every_kind_round_trips_bit_exactly_as_binary_and_ascii_stl() {
    let dir = temp_dir();
    for kind in Kind::ALL {
        let ply = dir.join("mesh.ply");
        generate_as(kind, 2000, 4, &ply, OutputFormat::Ply).unwrap();
        let mesh = reducem::input::PlyFile::open(&ply)
            .unwrap()
            .read_mesh()
            .unwrap();
        let expected: Vec<Facet> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|v| mesh.positions[v as usize]))
            .collect();
        let binary = dir.join("mesh.stl");
        let summary = reducem_gen::generate(kind, 2000, 4, &binary).unwrap();
        assert_eq!(summary.triangles, expected.len() as u64);
        let bits = |facets: &[Facet]| -> Vec<[[u32; 3]; 3]> {
            facets
                .iter()
                .map(|f| f.map(|c| c.map(f32::to_bits)))
                .collect()
        };
        let read = binary_facets(&std::fs::read(&binary).unwrap());
        assert_eq!(bits(&read), bits(&expected), "{kind} binary");
        let ascii = dir.join("mesh-ascii.stl");
        generate_as(kind, 2000, 4, &ascii, OutputFormat::Stl(StlFlavour::Ascii)).unwrap();
        let read = ascii_facets(&std::fs::read_to_string(&ascii).unwrap());
        assert_eq!(bits(&read), bits(&expected), "{kind} ASCII");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

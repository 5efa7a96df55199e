//! `TriangleIndex`: a real window's position is its row in `decode::triangles`, swap windows
//! skipped, on files with long strips full of swaps (f32 and grid vertices).

mod common;

use common::*;
use reducem::format::reader::ReducemFile;
use reducem_core::triangle_index::TriangleIndex;

fn check_positions(file: &ReducemFile) {
    let index = TriangleIndex::new(file);
    let decoded: Vec<_> = reducem::decode::triangles(file).collect();
    assert_eq!(index.total(), decoded.len() as u64);
    assert_eq!(index.total(), file.header().triangle_count);
    let mut row = 0u64;
    let mut swaps = 0;
    for s in 0..file.strip_count() {
        let view = file.strip(s);
        for window in 0..view.window_count() {
            let Some(corners) = view.window_points(window) else {
                swaps += 1;
                continue;
            };
            let position = index.position(file, s as u32, window as u16);
            assert_eq!(position, Some(row), "strip {s} window {window}");
            assert_eq!(decoded[row as usize], corners);
            row += 1;
        }
    }
    assert!(swaps > 0, "the file should have swap windows to skip");
    let longest = (0..file.strip_count())
        .map(|s| file.strip(s).window_count())
        .max();
    assert!(
        longest > Some(128),
        "a strip should span several of the index's reads of 64 windows"
    );
    assert_eq!(index.position(file, file.strip_count() as u32, 0), None);
}

#[test]
fn positions_are_decode_rows_on_f32_files() {
    check_positions(&open_with_long_strips(&torus(24, 16), "index_f32.rdm", 150));
}

#[test]
fn positions_are_decode_rows_on_grid_files() {
    let file = open_with_long_strips_on_grid(&torus(24, 16), "index_grid.rdm", 150, 12);
    check_positions(&file);
}

//! STL writers (binary and ASCII) for the STL reader's tests and benchmarks.
//!
//! STL repeats every corner in every facet, so the positions are generated into memory first
//! (12 bytes per vertex) and the facets are then written face chunk by face chunk. The facet
//! normal is written as zero, which the format allows and readers must recompute anyway. The
//! output is written to a temporary next to the target and renamed into place when complete.

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{ensure, Context, Result};
use reducem::atomic;

use super::{GenSummary, Generator};

/// Which kind of STL to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StlFlavour {
    Binary,
    Ascii,
}

/// Writes `generator`'s mesh to `path` as STL, `comment` in the binary header or after
/// `solid`.
pub fn write(
    generator: &dyn Generator,
    flavour: StlFlavour,
    path: &Path,
    comment: &str,
) -> Result<GenSummary> {
    let summary = generator.summary();
    ensure!(
        summary.triangles <= u64::from(u32::MAX),
        "{} triangles exceed the binary STL facet count",
        summary.triangles
    );
    let mut positions = Vec::with_capacity(summary.vertices as usize);
    for chunk in 0..generator.vertex_chunks() {
        generator.vertex_chunk(chunk, &mut positions);
    }
    let temporary = atomic::temporary_path(path);
    let written = write_facets(generator, flavour, &positions, &temporary, comment, summary)
        .and_then(|()| {
            atomic::replace(&temporary, path)
                .with_context(|| format!("cannot move output into {}", path.display()))
        });
    if written.is_err() {
        let _ = fs::remove_file(&temporary);
    }
    written.map(|()| summary)
}

fn write_facets(
    generator: &dyn Generator,
    flavour: StlFlavour,
    positions: &[[f32; 3]],
    temporary: &Path,
    comment: &str,
    summary: GenSummary,
) -> Result<()> {
    let file = File::create(temporary)
        .with_context(|| format!("cannot create {}", temporary.display()))?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    let one_line_comment = comment.replace(['\n', '\r'], " ");
    match flavour {
        StlFlavour::Binary => {
            let mut header = [b' '; 80];
            // A header beginning with `solid` would mislead readers that sniff for ASCII.
            let text = format!("binary STL: {one_line_comment}");
            let length = text.len().min(80);
            header[..length].copy_from_slice(&text.as_bytes()[..length]);
            out.write_all(&header)?;
            out.write_all(&(summary.triangles as u32).to_le_bytes())?;
        }
        StlFlavour::Ascii => writeln!(out, "solid {one_line_comment}")?,
    }
    let mut triangles = Vec::new();
    let mut facets = 0u64;
    for chunk in 0..generator.face_chunks() {
        triangles.clear();
        generator.face_chunk(chunk, &mut triangles);
        for triangle in &triangles {
            let corners = triangle.map(|v| positions[v as usize]);
            match flavour {
                StlFlavour::Binary => write_binary_facet(&mut out, &corners)?,
                StlFlavour::Ascii => write_ascii_facet(&mut out, &corners)?,
            }
        }
        facets += triangles.len() as u64;
    }
    ensure!(
        facets == summary.triangles,
        "generator bug: {} triangles declared but {facets} produced",
        summary.triangles
    );
    if flavour == StlFlavour::Ascii {
        writeln!(out, "endsolid")?;
    }
    out.flush()?;
    out.get_ref().sync_all()?;
    Ok(())
}

fn write_binary_facet(out: &mut impl Write, corners: &[[f32; 3]; 3]) -> std::io::Result<()> {
    let mut record = [0u8; 50];
    for (value, bytes) in corners
        .as_flattened()
        .iter()
        .zip(record[12..48].chunks_exact_mut(4))
    {
        bytes.copy_from_slice(&value.to_le_bytes());
    }
    out.write_all(&record)
}

/// Coordinates in Rust's shortest decimal that reads back to the same `f32`.
fn write_ascii_facet(out: &mut impl Write, corners: &[[f32; 3]; 3]) -> std::io::Result<()> {
    writeln!(out, "facet normal 0 0 0\nouter loop")?;
    for [x, y, z] in corners {
        writeln!(out, "vertex {x:?} {y:?} {z:?}")?;
    }
    writeln!(out, "endloop\nendfacet")
}

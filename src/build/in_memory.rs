//! Writes a model converted in memory: its strips in the top level's order, through the
//! format's streaming writer.

use std::io::{self, Write};
use std::path::Path;

use crate::encode::EncodedStrip;
use crate::format::grid::NodeGrid;
use crate::format::writer::{write_nodes, write_streaming, FileInfo, SectionSource, WriteError};
use crate::format::{SectionKind, StripRecord, VERSION_MAJOR};
use crate::toplevel::TopLevel;

/// Writes `strips` (indexed by the top level's `strip_order`) as a ReduceM file at `path`.
pub fn write_file(
    path: &Path,
    info: &FileInfo,
    top: &TopLevel,
    strips: &[EncodedStrip],
) -> Result<(), WriteError> {
    let error = |source| WriteError {
        path: path.to_path_buf(),
        source,
    };
    let records = strip_records(top, strips).map_err(error)?;
    let mut source = InMemory {
        top,
        node_grid: info.node_grid().map_err(error)?,
        strips,
        records,
    };
    write_streaming(path, info, &mut source)
}

/// The sections of a model converted in memory.
struct InMemory<'a> {
    top: &'a TopLevel,
    node_grid: Option<NodeGrid>,
    strips: &'a [EncodedStrip],
    records: Vec<StripRecord>,
}

impl SectionSource for InMemory<'_> {
    fn strip_count(&self) -> u64 {
        self.strips.len() as u64
    }

    fn write_section(&mut self, kind: SectionKind, out: &mut dyn Write) -> io::Result<()> {
        match kind {
            SectionKind::TopNodes => write_nodes(out, &self.top.nodes, self.node_grid.as_ref()),
            SectionKind::StripRecords => out.write_all(bytemuck::cast_slice(&self.records)),
            SectionKind::StripData => self
                .top
                .strip_order
                .iter()
                .try_for_each(|&s| out.write_all(&self.strips[s as usize].block)),
        }
    }
}

/// Records in file order. Blocks are padded to 4 bytes, so offsets are counted in words.
fn strip_records(top: &TopLevel, strips: &[EncodedStrip]) -> io::Result<Vec<StripRecord>> {
    let mut word = 0u64;
    top.strip_order
        .iter()
        .map(|&s| {
            let strip = &strips[s as usize];
            let record = StripRecord {
                data_word: u32::try_from(word)
                    .map_err(|_| too_large("strip data exceeds 16 GiB"))?,
                vertex_count: strip.vertex_count,
                reference_count: strip.reference_count,
            };
            word += strip.block.len() as u64 / 4;
            Ok(record)
        })
        .collect()
}

fn too_large(what: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::FileTooLarge,
        format!("{what}: too large for format version {VERSION_MAJOR}"),
    )
}

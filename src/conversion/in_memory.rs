//! Writes a model converted in memory: its strips in the top level's order, through the
//! format's streaming writer.

use std::io::{self, Write};
use std::path::Path;

use super::layout::{strip_records, ChunkLayout, DataWords};
use crate::format::attribute_sections::AttributeVisit;
use crate::format::writer::{write_nodes, write_streaming, FileInfo, SectionSource, WriteError};
use crate::format::{SectionKind, StripRecord};
use crate::strip_encoding::EncodedStrip;
use crate::toplevel::TopLevel;

/// Writes `strips` (indexed by the top level's `strip_order`) as a ReduceM file at `path`.
pub fn write_file(
    path: &Path,
    info: &FileInfo,
    top: &TopLevel,
    strips: &[EncodedStrip],
) -> Result<(), WriteError> {
    let records = strip_records(&top.strip_order, strips, &mut DataWords::default())
        .map_err(|source| write_error(path, source))?;
    write_sections(path, info, top, &records, strips)
}

/// Writes a chunk laid out by [`ChunkLayout::new`] as a ReduceM file at `path`.
pub(super) fn write_layout(
    path: &Path,
    info: &FileInfo,
    layout: &ChunkLayout,
    strips: &[EncodedStrip],
) -> Result<(), WriteError> {
    write_sections(path, info, &layout.top, &layout.records, strips)
}

fn write_sections(
    path: &Path,
    info: &FileInfo,
    top: &TopLevel,
    records: &[StripRecord],
    strips: &[EncodedStrip],
) -> Result<(), WriteError> {
    let mut source = InMemory {
        top,
        strips,
        records,
    };
    write_streaming(path, info, &mut source)
}

fn write_error(path: &Path, source: io::Error) -> WriteError {
    WriteError {
        path: path.to_path_buf(),
        source,
    }
}

/// The sections of a model converted in memory.
struct InMemory<'a> {
    top: &'a TopLevel,
    strips: &'a [EncodedStrip],
    records: &'a [StripRecord],
}

impl SectionSource for InMemory<'_> {
    fn strip_count(&self) -> u64 {
        self.strips.len() as u64
    }

    fn write_section(&mut self, kind: SectionKind, out: &mut dyn Write) -> io::Result<()> {
        match kind {
            SectionKind::TopNodes => write_nodes(out, &self.top.nodes),
            SectionKind::StripRecords => out.write_all(bytemuck::cast_slice(self.records)),
            SectionKind::StripData => self
                .top
                .strip_order
                .iter()
                .try_for_each(|&s| out.write_all(&self.strips[s as usize].block)),
        }
    }

    fn visit_attributes(&mut self, visit: &mut AttributeVisit) -> io::Result<()> {
        self.top
            .strip_order
            .iter()
            .try_for_each(|&s| visit(&self.strips[s as usize].attributes))
    }
}

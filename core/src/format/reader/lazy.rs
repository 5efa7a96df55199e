//! Which strips and top-level nodes of a lazily opened file have been validated, and the first
//! defect met.
//!
//! One bit per strip, set once the strip's record and block passed the same checks a full
//! validation makes (`validate::check_strip`), and one per node, set once the node passed the
//! checks that need no other node (`validate::check_node`). The bits only ever go from 0 to 1
//! and publish nothing but themselves (the mapping is immutable), so relaxed atomics suffice: a
//! thread that does not see another's bit yet validates the element again, to the same outcome.

use crate::format::block_boxes::BlockBoxes;
use crate::format::{Defect, FilePart, SectionKind};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;

use super::{FormatError, References, StripVertices, StripView};
use crate::geometry::Point;

/// The validation state of a file's strips and top-level nodes.
pub(super) struct LazyChecks {
    pub(super) strips: Passed,
    pub(super) nodes: Passed,
    first_defect: OnceLock<KeptDefect>,
}

/// Bit `i % 64` of word `i / 64` is set once element `i` passed; `None` when every element was
/// validated at open.
pub(super) struct Passed(Option<Box<[AtomicU64]>>);

/// A defect as [`FormatError::Invalid`] reports it, without the path.
struct KeptDefect {
    section: FilePart,
    offset: u64,
    defect: Defect,
    detail: String,
}

impl Passed {
    /// Every element validated already.
    pub(super) fn all() -> Passed {
        Passed(None)
    }

    /// None of `count` elements validated yet. The bits are allocated zeroed, so the system
    /// supplies their pages on first touch and opening stays independent of the count.
    pub(super) fn none_of(count: u64) -> Passed {
        Passed(Some(
            bytemuck::zeroed_slice_box(count.div_ceil(64) as usize),
        ))
    }

    /// Whether element `index` passed validation (false beyond the last one).
    #[inline(always)]
    pub(super) fn get(&self, index: usize) -> bool {
        match &self.0 {
            None => true,
            Some(bits) => bits
                .get(index / 64)
                .is_some_and(|word| word.load(Ordering::Relaxed) >> (index % 64) & 1 != 0),
        }
    }

    pub(super) fn set(&self, index: usize) {
        if let Some(word) = self.0.as_ref().and_then(|bits| bits.get(index / 64)) {
            word.fetch_or(1 << (index % 64), Ordering::Relaxed);
        }
    }
}

impl LazyChecks {
    pub(super) fn new(strips: Passed, nodes: Passed) -> LazyChecks {
        LazyChecks {
            strips,
            nodes,
            first_defect: OnceLock::new(),
        }
    }

    /// Keeps `defect` unless an earlier one was kept.
    pub(super) fn keep(&self, defect: FormatError) {
        self.first_defect.get_or_init(|| match defect {
            FormatError::Invalid {
                section,
                offset,
                defect,
                detail,
                ..
            } => KeptDefect {
                section,
                offset,
                defect,
                detail,
            },
            FormatError::Io { source, .. } => KeptDefect {
                section: FilePart::Section(SectionKind::StripData),
                offset: 0,
                defect: Defect::Unreadable,
                detail: source.to_string(),
            },
        });
    }

    pub(super) fn first_defect(&self, path: &Path) -> Option<FormatError> {
        self.first_defect.get().map(|defect| FormatError::Invalid {
            path: path.to_path_buf(),
            section: defect.section,
            offset: defect.offset,
            defect: defect.defect,
            detail: defect.detail.clone(),
        })
    }
}

/// What a corrupt strip reads as: three vertices at the origin and one swap window, which is
/// no triangle, so no ray hits it and no decoder yields a triangle from it.
pub(super) fn no_triangles<'a>() -> StripView<'a> {
    static VERTICES: [Point; 3] = [[0.0; 3]; 3];
    static REFERENCES: [u8; 3] = [0; 3];
    StripView {
        vertices: StripVertices::F32(&VERTICES),
        axes: &[],
        references: References::bytes(&REFERENCES),
        boxes: BlockBoxes::default(),
    }
}

//! What is wrong with a file, as a kind a caller can match on: [`FormatError::Invalid`] carries
//! one next to the section, the byte offset and the worded detail.
//!
//! [`FormatError::Invalid`]: super::reader::FormatError::Invalid

/// The kind of a defect found while opening or validating a ReduceM file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Defect {
    /// The file, a section or an entry ends before the data it must hold.
    Truncated,
    /// The magic number is not ReduceM's: not a ReduceM file.
    BadMagic,
    /// The endianness marker reads swapped: written or read on a big-endian host.
    BadEndianMarker,
    /// A format version this reader does not read.
    UnsupportedVersion,
    /// A stored checksum differs from the one computed over the bytes it covers.
    ChecksumMismatch,
    /// A field holds a value its format does not define (an unknown kind, flag, encoding or
    /// split axis), or one its format version does not allow.
    BadEncoding,
    /// A count, index, width, exponent or reference outside its bounds.
    OutOfRange,
    /// Two counts or positions that must agree do not (records and strips, triangles, stored
    /// vertices, where an attribute group starts and the previous one ends).
    CountMismatch,
    /// Two fields that exclude each other are both set (a grid for f32 vertices, a shift
    /// without grid nodes, edge counts without their flag).
    Contradiction,
    /// A section offset is not a multiple of the section alignment.
    Misaligned,
    /// A section starts before the previous one ends.
    Overlap,
    /// A grid's corners or a node grid's cell are not finite.
    NonFinite,
    /// A grid cell is not a positive power of two.
    NotPowerOfTwo,
    /// A box minimum above its maximum.
    BadBounds,
    /// The node structure is not one tree: a node without parent or children, with a second
    /// parent, or deeper than the limit.
    BadTree,
    /// The file changed while it was being opened or mapped.
    ChangedWhileMapped,
    /// The bytes could not be read while validating lazily (an I/O error).
    Unreadable,
}

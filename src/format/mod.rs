//! The ReduceM file format.

//! Synthetic mesh generators.

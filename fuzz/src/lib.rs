//! Stable-toolchain fuzzing of reducem's hostile-input surface: the PLY and OBJ readers, opening
//! and tracing a ReduceM file, and the ray files of `reducem query`.
//!
//! cargo-fuzz needs a nightly toolchain and a `cargo-fuzz` install that this project's machines
//! do not have, so this crate is a seeded mutation fuzzer that runs on stable: [`mutate`] makes
//! inputs, [`targets`] runs them and asserts invariants, [`runner`] catches panics and hangs and
//! saves findings. `scripts/fuzz.sh` runs every target for a given time; `docs/HOSTILE.md`
//! describes the campaigns and their results.

pub mod mutate;
pub mod runner;
pub mod seeds;
pub mod targets;

//! The staged, resumable conversion behind the `pipeline` command, as a library: the command
//! (`main.rs`) and the Python package (`python/`) both run jobs through [`run::run`] and
//! [`convert::convert`].

pub mod border_edges;
pub mod checksum;
pub mod chunk_io;
pub mod config;
pub mod convert;
pub mod error;
pub mod fingerprint;
pub mod input;
pub mod interrupt;
pub mod job;
pub mod lock;
pub mod manifest;
pub mod outcome;
pub mod outcome_json;
pub mod preflight;
pub mod progress;
pub mod run;
pub mod stage;
pub mod stages;
pub mod status;
pub mod time;
pub mod workdir;

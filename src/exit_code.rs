//! The exit codes of both binaries, `reducem` and `pipeline`: sysexits.h values, as batch
//! schedulers and cron wrappers expect. One table, printed at the end of each `--help` and copied
//! in README.md.

pub const SUCCESS: u8 = 0;
/// Bad command-line arguments, or an output that would overwrite an input of the same command.
pub const USAGE: u8 = 64;
/// An input file (mesh, ReduceM file, ray file) is malformed.
pub const BAD_INPUT: u8 = 65;
pub const INTERNAL: u8 = 70;
/// Reading or writing failed (missing file, permissions, disk full, an output that is a
/// directory).
pub const IO: u8 = 74;
/// `pipeline` only: try again later (locked, stopped by a signal, stages not done yet).
pub const TEMPORARY: u8 = 75;
/// A configuration or scene file is invalid.
pub const CONFIG: u8 = 78;

/// The table at the end of `--help`.
pub const HELP: &str = "\
Exit codes (the same for reducem and pipeline):
   0  success
  64  usage: bad arguments, or an output that is one of the command's inputs
  65  bad input: a malformed mesh, ReduceM or ray file (the message says where)
  70  internal error
  74  I/O: reading or writing failed (missing file, permissions, disk full, output is a
      directory), or a mapped file truncated by another process
  75  try again later (pipeline): work directory locked, stopped by SIGTERM or SIGUSR1 (run the
      same command again to resume), stages not done
  78  configuration or scene error (including an [output] path that is an input)
 130  stopped by SIGINT (pipeline; run the same command again to resume)";

/// A command line that cannot be run as given.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// An exit code and its kind, the name `pipeline --log-format json` reports it by.
pub type Exit = (u8, &'static str);

/// The exit code of `error`, by the first error in its chain that `specific` (the binary's own
/// error types) or [`shared_exit`] knows; internal when neither knows any.
pub fn classify(
    error: &anyhow::Error,
    specific: impl Fn(&(dyn std::error::Error + 'static)) -> Option<Exit>,
) -> Exit {
    error
        .chain()
        .find_map(|cause| specific(cause).or_else(|| shared_exit(cause)))
        .unwrap_or((INTERNAL, "internal"))
}

/// The exit of the library's error types that both binaries meet.
fn shared_exit(cause: &(dyn std::error::Error + 'static)) -> Option<Exit> {
    if cause.is::<UsageError>() {
        return Some((USAGE, "usage"));
    }
    if cause.is::<crate::input::InputError>() {
        return Some((BAD_INPUT, "bad_input"));
    }
    if cause.is::<std::io::Error>() || cause.is::<crate::format::writer::WriteError>() {
        return Some((IO, "io"));
    }
    None
}

//! The contexts a run puts on its errors, so that `outcome` can report where it stopped. A leaf:
//! the stages add these and `outcome` reads them without either importing the other.

pub use reducem::exit_code::UsageError;

/// The stage a failed run stopped in (context on its error).
#[derive(Debug, thiserror::Error)]
#[error("stage {0}")]
pub struct InStage(pub String);

/// The chunk a failed unit worked on (context on its error).
#[derive(Debug, thiserror::Error)]
#[error("chunk {0}")]
pub struct InChunk(pub usize);

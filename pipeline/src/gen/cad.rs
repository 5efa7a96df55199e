//! placeholder
use super::{GenSummary, ply::Target}; pub fn generate(_: u64, _: u64, _: &Target) -> anyhow::Result<GenSummary> { todo!() }

//! The stage table: every stage once, in run order, with its unit of work, the fingerprints of
//! its units, its fresh result and its run. `pipeline run` (whole, resumed or `--stage`) and
//! `pipeline status` all walk this one table.

use crate::fingerprint::Fingerprint;
use crate::input;
use crate::job::Job;
use crate::manifest::Freshness;
use crate::stage::chunk::{self, Chunked};
use crate::stage::hierarchy::{self, Hierarchy};
use crate::stage::merge::{self, Merged};
use crate::stage::{strip, write, Shard, StageName, UpstreamPending};

/// What a stage's manifest entries stand for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnitOfWork {
    /// The stage as one unit.
    Stage,
    /// One unit per chunk, each locked on its own: tasks of a batch job array share the stage.
    Chunk,
}

/// A stage's units: their manifest keys and fingerprints.
pub type Units = Vec<(String, Fingerprint)>;

/// One stage of the table.
pub struct StageDef {
    pub name: StageName,
    pub unit: UnitOfWork,
    /// The stage's units (manifest keys) with their fingerprints, from the results of the
    /// stages before it; why not when they cannot be known yet.
    pub units: fn(&Job, &Results) -> Result<Units, String>,
    /// Puts the stage's recorded result into `results` if every unit is fresh; why not otherwise.
    pub fresh: fn(&Job, &mut Results) -> Result<(), String>,
    /// Does the stage's pending work (only `shard`'s chunks, for a per-chunk stage) and puts its
    /// result into `results`.
    pub run: fn(&Job, &mut Results, Shard) -> anyhow::Result<()>,
}

pub static STAGES: [StageDef; 5] = [
    StageDef {
        name: StageName::Chunk,
        unit: UnitOfWork::Stage,
        units: chunk_units,
        fresh: chunk_fresh,
        run: chunk_run,
    },
    StageDef {
        name: StageName::Strip,
        unit: UnitOfWork::Chunk,
        units: strip_units,
        fresh: strip_fresh,
        run: strip_run,
    },
    StageDef {
        name: StageName::Merge,
        unit: UnitOfWork::Stage,
        units: merge_units,
        fresh: merge_fresh,
        run: merge_run,
    },
    StageDef {
        name: StageName::Hierarchy,
        unit: UnitOfWork::Stage,
        units: hierarchy_units,
        fresh: hierarchy_fresh,
        run: hierarchy_run,
    },
    StageDef {
        name: StageName::Write,
        unit: UnitOfWork::Stage,
        units: write_units,
        fresh: write_fresh,
        run: write_run,
    },
];

/// The table's entry for `name`: the table lists the stages in the order `StageName` declares
/// them (a test checks it).
pub fn stage(name: StageName) -> &'static StageDef {
    &STAGES[name as usize]
}

/// Runs every stage in order, each skipping its fresh units.
pub fn run_all(job: &Job) -> anyhow::Result<()> {
    let mut results = Results::default();
    STAGES
        .iter()
        .try_for_each(|stage| (stage.run)(job, &mut results, Shard::WHOLE))
}

/// Runs stage `name` alone, after checking that every stage before it is done.
pub fn run_one(job: &Job, name: StageName, shard: Shard) -> anyhow::Result<()> {
    let mut results = Results::default();
    for stage in &STAGES[..name as usize] {
        (stage.fresh)(job, &mut results).map_err(|reason| UpstreamPending {
            needed: stage.name,
            reason,
        })?;
    }
    (self::stage(name).run)(job, &mut results, shard)
}

/// What the stages before the one at hand produced.
#[derive(Default)]
pub struct Results {
    chunked: Option<Chunked>,
    strip_digest: Option<String>,
    merged: Option<Merged>,
    hierarchy: Option<Hierarchy>,
}

const NOT_FRESH: &str = "not run, or stale";

/// A result that the table's order puts in place before any stage asks for it.
fn earlier<T>(result: &Option<T>, stage: StageName) -> Result<&T, String> {
    result
        .as_ref()
        .ok_or_else(|| format!("the result of stage {stage} is missing"))
}

fn chunk_units(job: &Job, _: &Results) -> Result<Units, String> {
    let input = input::peek(job)?;
    Ok(vec![(chunk::UNIT.into(), chunk::fingerprint(job, &input))])
}

fn chunk_fresh(job: &Job, results: &mut Results) -> Result<(), String> {
    let input = input::peek(job)?;
    let fingerprint = chunk::fingerprint(job, &input);
    results.chunked = Some(chunk::fresh_result(job, &fingerprint).ok_or(NOT_FRESH)?);
    Ok(())
}

fn chunk_run(job: &Job, results: &mut Results, _: Shard) -> anyhow::Result<()> {
    results.chunked = Some(chunk::run(job, &input::resolve(job)?)?);
    Ok(())
}

fn strip_units(job: &Job, results: &Results) -> Result<Units, String> {
    let chunked = earlier(&results.chunked, StageName::Chunk)?;
    let units = (0..chunked.chunk_count())
        .map(|chunk| (strip::unit(chunk), strip::fingerprint(job, chunked, chunk)))
        .collect();
    Ok(units)
}

fn strip_fresh(job: &Job, results: &mut Results) -> Result<(), String> {
    let chunked = earlier(&results.chunked, StageName::Chunk)?;
    let missing = strip::pending_chunks(job, chunked, Shard::WHOLE);
    if let Some(first) = missing.first() {
        let total = chunked.chunk_count();
        return Err(format!(
            "{} of {total} chunks pending, first {first}",
            missing.len()
        ));
    }
    results.strip_digest = Some(strip::digest(job, chunked));
    Ok(())
}

fn strip_run(job: &Job, results: &mut Results, shard: Shard) -> anyhow::Result<()> {
    let chunked = earlier(&results.chunked, StageName::Chunk).map_err(anyhow::Error::msg)?;
    results.strip_digest = Some(strip::run(job, chunked, shard)?);
    Ok(())
}

fn merge_fingerprint(results: &Results) -> Result<Fingerprint, String> {
    let strip_digest = earlier(&results.strip_digest, StageName::Strip)?;
    Ok(merge::fingerprint(strip_digest))
}

fn merge_units(_: &Job, results: &Results) -> Result<Units, String> {
    Ok(vec![(merge::UNIT.into(), merge_fingerprint(results)?)])
}

fn merge_fresh(job: &Job, results: &mut Results) -> Result<(), String> {
    let fingerprint = merge_fingerprint(results)?;
    results.merged = Some(merge::fresh_result(job, &fingerprint).ok_or(NOT_FRESH)?);
    Ok(())
}

fn merge_run(job: &Job, results: &mut Results, _: Shard) -> anyhow::Result<()> {
    let chunked = earlier(&results.chunked, StageName::Chunk).map_err(anyhow::Error::msg)?;
    let strip_digest =
        earlier(&results.strip_digest, StageName::Strip).map_err(anyhow::Error::msg)?;
    results.merged = Some(merge::run(job, chunked, strip_digest)?);
    Ok(())
}

fn hierarchy_fingerprint(results: &Results) -> Result<Fingerprint, String> {
    let merged = earlier(&results.merged, StageName::Merge)?;
    Ok(hierarchy::fingerprint(merged))
}

fn hierarchy_units(_: &Job, results: &Results) -> Result<Units, String> {
    Ok(vec![(
        hierarchy::UNIT.into(),
        hierarchy_fingerprint(results)?,
    )])
}

fn hierarchy_fresh(job: &Job, results: &mut Results) -> Result<(), String> {
    let fingerprint = hierarchy_fingerprint(results)?;
    results.hierarchy = Some(hierarchy::fresh_result(job, &fingerprint).ok_or(NOT_FRESH)?);
    Ok(())
}

fn hierarchy_run(job: &Job, results: &mut Results, _: Shard) -> anyhow::Result<()> {
    let merged = earlier(&results.merged, StageName::Merge).map_err(anyhow::Error::msg)?;
    results.hierarchy = Some(hierarchy::run(job, merged)?);
    Ok(())
}

fn write_fingerprint(job: &Job, results: &Results) -> Result<Fingerprint, String> {
    let built = earlier(&results.hierarchy, StageName::Hierarchy)?;
    Ok(write::fingerprint(job, built))
}

fn write_units(job: &Job, results: &Results) -> Result<Units, String> {
    Ok(vec![(write::UNIT.into(), write_fingerprint(job, results)?)])
}

/// The written file is the last stage's result; nothing after it needs more than its being fresh.
fn write_fresh(job: &Job, results: &mut Results) -> Result<(), String> {
    let fingerprint = write_fingerprint(job, results)?;
    match job.freshness(write::UNIT, &fingerprint) {
        Freshness::Fresh => Ok(()),
        _ => Err(NOT_FRESH.into()),
    }
}

fn write_run(job: &Job, results: &mut Results, _: Shard) -> anyhow::Result<()> {
    let merged = earlier(&results.merged, StageName::Merge).map_err(anyhow::Error::msg)?;
    let built = earlier(&results.hierarchy, StageName::Hierarchy).map_err(anyhow::Error::msg)?;
    write::run(job, merged, built)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_lists_every_stage_once_in_declaration_order() {
        let names: Vec<StageName> = STAGES.iter().map(|stage| stage.name).collect();
        let declared: Vec<StageName> = clap::ValueEnum::value_variants().to_vec();
        assert_eq!(names, declared);
    }
}

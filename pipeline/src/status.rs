//! `pipeline status`: every stage, and every chunk of the strip stage, as done, pending or
//! stale, with the reason, computed from the manifest without doing any work. The same walk
//! names the stage a failed run stopped in.

use std::path::Path;

use crate::config::Config;
use crate::input;
use crate::manifest::Freshness;
use crate::progress::{LogFormat, Progress};
use crate::stage::{chunk, hierarchy, merge, strip, write, Job};
use crate::workdir::WorkDir;

const STAGES: [&str; 5] = ["chunk", "strip", "merge", "hierarchy", "write"];

/// A unit (a stage, or `strip/chunk-N`) and its state.
struct UnitState {
    unit: String,
    state: State,
}

enum State {
    Done,
    Pending(String),
    Stale(String),
}

pub fn status(config_path: &Path) -> anyhow::Result<()> {
    let config = Config::load(config_path)?;
    let progress = Progress::new(LogFormat::Plain);
    let job = Job::new(&config, WorkDir::new(config.work_dir()), &progress);
    println!("work directory {}", job.work.root().display());
    if let Ok(input) = input::peek(&job) {
        println!("{:<20} {}", "input", input.describe());
    }
    for UnitState { unit, state } in unit_states(&job) {
        match state {
            State::Done => println!("{unit:<20} done"),
            State::Pending(reason) => println!("{unit:<20} pending: {reason}"),
            State::Stale(reason) => println!("{unit:<20} stale: {reason}"),
        }
    }
    Ok(())
}

/// The stage of the first unit that is not done: where a failed run stopped.
pub fn first_unfinished_stage(job: &Job) -> Option<String> {
    let first = unit_states(job)
        .into_iter()
        .find(|unit| !matches!(unit.state, State::Done))?;
    let stage = first.unit.split('/').next().unwrap_or_default();
    Some(stage.to_string())
}

fn unit_states(job: &Job) -> Vec<UnitState> {
    let mut states = Vec::new();
    let input = match input::peek(job) {
        Ok(input) => input,
        Err(reason) => return pending_from(states, "chunk", &reason),
    };
    let fingerprint = chunk::fingerprint(job, &input);
    states.push(unit_state(
        "chunk",
        job.freshness(chunk::UNIT, &fingerprint),
    ));
    let Some(chunked) = chunk::fresh_result(job, &fingerprint) else {
        return pending_from(states, "strip", "waits for chunk");
    };
    let mut strip_done = true;
    for index in 0..chunked.chunk_count() {
        let unit = strip::unit(index);
        let state = job.freshness(&unit, &strip::fingerprint(job, &chunked, index));
        strip_done &= state == Freshness::Fresh;
        states.push(unit_state(&unit, state));
    }
    if !strip_done {
        return pending_from(states, "merge", "waits for strip");
    }
    let merge_fingerprint = merge::fingerprint(&strip::digest(job, &chunked));
    states.push(unit_state(
        "merge",
        job.freshness(merge::UNIT, &merge_fingerprint),
    ));
    let Some(merged) = merge::fresh_result(job, &merge_fingerprint) else {
        return pending_from(states, "hierarchy", "waits for merge");
    };
    let hierarchy_fingerprint = hierarchy::fingerprint(&merged);
    let hierarchy_state = job.freshness(hierarchy::UNIT, &hierarchy_fingerprint);
    states.push(unit_state("hierarchy", hierarchy_state));
    let Some(built) = hierarchy::fresh_result(job, &hierarchy_fingerprint) else {
        return pending_from(states, "write", "waits for hierarchy");
    };
    let write_state = job.freshness(write::UNIT, &write::fingerprint(job, &built));
    states.push(unit_state("write", write_state));
    states
}

fn unit_state(unit: &str, freshness: Freshness) -> UnitState {
    let state = match freshness {
        Freshness::Fresh => State::Done,
        Freshness::Pending => State::Pending("never run".into()),
        Freshness::Stale(reason) => State::Stale(reason),
        Freshness::Changed(output) => {
            State::Stale(format!("{output} changed since it was written"))
        }
    };
    UnitState {
        unit: unit.to_string(),
        state,
    }
}

/// `states` followed by `first` and every later stage, pending for `reason`.
fn pending_from(mut states: Vec<UnitState>, first: &str, reason: &str) -> Vec<UnitState> {
    let start = STAGES.iter().position(|s| *s == first).unwrap_or(0);
    states.extend(STAGES[start..].iter().map(|stage| UnitState {
        unit: stage.to_string(),
        state: State::Pending(reason.to_string()),
    }));
    states
}

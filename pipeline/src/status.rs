//! `pipeline status`: every stage of the table, and every chunk of a per-chunk stage, as done, pending or
//! stale, with the reason, computed from the manifest without doing any work. The same walk
//! names the stage a failed run stopped in.

use std::path::Path;

use crate::config::Config;
use crate::input;
use crate::manifest::Freshness;
use crate::progress::{LogFormat, Progress};
use crate::stage::{Job, StageName};
use crate::stages::{Results, STAGES};
use crate::workdir::WorkDir;

/// A unit (a stage, or `strip/chunk-N`), its stage and its state.
struct UnitState {
    stage: StageName,
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
    for UnitState { unit, state, .. } in unit_states(&job) {
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
    Some(first.stage.to_string())
}

/// Every unit of every stage of the table, in order. A stage whose units cannot be known yet
/// stands as one pending unit, and so does every stage after one that is not done.
fn unit_states(job: &Job) -> Vec<UnitState> {
    let mut states = Vec::new();
    let mut results = Results::default();
    let mut blocked: Option<String> = None;
    for stage in &STAGES {
        if let Some(reason) = &blocked {
            states.push(pending(stage.name, reason));
            continue;
        }
        match (stage.units)(job, &results) {
            Ok(units) => states.extend(units.iter().map(|(unit, fingerprint)| {
                unit_state(stage.name, unit, job.freshness(unit, fingerprint))
            })),
            Err(reason) => {
                states.push(pending(stage.name, &reason));
                blocked = Some(reason);
                continue;
            }
        }
        if (stage.fresh)(job, &mut results).is_err() {
            blocked = Some(format!("waits for {}", stage.name));
        }
    }
    states
}

fn unit_state(stage: StageName, unit: &str, freshness: Freshness) -> UnitState {
    let state = match freshness {
        Freshness::Fresh => State::Done,
        Freshness::Pending => State::Pending("never run".into()),
        Freshness::Stale(reason) => State::Stale(reason),
        Freshness::Changed(output) => {
            State::Stale(format!("{output} changed since it was written"))
        }
    };
    UnitState {
        stage,
        unit: unit.to_string(),
        state,
    }
}

/// The whole of `stage`, pending for `reason`.
fn pending(stage: StageName, reason: &str) -> UnitState {
    UnitState {
        stage,
        unit: stage.to_string(),
        state: State::Pending(reason.to_string()),
    }
}

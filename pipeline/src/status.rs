//! `pipeline status`: every stage, and every chunk of the strip stage, as done, pending or
//! stale, with the reason, computed from the manifest without doing any work.

use std::path::Path;

use crate::config::Config;
use crate::input;
use crate::manifest::Freshness;
use crate::progress::{LogFormat, Progress};
use crate::stage::{chunk, hierarchy, merge, strip, write, Job};
use crate::workdir::WorkDir;

pub fn status(config_path: &Path) -> anyhow::Result<()> {
    let config = Config::load(config_path)?;
    let progress = Progress::new(LogFormat::Plain);
    let job = Job::new(&config, WorkDir::new(config.work_dir()), &progress);
    println!("work directory {}", job.work.root().display());
    let input = match input::peek(&job) {
        Ok(input) => input,
        Err(reason) => return pending_from("chunk", &reason),
    };
    let fingerprint = chunk::fingerprint(&job, &input);
    report("chunk", &job.freshness(chunk::UNIT, &fingerprint));
    let Some(chunked) = chunk::fresh_result(&job, &fingerprint) else {
        return pending_from("strip", "waits for chunk");
    };
    let mut strip_done = true;
    for index in 0..chunked.chunk_count() {
        let state = job.freshness(
            &strip::unit(index),
            &strip::fingerprint(&job, &chunked, index),
        );
        strip_done &= state == Freshness::Fresh;
        report(&strip::unit(index), &state);
    }
    if !strip_done {
        return pending_from("merge", "waits for strip");
    }
    let merge_fingerprint = merge::fingerprint(&strip::digest(&job, &chunked));
    report("merge", &job.freshness(merge::UNIT, &merge_fingerprint));
    let Some(merged) = merge::fresh_result(&job, &merge_fingerprint) else {
        return pending_from("hierarchy", "waits for merge");
    };
    let hierarchy_fingerprint = hierarchy::fingerprint(&merged);
    report(
        "hierarchy",
        &job.freshness(hierarchy::UNIT, &hierarchy_fingerprint),
    );
    let Some(built) = hierarchy::fresh_result(&job, &hierarchy_fingerprint) else {
        return pending_from("write", "waits for hierarchy");
    };
    report(
        "write",
        &job.freshness(write::UNIT, &write::fingerprint(&job, &built)),
    );
    Ok(())
}

fn report(unit: &str, state: &Freshness) {
    match state {
        Freshness::Fresh => println!("{unit:<20} done"),
        Freshness::Pending => println!("{unit:<20} pending: never run"),
        Freshness::Stale(reason) => println!("{unit:<20} stale: {reason}"),
    }
}

/// Prints `first` and every later stage as pending for `reason`.
fn pending_from(first: &str, reason: &str) -> anyhow::Result<()> {
    let stages = ["chunk", "strip", "merge", "hierarchy", "write"];
    let start = stages.iter().position(|s| *s == first).unwrap_or(0);
    for stage in &stages[start..] {
        println!("{stage:<20} pending: {reason}");
    }
    Ok(())
}

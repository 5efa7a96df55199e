//! `pipeline status` lists the stage table's units in run order, and says why each is not done.

mod common;

use std::path::{Path, PathBuf};

use common::pipeline;

/// The lines of `pipeline status` after the work directory and input lines, as (unit, state).
fn unit_lines(config: &Path) -> Vec<(String, String)> {
    let output = pipeline(&["status", config.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(0));
    let text = String::from_utf8_lossy(&output.stdout).to_string();
    text.lines()
        .skip(2)
        .map(|line| {
            let (unit, state) = line.split_once(' ').expect("unit and state");
            (unit.to_string(), state.trim_start().to_string())
        })
        .collect()
}

fn expected(units: &[(&str, &str)]) -> Vec<(String, String)> {
    units
        .iter()
        .map(|(unit, state)| (unit.to_string(), state.to_string()))
        .collect()
}

fn job(name: &str) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("pipeline-status-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let config = dir.join("job.toml");
    let body = "[input.generate]\nkind = \"sphere\"\ntriangles = 2000\n\n[output]\n\
                path = \"sphere.rdm\"\n\n[chunk]\nmax_triangles = 800\n";
    std::fs::write(&config, body).expect("write config");
    (dir, config)
}

#[test]
fn status_lists_the_stages_in_run_order_before_during_and_after_a_run() {
    let (dir, config) = job("order");
    let config_arg = config.to_str().unwrap();
    assert_eq!(
        unit_lines(&config),
        expected(&[
            ("chunk", "pending: never run"),
            ("strip", "pending: waits for chunk"),
            ("merge", "pending: waits for chunk"),
            ("hierarchy", "pending: waits for chunk"),
            ("write", "pending: waits for chunk"),
        ])
    );

    let chunk = pipeline(&["run", config_arg, "--stage", "chunk"]);
    assert_eq!(chunk.status.code(), Some(0));
    let after_chunk = unit_lines(&config);
    let chunks = after_chunk.len() - 4;
    assert!(chunks >= 2, "{after_chunk:?}");
    let mut units = vec![("chunk".to_string(), "done".to_string())];
    units.extend((0..chunks).map(|c| (format!("strip/chunk-{c:06}"), "pending: never run".into())));
    units.extend(
        ["merge", "hierarchy", "write"].map(|s| (s.into(), "pending: waits for strip".into())),
    );
    assert_eq!(after_chunk, units);

    assert_eq!(pipeline(&["run", config_arg]).status.code(), Some(0));
    let mut done = vec!["chunk".to_string()];
    done.extend((0..chunks).map(|c| format!("strip/chunk-{c:06}")));
    done.extend(["merge", "hierarchy", "write"].map(String::from));
    let done: Vec<(String, String)> = done.into_iter().map(|u| (u, "done".into())).collect();
    assert_eq!(unit_lines(&config), done);
    std::fs::remove_dir_all(&dir).expect("remove temp dir");
}

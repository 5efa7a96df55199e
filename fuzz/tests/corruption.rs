//! 12,000 corrupted ReduceM files (bit flips, truncations, section swaps, 4,000 of each):
//! opening and tracing each either fails with an error or returns results, never panics or
//! hangs. The runner's watchdog turns a hang into a failure instead of a stuck test.

use std::path::Path;
use std::time::Duration;

use reducem_fuzz::runner::{read_corpus, run_campaign, Inputs, Limits};
use reducem_fuzz::targets::Target;

#[test]
fn corrupted_files_fail_cleanly_or_trace() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let corpus = read_corpus(&root.join("corpus/reducem")).expect("seeds");
    // Each seed meets each corruption kind equally often.
    let cases = 4_000 * corpus.len() as u64;
    let scratch = std::env::temp_dir().join(format!("reducem-corruption-{}", std::process::id()));
    let crashes = scratch.join("crashes");
    let report = run_campaign(
        Target::Reducem,
        corpus,
        Inputs::Corruptions,
        7,
        Limits {
            cases: Some(cases),
            duration: None,
            case_timeout: Duration::from_secs(60),
        },
        &scratch.join("work"),
        &crashes,
    )
    .expect("campaign");
    assert_eq!(report.hang, None, "a corrupted file hung");
    assert!(
        report.panics.is_empty(),
        "{} panicking cases, saved: {:?}",
        report.panicking_cases,
        report.panics
    );
    assert_eq!(report.executions, cases);
    // Both paths ran: some corruptions are caught on open, some files still open and trace.
    assert!(report.rejected > cases / 4, "{report:?}");
    assert!(report.accepted > 100, "{report:?}");
}

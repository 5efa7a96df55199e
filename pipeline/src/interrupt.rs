//! Clean stops on request: SIGUSR1 (Slurm's warning before a time limit, `--signal=B:USR1@…`)
//! and SIGTERM set a flag; stages check it before starting each unit, so a stopped run has
//! recorded every unit it finished and a resubmission resumes from there.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

static REQUESTED: OnceLock<Arc<AtomicBool>> = OnceLock::new();

/// The run stopped because it was asked to; resubmitting it resumes.
#[derive(Debug, thiserror::Error)]
#[error("stopped on request (SIGUSR1 or SIGTERM) after finishing the units in progress; run again to resume")]
pub struct Interrupted;

/// Routes SIGUSR1 and SIGTERM to the stop flag.
pub fn install() -> std::io::Result<()> {
    let flag = REQUESTED.get_or_init(|| Arc::new(AtomicBool::new(false)));
    for signal in [signal_hook::consts::SIGUSR1, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(flag))?;
    }
    Ok(())
}

/// Fails with [`Interrupted`] once a stop was requested.
pub fn check() -> Result<(), Interrupted> {
    match REQUESTED.get() {
        Some(flag) if flag.load(Ordering::Relaxed) => Err(Interrupted),
        _ => Ok(()),
    }
}

//! Stops on request. SIGUSR1 (Slurm's warning before a time limit, `--signal=B:USR1@…`) lets the
//! units in progress finish and be recorded. SIGINT and SIGTERM end the run at its next safe
//! point: stages check the flag before each unit and between the chunks they read; a run that
//! meets none within [`GRACE`] (inside one long unit) is ended by the signal thread itself,
//! after removing this process's temporaries. Either way every unit finished before stays
//! recorded (the manifest is only ever replaced whole) and the same command resumes.

use std::sync::atomic::{AtomicI32, Ordering};
use std::time::Duration;

use signal_hook::consts::{SIGINT, SIGTERM, SIGUSR1};

/// The signal that asked the run to stop, 0 until one did.
static REQUESTED: AtomicI32 = AtomicI32::new(0);

/// How long SIGINT and SIGTERM wait for the run to reach a safe point before ending it.
pub const GRACE: Duration = Duration::from_secs(2);

/// The run stopped because it was asked to; the same command resumes it.
#[derive(Debug, thiserror::Error)]
#[error(
    "interrupted; run the same command again to resume ({}, {})",
    signal_name(*signal),
    if *signal == SIGUSR1 { "after finishing the units in progress" } else { "every finished unit is recorded" }
)]
pub struct Interrupted {
    pub signal: i32,
}

impl Interrupted {
    /// 130 for SIGINT (128 + 2, as shells report Ctrl-C), else 75: try again later.
    pub fn exit_code(&self) -> u8 {
        match self.signal {
            SIGINT => 130,
            _ => reducem::exit_code::TEMPORARY,
        }
    }
}

fn signal_name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "SIGINT",
        SIGTERM => "SIGTERM",
        _ => "SIGUSR1",
    }
}

/// Routes SIGUSR1, SIGINT and SIGTERM to the stop flag, and installs the handler that names a
/// mapped input truncated under the run.
pub fn install() -> std::io::Result<()> {
    reducem_core::signals::install_bus_handler()?;
    let mut signals = signal_hook::iterator::Signals::new([SIGUSR1, SIGINT, SIGTERM])?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            for signal in signals.forever() {
                if signal == SIGUSR1 {
                    let _ =
                        REQUESTED.compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst);
                    continue;
                }
                // A second SIGINT or SIGTERM: the user will not wait.
                if matches!(REQUESTED.swap(signal, Ordering::SeqCst), SIGINT | SIGTERM) {
                    end_now(signal);
                }
                std::thread::spawn(move || {
                    std::thread::sleep(GRACE);
                    end_now(signal)
                });
            }
        })?;
    Ok(())
}

/// Ends the process at once: removes its temporaries and says how to resume.
fn end_now(signal: i32) -> ! {
    reducem_core::signals::remove_own_temporaries();
    let interrupted = Interrupted { signal };
    eprintln!("pipeline: {interrupted}");
    std::process::exit(interrupted.exit_code().into())
}

/// Fails with [`Interrupted`] once a stop was requested.
pub fn check() -> Result<(), Interrupted> {
    match REQUESTED.load(Ordering::SeqCst) {
        0 => Ok(()),
        signal => Err(Interrupted { signal }),
    }
}

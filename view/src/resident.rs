//! The file's resident bytes for the page's overlay, measured on a thread of their own: the
//! measure reads the process's whole memory map (hundreds of milliseconds with gigabytes of the
//! file resident), which on the renderer's thread delayed frames, or the next view's.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use reducem::render::residency;

/// How long a measure is shown before it is taken again.
const INTERVAL: Duration = Duration::from_millis(500);

/// The last measure of a mapping's resident bytes, and the thread that takes the next.
pub struct ResidentBytes {
    shared: Arc<Shared>,
}

struct Shared {
    state: Mutex<State>,
    asked: Condvar,
}

struct State {
    measured: Instant,
    bytes: Option<u64>,
    /// A new measure is asked for and not yet taken.
    asked: bool,
}

impl Shared {
    fn state(&self) -> MutexGuard<'_, State> {
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

impl ResidentBytes {
    /// The resident bytes of the mapping of `path`: measured now, then whenever asked.
    pub fn of(path: PathBuf) -> ResidentBytes {
        let state = State {
            measured: Instant::now(),
            bytes: residency::mapping_rss(&path),
            asked: false,
        };
        let shared = Arc::new(Shared {
            state: Mutex::new(state),
            asked: Condvar::new(),
        });
        let measuring = Arc::clone(&shared);
        let spawned = std::thread::Builder::new()
            .name("residency".into())
            .spawn(move || measure_when_asked(&measuring, &path));
        if let Err(error) = spawned {
            eprintln!("reducem view: cannot start measuring the file's residency: {error}");
        }
        ResidentBytes { shared }
    }

    /// The last measure.
    pub fn last(&self) -> Option<u64> {
        self.shared.state().bytes
    }

    /// Asks for a new measure once the last is [`INTERVAL`] old.
    pub fn refresh_when_due(&self) {
        let mut state = self.shared.state();
        if !state.asked && state.measured.elapsed() >= INTERVAL {
            state.asked = true;
            self.shared.asked.notify_one();
        }
    }
}

/// Measures whenever asked; sleeps otherwise, so an idle viewer costs no CPU.
fn measure_when_asked(shared: &Shared, path: &Path) {
    let mut state = shared.state();
    loop {
        if state.asked {
            drop(state);
            let bytes = residency::mapping_rss(path);
            state = shared.state();
            (state.measured, state.bytes, state.asked) = (Instant::now(), bytes, false);
        } else {
            state = shared.asked.wait(state).unwrap_or_else(|p| p.into_inner());
        }
    }
}

//! When each frame's stages ended, counted from the moment its view arrived: with
//! `REDUCEM_VIEW_STAGES=1` in the environment, one line per frame sent on standard error, so
//! that a frame cycle's time can be split without a profiler.

use std::sync::OnceLock;
use std::time::Instant;

use crate::views::FrameHeader;

/// The stages a frame has passed, each with the moment it ended.
pub struct Stages {
    received: Instant,
    ends: Vec<(&'static str, Instant)>,
}

impl Stages {
    /// A frame of the view that arrived at `received`.
    pub fn since(received: Instant) -> Stages {
        Stages {
            received,
            ends: Vec::with_capacity(8),
        }
    }

    /// The stage `name` ends now.
    pub fn end(&mut self, name: &'static str) {
        self.ends.push((name, Instant::now()));
    }

    /// The stages of the frame `header` describes on standard error when logging is on:
    /// milliseconds since the view arrived.
    pub fn log(&self, header: &FrameHeader) {
        if !logging() {
            return;
        }
        let ms = |at: Instant| at.duration_since(self.received).as_secs_f64() * 1e3;
        let stages: Vec<String> = self
            .ends
            .iter()
            .map(|&(name, at)| format!("{name} {:.1}", ms(at)))
            .collect();
        eprintln!(
            "reducem view: stages ms: view {} {}x{} spp {}: {} (rays {:.1})",
            header.generation,
            header.width,
            header.height,
            header.spp,
            stages.join(", "),
            header.seconds * 1e3
        );
    }
}

/// On standard error when logging is on: how long the renderer waited for the view `generation`
/// that arrived at `received` since its last frame was sent at `idle_since` (0 when the view
/// came while it was busy): the closed loop's time on the way to the page and back.
pub fn log_idle(generation: u64, received: Instant, idle_since: Option<Instant>) {
    if let Some(idle_since) = idle_since.filter(|_| logging()) {
        let idle = received.saturating_duration_since(idle_since);
        let ms = idle.as_secs_f64() * 1e3;
        eprintln!("reducem view: idle ms before view {generation}: {ms:.1}");
    }
}

fn logging() -> bool {
    static LOGGING: OnceLock<bool> = OnceLock::new();
    *LOGGING.get_or_init(|| std::env::var_os("REDUCEM_VIEW_STAGES").is_some_and(|v| v != "0"))
}

//! Progress for people and for logs: indicatif bars with per-stage ETA on a terminal, periodic
//! plain lines otherwise (cron mails, batch logs), or one JSON object per line.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// `--log-format`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LogFormat {
    /// Bars on a terminal, plain lines otherwise.
    Auto,
    /// Plain log lines, progress every 10 s per stage.
    Plain,
    /// One JSON object per line; the last one is the outcome (error or summary).
    Json,
}

/// How often a plain or JSON log reports progress within a stage.
const LOG_INTERVAL: Duration = Duration::from_secs(10);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Bars,
    Plain,
    Json,
}

/// The run's reporter.
pub struct Progress {
    mode: Mode,
}

impl Progress {
    pub fn new(format: LogFormat) -> Progress {
        let mode = match format {
            LogFormat::Auto if std::io::stderr().is_terminal() => Mode::Bars,
            LogFormat::Auto | LogFormat::Plain => Mode::Plain,
            LogFormat::Json => Mode::Json,
        };
        Progress { mode }
    }

    /// A one-off message about `stage`.
    pub fn event(&self, stage: &str, event: &str, message: &str) {
        match self.mode {
            Mode::Json => eprintln!(
                "{}",
                serde_json::json!({"time": unix_time(), "stage": stage, "event": event, "message": message})
            ),
            Mode::Bars | Mode::Plain => eprintln!("pipeline: {stage}: {message}"),
        }
    }

    /// The final line of a successful run: plain text, or the JSON summary of
    /// [`crate::outcome::summary_json`] with the output's counts.
    pub fn summary(&self, seconds: f64, counts: Option<serde_json::Value>) {
        match self.mode {
            Mode::Json => {
                let counts = counts.unwrap_or(serde_json::Value::Null);
                eprintln!("{}", crate::outcome::summary_json(seconds, counts));
            }
            Mode::Bars | Mode::Plain => eprintln!("pipeline: run: finished in {seconds:.1} s"),
        }
    }

    /// Starts reporting a stage of `total` units (chunks, triangles, bytes).
    pub fn stage(&self, stage: &str, total: u64, unit: &str) -> StageProgress {
        self.event(stage, "start", &format!("{total} {unit} to do"));
        let bar = (self.mode == Mode::Bars).then(|| {
            let bar = ProgressBar::new(total);
            let template =
                format!("{stage:>9} [{{bar:30}}] {{pos}}/{{len}} {unit} {{elapsed}} eta {{eta}}");
            bar.set_style(
                ProgressStyle::with_template(&template)
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar
        });
        StageProgress {
            mode: self.mode,
            stage: stage.to_string(),
            unit: unit.to_string(),
            total,
            done: AtomicU64::new(0),
            started: Instant::now(),
            last_log: Mutex::new(Instant::now()),
            bar,
        }
    }
}

/// Progress of one stage; `advance` may be called from any thread.
pub struct StageProgress {
    mode: Mode,
    stage: String,
    unit: String,
    total: u64,
    done: AtomicU64,
    started: Instant,
    last_log: Mutex<Instant>,
    bar: Option<ProgressBar>,
}

impl StageProgress {
    pub fn advance(&self, units: u64) {
        let done = self.done.fetch_add(units, Ordering::Relaxed) + units;
        if let Some(bar) = &self.bar {
            bar.set_position(done);
            return;
        }
        let Ok(mut last) = self.last_log.lock() else {
            return;
        };
        if last.elapsed() < LOG_INTERVAL {
            return;
        }
        *last = Instant::now();
        let elapsed = self.started.elapsed().as_secs_f64();
        let eta = elapsed / done.max(1) as f64 * self.total.saturating_sub(done) as f64;
        let percent = 100.0 * done as f64 / self.total.max(1) as f64;
        let message = format!(
            "{done}/{} {} ({percent:.0}%), eta {eta:.0} s",
            self.total, self.unit
        );
        self.log("progress", &message, Some((done, eta)));
    }

    pub fn finish(&self, summary: &str) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
        let message = format!(
            "done in {:.1} s{summary}",
            self.started.elapsed().as_secs_f64()
        );
        self.log("done", &message, None);
    }

    fn log(&self, event: &str, message: &str, progress: Option<(u64, f64)>) {
        match self.mode {
            Mode::Json => {
                let mut line = serde_json::json!({
                    "time": unix_time(), "stage": self.stage, "event": event, "message": message,
                    "elapsed_s": self.started.elapsed().as_secs_f64(),
                });
                if let Some((done, eta)) = progress {
                    line["done"] = done.into();
                    line["total"] = self.total.into();
                    line["eta_s"] = eta.into();
                }
                eprintln!("{line}");
            }
            Mode::Bars | Mode::Plain => eprintln!("pipeline: {}: {message}", self.stage),
        }
    }
}

pub fn unix_time() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

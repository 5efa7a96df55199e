//! Progress for people and for logs: indicatif bars with per-stage ETA on a terminal, periodic
//! plain lines otherwise (cron mails, batch logs), one JSON object per line, or reports handed
//! to a [`ProgressSink`] (the Python package's `logging` and progress callback).

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

use crate::time::unix_time;

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

/// One report of a run, as a [`ProgressSink`] receives it.
pub struct Report<'a> {
    /// A stage's name, or `run` for the run as a whole.
    pub stage: &'a str,
    /// `start`, `progress` and `done` within a stage; `skip`, `clean` and `finished` for the run;
    /// the stages' own one-off events otherwise.
    pub event: &'a str,
    /// The line a plain log would print after `pipeline: STAGE: `.
    pub message: &'a str,
    /// For a stage's `start`, `progress` and `done`: units done, units in all, and their name.
    pub units: Option<Units<'a>>,
}

/// How far a stage is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Units<'a> {
    pub done: u64,
    pub total: u64,
    pub name: &'a str,
}

/// Receives a run's reports instead of stderr; called from any of the run's threads, at a
/// stage's start, after each unit it finishes (few: chunks, sections) in counting order, and at
/// its end.
pub trait ProgressSink: Send + Sync {
    fn report(&self, report: &Report<'_>);
}

/// The run's reporter.
pub struct Progress {
    mode: Mode,
    /// When set, every report goes here and nothing is printed.
    sink: Option<Arc<dyn ProgressSink>>,
}

impl Progress {
    pub fn new(format: LogFormat) -> Progress {
        let mode = match format {
            LogFormat::Auto if std::io::stderr().is_terminal() => Mode::Bars,
            LogFormat::Auto | LogFormat::Plain => Mode::Plain,
            LogFormat::Json => Mode::Json,
        };
        Progress { mode, sink: None }
    }

    /// A reporter that hands every report to `sink` and prints nothing.
    pub fn to_sink(sink: Arc<dyn ProgressSink>) -> Progress {
        Progress {
            mode: Mode::Plain,
            sink: Some(sink),
        }
    }

    /// A one-off message about `stage`.
    pub fn event(&self, stage: &str, event: &str, message: &str) {
        self.report(stage, event, message, None);
    }

    fn report(&self, stage: &str, event: &str, message: &str, units: Option<Units<'_>>) {
        if let Some(sink) = &self.sink {
            let report = Report {
                stage,
                event,
                message,
                units,
            };
            sink.report(&report);
            return;
        }
        match self.mode {
            Mode::Json => eprintln!(
                "{}",
                serde_json::json!({"time": unix_time(), "stage": stage, "event": event, "message": message})
            ),
            Mode::Bars | Mode::Plain => eprintln!("pipeline: {stage}: {message}"),
        }
    }

    /// The final line of a successful run: plain text, or the JSON summary of
    /// [`crate::outcome_json::summary_json`] with the output's counts.
    pub fn summary(&self, seconds: f64, counts: Option<serde_json::Value>) {
        if self.sink.is_some() {
            self.event("run", "finished", &format!("finished in {seconds:.1} s"));
            return;
        }
        match self.mode {
            Mode::Json => {
                let counts = counts.unwrap_or(serde_json::Value::Null);
                eprintln!("{}", crate::outcome_json::summary_json(seconds, counts));
            }
            Mode::Bars | Mode::Plain => eprintln!("pipeline: run: finished in {seconds:.1} s"),
        }
    }

    /// Starts reporting a stage of `total` units (chunks, triangles, bytes).
    pub fn stage(&self, stage: &str, total: u64, unit: &str) -> StageProgress {
        let units = Units {
            done: 0,
            total,
            name: unit,
        };
        let message = format!("{total} {unit} to do");
        self.report(stage, "start", &message, Some(units));
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
            sink: self.sink.clone(),
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
    sink: Option<Arc<dyn ProgressSink>>,
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
        if let Some(sink) = &self.sink {
            if units == 0 {
                return;
            }
            // Counted and reported under the lock, so that a sink sees the count go up in order.
            let _in_order = self.last_log.lock();
            let done = self.done.fetch_add(units, Ordering::Relaxed) + units;
            let message = format!("{done}/{} {}", self.total, self.unit);
            self.report_to(sink.as_ref(), "progress", &message, done);
            return;
        }
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

    fn report_to(&self, sink: &dyn ProgressSink, event: &str, message: &str, done: u64) {
        let units = Units {
            done,
            total: self.total,
            name: &self.unit,
        };
        sink.report(&Report {
            stage: &self.stage,
            event,
            message,
            units: Some(units),
        });
    }

    fn log(&self, event: &str, message: &str, progress: Option<(u64, f64)>) {
        if let Some(sink) = &self.sink {
            let done = self.done.load(Ordering::Relaxed);
            self.report_to(sink.as_ref(), event, message, done);
            return;
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Keeps every report as `STAGE EVENT DONE/TOTAL UNIT`.
    #[derive(Default)]
    struct Recorder(Mutex<Vec<String>>);

    impl ProgressSink for Recorder {
        fn report(&self, report: &Report<'_>) {
            let units = report.units.map_or(String::new(), |units| {
                format!(" {}/{} {}", units.done, units.total, units.name)
            });
            let entry = format!("{} {}{units}", report.stage, report.event);
            self.0.lock().unwrap().push(entry);
        }
    }

    #[test]
    fn a_sink_receives_every_report_with_its_units() {
        let recorder = Arc::new(Recorder::default());
        let progress = Progress::to_sink(recorder.clone());
        let stage = progress.stage("strip", 2, "chunks");
        stage.advance(0);
        stage.advance(1);
        stage.advance(1);
        stage.finish("");
        progress.event("run", "clean", "removed work");
        progress.summary(1.0, None);
        let expected = [
            "strip start 0/2 chunks",
            "strip progress 1/2 chunks",
            "strip progress 2/2 chunks",
            "strip done 2/2 chunks",
            "run clean",
            "run finished",
        ];
        assert_eq!(*recorder.0.lock().unwrap(), expected);
    }
}

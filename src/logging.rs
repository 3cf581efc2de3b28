//! Logging through `tracing` (issue 14 item 2).
//!
//! The library emits `tracing` events (`info!` for what a run does, `warn!` for what a user should
//! look at, `debug!` for detail); the command line installs [`init`]'s subscriber, which
//! - prints events at the chosen level on stderr through [`crate::io::progress::println`], so lines
//!   and progress bars do not smear: `-q` warnings and errors only, default info, `-v` debug,
//!   `-vv` trace; warnings read `warning: …`, errors `error: …`;
//! - copies every event of level debug or above that a run's own thread emits into that run's
//!   `DIR/log.txt` ([`RunFile`], set up by [`crate::kinds::RunLog`]), whatever the console level.
//!
//! The lines a run reports through its log callback are written to `log.txt` by
//! [`crate::kinds::RunLog`] itself (so a library user without a subscriber still gets the file) and
//! sent to the console as events of target [`RUN_TARGET`], which the file copy skips.

use std::cell::RefCell;
use std::io::Write;
use std::sync::{Arc, Mutex};
use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::layer::{Context, Layer};
use tracing_subscriber::prelude::*;

/// Prefix of a run log line that is detail (per-detection lines of a compact run, issue 25):
/// `crate::kinds::RunLog` writes it to `log.txt` without the prefix and shows it on the console at
/// `-v` only (a debug event).
pub const DETAIL: &str = "detail: ";

/// Target of the events that carry a run's log lines (already in `log.txt`).
pub const RUN_TARGET: &str = "sinterdem::kinds";

/// How much the console shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verbosity {
    /// Warnings and errors only (`-q`).
    Quiet,
    /// Info and above (default).
    Normal,
    /// Debug and above (`-v`).
    Verbose,
    /// Everything (`-vv`).
    Trace,
}

impl Verbosity {
    /// From the `-q` flag and the number of `-v`.
    pub fn from_flags(quiet: bool, verbose: u8) -> Self {
        match (quiet, verbose) {
            (true, _) => Verbosity::Quiet,
            (false, 0) => Verbosity::Normal,
            (false, 1) => Verbosity::Verbose,
            _ => Verbosity::Trace,
        }
    }

    fn max_level(self) -> Level {
        match self {
            Verbosity::Quiet => Level::WARN,
            Verbosity::Normal => Level::INFO,
            Verbosity::Verbose => Level::DEBUG,
            Verbosity::Trace => Level::TRACE,
        }
    }
}

thread_local! {
    static RUN_FILE: RefCell<Vec<Arc<Mutex<std::fs::File>>>> = const { RefCell::new(Vec::new()) };
}

/// While alive, events of this thread also go to a run's `log.txt` (nested runs: the innermost).
pub struct RunFile {
    _private: (),
}

impl RunFile {
    pub fn enter(file: Arc<Mutex<std::fs::File>>) -> RunFile {
        RUN_FILE.with(|f| f.borrow_mut().push(file));
        RunFile { _private: () }
    }
}

impl Drop for RunFile {
    fn drop(&mut self) {
        RUN_FILE.with(|f| {
            f.borrow_mut().pop();
        });
    }
}

/// The message of an event with its other fields as `key=value`.
struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let s = format!("{value:?}");
            self.0 = if self.0.is_empty() { s } else { format!("{s} {}", self.0) };
        } else {
            self.0.push_str(&format!("{}{}={value:?}", if self.0.is_empty() { "" } else { " " }, field.name()));
        }
    }
}

/// The line of an event as a user reads it: `warning: …`, `error: …`, or the message alone.
pub fn line_of(level: Level, message: &str) -> String {
    let strip = |p: &str| message.strip_prefix(p).unwrap_or(message).to_string();
    match level {
        Level::ERROR => format!("error: {}", strip("error: ")),
        Level::WARN => format!("warning: {}", strip("warning: ")),
        _ => message.to_string(),
    }
}

/// Where the events a user should see go: the command line's stderr, or an embedding's sink.
pub type Sink = Box<dyn Fn(Level, &str) + Send + Sync>;

struct SinterdemLayer {
    console: Level,
    /// Receives (level, line) instead of stderr (the Python package: `logging` and `warnings`).
    sink: Option<Sink>,
}

impl<S: Subscriber> Layer<S> for SinterdemLayer {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let meta = event.metadata();
        let level = *meta.level();
        let to_console = level <= self.console;
        let to_file = level <= Level::DEBUG && meta.target() != RUN_TARGET;
        if !to_console && !to_file {
            return;
        }
        let mut m = Message(String::new());
        event.record(&mut m);
        let line = line_of(level, &m.0);
        if to_file {
            RUN_FILE.with(|f| {
                if let Some(file) = f.borrow().last() {
                    let mut g = file.lock().unwrap_or_else(|e| e.into_inner());
                    let _ = writeln!(g, "{line}");
                }
            });
        }
        if to_console {
            match &self.sink {
                Some(sink) => sink(level, &line),
                None => crate::io::progress::println(&line),
            }
        }
    }
}

/// Installs the subscriber of the command line (module docs). A second call does nothing.
pub fn init(v: Verbosity) {
    let layer = SinterdemLayer { console: v.max_level(), sink: None };
    let _ = tracing_subscriber::registry().with(layer).try_init();
}

/// Installs the subscriber of an embedding (the Python package): events of level `level` and
/// above go to `sink(level, line)` (the line as [`line_of`] writes it), and a run's events are
/// copied to its `log.txt` as with [`init`]. Returns false when a subscriber was already set.
pub fn init_with_sink(level: Level, sink: Sink) -> bool {
    let layer = SinterdemLayer { console: level, sink: Some(sink) };
    tracing_subscriber::registry().with(layer).try_init().is_ok()
}

//! Progress bar with simulated time and ETA on a terminal; silent when stderr is not a terminal
//! or `CI` is set.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;

/// A progress bar over simulated time [s].
pub struct Progress {
    bar: Option<ProgressBar>,
    end: f64,
}

impl Progress {
    /// `enabled = false` or a non-terminal stderr gives a silent bar.
    pub fn new(end_time: f64, enabled: bool) -> Self {
        let on = enabled && std::io::stderr().is_terminal() && std::env::var_os("CI").is_none();
        let bar = on.then(|| {
            let b = ProgressBar::with_draw_target(Some(1_000_000), ProgressDrawTarget::stderr());
            b.set_style(
                ProgressStyle::with_template("{bar:40.cyan/blue} {percent:>3}% {msg} [elapsed {elapsed_precise}, ETA {eta_precise}]")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        Progress { bar, end: end_time }
    }

    /// Reports simulated time `t` [s].
    pub fn set(&self, t: f64, extra: &str) {
        if let Some(b) = &self.bar {
            b.set_position(((t / self.end).clamp(0.0, 1.0) * 1e6) as u64);
            b.set_message(format!("t = {} / {} {extra}", fmt_time(t), fmt_time(self.end)));
        }
    }

    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// Human-readable time: s, min or h.
pub fn fmt_time(t: f64) -> String {
    if t < 120.0 {
        format!("{t:.3} s")
    } else if t < 7200.0 {
        format!("{:.2} min", t / 60.0)
    } else {
        format!("{:.2} h", t / 3600.0)
    }
}

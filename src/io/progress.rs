//! The terminal progress bar over simulated time, with an ETA that does not lie, and the one
//! place that prints log lines to stderr ([`println`]) so that lines and bars do not smear.
//!
//! - Silent when stderr is not a terminal or `CI` is set (logs in CI stay plain lines).
//! - Every bar is drawn through one [`indicatif::MultiProgress`]; [`println`] suspends the bars,
//!   prints the line and redraws them below it, so a log line never lands inside a bar.
//! - The ETA ([`Eta`]) comes from quantities that progress evenly: the steps left at the current
//!   Δt times the recent wall time per step, and, while Δt grows (compact and pair runs grow it by
//!   orders of magnitude), the logarithm of the simulated time; the smaller of the two. It reads
//!   "ETA unknown" until 2 s and 5 steps have passed, and whenever the estimate is not finite or
//!   above 10⁶ s.

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{LazyLock, Mutex};
use std::time::Instant;

static MULTI: LazyLock<MultiProgress> = LazyLock::new(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr()));

/// Whether bars may be drawn: stderr is a terminal and `CI` is not set.
pub fn bars_allowed() -> bool {
    std::io::stderr().is_terminal() && std::env::var_os("CI").is_none()
}

/// Adds a bar to the common draw target (every bar of the process goes through it).
pub fn add_bar(bar: ProgressBar) -> ProgressBar {
    MULTI.add(bar)
}

/// Prints one line on stderr above any bars (bars are suspended and redrawn).
pub fn println(line: &str) {
    MULTI.suspend(|| eprintln!("{line}"));
}

/// ETA of a run over simulated time (module docs).
#[derive(Debug, Clone)]
pub struct Eta {
    end: f64,
    start_wall: f64,
    start_t: Option<f64>,
    last: Option<(f64, f64)>,
    /// Smallest positive Δt seen [s].
    dt_min: f64,
    /// Last Δt [s] and the recent wall time per step [s] (exponential average).
    dt_last: f64,
    wall_per_step: f64,
    steps: u64,
    /// Exponential average of ln(Δt/Δt_previous): positive while the step grows.
    growth: f64,
}

impl Eta {
    pub fn new(end: f64, wall_now: f64) -> Self {
        Eta { end, start_wall: wall_now, start_t: None, last: None, dt_min: f64::INFINITY, dt_last: f64::NAN, wall_per_step: f64::NAN, steps: 0, growth: 0.0 }
    }

    /// Records that simulated time `t` [s] was reached at wall time `wall` [s].
    pub fn record(&mut self, t: f64, wall: f64) {
        match self.last {
            None => {
                self.start_t = Some(t);
                self.start_wall = wall;
            }
            Some((t0, w0)) if t > t0 => {
                let (dt, dw) = (t - t0, (wall - w0).max(0.0));
                self.steps += 1;
                if self.dt_last.is_finite() && self.dt_last > 0.0 {
                    self.growth = 0.8 * self.growth + 0.2 * (dt / self.dt_last).ln();
                }
                self.dt_last = dt;
                self.dt_min = self.dt_min.min(dt);
                self.wall_per_step = if self.wall_per_step.is_finite() { 0.8 * self.wall_per_step + 0.2 * dw } else { dw };
            }
            _ => {}
        }
        self.last = Some((t, wall));
    }

    /// Seconds of wall time left, or `None` when no honest estimate exists yet.
    pub fn remaining(&self) -> Option<f64> {
        let (t, wall) = self.last?;
        let elapsed = wall - self.start_wall;
        if self.steps < 5 || elapsed < 2.0 || t >= self.end {
            return None;
        }
        // steps left at the current Δt
        let by_steps = (self.end - t) / self.dt_last * self.wall_per_step;
        let mut est = by_steps;
        // a step capped at dt_max (or at an output time) no longer grows: the steps left at the
        // current Δt are then the estimate; the log-of-time estimate, used while Δt still grows,
        // would read "0s" with most of a capped run left (issue 25)
        if self.dt_last > 2.0 * self.dt_min && self.growth > 0.02 {
            // Δt grows: the logarithm of the simulated time advances evenly
            let t_ref = self.dt_min;
            let t0 = self.start_t.unwrap_or(0.0).max(0.0) + t_ref;
            let (l0, l, le) = ((t0).ln(), (t + t_ref).ln(), (self.end + t_ref).ln());
            if l > l0 {
                est = est.min(elapsed * (le - l) / (l - l0));
            }
        }
        (est.is_finite() && (0.0..1e6).contains(&est)).then_some(est)
    }

    /// "ETA 1m 23s" or "ETA unknown".
    pub fn label(&self) -> String {
        match self.remaining() {
            Some(s) => format!("ETA {}", fmt_wall(s)),
            None => "ETA unknown".into(),
        }
    }
}

/// Wall time as `2h 03m`, `4m 05s` or `12s`.
pub fn fmt_wall(s: f64) -> String {
    let s = s.round() as u64;
    if s >= 3600 {
        format!("{}h {:02}m", s / 3600, (s % 3600) / 60)
    } else if s >= 60 {
        format!("{}m {:02}s", s / 60, s % 60)
    } else {
        format!("{s}s")
    }
}

/// Simulated time and end time [s] of the last enabled [`Progress`] (f64 bits; NaN: none).
static LATEST: [AtomicU64; 2] = [AtomicU64::new(0x7ff8_0000_0000_0000), AtomicU64::new(0x7ff8_0000_0000_0000)];

fn publish(t: f64, end: f64) {
    LATEST[0].store(t.to_bits(), Ordering::Relaxed);
    LATEST[1].store(end.to_bits(), Ordering::Relaxed);
}

/// The simulated time and end time [s] last reported by a progress bar that was enabled
/// (whether drawn or not): for embeddings that draw their own progress (the Python package's
/// plain line in Jupyter, where stderr is not a terminal).
pub fn latest() -> Option<(f64, f64)> {
    let (t, end) = (f64::from_bits(LATEST[0].load(Ordering::Relaxed)), f64::from_bits(LATEST[1].load(Ordering::Relaxed)));
    (t.is_finite() && end.is_finite()).then_some((t, end))
}

/// The bar's template: a 24-column bar, the percentage and the message cut to the terminal's
/// width (`wide_msg`), so that the bar is one line at any width from 40 columns.
pub const BAR_TEMPLATE: &str = "{bar:24.cyan/blue} {percent:>3}% {wide_msg}";

/// A progress bar over simulated time [s].
pub struct Progress {
    bar: Option<ProgressBar>,
    /// Publish the simulated time for [`latest`] (an enabled bar, drawn or not).
    report: bool,
    end: f64,
    clock: Instant,
    eta: Mutex<Eta>,
}

impl Progress {
    /// `enabled = false` or a non-terminal stderr gives a silent bar.
    pub fn new(end_time: f64, enabled: bool) -> Self {
        let bar = (enabled && bars_allowed()).then(|| {
            let b = add_bar(ProgressBar::new(1_000_000));
            b.set_style(
                // one line that fits the terminal (issue 39: the 40-column bar and its text wrapped
                // at 80 and 120 columns): a 24-column bar, then the text cut to the width left
                // (`wide_msg`), most important first: ETA, simulated time, elapsed wall time
                ProgressStyle::with_template(BAR_TEMPLATE).unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        });
        if enabled {
            publish(0.0, end_time);
        }
        Progress { bar, report: enabled, end: end_time, clock: Instant::now(), eta: Mutex::new(Eta::new(end_time, 0.0)) }
    }

    /// Reports simulated time `t` [s].
    pub fn set(&self, t: f64, extra: &str) {
        if self.report {
            publish(t, self.end);
        }
        if let Some(b) = &self.bar {
            let label = {
                let mut eta = self.eta.lock().unwrap_or_else(|e| e.into_inner());
                eta.record(t, self.clock.elapsed().as_secs_f64());
                eta.label()
            };
            b.set_position(((t / self.end).clamp(0.0, 1.0) * 1e6) as u64);
            let extra = if extra.trim().is_empty() { String::new() } else { format!(", {}", extra.trim()) };
            b.set_message(format!("{label} · t = {}{extra} · elapsed {}", fmt_progress(t, self.end), fmt_wall(self.clock.elapsed().as_secs_f64())));
        }
    }

    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
            MULTI.remove(b);
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.finish();
    }
}

/// The bar's time and end time in one unit (issue 25): seconds as in the log lines
/// ([`crate::units::fmt_seconds`]), and both in minutes or hours when the end is 2 min or more:
/// `111.4 s / 5000 s (1.86 / 83.33 min)`.
pub fn fmt_progress(t: f64, end: f64) -> String {
    let s = format!("{} / {}", crate::units::fmt_seconds(t), crate::units::fmt_seconds(end));
    if end >= 7200.0 {
        format!("{s} ({:.2} / {:.2} h)", t / 3600.0, end / 3600.0)
    } else if end >= 120.0 {
        format!("{s} ({:.2} / {:.2} min)", t / 60.0, end / 60.0)
    } else {
        s
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eta_is_unknown_early_and_exact_for_a_constant_step() {
        let mut e = Eta::new(100.0, 0.0);
        // 1 s of simulated time per 0.5 s of wall
        for k in 0..=3 {
            e.record(k as f64, 0.5 * k as f64);
        }
        assert_eq!(e.label(), "ETA unknown", "three steps, 1.5 s");
        for k in 4..=20 {
            e.record(k as f64, 0.5 * k as f64);
        }
        let r = e.remaining().unwrap();
        assert!((r - 40.0).abs() < 1e-9, "{r}");
        assert_eq!(e.label(), "ETA 40s");
    }

    #[test]
    fn eta_follows_the_log_of_time_while_the_step_grows() {
        // Δt grows by 1.5 per step from 1e-12 s to the end 1e3 s, each step 0.1 s of wall: the
        // run takes n steps; the steps-at-current-Δt estimate would say 1e14 s early on
        let end = 1e3;
        let (mut t, mut dt, mut n) = (0.0f64, 1e-12, 0);
        while t < end {
            t = (t + dt).min(end);
            dt *= 1.5;
            n += 1;
        }
        let mut e = Eta::new(end, 0.0);
        let (mut t, mut dt) = (0.0, 1e-12);
        e.record(0.0, 0.0);
        for k in 1..=n / 3 {
            t += dt;
            dt *= 1.5;
            e.record(t, 0.1 * k as f64);
        }
        let truth = 0.1 * (n - n / 3) as f64;
        let r = e.remaining().unwrap();
        assert!(r > 0.3 * truth && r < 3.0 * truth, "ETA {r} s against {truth} s");
    }

    #[test]
    fn eta_follows_the_steps_left_once_the_step_is_capped() {
        // Δt grows by 1.5 from 1e-6 s to dt_max = 10 s, then stays there up to 5000 s (the
        // copper compact's step control); each step 0.01 s of wall. At half the run the truth is
        // the capped steps left times 0.01 s; the log-of-time estimate alone said about 0.2 s.
        let (end, dt_max, wall_step) = (5000.0, 10.0, 0.01);
        let mut e = Eta::new(end, 0.0);
        let (mut t, mut dt, mut k) = (0.0f64, 1e-6, 0u32);
        e.record(0.0, 0.0);
        while t < 0.5 * end {
            t += dt;
            dt = (dt * 1.5).min(dt_max);
            k += 1;
            e.record(t, wall_step * k as f64);
        }
        let truth = (end - t) / dt_max * wall_step;
        let r = e.remaining().unwrap();
        assert!((r - truth).abs() < 0.05 * truth, "ETA {r} s against {truth} s");
    }

    #[test]
    fn the_bar_reads_one_time_unit() {
        assert_eq!(fmt_progress(111.397, 5000.0), "111.4 s / 5000 s (1.86 / 83.33 min)");
        assert_eq!(fmt_progress(4700.0, 11580.0), "4700 s / 11580 s (1.31 / 3.22 h)");
        assert_eq!(fmt_progress(1.5, 60.0), "1.5 s / 60 s");
    }

    #[test]
    fn absurd_estimates_read_unknown() {
        let mut e = Eta::new(1e9, 0.0);
        for k in 0..10 {
            e.record(k as f64 * 1e-3, k as f64);
        }
        assert_eq!(e.label(), "ETA unknown");
    }
}

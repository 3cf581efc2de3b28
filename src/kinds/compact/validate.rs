//! Validation of a checkpoint before a run resumes from it (issue 16): a checkpoint is input like
//! a case file, and gets the same ranges and invariants — indices in range, times finite and
//! ordered, the step in (0, dt_max], the state finite — so that a damaged or edited file ends in a
//! [`ConfigError`] naming the entry instead of a panic, a NaN or a run that never finishes.

use super::Checkpoint;
use crate::config::ranges;
use crate::coupled::Settings;
use crate::error::{ConfigError, fmt_value};

/// Largest step counter a checkpoint may carry (no run takes 10¹² steps).
pub const MAX_CHECKPOINT_STEP: u64 = 1_000_000_000_000;

fn out_of_range(key: String, value: f64, range: String, unit: &str) -> ConfigError {
    ConfigError::OutOfRange { key, value, range, unit: unit.into() }
}

fn finite(key: impl FnOnce() -> String, v: f64, unit: &str) -> Result<(), ConfigError> {
    if v.is_finite() { Ok(()) } else { Err(out_of_range(key(), v, "finite".into(), unit)) }
}

fn ranged(table_key: &str, key: impl FnOnce() -> String, v: f64) -> Result<(), ConfigError> {
    let r = ranges::lookup(table_key).expect("range table entry");
    if r.contains(v) { Ok(()) } else { Err(out_of_range(key(), v, r.describe(), r.unit)) }
}

impl Checkpoint {
    /// Checks the checkpoint against its case: `n` particles, the case's step-control `settings`.
    pub fn validate(&self, n: usize, s: &Settings) -> Result<(), ConfigError> {
        let count = |key: &str, len: usize, want: usize, what: &str| -> Result<(), ConfigError> {
            if len == want {
                Ok(())
            } else {
                Err(ConfigError::inconsistent(format!("checkpoint.{key}"), format!("has {len} entries, the case has {want} {what}")))
            }
        };
        // times and step
        if !(self.t.is_finite() && self.t >= 0.0 && self.t <= s.end) {
            return Err(out_of_range("checkpoint.t".into(), self.t, format!("[0, {}] (time.end)", fmt_value(s.end)), "s"));
        }
        if !(self.dt.is_finite() && self.dt > 0.0 && self.dt <= s.dt_max) {
            return Err(out_of_range("checkpoint.dt".into(), self.dt, format!("(0, {}] (time.dt_max)", fmt_value(s.dt_max)), "s"));
        }
        if self.step > MAX_CHECKPOINT_STEP {
            return Err(out_of_range("checkpoint.step".into(), self.step as f64, format!("[0, {}]", fmt_value(MAX_CHECKPOINT_STEP as f64)), "1"));
        }
        if self.rejected > MAX_CHECKPOINT_STEP {
            return Err(out_of_range("checkpoint.rejected".into(), self.rejected as f64, format!("[0, {}]", fmt_value(MAX_CHECKPOINT_STEP as f64)), "1"));
        }
        // particles
        count("position", self.position.len(), n, "particles")?;
        count("temperature", self.temperature.len(), n, "particles")?;
        count("rotation", self.rotation.len(), n, "particles")?;
        for (i, x) in self.position.iter().enumerate() {
            for (a, &v) in x.iter().enumerate() {
                ranged("particles.position", || format!("checkpoint.position[{i}][{a}]"), v)?;
            }
        }
        for (i, &t) in self.temperature.iter().enumerate() {
            ranged("particles.initial_temperature", || format!("checkpoint.temperature[{i}]"), t)?;
        }
        for (i, x) in self.rotation.iter().enumerate() {
            for (a, &v) in x.iter().enumerate() {
                finite(|| format!("checkpoint.rotation[{i}][{a}]"), v, "rad")?;
            }
        }
        // contacts
        let m = self.pairs.len();
        count("contacts", self.contacts.len(), m, "pairs (checkpoint.pairs)")?;
        count("dl_bar", self.dl_bar.len(), m, "pairs (checkpoint.pairs)")?;
        count("substeps", self.substeps.len(), m, "pairs (checkpoint.pairs)")?;
        if !self.dose.is_empty() {
            count("dose", self.dose.len(), m, "pairs (checkpoint.pairs)")?;
        }
        let mut seen = std::collections::HashSet::with_capacity(m);
        for (k, &[i, j]) in self.pairs.iter().enumerate() {
            if !(i < j && (j as usize) < n) {
                return Err(ConfigError::inconsistent(
                    format!("checkpoint.pairs[{k}]"),
                    format!("[{i}, {j}] is not a pair i < j of particle indices below {n}"),
                ));
            }
            if !seen.insert((i, j)) {
                return Err(ConfigError::inconsistent(format!("checkpoint.pairs[{k}]"), format!("[{i}, {j}] appears twice")));
            }
        }
        for (k, c) in self.contacts.iter().enumerate() {
            for (q, &v) in c.y.iter().chain(&c.y_prev).chain(&c.e3).chain(&[c.l0, c.h_last]).enumerate() {
                finite(|| format!("checkpoint.contacts[{k}] (state entry {q})"), v, "m")?;
            }
            // the initial radii of the two spheres: inside the range of particle radii
            for (side, &r) in c.r0.iter().enumerate() {
                ranged("particles.radius", || format!("checkpoint.contacts[{k}].r0[{side}]"), r)?;
            }
            // the centre distance at creation (R3): neither sphere inside the other, and not
            // further apart than the sum of the radii plus half of it (contacts are detected at a
            // gap tolerance far below that)
            let (lo, hi) = ((c.r0[0] - c.r0[1]).abs(), 1.5 * (c.r0[0] + c.r0[1]));
            if !(c.l0 > lo && c.l0 <= hi) {
                return Err(out_of_range(
                    format!("checkpoint.contacts[{k}].l0"),
                    c.l0,
                    format!("({}, {}] (|r0_a − r0_b|, 1.5·(r0_a + r0_b))", fmt_value(lo), fmt_value(hi)),
                    "m",
                ));
            }
            if !(c.t_created.is_finite() && c.t_created >= 0.0 && c.t_created <= self.t) {
                return Err(out_of_range(
                    format!("checkpoint.contacts[{k}].t_created"),
                    c.t_created,
                    format!("[0, {}] (checkpoint.t)", fmt_value(self.t)),
                    "s",
                ));
            }
            if c.h_last < 0.0 {
                return Err(out_of_range(format!("checkpoint.contacts[{k}].h_last"), c.h_last, "[0, inf)".into(), "s"));
            }
        }
        for (k, &v) in self.dl_bar.iter().enumerate() {
            finite(|| format!("checkpoint.dl_bar[{k}]"), v, "m")?;
        }
        // accounts and output bookkeeping
        for (key, v) in [("checkpoint.heat_in", self.heat_in), ("checkpoint.heat_stored", self.heat_stored), ("checkpoint.heat_scale", self.heat_scale)] {
            crate::heat::balance::energy_account(key, v)?;
        }
        finite(|| "checkpoint.mechanics_counters".into(), self.mechanics_counters.2, "1")?;
        if let Some((h, dt)) = &self.heat_history {
            finite(|| "checkpoint.heat_history".into(), *dt, "s")?;
            for (i, &v) in h.iter().enumerate() {
                finite(|| format!("checkpoint.heat_history[{i}]"), v, "K")?;
            }
        }
        let o = &self.output;
        if o.next_cond > s.conductivity_at.len() {
            return Err(ConfigError::inconsistent(
                "checkpoint.output.next_cond",
                format!("{} is beyond the {} entries of output.conductivity_at", o.next_cond, s.conductivity_at.len()),
            ));
        }
        if o.next_hist > s.histogram_at.len() {
            return Err(ConfigError::inconsistent(
                "checkpoint.output.next_hist",
                format!("{} is beyond the {} entries of output.correction_histogram_at", o.next_hist, s.histogram_at.len()),
            ));
        }
        if o.series_lines == 0 {
            return Err(ConfigError::inconsistent("checkpoint.output.series_lines", "must count the header line"));
        }
        finite(|| "checkpoint.output.wall_before".into(), o.wall_before, "s")?;
        Ok(())
    }
}

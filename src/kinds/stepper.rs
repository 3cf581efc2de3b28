//! The run API one step at a time (docs/python.md "Stepping"): [`Stepper`] is a heat, compact or
//! explicit_sinter run that a caller advances step by step, reads between steps (time, particles,
//! contacts) and changes between steps (furnace temperature, applied stress: heat and compact).
//! [`super::run`] runs these kinds as the same loop, so a run stepped to its end writes the same
//! files, bit for bit.

use super::state::{ContactState, ParticleState};
use super::{Kind, RunLog, RunParams, RunSummary};
use crate::error::{ConfigError, Error};
use crate::kinds::compact::CompactRun;
use crate::kinds::explicit_sinter::ExplicitRun;
use crate::kinds::heat::HeatRun;
use std::path::Path;
use std::time::Instant;

/// The run object of a kind that can be stepped.
enum Inner {
    Heat(Box<HeatRun>),
    Compact(Box<CompactRun>),
    Explicit(Box<ExplicitRun>),
}

/// A heat, compact or explicit_sinter run in progress, with its log (`DIR/log.txt`).
pub struct Stepper {
    kind: Kind,
    inner: Inner,
    log: RunLog,
    wall: Instant,
}

impl Stepper {
    /// Prepares `case` with `overrides` (as [`super::run`] does), opens the outputs in `out` and
    /// writes those due at the start. Pair and generate cases are a configuration error.
    pub fn start(case: &toml::Value, overrides: &[String], out: &Path, params: &RunParams) -> Result<Stepper, Error> {
        let wall = Instant::now();
        let (value, kind, log) = super::open_run(case, overrides, out, params)?;
        Self::opened(value, kind, log, out, params, wall)
    }

    /// [`Stepper::start`] after [`super::open_run`]; `wall`: when the run started.
    pub(crate) fn opened(value: toml::Value, kind: Kind, mut log: RunLog, out: &Path, params: &RunParams, wall: Instant) -> Result<Stepper, Error> {
        let mut logf = |m: &str| log.line(m);
        let inner = Self::build(kind, value, out, params, &mut logf)?;
        Ok(Stepper { kind, inner, log, wall })
    }

    /// A stepper over a compact run already started (a resumed one: `sinterdem resume` of an rve
    /// run), with its log; `wall`: when the resume started.
    pub(crate) fn from_compact(run: CompactRun, log: RunLog, wall: Instant) -> Stepper {
        Stepper { kind: Kind::Compact, inner: Inner::Compact(Box::new(run)), log, wall }
    }

    fn build(kind: Kind, value: toml::Value, out: &Path, params: &RunParams, log: &mut dyn FnMut(&str)) -> Result<Inner, Error> {
        let base = &params.base_dir;
        Ok(match kind {
            Kind::Heat => {
                let text = toml::to_string(&value).map_err(|e| ConfigError::invalid(format!("case cannot be re-serialised: {e}")))?;
                let mut prep = crate::scene::prepare(value, base)?;
                prep.source = Some((text, base.canonicalize().unwrap_or_else(|_| base.to_path_buf())));
                Inner::Heat(Box::new(HeatRun::start(prep, out, params.progress, log)?))
            }
            Kind::Compact => {
                let mut sim = crate::coupled::prepare(value, base, log)?;
                sim.settings.plots = params.plots;
                sim.settings.wall_limit = params.wall_limit;
                Inner::Compact(Box::new(CompactRun::start(sim, out, params.progress, None, log)?))
            }
            Kind::ExplicitSinter => Inner::Explicit(Box::new(ExplicitRun::start(&value, out, log)?)),
            k => {
                return Err(ConfigError::invalid(format!(
                    "kind = \"{}\": only heat, compact and explicit_sinter runs can be stepped (Simulation); run it whole (sinterdem.run / sinterdem run)",
                    k.name()
                ))
                .into());
            }
        })
    }

    /// The kind of the case.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// Takes one accepted step (and writes what is due in it); returns whether the run goes on.
    pub fn step(&mut self) -> Result<bool, Error> {
        let log = &mut self.log;
        let mut logf = |m: &str| log.line(m);
        match &mut self.inner {
            Inner::Heat(r) => r.step(&mut logf),
            Inner::Compact(r) => r.step(&mut logf),
            Inner::Explicit(r) => r.step(&mut logf),
        }
    }

    /// Steps until the time reaches `to` [s] or the run ends (the last step may pass `to`: steps
    /// are never shortened for it); returns whether the run goes on.
    pub fn advance(&mut self, to: f64) -> Result<bool, Error> {
        if !to.is_finite() {
            return Err(ConfigError::invalid(format!("advance(to = {to}): expected a finite time in s")).into());
        }
        let log = &mut self.log;
        let mut logf = |m: &str| log.line(m);
        match &mut self.inner {
            Inner::Heat(r) => r.advance(to, &mut logf),
            Inner::Compact(r) => r.advance(to, &mut logf),
            Inner::Explicit(r) => r.advance(to, &mut logf),
        }
    }

    /// Current time [s].
    pub fn time(&self) -> f64 {
        match &self.inner {
            Inner::Heat(r) => r.time(),
            Inner::Compact(r) => r.sim.t,
            Inner::Explicit(r) => r.time(),
        }
    }

    /// Accepted steps so far.
    pub fn steps(&self) -> u64 {
        match &self.inner {
            Inner::Heat(r) => r.steps() as u64,
            Inner::Compact(r) => r.sim.step,
            Inner::Explicit(r) => r.steps(),
        }
    }

    /// End time of the case [s].
    pub fn end(&self) -> f64 {
        match &self.inner {
            Inner::Heat(r) => r.end(),
            Inner::Compact(r) => r.sim.settings.end,
            Inner::Explicit(r) => r.end(),
        }
    }

    /// Whether the run is over (only [`Stepper::finish`] is left).
    pub fn done(&self) -> bool {
        match &self.inner {
            Inner::Heat(r) => r.done(),
            Inner::Compact(r) => r.done(),
            Inner::Explicit(r) => r.done(),
        }
    }

    /// Whether a model error ended the run: [`Stepper::finish`] writes the outputs and returns it.
    pub fn failed(&self) -> bool {
        matches!(&self.inner, Inner::Compact(r) if r.failed())
    }

    /// Relative density of the compact now [1] (None for heat runs: the packing is static;
    /// explicit_sinter: the solid fraction ΣV_i/V_box of the sample being advanced).
    pub fn relative_density(&self) -> Option<f64> {
        match &self.inner {
            Inner::Heat(_) => None,
            Inner::Compact(r) => Some(r.sim.relative_density()),
            Inner::Explicit(r) => r.density(),
        }
    }

    /// Shrinkage of the compact now per axis, 1 − L/L₀ [1] (the `shrinkage_x/y/z` columns of
    /// `series.csv`); None for heat and explicit_sinter runs.
    pub fn shrinkage(&self) -> Option<[f64; 3]> {
        match &self.inner {
            Inner::Compact(r) => {
                let s = r.sim.shrinkage();
                Some([s.x, s.y, s.z])
            }
            Inner::Heat(_) | Inner::Explicit(_) => None,
        }
    }

    /// Where an explicit_sinter protocol is: stage, confining pressure [Pa], sintering time of
    /// the branch in progress [s] ([`ExplicitRun::stage`]); None for heat and compact runs.
    pub fn stage(&self) -> Option<(&'static str, f64, Option<f64>)> {
        match &self.inner {
            Inner::Explicit(r) => Some(r.stage()),
            _ => None,
        }
    }

    /// The compact simulation in its current state (None for heat and explicit_sinter runs):
    /// what `sinterdem rve` branches its perturbed runs from (docs/rve.md).
    pub(crate) fn compact_simulation(&self) -> Option<&crate::coupled::Simulation> {
        match &self.inner {
            Inner::Compact(r) => Some(&r.sim),
            Inner::Heat(_) | Inner::Explicit(_) => None,
        }
    }

    /// The particles now.
    pub fn particles(&self) -> ParticleState {
        match &self.inner {
            Inner::Heat(r) => r.particles(),
            Inner::Compact(r) => r.particles(),
            Inner::Explicit(r) => r.particles(),
        }
    }

    /// The contacts now.
    pub fn contacts(&self) -> ContactState {
        match &self.inner {
            Inner::Heat(r) => r.contacts(),
            Inner::Compact(r) => r.contacts(),
            Inner::Explicit(r) => r.contacts(),
        }
    }

    /// Holds the furnace at `temperature` [K] from now on (module docs of [`super::state`]);
    /// explicit_sinter runs have no furnace to hold ([`ExplicitRun::set_furnace_temperature`]).
    pub fn set_furnace_temperature(&mut self, temperature: f64) -> Result<(), Error> {
        let t = self.time();
        let held = match &mut self.inner {
            Inner::Heat(r) => r.set_furnace_temperature(temperature),
            Inner::Compact(r) => r.set_furnace_temperature(temperature),
            Inner::Explicit(r) => return r.set_furnace_temperature(temperature),
        };
        if held.is_ok() {
            self.log.line(&format!("t = {t} s: furnace held at {temperature} K from now on (set by the caller)"));
        }
        held
    }

    /// Holds the applied stress at `stress` [Pa] from now on (compact runs with `[load]`).
    pub fn set_applied_stress(&mut self, stress: f64) -> Result<(), Error> {
        let t = self.time();
        match &mut self.inner {
            Inner::Heat(_) => Err(ConfigError::invalid("set_applied_stress: a heat run has no mechanics (compact runs with [load] only)").into()),
            Inner::Explicit(r) => r.set_applied_stress(stress),
            Inner::Compact(r) => {
                r.set_applied_stress(stress)?;
                self.log.line(&format!("t = {t} s: applied stress held at {stress} Pa from now on (set by the caller)"));
                Ok(())
            }
        }
    }

    /// Ends the run before its end time with `reason` as `stop_reason` (`completed = false`).
    pub fn stop(&mut self, reason: &str) -> Result<(), Error> {
        let log = &mut self.log;
        let mut logf = |m: &str| log.line(m);
        match &mut self.inner {
            Inner::Heat(r) => r.stop(reason, &mut logf),
            Inner::Compact(r) => r.stop(reason, &mut logf),
            Inner::Explicit(r) => r.stop(reason, &mut logf),
        }
    }

    /// Ends a run whose step failed with `e` so that it keeps what it computed (issue 39): the
    /// error in `log.txt`, then the end of the run as a stop (series and snapshots up to the last
    /// accepted step, `summary.json` with `completed = false`, `stop_reason = "error"` and the
    /// error). Returns `e` (a failure while writing the end is logged, not returned).
    pub fn fail(mut self, e: Error, out: &Path) -> Error {
        self.log.line(&format!("error: {e}"));
        let written = self.stop("error").and_then(|_| {
            let mut s = self.finish()?;
            s.summary["completed"] = serde_json::json!(false);
            if s.summary.get("stop_reason").is_none_or(|r| r.is_null() || r == "error") {
                s.summary["stop_reason"] = serde_json::json!(format!("error: {e}"));
            }
            s.summary["error"] = serde_json::json!(e.to_string());
            Ok(crate::io::write_json(&out.join("summary.json"), &s.summary)?)
        });
        if let Err(w) = written {
            tracing::warn!(target: "sinterdem::kinds", "the failed run's summary could not be written: {w}");
        }
        e
    }

    /// Writes the end of the run (`summary.json`, plots) and returns its summary; a run not yet
    /// over is stopped first (`stop_reason = "stopped by the caller"`).
    pub fn finish(self) -> Result<RunSummary, Error> {
        let Stepper { kind, inner, mut log, wall } = self;
        let mut logf = |m: &str| log.line(m);
        let summary = match inner {
            Inner::Heat(r) => r.finish(&mut logf)?,
            Inner::Compact(r) => r.finish(&mut logf)?,
            Inner::Explicit(r) => r.finish(&mut logf)?,
        };
        Ok(RunSummary { kind, wall_seconds: wall.elapsed().as_secs_f64(), summary })
    }
}

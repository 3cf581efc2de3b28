//! An `explicit_sinter` run one explicit step at a time (the stepping API, `sinterdem.Simulation`
//! in Python; docs/python.md "Stepping an explicit_sinter protocol"). [`ExplicitRun::start`]
//! builds the protocol, [`ExplicitRun::step`] takes one explicit step of the sample being advanced
//! (and makes the stage changes that follow it: a branch splitting off, a branch finished, the
//! next pressure's sample), [`ExplicitRun::finish`] writes the outputs. `sinterdem run`, `resume`
//! and [`super::run_explicit`] are this loop, so a stepped run writes the same files, bit for bit.
//!
//! Time: the protocol advances one sample at a time, so [`ExplicitRun::time`] is the time of the
//! sample being advanced. It goes back when a branch is finished (the trunk goes on sintering from
//! the branch's sintering time) and restarts at 0 for each pressure.

use super::case::ExplicitSinterCase;
use super::checkpoint::CheckpointSink;
use super::machine::{Pause, Plan, Protocol, Stage};
use super::output::{ExplicitSinterRun, Row, columns, write_outputs};
use crate::error::{ConfigError, Error};
use crate::kinds::state::{ContactState, ParticleState};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// An `explicit_sinter` run in progress (module docs).
pub struct ExplicitRun {
    case: ExplicitSinterCase,
    plan: Plan,
    protocol: Option<Box<dyn Protocol>>,
    sink: Option<CheckpointSink>,
    /// Output directory (None: a run without files, [`super::run_explicit`]).
    out: Option<PathBuf>,
    /// Positions of the loose random start [m] (every pressure's sample starts there).
    x0: Vec<Vector3<f64>>,
    finished: bool,
    /// Stopped right after a checkpoint as if killed (`stop_after`, tests): no outputs.
    killed: bool,
    stop_reason: Option<String>,
}

impl ExplicitRun {
    /// Parses `case` (overrides applied), opens `out` and builds the first sample (the loose
    /// random start of the first pressure, no step taken yet). Checkpoints go to
    /// `out/checkpoint.json` every `output.checkpoint_every` steps.
    pub fn start(case: &toml::Value, out: &Path, log: &mut dyn FnMut(&str)) -> Result<ExplicitRun, Error> {
        Self::start_stopping(case, out, None, log)
    }

    /// [`ExplicitRun::start`] that stops right after the checkpoint at or after step `stop_after`
    /// as if killed there (tests of `resume`).
    pub(super) fn start_stopping(case: &toml::Value, out: &Path, stop_after: Option<u64>, log: &mut dyn FnMut(&str)) -> Result<ExplicitRun, Error> {
        let c = super::parse_explicit_case(case)?;
        crate::io::ensure_dir(out)?;
        let case_toml = toml::to_string(case).map_err(|e| ConfigError::invalid(format!("case cannot be re-serialised: {e}")))?;
        let sink = (c.output.checkpoint_every > 0.0).then(|| CheckpointSink { dir: out.to_path_buf(), case_toml, stop_after });
        Self::new(c, sink, None, Some(out.to_path_buf()), log)
    }

    /// The run of a parsed case: checkpoints into `sink`, continued from `resume` (a checkpoint's
    /// text and path), outputs into `out`.
    pub(super) fn new(
        case: ExplicitSinterCase,
        sink: Option<CheckpointSink>,
        resume: Option<(&str, &Path)>,
        out: Option<PathBuf>,
        log: &mut dyn FnMut(&str),
    ) -> Result<ExplicitRun, Error> {
        let plan = Plan::new(&case)?;
        let protocol = case.law.protocol(&case, resume, log)?;
        let x0 = super::sample::random_loose_sample(&case)?.0.position;
        let mut run = ExplicitRun { case, plan, protocol: Some(protocol), sink, out, x0, finished: false, killed: false, stop_reason: None };
        // the stage changes before the first step (a new run: the first sample is built)
        run.run_to(0, log)?;
        Ok(run)
    }

    fn run_to(&mut self, budget: u64, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let p = self.protocol.as_mut().expect("the protocol lives until finish");
        match p.run_to(&self.case, &self.plan, self.sink.as_ref(), log, budget)? {
            Pause::Budget => {}
            Pause::Killed => self.killed = true,
            Pause::Finished => self.finished = true,
        }
        Ok(())
    }

    /// Takes one explicit step of the sample being advanced (with the history row and checkpoint
    /// due in it, and the stage changes that follow); returns whether the run goes on. An
    /// interrupt ([`crate::interrupt`]) ends the run here.
    pub fn step(&mut self, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        if self.done() {
            return Ok(false);
        }
        let next = self.steps() + 1;
        self.run_to(next, log)?;
        if !self.done() && crate::interrupt::requested() {
            self.stop("interrupted", log)?;
        }
        Ok(!self.done())
    }

    /// Steps until the time of the sample being advanced reaches `to` [s] or the run ends (module
    /// docs: the time goes back when a branch is finished); returns whether the run goes on.
    pub fn advance(&mut self, to: f64, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        while !self.done() && self.time() < to {
            self.step(log)?;
        }
        Ok(!self.done())
    }

    /// Time of the sample being advanced [s] (module docs); the end time once the run is over.
    pub fn time(&self) -> f64 {
        match self.protocol.as_ref().and_then(|p| p.current()) {
            Some(c) => c.time,
            None => self.end(),
        }
    }

    /// Explicit steps so far (all samples).
    pub fn steps(&self) -> u64 {
        self.protocol.as_ref().map_or(0, |p| p.steps())
    }

    /// End of the longest branch's history [s] (compression test included).
    pub fn end(&self) -> f64 {
        self.plan.end(&self.case)
    }

    /// Whether the run is over (only [`ExplicitRun::finish`] is left).
    pub fn done(&self) -> bool {
        self.finished || self.killed || self.stop_reason.is_some()
    }

    /// Where the protocol is: the stage (`prepare`, `heat`, `sinter`, `cool`, `compress`; `done`
    /// at the end), the confining pressure [Pa] and the sintering time [s] of the branch it works
    /// towards (None before sintering).
    pub fn stage(&self) -> (&'static str, f64, Option<f64>) {
        let pressures = &self.case.walls.pressures;
        let Some((stage, i)) = self.protocol.as_ref().map(|p| p.stage()).filter(|_| !self.finished) else {
            return ("done", *pressures.last().unwrap_or(&0.0), self.plan.times.last().copied());
        };
        let ts = match stage {
            Stage::Sinter { k } | Stage::Cool { k } | Stage::Compress { k } => Some(self.plan.times[k]),
            _ => None,
        };
        (stage.name(), pressures.get(i).copied().unwrap_or(0.0), ts)
    }

    /// Solid fraction ΣV_i/V_box of the sample being advanced [1].
    pub fn density(&self) -> Option<f64> {
        self.protocol.as_ref().and_then(|p| p.current()).map(|c| c.density)
    }

    /// The particles of the sample being advanced: positions [m], radii [m] (eq. 9 of
    /// docs/luding.md: they follow the temperature), temperatures [K], displacements from the
    /// loose random start [m]. Empty once the run is over.
    pub fn particles(&self) -> ParticleState {
        let Some(c) = self.protocol.as_ref().and_then(|p| p.current()) else { return ParticleState::default() };
        let p = c.particles;
        let mut displacements = Vec::with_capacity(3 * p.len());
        for (x, x0) in p.position.iter().zip(&self.x0) {
            let d = x - x0;
            displacements.extend_from_slice(&[d.x, d.y, d.z]);
        }
        ParticleState {
            ids: (0..p.len() as i64).collect(),
            positions: crate::kinds::state::flat3(p.position.iter()),
            radii: p.radius.clone(),
            temperatures: p.temperature.clone(),
            displacements,
        }
    }

    /// The particle–particle contacts of the sample being advanced (at the last force
    /// evaluation): pairs, neck radius [m] = the radius of the circle where the two spheres
    /// intersect, √(r_i² − x_i²) with x_i = (d² + r_i² − r_j²)/(2d) (0 for a contact at a gap:
    /// Luding's attractive branch), normal force [N] (positive repulsive).
    pub fn contacts(&self) -> ContactState {
        let Some(c) = self.protocol.as_ref().and_then(|p| p.current()) else { return ContactState::default() };
        let p = c.particles;
        let mut out = ContactState::default();
        for &((i, j), f) in &c.contacts {
            let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
            out.pairs.extend_from_slice(&[i as i64, j as i64]);
            out.neck_radii.push(intersection_radius(ri, rj, (p.position[i as usize] - p.position[j as usize]).norm()));
            out.forces.push(f);
        }
        out
    }

    /// Not available: the temperature history is the protocol (its stages are defined by it, and
    /// every branch shares the trunk's history up to its sintering time).
    pub fn set_furnace_temperature(&mut self, _temperature: f64) -> Result<(), Error> {
        Err(ConfigError::invalid(
            "set_furnace_temperature: an explicit_sinter run has no furnace to hold: its temperature history is the protocol's (protocol.temperature_cold, temperature_hot, t_heat, t_sinter, t_cool), which defines its stages and the branches' shared history; change those keys in the case",
        )
        .into())
    }

    /// Not available: the walls' pressures are the case's list of experiments (one branch set
    /// per pressure, named by it in the outputs) and the compression test is strain-controlled.
    pub fn set_applied_stress(&mut self, _stress: f64) -> Result<(), Error> {
        Err(ConfigError::invalid(
            "set_applied_stress: an explicit_sinter run's wall pressures are its list of experiments (walls.pressures, one set of branches per pressure, named by it in the outputs) and its compression test is strain-controlled; change walls.pressures in the case",
        )
        .into())
    }

    /// Ends the run before the end of its protocol (`completed = false`, `stop_reason = reason`).
    pub fn stop(&mut self, reason: &str, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        if self.done() {
            return Ok(());
        }
        let (stage, p, _) = self.stage();
        log(&format!("t = {} s (step {}, p = {p:.3e} Pa, {stage}): {reason}: the run ends here", self.time(), self.steps()));
        self.stop_reason = Some(reason.to_string());
        Ok(())
    }

    /// The run's result (finished branches; a run stopped early says where), None when it was
    /// stopped as if killed (`stop_after`). A run not yet over is stopped first ("stopped by the
    /// caller").
    pub(super) fn into_run(mut self, log: &mut dyn FnMut(&str)) -> Result<Option<(ExplicitSinterRun, ExplicitSinterCase, Option<Vec<Row>>)>, Error> {
        if !self.done() {
            self.stop("stopped by the caller", log)?;
        }
        if self.killed {
            return Ok(None);
        }
        let in_compression = matches!(self.protocol.as_ref().map(|p| p.stage().0), Some(Stage::Compress { .. }));
        let stopped = self.stop_reason.as_ref().map(|reason| {
            let (stage, pressure, t_sinter) = self.stage();
            super::output::Stopped { reason: reason.clone(), stage, pressure, t_sinter, time: self.time(), steps: self.steps(), in_compression }
        });
        let current_rows = self.protocol.as_ref().and_then(|p| p.current()).map(|c| c.rows.to_vec());
        let f = self.protocol.take().expect("the protocol lives until finish").into_finished();
        let c = &self.case;
        let run = ExplicitSinterRun {
            title: c.title.clone(),
            model: c.law.name().into(),
            particles: c.sample.particles as usize,
            dt: f.dt_used,
            branches: f.branches,
            warnings: f.warnings,
            wall_seconds: f.wall_before,
            stopped,
        };
        Ok(Some((run, self.case, current_rows.filter(|_| self.stop_reason.is_some()))))
    }

    /// Writes the outputs (module docs of [`super`]; a run stopped early also gets
    /// `completed = false`, its `stop_reason` and where it stopped in `summary.json`, and the rows
    /// of the sample in progress in `history_stopped.csv` or `compression_stopped.csv`) and
    /// returns the summary; `Value::Null` for a run stopped as if killed (no outputs).
    pub fn finish(self, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
        let out = self.out.clone();
        let Some((run, case, rows)) = self.into_run(log)? else { return Ok(serde_json::Value::Null) };
        for w in &run.warnings {
            log(&format!("warning: {w}"));
        }
        let Some(out) = out else { return Ok(super::output::summary_json(&run)) };
        let summary = write_outputs(&case, &run, &out)?;
        if let (Some(rows), Some(s)) = (rows, run.stopped.as_ref()) {
            let cols = columns(case.law.state());
            let name = if s.in_compression { "compression_stopped.csv" } else { "history_stopped.csv" };
            let mut csv = crate::io::Series::create(&out.join(name), &crate::io::header(&cols))?;
            for r in &rows {
                csv.row(&crate::io::values(&cols, r))?;
            }
        }
        match &run.stopped {
            None => log("done: explicit sintering protocol finished (summary.json)"),
            Some(s) => log(&format!("done: stopped ({}) with {} branches finished (summary.json: completed = false)", s.reason, run.branches.len())),
        }
        Ok(summary)
    }
}

/// Radius of the circle where two spheres of radii `ri`, `rj` [m] at centre distance `d` [m]
/// intersect [m]; 0 when they do not.
pub(super) fn intersection_radius(ri: f64, rj: f64, d: f64) -> f64 {
    if !(d > 0.0) || d >= ri + rj {
        return 0.0;
    }
    let x = (d * d + ri * ri - rj * rj) / (2.0 * d);
    (ri * ri - x * x).max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::intersection_radius;

    #[test]
    fn intersection_radius_of_equal_and_unequal_spheres() {
        // equal spheres at d = 2r cos(θ): a = r sin(θ)
        let (r, th) = (1e-5, 0.3_f64);
        let a = intersection_radius(r, r, 2.0 * r * th.cos());
        assert!((a - r * th.sin()).abs() < 1e-15 * r, "{a}");
        // 3-4-5: spheres of radii 3 and 4 at distance 5 meet at right angles: a = 12/5
        assert!((intersection_radius(3.0, 4.0, 5.0) - 2.4).abs() < 1e-12);
        assert_eq!(intersection_radius(1.0, 1.0, 2.5), 0.0);
    }
}

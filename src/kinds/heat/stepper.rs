//! A heat run one accepted step at a time (the stepping API; `sinterdem.Simulation` in Python):
//! [`HeatRun::start`] builds the network and opens the outputs, [`HeatRun::step`] takes one step
//! and writes what is due in it, [`HeatRun::finish`] writes `summary.json`. The run of
//! `sinterdem run` ([`super::run_returning_temperatures`]) is exactly this loop.

use super::output::{self, Snapshots};
use super::step::{self, Plan};
use super::{COLUMNS, HeatCheckpoint, HeatLoop, HeatRow, loop_state, open_outputs, setup};
use crate::error::{ConfigError, Error};
use crate::heat::{HeatNetwork, PipeConductance};
use crate::io::{self, Series};
use crate::kinds::state::{self, ContactState, ParticleState};
use crate::scene::Prepared;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A heat run in progress.
pub struct HeatRun {
    /// The prepared case (particles and their temperatures now in `prep.scene.particles`).
    pub prep: Prepared,
    net: HeatNetwork,
    parts: Vec<PipeConductance>,
    series: Series,
    pub(super) st: HeatLoop,
    plan: Plan,
    snaps: Snapshots,
    pub(super) bar: io::progress::Progress,
    out: PathBuf,
    wall: Instant,
    /// Tests: stop as if killed right after the checkpoint at or after this step.
    pub(super) stop_after_step: Option<usize>,
    pub(super) killed: bool,
    stop_reason: Option<String>,
    /// Steps whose series row was written last (`usize::MAX`: none yet).
    row_step: usize,
    last: Option<step::Step>,
}

impl HeatRun {
    /// Builds the network of a prepared case, opens the outputs in `out` and writes those due at
    /// the start.
    pub fn start(prep: Prepared, out: &Path, progress: bool, log: &mut dyn FnMut(&str)) -> Result<HeatRun, Error> {
        Self::start_from(prep, out, progress, log, None, false)
    }

    /// [`HeatRun::start`] from a checkpoint (`ck`), collecting the snapshot temperatures with
    /// `collect` (benchmarks).
    pub(super) fn start_from(
        mut prep: Prepared,
        out: &Path,
        progress: bool,
        log: &mut dyn FnMut(&str),
        ck: Option<HeatCheckpoint>,
        collect: bool,
    ) -> Result<HeatRun, Error> {
        let wall = Instant::now();
        io::ensure_dir(out)?;
        let (mut net, parts) = setup(&mut prep, log)?;
        let (series, writer) = open_outputs(&mut prep, &mut net, out, ck.as_ref(), log)?;
        let mut st = loop_state(&prep, &net, ck);
        let plan = Plan::new(&prep, log)?;
        let mut snaps = Snapshots::new(writer, &prep.case, collect);
        let bar = io::progress::Progress::new(plan.end, progress);
        let first = st.t + 1e-12 * plan.end;
        snaps.write_due(&plan.snap_times, &mut st, first, &prep)?;
        let row_step = st.steps;
        Ok(HeatRun {
            prep,
            net,
            parts,
            series,
            st,
            plan,
            snaps,
            bar,
            out: out.to_path_buf(),
            wall,
            stop_after_step: None,
            killed: false,
            stop_reason: None,
            row_step,
            last: None,
        })
    }

    /// Current time [s].
    pub fn time(&self) -> f64 {
        self.st.t
    }

    /// Accepted steps so far.
    pub fn steps(&self) -> usize {
        self.st.steps
    }

    /// End time of the case [s].
    pub fn end(&self) -> f64 {
        self.plan.end
    }

    /// Whether the run is over (end time reached or stopped).
    pub fn done(&self) -> bool {
        self.killed || self.stop_reason.is_some() || self.st.t >= self.plan.end * (1.0 - 1e-12)
    }

    /// The output directory.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Takes one accepted step and writes the series row, snapshots and checkpoint due in it;
    /// returns whether the run goes on. An interrupt ([`crate::interrupt`]) ends the run here.
    pub fn step(&mut self, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        if self.done() {
            return Ok(false);
        }
        let (plan, st) = (&self.plan, &mut self.st);
        // the first step after a resume: the factor of the checkpoint's matrix is rebuilt
        let resumed_factor = st.factor_sha256.take();
        let (rejected0, factored0) = (st.rejected, st.factorizations);
        let step = step::advance(plan, st, &mut self.prep, &mut self.net, &self.parts, log)?;
        if let Some(h) = resumed_factor
            && st.rejected == rejected0
            && st.factorizations > factored0
            && self.net.factored_values().map(output::values_sha256).as_ref() == Some(&h)
        {
            // the same matrix as at the checkpoint: the uninterrupted run reused its factor here
            st.factorizations -= 1;
        }
        st.t += step.dt;
        st.steps += 1;
        if st.steps.is_multiple_of(self.prep.case.output.series_every as usize) || st.t >= plan.end * (1.0 - 1e-12) {
            self.series.row(&io::values(COLUMNS, &HeatRow::new(st, &step, &self.prep.scene.particles.temperature, &self.net)))?;
            st.series_lines += 1;
            self.row_step = st.steps;
        }
        let due = st.t + 1e-9 * step.dt;
        self.snaps.write_due(&plan.snap_times, st, due, &self.prep)?;
        self.last = Some(step);
        if plan.checkpoint_due(st.steps, st.t) {
            output::write_checkpoint(&self.prep, &self.out, st, plan, &self.snaps.writer, &self.net, self.wall)?;
            if self.stop_after_step.is_some_and(|k| st.steps >= k) {
                self.killed = true;
                return Ok(false);
            }
        }
        self.bar.set(st.t, "");
        if !self.done() && crate::interrupt::requested() {
            self.stop("interrupted", log)?;
        }
        Ok(!self.done())
    }

    /// Steps until the time reaches `to` [s] (the last step may pass it: the steps are those of
    /// an uninterrupted run); returns whether the run goes on.
    pub fn advance(&mut self, to: f64, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        while !self.done() && self.st.t < to {
            self.step(log)?;
        }
        Ok(!self.done())
    }

    /// Ends the run before its end time (`completed = false`, `stop_reason = reason` in the
    /// summary); the series row of the current state is written if it is not yet.
    pub fn stop(&mut self, reason: &str, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        if self.done() {
            return Ok(());
        }
        log(&format!("t = {} s (step {}): {reason}: the run ends here", self.st.t, self.st.steps));
        if let Some(step) = self.last.as_ref().filter(|_| self.row_step != self.st.steps) {
            self.series.row(&io::values(COLUMNS, &HeatRow::new(&self.st, step, &self.prep.scene.particles.temperature, &self.net)))?;
            self.st.series_lines += 1;
            self.row_step = self.st.steps;
        }
        self.stop_reason = Some(reason.to_string());
        Ok(())
    }

    /// Writes `summary.json` (a run not yet over is stopped first: "stopped by the caller").
    pub fn finish(self, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
        self.finish_collected(log).map(|(s, _)| s)
    }

    /// [`HeatRun::finish`] that also returns the temperatures collected at the snapshot times
    /// and the final state's.
    pub(super) fn finish_collected(mut self, log: &mut dyn FnMut(&str)) -> Result<(serde_json::Value, Vec<(f64, Vec<f64>)>), Error> {
        if !self.done() {
            self.stop("stopped by the caller", log)?;
        }
        self.bar.finish();
        let (prep, st) = (&self.prep, &self.st);
        let summary = output::finish(prep, &self.out, st, &self.plan, &self.net, &self.snaps.writer, self.wall, self.stop_reason.as_deref(), log)?;
        let mut collected = self.snaps.collected;
        if collected.last().is_none_or(|c| c.0 != st.t) {
            collected.push((st.t, prep.scene.particles.temperature.clone()));
        }
        Ok((summary, collected))
    }

    /// The particles now (static packing: zero displacements).
    pub fn particles(&self) -> ParticleState {
        let p = &self.prep.scene.particles;
        ParticleState {
            ids: (0..p.len() as i64).collect(),
            positions: state::flat3(p.position.iter()),
            radii: p.radius.clone(),
            temperatures: p.temperature.clone(),
            displacements: vec![0.0; 3 * p.len()],
        }
    }

    /// The contacts (pipes) of the packing: pairs, neck radii [m]; no forces in a heat run (0).
    pub fn contacts(&self) -> ContactState {
        let pipes = &self.prep.pipes;
        ContactState { pairs: state::flat_pairs(&pipes.pairs), neck_radii: pipes.neck.clone(), forces: vec![0.0; pipes.pairs.len()] }
    }

    /// Holds the furnace at `temperature` [K] from now on (gas and walls; isothermal runs: every
    /// particle): the case's furnace profile as a table with a jump now, which the step control
    /// then treats as a kink; the run's case text (checkpoints) is rewritten the same way.
    pub fn set_furnace_temperature(&mut self, temperature: f64) -> Result<(), Error> {
        let t = self.st.t;
        let mut table = None;
        if let Some(p) = self.prep.isothermal.as_mut() {
            *p = p.hold_from(t, temperature)?;
            table = Some(p.clone());
        }
        if let Some(f) = self.prep.sources.furnace.as_mut() {
            f.gas = f.gas.hold_from(t, temperature)?;
            f.wall = f.wall.hold_from(t, temperature)?;
            table.get_or_insert_with(|| f.gas.clone());
            self.net.set_furnace(f.clone());
        }
        let Some(profile) = table else {
            return Err(ConfigError::invalid("set_furnace_temperature: this heat case has no furnace (add [thermal.furnace] with a profile)").into());
        };
        self.plan.update_kinks(&self.prep);
        if self.plan.kinks.contains(&t) {
            // the step that ended here now ends at a kink: the error estimate restarts, as
            // `step::advance` does for a step landing on a kink of the case's profiles
            let keep = self.st.hist.len().saturating_sub(1);
            self.st.hist.drain(..keep);
            self.st.hist_t.drain(..keep.min(self.st.hist_t.len()));
        }
        if let Some((text, _)) = self.prep.source.as_mut() {
            state::rewrite_furnace(text, &profile)?;
        }
        Ok(())
    }
}

//! The protocol's state machine (module docs of [`super`]): prepare → heat → per sintering time
//! sinter the trunk, then a branch that cools, relaxes and is compressed; one method per stage,
//! each advancing until its end, the next checkpoint or the end of the caller's step budget
//! ([`StepClock::budget`]: the stepping API takes one explicit step per call, [`super::ExplicitRun`]).

use super::case::{CouplingMode, ExplicitSinterCase};
use super::checkpoint::{CheckpointSink, ExplicitCheckpoint};
use super::output::{Branch, Row};
use super::sample::{Sample, box_size};
use crate::error::{ConfigError, Error, IoError};
use crate::explicit::WallControl;
use crate::explicit::sinter::SinterLaw;
use crate::heat::network::HeatNetwork;
use crate::profile::Profile;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Counts the explicit steps of a whole protocol and says when a checkpoint is due or the caller's
/// step budget is spent.
#[derive(Debug, Clone, Copy)]
pub struct StepClock {
    /// Steps so far (all pressures and branches).
    pub steps: u64,
    /// Checkpoint interval [steps]; 0: never.
    pub every: u64,
    /// The protocol pauses before a step once `steps` reaches this (u64::MAX: never).
    pub budget: u64,
    /// A checkpoint is due (set by the step that reached it, taken by the machine).
    due: bool,
}

impl Default for StepClock {
    fn default() -> Self {
        StepClock { steps: 0, every: 0, budget: u64::MAX, due: false }
    }
}

impl StepClock {
    /// Counts a step; true when a checkpoint is due after it.
    pub(super) fn tick(&mut self) -> bool {
        self.steps += 1;
        self.due = self.every > 0 && self.steps.is_multiple_of(self.every);
        self.due
    }

    /// Whether the step budget is spent (the advance pauses before its next step).
    pub(super) fn spent(&self) -> bool {
        self.steps >= self.budget
    }
}

/// Where the protocol is (module docs: prepare → heat → per t_s: sinter, then a branch that
/// cools, relaxes and is compressed). Checkpoints record it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "stage", rename_all = "snake_case")]
pub enum Stage {
    /// A new sample for the pressure `pressure_index`.
    Start,
    Prepare,
    Heat,
    /// Sintering the trunk to the `k`-th sintering time.
    Sinter {
        k: usize,
    },
    /// The `k`-th branch cooling and relaxing.
    Cool {
        k: usize,
    },
    /// The `k`-th branch under the compression test.
    Compress {
        k: usize,
    },
}

impl Stage {
    /// The stage's name (`prepare`, `heat`, `sinter`, `cool`, `compress`; `start`: between two
    /// samples).
    pub fn name(self) -> &'static str {
        match self {
            Stage::Start => "start",
            Stage::Prepare => "prepare",
            Stage::Heat => "heat",
            Stage::Sinter { .. } => "sinter",
            Stage::Cool { .. } => "cool",
            Stage::Compress { .. } => "compress",
        }
    }
}

/// How a call of [`Machine::run_to`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pause {
    /// The step budget is spent; the protocol goes on with the next call.
    Budget,
    /// Stopped right after a checkpoint by `CheckpointSink::stop_after` (as if killed; tests).
    Killed,
    /// The protocol is over.
    Finished,
}

/// Values of the branch in progress taken at earlier stages.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub(super) struct Partial {
    density_prepared: f64,
    density_sintered: f64,
    forces_sintered: Vec<f64>,
    density_final: f64,
    forces_cooled: Vec<f64>,
    coordination_final: f64,
    history: Vec<Row>,
    /// Compression test: initial height z_0 [m], top-wall speed [m/s], start time [s].
    z0: f64,
    speed: f64,
    t_start: f64,
}

/// The protocol's state machine: one call of [`Machine::run`] takes the protocol from `stage` to
/// its end, pausing at every checkpoint.
pub(super) struct Machine<M: SinterLaw> {
    pub(super) law: M,
    pub(super) pressure_index: usize,
    pub(super) stage: Stage,
    pub(super) trunk: Option<Sample<M>>,
    pub(super) net: Option<HeatNetwork>,
    pub(super) branch: Option<Sample<M>>,
    pub(super) bnet: Option<HeatNetwork>,
    pub(super) partial: Partial,
    pub(super) branches: Vec<Branch>,
    pub(super) warnings: Vec<String>,
    pub(super) dt_used: f64,
    pub(super) clock: StepClock,
    pub(super) wall_before: f64,
    /// When this machine was built or restored (its share of the wall time).
    pub(super) started: std::time::Instant,
    /// The protocol is over and its warnings are collected.
    closed: bool,
}

/// What a finished protocol hands to the run's result.
pub struct Finished {
    pub branches: Vec<Branch>,
    pub dt_used: f64,
    pub warnings: Vec<String>,
    pub wall_before: f64,
}

/// The values of a case every stage reads (computed once per run).
pub struct Plan {
    /// Sorted sintering times [s].
    pub(super) times: Vec<f64>,
    /// History row interval [s].
    interval: f64,
    /// Start of sintering [s].
    t_s0: f64,
    /// The temperature history of the longest sintering time (the trunk's).
    profile_max: Profile,
    /// The temperature history of each branch (per sorted sintering time).
    profiles: Vec<Profile>,
}

impl Plan {
    pub(super) fn new(case: &ExplicitSinterCase) -> Result<Plan, Error> {
        let times = case.sinter_times();
        let profiles = times.iter().map(|&ts| case.profile(ts)).collect::<Result<Vec<_>, _>>()?;
        let profile_max = profiles.last().cloned().ok_or_else(|| ConfigError::invalid("protocol.t_sinter: expected at least one sintering time [s]"))?;
        Ok(Plan { interval: case.output_interval(), t_s0: case.t_sinter_start(), times, profile_max, profiles })
    }

    /// The end of the longest branch's history [s] (its compression test included).
    pub(super) fn end(&self, case: &ExplicitSinterCase) -> f64 {
        let c = &case.compression;
        let compress = if c.enabled { c.max_strain / c.strain_rate } else { 0.0 };
        self.t_s0 + self.times.last().copied().unwrap_or(0.0) + case.protocol.t_cool + case.protocol.t_relax + compress
    }
}

fn forces_of<M: SinterLaw>(s: &Sample<M>) -> Vec<f64> {
    s.driver.contact_states().iter().map(|c| c.1).collect()
}

impl<M: SinterLaw> Machine<M> {
    pub(super) fn new(law: M, every: u64) -> Self {
        Machine {
            law,
            pressure_index: 0,
            stage: Stage::Start,
            trunk: None,
            net: None,
            branch: None,
            bnet: None,
            partial: Partial::default(),
            branches: Vec::new(),
            warnings: Vec::new(),
            dt_used: 0.0,
            clock: StepClock { every, ..Default::default() },
            wall_before: 0.0,
            started: std::time::Instant::now(),
            closed: false,
        }
    }

    /// Runs the protocol from the current stage until the clock reaches `budget` steps (the stage
    /// changes that take no step are made first: after a pause the next call's first act is a
    /// step), the run is stopped after a checkpoint (`sink.stop_after`), or the protocol ends. A
    /// pause does not change what follows: the steps are those of an uninterrupted run.
    pub(super) fn run_to(
        &mut self,
        case: &ExplicitSinterCase,
        plan: &Plan,
        sink: Option<&CheckpointSink>,
        log: &mut dyn FnMut(&str),
        budget: u64,
    ) -> Result<Pause, Error> {
        self.clock.budget = budget;
        while self.pressure_index < case.walls.pressures.len() {
            let pressure = case.walls.pressures[self.pressure_index];
            let done = match self.stage {
                Stage::Start => self.start(case, pressure, log)?,
                Stage::Prepare => self.prepare(case, plan)?,
                Stage::Heat => self.heat(case, plan, pressure, log)?,
                Stage::Sinter { k } => self.sinter(case, plan, k)?,
                Stage::Cool { k } => self.cool(case, plan, pressure, k, log)?,
                Stage::Compress { k } => self.compress(case, plan, pressure, k, log)?,
            };
            if done {
                continue;
            }
            if std::mem::take(&mut self.clock.due)
                && let Some(sink) = sink
                && self.write_checkpoint(sink, M::NAME, self.started.elapsed().as_secs_f64())?
            {
                return Ok(Pause::Killed);
            }
            if self.clock.spent() {
                return Ok(Pause::Budget);
            }
        }
        self.close();
        Ok(Pause::Finished)
    }

    /// Collects the warnings (those of the samples in progress too, for a run stopped early) and
    /// the wall time, once.
    fn close(&mut self) {
        if self.closed {
            return;
        }
        for s in [&self.trunk, &self.branch].into_iter().flatten() {
            self.warnings.extend(s.warnings.iter().cloned());
        }
        self.warnings.sort();
        self.warnings.dedup();
        self.wall_before += self.started.elapsed().as_secs_f64();
        self.closed = true;
    }

    /// A new trunk sample for the pressure `pressure` [Pa].
    fn start(&mut self, case: &ExplicitSinterCase, pressure: f64, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        let s = Sample::new(case, self.law.clone(), pressure)?;
        self.dt_used = s.driver.settings.dt;
        log(&format!("explicit_sinter: p = {pressure:.3e} Pa, {} particles, dt = {:.3e} s: prepare", s.particles.len(), self.dt_used));
        self.trunk = Some(s);
        self.net = None;
        self.stage = Stage::Prepare;
        Ok(true)
    }

    /// Compression and relaxation at `temperature_cold`, frictionless; then the law's friction.
    fn prepare(&mut self, case: &ExplicitSinterCase, plan: &Plan) -> Result<bool, Error> {
        let s = self.trunk.as_mut().unwrap();
        let done = s.advance(case, &plan.profile_max, &mut self.net, case.protocol.t_prepare, plan.interval, false, None, &mut self.clock)?;
        if done {
            self.partial = Partial { density_prepared: s.density(), ..Default::default() };
            s.driver.law.set_friction(self.law.friction());
            self.stage = Stage::Heat;
        }
        Ok(done)
    }

    /// The heating ramp to `temperature_hot`.
    fn heat(&mut self, case: &ExplicitSinterCase, plan: &Plan, pressure: f64, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        let s = self.trunk.as_mut().unwrap();
        let done = s.advance(case, &plan.profile_max, &mut self.net, plan.t_s0, plan.interval, false, None, &mut self.clock)?;
        if done {
            self.stage = Stage::Sinter { k: 0 };
            log(&format!("explicit_sinter: p = {pressure:.3e} Pa: sinter to t_s = {} s", plan.times[0]));
        }
        Ok(done)
    }

    /// Sintering the trunk to the `k`-th sintering time; then the branch `k` splits off.
    fn sinter(&mut self, case: &ExplicitSinterCase, plan: &Plan, k: usize) -> Result<bool, Error> {
        let ts = plan.times[k];
        let s = self.trunk.as_mut().unwrap();
        let done = s.advance(case, &plan.profile_max, &mut self.net, plan.t_s0 + ts, plan.interval, true, None, &mut self.clock)?;
        if done {
            self.partial.density_sintered = s.density();
            self.partial.forces_sintered = forces_of(s);
            let mut b = s.clone();
            self.bnet = None;
            if case.coupling.mode == CouplingMode::Network && self.net.is_some() {
                self.bnet = Some(b.build_network_keep(case, &plan.profiles[k])?);
            }
            self.branch = Some(b);
            self.stage = Stage::Cool { k };
        }
        Ok(done)
    }

    /// The branch `k` cools and relaxes; then its compression test starts (or it is finished).
    fn cool(&mut self, case: &ExplicitSinterCase, plan: &Plan, pressure: f64, k: usize, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        let ts = plan.times[k];
        let profile = &plan.profiles[k];
        let t_end = plan.t_s0 + ts + case.protocol.t_cool + case.protocol.t_relax;
        let b = self.branch.as_mut().unwrap();
        let done = b.advance(case, profile, &mut self.bnet, t_end, plan.interval, false, None, &mut self.clock)?;
        if done {
            let pa = &mut self.partial;
            pa.density_final = b.density();
            pa.forces_cooled = forces_of(b);
            pa.coordination_final = 2.0 * pa.forces_cooled.len() as f64 / b.particles.len() as f64;
            pa.history = b.rows.clone();
            if case.compression.enabled {
                pa.z0 = box_size(&b.driver.walls)[2];
                pa.speed = case.compression.strain_rate * pa.z0;
                b.driver.walls[5].control = WallControl::Velocity;
                b.driver.walls[5].velocity = pa.speed;
                pa.t_start = b.driver.time;
                b.rows.clear();
                let first = b.row(profile.temperature(pa.t_start), 0.0);
                b.rows.push(first);
                self.stage = Stage::Compress { k };
            } else {
                self.finish_branch(case, pressure, k, &plan.times, log);
            }
        }
        Ok(done)
    }

    /// The compression test of the branch `k`; then the branch is finished.
    fn compress(&mut self, case: &ExplicitSinterCase, plan: &Plan, pressure: f64, k: usize, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        let profile = &plan.profiles[k];
        let duration = case.compression.max_strain / case.compression.strain_rate;
        let d_int = case.compression.output_strain / case.compression.strain_rate;
        let (z0, v, t_start) = (self.partial.z0, self.partial.speed, self.partial.t_start);
        let b = self.branch.as_mut().unwrap();
        let done = b.advance(case, profile, &mut self.bnet, t_start + duration, d_int, false, Some((z0, v)), &mut self.clock)?;
        if done {
            self.finish_branch(case, pressure, k, &plan.times, log);
        }
        Ok(done)
    }

    /// The branch `k` of the current pressure is done: its results become a [`Branch`], and the
    /// protocol moves to the next sintering time or pressure.
    fn finish_branch(&mut self, case: &ExplicitSinterCase, pressure: f64, k: usize, times: &[f64], log: &mut dyn FnMut(&str)) {
        let ts = times[k];
        let b = self.branch.take().unwrap();
        self.bnet = None;
        let pa = std::mem::take(&mut self.partial);
        let compression = if case.compression.enabled { b.rows.clone() } else { Vec::new() };
        // no contact left: 0 (as in the history rows), with a warning below
        let min_f = |f: &[f64]| if f.is_empty() { 0.0 } else { f.iter().copied().fold(f64::INFINITY, f64::min) };
        let max_f = |f: &[f64]| if f.is_empty() { 0.0 } else { f.iter().copied().fold(f64::NEG_INFINITY, f64::max) };
        for (f, when) in [(&pa.forces_sintered, "after sintering"), (&pa.forces_cooled, "after cool-down")] {
            if f.is_empty() {
                self.warnings.push(format!("p = {pressure} Pa, t_sinter = {ts} s: no contacts {when}; its force extremes are reported as 0"));
            }
        }
        let (mut peak, mut eps_peak) = (if compression.is_empty() { 0.0 } else { f64::NEG_INFINITY }, 0.0);
        for r in &compression {
            if r.stress[2] > peak {
                peak = r.stress[2];
                eps_peak = r.strain;
            }
        }
        let stiffness = if compression.len() > 2 && eps_peak > 0.0 {
            let e1 = 0.2 * eps_peak;
            let r1 = compression.iter().find(|r| r.strain >= e1).unwrap();
            (r1.stress[2] - compression[0].stress[2]) / r1.strain.max(f64::MIN_POSITIVE)
        } else {
            // the stress never rose above its start (or no compression test): no resistance
            if case.compression.enabled {
                self.warnings
                    .push(format!("p = {pressure} Pa, t_sinter = {ts} s: the compression stress never rose above its initial value; stiffness reported as 0"));
            }
            0.0
        };
        self.warnings.extend(b.warnings.iter().cloned());
        self.branches.push(Branch {
            pressure,
            t_sinter: ts,
            history: pa.history,
            compression,
            min_force_sintered: min_f(&pa.forces_sintered),
            min_force_cooled: min_f(&pa.forces_cooled),
            max_force_cooled: max_f(&pa.forces_cooled),
            forces_sintered: pa.forces_sintered,
            forces_cooled: pa.forces_cooled,
            density_prepared: pa.density_prepared,
            density_sintered: pa.density_sintered,
            density_final: pa.density_final,
            coordination_final: pa.coordination_final,
            peak_stress: peak,
            strain_at_peak: eps_peak,
            stiffness,
            heat_solves: b.heat_solves,
            steps: b.driver.counters.steps,
        });
        let br = self.branches.last().unwrap();
        log(&format!(
            "  t_s = {ts}: density sintered {:.4}, final {:.4}, min force after cooling {:.3e} N, peak sigma_zz {:.4e} Pa",
            br.density_sintered, br.density_final, br.min_force_cooled, br.peak_stress
        ));
        // the next branch starts from the same preparation
        self.partial = Partial { density_prepared: pa.density_prepared, ..Default::default() };
        if k + 1 < times.len() {
            self.stage = Stage::Sinter { k: k + 1 };
            log(&format!("explicit_sinter: p = {pressure:.3e} Pa: sinter to t_s = {} s", times[k + 1]));
        } else {
            let s = self.trunk.take().unwrap();
            self.warnings.extend(s.warnings.iter().cloned());
            self.net = None;
            self.pressure_index += 1;
            self.stage = Stage::Start;
        }
    }
}

/// The protocol of one law behind one object (the run object [`super::ExplicitRun`] holds it).
pub trait Protocol {
    /// [`Machine::run_to`].
    fn run_to(&mut self, case: &ExplicitSinterCase, plan: &Plan, sink: Option<&CheckpointSink>, log: &mut dyn FnMut(&str), budget: u64)
    -> Result<Pause, Error>;
    /// Explicit steps so far (all samples).
    fn steps(&self) -> u64;
    /// Where the protocol is, and the index of its pressure.
    fn stage(&self) -> (Stage, usize);
    /// The sample being advanced: the branch, else the trunk (none between two pressures).
    fn current(&self) -> Option<Current<'_>>;
    /// The finished branches, the step, the warnings (the samples' in progress included) and the
    /// wall time.
    fn into_finished(self: Box<Self>) -> Finished;
}

/// A view of the sample being advanced.
pub struct Current<'a> {
    pub(super) particles: &'a crate::particles::Particles,
    /// Time of the sample [s].
    pub(super) time: f64,
    /// Solid fraction ΣV_i/V_box [1].
    pub(super) density: f64,
    /// Particle–particle contacts and their normal force [N] (positive repulsive).
    pub(super) contacts: Vec<((u32, u32), f64)>,
    /// The sample's history rows so far (in the compression test: its compression rows).
    pub(super) rows: &'a [Row],
}

impl<M: SinterLaw> Protocol for Machine<M> {
    fn run_to(
        &mut self,
        case: &ExplicitSinterCase,
        plan: &Plan,
        sink: Option<&CheckpointSink>,
        log: &mut dyn FnMut(&str),
        budget: u64,
    ) -> Result<Pause, Error> {
        Machine::run_to(self, case, plan, sink, log, budget)
    }
    fn steps(&self) -> u64 {
        self.clock.steps
    }
    fn stage(&self) -> (Stage, usize) {
        (self.stage, self.pressure_index)
    }
    fn current(&self) -> Option<Current<'_>> {
        let s = self.branch.as_ref().or(self.trunk.as_ref())?;
        Some(Current {
            particles: &s.particles,
            time: s.driver.time,
            density: s.density(),
            contacts: s.driver.contact_states().into_iter().map(|(p, f, _)| (p, f)).collect(),
            rows: &s.rows,
        })
    }
    fn into_finished(mut self: Box<Self>) -> Finished {
        self.close();
        let m = *self;
        Finished { branches: m.branches, dt_used: m.dt_used, warnings: m.warnings, wall_before: m.wall_before }
    }
}

/// The protocol of `case` for one law, new or continued from `resume` (the checkpoint's text and
/// its path).
pub(super) fn start_law<M: SinterLaw>(
    case: &ExplicitSinterCase,
    law: M,
    resume: Option<(&str, &Path)>,
    log: &mut dyn FnMut(&str),
) -> Result<Box<dyn Protocol>, Error> {
    let every = case.output.checkpoint_every as u64;
    let m = match resume {
        None => Machine::new(law, every),
        Some((text, path)) => {
            let ck: ExplicitCheckpoint<M::State> = serde_json::from_str(text).map_err(|e| IoError::new(path, e))?;
            let (steps, stage) = (ck.steps, ck.stage);
            let m = Machine::restore(case, law, ck, every).map_err(|e| ConfigError::invalid(format!("{}: {e}", path.display())))?;
            log(&format!("resumed from the checkpoint at step {steps} ({stage:?}, pressure {} of {})", m.pressure_index + 1, case.walls.pressures.len()));
            m
        }
    };
    Ok(Box::new(m))
}

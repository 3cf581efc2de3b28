//! The protocol's state machine (module docs of [`super`]): prepare → heat → per sintering time
//! sinter the trunk, then a branch that cools, relaxes and is compressed; one method per stage,
//! each advancing until its end or the next checkpoint.

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

/// Counts the explicit steps of a whole protocol and says when a checkpoint is due.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepClock {
    /// Steps so far (all pressures and branches).
    pub steps: u64,
    /// Checkpoint interval [steps]; 0: never.
    pub every: u64,
}

impl StepClock {
    pub(super) fn tick(&mut self) -> bool {
        self.steps += 1;
        self.every > 0 && self.steps.is_multiple_of(self.every)
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
}

/// What a finished protocol hands to the run's result.
pub struct Finished {
    pub branches: Vec<Branch>,
    pub dt_used: f64,
    pub warnings: Vec<String>,
    pub wall_before: f64,
}

/// The values of a case every stage reads (computed once per [`Machine::run`]).
struct Plan {
    /// Sorted sintering times [s].
    times: Vec<f64>,
    /// History row interval [s].
    interval: f64,
    /// Start of sintering [s].
    t_s0: f64,
    /// The temperature history of the longest sintering time (the trunk's).
    profile_max: Profile,
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
            clock: StepClock { steps: 0, every },
            wall_before: 0.0,
        }
    }

    /// Runs the protocol from the current stage to its end; `Ok(false)` when stopped after a
    /// checkpoint by `sink.stop_after`.
    fn run(&mut self, case: &ExplicitSinterCase, model: &str, mut sink: Option<&mut CheckpointSink>, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        let wall = std::time::Instant::now();
        let times = case.sinter_times();
        let interval = case.output_interval();
        let t_s0 = case.t_sinter_start();
        let profile_max = case.profile(*times.last().unwrap())?;
        let plan = Plan { times, interval, t_s0, profile_max };
        while self.pressure_index < case.walls.pressures.len() {
            let pressure = case.walls.pressures[self.pressure_index];
            let done = match self.stage {
                Stage::Start => self.start(case, pressure, log)?,
                Stage::Prepare => self.prepare(case, &plan)?,
                Stage::Heat => self.heat(case, &plan, pressure, log)?,
                Stage::Sinter { k } => self.sinter(case, &plan, k)?,
                Stage::Cool { k } => self.cool(case, &plan, pressure, k, log)?,
                Stage::Compress { k } => self.compress(case, &plan, pressure, k, log)?,
            };
            if !done
                && let Some(sink) = sink.as_deref_mut()
                && self.write_checkpoint(sink, model, wall.elapsed().as_secs_f64())?
            {
                return Ok(false);
            }
        }
        self.warnings.sort();
        self.warnings.dedup();
        self.wall_before += wall.elapsed().as_secs_f64();
        Ok(true)
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
                self.bnet = Some(b.build_network_keep(case, &case.profile(ts)?)?);
            }
            self.branch = Some(b);
            self.stage = Stage::Cool { k };
        }
        Ok(done)
    }

    /// The branch `k` cools and relaxes; then its compression test starts (or it is finished).
    fn cool(&mut self, case: &ExplicitSinterCase, plan: &Plan, pressure: f64, k: usize, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        let ts = plan.times[k];
        let profile = case.profile(ts)?;
        let t_end = plan.t_s0 + ts + case.protocol.t_cool + case.protocol.t_relax;
        let b = self.branch.as_mut().unwrap();
        let done = b.advance(case, &profile, &mut self.bnet, t_end, plan.interval, false, None, &mut self.clock)?;
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
        let ts = plan.times[k];
        let profile = case.profile(ts)?;
        let duration = case.compression.max_strain / case.compression.strain_rate;
        let d_int = case.compression.output_strain / case.compression.strain_rate;
        let (z0, v, t_start) = (self.partial.z0, self.partial.speed, self.partial.t_start);
        let b = self.branch.as_mut().unwrap();
        let done = b.advance(case, &profile, &mut self.bnet, t_start + duration, d_int, false, Some((z0, v)), &mut self.clock)?;
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

/// Runs (or continues, from `resume`: the checkpoint's text and its path) the machine of one law.
pub(super) fn run_law<M: SinterLaw>(
    case: &ExplicitSinterCase,
    law: M,
    sink: Option<&mut CheckpointSink>,
    resume: Option<(&str, &Path)>,
    log: &mut dyn FnMut(&str),
) -> Result<Option<Finished>, Error> {
    let every = case.output.checkpoint_every as u64;
    let mut m = match resume {
        None => Machine::new(law, every),
        Some((text, path)) => {
            let ck: ExplicitCheckpoint<M::State> = serde_json::from_str(text).map_err(|e| IoError::new(path, e))?;
            let (steps, stage) = (ck.steps, ck.stage);
            let m = Machine::restore(case, law, ck, every).map_err(|e| ConfigError::invalid(format!("{}: {e}", path.display())))?;
            log(&format!("resumed from the checkpoint at step {steps} ({stage:?}, pressure {} of {})", m.pressure_index + 1, case.walls.pressures.len()));
            m
        }
    };
    let done = m.run(case, M::NAME, sink, log)?;
    Ok(done.then_some(Finished { branches: m.branches, dt_used: m.dt_used, warnings: m.warnings, wall_before: m.wall_before }))
}

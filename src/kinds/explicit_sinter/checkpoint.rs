//! Checkpoints of `explicit_sinter` runs (docs/explicit.md): `DIR/checkpoint.json` holds the case
//! as run, where the protocol is, the trunk sample and the branch in progress, and the finished
//! branches; a resumed run continues bit for bit.

use super::EXPLICIT_CHECKPOINT_FORMAT;
use super::case::ExplicitSinterCase;
use super::machine::{Machine, Partial, Stage};
use super::output::{Branch, Row};
use super::sample::Sample;
use crate::error::{Error, IoError};
use crate::explicit::sinter::SinterLaw;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

type V3 = Vector3<f64>;

/// A [`Sample`] in a checkpoint: what is not rebuilt from the case by [`Sample::new`].
#[derive(Debug, Clone, Serialize, Deserialize)]
struct SampleState<S> {
    pressure: f64,
    #[serde(with = "crate::io::serde_v3::vec")]
    position: Vec<V3>,
    #[serde(with = "crate::io::serde_v3::vec")]
    velocity: Vec<V3>,
    #[serde(with = "crate::io::serde_v3::vec")]
    angular_velocity: Vec<V3>,
    #[serde(with = "crate::io::serde_v3::vec")]
    rotation: Vec<V3>,
    radius: Vec<f64>,
    temperature: Vec<f64>,
    /// The law's particle friction at the checkpoint (the preparation runs frictionless).
    friction: f64,
    driver: crate::explicit::DriverState<S>,
    fixed: Vec<bool>,
    heat_solves: u64,
    since_heat: u64,
    radius_drift: f64,
    acc: [f64; 3],
    acc_n: u64,
    rows: Vec<Row>,
    warnings: Vec<String>,
    /// The sample had a heat network (rebuilt on resume from `fixed`, which fully defines it).
    network: bool,
}

impl<M: SinterLaw> Sample<M> {
    fn save(&self, network: bool) -> SampleState<M::State> {
        let p = &self.particles;
        SampleState {
            pressure: self.pressure,
            position: p.position.clone(),
            velocity: p.velocity.clone(),
            angular_velocity: p.angular_velocity.clone(),
            rotation: p.rotation.clone(),
            radius: p.radius.clone(),
            temperature: p.temperature.clone(),
            friction: self.driver.law.friction(),
            driver: self.driver.save_state(),
            fixed: self.fixed.clone(),
            heat_solves: self.heat_solves,
            since_heat: self.since_heat,
            radius_drift: self.radius_drift,
            acc: self.acc,
            acc_n: self.acc_n,
            rows: self.rows.clone(),
            warnings: self.warnings.clone(),
            network,
        }
    }

    /// The sample of `st`: built again from the case (masses, radii at T_cold, step), then the
    /// saved state laid over it; `what` names it in errors.
    fn restore(case: &ExplicitSinterCase, law: M, st: SampleState<M::State>, what: &str) -> Result<Self, String> {
        let mut s = Sample::new(case, law, st.pressure).map_err(|e| format!("{what}: {e}"))?;
        let n = s.particles.len();
        let vecs = [("position", &st.position), ("velocity", &st.velocity), ("angular_velocity", &st.angular_velocity), ("rotation", &st.rotation)];
        for (k, v) in vecs {
            if v.len() != n || !v.iter().all(|x| x.iter().all(|c| c.is_finite())) {
                return Err(format!("{what}.{k}: {} values, expected {n} finite vectors (sample.particles = {n})", v.len()));
            }
        }
        if st.radius.len() != n || !st.radius.iter().all(|r| r.is_finite() && *r > 0.0) {
            return Err(format!("{what}.radius: expected {n} positive radii [m]"));
        }
        if st.temperature.len() != n || !st.temperature.iter().all(|t| t.is_finite() && *t > 0.0) {
            return Err(format!("{what}.temperature: expected {n} positive temperatures [K]"));
        }
        if st.fixed.len() != n {
            return Err(format!("{what}.fixed: {} flags, expected {n}", st.fixed.len()));
        }
        if !(st.friction.is_finite() && st.friction >= 0.0) || !(st.radius_drift.is_finite() && st.acc.iter().all(|a| a.is_finite())) {
            return Err(format!("{what}: friction, radius drift or stress accumulator out of range"));
        }
        s.driver.restore_state(st.driver, n).map_err(|e| format!("{what}.driver.{e}"))?;
        let p = &mut s.particles;
        p.position = st.position;
        p.velocity = st.velocity;
        p.angular_velocity = st.angular_velocity;
        p.rotation = st.rotation;
        p.radius = st.radius;
        p.temperature = st.temperature;
        s.driver.law.set_friction(st.friction);
        s.fixed = st.fixed;
        s.heat_solves = st.heat_solves;
        s.since_heat = st.since_heat;
        s.radius_drift = st.radius_drift;
        s.acc = st.acc;
        s.acc_n = st.acc_n;
        s.rows = st.rows;
        s.warnings = st.warnings;
        Ok(s)
    }
}

/// `DIR/checkpoint.json` of an `explicit_sinter` run: the case as run, where the protocol is, the
/// trunk sample and the branch in progress, and the finished branches.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(super) struct ExplicitCheckpoint<S> {
    format: String,
    case_toml: String,
    model: String,
    pressure_index: usize,
    pub(super) stage: Stage,
    pub(super) steps: u64,
    dt_used: f64,
    trunk: Option<SampleState<S>>,
    branch: Option<SampleState<S>>,
    partial: Partial,
    branches: Vec<Branch>,
    warnings: Vec<String>,
    /// Wall time before the checkpoint [s].
    wall_before: f64,
}

/// Checkpoint writing of a run: where, and the case text the checkpoint carries.
pub struct CheckpointSink {
    pub dir: std::path::PathBuf,
    /// The case as run (overrides applied), TOML.
    pub case_toml: String,
    /// Stop right after the checkpoint at or after this step (as if killed there; for tests).
    pub stop_after: Option<u64>,
}

impl<M: SinterLaw> Machine<M> {
    fn checkpoint(&self, case_toml: &str, model: &str, wall: f64) -> ExplicitCheckpoint<M::State> {
        ExplicitCheckpoint {
            format: EXPLICIT_CHECKPOINT_FORMAT.into(),
            case_toml: case_toml.into(),
            model: model.into(),
            pressure_index: self.pressure_index,
            stage: self.stage,
            steps: self.clock.steps,
            dt_used: self.dt_used,
            trunk: self.trunk.as_ref().map(|s| s.save(self.net.is_some())),
            branch: self.branch.as_ref().map(|s| s.save(self.bnet.is_some())),
            partial: self.partial.clone(),
            branches: self.branches.clone(),
            warnings: self.warnings.clone(),
            wall_before: self.wall_before + wall,
        }
    }

    /// The machine of a checkpoint, checked against the case (the error says what does not fit).
    pub(super) fn restore(case: &ExplicitSinterCase, law: M, ck: ExplicitCheckpoint<M::State>, every: u64) -> Result<Self, String> {
        let times = case.sinter_times().len();
        let np = case.walls.pressures.len();
        if ck.pressure_index > np || (ck.pressure_index == np && ck.stage != Stage::Start) {
            return Err(format!("pressure_index = {}: the case has {np} pressures", ck.pressure_index));
        }
        let k = match ck.stage {
            Stage::Sinter { k } | Stage::Cool { k } | Stage::Compress { k } => Some(k),
            _ => None,
        };
        if let Some(k) = k
            && k >= times
        {
            return Err(format!("stage {:?}: the case has {times} sintering times", ck.stage));
        }
        let needs_trunk = ck.stage != Stage::Start;
        let needs_branch = matches!(ck.stage, Stage::Cool { .. } | Stage::Compress { .. });
        if ck.trunk.is_some() != needs_trunk || ck.branch.is_some() != needs_branch {
            return Err(format!("stage {:?} does not match the samples it carries (trunk {}, branch {})", ck.stage, ck.trunk.is_some(), ck.branch.is_some()));
        }
        if ck.branches.len() != ck.pressure_index * times + k.unwrap_or(0) {
            return Err(format!("{} finished branches do not fit pressure {} at stage {:?}", ck.branches.len(), ck.pressure_index, ck.stage));
        }
        if !(ck.dt_used.is_finite() && ck.dt_used >= 0.0) {
            return Err(format!("dt_used = {}: expected a finite step [s]", ck.dt_used));
        }
        let mut m = Machine::new(law.clone(), every);
        let profile_max = case.profile(*case.sinter_times().last().unwrap()).map_err(|e| e.to_string())?;
        if let Some(st) = ck.trunk {
            let net = st.network;
            let mut s = Sample::restore(case, law.clone(), st, "trunk")?;
            if net {
                m.net = Some(s.build_network_keep(case, &profile_max).map_err(|e| e.to_string())?);
            }
            m.trunk = Some(s);
        }
        if let Some(st) = ck.branch {
            let net = st.network;
            let mut s = Sample::restore(case, law.clone(), st, "branch")?;
            if net {
                let ts = case.sinter_times()[k.unwrap_or(0)];
                m.bnet = Some(s.build_network_keep(case, &case.profile(ts).map_err(|e| e.to_string())?).map_err(|e| e.to_string())?);
            }
            m.branch = Some(s);
        }
        m.pressure_index = ck.pressure_index;
        m.stage = ck.stage;
        m.partial = ck.partial;
        m.branches = ck.branches;
        m.warnings = ck.warnings;
        m.dt_used = ck.dt_used;
        m.clock.steps = ck.steps;
        m.wall_before = ck.wall_before;
        Ok(m)
    }

    /// Writes the checkpoint of the current state into `sink` (`wall`: wall time of this call of
    /// [`Machine::run`] [s]); true when the run is to stop after it (`sink.stop_after`).
    pub(super) fn write_checkpoint(&self, sink: &CheckpointSink, model: &str, wall: f64) -> Result<bool, Error> {
        let ck = self.checkpoint(&sink.case_toml, model, wall);
        let path = sink.dir.join("checkpoint.json");
        let json = serde_json::to_string(&ck).map_err(|e| IoError::new(&path, e))?;
        crate::io::write_checkpoint_json(&path, &json)?;
        tracing::debug!("checkpoint at step {} ({:?}, pressure {}) written to {}", self.clock.steps, self.stage, self.pressure_index + 1, path.display());
        Ok(sink.stop_after.is_some_and(|k| self.clock.steps >= k))
    }
}

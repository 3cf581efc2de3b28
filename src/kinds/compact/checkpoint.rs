//! Checkpoints of a compact run: what `DIR/checkpoint.json` holds, writing it atomically,
//! reading and validating it, and rebuilding a [`Simulation`] from it bit for bit.

use super::*;
use crate::coupled::*;
use crate::error::{ConfigError, Error, IoError};
use crate::models::diffusion7::Contact7;
use crate::models::ode::OdeStats;
use nalgebra::Vector3;
use std::path::Path;

/// Output bookkeeping that a checkpoint carries.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct OutputState {
    pub next_snap: usize,
    pub next_cond: usize,
    pub cond_results: Vec<serde_json::Value>,
    /// Next entry of `output.correction_histogram_at` to write [1].
    #[serde(default)]
    pub next_hist: usize,
    /// The histograms written so far (time [s], mean and std of ΔL̄/L0 [1], files).
    #[serde(default)]
    pub hist_results: Vec<serde_json::Value>,
    /// Lines of series.csv (header included) at the checkpoint.
    pub series_lines: usize,
    pub snapshots: usize,
    pub vtu_entries: Vec<(f64, String, String)>,
    /// Wall time spent before the checkpoint [s].
    pub wall_before: f64,
}

/// Everything needed to continue a run bit for bit (`DIR/checkpoint.json`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Checkpoint {
    pub format: String,
    pub case_toml: String,
    pub base_dir: std::path::PathBuf,
    pub t: f64,
    pub dt: f64,
    pub step: u64,
    pub rejected: u64,
    pub ode: OdeStats,
    pub timing: Timing,
    pub heat_in: f64,
    pub heat_stored: f64,
    pub heat_scale: f64,
    pub warnings: Vec<String>,
    pub limited_corrections: u64,
    pub position: Vec<[f64; 3]>,
    pub temperature: Vec<f64>,
    pub rotation: Vec<[f64; 3]>,
    /// Mechanics counters: Newton iterations, numeric factorisations, largest final scaled residual.
    #[serde(default)]
    pub mechanics_counters: (u64, u64, f64),
    /// Counters of `mechanics_profile`: topology analyses and CG iterations (so that a resumed
    /// run's summary equals the uninterrupted one's; absent in older checkpoints: zero).
    #[serde(default)]
    pub mechanics_profile_counts: (u64, u64),
    /// `mechanics_profile.updates`: changes of the bond set served by the low-rank factor update
    /// (`mechanics.update_rank`); left out when zero (absent in older checkpoints: zero).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mechanics_updates: u64,
    pub pairs: Vec<[u32; 2]>,
    pub contacts: Vec<Contact7>,
    pub dl_bar: Vec<f64>,
    pub substeps: Vec<u32>,
    /// Each contact's diffusion dose (docs/diffusion7.md (V1)); absent in older checkpoints: zero.
    #[serde(default)]
    pub dose: Vec<crate::coupled::dose::Dose>,
    /// The lowest contact temperature per material [K] (absent in older checkpoints).
    #[serde(default)]
    pub lowest_contact_temperature: Vec<f64>,
    /// The heat network's BDF2 history; absent for runs without a heat solve.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heat_history: Option<(Vec<f64>, f64)>,
    pub output: OutputState,
    /// The applied load's state (docs/pressure.md); absent for runs without a load.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load: Option<crate::coupled::load::LoadCheckpoint>,
    /// The periodic cell (docs/mechanics.md "Periodic cell"); absent for walled runs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell: Option<crate::coupled::cell::CellState>,
    /// With `mechanics.sliding = "viscous"`: the stored tangential link force per contact [N]
    /// (docs/mechanics.md (B27)); absent without sliding.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sliding_tangential: Vec<[f64; 3]>,
    /// With sliding: the stored link moment per contact (docs/mechanics.md (B30)) [N·m]; absent
    /// without sliding.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sliding_moment: Vec<[f64; 3]>,
}

/// Format tag of compact checkpoints.
pub const CHECKPOINT_FORMAT: &str = "sinterdem-checkpoint-1";

impl Simulation {
    pub(crate) fn checkpoint(&self, output: OutputState) -> Checkpoint {
        let p = &self.prep.scene.particles;
        Checkpoint {
            format: CHECKPOINT_FORMAT.into(),
            case_toml: self.source.0.clone(),
            base_dir: self.source.1.clone(),
            t: self.t,
            dt: self.dt,
            step: self.step,
            rejected: self.rejected,
            ode: self.ode,
            timing: self.timing,
            heat_in: self.heat_in,
            heat_stored: self.heat_stored,
            heat_scale: self.heat_scale,
            warnings: self.warnings.clone(),
            limited_corrections: self.limited_corrections,
            position: p.position.iter().map(|x| [x.x, x.y, x.z]).collect(),
            temperature: p.temperature.clone(),
            rotation: self.mechanics.rotation.iter().map(|x| [x.x, x.y, x.z]).collect(),
            mechanics_counters: (self.mechanics.newton_iterations, self.mechanics.factorizations, self.mechanics.max_residual),
            mechanics_profile_counts: (self.mechanics.profile.topology_changes, self.mechanics.profile.cg_iterations),
            mechanics_updates: self.mechanics.profile.updates,
            pairs: self.contacts.pairs.clone(),
            contacts: self.contacts.state.clone(),
            dl_bar: self.contacts.dl_bar.clone(),
            substeps: self.contacts.substeps.clone(),
            dose: self.contacts.dose.clone(),
            lowest_contact_temperature: self.lowest_contact_temperature.clone(),
            heat_history: self.heat.as_ref().and_then(|h| h.history().cloned()),
            output,
            load: self.load.as_ref().map(|l| l.to_checkpoint()),
            cell: self.cell.clone(),
            sliding_tangential: self.mechanics.tangential.iter().map(|x| [x.x, x.y, x.z]).collect(),
            sliding_moment: self.mechanics.moment.iter().map(|x| [x.x, x.y, x.z]).collect(),
        }
    }

    /// Rebuilds a simulation from a checkpoint: the case is prepared again from its text (so the
    /// initial packing, planes and constraints are the same), then the state is restored.
    pub fn from_checkpoint(ck: &Checkpoint, log: &mut dyn FnMut(&str)) -> Result<(Simulation, OutputState), Error> {
        if ck.format != CHECKPOINT_FORMAT {
            return Err(ConfigError::invalid(format!("checkpoint format \"{}\" is not {CHECKPOINT_FORMAT}", ck.format)).into());
        }
        let value: toml::Value = toml::Value::Table(ck.case_toml.parse::<toml::Table>().map_err(|e| ConfigError::invalid(format!("checkpoint case: {e}")))?);
        let mut sim = prepare(value, &ck.base_dir, &mut |_| {})?;
        let n = sim.prep.scene.particles.len();
        ck.validate(n, &sim.settings)?;
        let p = &mut sim.prep.scene.particles;
        p.position = ck.position.iter().map(|x| Vector3::new(x[0], x[1], x[2])).collect();
        p.temperature = ck.temperature.clone();
        sim.mechanics.rotation = ck.rotation.iter().map(|x| Vector3::new(x[0], x[1], x[2])).collect();
        sim.mechanics.tangential = ck.sliding_tangential.iter().map(|x| Vector3::new(x[0], x[1], x[2])).collect();
        sim.mechanics.moment = ck.sliding_moment.iter().map(|x| Vector3::new(x[0], x[1], x[2])).collect();
        (sim.mechanics.newton_iterations, sim.mechanics.factorizations, sim.mechanics.max_residual) = ck.mechanics_counters;
        (sim.mechanics.profile.topology_changes, sim.mechanics.profile.cg_iterations) = ck.mechanics_profile_counts;
        sim.mechanics.profile.updates = ck.mechanics_updates;
        let mut dose = ck.dose.clone();
        dose.resize(ck.pairs.len(), Default::default());
        sim.contacts = Contacts { pairs: ck.pairs.clone(), state: ck.contacts.clone(), dl_bar: ck.dl_bar.clone(), substeps: ck.substeps.clone(), dose };
        sim.lowest_contact_temperature = ck.lowest_contact_temperature.clone();
        if let Some(h) = sim.heat.as_mut() {
            h.set_history(ck.heat_history.clone());
        }
        sim.t = ck.t;
        sim.dt = ck.dt;
        sim.step = ck.step;
        sim.rejected = ck.rejected;
        sim.ode = ck.ode;
        sim.timing = ck.timing;
        sim.heat_in = ck.heat_in;
        sim.heat_stored = ck.heat_stored;
        sim.heat_scale = ck.heat_scale;
        sim.warnings = ck.warnings.clone();
        sim.limited_corrections = ck.limited_corrections;
        if let (Some(l), Some(c)) = (sim.load.as_mut(), ck.load.as_ref()) {
            l.restore(c);
        }
        if sim.cell.is_some() != ck.cell.is_some() {
            return Err(
                ConfigError::invalid("checkpoint: the periodic cell of the case and of the checkpoint do not match (mechanics.boundary changed?)").into()
            );
        }
        if ck.cell.is_some() {
            sim.cell = ck.cell.clone();
        }
        validate_contact_geometry(&sim)?;
        log(&format!("resumed from the checkpoint at t = {} s (step {}, {} contacts)", sim.t, sim.step, sim.contacts.len()));
        Ok((sim, ck.output.clone()))
    }
}

/// Checks every stored contact against the restored positions and radii (issue 38): the centre
/// distance (minimum image in a periodic cell) of a pair must lie in (|r_a − r_b|, 1.5·(r_a + r_b)]
/// (the bound of `checkpoint.contacts[k].l0`; a contact is found touching and stays bonded near
/// it), and the contact's initial radii are those of its two particles.
fn validate_contact_geometry(sim: &Simulation) -> Result<(), ConfigError> {
    let r = &sim.prep.scene.particles.radius;
    for (k, (&[i, j], c)) in sim.contacts.pairs.iter().zip(&sim.contacts.state).enumerate() {
        let (ra, rb) = (r[i as usize], r[j as usize]);
        let d = sim.distance(i, j);
        let (lo, hi) = ((ra - rb).abs(), 1.5 * (ra + rb));
        if !(d > lo && d <= hi) {
            return Err(ConfigError::OutOfRange {
                key: format!("checkpoint.pairs[{k}] = [{i}, {j}]"),
                value: d,
                range: format!(
                    "({}, {}] (centre distance of a contact: |r_a − r_b|, 1.5·(r_a + r_b) for the radii of particles {i} and {j})",
                    crate::error::fmt_value(lo),
                    crate::error::fmt_value(hi)
                ),
                unit: "m".into(),
            });
        }
        let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
        if !(same(c.r0[0], ra) && same(c.r0[1], rb)) && !(same(c.r0[0], rb) && same(c.r0[1], ra)) {
            return Err(ConfigError::inconsistent(
                format!("checkpoint.contacts[{k}].r0"),
                format!("[{}, {}] m are not the radii of particles {i} and {j} ({} m, {} m)", c.r0[0], c.r0[1], ra, rb),
            ));
        }
    }
    Ok(())
}

/// Writes `dir/checkpoint.json` atomically (temporary file, then rename).
pub(crate) fn write_checkpoint(dir: &Path, ck: &Checkpoint) -> Result<(), IoError> {
    let path = dir.join("checkpoint.json");
    let text = serde_json::to_string(ck).map_err(|e| IoError::new(&path, e))?;
    crate::io::write_checkpoint_json(&path, &text)
}

/// Reads `dir/checkpoint.json`.
pub fn read_checkpoint(dir: &Path) -> Result<Checkpoint, Error> {
    let path = dir.join("checkpoint.json");
    let text = crate::io::read_checkpoint_json(&path)?;
    Ok(serde_json::from_str(&text).map_err(|e| IoError::new(&path, e))?)
}

/// `sinterdem resume DIR`: continues the run whose checkpoint is in `dir`.
pub fn resume(dir: &Path, progress: bool, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    let ck = read_checkpoint(dir)?;
    let (sim, out_state) = Simulation::from_checkpoint(&ck, log)?;
    run_from(sim, dir, progress, log, Some(out_state), None)
}

fn is_zero(v: &u64) -> bool {
    *v == 0
}

//! What a heat run writes: the series columns, snapshots, checkpoints and the summary.

use super::step::{Plan, Step};
use super::{HEAT_CHECKPOINT_FORMAT, HeatCheckpoint, HeatLoop};
use crate::error::{Error, IoError};
use crate::heat::HeatNetwork;
use crate::heat::balance::energy_balance_rel;
use crate::io::{self, Column, Snapshot, SnapshotWriter};
use crate::scene::Prepared;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// One row of the heat series (`series.csv`), read by [`COLUMNS`].
pub struct HeatRow {
    /// Time [s] and the step's Δt [s].
    pub time: f64,
    pub dt: f64,
    /// Mean, min and max particle temperature [K].
    pub mean: f64,
    pub min: f64,
    pub max: f64,
    /// Heat into the free particles over the step [J].
    pub heat_in_step: f64,
    /// Stored heat of the free particles [J].
    pub stored: f64,
    /// Heat in since the start [J].
    pub heat_in: f64,
    /// Radiation (and property) iterations of the step.
    pub iterations: f64,
}

/// The heat series' columns (header, row and labels are derived from this list).
pub const COLUMNS: &[Column<HeatRow>] = &[
    Column { name: "time_s", unit: "s", get: |r| r.time },
    Column { name: "dt_s", unit: "s", get: |r| r.dt },
    Column { name: "mean_temperature_K", unit: "K", get: |r| r.mean },
    Column { name: "min_temperature_K", unit: "K", get: |r| r.min },
    Column { name: "max_temperature_K", unit: "K", get: |r| r.max },
    Column { name: "heat_in_J", unit: "J", get: |r| r.heat_in_step },
    Column { name: "stored_heat_J", unit: "J", get: |r| r.stored },
    Column { name: "heat_in_cumulative_J", unit: "J", get: |r| r.heat_in },
    Column { name: "radiation_iterations", unit: "1", get: |r| r.iterations },
];

impl HeatRow {
    /// The row after `step`, with the loop state `st` and the temperatures `temps` [K].
    pub(super) fn new(st: &HeatLoop, step: &Step, temps: &[f64], net: &HeatNetwork) -> HeatRow {
        let (mean, min, max) = stats(temps);
        HeatRow {
            time: st.t,
            dt: step.dt,
            mean,
            min,
            max,
            heat_in_step: step.heat_in,
            stored: net.stored_heat(temps),
            heat_in: st.heat_in,
            iterations: step.iterations as f64,
        }
    }
}

/// Mean, min and max of `t`.
fn stats(t: &[f64]) -> (f64, f64, f64) {
    let mean = t.iter().sum::<f64>() / t.len() as f64;
    let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (mean, lo, hi)
}

/// The snapshot writer, the run parameters it writes once, and (with `collect`) the temperatures
/// at the snapshot times.
pub(super) struct Snapshots {
    pub writer: SnapshotWriter,
    parameters: io::Parameters,
    collect: bool,
    pub collected: Vec<(f64, Vec<f64>)>,
}

impl Snapshots {
    pub fn new(writer: SnapshotWriter, case: &crate::scene::case::Case, collect: bool) -> Snapshots {
        let parameters = io::Parameters {
            case_toml: toml::to_string(case).unwrap_or_else(|e| format!("# the case could not be written as TOML: {e}")),
            materials_json: serde_json::to_string_pretty(&case.materials).unwrap_or_default(),
        };
        Snapshots { writer, parameters, collect, collected: Vec::new() }
    }

    /// Writes the snapshots of `times` due at `limit` [s] (advancing `st.next_snap`).
    pub fn write_due(&mut self, times: &[f64], st: &mut HeatLoop, limit: f64, prep: &Prepared) -> Result<(), IoError> {
        let (p, pipes) = (&prep.scene.particles, &prep.pipes);
        // one snapshot per step however many snapshot times the step passed (a step longer than
        // the snapshot interval wrote the same state once per due time: 73 083 snapshots of a
        // 60-step run took minutes a step; issue 26, run-path fuzzer)
        if st.next_snap < times.len() && times[st.next_snap] <= limit {
            if self.collect {
                self.collected.push((st.t, p.temperature.clone()));
            }
            self.writer.write(&Snapshot {
                time: st.t,
                step: st.steps as u64,
                position: &p.position,
                radius: &p.radius,
                temperature: &p.temperature,
                contacts: &pipes.pairs,
                contact_data: vec![("neck_radius_m", &pipes.neck), ("conductance_W_per_K", &pipes.conductance), ("overlap_m", &pipes.overlap)],
                particle_data: vec![],
                particle_vectors: vec![],
                parameters: Some(self.parameters.clone()),
            })?;
            while st.next_snap < times.len() && times[st.next_snap] <= limit {
                st.next_snap += 1;
            }
        }
        Ok(())
    }
}

/// Writes `out/checkpoint.json` (atomically) after the step that ended in `st`.
/// SHA-256 (hex) of the bits of `values`.
pub(super) fn values_sha256(values: &[f64]) -> String {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    for v in values {
        h.update(v.to_bits().to_le_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

pub(super) fn write_checkpoint(
    prep: &Prepared,
    out: &Path,
    st: &HeatLoop,
    plan: &Plan,
    snaps: &SnapshotWriter,
    net: &HeatNetwork,
    wall: Instant,
) -> Result<(), Error> {
    let (text, base) = prep.source.clone().unwrap_or_else(|| (toml::to_string(&prep.case).unwrap_or_default(), std::path::PathBuf::from(".")));
    let state = HeatLoop {
        hist_dt: None,
        factor_sha256: net.factored_values().map(values_sha256),
        dt_next: plan.control.is_some().then(|| st.dt_next.unwrap_or(plan.dt0)),
        snapshots: snaps.count(),
        vtu_entries: snaps.vtu_entries(),
        wall_before: st.wall_before + wall.elapsed().as_secs_f64(),
        ..st.clone()
    };
    let hc = HeatCheckpoint {
        format: HEAT_CHECKPOINT_FORMAT.into(),
        case_toml: text,
        base_dir: base,
        state,
        temperature: prep.scene.particles.temperature.clone(),
        bdf2: net.history().cloned(),
    };
    let path = out.join("checkpoint.json");
    let json = serde_json::to_string(&hc).map_err(|e| IoError::new(&path, e))?;
    io::write_checkpoint_json(&path, &json)?;
    Ok(())
}

/// Writes `out/summary.json` (and closes the HDF5 file), logs the closing line, and returns the
/// summary.
pub(super) fn finish(
    prep: &Prepared,
    out: &Path,
    st: &HeatLoop,
    plan: &Plan,
    net: &HeatNetwork,
    snaps: &SnapshotWriter,
    wall: Instant,
    stop_reason: Option<&str>,
    log: &mut dyn FnMut(&str),
) -> Result<serde_json::Value, Error> {
    let temps = &prep.scene.particles.temperature;
    let (mean, lo, hi) = stats(temps);
    let balance = if prep.isothermal.is_some() { 0.0 } else { energy_balance_rel(st.stored, st.heat_in, st.scale, st.stored0) };
    let mut summary = summary(prep, st, plan, net, snaps, balance, st.wall_before + wall.elapsed().as_secs_f64());
    if let Some(r) = stop_reason {
        // only a run that ended early says so (a complete heat run's summary has no such fields)
        summary["completed"] = json!(false);
        summary["stop_reason"] = json!(r);
    }
    io::write_json(&out.join("summary.json"), &summary)?;
    if snaps.hdf5_enabled() {
        io::hdf5::finish(out)?;
    }
    log(&format!(
        "done: {} steps to t = {} s in {:.3} s; mean T = {mean:.3} K (min {lo:.3}, max {hi:.3}); energy balance residual {balance:.2e} (relative)",
        st.steps,
        st.t,
        wall.elapsed().as_secs_f64()
    ));
    Ok(summary)
}

/// The summary of the run (`summary.json`).
fn summary(prep: &Prepared, st: &HeatLoop, plan: &Plan, net: &HeatNetwork, snaps: &SnapshotWriter, balance: f64, wall_seconds: f64) -> serde_json::Value {
    let temps = &prep.scene.particles.temperature;
    let (mean, lo, hi) = stats(temps);
    let control = &plan.control;
    let mut summary = json!({
        "kind": "heat",
        "final_time_s": st.t,
        "steps": st.steps,
        "wall_seconds": wall_seconds,
        "particles": temps.len(),
        "contacts": prep.pipes.pairs.len(),
        "contacts_extrapolated": prep.pipes.extrapolated,
        "scheme": format!("{:?}", prep.case.time.scheme),
        "energy_balance_rel": balance,
        "heat_in_J": st.heat_in,
        "stored_heat_change_J": st.stored,
        "stored_heat_change_plain_J": st.stored_plain,
        "stored_heat_J": net.stored_heat(temps),
        "stored_heat_initial_J": st.stored0,
        "mean_temperature_K": mean,
        "min_temperature_K": lo,
        "max_temperature_K": hi,
        "factorizations": st.factorizations,
        "max_radiation_iterations": st.max_iters,
        "max_local_error_estimate_K": st.max_err_est,
        "time_step_control": if control.is_some() { "error" } else { "fixed" },
        "steps_accepted": st.steps,
        "steps_rejected": st.rejected,
        "steps_above_tolerance_at_dt_min": st.forced_at_dt_min,
        "temperature_dependent_properties": net.properties().is_some(),
        "max_scaled_residual": st.max_resid,
        "seconds_assemble": st.t_assemble,
        "seconds_factorize": st.t_factor,
        "seconds_solve": st.t_solve,
        "snapshots": snaps.count(),
        "hdf5": snaps.hdf5_enabled(),
        "skipped": if prep.isothermal.is_some() { vec!["heat solve (isothermal)", "neighbour search (static packing)", "diffusion", "mechanics"] } else { vec!["neighbour search after start (static packing)", "diffusion", "mechanics"] },
    });
    if let Some(c) = control {
        summary["heat_tolerance_K"] = json!(c.tolerance);
    }
    if prep.gap.is_some() {
        summary["gap_pipes"] = json!(net.gap_pipes());
    }
    summary
}

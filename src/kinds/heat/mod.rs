//! A heat run (`kind = "heat"`): a static packing whose temperatures evolve in the implicit pipe
//! network under heating profiles, furnace exchange and volumetric sources. Writes
//! `summary.json`, `series.csv`, snapshots (VTU/PVD, HDF5) and `log.txt`.

mod output;
mod step;
mod stepper;

use crate::error::{ConfigError, Error, IoError};
use crate::heat::{HeatNetwork, PipeConductance};
use crate::io::{self, Series, SnapshotWriter};
use crate::scene::{Prepared, network_for, prepare};
use std::path::Path;

pub use output::{COLUMNS, HeatRow};
pub use stepper::HeatRun;

/// The heat run's loop state: what a checkpoint must carry besides the temperatures.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct HeatLoop {
    /// Time [s] and steps done.
    pub t: f64,
    pub steps: usize,
    /// Energy accounts [J]: heat in, scheme's stored change, plain stored change, Σ|Q_step|,
    /// stored heat at the start.
    pub heat_in: f64,
    pub stored: f64,
    pub stored_plain: f64,
    pub scale: f64,
    pub stored0: f64,
    /// Wall-time shares [s] and solver counters.
    pub t_assemble: f64,
    pub t_factor: f64,
    pub t_solve: f64,
    pub factorizations: usize,
    pub max_resid: f64,
    pub max_iters: u32,
    /// Temperatures of the last steps of equal Δt for the local error estimate [K], that Δt [s].
    pub hist: Vec<Vec<f64>>,
    pub hist_dt: Option<f64>,
    /// Times of `hist` [s] (eq. E1 with unequal steps).
    #[serde(default)]
    pub hist_t: Vec<f64>,
    /// Step control (time.heat_tolerance): the next proposed Δt [s], rejected steps, steps
    /// accepted at dt_min above the tolerance.
    #[serde(default)]
    pub dt_next: Option<f64>,
    #[serde(default)]
    pub rejected: usize,
    #[serde(default)]
    pub forced_at_dt_min: usize,
    pub max_err_est: f64,
    /// Next snapshot, series lines written (header included), snapshots and VTU entries so far.
    pub next_snap: usize,
    pub series_lines: usize,
    pub snapshots: usize,
    pub vtu_entries: Vec<(f64, String, String)>,
    /// Wall time before the checkpoint [s].
    pub wall_before: f64,
    /// SHA-256 of the matrix factored last ([`crate::heat::HeatNetwork::factored_values`]) at the
    /// checkpoint; a resumed run whose first step factors that same matrix again does not count
    /// it (the uninterrupted run reused its factor there), so `factorizations` is the
    /// uninterrupted run's.
    #[serde(default)]
    pub factor_sha256: Option<String>,
}

/// `DIR/checkpoint.json` of a heat run.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct HeatCheckpoint {
    pub format: String,
    pub case_toml: String,
    pub base_dir: std::path::PathBuf,
    pub state: HeatLoop,
    /// Particle temperatures [K].
    pub temperature: Vec<f64>,
    /// The network's BDF2 history (T^{n−1} [K], Δt_{n−1} [s]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bdf2: Option<(Vec<f64>, f64)>,
}

/// Format tag of heat checkpoints.
pub const HEAT_CHECKPOINT_FORMAT: &str = "sinterdem-heat-checkpoint-1";

/// Runs a prepared heat case into `out`, returning the summary that is also written to
/// `out/summary.json`.
pub fn run(prep: Prepared, out: &Path, progress: bool, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    run_from(prep, out, progress, log, None, None)
}

/// `sinterdem resume DIR` for a heat run: rebuilds the case from the checkpoint's text, restores
/// temperatures, BDF2 history and loop state, and continues bit for bit.
pub fn resume(dir: &Path, progress: bool, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    let path = dir.join("checkpoint.json");
    let text = crate::io::read_checkpoint_json(&path)?;
    let ck: HeatCheckpoint = serde_json::from_str(&text).map_err(|e| IoError::new(&path, e))?;
    if ck.format != HEAT_CHECKPOINT_FORMAT {
        return Err(ConfigError::invalid(format!("{}: format \"{}\" is not {HEAT_CHECKPOINT_FORMAT}", path.display(), ck.format)).into());
    }
    let value = toml::Value::Table(ck.case_toml.parse::<toml::Table>().map_err(|e| ConfigError::invalid(format!("{}: case: {e}", path.display())))?);
    let mut prep = prepare(value, &ck.base_dir)?;
    prep.source = Some((ck.case_toml.clone(), ck.base_dir.clone()));
    let n = prep.scene.particles.len();
    let st = &ck.state;
    let end = prep.case.time.end;
    let bad = |m: String| -> Error { ConfigError::invalid(format!("{}: {m}", path.display())).into() };
    if ck.temperature.len() != n || ck.temperature.iter().any(|t| !(t.is_finite() && *t > 0.0)) {
        return Err(bad(format!("temperatures: need {n} finite positive values")));
    }
    if !(st.t.is_finite() && st.t >= 0.0 && st.t <= end) || st.steps as f64 > 1e12 || st.series_lines == 0 || st.hist.iter().any(|h| h.len() != n) {
        return Err(bad(format!("loop state out of range (t = {} s of end {end} s, steps {}, series lines {})", st.t, st.steps, st.series_lines)));
    }
    for (key, v) in [("heat_in", st.heat_in), ("stored", st.stored), ("stored_plain", st.stored_plain), ("scale", st.scale), ("stored0", st.stored0)] {
        crate::heat::balance::energy_account(&format!("checkpoint.state.{key}"), v).map_err(|e| bad(e.to_string()))?;
    }
    // the error-estimate history: as many times as temperature vectors (E1), positive steps
    if !st.hist_t.is_empty() && st.hist_t.len() != st.hist.len() {
        return Err(bad(format!("state.hist_t has {} times for {} temperature vectors (state.hist)", st.hist_t.len(), st.hist.len())));
    }
    let positive = |v: Option<f64>| v.is_none_or(|x| x.is_finite() && x > 0.0);
    if !positive(st.hist_dt) || !positive(st.dt_next) || st.hist.iter().flatten().chain(&st.hist_t).any(|v| !v.is_finite()) {
        return Err(bad(format!("state.hist, hist_t, hist_dt or dt_next is not finite and positive (hist_dt {:?} s, dt_next {:?} s)", st.hist_dt, st.dt_next)));
    }
    if let Some((h, dt)) = &ck.bdf2
        && (h.len() != n || !(dt.is_finite() && *dt > 0.0) || h.iter().any(|t| !t.is_finite()))
    {
        return Err(bad("BDF2 history does not match the case".into()));
    }
    log(&format!("resumed from the checkpoint at t = {} s (step {})", st.t, st.steps));
    run_from(prep, dir, progress, log, Some(ck), None)
}

/// Runs from the start or from a checkpoint; `stop_after_step` ends the run right after the
/// checkpoint of that step (as if killed there; for tests) with `Ok(Value::Null)`.
pub fn run_from(
    prep: Prepared,
    out: &Path,
    progress: bool,
    log: &mut dyn FnMut(&str),
    ck: Option<HeatCheckpoint>,
    stop_after_step: Option<usize>,
) -> Result<serde_json::Value, Error> {
    run_returning_temperatures(prep, out, progress, log, ck, stop_after_step, false).map(|(s, _)| s)
}

/// [`run_from`] that also returns the particle temperatures [K] at the snapshot times [s] (with
/// `collect`; the final state is always the last entry), for benchmarks and tests. The loop is
/// [`HeatRun::step`] until the end.
pub fn run_returning_temperatures(
    prep: Prepared,
    out: &Path,
    progress: bool,
    log: &mut dyn FnMut(&str),
    ck: Option<HeatCheckpoint>,
    stop_after_step: Option<usize>,
    collect: bool,
) -> Result<(serde_json::Value, Vec<(f64, Vec<f64>)>), Error> {
    let mut run = HeatRun::start_from(prep, out, progress, log, ck, collect)?;
    run.stop_after_step = stop_after_step;
    while run.step(log)? {}
    if run.killed {
        run.bar.finish();
        return Ok((serde_json::Value::Null, vec![(run.st.t, run.prep.scene.particles.temperature.clone())]));
    }
    run.finish_collected(log)
}

/// The heat network of the case with its pipes' conductances (contacts, then gap pipes), the
/// Dirichlet particles at their t = 0 temperatures (isothermal: every particle at the furnace's).
fn setup(prep: &mut Prepared, log: &mut dyn FnMut(&str)) -> Result<(HeatNetwork, Vec<PipeConductance>), Error> {
    let case = &prep.case;
    let p = &mut prep.scene.particles;
    let n = p.len();
    log(&format!(
        "heat run: {} particles, {} contacts ({} with a/r > 0.7, conductance law extrapolated), scheme {:?}, Δt = {} s, end = {} s",
        n,
        prep.pipes.pairs.len(),
        prep.pipes.extrapolated,
        case.time.scheme,
        crate::error::fmt_value(case.time.dt),
        crate::error::fmt_value(case.time.end)
    ));
    let mut net = network_for(&prep.case, &prep.sources, p, &prep.scene.materials, &prep.conductance);
    // the conductances of the network's pipes: the contacts', then the gap pipes' (static packing)
    let mut parts = prep.pipes.parts.clone();
    if net.properties().is_some() {
        log("temperature-dependent properties: c(T) and/or κ(T) tables (enthalpy form, Picard iteration; docs/heat-model.md eqs. P1–P4)");
    }
    if let Some(prof) = &prep.isothermal {
        log("thermal.mode = isothermal: the heat network solve is skipped; every particle follows the furnace profile");
        p.temperature.iter_mut().for_each(|t| *t = prof.temperature(0.0));
        return Ok((net, parts));
    }
    let (all, secs) = crate::heat::gap::attach(&mut net, prep.gap.as_mut(), &p.position, &p.radius, &prep.pipes.pairs, prep.pipes.parts.clone())?;
    parts = all;
    log(&format!("heat network: {} unknowns, {} fixed-temperature particles; symbolic analysis {secs:.3} s", net.unknowns(), n - net.unknowns()));
    if let Some(g) = &prep.gap {
        let m = g.model;
        log(&format!(
            "gap model (docs/heat-model.md (H18)–(H23)): {} gap pipes between particles not in contact (gas k_g = {} W/(m·K), layer f = {}, jump distance M = {} m, surface emissivity {})",
            net.gap_pipes(),
            m.gas_conductivity,
            m.layer_thickness,
            m.jump_distance,
            m.emissivity
        ));
    }
    net.apply_fixed(0.0, &mut p.temperature);
    // neighbour search is done once: the packing is static in a heat run
    log("static packing: neighbour search done once, mechanics and diffusion are not part of a heat run");
    Ok((net, parts))
}

/// The series and snapshot writers: new, or (resume) reopened after the checkpoint's rows and
/// snapshots, with the checkpoint's temperatures and BDF2 history restored.
fn open_outputs(
    prep: &mut Prepared,
    net: &mut HeatNetwork,
    out: &Path,
    ck: Option<&HeatCheckpoint>,
    log: &mut dyn FnMut(&str),
) -> Result<(Series, SnapshotWriter), Error> {
    let o = &prep.case.output;
    Ok(match ck {
        Some(c) => {
            prep.scene.particles.temperature = c.temperature.clone();
            net.set_history(c.bdf2.clone());
            (
                Series::resume(&out.join("series.csv"), c.state.series_lines, COLUMNS.len())?,
                SnapshotWriter::resume(out, o.vtu, o.hdf5, c.state.snapshots, c.state.vtu_entries.clone(), log)?,
            )
        }
        None => (Series::create(&out.join("series.csv"), &io::header(COLUMNS))?, SnapshotWriter::new(out, o.vtu, o.hdf5, log)?),
    })
}

/// The loop state at the start: the checkpoint's, or a fresh one (header line written, stored
/// heat at the start). The local error estimate (docs/heat-model.md eqs. E1–E2,
/// src/heat/adaptive.rs) extrapolates through the last accepted points (times `hist_t`, values
/// `hist`, the last one the current state).
fn loop_state(prep: &Prepared, net: &HeatNetwork, ck: Option<HeatCheckpoint>) -> HeatLoop {
    let temps = &prep.scene.particles.temperature;
    let mut st = match ck {
        Some(c) => c.state,
        None => HeatLoop { series_lines: 1, stored0: net.stored_heat(temps), ..HeatLoop::default() },
    };
    if st.hist_t.len() != st.hist.len() {
        // a checkpoint of an older version: equal steps hist_dt ending at t
        let h = st.hist_dt.unwrap_or(0.0);
        let (t, len) = (st.t, st.hist.len());
        st.hist_t = (0..len).map(|k| t - (len - 1 - k) as f64 * h).collect();
    }
    if st.hist.is_empty() && prep.isothermal.is_none() {
        st.hist.push(temps.clone());
        st.hist_t.push(st.t);
    }
    st
}

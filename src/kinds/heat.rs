//! A heat run (`kind = "heat"`): a static packing whose temperatures evolve in the implicit pipe
//! network under heating profiles, furnace exchange and volumetric sources. Writes
//! `summary.json`, `series.csv`, snapshots (VTU/PVD, HDF5) and `log.txt`.

use crate::error::{ConfigError, Error, IoError};
use crate::heat::HeatNetwork;
use crate::heat::Pipes;
use crate::heat::balance::energy_balance_rel;
use crate::io::{self, Series, Snapshot, SnapshotWriter};
use crate::scene::{Prepared, network_for, prepare, step_control};
use serde_json::json;
use std::path::Path;
use std::time::Instant;

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
    let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
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
    if let Some((h, dt)) = &ck.bdf2
        && (h.len() != n || !(dt.is_finite() && *dt > 0.0))
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
/// `collect`; the final state is always the last entry), for benchmarks and tests.
pub fn run_returning_temperatures(
    mut prep: Prepared,
    out: &Path,
    progress: bool,
    log: &mut dyn FnMut(&str),
    ck: Option<HeatCheckpoint>,
    stop_after_step: Option<usize>,
    collect: bool,
) -> Result<(serde_json::Value, Vec<(f64, Vec<f64>)>), Error> {
    let mut collected: Vec<(f64, Vec<f64>)> = Vec::new();
    let wall = Instant::now();
    io::ensure_dir(out)?;
    let case = &prep.case;
    let end = case.time.end;
    let dt0 = case.time.dt;
    let p = &mut prep.scene.particles;
    let n = p.len();
    log(&format!(
        "heat run: {} particles, {} contacts ({} with a/r > 0.7, conductance law extrapolated), scheme {:?}, Δt = {dt0} s, end = {end} s",
        n,
        prep.pipes.pairs.len(),
        prep.pipes.extrapolated,
        case.time.scheme
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
    } else {
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
    }
    const HEADER: [&str; 9] = [
        "time_s",
        "dt_s",
        "mean_temperature_K",
        "min_temperature_K",
        "max_temperature_K",
        "heat_in_J",
        "stored_heat_J",
        "heat_in_cumulative_J",
        "radiation_iterations",
    ];
    let resumed = ck.is_some();
    let (mut series, mut snaps) = match &ck {
        Some(c) => {
            p.temperature = c.temperature.clone();
            net.set_history(c.bdf2.clone());
            (
                Series::resume(&out.join("series.csv"), c.state.series_lines, HEADER.len())?,
                SnapshotWriter::resume(out, case.output.vtu, case.output.hdf5, c.state.snapshots, c.state.vtu_entries.clone(), log)?,
            )
        }
        None => (Series::create(&out.join("series.csv"), &HEADER)?, SnapshotWriter::new(out, case.output.vtu, case.output.hdf5, log)?),
    };
    let ck_every = case.output.checkpoint_every as usize;
    let n_snap = case.output.snapshots as usize;
    let snap_times: Vec<f64> = match n_snap {
        0 => vec![],
        1 => vec![end],
        k => (0..k).map(|i| end * i as f64 / (k - 1) as f64).collect(),
    };
    let st0 = ck.as_ref().map(|c| c.state.clone()).unwrap_or_default();
    let mut next_snap = st0.next_snap;
    let mut series_lines = if resumed { st0.series_lines } else { 1 };
    let stored_of = |temps: &[f64], net: &HeatNetwork, _cap: &[f64]| -> f64 { net.stored_heat(temps) };
    let stored0 = if resumed { st0.stored0 } else { stored_of(&p.temperature, &net, &p.capacity) };
    let parameters = io::Parameters {
        case_toml: toml::to_string(case).unwrap_or_else(|e| format!("# the case could not be written as TOML: {e}")),
        materials_json: serde_json::to_string_pretty(&case.materials).unwrap_or_default(),
    };
    let write_snapshot = |snaps: &mut SnapshotWriter, t: f64, step: usize, p: &crate::particles::Particles, pipes: &Pipes| -> Result<(), IoError> {
        snaps.write(&Snapshot {
            time: t,
            step: step as u64,
            position: &p.position,
            radius: &p.radius,
            temperature: &p.temperature,
            contacts: &pipes.pairs,
            contact_data: vec![("neck_radius_m", &pipes.neck), ("conductance_W_per_K", &pipes.conductance), ("overlap_m", &pipes.overlap)],
            particle_data: vec![],
            particle_vectors: vec![],
            parameters: Some(parameters.clone()),
        })
    };
    let stats = |t: &[f64]| {
        let mean = t.iter().sum::<f64>() / t.len() as f64;
        let lo = t.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (mean, lo, hi)
    };
    let bar = io::progress::Progress::new(end, progress);
    let (mut t, mut steps) = (st0.t, st0.steps);
    let (mut heat_in, mut stored, mut stored_plain, mut scale) = (st0.heat_in, st0.stored, st0.stored_plain, st0.scale);
    let (mut t_assemble, mut t_factor, mut t_solve, mut factorizations, mut max_resid) =
        (st0.t_assemble, st0.t_factor, st0.t_solve, st0.factorizations, st0.max_resid);
    let mut max_iters = st0.max_iters;
    // local error estimate (docs/heat-model.md eqs. E1–E2, src/heat/adaptive.rs): the step's
    // result against the extrapolation through the last accepted points (times `hist_t`, values
    // `hist`, the last one the current state), restarted at every kink of a prescribed profile
    let mut hist: Vec<Vec<f64>> = st0.hist.clone();
    let mut hist_t: Vec<f64> = st0.hist_t.clone();
    if hist_t.len() != hist.len() {
        // a checkpoint of an older version: equal steps hist_dt ending at t
        let h = st0.hist_dt.unwrap_or(0.0);
        hist_t = (0..hist.len()).map(|k| t - (hist.len() - 1 - k) as f64 * h).collect();
    }
    if hist.is_empty() && prep.isothermal.is_none() {
        hist.push(p.temperature.clone());
        hist_t.push(t);
    }
    let mut max_err_est = st0.max_err_est;
    let wall_before = st0.wall_before;
    // the extrapolation is not valid across a kink of a prescribed profile: restart it there
    let mut kinks: Vec<f64> = prep.sources.profiles.iter().flat_map(|p| p.breakpoints().to_vec()).collect();
    if let Some(f) = &prep.sources.furnace {
        kinks.extend_from_slice(f.gas.breakpoints());
        kinks.extend_from_slice(f.wall.breakpoints());
    }
    kinks.retain(|k| *k > 0.0 && *k < end);
    kinks.sort_by(f64::total_cmp);
    // step control (eq. E3): None = the fixed Δt of the case
    let control = step_control(case)?;
    let mut dt_next = st0.dt_next.unwrap_or(dt0);
    let (mut rejected, mut forced) = (st0.rejected, st0.forced_at_dt_min);
    if let Some(c) = &control {
        log(&format!("Δt chosen by error: time.heat_tolerance = {} K per step, first step {dt0} s, Δt in [{:e}, {:e}] s", c.tolerance, c.dt_min, c.dt_max));
    }
    let tiny = 1e-12 * end;
    while next_snap < snap_times.len() && snap_times[next_snap] <= t + 1e-12 * end {
        if collect {
            collected.push((t, p.temperature.clone()));
        }
        write_snapshot(&mut snaps, t, steps, p, &prep.pipes)?;
        next_snap += 1;
    }
    while t < end * (1.0 - 1e-12) {
        // where this step must land: the end, or (adaptive) the next snapshot or profile kink
        let stop = match &control {
            None => end,
            Some(_) => {
                let snap = snap_times.get(next_snap).copied().filter(|&s| s > t + tiny).unwrap_or(end);
                let kink = kinks.iter().copied().find(|&k| k > t + tiny).unwrap_or(end);
                end.min(snap).min(kink)
            }
        };
        let mut h = match &control {
            None => dt0,
            Some(c) => dt_next.clamp(c.dt_min, c.dt_max),
        };
        let mut iters = 0;
        let mut hin = 0.0;
        let dt = loop {
            let left = stop - t;
            let dt = if h >= left * (1.0 - 1e-12) {
                left
            } else if control.is_some() && h > 0.5 * left {
                0.5 * left // two equal steps rather than a sliver
            } else {
                h
            };
            if let Some(prof) = &prep.isothermal {
                let tt = prof.temperature(t + dt);
                p.temperature.iter_mut().for_each(|v| *v = tt);
                break dt;
            }
            let spans_kink = kinks.iter().any(|&k| k > t + tiny && k < t + dt - tiny);
            if spans_kink || hist_t.last().is_some_and(|&tl| (tl - t).abs() > tiny) {
                hist.clear();
                hist_t.clear();
                hist.push(p.temperature.clone());
                hist_t.push(t);
            }
            let saved = control.as_ref().map(|_| (p.temperature.clone(), net.history().cloned()));
            // the fixed-Δt report uses full-order estimates only; step control also the
            // conservative lower-order ones while the history builds up
            let ydot = (control.is_some() && hist.len() == 1 && !spans_kink).then(|| net.rate_of_change(t, &p.temperature, &parts));
            let bdf2_step = case.time.scheme == crate::heat::Scheme::Bdf2 && net.history().is_some();
            let step_order =
                if case.time.scheme == crate::heat::Scheme::BackwardEuler || (case.time.scheme == crate::heat::Scheme::Bdf2 && !bdf2_step) { 1 } else { 2 };
            let info = match (net.step_pipes(t, dt, &mut p.temperature, &parts), &control, &saved) {
                (Ok(i), _, _) => i,
                (Err(e), Some(c), Some((temps, bdf))) if dt > c.dt_min * (1.0 + 1e-9) => {
                    // a failed solve (radiation or property iteration) on a long step: shorter
                    log(&format!("t = {t:e} s: step of {dt:e} s failed ({e}); retried with a shorter one"));
                    p.temperature.clone_from(temps);
                    net.set_history(bdf.clone());
                    rejected += 1;
                    h = (dt * crate::heat::adaptive::SHRINK_MIN).max(c.dt_min);
                    continue;
                }
                (Err(e), _, _) => return Err(e.into()),
            };
            crate::finite::ensure_finite("heat", steps as u64 + 1, t + dt, "particle", "temperature", p.temperature.iter().copied())?;
            let est = if spans_kink {
                None
            } else {
                let vals: Vec<&[f64]> = hist.iter().map(|v| v.as_slice()).collect();
                crate::heat::adaptive::estimate(case.time.scheme, bdf2_step, &hist_t, &vals, t + dt, &p.temperature, ydot.as_deref(), |i| !net.is_fixed(i))
                    .filter(|e| control.is_some() || e.order == step_order)
            };
            if let (Some(c), Some(e), Some((temps, bdf))) = (&control, est, &saved) {
                if e.error > c.tolerance && dt > c.dt_min * (1.0 + 1e-9) {
                    p.temperature.clone_from(temps);
                    net.set_history(bdf.clone());
                    rejected += 1;
                    h = (dt * c.factor(e.error, e.order).min(1.0)).max(c.dt_min);
                    continue;
                }
                if e.error > c.tolerance {
                    forced += 1;
                }
                let proposal = (dt * c.factor(e.error, e.order)).clamp(c.dt_min, c.dt_max);
                // a step shortened to land on a stop does not shrink the next one
                dt_next = if dt < h { proposal.max(dt_next) } else { proposal };
            }
            if let Some(e) = est {
                max_err_est = max_err_est.max(e.error);
            }
            heat_in += info.heat_in;
            stored += info.stored_change;
            stored_plain += info.stored_change_plain;
            scale += info.heat_in.abs();
            t_assemble += info.assemble_seconds;
            t_factor += info.solve.factor_seconds;
            t_solve += info.solve.solve_seconds;
            factorizations += (!info.reused_factor) as usize * info.iterations.max(1) as usize;
            max_resid = max_resid.max(info.solve.residual);
            iters = info.iterations;
            max_iters = max_iters.max(iters);
            hin = info.heat_in;
            let ends_at_kink = kinks.iter().any(|&k| (k - (t + dt)).abs() <= tiny);
            if spans_kink || ends_at_kink {
                hist.clear();
                hist_t.clear();
            }
            hist.push(p.temperature.clone());
            hist_t.push(t + dt);
            if hist.len() > 3 {
                hist.remove(0);
                hist_t.remove(0);
            }
            break dt;
        };
        t += dt;
        steps += 1;
        if steps % case.output.series_every as usize == 0 || t >= end * (1.0 - 1e-12) {
            let (mean, lo, hi) = stats(&p.temperature);
            series.row(&[t, dt, mean, lo, hi, hin, stored_of(&p.temperature, &net, &p.capacity), heat_in, iters as f64])?;
            series_lines += 1;
        }
        while next_snap < snap_times.len() && snap_times[next_snap] <= t + 1e-9 * dt {
            if collect {
                collected.push((t, p.temperature.clone()));
            }
            write_snapshot(&mut snaps, t, steps, p, &prep.pipes)?;
            next_snap += 1;
        }
        if ck_every > 0 && steps.is_multiple_of(ck_every) && t < end * (1.0 - 1e-12) {
            let (text, base) = prep.source.clone().unwrap_or_else(|| (toml::to_string(&prep.case).unwrap_or_default(), std::path::PathBuf::from(".")));
            let state = HeatLoop {
                t,
                steps,
                heat_in,
                stored,
                stored_plain,
                scale,
                stored0,
                t_assemble,
                t_factor,
                t_solve,
                factorizations,
                max_resid,
                max_iters,
                hist: hist.clone(),
                hist_dt: None,
                hist_t: hist_t.clone(),
                dt_next: control.is_some().then_some(dt_next),
                rejected,
                forced_at_dt_min: forced,
                max_err_est,
                next_snap,
                series_lines,
                snapshots: snaps.count(),
                vtu_entries: snaps.vtu_entries(),
                wall_before: wall_before + wall.elapsed().as_secs_f64(),
            };
            let hc = HeatCheckpoint {
                format: HEAT_CHECKPOINT_FORMAT.into(),
                case_toml: text,
                base_dir: base,
                state,
                temperature: p.temperature.clone(),
                bdf2: net.history().cloned(),
            };
            let path = out.join("checkpoint.json");
            let json = serde_json::to_string(&hc).map_err(|e| IoError::new(&path, e))?;
            io::write_atomic(&path, &json)?;
            if stop_after_step.is_some_and(|k| steps >= k) {
                bar.finish();
                return Ok((serde_json::Value::Null, vec![(t, p.temperature.clone())]));
            }
        }
        bar.set(t, "");
    }
    bar.finish();
    let (mean, lo, hi) = stats(&p.temperature);
    let balance = if prep.isothermal.is_some() { 0.0 } else { energy_balance_rel(stored, heat_in, scale, stored0) };
    let stored_end = stored_of(&p.temperature, &net, &p.capacity);
    let mut summary = json!({
        "kind": "heat",
        "final_time_s": t,
        "steps": steps,
        "wall_seconds": wall_before + wall.elapsed().as_secs_f64(),
        "particles": n,
        "contacts": prep.pipes.pairs.len(),
        "contacts_extrapolated": prep.pipes.extrapolated,
        "scheme": format!("{:?}", case.time.scheme),
        "energy_balance_rel": balance,
        "heat_in_J": heat_in,
        "stored_heat_change_J": stored,
        "stored_heat_change_plain_J": stored_plain,
        "stored_heat_J": stored_end,
        "stored_heat_initial_J": stored0,
        "mean_temperature_K": mean,
        "min_temperature_K": lo,
        "max_temperature_K": hi,
        "factorizations": factorizations,
        "max_radiation_iterations": max_iters,
        "max_local_error_estimate_K": max_err_est,
        "time_step_control": if control.is_some() { "error" } else { "fixed" },
        "steps_accepted": steps,
        "steps_rejected": rejected,
        "steps_above_tolerance_at_dt_min": forced,
        "temperature_dependent_properties": net.properties().is_some(),
        "max_scaled_residual": max_resid,
        "seconds_assemble": t_assemble,
        "seconds_factorize": t_factor,
        "seconds_solve": t_solve,
        "snapshots": snaps.count(),
        "hdf5": snaps.hdf5_enabled(),
        "skipped": if prep.isothermal.is_some() { vec!["heat solve (isothermal)", "neighbour search (static packing)", "diffusion", "mechanics"] } else { vec!["neighbour search after start (static packing)", "diffusion", "mechanics"] },
    });
    if let Some(c) = &control {
        summary["heat_tolerance_K"] = json!(c.tolerance);
    }
    if prep.gap.is_some() {
        summary["gap_pipes"] = json!(net.gap_pipes());
    }
    io::write_json(&out.join("summary.json"), &summary)?;
    if snaps.hdf5_enabled() {
        io::hdf5::finish(out)?;
    }
    log(&format!(
        "done: {steps} steps to t = {t} s in {:.3} s; mean T = {mean:.3} K (min {lo:.3}, max {hi:.3}); energy balance residual {balance:.2e} (relative)",
        wall.elapsed().as_secs_f64()
    ));
    if collected.last().is_none_or(|c| c.0 != t) {
        collected.push((t, p.temperature.clone()));
    }
    Ok((summary, collected))
}

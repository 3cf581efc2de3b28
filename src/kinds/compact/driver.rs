//! The driver loop of a compact run: steps to the end time (or a stop criterion), writes the series,
//! the due outputs and the checkpoints, then the summary. [`run_from`] is the loop; each of its
//! stages (announce, open or resume the outputs, a series row, a checkpoint, the stop criteria,
//! the summary) is a function below; [`CompactRun`] is the loop one step at a time.

use super::columns::{self, Row};
use super::*;
use crate::coupled::*;
use crate::error::{Error, IoError};
use crate::io::{self, Series, SnapshotWriter};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Runs a compact simulation to its end time, writing series, snapshots, checkpoints and the summary.
pub fn run(sim: Simulation, out: &Path, progress: bool, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    run_from(sim, out, progress, log, None, None)
}

/// Runs from a fresh start (`state = None`) or a checkpoint's output state; `stop_after_step`
/// ends the run early after that step (as if killed right after its checkpoint, for tests), with
/// `Ok(Value::Null)`. The loop is [`CompactRun::step`] until it says the run is over.
pub fn run_from(
    sim: Simulation,
    out: &Path,
    progress: bool,
    log: &mut dyn FnMut(&str),
    state: Option<OutputState>,
    stop_after_step: Option<u64>,
) -> Result<serde_json::Value, Error> {
    let mut run = CompactRun::start(sim, out, progress, state, log)?;
    run.stop_after_step = stop_after_step;
    while run.step(log)? {}
    if run.killed {
        run.bar.finish();
        return Ok(serde_json::Value::Null);
    }
    run.finish(log)
}

/// A compact run in progress, one accepted step at a time (the stepping API: `sinterdem.Simulation`
/// in Python). [`CompactRun::start`] opens the outputs and writes those due at the start,
/// [`CompactRun::step`] takes one accepted step and writes what is due in it (series row,
/// snapshots, analyses, checkpoint), [`CompactRun::finish`] writes `summary.json` and the plots.
/// [`run_from`] is exactly this loop, so a stepped run and `sinterdem run` are identical.
pub struct CompactRun {
    /// The simulation (current state: `sim.t`, particles in `sim.prep.scene.particles`, contacts).
    pub sim: Simulation,
    out: PathBuf,
    outputs: Outputs,
    wall: Instant,
    bar: io::progress::Progress,
    stop_reason: Option<String>,
    failure: Option<Error>,
    /// The run is over (end time, stop criterion, model error or [`CompactRun::stop`]).
    done: bool,
    /// Step whose series row was written last, and the length of the last step [s].
    row_step: u64,
    last_dt: f64,
    /// Tests: stop as if killed right after the checkpoint at or after this step.
    stop_after_step: Option<u64>,
    killed: bool,
    /// The next time a status line is due [s] and the contact count at the last one.
    status_next: f64,
    status_contacts: usize,
}

/// Status lines per run: one each tenth of the end time (LAMMPS `thermo` style, issue 25).
pub const STATUS_LINES: f64 = 10.0;

impl CompactRun {
    /// Opens the outputs of a fresh run (`state = None`) or of a checkpoint's output state and
    /// writes those due at the current time.
    pub fn start(sim: Simulation, out: &Path, progress: bool, state: Option<OutputState>, log: &mut dyn FnMut(&str)) -> Result<CompactRun, Error> {
        let wall = Instant::now();
        io::ensure_dir(out)?;
        announce(&sim, log);
        let outputs = Outputs::open(&sim, out, state, log)?;
        let bar = io::progress::Progress::new(sim.settings.end, progress);
        let row_step = sim.step;
        let mut run = CompactRun {
            sim,
            out: out.to_path_buf(),
            outputs,
            wall,
            bar,
            stop_reason: None,
            failure: None,
            done: false,
            row_step,
            last_dt: 0.0,
            stop_after_step: None,
            killed: false,
            status_next: 0.0,
            status_contacts: 0,
        };
        let every = run.sim.settings.end / STATUS_LINES;
        run.status_next = ((run.sim.t / every).floor() + 1.0) * every;
        run.status_contacts = run.sim.contacts.len();
        run.write_due(log)?;
        run.done = run.sim.t >= run.sim.settings.end;
        Ok(run)
    }

    /// The snapshots and analyses due at the current time.
    fn write_due(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let tic = Instant::now();
        self.outputs.due.write(&self.sim, &self.out, &mut self.outputs.snaps, log)?;
        self.sim.timing.output += tic.elapsed().as_secs_f64();
        Ok(())
    }

    /// Whether the run is over (no more steps; [`CompactRun::finish`] is next).
    pub fn done(&self) -> bool {
        self.done
    }

    /// The output directory.
    pub fn out(&self) -> &Path {
        &self.out
    }

    /// Whether a model error ended the run (it is returned by `finish`, after the outputs).
    pub fn failed(&self) -> bool {
        self.failure.is_some()
    }

    /// Takes one accepted step and writes the outputs due in it; returns whether the run goes on.
    /// A model error ends the run (the error is returned by [`CompactRun::finish`]); an
    /// interrupt ([`crate::interrupt`]) or a stop criterion ends it after this step.
    pub fn step(&mut self, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        if self.done {
            return Ok(false);
        }
        let sim = &mut self.sim;
        let end = sim.settings.end;
        sim.stop_at = self.outputs.due.next_time(sim);
        let dt_used = sim.dt.min(sim.stop_at.min(end) - sim.t);
        match sim.advance_step(log) {
            Ok(()) => {}
            // the model's validity ends (a contact's geometry or integrator breaks down): the
            // run stops with the last completed step summarised, then reports the error
            Err(Error::Model(m)) => {
                log(&format!("stopped at t = {} s (step {}): {m}", sim.t, sim.step));
                self.stop_reason = Some(format!("model error after t = {} s: {m}", sim.t));
                self.failure = Some(Error::Model(m));
                self.done = true;
                return Ok(false);
            }
            Err(e) => return Err(e),
        }
        self.last_dt = dt_used;
        let tic = Instant::now();
        let stop_now = stop_criterion(sim, &self.wall, log);
        if sim.step.is_multiple_of(sim.settings.series_every) || sim.t >= end || stop_now.is_some() {
            self.outputs.row(sim, dt_used)?;
            self.row_step = sim.step;
        }
        if sim.settings.checkpoint_every > 0 && sim.step.is_multiple_of(sim.settings.checkpoint_every) && sim.t < end {
            self.outputs.checkpoint(sim, &self.out, &self.wall, log)?;
            if self.stop_after_step.is_some_and(|s| sim.step >= s) {
                self.killed = true;
                self.done = true;
                return Ok(false);
            }
        }
        sim.timing.output += tic.elapsed().as_secs_f64();
        if stop_now.is_some() {
            self.stop_reason = stop_now;
            self.done = true;
            return Ok(false);
        }
        self.bar.set(sim.t, &format!("step {}, Δt = {}, contacts {}", sim.step, crate::units::fmt_seconds(sim.dt), sim.contacts.len()));
        tracing::trace!(
            target: "sinterdem::coupled",
            "step {}: t = {}, Δt = {}, {} contacts, subdivided fraction {:.3}; wall so far: detection {:.3} s, heat {:.3} s, diffusion {:.3} s, mechanics {:.3} s, correction {:.3} s",
            sim.step,
            crate::units::fmt_seconds(sim.t),
            crate::units::fmt_seconds(dt_used),
            sim.contacts.len(),
            sim.subdivided_fraction(),
            sim.timing.detection,
            sim.timing.heat,
            sim.timing.diffusion,
            sim.timing.mechanics,
            sim.timing.correction
        );
        if sim.t >= self.status_next && sim.t < end {
            let every = end / STATUS_LINES;
            self.status_next = ((sim.t / every).floor() + 1.0) * every;
            log(&status_line(sim, dt_used, self.status_contacts, self.wall.elapsed().as_secs_f64()));
            self.status_contacts = sim.contacts.len();
        }
        self.write_due(log)?;
        self.done = self.sim.t >= end;
        Ok(!self.done)
    }

    /// Steps until the time reaches `to` [s] (or the run ends); the last step may pass `to`: the
    /// steps are those of an uninterrupted run. Returns whether the run goes on.
    pub fn advance(&mut self, to: f64, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        while !self.done && self.sim.t < to {
            self.step(log)?;
        }
        Ok(!self.done)
    }

    /// Ends the run before its end time with `reason` as `stop_reason` (`completed = false`):
    /// the series row of the current state is written if it is not yet.
    pub fn stop(&mut self, reason: &str, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        if self.done {
            return Ok(());
        }
        log(&format!("t = {} s (step {}): {reason}: the run ends here", self.sim.t, self.sim.step));
        if self.row_step != self.sim.step {
            self.outputs.row(&self.sim, self.last_dt)?;
            self.row_step = self.sim.step;
        }
        self.stop_reason = Some(reason.to_string());
        self.done = true;
        Ok(())
    }

    /// Writes the end of the run (`summary.json`, plots, the last state as a snapshot if the run
    /// ended early) and returns the summary; a run not yet over is stopped first ("stopped by
    /// the caller"). A model error that ended the run is returned here, after the outputs.
    pub fn finish(mut self, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
        if !self.done {
            self.stop("stopped by the caller", log)?;
        }
        self.bar.finish();
        finish(&self.sim, &self.out, self.outputs, self.stop_reason, self.failure, &self.wall, log)
    }
}

/// The periodic status line of a compact run (issue 25, LAMMPS `thermo` style): time and the
/// end time, step, Δt, temperature range (conducting particles), mean linear
/// shrinkage, relative density (eq. 49), contacts and those new since the last line, wall time.
fn status_line(sim: &Simulation, dt: f64, contacts_before: usize, wall: f64) -> String {
    let (_, lo, hi) = sim.temperature_stats(&sim.isolated_particles());
    let sh = sim.shrinkage();
    let n = sim.contacts.len();
    format!(
        "t = {} of {}: step {}, Δt = {}, T {:.1}–{:.1} K, shrinkage {:.3e}, relative density {:.4}, {} contacts ({:+}), {} kept by (T2), wall {}",
        crate::units::fmt_seconds(sim.t),
        crate::units::fmt_seconds(sim.settings.end),
        sim.step,
        crate::units::fmt_seconds(dt),
        lo,
        hi,
        (sh.x + sh.y + sh.z) / 3.0,
        sim.relative_density(),
        n,
        n as i64 - contacts_before as i64,
        sim.skipped_last,
        io::progress::fmt_wall(wall)
    )
}

/// The start of the log: the run's size and step control, the particles without a path to a heat
/// source and the gap model.
fn announce(sim: &Simulation, log: &mut dyn FnMut(&str)) {
    log(&format!(
        "compact run: {} particles, {} initial contacts, strategy {}, Δt0 = {:e} s, Δt_max = {} s, end = {} s",
        sim.prep.scene.particles.len(),
        sim.contacts.len(),
        sim.settings.strategy,
        sim.dt,
        crate::error::fmt_value(sim.settings.dt_max),
        crate::error::fmt_value(sim.settings.end)
    ));
    let isolated = sim.isolated_particles();
    if !isolated.is_empty() {
        let ids: Vec<String> = isolated.iter().take(20).map(|i| i.to_string()).collect();
        log(&format!(
            "warning: {} particle{} without a conductive path to any heat source (no chain of contacts{} to a heated, fixed or exposed particle): {}{}; they keep their initial temperature and are left out of the mean/min/max temperatures (series.csv, summary.json)",
            isolated.len(),
            if isolated.len() == 1 { "" } else { "s" },
            if sim.prep.gap.is_some() { " or gap pipes" } else { "" },
            ids.join(", "),
            if isolated.len() > 20 { ", …" } else { "" }
        ));
    }
    if let Some(g) = &sim.prep.gap {
        let via = sim.particles_connected_only_through_gaps();
        log(&format!(
            "gap model (docs/heat-model.md (H18)–(H23)): gas k_g = {} W/(m·K), layer f = {}, jump distance M = {} m, surface emissivity {}; {} particle(s) reach a heat source only across gaps",
            g.model.gas_conductivity,
            g.model.layer_thickness,
            g.model.jump_distance,
            g.model.emissivity,
            via.len()
        ));
    }
}

/// The outputs of a run in progress: `series.csv`, the snapshots, the analyses due and the wall
/// time spent before a resume [s].
struct Outputs {
    series: Series,
    snaps: SnapshotWriter,
    /// Lines of series.csv so far (header included).
    series_lines: usize,
    /// The series columns of the run (indices into `Row::COLUMNS`, [`columns::present`]).
    cols: Vec<usize>,
    due: Due,
    wall_before: f64,
}

impl Outputs {
    /// Creates the outputs of a fresh run (and writes its initial row) or reopens those of the
    /// checkpoint's output state `state`.
    fn open(sim: &Simulation, out: &Path, state: Option<OutputState>, log: &mut dyn FnMut(&str)) -> Result<Outputs, Error> {
        let resumed = state.is_some();
        let st = state.unwrap_or_default();
        let (cols, left_out) = columns::present(sim);
        if !resumed {
            left_out.iter().for_each(|l| log(&format!("{}{l}", crate::logging::DETAIL)));
        }
        let (vtu_on, h5_on) = (sim.prep.case.output.vtu, sim.prep.case.output.hdf5);
        let (series, snaps, series_lines) = if resumed {
            (
                Series::resume(&out.join("series.csv"), st.series_lines, cols.len())?,
                SnapshotWriter::resume(out, vtu_on, h5_on, st.snapshots, st.vtu_entries.clone(), log)?,
                st.series_lines,
            )
        } else {
            (Series::create(&out.join("series.csv"), &columns::header(&cols))?, SnapshotWriter::new(out, vtu_on, h5_on, log)?, 1)
        };
        let end = sim.settings.end;
        let snap_times: Vec<f64> = match sim.settings.snapshots {
            0 => vec![],
            1 => vec![end],
            k => (0..k).map(|i| end * i as f64 / (k - 1) as f64).collect(),
        };
        let due = Due {
            snap_times,
            next_snap: st.next_snap,
            next_cond: st.next_cond,
            cond_results: st.cond_results,
            next_hist: st.next_hist,
            hist_results: st.hist_results,
        };
        let mut outputs = Outputs { series, snaps, series_lines, cols, due, wall_before: st.wall_before };
        if !resumed {
            outputs.row(sim, 0.0)?;
        }
        Ok(outputs)
    }

    /// Appends the series row of the current state; `dt`: the step that led to it [s].
    fn row(&mut self, sim: &Simulation, dt: f64) -> Result<(), IoError> {
        self.series.row(&columns::values(&self.cols, &Row::new(sim, dt)))?;
        self.series_lines += 1;
        Ok(())
    }

    /// Writes the snapshots and analyses due now, then the checkpoint (the cached factor dropped
    /// first, so that a resumed run repeats this one bit for bit).
    fn checkpoint(&mut self, sim: &mut Simulation, out: &Path, wall: &Instant, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        self.due.write(sim, out, &mut self.snaps, log)?;
        sim.mechanics.drop_factor()?;
        let os = OutputState {
            next_snap: self.due.next_snap,
            next_cond: self.due.next_cond,
            cond_results: self.due.cond_results.clone(),
            next_hist: self.due.next_hist,
            hist_results: self.due.hist_results.clone(),
            series_lines: self.series_lines,
            snapshots: self.snaps.count(),
            vtu_entries: self.snaps.vtu_entries(),
            wall_before: self.wall_before + wall.elapsed().as_secs_f64(),
        };
        write_checkpoint(out, &sim.checkpoint(os))?;
        Ok(())
    }
}

/// Whether the run ends after this step: the relative density asked for, or the caller's
/// wall-time budget (benchmarks) is reached; the reason (logged), the state so far is summarised.
fn stop_criterion(sim: &Simulation, wall: &Instant, log: &mut dyn FnMut(&str)) -> Option<String> {
    if let Some(r) = sim.settings.stop_relative_density.filter(|&r| sim.relative_density() >= r) {
        log(&format!("t = {} s: relative density {:.4} reached time.stop_relative_density = {r}: the run ends here", sim.t, sim.relative_density()));
        Some(format!("relative density {r} reached"))
    } else if let Some(limit) = sim.settings.wall_limit.filter(|&l| wall.elapsed().as_secs_f64() > l && sim.t < sim.settings.end) {
        log(&format!("t = {} s (step {}): the wall-time limit of {limit} s is reached: the run ends here", sim.t, sim.step));
        Some(format!("wall-time limit of {limit} s reached"))
    } else if sim.t < sim.settings.end && crate::interrupt::requested() {
        log(&format!("t = {} s (step {}): interrupted (signal or KeyboardInterrupt): the outputs are written and the run ends here", sim.t, sim.step));
        Some("interrupted".into())
    } else {
        None
    }
}

/// The end of a run: its last state as a snapshot when it ended early, `summary.json` (also
/// into the HDF5 file), the plots and the closing log line; `failure` is returned after them.
fn finish(
    sim: &Simulation,
    out: &Path,
    mut outputs: Outputs,
    stop_reason: Option<String>,
    failure: Option<Error>,
    wall: &Instant,
    log: &mut dyn FnMut(&str),
) -> Result<serde_json::Value, Error> {
    if stop_reason.is_some() && sim.settings.snapshots > 0 {
        // a run that ends before its end time keeps its last state as a snapshot
        write_snapshot(sim, &mut outputs.snaps)?;
    }
    // data files first (a failed write is the run's error), plots last (a failed plot a warning)
    super::output::write_correction_csv(out, sim, "end")?;
    // the calibrated-range verdict on the run's diffusion dose (docs/diffusion7.md (V1)–(V3))
    let (warn, notes) = sim.below_range_messages();
    warn.iter().for_each(|w| log(&format!("warning: {w}")));
    notes.iter().for_each(|n| log(&format!("{}{n}", crate::logging::DETAIL)));
    let summary = summary(sim, &outputs.due, stop_reason, outputs.wall_before + wall.elapsed().as_secs_f64());
    io::write_json(&out.join("summary.json"), &summary)?;
    // the series and summary also go into the HDF5 file (docs/outputs.md)
    if sim.prep.case.output.hdf5
        && let Err(e) = io::hdf5::finish(out)
    {
        log(&format!("warning: series and summary not copied into sinterdem.h5: {e}"));
    }
    if !sim.settings.plots {
        log("plots skipped (turned off by the caller)");
    } else if let Err(e) = write_plots(out, sim) {
        log(&format!("warning: plots not written: {e}"));
    }
    log(&format!(
        "7-DOF sweep: {} contact-steps kept unchanged by docs/diffusion7.md (T2) (not integrated); {} ODE steps ({} rejected), {} right-hand sides",
        sim.ode.skipped, sim.ode.steps, sim.ode.rejected, sim.ode.rhs
    ));
    let sh = sim.shrinkage();
    log(&format!(
        "done: {} steps to t = {} s in {:.3} s; shrinkage x/y/z = {:.4e}/{:.4e}/{:.4e}; relative density {:.4}; mean neck ratio {:.4}",
        sim.step,
        sim.t,
        wall.elapsed().as_secs_f64(),
        sh.x,
        sh.y,
        sh.z,
        sim.relative_density(),
        sim.mean_neck_ratio()
    ));
    match failure {
        Some(e) => Err(e),
        None => Ok(summary),
    }
}

/// `summary.json` of a run in its current state; `wall_seconds`: the wall time of the run so far,
/// resumes included [s].
fn summary(sim: &Simulation, due: &Due, stop_reason: Option<String>, wall_seconds: f64) -> serde_json::Value {
    let n = sim.prep.scene.particles.len();
    let sh = sim.shrinkage();
    let stored_total: f64 = sim.prep.scene.particles.capacity.iter().zip(&sim.prep.scene.particles.temperature).map(|(c, t)| c * t).sum();
    let balance = if sim.heat.is_some() { crate::heat::balance::energy_balance_rel(sim.heat_stored, sim.heat_in, sim.heat_scale, stored_total) } else { 0.0 };
    let isolated = sim.isolated_particles();
    let t_stats = sim.temperature_stats(&isolated);
    let dl = &sim.contacts.dl_bar;
    let dl_mean = dl.iter().sum::<f64>() / dl.len().max(1) as f64;
    let dl_std = (dl.iter().map(|v| (v - dl_mean) * (v - dl_mean)).sum::<f64>() / dl.len().max(1) as f64).sqrt();
    let v_particles: f64 = sim.prep.scene.particles.radius.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    let rho0 = v_particles / (sim.extent0.x * sim.extent0.y * sim.extent0.z);
    let stress = sim.macroscopic_stress();
    let mut summary = json!({
        "kind": "compact",
        "final_time_s": sim.t,
        "steps": sim.step,
        "rejected_steps": sim.rejected,
        "wall_seconds": wall_seconds,
        "particles": n,
        "contacts": sim.contacts.len(),
        "shrinkage_x": sh.x,
        "shrinkage_y": sh.y,
        "shrinkage_z": sh.z,
        "relative_density": sim.relative_density(),
        "relative_density_initial": rho0,
        "coordination_mean": sim.coordination(),
        "neck_ratio": sim.mean_neck_ratio(),
        "mean_temperature_K": t_stats.0,
        "min_temperature_K": t_stats.1,
        "max_temperature_K": t_stats.2,
        "isolated_particles": isolated.len(),
        "isolated_particle_ids": isolated.iter().take(100).collect::<Vec<_>>(),
        "temperatures_exclude_isolated": !isolated.is_empty() && isolated.len() < n,
        "energy_balance_rel": balance,
        "rhs_evaluations": sim.ode.rhs,
        "limited_corrections": sim.limited_corrections,
        "ode_steps": sim.ode.steps,
        "ode_rejected": sim.ode.rejected,
        "timing_seconds": sim.timing,
        "mechanics_profile": sim.mechanics.profile,
        "dl_bar_mean_m": dl_mean,
        "dl_bar_std_m": dl_std,
        "conductivity": due.cond_results,
        "correction_histograms": due.hist_results,
        "mechanics": {
            "newton_iterations": sim.mechanics.newton_iterations,
            "factorizations": sim.mechanics.factorizations,
            "max_final_residual": sim.mechanics.max_residual,
            "rtol": sim.settings.mechanics.rtol,
        },
        "load": sim.load.as_ref().map(|l| json!({
            "mode": format!("{:?}", l.settings.mode),
            "applied_stress_Pa": sim.applied_stress(),
            "peak_stress_Pa": l.settings.stress.max(),
            "distribution_solves": l.solves,
        })).unwrap_or_else(|| json!({"mode": "none"})),
        "stress_tensor_Pa": {
            "xx": stress[0], "yy": stress[1], "zz": stress[2],
            "yz": stress[3], "xz": stress[4], "xy": stress[5],
        },
        "normal_force_mean_N": sim.mean_normal_force(),
        "skipped": sim.skipped,
        "warnings": sim
            .warnings
            .iter()
            .cloned()
            .chain(sim.below_range_messages().0)
            // the cut-face warning of the faces method (H17b), once
            .chain(due.cond_results.iter().find_map(|c| c.get("warning").and_then(|w| w.as_str()).map(String::from)))
            .collect::<Vec<_>>(),
        "extrapolated_below_range": sim.below_range_summary(),
        "threads": rayon::current_num_threads(),
        "completed": stop_reason.is_none(),
        "stop_reason": stop_reason.unwrap_or_else(|| "end time reached".into()),
    });
    let prof = sim.layer_profile(5);
    summary["contact_steps_skipped"] = json!(sim.ode.skipped);
    summary["layer_z_m"] = json!(prof.iter().map(|l| l.0).collect::<Vec<_>>());
    summary["layer_contact_shrinkage"] = json!(prof.iter().map(|l| l.1).collect::<Vec<_>>());
    summary["layer_neck_ratio"] = json!(prof.iter().map(|l| l.2).collect::<Vec<_>>());
    if let Some(g) = &sim.prep.gap {
        // the gap model (docs/heat-model.md (H18)–(H23)): pipes of the last step, and the particles
        // that reach a heat source only across gaps (not isolated, but hanging on the gas)
        summary["gap_pipes"] = json!(g.pipes().map_or(0, |p| p.len()));
        summary["particles_connected_only_through_gaps"] = json!(sim.particles_connected_only_through_gaps());
    }
    // thermal expansion (docs/coupled.md (X10), (X11)): zeros and the total shrinkage when off
    let (eps, ss) = (sim.thermal_strain(), sim.sintering_shrinkage());
    summary["thermal_expansion"] = json!(sim.expansion.is_some());
    summary["thermal_strain"] = json!(eps.0);
    summary["thermal_strain_min"] = json!(eps.1);
    summary["thermal_strain_max"] = json!(eps.2);
    summary["sintering_shrinkage_x"] = json!(ss.x);
    summary["sintering_shrinkage_y"] = json!(ss.y);
    summary["sintering_shrinkage_z"] = json!(ss.z);
    if let Some(c) = &sim.cell {
        summary["periodic_cell"] = c.summary();
        if let Ok(Some(s)) = sim.sintering_stress() {
            summary["periodic_cell"]["sintering_stress_Pa"] = json!(s);
            summary["periodic_cell"]["sintering_stress_mean_Pa"] = json!((s[0] + s[1] + s[2]) / 3.0);
        }
    }
    summary
}

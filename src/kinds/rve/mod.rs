//! Constitutive data of a periodic compact (`sinterdem rve CASE --out DIR`, docs/rve.md): the
//! free sintering run of a periodic cell (a [`Stepper`], the same files as `sinterdem run`), and
//! at each time of `rve.at` short branch runs cloned from it (checkpoint state) under small
//! compressive stress perturbations, whose strain-rate differences give the bulk viscosity (R3),
//! the uniaxial viscosity (R4), the viscous Poisson ratio (R5), the shear viscosity (R6) and the
//! sintering stress (R7); with the conductivity tensor of the cell, one row of
//! `DIR/constitutive.csv` per time. A Skorohod–Olevsky law (R9)–(R11) fitted to the table goes
//! to `DIR/fit.json`.

mod branch;
pub mod fit;
mod output;

pub use branch::{Point, measure_point};
pub use fit::{LawFit, fit_skorohod_olevsky};
pub use output::{fit_rows, rve_plots};

use super::{RunParams, RunSummary, Stepper};
use crate::config::ranges::{Range, c, p};
use crate::coupled::cell::Control;
use crate::error::{ConfigError, Error};
use std::path::Path;
use std::time::Instant;

/// The keys of `[rve]` (docs/case-file.md, docs/rve.md).
pub static RANGES: &[Range] = &[
    p("rve.at", 0.0, 1e9, "s", "sinterdem rve: times of the free run at which the branch runs start (strictly increasing, at most time.end)"),
    p("rve.interval", 0.0, 1e6, "s", "sinterdem rve: simulated length of each branch run (R2)"),
    c("rve.steps", 2.0, 1000.0, "1", "sinterdem rve: global steps of equal length per branch run; the rate is measured over all but the first (R2)"),
    c(
        "rve.perturbation",
        1e-3,
        1.0,
        "1",
        "sinterdem rve: compressive stress perturbation Δ as a fraction of the cell's (B23) sintering stress at the branch point (R1)",
    ),
    p(
        "rve.fit_temperature",
        0.0,
        5000.0,
        "K",
        "sinterdem rve: the law (R9)–(R11) is fitted to the rows within 0.5 K of this temperature (default: the last row's)",
    ),
];

fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(RANGES, key, v)
}

/// `[rve]` as written.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RveSpec {
    at: Vec<f64>,
    interval: f64,
    steps: Option<f64>,
    perturbation: Option<f64>,
    fit_temperature: Option<f64>,
}

/// The validated `[rve]`.
#[derive(Debug, Clone, PartialEq)]
pub struct RveSettings {
    /// Branch times [s], strictly increasing.
    pub at: Vec<f64>,
    /// Branch length [s].
    pub interval: f64,
    /// Steps per branch [1] (≥ 2).
    pub steps: u32,
    /// Δ / σ_s(B23) [1].
    pub perturbation: f64,
    /// Temperature of the rows fitted [K] (None: the last row's).
    pub fit_temperature: Option<f64>,
}

impl RveSettings {
    /// Reads `[rve]` of a resolved case (`end`: `time.end` [s]); errors name the key, the value
    /// and what is allowed.
    pub fn from_case(case: &toml::Value, end: f64) -> Result<RveSettings, ConfigError> {
        let Some(v) = case.get("rve") else {
            return Err(ConfigError::invalid(
                "sinterdem rve: the case has no [rve] section: give at least rve.at = [t1, t2, …] (s, times of the free run) and rve.interval (s) (docs/rve.md)",
            ));
        };
        let spec: RveSpec = v.clone().try_into().map_err(|e| ConfigError::invalid(format!("[rve]: {e}")))?;
        if spec.at.is_empty() {
            return Err(ConfigError::invalid("rve.at = []: give at least one time (s) of the free run"));
        }
        for (k, &t) in spec.at.iter().enumerate() {
            check("rve.at", t).map_err(|e| rename(e, format!("rve.at[{k}]")))?;
            if t > end {
                return Err(ConfigError::inconsistent(
                    format!("rve.at[{k}]"),
                    format!("{} s is after time.end = {} s", crate::error::fmt_value(t), crate::error::fmt_value(end)),
                ));
            }
            if k > 0 && t <= spec.at[k - 1] {
                return Err(ConfigError::invalid(format!(
                    "rve.at[{k}]: {} s is not after the previous time {} s (strictly increasing)",
                    crate::error::fmt_value(t),
                    crate::error::fmt_value(spec.at[k - 1])
                )));
            }
        }
        let interval = check("rve.interval", spec.interval)?;
        let steps = check("rve.steps", spec.steps.unwrap_or(4.0))?;
        if steps.fract() != 0.0 {
            return Err(ConfigError::invalid(format!("rve.steps = {}: expected a whole number of steps in [2, 1000]", crate::error::fmt_value(steps))));
        }
        // a branch step must advance the clock at every branch time: far above its resolution
        // (the branch loop compares times to 1e-12 relative; issue 38: 1e-15 s indexed past the
        // strains of a branch that never stepped)
        let h = interval / steps;
        for (k, &t) in spec.at.iter().enumerate() {
            if !(h >= 1e-9 * t) {
                return Err(ConfigError::inconsistent(
                    "rve.interval",
                    format!(
                        "{} s over rve.steps = {steps} is a branch step of {} s, below the time resolution at rve.at[{k}] = {} s: give rve.interval ≥ {} s (a step of at least 1e-9 × the branch time)",
                        crate::error::fmt_value(interval),
                        crate::error::fmt_value(h),
                        crate::error::fmt_value(t),
                        crate::error::fmt_value(1e-9 * t * steps)
                    ),
                ));
            }
        }
        let perturbation = check("rve.perturbation", spec.perturbation.unwrap_or(0.2))?;
        let fit_temperature = spec.fit_temperature.map(|t| check("rve.fit_temperature", t)).transpose()?;
        Ok(RveSettings { at: spec.at, interval, steps: steps as u32, perturbation, fit_temperature })
    }
}

fn rename(e: ConfigError, key: String) -> ConfigError {
    match e {
        ConfigError::OutOfRange { value, range, unit, .. } => ConfigError::OutOfRange { key, value, range, unit },
        o => o,
    }
}

/// Refuses a compact that is not free sintering on a periodic cell (every component stress
/// controlled at zero at all times), naming the key at fault.
pub fn check_free_periodic(sim: &crate::coupled::Simulation) -> Result<(), ConfigError> {
    let Some(cs) = sim.settings.mechanics.cell.as_ref() else {
        return Err(ConfigError::inconsistent(
            "mechanics.boundary",
            "sinterdem rve needs a periodic cell: mechanics.boundary = \"periodic\" on a periodic packing (docs/rve.md)",
        ));
    };
    for (k, ctl) in cs.controls.iter().enumerate() {
        let name = crate::mechanics::periodic::COMPONENTS[k];
        match ctl {
            Control::Stress(rows) if rows.iter().all(|r| r[1] == 0.0) => {}
            _ => {
                return Err(ConfigError::inconsistent(
                    format!("mechanics.cell.{name}"),
                    "sinterdem rve perturbs free sintering: every cell component must be stress-controlled at 0 Pa (xx = { stress = 0.0 })",
                ));
            }
        }
    }
    Ok(())
}

/// The times `at` merged into the case's `output.conductivity_at` (so that the free run lands
/// exactly on them and its summary lists the tensors there), as an override.
fn conductivity_override(case: &toml::Value, at: &[f64]) -> String {
    let mut times: Vec<f64> = case
        .get("output")
        .and_then(|o| o.get("conductivity_at"))
        .and_then(|a| a.as_array())
        .map(|a| a.iter().filter_map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64))).collect())
        .unwrap_or_default();
    times.extend_from_slice(at);
    times.sort_by(f64::total_cmp);
    times.dedup();
    format!("output.conductivity_at=[{}]", times.iter().map(|t| format!("{t:?}")).collect::<Vec<_>>().join(", "))
}

/// `sinterdem rve`: the free run into `out` (series, snapshots, checkpoints as `sinterdem run`),
/// the branch runs at `rve.at`, then `constitutive.csv`, `constitutive.png`,
/// `sintering_stress.png`, `fit.json` and `summary.json` (the compact summary with an `rve` block).
pub fn run(case: &toml::Value, overrides: &[String], out: &Path, params: &RunParams) -> Result<RunSummary, Error> {
    let wall = Instant::now();
    let mut expanded = case.clone();
    crate::config::expand_includes(&mut expanded, &params.base_dir)?;
    let value = super::resolve(&expanded, overrides)?;
    if super::Kind::of(&value)? != super::Kind::Compact {
        return Err(ConfigError::invalid("sinterdem rve: kind must be \"compact\" (a periodic compact, mechanics.boundary = \"periodic\")").into());
    }
    let end = value.get("time").and_then(|t| t.get("end")).and_then(|e| e.as_float().or_else(|| e.as_integer().map(|i| i as f64))).unwrap_or(f64::INFINITY);
    let rve = RveSettings::from_case(&value, end)?;
    let mut sets = overrides.to_vec();
    sets.push(conductivity_override(&value, &rve.at));
    let stepper = crate::io::lock::as_command("rve", || Stepper::start(&expanded, &sets, out, params))?;
    {
        let sim = stepper.compact_simulation().ok_or_else(|| ConfigError::invalid("sinterdem rve: kind must be \"compact\""))?;
        check_free_periodic(sim)?;
    }
    // the points file marks the directory as an rve run's before the first step (a checkpoint
    // may follow): `sinterdem resume` then completes the branches, table, fit and plots
    write_points(out, &[])?;
    complete(stepper, &rve, Vec::with_capacity(rve.at.len()), out, params, wall)
}

/// The branch points measured so far (`DIR/rve_points.json`, rewritten atomically after each
/// point): an rve run's directory holds it from its start, and `resume` continues from it.
pub const POINTS_FILE: &str = "rve_points.json";

/// The points file: `{"points": [...]}` sealed with its checksum as a checkpoint is
/// ([`crate::io::write_checkpoint_json`]): a point changed after it was measured is refused by
/// `resume`, not written into `constitutive.csv` (issue 38, found by the run-path fuzzer).
fn write_points(out: &Path, points: &[Point]) -> Result<(), Error> {
    let path = out.join(POINTS_FILE);
    let text = serde_json::to_string(&serde_json::json!({ "points": points })).map_err(|e| crate::error::IoError::new(&path, e))?;
    Ok(crate::io::write_checkpoint_json(&path, &text)?)
}

/// The points of a points file written by [`write_points`], its checksum checked.
fn read_points(path: &Path) -> Result<Vec<Point>, Error> {
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct File {
        points: Vec<Point>,
    }
    let text = crate::io::read_checkpoint_json(path)?;
    let f: File = serde_json::from_str(&text).map_err(|e| crate::error::IoError::new(path, format!("not an rve points file: {e}")))?;
    Ok(f.points)
}

/// Whether `dir` holds an rve run (its points file).
pub fn is_rve_dir(dir: &Path) -> bool {
    dir.join(POINTS_FILE).is_file()
}

/// `sinterdem resume DIR` of an rve run: the free run continued from its checkpoint, the points
/// not yet measured measured on it, then the table, fit, plots and summary, as the uninterrupted
/// run writes them (a point measured before the kill is kept: it depends on the free run's state
/// at its time only, which the resumed run reproduces bit for bit).
pub(crate) fn resume(dir: &Path, params: &RunParams, mut log: super::RunLog) -> Result<RunSummary, Error> {
    let wall = Instant::now();
    let ck = crate::kinds::compact::read_checkpoint(dir)?;
    let value: toml::Value = toml::Value::Table(ck.case_toml.parse::<toml::Table>().map_err(|e| ConfigError::invalid(format!("checkpoint case: {e}")))?);
    let end = value.get("time").and_then(|t| t.get("end")).and_then(|e| e.as_float().or_else(|| e.as_integer().map(|i| i as f64))).unwrap_or(f64::INFINITY);
    let rve = RveSettings::from_case(&value, end)?;
    let path = dir.join(POINTS_FILE);
    let points = read_points(&path)?;
    if points.len() > rve.at.len() || points.iter().zip(&rve.at).any(|(p, &t)| p.time < t * (1.0 - 1e-12)) {
        return Err(crate::error::IoError::new(
            &path,
            format!("does not match rve.at of the checkpoint's case ({} points for {} times)", points.len(), rve.at.len()),
        )
        .into());
    }
    let stepper = {
        let mut logf = |m: &str| log.line(m);
        let (sim, state) = crate::coupled::Simulation::from_checkpoint(&ck, &mut logf)?;
        if let Some(&t) = rve.at.get(points.len())
            && sim.t > t * (1.0 + 1e-12)
        {
            return Err(ConfigError::invalid(format!(
                "{}: the checkpoint (t = {} s) is past rve.at = {t} s, whose point is not in {POINTS_FILE}: the point cannot be measured again; run the case again with `sinterdem rve CASE --out {} --force`",
                dir.display(),
                sim.t,
                dir.display()
            ))
            .into());
        }
        logf(&format!("rve: {} of {} points measured before the interruption", points.len(), rve.at.len()));
        let run = crate::kinds::compact::CompactRun::start(sim, dir, params.progress, Some(state), &mut logf)?;
        Stepper::from_compact(run, log, wall)
    };
    complete(stepper, &rve, points, dir, params, wall)
}

/// The rest of an rve run from `stepper` (free run at its start, or resumed) with the points
/// `points` measured: the remaining points, the free run to its end, then the outputs.
fn complete(mut stepper: Stepper, rve: &RveSettings, mut points: Vec<Point>, out: &Path, params: &RunParams, wall: Instant) -> Result<RunSummary, Error> {
    let first = points.len();
    for (k, &t) in rve.at.iter().enumerate().skip(first) {
        stepper.advance(t)?;
        let sim = stepper.compact_simulation().ok_or_else(|| ConfigError::invalid("sinterdem rve: kind must be \"compact\""))?;
        if stepper.done() && sim.t < t * (1.0 - 1e-12) {
            // the free run ended early (a stop criterion or a model error): the rows so far
            break;
        }
        let tic = Instant::now();
        let point = measure_point(sim, rve)?;
        tracing::info!(
            "rve point {}/{} at t = {:.6e} s: relative density {:.4}, K = {:.4e} Pa s, E_p = {:.4e} Pa s, nu_p = {:.4}, sigma_s = {:.4e} Pa (B23 {:.4e} Pa), {:.2} s",
            k + 1,
            rve.at.len(),
            point.time,
            point.relative_density,
            point.bulk_viscosity,
            point.uniaxial_viscosity,
            point.poisson_ratio,
            point.sintering_stress,
            point.sintering_stress_b23,
            tic.elapsed().as_secs_f64()
        );
        points.push(point);
        write_points(out, &points)?;
    }
    while stepper.step()? {}
    let (r0, header) = {
        let sim = stepper.compact_simulation().ok_or_else(|| ConfigError::invalid("sinterdem rve: kind must be \"compact\""))?;
        (sim.prep.scene.particles.mean_radius(), crate::kinds::compact::plot_header(sim))
    };
    let mut summary = stepper.finish()?;
    let fit = output::fit_rows(&points, r0, rve.fit_temperature);
    output::write(out, &points, &fit, params.plots.then_some(&header))?;
    summary.summary["kind"] = serde_json::json!("rve");
    summary.summary["rve"] = output::summary_block(rve, &points, &fit);
    crate::io::write_json(&out.join("summary.json"), &summary.summary)?;
    summary.wall_seconds = wall.elapsed().as_secs_f64();
    Ok(summary)
}

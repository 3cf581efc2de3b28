//! Calibration of diffusion data and path factors against measured neck growth and shrinkage
//! (`sinterdem calibrate CALIB.toml --out DIR`; user guide `docs/calibration.md`).
//!
//! - [`data`]: the measured-data CSV files (file/line/column errors);
//! - [`params`]: the fitted parameters `PHASE.FIELD` / `model.FIELD`, bounds, log space;
//! - [`model`]: what the optimisers see of a forward model: batches of parameter sets, a memo;
//! - [`forward`]: the pair forward model, one 7-DOF pair run per experiment, in parallel;
//! - [`compact`]: the packing forward model (`model = "compact"`), each optimiser generation one
//!   study of the study engine (local or SLURM); and `--validate-compact`;
//! - [`loss`]: χ² of the normalised residuals, failed runs as a penalty;
//! - [`optimise`]: argmin's particle swarm, then a Gauss–Newton trust region or Nelder–Mead;
//! - [`report`]: σ and correlations from (JᵀWJ)⁻¹, `calibration.json`, `material.toml`,
//!   `residuals.csv`, PNGs;
//! - [`synthetic`]: the bundled synthetic titanium data set (perturbed β phase, seeded noise).
//!
//! [`check`] validates a calibration file without fitting (`sinterdem check CALIB.toml`).

pub mod compact;
pub mod data;
pub mod forward;
pub mod loss;
pub mod model;
pub mod optimise;
pub mod params;
pub mod report;
pub mod synthetic;

use crate::config::from_value;
use crate::config::ranges::{Range, c, o, p};
use crate::error::{ConfigError, Error, IoError};
use crate::models::diffusion7::{Material, PathFactors, SolverOptions};
use data::Experiment;
use forward::{PairGeometry, PairModel};
use model::{Evaluator, ForwardModel, Problem};
use params::{Parameter, ParameterEntry};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Numeric keys of calibration files and of their data files (added to the list by `every_table`).
pub static RANGES: &[Range] = &[
    c("optimiser.swarm_size", 1.0, 1e4, "1", "calibration: particles of the swarm (global phase)"),
    c("optimiser.swarm_iterations", 0.0, 1e5, "1", "calibration: swarm iterations (0: local phase only, from the starting material)"),
    c("optimiser.local_iterations", 0.0, 1e5, "1", "calibration: largest number of local iterations (trust region or Nelder-Mead)"),
    o("optimiser.tolerance", 0.0, 1.0, "1", "calibration: relative decrease of chi2 below which a local iteration counts as stalled"),
    c("optimiser.stall", 1.0, 1e3, "1", "calibration: stalled local iterations in a row that end the fit"),
    c(
        "optimiser.fd_step",
        1e-8,
        0.1,
        "1",
        "calibration: finite-difference step of the Jacobian in unit coordinates of the parameter ranges; at least 1e-8, so that the step moves every parameter by more than round-off",
    ),
    p(
        "optimiser.simplex_scale",
        0.0,
        1.0,
        "1",
        "calibration, local = \"nelder_mead\": edge of the initial simplex in unit coordinates of the parameter ranges",
    ),
    p(
        "optimiser.simplex_tolerance",
        0.0,
        1e6,
        "1",
        "calibration, local = \"nelder_mead\": standard deviation of chi2 over the simplex below which the local phase stops",
    ),
    p("data.diameter_m", 0.0, 2e-2, "m", "calibration data: mean particle diameter of an experiment"),
    c("data.neck_ratio", 0.0, 1.0, "1", "calibration data: measured neck ratio y1/R"),
    c(
        "data.neck_ratio_sigma",
        1e-9,
        1.0,
        "1",
        "calibration data: one standard deviation of the neck ratio (at least 1e-9, so that chi^2 and the 1/sigma-weighted Jacobian stay finite)",
    ),
    c("data.shrinkage", -1.0, 1.0, "1", "calibration data: measured shrinkage dL/L0"),
    c(
        "data.shrinkage_sigma",
        1e-9,
        1.0,
        "1",
        "calibration data: one standard deviation of the shrinkage (at least 1e-9, so that chi^2 and the 1/sigma-weighted Jacobian stay finite)",
    ),
    c("data.time_s", 0.0, 1e9, "s", "calibration series: time since the start of the schedule"),
];

/// Every range table of the crate: the kinds' list ([`crate::kinds::keys::tables`]) and the
/// calibration files' [`RANGES`] (for `sinterdem keys` and docs/case-file.md).
pub fn every_table() -> Vec<&'static [Range]> {
    let mut t = crate::kinds::keys::tables();
    t.push(RANGES);
    t
}

/// Checks `v` of a key of a calibration file or of a case ([`lookup`]).
fn check_range(key: &str, v: f64) -> Result<f64, ConfigError> {
    lookup(key).ok_or_else(|| ConfigError::invalid(format!("internal: key {key} has no entry in the range table")))?.check(key, v)
}

/// Looks up a key of a case or of a calibration file in [`every_table`].
pub(crate) fn lookup(key: &str) -> Option<&'static Range> {
    crate::kinds::keys::lookup(key).or_else(|| crate::config::ranges::lookup_in(&[RANGES], key))
}

fn default_model() -> String {
    "pair".into()
}
fn default_seed() -> u64 {
    1
}

/// `[optimiser]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct OptimiserSection {
    local: Option<String>,
    simplex_scale: Option<f64>,
    simplex_tolerance: Option<f64>,
    swarm_size: Option<f64>,
    swarm_iterations: Option<f64>,
    local_iterations: Option<f64>,
    tolerance: Option<f64>,
    stall: Option<f64>,
    fd_step: Option<f64>,
}

/// `[pair]`: initial geometry of every experiment's pair.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct PairSection {
    overlap: Option<f64>,
    neck_epsilon: Option<f64>,
    cone_eta: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibFile {
    /// Optional `kind = "calibration"` (what `sinterdem check` recognises; see [`crate::config::is_calibration`]).
    #[serde(default)]
    kind: Option<String>,
    #[serde(default)]
    title: Option<String>,
    #[serde(default)]
    description: Option<String>,
    data: String,
    #[serde(default)]
    series: Option<String>,
    material: String,
    #[serde(default)]
    include: Option<String>,
    #[serde(default)]
    materials: Vec<toml::Value>,
    #[serde(default = "default_model")]
    model: String,
    #[serde(default = "default_seed")]
    seed: u64,
    #[serde(default)]
    parameters: Vec<toml::Value>,
    #[serde(default)]
    optimiser: OptimiserSection,
    #[serde(default)]
    solver: SolverOptions,
    /// Starting path factors (the keys of `[model]` of pair cases), checked below.
    #[serde(default)]
    path_factors: Option<toml::Table>,
    #[serde(default)]
    pair: PairSection,
    /// The packing of `model = "compact"` and of `--validate-compact`.
    #[serde(default)]
    compact: compact::CompactSection,
}

/// The forward model of a calibration (`model = …`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    /// Every experiment as a two-particle run, in-process (`pair`, default).
    Pair,
    /// Every experiment on the packing of `[compact]`, each generation a study (`compact`).
    Compact,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Pair => "pair",
            ModelKind::Compact => "compact",
        }
    }
}

/// A validated calibration.
#[derive(Debug)]
pub struct Setup {
    pub title: String,
    pub model: ModelKind,
    pub data_path: PathBuf,
    pub series_path: Option<PathBuf>,
    pub experiments: Vec<Experiment>,
    pub material: Material,
    pub factors: PathFactors,
    pub params: Vec<Parameter>,
    pub settings: optimise::Settings,
    pub solver: SolverOptions,
    pub geometry: PairGeometry,
    /// `[compact]`: the packing of `model = "compact"` and of `--validate-compact`.
    pub compact: compact::CompactSection,
    /// The calibration file's folder (relative paths).
    pub base: PathBuf,
    /// Run the chosen experiments on the compact with the fitted material after the fit.
    pub validate_compact: bool,
    /// Remove the outputs of an earlier command in `out` first (`--force`).
    pub force: bool,
}

fn materials_of(list: Vec<toml::Value>, at: &str) -> Result<Vec<Material>, ConfigError> {
    list.into_iter()
        .enumerate()
        .map(|(i, v)| {
            Material::from_value(v).map_err(|e| match e {
                ConfigError::Invalid(m) => ConfigError::Invalid(format!("{at}materials[{i}]: {m}")),
                other => other,
            })
        })
        .collect()
}

/// Parses and validates a calibration file (`base`: its directory, for relative paths); reads the data.
pub fn parse(value: &toml::Value, base: &Path) -> Result<Setup, Error> {
    let f: CalibFile = from_value(value.clone(), "")?;
    if let Some(k) = f.kind.as_deref().filter(|k| *k != "calibration") {
        return Err(ConfigError::invalid(format!("kind = \"{k}\": a calibration file has kind = \"calibration\" (or none)")).into());
    }
    let model = match f.model.as_str() {
        "pair" => ModelKind::Pair,
        "compact" => ModelKind::Compact,
        m => return Err(ConfigError::invalid(format!("model = \"{m}\": expected \"pair\" or \"compact\"")).into()),
    };
    let mut defined = materials_of(f.materials, "")?;
    // path factors: [path_factors] as written, then the keys it lacks from an included [model]
    let mut factor_table = f.path_factors.clone().unwrap_or_default();
    if let Some(inc) = &f.include {
        let path = base.join(inc);
        let text = crate::io::read_input(&path)?;
        let t: toml::Table = text.parse().map_err(|e: toml::de::Error| ConfigError::invalid(format!("{}: {}", path.display(), e.message())))?;
        for k in t.keys() {
            if k != "materials" && k != "model" {
                return Err(ConfigError::invalid(format!(
                    "include = \"{inc}\": unknown key \"{k}\" (a material file holds [[materials]] and optionally [model])"
                ))
                .into());
            }
        }
        let list = t.get("materials").and_then(|m| m.as_array()).cloned().unwrap_or_default();
        defined.extend(materials_of(list, &format!("{inc}: "))?);
        if let Some(m) = t.get("model") {
            from_value::<PathFactors>(m.clone(), "model").map_err(|e| ConfigError::invalid(format!("include = \"{inc}\": {e}")))?;
            for (k, v) in m.as_table().into_iter().flatten() {
                factor_table.entry(k.clone()).or_insert_with(|| v.clone());
            }
        }
    }
    let factors: PathFactors = from_value(toml::Value::Table(factor_table), "path_factors")?;
    let material = match defined.iter().find(|m| m.name == f.material) {
        Some(m) => m.clone(),
        None => Material::builtin(&f.material).map_err(|e| match e {
            ConfigError::Invalid(m) => ConfigError::Invalid(format!("material: {m}")),
            o => o,
        })?,
    };
    factors.validate().map_err(|e| match e {
        ConfigError::OutOfRange { key, value, range, unit } => ConfigError::OutOfRange { key: key.replace("model.", "path_factors."), value, range, unit },
        o => o,
    })?;
    f.solver.validate()?;
    let mut entries = Vec::new();
    for (i, v) in f.parameters.into_iter().enumerate() {
        entries.push(from_value::<ParameterEntry>(v, &format!("parameters[{i}]"))?);
    }
    let params = params::parse_parameters(&entries, &material)?;
    params::check_start(&params, &material, &factors)?;
    let o = &f.optimiser;
    let d = optimise::Settings::default();
    let get = |k: &str, v: Option<f64>, dflt: f64| -> Result<f64, ConfigError> { check_range(&format!("optimiser.{k}"), v.unwrap_or(dflt)) };
    let local = match o.local.as_deref().unwrap_or("trust_region") {
        "trust_region" => optimise::LocalMethod::TrustRegion,
        "nelder_mead" => optimise::LocalMethod::NelderMead,
        m => return Err(ConfigError::invalid(format!("optimiser.local = \"{m}\": expected \"trust_region\" (default) or \"nelder_mead\"")).into()),
    };
    let settings = optimise::Settings {
        local,
        simplex_scale: get("simplex_scale", o.simplex_scale, d.simplex_scale)?,
        simplex_tolerance: get("simplex_tolerance", o.simplex_tolerance, d.simplex_tolerance)?,
        swarm_size: get("swarm_size", o.swarm_size, d.swarm_size as f64)? as usize,
        swarm_iterations: get("swarm_iterations", o.swarm_iterations, d.swarm_iterations as f64)? as u64,
        local_iterations: get("local_iterations", o.local_iterations, d.local_iterations as f64)? as u64,
        tolerance: get("tolerance", o.tolerance, d.tolerance)?,
        stall: get("stall", o.stall, d.stall as f64)? as u64,
        fd_step: get("fd_step", o.fd_step, d.fd_step)?,
        seed: f.seed,
    };
    let g = PairGeometry::default();
    let geometry = PairGeometry {
        overlap: check_range("pair.overlap", f.pair.overlap.unwrap_or(g.overlap))?,
        neck_epsilon: check_range("pair.neck_epsilon", f.pair.neck_epsilon.unwrap_or(g.neck_epsilon))?,
        cone_eta: check_range("pair.cone_eta", f.pair.cone_eta.unwrap_or(g.cone_eta))?,
    };
    let data_path = base.join(&f.data);
    let mut experiments = data::read_experiments(&data_path)?;
    let series_path = f.series.as_ref().map(|s| base.join(s));
    if let Some(sp) = &series_path {
        data::read_series(sp, &mut experiments)?;
    }
    data::check_counts(&experiments, &data_path.display().to_string())?;
    if model == ModelKind::Compact {
        // the packing fits the chosen experiments; its case and engine must be valid
        let chosen = f.compact.chosen(&experiments)?;
        experiments = chosen.into_iter().map(|i| experiments[i].clone()).collect();
        f.compact.engine_settings()?;
        compact::fit_case(&f.compact, base, &material, &factors)?;
    }
    Ok(Setup {
        title: f.title.or(f.description).unwrap_or_else(|| "calibration".into()),
        model,
        data_path,
        series_path,
        experiments,
        material,
        factors,
        params,
        settings,
        solver: f.solver,
        geometry,
        compact: f.compact,
        base: base.to_path_buf(),
        validate_compact: false,
        force: false,
    })
}

/// Runs a validated calibration and writes its results into `out`. `log` receives progress lines.
pub fn run(setup: Setup, out: &Path, log: &mut dyn FnMut(&str)) -> Result<report::CalibrationReport, Error> {
    let start = std::time::Instant::now();
    let lock = crate::io::lock::OutputLock::acquire(out, "calibrate")?;
    if let Some(note) = lock.takeover_note() {
        log(&note);
    }
    // an unfinished calibration is continued; finished or foreign outputs need --force (docs/outputs.md)
    let inputs: Vec<_> = [setup.data_path.clone()].into_iter().chain(setup.series_path.clone()).collect();
    if let Some(note) = crate::io::outdir::claim(out, crate::io::outdir::Claimant::Calibration, setup.force, None, &inputs)? {
        log(&note);
    }
    let Setup {
        title,
        model,
        data_path,
        series_path,
        experiments,
        material,
        factors,
        params,
        settings,
        solver,
        geometry,
        compact,
        base,
        validate_compact,
        force: _,
    } = setup;
    let nvals: usize = experiments.iter().map(|e| e.count()).sum();
    let problem = Problem { experiments, material, factors, params };
    let pair_model;
    let compact_model;
    let fwd: &dyn ForwardModel = match model {
        ModelKind::Pair => {
            pair_model = PairModel { problem, solver, geometry };
            &pair_model
        }
        ModelKind::Compact => {
            compact_model = compact::CompactModel::new(&compact, &base, problem, out)?;
            &compact_model
        }
    };
    let ev = Evaluator::new(fwd);
    let pb = ev.problem();
    log(&format!(
        "calibrating {} parameters against {nvals} values of {} experiments, model = \"{}\" ({} rayon threads)",
        pb.params.len(),
        pb.experiments.len(),
        model.name(),
        rayon::current_num_threads()
    ));
    if model == ModelKind::Compact {
        log(&format!(
            "each generation is one study in {} (engine {}): the sets of a generation × {} experiments",
            out.join("compact-fit").display(),
            compact.engine.as_deref().unwrap_or("local"),
            pb.experiments.len()
        ));
    }
    let u0: Vec<f64> = pb.params.iter().map(|p| p.unit_of(p.get(&pb.material, &pb.factors)).clamp(0.0, 1.0)).collect();
    let opt = optimise::optimise(&ev, &u0, &settings, log)?;
    let values = pb.values(&opt.u);
    let preds = ev.predict(std::slice::from_ref(&opt.u), "optimum")?.remove(0);
    let res = loss::residuals(&pb.experiments, &preds);
    let r: Vec<f64> = res.iter().map(|x| x.residual).collect();
    let chi2 = loss::chi2(&r);
    check_optimum(&preds, chi2, &r)?;
    let n = pb.params.len();
    let dof = nvals as i64 - n as i64;
    let reduced = if dof > 0 { chi2 / dof as f64 } else { f64::NAN };
    let ju = optimise::jacobian(&ev, &opt.u, settings.fd_step, None, "covariance")?;
    let spans: Vec<f64> = pb
        .params
        .iter()
        .map(|p| {
            let (a, b) = p.theta_bounds();
            b - a
        })
        .collect();
    let jt: Vec<Vec<f64>> = ju.iter().map(|row| row.iter().zip(&spans).map(|(x, s)| x / s).collect()).collect();
    let scale = if reduced > 1.0 { reduced } else { 1.0 };
    let unc = report::uncertainty(&jt, n, scale, &r)?;
    let mut warnings = Vec::new();
    if dof <= 0 {
        warnings.push(format!("{nvals} measured values for {n} parameters: no degrees of freedom, sigma is not meaningful"));
    }
    let (parameters, correlation) = report::parameter_reports(pb, &values, &opt.u, &unc, &mut warnings);
    let failed: Vec<&str> = preds.iter().zip(&pb.experiments).filter(|(p, _)| p.is_err()).map(|(_, e)| e.id.as_str()).collect();
    if !failed.is_empty() {
        warnings.push(format!("the runs of {} fail at the optimum (penalty residuals): see experiments[].error", failed.join(", ")));
    }
    let experiments_report = report::experiment_reports(&pb.experiments, &preds, &res);
    let evaluations = ev.evaluations();
    let batches = ev.batches();
    let runs: usize = batches.iter().map(|b| b.runs).sum();
    let runs_executed: usize = batches.iter().map(|b| b.executed).sum();
    let rep = report::CalibrationReport {
        title: title.clone(),
        data: data_path.display().to_string(),
        series: series_path.as_ref().map(|p| p.display().to_string()),
        model: model.name().into(),
        material: pb.material.name.clone(),
        seed: settings.seed,
        parameter_order: pb.params.iter().map(|p| p.key.clone()).collect(),
        parameters,
        correlation,
        chi2,
        reduced_chi2: reduced,
        dof,
        values: nvals,
        sigma_scaled: reduced > 1.0,
        chi2_after_global: opt.chi2_global,
        swarm_iterations: opt.swarm_iterations,
        local_method: settings.local.name().into(),
        local_iterations: opt.local_iterations,
        local_stop: opt.local_stop.clone(),
        local_chi2_history: opt.local_history.clone(),
        evaluations,
        pair_runs: if model == ModelKind::Pair { runs as u64 } else { 0 },
        runs: runs as u64,
        runs_executed: runs_executed as u64,
        failed_runs: ev.failures(),
        batches,
        wall_seconds: start.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
        experiments: experiments_report,
        warnings,
    };
    let (m_out, f_fit) = write_outputs(out, &rep, pb, &res, &values, &data_path)?;
    log(&format!(
        "chi2 = {chi2:.6}, dof = {dof}, chi2/dof = {reduced:.4}; {evaluations} evaluations in {} batches ({} {} runs, {} run now) in {:.2} s; results in {}",
        rep.batches.len(),
        rep.runs,
        model.name(),
        rep.runs_executed,
        rep.wall_seconds,
        out.display()
    ));
    for w in &rep.warnings {
        log(&format!("warning: {w}"));
    }
    if validate_compact {
        let path = compact::validate(&compact, &base, &m_out, &f_fit, &pb.factors, &pb.experiments, &preds, out, log)?;
        log(&format!("compact validation: {}", path.display()));
    }
    Ok(rep)
}

/// The files of a finished calibration in `out`: `calibration.json`, the fitted material,
/// `residuals.csv` and the plots; returns the fitted material (as written) and path factors.
fn write_outputs(
    out: &Path,
    rep: &report::CalibrationReport,
    pb: &Problem,
    res: &[loss::Residual],
    values: &[f64],
    data_path: &Path,
) -> Result<(crate::models::diffusion7::Material, crate::models::diffusion7::PathFactors), Error> {
    let (m_fit, f_fit) = pb.configured(values);
    let json_path = out.join("calibration.json");
    let text = serde_json::to_string_pretty(rep).map_err(|e| IoError::new(&json_path, e))?;
    crate::io::write_atomic(&json_path, &(text + "\n"))?;
    let m_out = write_fitted_material(out, rep, pb, &m_fit, &f_fit, values, data_path)?;
    report::write_residuals(&out.join("residuals.csv"), &pb.experiments, res)?;
    let header = (
        rep.title.clone(),
        format!(
            "calibration of {}: {} model, {} experiments, {} fitted parameters, chi2 per degree of freedom {:.3}",
            rep.material,
            rep.model,
            pb.experiments.len(),
            rep.parameter_order.len(),
            rep.reduced_chi2
        ),
    );
    if let Err(e) = report::write_plots(out, &pb.experiments, res, &header) {
        crate::plot::warn_not_written(&e);
    }
    Ok((m_out, f_fit))
}

/// A fit in which every run fails has no result (an error, not a report of penalties), and a
/// non-finite χ² at the optimum is a SolveError carrying the residuals (issue 26 class 6).
fn check_optimum<T, E: std::fmt::Display>(preds: &[Result<T, E>], chi2: f64, r: &[f64]) -> Result<(), Error> {
    if let Some(Err(first)) = preds.first().filter(|_| preds.iter().all(|p| p.is_err())) {
        return Err(crate::error::ModelError::new(format!(
            "every run of the calibration fails at the optimum ({} experiments); the first: {first}",
            preds.len()
        ))
        .into());
    }
    if !chi2.is_finite() {
        return Err(crate::error::SolveError {
            stage: "calibration".into(),
            message: format!("chi2 at the optimum is {chi2}: not finite"),
            residuals: r.to_vec(),
        }
        .into());
    }
    Ok(())
}

/// Writes `out/material.toml`: the fitted material (and path factors when the fit moved any) with
/// a header of χ², the values and their σ; returns the material as written.
fn write_fitted_material(
    out: &Path,
    rep: &report::CalibrationReport,
    pb: &Problem,
    m_fit: &crate::models::diffusion7::Material,
    f_fit: &crate::models::diffusion7::PathFactors,
    values: &[f64],
    data_path: &Path,
) -> Result<crate::models::diffusion7::Material, Error> {
    let (title, chi2, dof, reduced) = (&rep.title, rep.chi2, rep.dof, rep.reduced_chi2);
    let mut m_out = m_fit.clone();
    m_out.source =
        format!("calibrated by sinterdem calibrate ({title}; data {}; chi2/dof = {reduced:.4}), starting from: {}", data_path.display(), pb.material.source);
    let fitted_model = pb.params.iter().any(|p| matches!(p.target, params::Target::Model { .. }));
    let mut header = format!("Calibrated material written by `sinterdem calibrate` ({title}).\nchi2 = {chi2:.6}, dof = {dof}, chi2/dof = {reduced:.4}\n");
    for (p, v) in pb.params.iter().zip(values) {
        let s = rep.parameters.get(&p.key).and_then(|x| x.get("sigma")).and_then(|x| x.as_f64()).unwrap_or(f64::NAN);
        header.push_str(&format!("{} = {v:e} +- {s:.3e} {}\n", p.key, p.unit));
    }
    header.push_str("Use: paste into a pair case (material = the name below), or include the file where a case accepts a material file.");
    report::write_material(&out.join("material.toml"), &m_out, fitted_model.then_some(f_fit), &header)?;
    Ok(m_out)
}

/// `sinterdem check FILE`: a calibration file (recognised by [`crate::config::is_calibration`])
/// with `overrides` applied, or else a case of any kind ([`crate::kinds::check`]).
pub fn check_file(value: &toml::Value, overrides: &[String], base: &Path) -> Result<String, Error> {
    if !crate::config::is_calibration(value) {
        return crate::kinds::check(value, overrides, base);
    }
    let mut value = value.clone();
    for o in overrides {
        crate::config::apply_override(&mut value, o)?;
    }
    check(&value, base)
}

/// Validates a calibration file without fitting (`sinterdem check CALIB.toml`): the file, its data
/// files (file, line, column in errors), the parameters against the material, the optimiser, and
/// the `[compact]` section when it names a case: the derived compact case with the first chosen
/// experiment's schedule is checked like any case (scene built, nothing run). Returns a one-line
/// description.
pub fn check(value: &toml::Value, base: &Path) -> Result<String, Error> {
    let setup = parse(value, base)?;
    let mut packing = String::new();
    if let Some(rel) = &setup.compact.case {
        let sec = &setup.compact;
        let case_path = base.join(rel);
        sec.engine_settings()?;
        let chosen = sec.chosen(&setup.experiments)?;
        let (mut case, _) = match setup.model {
            ModelKind::Compact => compact::fit_case(sec, base, &setup.material, &setup.factors)?,
            ModelKind::Pair => compact::derived_case(&case_path, &setup.material, &setup.factors, &setup.factors, &sec.overrides)?,
        };
        let e = &setup.experiments[chosen[0]];
        let at = |err: ConfigError| ConfigError::invalid(format!("[compact] case = {} with experiment {}'s schedule: {err}", case_path.display(), e.id));
        crate::config::apply_override(&mut case, &format!("thermal.furnace.profile.schedule={}", toml::Value::String(e.schedule.clone()))).map_err(at)?;
        crate::config::apply_override(&mut case, &format!("time.end={:?}", e.profile.duration())).map_err(at)?;
        let what = crate::kinds::check(&case, &[], case_path.parent().unwrap_or(Path::new("."))).map_err(|err| match err {
            Error::Config(c) => Error::Config(at(c)),
            other => other,
        })?;
        packing = format!("; [compact] {} ({what}), {} experiment(s)", case_path.display(), chosen.len());
    }
    Ok(format!(
        "calibration file, model = \"{}\", {} parameter{} ({}), {} experiment{} with {} measured values, local = \"{}\"{packing}",
        setup.model.name(),
        setup.params.len(),
        if setup.params.len() == 1 { "" } else { "s" },
        setup.params.iter().map(|p| p.key.as_str()).collect::<Vec<_>>().join(", "),
        setup.experiments.len(),
        if setup.experiments.len() == 1 { "" } else { "s" },
        setup.experiments.iter().map(|e| e.count()).sum::<usize>(),
        setup.settings.local.name()
    ))
}

/// `sinterdem calibrate CALIB.toml --out DIR [--set k=v]`: parse, fit, write. With `generate_synthetic`
/// it instead (re)writes the calibration's data file with the bundled synthetic titanium data
/// ([`synthetic::write_titanium_synthetic`]).
pub fn run_file(path: &Path, overrides: &[String], out: &Path, quiet: bool, generate_synthetic: bool, validate_compact: bool) -> Result<(), Error> {
    run_file_forced(path, overrides, out, quiet, generate_synthetic, validate_compact, false)
}

/// [`run_file`] with `--force`: the outputs of an earlier command in `out` are removed first.
pub fn run_file_forced(
    path: &Path,
    overrides: &[String],
    out: &Path,
    quiet: bool,
    generate_synthetic: bool,
    validate_compact: bool,
    force: bool,
) -> Result<(), Error> {
    let value = crate::config::load_case(path, overrides)?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    if generate_synthetic {
        let data = value.get("data").and_then(|d| d.as_str()).ok_or_else(|| ConfigError::invalid("data: needed to know where to write the synthetic data"))?;
        let target = base.join(data);
        synthetic::write_titanium_synthetic(&target)?;
        tracing::info!("synthetic titanium data written to {}", target.display());
        return Ok(());
    }
    let mut setup = parse(&value, &base)?;
    if validate_compact {
        if setup.model == ModelKind::Compact {
            return Err(ConfigError::inconsistent(
                "model",
                "\"compact\" already fits on the packing (its values are in calibration.json); --validate-compact is for a pair fit",
            )
            .into());
        }
        // fail before the fit, not after it
        let case_path = setup.compact.case_path(&base, "--validate-compact")?;
        setup.compact.chosen(&setup.experiments)?;
        compact::derived_case(&case_path, &setup.material, &setup.factors, &setup.factors, &setup.compact.overrides)?;
    }
    setup.validate_compact = validate_compact;
    setup.force = force;
    let mut log = |m: &str| {
        if !quiet {
            tracing::info!("{m}");
        }
    };
    run(setup, out, &mut log)?;
    Ok(())
}

#[cfg(test)]
mod table_tests {
    #[test]
    fn every_key_is_unique_and_found() {
        let all: Vec<&crate::config::ranges::Range> = super::every_table().iter().flat_map(|t| t.iter()).collect();
        for (i, a) in all.iter().enumerate() {
            assert!(all[i + 1..].iter().all(|b| b.key != a.key), "{} twice", a.key);
            assert_eq!(super::lookup(&a.key.replace('*', "x")).map(|r| r.key), Some(a.key));
        }
    }
}

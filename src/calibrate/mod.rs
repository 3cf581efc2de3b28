//! Calibration of diffusion data and path factors against measured neck growth and shrinkage
//! (`sinterdem calibrate CALIB.toml --out DIR`; user guide `docs/calibration.md`).
//!
//! - [`data`]: the measured-data CSV files (file/line/column errors);
//! - [`params`]: the fitted parameters `PHASE.FIELD` / `model.FIELD`, bounds, log space;
//! - [`forward`]: the forward model, one 7-DOF pair run per experiment, parallel over experiments;
//! - [`loss`]: χ² of the normalised residuals, failed runs as a penalty;
//! - [`optimise`]: argmin's particle swarm, then a Gauss–Newton trust region;
//! - [`report`]: σ and correlations from (JᵀWJ)⁻¹, `calibration.json`, `material.toml`,
//!   `residuals.csv`, PNGs;
//! - [`synthetic`]: the bundled synthetic titanium data set (perturbed β phase, seeded noise).
//!
//! Only `model = "pair"` is implemented; `"compact"` (each experiment on a packing) is refused.

pub mod compact;
pub mod data;
pub mod forward;
pub mod loss;
pub mod optimise;
pub mod params;
pub mod report;
pub mod synthetic;

use crate::config::ranges::{Range, c, o, p};
use crate::config::{check, from_value};
use crate::error::{ConfigError, Error, IoError};
use crate::models::diffusion7::{Material, PathFactors, SolverOptions};
use data::Experiment;
use forward::{Forward, PairGeometry};
use params::{Parameter, ParameterEntry};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Numeric keys of calibration files and of their data files (registered in `config::ranges::TABLES`).
pub static RANGES: &[Range] = &[
    c("optimiser.swarm_size", 1.0, 1e4, "1", "calibration: particles of the swarm (global phase)"),
    c("optimiser.swarm_iterations", 0.0, 1e5, "1", "calibration: swarm iterations (0: local phase only, from the starting material)"),
    c("optimiser.local_iterations", 0.0, 1e5, "1", "calibration: largest number of trust-region (Gauss-Newton) iterations"),
    o("optimiser.tolerance", 0.0, 1.0, "1", "calibration: relative decrease of chi2 below which a local iteration counts as stalled"),
    c("optimiser.stall", 1.0, 1e3, "1", "calibration: stalled local iterations in a row that end the fit"),
    p("optimiser.fd_step", 0.0, 0.1, "1", "calibration: finite-difference step of the Jacobian in unit coordinates of the parameter ranges"),
    p("data.diameter_m", 0.0, 2e-2, "m", "calibration data: mean particle diameter of an experiment"),
    c("data.neck_ratio", 0.0, 1.0, "1", "calibration data: measured neck ratio y1/R"),
    p("data.neck_ratio_sigma", 0.0, 1.0, "1", "calibration data: one standard deviation of the neck ratio"),
    c("data.shrinkage", -1.0, 1.0, "1", "calibration data: measured shrinkage dL/L0"),
    p("data.shrinkage_sigma", 0.0, 1.0, "1", "calibration data: one standard deviation of the shrinkage"),
    c("data.time_s", 0.0, 1e9, "s", "calibration series: time since the start of the schedule"),
];

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
    #[serde(default)]
    path_factors: PathFactors,
    #[serde(default)]
    pair: PairSection,
    /// The packing for `--validate-compact`.
    #[serde(default)]
    compact: compact::CompactSection,
}

/// A validated calibration.
#[derive(Debug)]
pub struct Setup {
    pub title: String,
    pub data_path: PathBuf,
    pub series_path: Option<PathBuf>,
    pub experiments: Vec<Experiment>,
    pub material: Material,
    pub factors: PathFactors,
    pub params: Vec<Parameter>,
    pub settings: optimise::Settings,
    pub solver: SolverOptions,
    pub geometry: PairGeometry,
    /// `[compact]`: the packing of `--validate-compact`.
    pub compact: compact::CompactSection,
    /// The calibration file's folder (relative paths).
    pub base: PathBuf,
    /// Run the chosen experiments on the compact with the fitted material after the fit.
    pub validate_compact: bool,
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
    match f.model.as_str() {
        "pair" => {}
        "compact" => {
            return Err(ConfigError::inconsistent(
                "model",
                "\"compact\" (each experiment run on a packing) is not yet supported; use model = \"pair\" and check the pair-calibrated material on a compact case",
            )
            .into());
        }
        m => return Err(ConfigError::invalid(format!("model = \"{m}\": expected \"pair\" (or, later, \"compact\")")).into()),
    }
    let mut defined = materials_of(f.materials, "")?;
    if let Some(inc) = &f.include {
        let path = base.join(inc);
        let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
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
    }
    let material = match defined.iter().find(|m| m.name == f.material) {
        Some(m) => m.clone(),
        None => Material::builtin(&f.material).map_err(|e| match e {
            ConfigError::Invalid(m) => ConfigError::Invalid(format!("material: {m}")),
            o => o,
        })?,
    };
    f.path_factors.validate().map_err(|e| match e {
        ConfigError::OutOfRange { key, value, range, unit } => ConfigError::OutOfRange { key: key.replace("model.", "path_factors."), value, range, unit },
        o => o,
    })?;
    f.solver.validate()?;
    let mut entries = Vec::new();
    for (i, v) in f.parameters.into_iter().enumerate() {
        entries.push(from_value::<ParameterEntry>(v, &format!("parameters[{i}]"))?);
    }
    let params = params::parse_parameters(&entries, &material)?;
    let o = &f.optimiser;
    let d = optimise::Settings::default();
    let get = |k: &str, v: Option<f64>, dflt: f64| -> Result<f64, ConfigError> { check(&format!("optimiser.{k}"), v.unwrap_or(dflt)) };
    let settings = optimise::Settings {
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
        overlap: check("pair.overlap", f.pair.overlap.unwrap_or(g.overlap))?,
        neck_epsilon: check("pair.neck_epsilon", f.pair.neck_epsilon.unwrap_or(g.neck_epsilon))?,
        cone_eta: check("pair.cone_eta", f.pair.cone_eta.unwrap_or(g.cone_eta))?,
    };
    let data_path = base.join(&f.data);
    let mut experiments = data::read_experiments(&data_path)?;
    let series_path = f.series.as_ref().map(|s| base.join(s));
    if let Some(sp) = &series_path {
        data::read_series(sp, &mut experiments)?;
    }
    data::check_counts(&experiments, &data_path.display().to_string())?;
    Ok(Setup {
        title: f.title.or(f.description).unwrap_or_else(|| "calibration".into()),
        data_path,
        series_path,
        experiments,
        material,
        factors: f.path_factors,
        params,
        settings,
        solver: f.solver,
        geometry,
        compact: f.compact,
        base: base.to_path_buf(),
        validate_compact: false,
    })
}

/// Runs a validated calibration and writes its results into `out`. `log` receives progress lines.
pub fn run(setup: Setup, out: &Path, log: &mut dyn FnMut(&str)) -> Result<report::CalibrationReport, Error> {
    let start = std::time::Instant::now();
    std::fs::create_dir_all(out).map_err(|e| IoError::new(out, e))?;
    let Setup { title, data_path, series_path, experiments, material, factors, params, settings, solver, geometry, compact, base, validate_compact } = setup;
    let nvals: usize = experiments.iter().map(|e| e.count()).sum();
    log(&format!(
        "calibrating {} parameters against {nvals} values of {} experiments ({} rayon threads)",
        params.len(),
        experiments.len(),
        rayon::current_num_threads()
    ));
    let fwd = Forward::new(experiments, material, factors, params, solver, geometry);
    let u0: Vec<f64> = fwd.params.iter().map(|p| p.unit_of(p.get(&fwd.material, &fwd.factors)).clamp(0.0, 1.0)).collect();
    let opt = optimise::optimise(&fwd, &u0, &settings, log)?;
    let values = fwd.values(&opt.u);
    let preds = fwd.predict(&values);
    let res = loss::residuals(&fwd.experiments, &preds);
    let r: Vec<f64> = res.iter().map(|x| x.residual).collect();
    let chi2 = loss::chi2(&r);
    let n = fwd.params.len();
    let dof = nvals as i64 - n as i64;
    let reduced = if dof > 0 { chi2 / dof as f64 } else { f64::NAN };
    let ju = optimise::jacobian(&fwd, &opt.u, settings.fd_step, None);
    let spans: Vec<f64> = fwd
        .params
        .iter()
        .map(|p| {
            let (a, b) = p.theta_bounds();
            b - a
        })
        .collect();
    let jt: Vec<Vec<f64>> = ju.iter().map(|row| row.iter().zip(&spans).map(|(x, s)| x / s).collect()).collect();
    let scale = if reduced > 1.0 { reduced } else { 1.0 };
    let unc = report::uncertainty(&jt, n, scale);
    let mut warnings = Vec::new();
    if dof <= 0 {
        warnings.push(format!("{nvals} measured values for {n} parameters: no degrees of freedom, sigma is not meaningful"));
    }
    let (parameters, correlation) = report::parameter_reports(&fwd, &values, &opt.u, &unc, &mut warnings);
    let failed: Vec<&str> = preds.iter().zip(&fwd.experiments).filter(|(p, _)| p.is_err()).map(|(_, e)| e.id.as_str()).collect();
    if !failed.is_empty() {
        warnings.push(format!("the runs of {} fail at the optimum (penalty residuals): see experiments[].error", failed.join(", ")));
    }
    let (m_fit, f_fit) = fwd.configured(&values);
    let experiments_report = report::experiment_reports(&fwd.experiments, &preds, &res);
    let evaluations = fwd.evaluations();
    let rep = report::CalibrationReport {
        title: title.clone(),
        data: data_path.display().to_string(),
        series: series_path.as_ref().map(|p| p.display().to_string()),
        model: "pair".into(),
        material: fwd.material.name.clone(),
        seed: settings.seed,
        parameter_order: fwd.params.iter().map(|p| p.key.clone()).collect(),
        parameters,
        correlation,
        chi2,
        reduced_chi2: reduced,
        dof,
        values: nvals,
        sigma_scaled: reduced > 1.0,
        chi2_after_global: opt.chi2_global,
        swarm_iterations: opt.swarm_iterations,
        local_iterations: opt.local_iterations,
        local_stop: opt.local_stop.clone(),
        local_chi2_history: opt.local_history.clone(),
        evaluations,
        pair_runs: evaluations * fwd.experiments.len() as u64,
        failed_runs: fwd.failures(),
        wall_seconds: start.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
        experiments: experiments_report,
        warnings,
    };
    let json_path = out.join("calibration.json");
    let text = serde_json::to_string_pretty(&rep).map_err(|e| IoError::new(&json_path, e))?;
    std::fs::write(&json_path, text + "\n").map_err(|e| IoError::new(&json_path, e))?;
    let mut m_out = m_fit.clone();
    m_out.source =
        format!("calibrated by sinterdem calibrate ({title}; data {}; chi2/dof = {reduced:.4}), starting from: {}", data_path.display(), fwd.material.source);
    let fitted_model = fwd.params.iter().any(|p| matches!(p.target, params::Target::Model { .. }));
    let mut header = format!("Calibrated material written by `sinterdem calibrate` ({title}).\nchi2 = {chi2:.6}, dof = {dof}, chi2/dof = {reduced:.4}\n");
    for (p, v) in fwd.params.iter().zip(&values) {
        let s = rep.parameters.get(&p.key).and_then(|x| x.get("sigma")).and_then(|x| x.as_f64()).unwrap_or(f64::NAN);
        header.push_str(&format!("{} = {v:e} +- {s:.3e} {}\n", p.key, p.unit));
    }
    header.push_str("Use: paste into a pair case (material = the name below), or include the file where a case accepts a material file.");
    report::write_material(&out.join("material.toml"), &m_out, fitted_model.then_some(&f_fit), &header)?;
    report::write_residuals(&out.join("residuals.csv"), &fwd.experiments, &res)?;
    report::write_plots(out, &fwd.experiments, &res)?;
    log(&format!(
        "chi2 = {chi2:.6}, dof = {dof}, chi2/dof = {reduced:.4}; {evaluations} evaluations ({} pair runs) in {:.2} s; results in {}",
        rep.pair_runs,
        rep.wall_seconds,
        out.display()
    ));
    for w in &rep.warnings {
        log(&format!("warning: {w}"));
    }
    if validate_compact {
        let path = compact::validate(&compact, &base, &m_out, &fwd.experiments, &preds, out, log)?;
        log(&format!("compact validation: {}", path.display()));
    }
    Ok(rep)
}

/// `sinterdem calibrate CALIB.toml --out DIR [--set k=v]`: parse, fit, write. With `generate_synthetic`
/// it instead (re)writes the calibration's data file with the bundled synthetic titanium data
/// ([`synthetic::write_titanium_synthetic`]).
pub fn run_file(path: &Path, overrides: &[String], out: &Path, quiet: bool, generate_synthetic: bool, validate_compact: bool) -> Result<(), Error> {
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
    setup.validate_compact = validate_compact;
    let mut log = |m: &str| {
        if !quiet {
            tracing::info!("{m}");
        }
    };
    run(setup, out, &mut log)?;
    Ok(())
}

//! Results of a calibration in the output directory:
//! - `calibration.json`: parameters `{KEY: {value, sigma, …}}`, correlation matrix, χ², reduced χ²,
//!   degrees of freedom, per-experiment residuals, evaluations, wall time, warnings;
//! - `material.toml`: the calibrated material as `[[materials]]`/`[[materials.phases]]` (plus `[model]`
//!   when path factors were fitted), the syntax of pair cases;
//! - `residuals.csv`: one row per measured value;
//! - `neck_ratio.png`, `shrinkage.png` (measured ± σ vs fitted per experiment), `residuals.png`, and
//!   `series_<id>.png` for experiments with time series.
//!
//! Uncertainty: with J = ∂r/∂θ at the optimum (r already divided by σ, so JᵀJ = JᵀWJ), the
//! covariance of the fit coordinates θ (log10 of log parameters) is `C = (JᵀJ)⁻¹ · max(1, χ²/ν)`,
//! ν = values − parameters; σ_θ = √C_ii, r_ij = C_ij/(σ_i σ_j). A log parameter's `sigma` is the
//! linearised `value·ln10·σ_θ`, its `sigma_log10` is σ_θ.

use super::data::Experiment;
use super::forward::Prediction;
use super::loss::{Quantity, Residual};
use super::model::{BatchInfo, Problem};
use crate::error::{Error, IoError, ModelError, SolveError};
use crate::models::diffusion7::{Material, PathFactors};
use crate::plot::{Plot, Series};
use nalgebra::DMatrix;
use serde::Serialize;
use std::path::Path;

/// |r| above which two parameters are reported as correlated.
pub const CORRELATION_WARNING: f64 = 0.95;
/// A parameter within this fraction of its (θ) range from a bound is "at the bound".
pub const BOUND_WARNING: f64 = 1e-3;

/// Covariance of the fit coordinates θ.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// σ_θ per parameter (NaN if not determined).
    pub sigma_theta: Vec<f64>,
    /// Correlation matrix (NaN where undetermined).
    pub correlation: Vec<Vec<f64>>,
    /// Whether JᵀJ was singular (to round-off).
    pub singular: bool,
}

/// Covariance from the Jacobian `j` (m × n rows) of the normalised residuals in θ and a scale.
/// The columns are first scaled to unit norm (D = diag(1/|J_i|)), so that a direction counts as
/// undetermined by its relative singular value (< 1e-12 of the largest) and not by the units of θ:
/// `C = D ((JD)ᵀ(JD))⁺ D · scale`.
///
/// A non-finite entry of `j` or a non-finite `scale` is a [`SolveError`] (stage "covariance") that
/// carries the residuals `r`: the SVD is never asked to decompose NaN or inf (issue 26, class 6).
pub fn uncertainty(j: &[Vec<f64>], n: usize, scale: f64, r: &[f64]) -> Result<Uncertainty, SolveError> {
    if let Some((row, col)) = j.iter().enumerate().find_map(|(a, row)| row.iter().position(|x| !x.is_finite()).map(|b| (a, b))) {
        return Err(SolveError {
            stage: "covariance".into(),
            message: format!(
                "the Jacobian of the residuals is not finite (row {row}, parameter {col}: {}); the uncertainty cannot be computed (a data sigma too small, or a run that fails near the optimum)",
                j[row][col]
            ),
            residuals: r.to_vec(),
        });
    }
    if !scale.is_finite() {
        return Err(SolveError { stage: "covariance".into(), message: format!("chi2 / dof = {scale:e} is not finite"), residuals: r.to_vec() });
    }
    let m = j.len();
    let norms: Vec<f64> = (0..n).map(|b| j.iter().map(|r| r[b] * r[b]).sum::<f64>().sqrt()).collect();
    let d: Vec<f64> = norms.iter().map(|x| if *x > 0.0 && x.is_finite() { 1.0 / x } else { 0.0 }).collect();
    let jm = DMatrix::from_fn(m, n, |a, b| j[a][b] * d[b]);
    let jtj = jm.transpose() * &jm;
    let svd = jtj.svd(true, true);
    let smax = svd.singular_values.max();
    let tol = smax * 1e-12;
    let mut undetermined = vec![false; n];
    for (k, s) in svd.singular_values.iter().enumerate() {
        if (*s <= tol || !s.is_finite())
            && let Some(vt) = svd.v_t.as_ref()
        {
            for (i, u) in undetermined.iter_mut().enumerate() {
                if vt[(k, i)].abs() > 1e-6 {
                    *u = true;
                }
            }
        }
    }
    for (i, x) in d.iter().enumerate() {
        if *x == 0.0 {
            undetermined[i] = true;
        }
    }
    let singular = undetermined.iter().any(|u| *u) || !(smax > 0.0);
    let pinv = svd.pseudo_inverse(tol).unwrap_or_else(|_| DMatrix::from_element(n, n, f64::NAN));
    let cov = DMatrix::from_fn(n, n, |a, b| pinv[(a, b)] * d[a] * d[b] * scale);
    let sigma: Vec<f64> = (0..n).map(|i| if undetermined[i] { f64::NAN } else { cov[(i, i)].max(0.0).sqrt() }).collect();
    let correlation = (0..n).map(|a| (0..n).map(|b| cov[(a, b)] / (sigma[a] * sigma[b])).collect()).collect();
    Ok(Uncertainty { sigma_theta: sigma, correlation, singular })
}

/// One fitted parameter in `calibration.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ParamReport {
    /// Fitted value [unit].
    pub value: f64,
    /// Standard error [unit] (linearised for log parameters; null if undetermined).
    pub sigma: f64,
    pub unit: String,
    pub log: bool,
    /// σ of log10(value) (log parameters only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_log10: Option<f64>,
    pub min: f64,
    pub max: f64,
    /// Value in the starting material [unit].
    pub start: f64,
}

/// One measured value in `calibration.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ValueReport {
    pub measured: f64,
    pub sigma: f64,
    pub fitted: f64,
    /// (fitted − measured)/σ.
    pub residual: f64,
}

/// One experiment in `calibration.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentReport {
    pub id: String,
    pub diameter_m: f64,
    pub schedule: String,
    /// End-of-schedule values.
    pub neck_ratio: Option<ValueReport>,
    pub shrinkage: Option<ValueReport>,
    /// Σ r² of the experiment's series points.
    pub series_chi2: f64,
    pub series_points: usize,
    /// The run's error at the optimum, if it failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// `calibration.json`.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    pub title: String,
    pub data: String,
    pub series: Option<String>,
    pub model: String,
    pub material: String,
    pub seed: u64,
    /// Keys in the order of the correlation matrix.
    pub parameter_order: Vec<String>,
    pub parameters: serde_json::Map<String, serde_json::Value>,
    pub correlation: Vec<Vec<f64>>,
    pub chi2: f64,
    pub reduced_chi2: f64,
    /// Degrees of freedom ν = values − parameters.
    pub dof: i64,
    pub values: usize,
    /// σ scaled by √(χ²/ν) (covariance by χ²/ν) because χ²/ν > 1.
    pub sigma_scaled: bool,
    pub chi2_after_global: f64,
    pub swarm_iterations: u64,
    /// `trust_region` or `nelder_mead`.
    pub local_method: String,
    pub local_iterations: u64,
    pub local_stop: String,
    /// χ² at the start of the local phase and after each of its iterations (a rejected trust-region
    /// step repeats the value).
    pub local_chi2_history: Vec<f64>,
    /// Parameter sets evaluated (each runs every experiment once; a set is run at most once).
    pub evaluations: u64,
    /// Pair runs (`model = "pair"`; 0 for a packing fit).
    pub pair_runs: u64,
    /// Runs of all batches (sets × experiments), and those computed by this invocation (a packing
    /// fit re-run into the same directory reuses the finished runs of its study store).
    pub runs: u64,
    pub runs_executed: u64,
    pub failed_runs: u64,
    /// Every batch sent to the forward model, in order: one optimiser generation each (the
    /// swarm's particles of one iteration, a Jacobian's points, …); a packing fit's batch `k` is
    /// the study `compact-fit/gen-k-LABEL/`.
    pub batches: Vec<BatchInfo>,
    pub wall_seconds: f64,
    pub threads: usize,
    pub experiments: Vec<ExperimentReport>,
    pub warnings: Vec<String>,
}

/// Parameter reports, warnings and correlation at the optimum.
pub fn parameter_reports(
    fwd: &Problem,
    values: &[f64],
    u: &[f64],
    unc: &Uncertainty,
    warnings: &mut Vec<String>,
) -> (serde_json::Map<String, serde_json::Value>, Vec<Vec<f64>>) {
    let mut map = serde_json::Map::new();
    for (i, p) in fwd.params.iter().enumerate() {
        let st = unc.sigma_theta[i];
        let sigma = if p.log { values[i] * std::f64::consts::LN_10 * st } else { st };
        let r = ParamReport {
            value: values[i],
            sigma,
            unit: p.unit.to_string(),
            log: p.log,
            sigma_log10: p.log.then_some(st),
            min: p.min,
            max: p.max,
            start: p.get(&fwd.material, &fwd.factors),
        };
        map.insert(p.key.clone(), serde_json::to_value(&r).unwrap_or(serde_json::Value::Null));
        if u[i] <= BOUND_WARNING || u[i] >= 1.0 - BOUND_WARNING {
            warnings.push(format!(
                "{} = {:e} {} sits at a bound of [{:e}, {:e}]: widen the range, or the data do not constrain it from that side (its sigma is not meaningful)",
                p.key, values[i], p.unit, p.min, p.max
            ));
        }
        if !st.is_finite() {
            warnings.push(format!("{}: not determined by the data (JᵀWJ is singular in its direction); sigma is null", p.key));
        }
    }
    let n = fwd.params.len();
    for a in 0..n {
        for b in a + 1..n {
            let r = unc.correlation[a][b];
            if r.abs() > CORRELATION_WARNING {
                warnings.push(format!(
                    "{} and {} correlate with r = {r:.4}: the data determine a combination of them better than either (D0 and Q of one mechanism do unless the experiments span a wide temperature range)",
                    fwd.params[a].key, fwd.params[b].key
                ));
            }
        }
    }
    (map, unc.correlation.clone())
}

/// Per-experiment reports.
pub fn experiment_reports(experiments: &[Experiment], preds: &[Result<Prediction, ModelError>], res: &[Residual]) -> Vec<ExperimentReport> {
    experiments
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let mine: Vec<&Residual> = res.iter().filter(|r| r.experiment == i).collect();
            let pick = |q: Quantity| {
                mine.iter().find(|r| r.end && r.quantity == q).map(|r| ValueReport {
                    measured: r.measured.value,
                    sigma: r.measured.sigma,
                    fitted: r.fitted,
                    residual: r.residual,
                })
            };
            ExperimentReport {
                id: e.id.clone(),
                diameter_m: e.diameter,
                schedule: e.schedule.clone(),
                neck_ratio: pick(Quantity::NeckRatio),
                shrinkage: pick(Quantity::Shrinkage),
                series_chi2: mine.iter().filter(|r| !r.end).fold(0.0, |a, r| a + r.residual * r.residual),
                series_points: e.series.len(),
                error: preds[i].as_ref().err().map(|e| e.to_string()),
            }
        })
        .collect()
}

/// A float as TOML: plain between 1e-3 and 1e6, else in exponent form (`1.81e-29`).
fn toml_float(x: f64) -> String {
    if x == 0.0 || (1e-3..1e6).contains(&x.abs()) { format!("{x:?}") } else { format!("{x:e}") }
}

/// The `[[materials]]` (and optional `[model]`) text of a material, fields in schema order.
pub fn material_toml(m: &Material, factors: Option<&PathFactors>) -> String {
    use super::params::{MODEL_FIELDS, PHASE_FIELDS, model_field, phase_field};
    let q = |s: &str| toml::Value::String(s.to_string()).to_string();
    let mut t = String::new();
    if let Some(f) = factors {
        t.push_str("[model]\n");
        for (i, k) in MODEL_FIELDS.iter().enumerate() {
            t.push_str(&format!("{k} = {}\n", toml_float(model_field(f, i))));
        }
        t.push('\n');
    }
    t.push_str(&format!("[[materials]]\nname = {}\nsource = {}\n", q(&m.name), q(&m.source)));
    for (k, v) in [
        ("young_modulus", m.young_modulus),
        ("poisson_ratio", m.poisson_ratio),
        ("calibrated_min_temperature", m.calibrated_min_temperature),
        ("calibrated_max_temperature", m.calibrated_max_temperature),
    ] {
        t.push_str(&format!("{k} = {}\n", toml_float(v)));
    }
    if let Some(tm) = m.melting_temperature {
        t.push_str(&format!("melting_temperature = {}\n", toml_float(tm)));
    }
    for p in &m.phases {
        t.push_str(&format!("\n[[materials.phases]]\nname = {}\nfrom_temperature = {}\n", q(&p.name), toml_float(p.from_temperature)));
        for (i, k) in PHASE_FIELDS.iter().enumerate() {
            t.push_str(&format!("{k} = {}\n", toml_float(phase_field(p, i))));
        }
    }
    t
}

/// Writes `material.toml` (`header` as comment lines).
pub fn write_material(path: &Path, m: &Material, factors: Option<&PathFactors>, header: &str) -> Result<(), Error> {
    let mut text = String::new();
    for l in header.lines() {
        text.push_str(&format!("# {l}\n"));
    }
    text.push('\n');
    text.push_str(&material_toml(m, factors));
    crate::io::manifest::record(path)?;
    std::fs::write(path, text).map_err(|e| IoError::new(path, e))?;
    Ok(())
}

/// Writes `residuals.csv`: `id,time_s,end,quantity,measured,sigma,fitted,residual`.
pub fn write_residuals(path: &Path, experiments: &[Experiment], res: &[Residual]) -> Result<(), Error> {
    // a value a failed run could not give is an empty field, never `NaN` (docs/calibration.md)
    let num = |x: f64, prec: usize| if x.is_finite() { format!("{x:.prec$e}") } else { String::new() };
    let mut text = String::from("id,time_s,end,quantity,measured,sigma,fitted,residual\n");
    for r in res {
        text.push_str(&format!(
            "{},{:.6},{},{},{},{},{},{}\n",
            crate::io::csv_text(&experiments[r.experiment].id),
            r.time,
            r.end as u8,
            r.quantity.name(),
            num(r.measured.value, 10),
            num(r.measured.sigma, 6),
            num(r.fitted, 10),
            num(r.residual, 6)
        ));
    }
    crate::io::write_atomic(path, &text)?;
    Ok(())
}

/// Writes the PNGs ([`calibration_plots`]); `header`: the title and the subtitle of the run.
pub fn write_plots(dir: &Path, experiments: &[Experiment], res: &[Residual], header: &(String, String)) -> Result<(), Error> {
    for (file, p) in calibration_plots(experiments, res, header) {
        p.save_png(&dir.join(file))?;
    }
    Ok(())
}

/// The plain name and axis label of a fitted quantity.
fn quantity_label(q: Quantity) -> &'static str {
    match q {
        Quantity::NeckRatio => "neck radius / particle radius",
        Quantity::Shrinkage => "shrinkage (approach / initial centre distance)",
    }
}

/// The plots of a calibration (file name, plot): measured (± σ) and fitted values at the end of
/// each schedule with the experiment ids as tick labels, the normalised residuals with the ±2
/// band, and each experiment's series against time (in the unit its span reads best in).
pub fn calibration_plots(experiments: &[Experiment], res: &[Residual], header: &(String, String)) -> Vec<(String, Plot)> {
    let ticks: Vec<(f64, String)> = experiments.iter().enumerate().map(|(i, e)| ((i + 1) as f64, e.id.clone())).collect();
    let mut out = Vec::new();
    for (q, file) in [(Quantity::NeckRatio, "neck_ratio.png"), (Quantity::Shrinkage, "shrinkage.png")] {
        let ends: Vec<&Residual> = res.iter().filter(|r| r.end && r.quantity == q).collect();
        if ends.is_empty() {
            continue;
        }
        let x = |r: &Residual| (r.experiment + 1) as f64;
        let short = if q == Quantity::NeckRatio { "neck size" } else { "shrinkage" };
        let mut p = Plot::new(format!("{}: {short} at the end of each schedule", header.0))
            .subtitle(header.1.clone())
            .labels("experiment", quantity_label(q))
            .x_ticks(ticks.clone())
            .y_zero(q == Quantity::Shrinkage);
        p.add(
            Series::new("measured (± σ)", ends.iter().map(|r| (x(r), r.measured.value)).collect())
                .points_only()
                .with_error_bars(ends.iter().map(|r| r.measured.sigma).collect()),
        );
        p.add(Series::new("fitted", ends.iter().map(|r| (x(r), r.fitted)).collect()).points_only());
        out.push((file.to_string(), p));
    }
    let mut p = Plot::new(format!("{}: residuals (fitted − measured) / σ", header.0))
        .subtitle(header.1.clone())
        .labels("experiment", "residual in units of σ")
        .x_ticks(ticks.clone())
        .y_zero(true);
    for q in [Quantity::NeckRatio, Quantity::Shrinkage] {
        let pts: Vec<(f64, f64)> = res.iter().filter(|r| r.quantity == q).map(|r| ((r.experiment + 1) as f64, r.residual)).collect();
        if !pts.is_empty() {
            p.add(Series::new(quantity_label(q), pts).points_only());
        }
    }
    let n = experiments.len() as f64 + 0.5;
    p.add(Series::new("±2 σ", vec![(0.5, 2.0), (n, 2.0), (f64::NAN, f64::NAN), (0.5, -2.0), (n, -2.0)]).reference());
    out.push(("residuals.png".to_string(), p));
    for (i, e) in experiments.iter().enumerate() {
        if e.series.is_empty() {
            continue;
        }
        let mine_all: Vec<&Residual> = res.iter().filter(|r| r.experiment == i).collect();
        let tu = crate::plot::time_unit(mine_all.iter().map(|r| r.time).fold(0.0, f64::max), false);
        let mut p = Plot::new(format!("{}: experiment {}, measured and fitted", header.0, e.id))
            .subtitle(header.1.clone())
            .labels(format!("time [{}]", tu.name), "ratio")
            .y_zero(true);
        for q in [Quantity::NeckRatio, Quantity::Shrinkage] {
            let mine: Vec<&Residual> = mine_all.iter().copied().filter(|r| r.quantity == q).collect();
            if mine.is_empty() {
                continue;
            }
            p.add(
                Series::new(format!("{}, measured (± σ)", quantity_label(q)), mine.iter().map(|r| (tu.of(r.time), r.measured.value)).collect())
                    .points_only()
                    .with_error_bars(mine.iter().map(|r| r.measured.sigma).collect()),
            );
            p.add(Series::new(format!("{}, fitted", quantity_label(q)), mine.iter().map(|r| (tu.of(r.time), r.fitted)).collect()).with_markers());
        }
        let safe: String = e.id.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
        out.push((format!("series_{safe}.png"), p));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn covariance_of_a_linear_model_and_correlation_flag() {
        // r = J θ with J rows (1, 0), (0, 2), (1, 1): JᵀJ = [[2, 1], [1, 5]], inverse = [[5, -1], [-1, 2]]/9
        let j = vec![vec![1.0, 0.0], vec![0.0, 2.0], vec![1.0, 1.0]];
        let u = uncertainty(&j, 2, 1.0, &[]).unwrap();
        assert!((u.sigma_theta[0] - (5.0f64 / 9.0).sqrt()).abs() < 1e-12);
        assert!((u.sigma_theta[1] - (2.0f64 / 9.0).sqrt()).abs() < 1e-12);
        assert!((u.correlation[0][1] + 1.0 / 10f64.sqrt()).abs() < 1e-12);
        assert!(!u.singular);
        let s = uncertainty(&[vec![1.0, 1.0], vec![2.0, 2.0]], 2, 1.0, &[]).unwrap();
        assert!(s.singular && s.sigma_theta[0].is_nan());
    }

    #[test]
    fn a_non_finite_jacobian_is_a_solve_error_with_the_residuals_not_a_panic() {
        // issue 26, class 6: a sigma of 5e-324 made J infinite and nalgebra's SVD panicked
        // ("Singular value was NaN")
        let r = [1.0, f64::INFINITY, 2.0];
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let j = vec![vec![1.0, 0.0], vec![0.0, bad], vec![1.0, 1.0]];
            let e = uncertainty(&j, 2, 1.0, &r).unwrap_err();
            assert_eq!(e.stage, "covariance");
            assert!(e.message.contains("row 1, parameter 1"), "{}", e.message);
            assert_eq!(e.residuals.len(), 3);
        }
        let e = uncertainty(&[vec![1.0, 0.0], vec![0.0, 1.0]], 2, f64::INFINITY, &r).unwrap_err();
        assert!(e.message.contains("not finite"), "{}", e.message);
    }

    #[test]
    fn residuals_csv_writes_an_empty_field_for_a_value_a_failed_run_did_not_give() {
        let dir = std::env::temp_dir().join(format!("sinterdem-residuals-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let e = Experiment {
            id: "E1B".into(),
            diameter: 1e-4,
            schedule: String::new(),
            profile: crate::profile::Profile::constant(1000.0).unwrap(),
            end: super::super::data::Observation::default(),
            series: Vec::new(),
        };
        let measured = super::super::data::Measured { value: 0.5, sigma: 0.01 };
        let r = Residual {
            experiment: 0,
            time: 10.0,
            end: true,
            quantity: Quantity::NeckRatio,
            measured,
            fitted: f64::NAN,
            residual: super::super::loss::FAILURE_RESIDUAL,
        };
        let path = dir.join("residuals.csv");
        write_residuals(&path, std::slice::from_ref(&e), &[r]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().nth(1).unwrap(), "E1B,10.000000,1,neck_ratio,5.0000000000e-1,1.000000e-2,,1.000000e3");
        assert!(!text.contains("NaN"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn material_toml_round_trips() {
        let ti = Material::titanium();
        let f = PathFactors { path_factor_gb: 0.3, ..PathFactors::default() };
        let text = material_toml(&ti, Some(&f));
        assert!(text.contains("atomic_volume = 1.76e-29") && text.contains("[model]\npath_factor_gb = 0.3"), "{text}");
        let t: toml::Table = text.parse().unwrap();
        let m = Material::from_value(t["materials"].as_array().unwrap()[0].clone()).unwrap();
        assert_eq!(m, ti);
        let g: PathFactors = t["model"].clone().try_into().unwrap();
        assert_eq!(g, f);
    }
}

//! The files of `sinterdem rve` (docs/rve.md "Output"): `constitutive.csv`, `fit.json`,
//! `constitutive.png` / `sintering_stress.png`, and the `rve` block of `summary.json`.

use super::RveSettings;
use super::branch::Point;
use super::fit::{FitRow, LawFit, fit_power_law, fit_skorohod_olevsky, phi_psi};
use crate::error::IoError;
use crate::plot::{Plot, Series};
use serde_json::json;
use std::path::Path;

/// The columns of `constitutive.csv`, SI units in the names.
pub const COLUMNS: &[&str] = &[
    "time_s",
    "temperature_K",
    "relative_density",
    "shrinkage",
    "neck_ratio",
    "volumetric_rate_free_per_s",
    "perturbation_Pa",
    "sintering_stress_Pa",
    "sintering_stress_b23_Pa",
    "bulk_viscosity_Pa_s",
    "bulk_viscosity_half_Pa_s",
    "uniaxial_viscosity_Pa_s",
    "uniaxial_viscosity_x_Pa_s",
    "uniaxial_viscosity_x_half_Pa_s",
    "uniaxial_spread",
    "poisson_ratio",
    "poisson_ratio_isotropic",
    "shear_viscosity_Pa_s",
    "kappa_xx_W_per_mK",
    "kappa_yy_W_per_mK",
    "kappa_zz_W_per_mK",
    "kappa_yz_W_per_mK",
    "kappa_xz_W_per_mK",
    "kappa_xy_W_per_mK",
    "mean_overlap_over_radius",
    "kappa_extrapolated",
    "sintering_stress_contact_law_Pa",
];

fn values(p: &Point) -> Vec<f64> {
    let mut v = vec![
        p.time,
        p.temperature,
        p.relative_density,
        p.shrinkage,
        p.neck_ratio,
        p.volumetric_rate_free,
        p.perturbation,
        p.sintering_stress,
        p.sintering_stress_b23,
        p.bulk_viscosity,
        p.bulk_viscosity_half,
        p.uniaxial_viscosity,
        p.uniaxial_viscosity_x,
        p.uniaxial_viscosity_x_half,
        p.uniaxial_spread,
        p.poisson_ratio,
        p.poisson_ratio_isotropic,
        p.shear_viscosity,
    ];
    v.extend_from_slice(&p.kappa);
    v.push(p.mean_overlap_over_radius);
    v.push(if p.kappa_extrapolated { 1.0 } else { 0.0 });
    v.push(p.sintering_stress_contact_law);
    v
}

/// The fit of (R9)–(R11) to the rows within 0.5 K of `temperature` (default: the last row's);
/// an error (fewer than two rows, a non-positive value) is kept as its message.
pub fn fit_rows(points: &[Point], r0: f64, temperature: Option<f64>) -> Result<LawFit, String> {
    let t = temperature.or(points.last().map(|p| p.temperature)).unwrap_or(0.0);
    let rows: Vec<FitRow> = points
        .iter()
        .filter(|p| (p.temperature - t).abs() <= 0.5)
        .map(|p| FitRow {
            relative_density: p.relative_density,
            bulk_viscosity: p.bulk_viscosity,
            shear_viscosity: p.shear_viscosity,
            sintering_stress: p.sintering_stress,
            uniaxial_viscosity: p.uniaxial_viscosity,
            poisson_ratio: p.poisson_ratio,
        })
        .collect();
    let mut fit = fit_skorohod_olevsky(&rows, r0).map_err(|e| format!("no fit at {t} K: {e}"))?;
    match fit_power_law(&rows) {
        Ok(p) => fit.density_law = Some(p),
        Err(e) => fit.density_law_reason = Some(format!("no porosity power law at {t} K: {e}")),
    }
    Ok(fit)
}

/// Writes `constitutive.csv`, `fit.json` and (with `plots`: the case title and key settings of the
/// run, [`crate::kinds::compact::plot_header`]) the two plots into `out`.
pub fn write(out: &Path, points: &[Point], fit: &Result<LawFit, String>, plots: Option<&(String, String)>) -> Result<(), IoError> {
    let mut text = COLUMNS.join(",") + "\n";
    for p in points {
        text += &values(p).iter().map(|v| format!("{v:e}")).collect::<Vec<_>>().join(",");
        text.push('\n');
    }
    crate::io::write_atomic(&out.join("constitutive.csv"), &text)?;
    crate::io::write_json(&out.join("fit.json"), &fit_json(fit))?;
    if let Some(header) = plots.filter(|_| !points.is_empty()) {
        for (name, plot) in rve_plots(header, points, fit) {
            plot.save_png_or_warn(&out.join(name));
        }
    }
    Ok(())
}

/// The two plots of the constitutive data (file name, plot): measured viscosities and sintering
/// stress against relative density, with the fitted Skorohod–Olevsky law (docs/rve.md (R3)–(R11))
/// where the fit succeeded; the stress axis from zero.
pub fn rve_plots(header: &(String, String), points: &[Point], fit: &Result<LawFit, String>) -> Vec<(&'static str, Plot)> {
    let rho: Vec<f64> = points.iter().map(|p| p.relative_density).collect();
    let line = |f: &dyn Fn(&Point) -> f64| points.iter().zip(&rho).map(|(p, &r)| (r, f(p))).collect::<Vec<_>>();
    let sub = format!("{}; periodic cell measured at {} times", header.1, points.len());
    let mut plot = Plot::new(format!("{}: viscosities of the periodic cell", header.0))
        .subtitle(sub.clone())
        .labels("relative density (solid volume fraction)", "viscosity [Pa s] (log scale)")
        .log_y(true);
    plot.add(Series::new("bulk viscosity K, measured", line(&|p| p.bulk_viscosity)).points_only());
    plot.add(Series::new("uniaxial viscosity, measured", line(&|p| p.uniaxial_viscosity)).points_only());
    plot.add(Series::new("shear viscosity G, measured", line(&|p| p.shear_viscosity)).points_only());
    if let Ok(f) = fit {
        let fine = law_grid(&rho);
        // each fit in the colour of the data it fits (series 0: K, 2: G)
        plot.add(Series::new("bulk, Skorohod-Olevsky fit", fine.iter().map(|&r| (r, 2.0 * f.eta0 * phi_psi(r).1)).collect()).colour_of(0));
        plot.add(Series::new("shear, Skorohod-Olevsky fit", fine.iter().map(|&r| (r, f.eta0 * phi_psi(r).0)).collect()).colour_of(2));
        if let Some(p) = &f.density_law {
            plot.add(Series::new("bulk, porosity power law", fine.iter().map(|&r| (r, p.bulk.at(r))).collect()).colour_of(0));
            plot.add(Series::new("shear, porosity power law", fine.iter().map(|&r| (r, p.shear.at(r))).collect()).colour_of(2));
        }
    }
    // the stress in kPa or MPa, whichever its values read in
    let top = points.iter().map(|p| p.sintering_stress.abs().max(p.sintering_stress_b23.abs())).fold(0.0, f64::max);
    let (unit, k) = if top >= 1e6 { ("MPa", 1e-6) } else { ("kPa", 1e-3) };
    let mut stress = Plot::new(format!("{}: sintering stress (tension positive)", header.0))
        .subtitle(sub)
        .labels("relative density (solid volume fraction)", format!("sintering stress [{unit}]"))
        .y_zero(true);
    stress.add(Series::new("from the free shrinkage rate", line(&|p| k * p.sintering_stress)).points_only());
    stress.add(Series::new("from the cell's contact forces", line(&|p| k * p.sintering_stress_b23)).points_only());
    if let Ok(f) = fit {
        let fine = law_grid(&rho);
        // the fits are fitted to σ_s from the free shrinkage rate (series 0)
        stress.add(Series::new("Skorohod-Olevsky fit", fine.iter().map(|&r| (r, k * 3.0 * f.alpha * r * r / f.r0_m)).collect()).colour_of(0));
        if let Some(p) = &f.density_law {
            stress.add(Series::new("porosity power law", fine.iter().map(|&r| (r, k * p.stress_at(r))).collect()).colour_of(0));
        }
    }
    vec![("constitutive.png", plot), ("sintering_stress.png", stress)]
}

fn law_grid(rho: &[f64]) -> Vec<f64> {
    let (lo, hi) = rho.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &r| (a.min(r), b.max(r)));
    let hi = if hi > lo { hi } else { lo + 1e-3 };
    (0..=40).map(|k| lo + (hi - lo) * k as f64 / 40.0).collect()
}

fn fit_json(fit: &Result<LawFit, String>) -> serde_json::Value {
    match fit {
        Ok(f) => {
            let mut v = serde_json::to_value(f).unwrap_or_else(|_| json!({}));
            v["fitted"] = json!(true);
            v["equations"] =
                json!("docs/rve.md (R9)-(R11): phi = (1-theta)^2, psi = (2/3)(1-theta)^3/theta, K = 2 eta0 psi, G = eta0 phi, P_L = 3 alpha (1-theta)^2 / r0");
            if f.density_law.is_some() {
                v["density_law"]["equations"] = json!(
                    "docs/rve.md (R12)-(R13): G = shear.prefactor rho^shear.density_exponent (1-rho)^-shear.porosity_exponent, K likewise with bulk.*, sigma_s = stress_prefactor rho^stress_density_exponent"
                );
                if f.density_law.as_ref().is_some_and(|p| p.uniaxial.is_some()) {
                    v["density_law"]["uniaxial_equations"] = json!(
                        "docs/rve.md (R14)-(R15): E_p = uniaxial.prefactor rho^uniaxial.density_exponent (1-rho)^-uniaxial.porosity_exponent, nu_p = poisson_intercept + poisson_slope rho; under a uniaxial compression sigma: axial rate -sigma/E_p - sigma_s/(3K), lateral rate +nu_p sigma/E_p - sigma_s/(3K)"
                    );
                }
            }
            v
        }
        Err(e) => json!({"fitted": false, "law": "skorohod-olevsky", "reason": e}),
    }
}

/// The `rve` block of `summary.json`: the settings, the rows, the linearity check and the fit.
pub fn summary_block(rve: &RveSettings, points: &[Point], fit: &Result<LawFit, String>) -> serde_json::Value {
    let rel = |a: f64, b: f64| (a / b - 1.0).abs();
    let lin_k = points.iter().map(|p| rel(p.bulk_viscosity_half, p.bulk_viscosity)).fold(0.0, f64::max);
    let lin_e = points.iter().map(|p| rel(p.uniaxial_viscosity_x_half, p.uniaxial_viscosity_x)).fold(0.0, f64::max);
    let ratio: Vec<f64> = points.iter().map(|p| p.sintering_stress / p.sintering_stress_b23).collect();
    json!({
        "at_s": rve.at,
        "interval_s": rve.interval,
        "steps": rve.steps,
        "perturbation": rve.perturbation,
        "points": points.len(),
        "rows": points,
        "linearity_bulk_max_rel": lin_k,
        "linearity_uniaxial_max_rel": lin_e,
        "sintering_stress_over_b23": ratio,
        "fit": fit_json(fit),
        "files": ["constitutive.csv", "fit.json", "constitutive.png", "sintering_stress.png"],
    })
}

//! The Skorohod–Olevsky linear viscous law of a porous body (Olevsky 1998, docs/rve.md
//! (R9)–(R11)) fitted to a constitutive table: the shear viscosity of the solid η0 and the
//! surface tension α, by least squares in the logarithm (closed form), with their standard errors.
//!
//! With θ = 1 − ρ the porosity: φ = (1−θ)², ψ = (2/3)(1−θ)³/θ (R9); the bulk viscosity
//! K = 2η0ψ and the shear viscosity G = η0φ (R10); the sintering stress P_L = 3α(1−θ)²/r0 (R11).

use crate::error::ConfigError;

/// A row of the fit: relative density [1], bulk viscosity K [Pa·s], shear viscosity G [Pa·s],
/// sintering stress σ_s [Pa].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitRow {
    pub relative_density: f64,
    pub bulk_viscosity: f64,
    pub shear_viscosity: f64,
    pub sintering_stress: f64,
}

/// The fitted law (`DIR/fit.json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LawFit {
    pub law: &'static str,
    /// η0 from K and G together, and from each alone [Pa·s].
    #[serde(rename = "eta0_Pa_s")]
    pub eta0: f64,
    #[serde(rename = "eta0_from_bulk_Pa_s")]
    pub eta0_from_bulk: f64,
    #[serde(rename = "eta0_from_shear_Pa_s")]
    pub eta0_from_shear: f64,
    /// Standard error of ln η0 (≈ relative error of η0) [1].
    pub eta0_rel_error: f64,
    /// α [J/m² = N/m] and the standard error of ln α [1].
    #[serde(rename = "alpha_J_per_m2")]
    pub alpha: f64,
    pub alpha_rel_error: f64,
    /// Particle radius r0 of (R11) [m] (the mean radius).
    pub r0_m: f64,
    /// Root mean square of the relative residuals of K, G and σ_s under the fitted law [1].
    pub rms_rel_residual_bulk: f64,
    pub rms_rel_residual_shear: f64,
    pub rms_rel_residual_stress: f64,
    /// Rows used.
    pub rows: usize,
}

/// (R9) φ(ρ), ψ(ρ).
pub fn phi_psi(rho: f64) -> (f64, f64) {
    let theta = 1.0 - rho;
    ((1.0 - theta).powi(2), 2.0 / 3.0 * (1.0 - theta).powi(3) / theta)
}

/// Mean and standard error of the mean of `v` (0 for one value).
fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (m, 0.0);
    }
    let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (s / n.max(1) as f64).sqrt()
}

/// Fits η0 and α of (R9)–(R11) to `rows` (`r0` [m]): ln η0 is the mean of ln(K/2ψ) and ln(G/φ)
/// over the rows, ln α the mean of ln(σ_s r0/(3ρ²)) — the least-squares solutions in the
/// logarithm, so every row weighs alike whatever its magnitude. Rows need 0 < ρ < 1 and positive
/// K, G, σ_s; at least two rows.
pub fn fit_skorohod_olevsky(rows: &[FitRow], r0: f64) -> Result<LawFit, ConfigError> {
    if !(r0.is_finite() && r0 > 0.0) {
        return Err(ConfigError::invalid(format!("fit: particle radius r0 = {r0:e} m: expected a positive radius")));
    }
    for (k, r) in rows.iter().enumerate() {
        let ok = r.relative_density > 0.0
            && r.relative_density < 1.0
            && [r.bulk_viscosity, r.shear_viscosity, r.sintering_stress].iter().all(|v| v.is_finite() && *v > 0.0);
        if !ok {
            return Err(ConfigError::invalid(format!(
                "fit: row {k} (relative density {}, K = {:e} Pa s, G = {:e} Pa s, sigma_s = {:e} Pa): expected 0 < relative density < 1 and positive finite K, G, sigma_s",
                r.relative_density, r.bulk_viscosity, r.shear_viscosity, r.sintering_stress
            )));
        }
    }
    if rows.len() < 2 {
        return Err(ConfigError::invalid(format!("fit: {} row(s): the law's two parameters need at least two rows", rows.len())));
    }
    let lk: Vec<f64> = rows.iter().map(|r| (r.bulk_viscosity / (2.0 * phi_psi(r.relative_density).1)).ln()).collect();
    let lg: Vec<f64> = rows.iter().map(|r| (r.shear_viscosity / phi_psi(r.relative_density).0).ln()).collect();
    let la: Vec<f64> = rows.iter().map(|r| (r.sintering_stress * r0 / (3.0 * r.relative_density.powi(2))).ln()).collect();
    let both: Vec<f64> = lk.iter().chain(&lg).copied().collect();
    let (le, se_e) = mean_se(&both);
    let (lal, se_a) = mean_se(&la);
    let (eta0, alpha) = (le.exp(), lal.exp());
    let (pk, pg) = (|r: &FitRow| 2.0 * eta0 * phi_psi(r.relative_density).1, |r: &FitRow| eta0 * phi_psi(r.relative_density).0);
    Ok(LawFit {
        law: "skorohod-olevsky",
        eta0,
        eta0_from_bulk: mean_se(&lk).0.exp(),
        eta0_from_shear: mean_se(&lg).0.exp(),
        eta0_rel_error: se_e,
        alpha,
        alpha_rel_error: se_a,
        r0_m: r0,
        rms_rel_residual_bulk: rms(rows.iter().map(|r| r.bulk_viscosity / pk(r) - 1.0)),
        rms_rel_residual_shear: rms(rows.iter().map(|r| r.shear_viscosity / pg(r) - 1.0)),
        rms_rel_residual_stress: rms(rows.iter().map(|r| r.sintering_stress / (3.0 * alpha * r.relative_density.powi(2) / r0) - 1.0)),
        rows: rows.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table made by the law itself is fitted back exactly (to round-off), with zero error;
    /// multiplicative noise ±ε on every value gives an error of the order ε/√n.
    #[test]
    fn recovers_the_parameters_of_a_synthetic_table() {
        let (eta0, alpha, r0) = (3.0e9, 1.7, 25e-6);
        let table = |noise: &dyn Fn(usize) -> f64| -> Vec<FitRow> {
            (0..8)
                .map(|k| {
                    let rho = 0.62 + 0.03 * k as f64;
                    let (phi, psi) = phi_psi(rho);
                    FitRow {
                        relative_density: rho,
                        bulk_viscosity: 2.0 * eta0 * psi * noise(3 * k),
                        shear_viscosity: eta0 * phi * noise(3 * k + 1),
                        sintering_stress: 3.0 * alpha * rho * rho / r0 * noise(3 * k + 2),
                    }
                })
                .collect()
        };
        let f = fit_skorohod_olevsky(&table(&|_| 1.0), r0).unwrap();
        assert!((f.eta0 / eta0 - 1.0).abs() < 1e-12 && (f.alpha / alpha - 1.0).abs() < 1e-12, "{f:?}");
        assert!(f.eta0_rel_error < 1e-12 && f.rms_rel_residual_bulk < 1e-12 && f.rms_rel_residual_stress < 1e-12);
        // alternating ±5 %: the estimates stay within 2 % and the stated errors cover them
        let f = fit_skorohod_olevsky(&table(&|k| if k % 2 == 0 { 1.05 } else { 0.95 }), r0).unwrap();
        assert!((f.eta0 / eta0 - 1.0).abs() < 0.02 && (f.alpha / alpha - 1.0).abs() < 0.02, "{f:?}");
        assert!(f.eta0_rel_error > 0.005 && f.eta0_rel_error < 0.02, "{}", f.eta0_rel_error);
        assert!((f.rms_rel_residual_bulk - 0.05).abs() < 0.01, "{}", f.rms_rel_residual_bulk);
    }

    #[test]
    fn bad_rows_are_errors() {
        let good = FitRow { relative_density: 0.7, bulk_viscosity: 1e9, shear_viscosity: 1e9, sintering_stress: 1e5 };
        let e = fit_skorohod_olevsky(&[good], 25e-6).unwrap_err().to_string();
        assert!(e.contains("at least two rows"), "{e}");
        let bad = FitRow { bulk_viscosity: -1.0, ..good };
        let e = fit_skorohod_olevsky(&[good, bad], 25e-6).unwrap_err().to_string();
        assert!(e.contains("row 1") && e.contains("positive"), "{e}");
        let e = fit_skorohod_olevsky(&[good, good], 0.0).unwrap_err().to_string();
        assert!(e.contains("r0"), "{e}");
    }
}

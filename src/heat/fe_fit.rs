//! `fe_fit`: the second conductance law of the heat network, fitted to our own converged
//! axisymmetric FE of Rojek et al. (2022)'s half sintering geometry
//! (`validation/fe_conductance.py`, table `validation/data/conductance_half.csv`,
//! write-up `docs/validation-conductance.md`).
//!
//! The published law (eq. 43) is `K_i = 1.064·κ_i·π·a`. The converged FE shows that the factor
//! is not constant: it rises towards Holm's constriction limit 4/π for small necks (+11.5 % at
//! a/r = 0.05), dips to 1.046 near a/r = 0.4 and rises again as the sphere segment shortens
//! (+10 % at a/r = 0.8). `fe_fit_factor` replaces the constant 1.064:
//! `K_half = fe_fit_factor(a / r)·κ·π·a`, r the radius of the particle of that half.

/// Holm small-neck limit of the factor, 4/π, reached at a/r → 0.
pub const FE_FIT_SMALL_NECK_LIMIT: f64 = 4.0 / std::f64::consts::PI;
/// Exact factor at a/r = 1 (the half geometry is then a cylinder of radius r, length 2r/3).
pub const FE_FIT_CYLINDER_LIMIT: f64 = 1.5;
/// Upper end of the fitted range of a/r (the FE table covers 0.05..=0.8).
pub const FE_FIT_A_OVER_R_MAX: f64 = 0.8;
/// Lower end of the FE table; below it the formula approaches 4/π as derived, not fitted.
pub const FE_FIT_A_OVER_R_MIN: f64 = 0.05;

/// Coefficient of x in D(x).
pub const FE_FIT_P1: f64 = 0.2585484101;
/// Coefficient of x·ln x in D(x).
pub const FE_FIT_P2: f64 = -0.2952644660;
/// Coefficient of x² in D(x).
pub const FE_FIT_P3: f64 = -0.2177877089;
/// Coefficient of x·(1 − √(1 − x²)) in D(x), fixed by D(1) = 1/1.5.
pub const FE_FIT_P4: f64 = 2.0 / 3.0 - std::f64::consts::FRAC_PI_4 - FE_FIT_P1 - FE_FIT_P3;

/// Dimensionless conductance factor of one half of a sintered pair,
/// `f(x) = K_i/(κ·π·a)` with `x = a/r` (the published linear law is f ≡ 1.064):
///
/// ```text
/// f(x) = 1 / D(x),
/// D(x) = π/4 + p1·x + p2·x·ln x + p3·x² + p4·x·(1 − √(1 − x²)),   p4 = 2/3 − π/4 − p1 − p3
/// ```
///
/// so that f → 4/π as x → 0 (Holm's constriction of a circular contact) and f(1) = 1.5 exactly
/// (the cylinder the half geometry becomes at a = r). `x ln x` carries the slow approach to the
/// Holm limit (the thin neck), `√(1 − x²)` the shortening sphere segment.
///
/// Validity: fitted for 0.05 ≤ a/r ≤ 0.8 (minimax; max deviation 0.085 % from the converged
/// FE table, whose own discretisation error is below 1e-6). 0 < a/r < 0.05 follows the formula
/// towards the exact limit 4/π; 0.8 < a/r ≤ 1 follows the formula to the exact value 1.5 (not
/// fitted there: expect a few per cent). r is the radius of the particle of that half, so for an
/// unequal pair each half uses its own radius: `K_half_i = f(a/r_i)·κ_i·π·a`.
///
/// Outside: a/r ≤ 0 returns 4/π, a/r ≥ 1 returns 1.5 (a > r cannot occur under the neck's
/// validity limit); the result is finite and positive for every non-NaN input (between 1.04 and
/// 1.5), never panics; NaN propagates.
pub fn fe_fit_factor(a_over_r: f64) -> f64 {
    let x = a_over_r;
    if x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return FE_FIT_SMALL_NECK_LIMIT;
    }
    if x >= 1.0 {
        return FE_FIT_CYLINDER_LIMIT;
    }
    let d = std::f64::consts::FRAC_PI_4 + FE_FIT_P1 * x + FE_FIT_P2 * x * x.ln() + FE_FIT_P3 * x * x + FE_FIT_P4 * x * (1.0 - (1.0 - x * x).sqrt());
    1.0 / d
}

#[cfg(test)]
mod tests {
    use super::*;

    const TABLE: &str = include_str!("../../validation/data/conductance_half.csv");

    /// (a/r, K_i/(κπa)) rows of the converged FE table.
    fn table() -> Vec<(f64, f64)> {
        let mut lines = TABLE.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty());
        let header: Vec<&str> = lines.next().expect("header").split(',').collect();
        let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
        let (ix, ik) = (col("a_over_r"), col("K_over_Kcyl_converged"));
        lines
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|s| s.parse().expect("number")).collect();
                (v[ix], v[ik] / v[ix])
            })
            .collect()
    }

    #[test]
    fn within_half_a_percent_of_every_converged_row() {
        let rows = table();
        assert!(rows.len() >= 16);
        for (x, f) in rows {
            let dev = fe_fit_factor(x) / f - 1.0;
            assert!(dev.abs() < 0.005, "a/r = {x}: fit {} vs FE {f} ({:.3} %)", fe_fit_factor(x), 100.0 * dev);
            // the fit is in fact much closer than the 0.5 % requirement
            assert!(dev.abs() < 0.001, "a/r = {x}: {:.3} %", 100.0 * dev);
        }
    }

    #[test]
    fn limits_and_extrapolation() {
        assert!((fe_fit_factor(1e-12) - 4.0 / std::f64::consts::PI).abs() < 1e-9);
        assert_eq!(fe_fit_factor(0.0), FE_FIT_SMALL_NECK_LIMIT);
        assert_eq!(fe_fit_factor(-1.0), FE_FIT_SMALL_NECK_LIMIT);
        assert!((fe_fit_factor(1.0 - 1e-12) - 1.5).abs() < 1e-5);
        assert_eq!(fe_fit_factor(2.0), 1.5);
        assert_eq!(fe_fit_factor(f64::INFINITY), 1.5);
        assert!(fe_fit_factor(f64::NAN).is_nan());
        // continuous, positive, bounded on a fine grid over (0, 1)
        let mut prev = fe_fit_factor(1e-9);
        for i in 1..=100_000 {
            let x = i as f64 * 1e-5;
            let f = fe_fit_factor(x);
            assert!(f.is_finite() && (1.0..=1.5).contains(&f), "x = {x}: {f}");
            assert!((f - prev).abs() < 2e-3, "jump at x = {x}");
            prev = f;
        }
    }

    #[test]
    fn paper_pair_halves() {
        // r_i = 1 mm, r_j = 3 mm, a = 0.4191863 mm, copper: series of the two halves
        let (kappa, a) = (394.0, 0.4191863e-3);
        let ki = fe_fit_factor(a / 1e-3) * kappa * std::f64::consts::PI * a;
        let kj = fe_fit_factor(a / 3e-3) * kappa * std::f64::consts::PI * a;
        let k = ki * kj / (ki + kj);
        // FE of the whole pair: 0.2791677 W/K (validation/data/conductance_pair.csv)
        assert!((k / 0.2791677 - 1.0).abs() < 0.005, "{k}");
    }
}

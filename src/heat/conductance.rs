//! Conductance of one thermal pipe (docs/heat-model.md (H6)–(H8); Rojek et al. 2022
//! eqs. 5–9, 40–45).

use serde::{Deserialize, Serialize};

/// How a half pipe's conductance depends on the neck.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ConductanceLaw {
    /// `K_i = c_K·κ_i·π·a` with the published FE slope c_K = 1.064 by default (eq. 43).
    #[default]
    Linear,
    /// `K_i = f(a/r_i)·κ_i·π·a`, f fitted to sinterdem's own axisymmetric FE table
    /// (`validation/`, docs/validation-conductance.md); within 0.1 % of it for 0.05 ≤ a/r ≤ 0.8.
    FeFit,
}

/// The conductance model of a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conductance {
    pub law: ConductanceLaw,
    /// c_K of the linear law [1] (default 1.064).
    pub factor: f64,
    /// Optional interface conductance K_c in series [W/K] (eq. 8).
    pub contact: Option<f64>,
}

impl Default for Conductance {
    fn default() -> Self {
        Conductance { law: ConductanceLaw::Linear, factor: 1.064, contact: None }
    }
}

/// The two halves and the pipe [W/K].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PipeConductance {
    /// Half of particle i, K_i [W/K].
    pub half_i: f64,
    /// Half of particle j, K_j [W/K].
    pub half_j: f64,
    /// The pipe, `1/K_ij = 1/K_i + 1/K_j (+ 1/K_c)` (eqs. 8–9) [W/K].
    pub pair: f64,
}

impl Conductance {
    /// Conductance of one half pipe of a particle of radius `r` [m] and conductivity `kappa`
    /// [W/(m·K)] at neck radius `a` [m] (eq. 43 or the FE fit).
    pub fn half(&self, kappa: f64, r: f64, a: f64) -> f64 {
        let f = match self.law {
            ConductanceLaw::Linear => self.factor,
            ConductanceLaw::FeFit => super::fe_fit::fe_fit_factor(a / r),
        };
        f * kappa * std::f64::consts::PI * a
    }

    /// Both halves and the series pipe for a neck of radius `a` [m] between particles of radii
    /// `r_i`, `r_j` [m] and conductivities `kappa_i`, `kappa_j` [W/(m·K)]. `a = 0` gives zero.
    pub fn pipe(&self, kappa_i: f64, kappa_j: f64, r_i: f64, r_j: f64, a: f64) -> PipeConductance {
        let half_i = self.half(kappa_i, r_i, a);
        let half_j = self.half(kappa_j, r_j, a);
        if !(half_i > 0.0 && half_j > 0.0) {
            return PipeConductance { half_i, half_j, pair: 0.0 };
        }
        let mut inv = 1.0 / half_i + 1.0 / half_j;
        if let Some(kc) = self.contact {
            inv += 1.0 / kc;
        }
        PipeConductance { half_i, half_j, pair: 1.0 / inv }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn published_copper_pair() {
        // worked check of docs/heat-model.md: κ = 394, r_i = 1 mm, r_j = 3 mm, h = 0.06 mm.
        let n = crate::neck::solve(1e-3, 3e-3, 0.06e-3).unwrap();
        let p = Conductance::default().pipe(394.0, 394.0, 1e-3, 3e-3, n.a);
        assert!((p.half_i / 0.552071 - 1.0).abs() < 1e-6, "{}", p.half_i);
        assert!((p.pair / 0.2760354 - 1.0).abs() < 1e-6, "{}", p.pair);
        assert_eq!(p.half_i, p.half_j);
    }

    #[test]
    fn series_with_mixed_materials_and_contact_resistance() {
        let c = Conductance { contact: Some(0.5), ..Default::default() };
        let p = c.pipe(100.0, 300.0, 1.0, 1.0, 0.1);
        let k = 1.064 * std::f64::consts::PI * 0.1;
        let expect = 1.0 / (1.0 / (100.0 * k) + 1.0 / (300.0 * k) + 2.0);
        assert!((p.pair / expect - 1.0).abs() < 1e-14);
        assert_eq!(c.pipe(1.0, 1.0, 1.0, 1.0, 0.0).pair, 0.0);
    }

    #[test]
    fn fe_fit_uses_each_half_its_own_radius() {
        let c = Conductance { law: ConductanceLaw::FeFit, ..Default::default() };
        let p = c.pipe(394.0, 394.0, 1e-3, 3e-3, 0.3e-3);
        let k = 394.0 * std::f64::consts::PI * 0.3e-3;
        assert!((p.half_i / (crate::heat::fe_fit::fe_fit_factor(0.3) * k) - 1.0).abs() < 1e-14);
        assert!((p.half_j / (crate::heat::fe_fit::fe_fit_factor(0.1) * k) - 1.0).abs() < 1e-14);
        // small necks conduct more than the linear law says (Holm's limit 4/π per side)
        assert!(p.half_j > Conductance::default().half(394.0, 3e-3, 0.3e-3));
    }
}

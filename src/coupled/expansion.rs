//! Thermal expansion of the particles of a compact run (docs/coupled.md "Thermal expansion",
//! (X1)–(X12)).
//!
//! Each particle's free radius is `r_i(1 + ε_i)` with `ε_i = ∫ α dT` from its temperature at
//! t = 0 (X1). The 7-DOF contacts, the heat network and the contact search keep working in the
//! reference (unexpanded) geometry; the bonded mechanics receives, per bond and step, the thermal
//! eigen-elongation (X4) beside the sintering approach, scaled to the current geometry (X5), and
//! hands back to the correction the mechanical approach net of it (X8). A compact heated
//! uniformly without sintering thus expands homogeneously by exactly ε in every direction.
//! Without any expanding material nothing here is built and a run is bit-identical to one
//! without the feature.

use crate::material::{Expansion, Material};
use crate::particles::Particles;
use nalgebra::Vector3;

/// The expansion data of a compact run: α per material and the reference temperature per
/// particle. Built once at the start from the prepared scene, so a run resumed from a checkpoint
/// rebuilds the same (no per-particle state of its own).
#[derive(Debug, Clone)]
pub struct ThermalExpansion {
    /// α of each material index; None: that material does not expand.
    alpha: Vec<Option<Expansion>>,
    /// Reference temperature T_ref,i of each particle [K]: its temperature at t = 0 (X1).
    pub reference_temperature: Vec<f64>,
    /// Principal planes each particle is held on (bits 1, 2, 4: x, y, z; docs/mechanics.md
    /// "Constraints"); all 0 without constrained planes.
    pub plane_mask: Vec<u8>,
}

/// Per-contact terms of one mechanics step with expansion on ((X3)–(X5)).
#[derive(Debug, Clone, Default)]
pub struct StepTerms {
    /// Thermal elongation Δ_th of each bond over the step (X4) [m], > 0: apart.
    pub elongation: Vec<f64>,
    /// Expansion factor f_ij of each bond at the step's end (X3) [1].
    pub factor: Vec<f64>,
    /// Expanded radii at the step's start (X6) [m], one per particle: R_m of the links and r̄ (the
    /// step is linearised about its start, as are the lever arms (B2)).
    pub radii: Vec<f64>,
    /// The predicted thermal displacement of each particle over the step (X7) [m].
    pub predictor: Vec<Vector3<f64>>,
    /// Each bond's axial approach under the predictor, `(u_A − u_B)·e3` (X7) [m].
    pub predictor_approach: Vec<f64>,
}

impl ThermalExpansion {
    /// The expansion of a run: None when no material expands (then nothing changes). The
    /// reference temperatures are the particles' temperatures `p.temperature` at t = 0.
    pub fn new(materials: &[Material], p: &Particles) -> Option<ThermalExpansion> {
        let alpha: Vec<Option<Expansion>> = materials.iter().map(|m| m.thermal_expansion.clone()).collect();
        if alpha.iter().all(Option::is_none) {
            return None;
        }
        Some(ThermalExpansion { alpha, reference_temperature: p.temperature.clone(), plane_mask: vec![0; p.len()] })
    }

    /// (X1) ε_i = ∫_{T_ref,i}^{T} α dT of particle `i` at temperature `t` [K] (0 for a material
    /// that does not expand) [1].
    pub fn strain(&self, p: &Particles, i: usize, t: f64) -> f64 {
        match &self.alpha[p.material[i] as usize] {
            Some(a) => a.strain(self.reference_temperature[i], t),
            None => 0.0,
        }
    }

    /// ε_i of every particle at the temperatures `temps` [K].
    pub fn strains(&self, p: &Particles, temps: &[f64]) -> Vec<f64> {
        (0..p.len()).map(|i| self.strain(p, i, temps[i])).collect()
    }

    /// (X2) The free length `r_i(1 + ε_i) + r_j(1 + ε_j)` of the pair `i`, `j` [m].
    pub fn free_length(p: &Particles, eps: &[f64], i: usize, j: usize) -> f64 {
        p.radius[i] * (1.0 + eps[i]) + p.radius[j] * (1.0 + eps[j])
    }

    /// (X3)–(X6) and (X7) of one step, from the strains `eps0` at its start and `eps1` at its
    /// end, at the positions of its start; `corner` [m]: the corner of the principal planes.
    pub fn step_terms(&self, p: &Particles, pairs: &[[u32; 2]], eps0: &[f64], eps1: &[f64], corner: &Vector3<f64>) -> StepTerms {
        let m = pairs.len();
        let mut t =
            StepTerms { elongation: Vec::with_capacity(m), factor: Vec::with_capacity(m), predictor_approach: Vec::with_capacity(m), ..Default::default() };
        // (X7): the affine expansion by the mean strain about the planes' corner; a particle held
        // on a plane moves off it by its own radial growth instead of the mean one (its surface
        // keeps its distance to the plane)
        let (mean0, mean1) = (Self::mean_strain(p, eps0, pairs).0, Self::mean_strain(p, eps1, pairs).0);
        let g = (mean1 - mean0) / (1.0 + mean0);
        t.predictor = (0..p.len())
            .map(|i| {
                let mut u = (p.position[i] - corner) * g;
                for a in 0..3 {
                    if self.plane_mask[i] & (1 << a) != 0 {
                        u[a] += p.radius[i] * ((eps1[i] - eps0[i]) - g * (1.0 + eps0[i]));
                    }
                }
                u
            })
            .collect();
        for &[i, j] in pairs {
            let (i, j) = (i as usize, j as usize);
            let dx = p.position[j] - p.position[i];
            let d = dx.norm();
            let (l0, l1) = (Self::free_length(p, eps0, i, j), Self::free_length(p, eps1, i, j));
            // (X4) Δ_th = d·(L(ε1)/L(ε0) − 1), written so that it is exactly 0 when ε1 = ε0
            t.elongation.push(d * (l1 - l0) / l0);
            // (X3) f = L(ε1)/L_ref
            t.factor.push(l1 / (p.radius[i] + p.radius[j]));
            t.predictor_approach.push((t.predictor[i] - t.predictor[j]).dot(&(dx / d)));
        }
        t.radii = p.radius.iter().zip(eps0).map(|(r, e)| r * (1.0 + e)).collect();
        t
    }

    /// (X9) The reference centre distance of the pair `i`, `j` at distance `d` [m]: `d·L_ref/L(ε)`.
    pub fn reference_distance(p: &Particles, eps: &[f64], i: usize, j: usize, d: f64) -> f64 {
        d * (p.radius[i] + p.radius[j]) / Self::free_length(p, eps, i, j)
    }

    /// (X10) The volume-weighted mean thermal strain `Σ V_i ε_i / Σ V_i` over the particles with a
    /// contact (all particles when none has one) [1], and the smallest and largest ε_i among them.
    pub fn mean_strain(p: &Particles, eps: &[f64], pairs: &[[u32; 2]]) -> (f64, f64, f64) {
        let mut bonded = vec![pairs.is_empty(); p.len()];
        for &[i, j] in pairs {
            bonded[i as usize] = true;
            bonded[j as usize] = true;
        }
        let (mut sv, mut se, mut lo, mut hi) = (0.0, 0.0, f64::INFINITY, f64::NEG_INFINITY);
        for i in (0..p.len()).filter(|&i| bonded[i]) {
            let v = p.radius[i].powi(3);
            sv += v;
            se += v * eps[i];
            lo = lo.min(eps[i]);
            hi = hi.max(eps[i]);
        }
        if sv > 0.0 { (se / sv, lo, hi) } else { (0.0, 0.0, 0.0) }
    }
}

/// (X11) The sintering shrinkage `s_sint = 1 − (1 − s)/(1 + ε̄)` of a total shrinkage `s` (1 −
/// L/L0 of the extents) with the mean thermal strain `eps` [1].
pub fn sintering_shrinkage(s: f64, eps: f64) -> f64 {
    1.0 - (1.0 - s) / (1.0 + eps)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::{Quantity, Table};

    #[test]
    fn strain_is_the_integral_of_alpha_and_zero_at_the_reference() {
        let c = Expansion::Constant(1.5e-5);
        assert_eq!(c.strain(300.0, 300.0), 0.0);
        assert!((c.strain(300.0, 1300.0) - 1.5e-2).abs() < 1e-15);
        // α = 1e-5 + 1e-8 (T − 300) over [300, 1300]: ε = 1e-5·ΔT + 0.5e-8·ΔT²
        let t = Table::new(&[[300.0, 1e-5], [1300.0, 2e-5]], "a", Quantity::ThermalExpansion).unwrap();
        let e = Expansion::Table(t);
        assert_eq!(e.strain(500.0, 500.0), 0.0);
        let want = 1e-5 * 700.0 + 0.5e-8 * 700.0 * 700.0;
        assert!((e.strain(300.0, 1000.0) - want).abs() < 1e-15, "{}", e.strain(300.0, 1000.0));
        assert!((e.strain(1000.0, 300.0) + want).abs() < 1e-15);
    }

    #[test]
    fn sintering_shrinkage_undoes_the_thermal_strain() {
        // a body that expanded by ε without sintering: total shrinkage −ε, sintering shrinkage 0
        let eps = 0.0123;
        assert!(sintering_shrinkage(-eps, eps).abs() < 1e-16);
        // (1 − s) = (1 − s_sint)(1 + ε)
        let (ss, e) = (0.03, 0.015);
        let s = 1.0 - (1.0 - ss) * (1.0 + e);
        assert!((sintering_shrinkage(s, e) - ss).abs() < 1e-15);
    }
}

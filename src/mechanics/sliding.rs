//! Viscous grain-boundary sliding at the necks (docs/mechanics.md (B24)–(B28)).
//!
//! The two shear springs of each link (`K_link[0]`, `K_link[1]`, (B5)) become Maxwell elements:
//! the elastic shear spring `k_t` in series with a dashpot of the tangential viscosity `η_t`
//! (B24) of the neck. Integrated by backward Euler over a step Δt (B25)–(B27): the step sees the
//! effective stiffness `φ·k_t`, `φ = η_t/(η_t + k_t·Δt)`, and the release `(1 − φ)·P_t` of the
//! stored tangential link force `P_t` as a load; after the step `P_t ← φ·(P_t + k_t·Δε_t)`.
//! Axial, bending and torsion springs stay elastic (no source gives their relaxation,
//! docs/decisions-mechanics.md).

use crate::error::{ConfigError, Error};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// The tangential viscosity of a neck (B24) [N·s/m]:
/// `η_t = f·π·a²·R*²·k_B·T / (8·Ω·δD_gb)`, with `R* = 2R_A·R_B/(R_A + R_B)` (= R for equal
/// spheres), `a` the neck radius [m], `omega` the atomic volume Ω [m³], `delta_d_gb` the grain
/// boundary's δ·D_gb [m³/s] at the contact temperature `temperature` [K] and `factor` f [1] the
/// sliding factor (`mechanics.sliding_factor`). The tangential term of the Bouvard–McMeeking /
/// Parhami–McMeeking contact law as DEM sintering codes write it (MUSEN `ModelPPSintering`).
pub fn tangential_viscosity(factor: f64, a: f64, r_a: f64, r_b: f64, omega: f64, delta_d_gb: f64, temperature: f64) -> f64 {
    let r_star = 2.0 * r_a * r_b / (r_a + r_b);
    factor * PI * a * a * r_star * r_star * crate::units::BOLTZMANN * temperature / (8.0 * omega * delta_d_gb)
}

/// The Maxwell factor of (B25): `φ = η/(η + k·Δt)` [1] for a spring `k` [N/m], a dashpot `η`
/// [N·s/m] and a step `dt` [s]; 1 for `dt = 0` or `η = ∞` (the elastic link), 0 for `η = 0`.
pub fn maxwell_factor(k: f64, eta: f64, dt: f64) -> f64 {
    if eta.is_infinite() {
        1.0
    } else if eta == 0.0 {
        0.0
    } else {
        eta / (eta + k * dt)
    }
}

/// The sliding data of one step: the tangential viscosity of every bond, the step and the stored
/// tangential link forces at the step's start.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Relaxation {
    /// Step Δt [s] (≥ 0).
    pub dt: f64,
    /// η_t per bond in bond order (B24) [N·s/m] (> 0; +∞: no grain-boundary transport, the
    /// elastic link).
    pub viscosity: Vec<f64>,
    /// The stored tangential link force P_t per bond, global axes [N] (its component along the
    /// step's e3 is dropped: the frame turned); empty: none stored (a load distribution (P3),
    /// which sees the effective links only).
    pub stored: Vec<Vector3<f64>>,
}

impl Relaxation {
    /// Checks lengths and values against `bonds` bonds.
    pub fn validate(&self, bonds: usize) -> Result<(), Error> {
        if !(self.dt.is_finite() && self.dt >= 0.0) {
            return Err(ConfigError::invalid(format!("mechanics sliding: step {} s is not finite and ≥ 0", self.dt)).into());
        }
        if self.viscosity.len() != bonds || !(self.stored.is_empty() || self.stored.len() == bonds) {
            return Err(ConfigError::invalid(format!(
                "mechanics sliding: {} viscosities and {} stored forces given for {bonds} bonds",
                self.viscosity.len(),
                self.stored.len()
            ))
            .into());
        }
        if let Some(c) = self.viscosity.iter().position(|v| !(*v > 0.0)) {
            return Err(crate::error::ModelError::new(format!(
                "mechanics sliding: tangential viscosity of contact {c} = {} N s/m is not positive",
                self.viscosity[c]
            ))
            .into());
        }
        if let Some(c) = self.stored.iter().position(|f| !f.iter().all(|v| v.is_finite())) {
            return Err(crate::error::ModelError::new(format!("mechanics sliding: stored tangential force of contact {c} is not finite")).into());
        }
        Ok(())
    }

    /// The stored tangential force of bond `c` perpendicular to `e3` [N] (zero when none stored).
    pub fn stored_tangential(&self, c: usize, e3: &Vector3<f64>) -> Vector3<f64> {
        match self.stored.get(c) {
            Some(f) => f - e3 * f.dot(e3),
            None => Vector3::zeros(),
        }
    }
}

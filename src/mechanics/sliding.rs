//! Viscous grain-boundary sliding, rolling and twisting at the necks (docs/mechanics.md
//! (B24)–(B30)).
//!
//! The two shear springs of each link (`K_link[0]`, `K_link[1]`, (B5)) become Maxwell elements:
//! the elastic shear spring `k_t` in series with a dashpot of the tangential viscosity `η_t`
//! (B24) of the neck. Integrated by backward Euler over a step Δt (B25)–(B27): the step sees the
//! effective stiffness `φ·k_t`, `φ = η_t/(η_t + k_t·Δt)`, and the release `(1 − φ)·P_t` of the
//! stored tangential link force `P_t` as a load; after the step `P_t ← φ·(P_t + k_t·Δε_t)`.
//! With rolling viscosities the bending and torsion springs relax the same way (B30), with a
//! stored link moment; a load distribution may instead be solved as a viscous network (B29). The
//! axial spring stays the elastic penalty: its viscous compliance is the 7-DOF model's.

use crate::error::{ConfigError, Error};
use nalgebra::Vector3;

/// The tangential viscosity of a neck (B24) [N·s/m]: `η_t = f·(R*/a)²/M_c`, with
/// `R* = 2R_A·R_B/(R_A + R_B)` (= R for equal spheres), `a` the neck radius [m], `mobility` the
/// contact's normal mobility M_c of the 7-DOF model (docs/diffusion7.md (M13)) [m/(N·s)] at its
/// own state and temperature, and `factor` f [1] (`mechanics.sliding_factor`). The ratio
/// η_t/η_n = f·(R*/a)² of the tangential to the normal viscosity is that of the
/// Bouvard–McMeeking / Parhami–McMeeking contact law (tangential f·π a² R*²/(8Δ_b), normal
/// π a⁴/(8Δ_b)); the normal viscosity η_n = 1/M_c is the contact's own. +∞ for M_c = 0 (no
/// grain-boundary transport: the elastic link).
pub fn tangential_viscosity(factor: f64, a: f64, r_a: f64, r_b: f64, mobility: f64) -> f64 {
    if mobility <= 0.0 {
        return f64::INFINITY;
    }
    let r_star = 2.0 * r_a * r_b / (r_a + r_b);
    factor * (r_star / a) * (r_star / a) / mobility
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
    /// A load distribution's viscous network (B29): per bond the link viscosities `[shear,
    /// shear, axial, bending, bending, torsion]` ([N·s/m] ×3, [N·m·s] ×3, the order of
    /// [`crate::mechanics::link_stiffness`]) that replace the link stiffnesses of the solve; empty:
    /// the Maxwell links (B25).
    pub network: Vec<[f64; 6]>,
    /// The rolling and twisting viscosities `[η_b, η_tw]` per bond (B30) [N·m·s]: the bending
    /// and torsion springs become Maxwell elements too; empty: they stay elastic.
    pub rolling: Vec<[f64; 2]>,
    /// The stored link moment per bond, global axes [N·m] (bending ⟂ e3, torsion ∥ e3, split
    /// along the step's e3); empty: none stored.
    pub stored_moment: Vec<Vector3<f64>>,
}

/// The viscosities of every neck of a step (docs/mechanics.md (B24), (B29), (B30)), built by the
/// caller from each contact's 7-DOF state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NeckViscosities {
    /// η_t per contact (B24) [N·s/m].
    pub tangential: Vec<f64>,
    /// `[η_b, η_tw]` per contact (B30) [N·m·s].
    pub rolling: Vec<[f64; 2]>,
    /// The viscous network of a load distribution (B29); empty when a contact has no transport.
    pub network: Vec<[f64; 6]>,
}

/// The rolling (bending) and twisting viscosities of a neck (B30) [N·m·s]:
/// `[a²/(12·M_c), η_t·a²/2]`, M_c the normal mobility [m/(N·s)], `eta_t` of (B24) [N·s/m], `a`
/// the neck radius [m]; +∞ each without transport (M_c ≤ 0 or η_t = ∞).
pub fn rolling_viscosities(eta_t: f64, mobility: f64, a: f64) -> [f64; 2] {
    let bend = if mobility > 0.0 { a * a / (12.0 * mobility) } else { f64::INFINITY };
    let twist = if eta_t.is_finite() { eta_t * a * a / 2.0 } else { f64::INFINITY };
    [bend, twist]
}

/// The link viscosities of a neck in the viscous network of a load distribution (B29):
/// `[η_t, η_t, η_n, η_n·a²/12, η_n·a²/12, η_t·a²/2]` with the normal viscosity `η_n = 1/M_c` of
/// the 7-DOF model (`mobility` M_c [m/(N·s)], docs/diffusion7.md (M13)), the tangential `eta_t`
/// of (B24) [N·s/m] and the neck radius `a` [m]; None when M_c ≤ 0 or η_t is not finite (a
/// contact without transport: no viscous network).
pub fn network_links(eta_t: f64, mobility: f64, a: f64) -> Option<[f64; 6]> {
    if !(mobility > 0.0 && eta_t.is_finite() && eta_t > 0.0 && a > 0.0) {
        return None;
    }
    let [bend, twist] = rolling_viscosities(eta_t, mobility, a);
    Some([eta_t, eta_t, 1.0 / mobility, bend, bend, twist])
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
        if !(self.network.is_empty() || self.network.len() == bonds) {
            return Err(ConfigError::invalid(format!("mechanics sliding: {} network links given for {bonds} bonds", self.network.len())).into());
        }
        if let Some(c) = self.network.iter().position(|l| !l.iter().all(|v| v.is_finite() && *v > 0.0)) {
            return Err(crate::error::ModelError::new(format!(
                "mechanics sliding: viscous link of contact {c} is not positive and finite: {:?}",
                self.network[c]
            ))
            .into());
        }
        if !(self.rolling.is_empty() || self.rolling.len() == bonds) || !(self.stored_moment.is_empty() || self.stored_moment.len() == bonds) {
            return Err(ConfigError::invalid(format!(
                "mechanics sliding: {} rolling viscosities and {} stored moments given for {bonds} bonds",
                self.rolling.len(),
                self.stored_moment.len()
            ))
            .into());
        }
        if let Some(c) = self.rolling.iter().position(|v| !(v[0] > 0.0 && v[1] > 0.0)) {
            return Err(crate::error::ModelError::new(format!(
                "mechanics sliding: rolling viscosities of contact {c} = {:?} N m s are not positive",
                self.rolling[c]
            ))
            .into());
        }
        if let Some(c) = self.stored_moment.iter().position(|f| !f.iter().all(|v| v.is_finite())) {
            return Err(crate::error::ModelError::new(format!("mechanics sliding: stored moment of contact {c} is not finite")).into());
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

    /// The stored link moment of bond `c` [N·m] (zero when none stored).
    pub fn stored_moment(&self, c: usize) -> Vector3<f64> {
        self.stored_moment.get(c).copied().unwrap_or_else(Vector3::zeros)
    }

    /// The factors (B25), (B30) of bond `c`'s six elastic link springs `k` (order of
    /// [`crate::mechanics::link_stiffness`]): `[φ, φ, 1, φ_b, φ_b, φ_tw]` [1].
    pub fn link_factors(&self, c: usize, k: &[f64; 6]) -> [f64; 6] {
        let phi = maxwell_factor(k[0], self.viscosity[c], self.dt);
        let [pb, pt] = self.rolling_factors(c, k[3], k[5]);
        [phi, phi, 1.0, pb, pb, pt]
    }

    /// The Maxwell factors `[φ_b, φ_tw]` (B25) of bond `c`'s bending and torsion springs `k_b`,
    /// `k_tw` [N·m]: 1 each without rolling viscosities (elastic).
    pub fn rolling_factors(&self, c: usize, k_b: f64, k_tw: f64) -> [f64; 2] {
        match self.rolling.get(c) {
            Some(v) => [maxwell_factor(k_b, v[0], self.dt), maxwell_factor(k_tw, v[1], self.dt)],
            None => [1.0, 1.0],
        }
    }
}

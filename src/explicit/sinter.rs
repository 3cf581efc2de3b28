//! The explicit sintering laws as [`ContactModel`]s of the velocity-Verlet driver
//! (docs/luding.md, docs/frenkel.md; issue 6 item "plug both laws into the driver").
//!
//! - [`LudingLaw`]: Luding, Manetsberger & Müllers (2005), the kernels of [`crate::models::luding`]
//!   (eqs. 4–24): per-contact `Copy` state δ_max, δ_0, ξ, k1(T,t) ([`LudingSlot`]);
//! - [`FrenkelLaw`]: MercuryDPM's SinterNormal family, the kernels of [`crate::models::frenkel`]
//!   (docs/frenkel.md): per-contact state δ_p, ξ ([`FrenkelState`]).
//!
//! Both override [`ContactModel::contact`]: the contact temperature is the law's mean
//! (`contact_temperature`: arithmetic by default, harmonic for `temperature_frenkel`, docs/heat-model.md (H16)) of the
//! two particles' temperatures `Particles::temperature` [K], which the caller keeps current (a
//! prescribed profile or the heat network, [`crate::kinds::explicit_sinter`]); the time step enters the
//! relaxation of k1(T,t) (eqs. 11–12) and the plastic rate. The driver's tangential spring ξ is
//! handed to the law's own tangential rule (Luding eqs. 14–24, the cohesion-shifted Coulomb limit),
//! so the driver's `Settings::friction` is not used by these laws; the law's friction is.
//!
//! Particle–wall contacts (through [`ContactModel::normal`], fresh state each step) are cold,
//! elastic and unsintered: a linear spring with the un/reloading stiffness (Luding's k2, SinterNormal's
//! k2_max) and the law's normal damping. The paper does not specify the wall law; walls carry no
//! sintering history (decisions L20).
//!
//! Energy: the driver's account (`Energy`) counts the viscous and sliding dissipation and, as
//! elastic energy, `f_e²/(2k)` of the current un/reloading line; the plastic work of the
//! hysteretic branches (loading, cohesive shift, δ_p growth) is not counted, so `balance()` is not
//! conserved with these laws.

use super::law::{ContactCtx, ContactModel, ContactOut, NormalOut, PairGeom, TangentialParams};
use crate::models::frenkel::{self, FrenkelKinematics, FrenkelParams, FrenkelState};
use crate::models::luding::{self, ContactKinematics, LudingParams, LudingState};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// Luding's law in the driver.
#[derive(Debug, Clone, PartialEq)]
pub struct LudingLaw {
    pub params: LudingParams,
    /// Relaxation time t_0 [s] used this step (eqs. 11–12); the protocol shortens it while
    /// sintering (Table 1: 10³ s, 0.1 s for t_sinter ≤ t < t_cool).
    pub t0: f64,
}

impl LudingLaw {
    pub fn new(params: LudingParams) -> Self {
        let t0 = params.t0;
        LudingLaw { params, t0 }
    }
}

/// Per-contact state of [`LudingLaw`]: `None` until the contact first closes (then k1(T,t) = k1(T)
/// of that step's contact temperature, docs/luding.md: a new contact starts with k1(T,t) = k1(T)).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LudingSlot(pub Option<LudingState>);

impl ContactModel for LudingLaw {
    type State = LudingSlot;

    /// Particle–wall law: `f = k2·δ + γ_0·δ̇` (cold elastic wall, module docs).
    #[inline]
    fn normal(&self, g: &PairGeom, _: &mut LudingSlot) -> NormalOut {
        let k = self.params.k2;
        let fd = self.params.gamma_n * g.overlap_rate;
        NormalOut { force: k * g.overlap + fd, damping_force: fd, elastic_energy: 0.5 * k * g.overlap * g.overlap, stiffness: k, damping: self.params.gamma_n }
    }

    /// Half-period on the stiffest (k2) line, `t_c = π/√(k2/m − η_0²)` (eq. 6).
    fn collision_time(&self, mass: f64, _radius: f64, _v: f64) -> f64 {
        let eta = self.params.gamma_n / (2.0 * mass);
        let w2 = self.params.k2 / mass - eta * eta;
        if w2 > 0.0 { PI / w2.sqrt() } else { PI * (mass / self.params.k2).sqrt() }
    }

    /// [`luding::contact_force`] at the contact temperature `contact_temperature.of(T_i, T_j)`.
    #[inline]
    fn contact(&self, c: &ContactCtx, state: &mut LudingSlot, xi: &mut Vector3<f64>, t: &TangentialParams) -> ContactOut {
        let p = &self.params;
        let temp = p.contact_temperature.of(c.temperature_i, c.temperature_j);
        let mut s = state.0.unwrap_or_else(|| LudingState::new(p, temp));
        s.xi = *xi;
        let kin = ContactKinematics { normal: c.normal, overlap: c.geom.overlap, overlap_rate: c.geom.overlap_rate, surface_velocity: c.surface_velocity };
        let f = luding::contact_force(p, &mut s, &kin, temp, self.t0, t.dt);
        *xi = s.xi;
        state.0 = Some(s);
        let k2 = p.k2_of(s.delta_max);
        let fe = f.normal_parts.elastic;
        let kt = p.kt_of(s.delta_max);
        let vt = c.tangential_velocity;
        let diss_t = if f.sliding { (-f.tangential.dot(&vt)).max(0.0) } else { p.gamma_t * vt.norm_squared() };
        ContactOut {
            normal_force: f.normal,
            tangential: f.tangential,
            elastic_energy: 0.5 * fe * fe / k2 + 0.5 * kt * xi.norm_squared(),
            dissipation: f.normal_parts.damping * c.geom.overlap_rate + diss_t,
        }
    }
}

/// The SinterNormal family in the driver.
#[derive(Debug, Clone, PartialEq)]
pub struct FrenkelLaw {
    pub params: FrenkelParams,
}

impl ContactModel for FrenkelLaw {
    type State = FrenkelState;

    /// Particle–wall law: `f = k2_max·δ + γ·δ̇` (cold elastic wall, no pull, module docs).
    #[inline]
    fn normal(&self, g: &PairGeom, _: &mut FrenkelState) -> NormalOut {
        let k = self.params.k2_max;
        let fd = self.params.damping * g.overlap_rate;
        NormalOut { force: k * g.overlap + fd, damping_force: fd, elastic_energy: 0.5 * k * g.overlap * g.overlap, stiffness: k, damping: self.params.damping }
    }

    /// Half-period on the stiffest (k2_max) line.
    fn collision_time(&self, mass: f64, _radius: f64, _v: f64) -> f64 {
        let eta = self.params.damping / (2.0 * mass);
        let w2 = self.params.k2_max / mass - eta * eta;
        if w2 > 0.0 { PI / w2.sqrt() } else { PI * (mass / self.params.k2_max).sqrt() }
    }

    /// [`frenkel::contact_force`] at the contact temperature `contact_temperature.of(T_i, T_j)`.
    #[inline]
    fn contact(&self, c: &ContactCtx, state: &mut FrenkelState, xi: &mut Vector3<f64>, t: &TangentialParams) -> ContactOut {
        let p = &self.params;
        let temp = p.contact_temperature.of(c.temperature_i, c.temperature_j);
        state.xi = *xi;
        let kin = FrenkelKinematics {
            normal: c.normal,
            overlap: c.geom.overlap,
            overlap_rate: c.geom.overlap_rate,
            surface_velocity: c.surface_velocity,
            reduced_radius: c.geom.radius,
        };
        let f = frenkel::contact_force(p, state, &kin, temp, t.dt);
        *xi = state.xi;
        let k = p.unloading_stiffness(c.geom.radius, state.delta_p);
        let fe = f.normal.elastic;
        let vt = c.tangential_velocity;
        let diss_t = if f.tangential.sliding {
            (-f.tangential.force.dot(&vt)).max(0.0)
        } else if f.tangential.limit > 0.0 {
            p.tangential_damping * vt.norm_squared()
        } else {
            0.0
        };
        ContactOut {
            normal_force: f.normal.total,
            tangential: f.tangential.force,
            elastic_energy: 0.5 * fe * fe / k + 0.5 * p.tangential_stiffness * xi.norm_squared(),
            dissipation: f.normal.damping * c.geom.overlap_rate + diss_t,
        }
    }
}

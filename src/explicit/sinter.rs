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
use crate::config::ranges::Range;
use crate::error::{ConfigError, Error};
use crate::models::frenkel::{self, FrenkelKinematics, FrenkelParams, FrenkelState};
use crate::models::luding::{self, ContactKinematics, LudingParams, LudingState};
use nalgebra::Vector3;
use serde::Serialize;
use serde::de::DeserializeOwned;
use std::f64::consts::PI;

/// Everything the sintering protocol ([`crate::kinds::explicit_sinter`]) needs of a law beyond
/// [`ContactModel`]: its case facts (name, range table, state column) and its hooks. Adding a law:
/// its kernels and parameters in their own file, this impl, and one line in the list of laws of
/// the `explicit_sinter` kind (docs/architecture.md).
pub trait SinterLaw: ContactModel<State: Serialize + DeserializeOwned> + Clone + std::fmt::Debug + 'static {
    /// `model = "…"` of the case, also the name of the law's case section `[…]`.
    const NAME: &'static str;
    /// The range table of the section's keys (`sinterdem keys`, `sinterdem check`).
    const RANGES: &'static [Range];
    /// The history series' column of [`Self::state_mean`] and the title of its plot.
    const STATE: StateColumn;
    /// The law from its case section (`None`: the case has none) and the case values it reads.
    fn from_case(section: Option<toml::Value>, case: &LawInputs) -> Result<Self, Error>;
    /// Switches the sintering-time settings on (Luding: t_0 ← t0_sinter) or off.
    fn set_sintering(&mut self, on: bool, t0_sinter: Option<f64>);
    /// Sets the particle friction coefficient (0 during preparation).
    fn set_friction(&mut self, mu: f64);
    /// The law's friction coefficient as given.
    fn friction(&self) -> f64;
    /// Luding's thermal expansion (eq. 9): the radius at `temperature` of a particle whose radius is
    /// `r_ref` at `t_ref` [K]; identity for laws without expansion.
    fn radius(&self, r_ref: f64, t_ref: f64, temperature: f64) -> f64;
    /// A scalar state summary over the contacts ([`Self::STATE`]).
    fn state_mean(states: &[((u32, u32), f64, Self::State)]) -> f64;
}

/// The case values a law's construction reads besides its own section.
#[derive(Debug, Clone, Copy)]
pub struct LawInputs {
    /// `sample.mean_radius` [m].
    pub mean_radius: f64,
    /// `protocol.t0_sinter` [s] as given.
    pub t0_sinter: Option<f64>,
}

/// The column of a law's contact-state summary in the history series, and its plot.
#[derive(Debug, Clone, Copy)]
pub struct StateColumn {
    /// Column name with its unit suffix (`k1_t_mean_N_per_m`).
    pub name: &'static str,
    /// SI unit (`"1"`: dimensionless).
    pub unit: &'static str,
    /// Title of the plot of the column over time.
    pub title: &'static str,
    /// The quantity in words for the plot's axis, without its unit (`mean plastic overlap`).
    pub quantity: &'static str,
}

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

impl SinterLaw for LudingLaw {
    const NAME: &'static str = "luding";
    const RANGES: &'static [Range] = luding::RANGES;
    const STATE: StateColumn =
        StateColumn { name: "k1_t_mean_N_per_m", unit: "N/m", title: "mean loading stiffness k1(T, t) of the contacts", quantity: "mean loading stiffness k1" };
    /// `[luding]` may be left out (the defaults of Luding et al. 2005, Table 1).
    fn from_case(section: Option<toml::Value>, case: &LawInputs) -> Result<Self, Error> {
        let v = section.unwrap_or_else(|| toml::Value::Table(toml::Table::new()));
        Ok(LudingLaw::new(LudingParams::from_value(v, case.mean_radius)?))
    }
    fn set_sintering(&mut self, on: bool, t0_sinter: Option<f64>) {
        self.t0 = if on { t0_sinter.unwrap_or(self.params.t0) } else { self.params.t0 };
    }
    fn set_friction(&mut self, mu: f64) {
        self.params.friction = mu;
    }
    fn friction(&self) -> f64 {
        self.params.friction
    }
    fn radius(&self, r_ref: f64, t_ref: f64, temperature: f64) -> f64 {
        if self.params.expansion == 0.0 { r_ref } else { self.params.radius_from(r_ref, t_ref, temperature) }
    }
    fn state_mean(states: &[((u32, u32), f64, LudingSlot)]) -> f64 {
        let v: Vec<f64> = states.iter().filter_map(|(_, _, s)| s.0.map(|s| s.k1_t)).collect();
        // no (bonded) contact: 0, like the force columns of a row without contacts
        if v.is_empty() { 0.0 } else { v.iter().sum::<f64>() / v.len() as f64 }
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

impl SinterLaw for FrenkelLaw {
    const NAME: &'static str = "frenkel";
    const RANGES: &'static [Range] = frenkel::RANGES;
    const STATE: StateColumn =
        StateColumn { name: "delta_p_mean_m", unit: "m", title: "mean plastic overlap of the contacts", quantity: "mean plastic overlap" };
    /// `[frenkel]` is required; `protocol.t0_sinter` (Luding's) is refused.
    fn from_case(section: Option<toml::Value>, case: &LawInputs) -> Result<Self, Error> {
        let v = section.ok_or_else(|| ConfigError::inconsistent("frenkel", "model = \"frenkel\" needs a [frenkel] section"))?;
        if case.t0_sinter.is_some() {
            return Err(ConfigError::inconsistent("protocol.t0_sinter", "is Luding's relaxation time; model = \"frenkel\" does not use it").into());
        }
        Ok(FrenkelLaw { params: FrenkelParams::from_value(v)? })
    }
    fn set_sintering(&mut self, _on: bool, _t0: Option<f64>) {}
    fn set_friction(&mut self, mu: f64) {
        self.params.friction = mu;
    }
    fn friction(&self) -> f64 {
        self.params.friction
    }
    fn radius(&self, r_ref: f64, _t_ref: f64, _temperature: f64) -> f64 {
        r_ref
    }
    fn state_mean(states: &[((u32, u32), f64, FrenkelState)]) -> f64 {
        if states.is_empty() { 0.0 } else { states.iter().map(|(_, _, s)| s.delta_p).sum::<f64>() / states.len() as f64 }
    }
}

//! The SinterNormal contact law of MercuryDPM and its plastic-overlap rates (`model = "frenkel"`,
//! docs/frenkel.md): an elastic-plastic normal force whose unloading stiffness grows
//! with the plastic overlap δ_p, an adhesive sintering pull, and a rate law for δ_p:
//! `constant` (Frenkel's viscous sintering), `temperature_frenkel` (the same with k_s(T)),
//! `parhami_mcmeeking` (δ³ ∝ t) and `bouvard_mcmeeking` (viscous grain-boundary neck, as MUSEN/Kratos).
//!
//! Pure per-contact kernels for the explicit driver: [`FrenkelParams`] (from the `[frenkel]` case
//! section), per-contact `Copy` state [`FrenkelState`] (δ_p, ξ), and per step
//! [`normal_force`] (loading rule, elastic force, cohesive floor, damping, pull), then
//! [`advance_plastic`] (δ_p ← δ_p + ṙ·Δt), or both plus an optional tangential spring through
//! [`contact_force`]. Signs as in [`crate::models::luding`]: n from j to i, δ = r_i + r_j − |x_i − x_j|,
//! δ̇ = −(v_i − v_j)·n, normal force positive repulsive on i along +n. SI units, kelvin.
//!
//! [`free_sintering_pair`] integrates a free two-particle pair (velocity-Verlet in the overlap) for
//! the closed-form checks of the tests.

use crate::config::from_value;
use crate::config::ranges::{Range, c, o, p};

/// Checks a key of this law's [`RANGES`] (then the shared keys).
fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(RANGES, key, v)
}
use crate::error::{ConfigError, ModelError};
use crate::models::luding::{TangentialForce, tangential_spring};
use crate::units::{BOLTZMANN, GAS_CONSTANT};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Range table of the `[frenkel]` keys (listed through its law's entry in `kinds::explicit_sinter::laws::LAWS`).
pub static RANGES: &[Range] = &[
    p("frenkel.k1", 0.0, 1e12, "N/m", "loading stiffness k1"),
    p("frenkel.k2_max", 0.0, 1e12, "N/m", "largest unloading stiffness k2_max (> k1)"),
    c("frenkel.kc", 0.0, 1e12, "N/m", "cohesion stiffness kc of the floor -kc delta"),
    o("frenkel.penetration_depth_max", 0.0, 1.0, "1", "penetration-depth limit phi (d_fluid_0 = k2_max/(k2_max - k1) phi D*)"),
    c("frenkel.damping", 0.0, 1e6, "kg/s", "normal viscous damping gamma"),
    c("frenkel.sinter_adhesion", 0.0, 1e6, "N/m", "sinter adhesion s_a (pull f_a = s_a D*)"),
    c("frenkel.sinter_rate", 0.0, 1e6, "1/s", "sinter rate k_s"),
    o("frenkel.surface_energy", 0.0, 20.0, "J/m^2", "surface energy gamma_s"),
    o("frenkel.viscosity", 0.0, 1e20, "Pa s", "viscosity eta (constant: k_s = 3 gamma_s/(16 eta R_red))"),
    o("frenkel.viscosity_prefactor", 0.0, 1e20, "Pa s", "eta_0 of eta(T) = eta_0 exp(Q/(R T))"),
    c("frenkel.activation_energy", 0.0, 2e6, "J/mol", "Q of eta(T) = eta_0 exp(Q/(R T))"),
    c("frenkel.rate_table.temperature", 1.0, 1e4, "K", "temperature column of the k_s(T) table"),
    c("frenkel.rate_table.sinter_rate", 0.0, 1e6, "1/s", "k_s column of the k_s(T) table"),
    o("frenkel.atomic_volume", 0.0, 1e-27, "m^3", "atomic volume Omega (bouvard_mcmeeking)"),
    o("frenkel.gb_thickness", 0.0, 1e-7, "m", "grain-boundary thickness delta_gb (bouvard_mcmeeking)"),
    c("frenkel.gb_diffusion_prefactor", 0.0, 1e20, "m^2/s", "D0_gb of D_gb = D0_gb exp(-Q_gb/(R T)) (bouvard_mcmeeking)"),
    c("frenkel.gb_activation_energy", 0.0, 2e6, "J/mol", "Q_gb (bouvard_mcmeeking)"),
    c("frenkel.friction", 0.0, 10.0, "1", "Coulomb friction coefficient of the tangential spring"),
    c("frenkel.tangential_stiffness", 0.0, 1e12, "N/m", "tangential spring stiffness k_t"),
    c("frenkel.tangential_damping", 0.0, 1e6, "kg/s", "tangential viscous damping gamma_t"),
];

/// How a contact's temperature follows from its two particles' temperatures [K]
/// (docs/heat-model.md (H16)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MeanTemperature {
    /// (T_i + T_j)/2: the neck mid-plane of one material.
    #[default]
    Arithmetic,
    /// 2·T_i·T_j/(T_i + T_j), as MercuryDPM's temperature-dependent Frenkel rate.
    Harmonic,
}

impl MeanTemperature {
    /// The contact temperature [K] of particle temperatures `t_i`, `t_j` [K].
    pub fn of(self, t_i: f64, t_j: f64) -> f64 {
        match self {
            MeanTemperature::Arithmetic => 0.5 * (t_i + t_j),
            MeanTemperature::Harmonic => {
                let s = t_i + t_j;
                if s > 0.0 { 2.0 * t_i * t_j / s } else { 0.0 }
            }
        }
    }
}

/// `sinter_type`: the plastic-overlap rate (docs/frenkel.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SinterType {
    #[default]
    Constant,
    TemperatureFrenkel,
    ParhamiMcmeeking,
    BouvardMcmeeking,
}

/// `loading`: the virgin-loading rule for δ_p.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Loading {
    /// MercuryDPM's source: δ_p ← max(δ_p, min(δ/(1 + 1/(dk·δ)), d_fluid_0)).
    #[default]
    Mercury,
    /// δ_p ← max(δ_p, min(δ − k1·d_fluid_0/(k2_max − k1), d_fluid_0)) ≥ 0: k̂(δ − δ_p) = k1·δ exactly.
    Exact,
}

/// `mercury_variant`: which MercuryDPM text defines the fluid overlap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MercuryVariant {
    /// `SinterInteraction.cc`: d_fluid_0 = k2_max/(k2_max − k1)·φ·D*.
    #[default]
    Source,
    /// The documentation page and older releases: d_fluid_0 = φ·D*.
    DocPage,
}

/// The `[frenkel]` case section as written.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrenkelSpec {
    /// Loading stiffness k1 [N/m].
    pub k1: f64,
    /// Largest unloading stiffness k2_max [N/m] (> k1).
    pub k2_max: f64,
    /// Cohesion stiffness kc [N/m] (default 0).
    #[serde(default)]
    pub kc: f64,
    /// Penetration-depth limit φ [1], 0 < φ < 1.
    pub penetration_depth_max: f64,
    /// Normal viscous damping γ [kg/s] (default 0).
    #[serde(default)]
    pub damping: f64,
    /// Sinter adhesion s_a [N/m] (pull f_a = s_a·D*), > 0 when a rate is active.
    #[serde(default)]
    pub sinter_adhesion: f64,
    /// Sinter rate k_s [1/s] (constant, parhami_mcmeeking).
    pub sinter_rate: Option<f64>,
    #[serde(default)]
    pub sinter_type: SinterType,
    #[serde(default)]
    pub loading: Loading,
    #[serde(default)]
    pub mercury_variant: MercuryVariant,
    /// Contact temperature rule (default: harmonic for temperature_frenkel, arithmetic otherwise).
    pub contact_temperature: Option<MeanTemperature>,
    /// Surface energy γ_s [J/m²] (k_s from a viscosity; bouvard_mcmeeking's driving force).
    pub surface_energy: Option<f64>,
    /// Viscosity η [Pa·s] (constant: k_s = 3γ_s/(16·η·R_red)).
    pub viscosity: Option<f64>,
    /// η_0 [Pa·s] of η(T) = η_0·exp(Q/(R_gas·T)) (temperature_frenkel).
    pub viscosity_prefactor: Option<f64>,
    /// Q [J/mol] of η(T) (temperature_frenkel).
    pub activation_energy: Option<f64>,
    /// Table of [T K, k_s 1/s] rows, T strictly increasing, linear between, held outside (temperature_frenkel).
    pub rate_table: Option<Vec<[f64; 2]>>,
    /// Atomic volume Ω [m³] (bouvard_mcmeeking).
    pub atomic_volume: Option<f64>,
    /// Grain-boundary thickness δ_gb [m] (bouvard_mcmeeking).
    pub gb_thickness: Option<f64>,
    /// D0_gb [m²/s] (bouvard_mcmeeking).
    pub gb_diffusion_prefactor: Option<f64>,
    /// Q_gb [J/mol] (bouvard_mcmeeking).
    pub gb_activation_energy: Option<f64>,
    /// Coulomb friction coefficient μ [1] of the optional tangential spring (default 0).
    #[serde(default)]
    pub friction: f64,
    /// Tangential spring stiffness k_t [N/m] (default 0).
    #[serde(default)]
    pub tangential_stiffness: f64,
    /// Tangential damping γ_t [kg/s] (default 0).
    #[serde(default)]
    pub tangential_damping: f64,
}

/// Where the sinter rate k_s comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum SinterRateSource {
    /// A given k_s [1/s].
    Given(f64),
    /// Frenkel with sinterdem's neck: k_s = 3γ_s/(16·η·R_red) (γ_s [J/m²], η [Pa·s]).
    Viscous { surface_energy: f64, viscosity: f64 },
}

/// The resolved rate law.
#[derive(Debug, Clone, PartialEq)]
pub enum Rate {
    /// ṙ = 2·F·k_s/s_a.
    Constant(SinterRateSource),
    /// ṙ = 2·F·k_s(T)/s_a, k_s(T) from a table [(T K, k_s 1/s)].
    FrenkelTable(Vec<(f64, f64)>),
    /// ṙ = 2·F·k_s(T)/s_a, k_s(T) = 3γ_s/(16·η_0·e^(Q/(R_gas T))·R_red).
    FrenkelArrhenius { surface_energy: f64, viscosity_prefactor: f64, activation_energy: f64 },
    /// ṙ = F·k_s/(0.375·s_a·(δ/D*)²).
    ParhamiMcmeeking(f64),
    /// ṙ = F/η_c, η_c = π a⁴/(8Δ), a² = 4R_red·δ, Δ = Ω·δ_gb·D_gb(T)/(k_B T); pull f_a = 2.25π·R_red·γ_s.
    BouvardMcmeeking { surface_energy: f64, atomic_volume: f64, gb_thickness: f64, gb_diffusion_prefactor: f64, gb_activation_energy: f64 },
}

/// Validated parameters of the SinterNormal law.
#[derive(Debug, Clone, PartialEq)]
pub struct FrenkelParams {
    /// k1 [N/m].
    pub k1: f64,
    /// k2_max [N/m].
    pub k2_max: f64,
    /// kc [N/m].
    pub kc: f64,
    /// φ [1].
    pub phi: f64,
    /// γ [kg/s].
    pub damping: f64,
    /// s_a [N/m].
    pub sinter_adhesion: f64,
    pub rate: Rate,
    pub loading: Loading,
    pub mercury_variant: MercuryVariant,
    pub contact_temperature: MeanTemperature,
    /// μ [1], k_t [N/m], γ_t [kg/s] of the optional tangential spring.
    pub friction: f64,
    pub tangential_stiffness: f64,
    pub tangential_damping: f64,
}

fn need(key: &str, v: Option<f64>, why: &str) -> Result<f64, ConfigError> {
    let v = v.ok_or_else(|| ConfigError::inconsistent(format!("frenkel.{key}"), format!("required by {why}")))?;
    check(&format!("frenkel.{key}"), v)
}

fn forbid(key: &str, given: bool, why: &str) -> Result<(), ConfigError> {
    if given {
        return Err(ConfigError::inconsistent(format!("frenkel.{key}"), format!("not used by {why}; remove it")));
    }
    Ok(())
}

impl FrenkelParams {
    /// Validates a spec. Errors name the key: ranges ([`RANGES`]), `k2_max > k1` (d_fluid_0 divides
    /// by the difference), 0 < φ < 1, s_a > 0 when a rate is active, the keys each `sinter_type`
    /// needs (and rejects the ones it ignores).
    pub fn new(s: &FrenkelSpec) -> Result<Self, ConfigError> {
        let k1 = check("frenkel.k1", s.k1)?;
        let k2_max = check("frenkel.k2_max", s.k2_max)?;
        if !(k2_max > k1) {
            return Err(ConfigError::inconsistent(
                "frenkel.k2_max",
                format!("k2_max = {k2_max} N/m must exceed k1 = {k1} N/m (d_fluid_0 = k2_max/(k2_max - k1) phi D*)"),
            ));
        }
        let kc = check("frenkel.kc", s.kc)?;
        let phi = check("frenkel.penetration_depth_max", s.penetration_depth_max)?;
        let damping = check("frenkel.damping", s.damping)?;
        let sinter_adhesion = check("frenkel.sinter_adhesion", s.sinter_adhesion)?;
        let friction = check("frenkel.friction", s.friction)?;
        let tangential_stiffness = check("frenkel.tangential_stiffness", s.tangential_stiffness)?;
        let tangential_damping = check("frenkel.tangential_damping", s.tangential_damping)?;
        let bouvard_keys = [
            ("atomic_volume", s.atomic_volume.is_some()),
            ("gb_thickness", s.gb_thickness.is_some()),
            ("gb_diffusion_prefactor", s.gb_diffusion_prefactor.is_some()),
            ("gb_activation_energy", s.gb_activation_energy.is_some()),
        ];
        let (rate, active) = match s.sinter_type {
            SinterType::Constant | SinterType::ParhamiMcmeeking => {
                let why = if s.sinter_type == SinterType::Constant { "sinter_type = \"constant\"" } else { "sinter_type = \"parhami_mcmeeking\"" };
                for (k, g) in bouvard_keys {
                    forbid(k, g, why)?;
                }
                forbid("viscosity_prefactor", s.viscosity_prefactor.is_some(), why)?;
                forbid("activation_energy", s.activation_energy.is_some(), why)?;
                forbid("rate_table", s.rate_table.is_some(), why)?;
                let viscous = s.viscosity.is_some() || s.surface_energy.is_some();
                if s.sinter_type == SinterType::ParhamiMcmeeking {
                    forbid("viscosity", s.viscosity.is_some(), why)?;
                    forbid("surface_energy", s.surface_energy.is_some(), why)?;
                }
                let src = if viscous {
                    forbid("sinter_rate", s.sinter_rate.is_some(), "a viscosity-derived k_s (give sinter_rate or surface_energy + viscosity)")?;
                    let g = need("surface_energy", s.surface_energy, "k_s = 3 gamma_s/(16 eta R_red)")?;
                    let eta = need("viscosity", s.viscosity, "k_s = 3 gamma_s/(16 eta R_red)")?;
                    SinterRateSource::Viscous { surface_energy: g, viscosity: eta }
                } else {
                    SinterRateSource::Given(need("sinter_rate", s.sinter_rate, why)?)
                };
                let active = !matches!(src, SinterRateSource::Given(k) if k == 0.0);
                if s.sinter_type == SinterType::Constant {
                    (Rate::Constant(src), active)
                } else {
                    let SinterRateSource::Given(k) = src else { unreachable!() };
                    (Rate::ParhamiMcmeeking(k), active)
                }
            }
            SinterType::TemperatureFrenkel => {
                let why = "sinter_type = \"temperature_frenkel\"";
                for (k, g) in bouvard_keys {
                    forbid(k, g, why)?;
                }
                forbid("sinter_rate", s.sinter_rate.is_some(), why)?;
                forbid("viscosity", s.viscosity.is_some(), "temperature_frenkel (use viscosity_prefactor and activation_energy)")?;
                if let Some(table) = &s.rate_table {
                    forbid("viscosity_prefactor", s.viscosity_prefactor.is_some(), "a rate_table")?;
                    forbid("activation_energy", s.activation_energy.is_some(), "a rate_table")?;
                    forbid("surface_energy", s.surface_energy.is_some(), "a rate_table")?;
                    if table.is_empty() {
                        return Err(ConfigError::inconsistent("frenkel.rate_table", "needs at least one [T, k_s] row"));
                    }
                    let mut rows = Vec::with_capacity(table.len());
                    for (i, r) in table.iter().enumerate() {
                        let t = check("frenkel.rate_table.temperature", r[0])?;
                        let k = check("frenkel.rate_table.sinter_rate", r[1])?;
                        if i > 0 && !(t > rows.last().map(|x: &(f64, f64)| x.0).unwrap_or(0.0)) {
                            return Err(ConfigError::inconsistent("frenkel.rate_table", format!("temperatures must increase strictly (row {i}: {t} K)")));
                        }
                        rows.push((t, k));
                    }
                    let active = rows.iter().any(|r| r.1 > 0.0);
                    (Rate::FrenkelTable(rows), active)
                } else {
                    let g = need("surface_energy", s.surface_energy, "temperature_frenkel without a rate_table")?;
                    let eta0 = need("viscosity_prefactor", s.viscosity_prefactor, "temperature_frenkel without a rate_table")?;
                    let q = need("activation_energy", s.activation_energy, "temperature_frenkel without a rate_table")?;
                    (Rate::FrenkelArrhenius { surface_energy: g, viscosity_prefactor: eta0, activation_energy: q }, true)
                }
            }
            SinterType::BouvardMcmeeking => {
                let why = "sinter_type = \"bouvard_mcmeeking\"";
                forbid("sinter_rate", s.sinter_rate.is_some(), why)?;
                forbid("viscosity", s.viscosity.is_some(), why)?;
                forbid("viscosity_prefactor", s.viscosity_prefactor.is_some(), why)?;
                forbid("activation_energy", s.activation_energy.is_some(), why)?;
                forbid("rate_table", s.rate_table.is_some(), why)?;
                forbid("sinter_adhesion", s.sinter_adhesion != 0.0, "bouvard_mcmeeking (its pull is F_s = 2.25 pi R_red gamma_s)")?;
                (
                    Rate::BouvardMcmeeking {
                        surface_energy: need("surface_energy", s.surface_energy, why)?,
                        atomic_volume: need("atomic_volume", s.atomic_volume, why)?,
                        gb_thickness: need("gb_thickness", s.gb_thickness, why)?,
                        gb_diffusion_prefactor: need("gb_diffusion_prefactor", s.gb_diffusion_prefactor, why)?,
                        gb_activation_energy: need("gb_activation_energy", s.gb_activation_energy, why)?,
                    },
                    false,
                )
            }
        };
        if active && !(sinter_adhesion > 0.0) {
            return Err(ConfigError::inconsistent("frenkel.sinter_adhesion", "s_a must be > 0 when a sinter rate is active (the rates divide by s_a)"));
        }
        let contact_temperature = s.contact_temperature.unwrap_or(if s.sinter_type == SinterType::TemperatureFrenkel {
            MeanTemperature::Harmonic
        } else {
            MeanTemperature::Arithmetic
        });
        Ok(FrenkelParams {
            k1,
            k2_max,
            kc,
            phi,
            damping,
            sinter_adhesion,
            rate,
            loading: s.loading,
            mercury_variant: s.mercury_variant,
            contact_temperature,
            friction,
            tangential_stiffness,
            tangential_damping,
        })
    }

    /// Parses and validates the `[frenkel]` section (unknown keys rejected).
    pub fn from_value(value: toml::Value) -> Result<Self, ConfigError> {
        let spec: FrenkelSpec = from_value(value, "frenkel")?;
        Self::new(&spec)
    }

    /// Fluid overlap d_fluid_0 [m] for the reduced radius `r_red` [m]: k2_max/(k2_max − k1)·φ·D*
    /// (source) or φ·D* (doc_page), D* = 2R_red. The cap of δ_p and where k̂ reaches k2_max.
    pub fn fluid_overlap(&self, r_red: f64) -> f64 {
        let d_star = 2.0 * r_red;
        match self.mercury_variant {
            MercuryVariant::Source => self.k2_max / (self.k2_max - self.k1) * self.phi * d_star,
            MercuryVariant::DocPage => self.phi * d_star,
        }
    }

    /// Unloading stiffness k̂ = k1 + (k2_max − k1)·δ_p/d_fluid_0 [N/m].
    pub fn unloading_stiffness(&self, r_red: f64, delta_p: f64) -> f64 {
        self.k1 + (self.k2_max - self.k1) * delta_p / self.fluid_overlap(r_red)
    }

    /// The adhesive sintering pull f_a [N]: s_a·D*, or F_s = 2.25π·R_red·γ_s for bouvard_mcmeeking.
    pub fn pull(&self, r_red: f64) -> f64 {
        match &self.rate {
            Rate::BouvardMcmeeking { surface_energy, .. } => 2.25 * PI * r_red * surface_energy,
            _ => self.sinter_adhesion * 2.0 * r_red,
        }
    }

    /// The sinter rate k_s [1/s] of the Frenkel-type laws at contact temperature `temperature` [K]
    /// for reduced radius `r_red` [m] (0 for bouvard_mcmeeking, which has none).
    pub fn sinter_rate(&self, r_red: f64, temperature: f64) -> f64 {
        match &self.rate {
            Rate::Constant(SinterRateSource::Given(k)) | Rate::ParhamiMcmeeking(k) => *k,
            Rate::Constant(SinterRateSource::Viscous { surface_energy, viscosity }) => 3.0 * surface_energy / (16.0 * viscosity * r_red),
            Rate::FrenkelArrhenius { surface_energy, viscosity_prefactor, activation_energy } => {
                3.0 * surface_energy / (16.0 * viscosity_prefactor * r_red) * (-activation_energy / (GAS_CONSTANT * temperature)).exp()
            }
            Rate::FrenkelTable(rows) => interpolate(rows, temperature),
            Rate::BouvardMcmeeking { .. } => 0.0,
        }
    }

    /// Grain-boundary diffusion parameter Δ = Ω·δ_gb·D0_gb·e^(−Q_gb/(R T))/(k_B T) [m⁶/(J·s)] of
    /// bouvard_mcmeeking (0 for the other laws).
    pub fn gb_parameter(&self, temperature: f64) -> f64 {
        match &self.rate {
            Rate::BouvardMcmeeking { atomic_volume, gb_thickness, gb_diffusion_prefactor, gb_activation_energy, .. } => {
                atomic_volume * gb_thickness * gb_diffusion_prefactor * (-gb_activation_energy / (GAS_CONSTANT * temperature)).exp() / (BOLTZMANN * temperature)
            }
            _ => 0.0,
        }
    }

    /// Plastic-overlap rate ṙ [m/s] at overlap `delta` [m] under the contact force `force` [N]
    /// (elastic + damping, pull excluded, as the source) at contact temperature `temperature` [K]:
    /// constant / temperature_frenkel `2F·k_s/s_a`; parhami_mcmeeking `F·k_s/(0.375·s_a·(δ/D*)²)`;
    /// bouvard_mcmeeking `F/η_c`, `η_c = π a⁴/(8Δ)`, `a² = 4R_red·δ`. Zero for δ ≤ 0.
    pub fn plastic_rate(&self, r_red: f64, delta: f64, force: f64, temperature: f64) -> f64 {
        if !(delta > 0.0) {
            return 0.0;
        }
        match &self.rate {
            Rate::Constant(_) | Rate::FrenkelTable(_) | Rate::FrenkelArrhenius { .. } => {
                let ks = self.sinter_rate(r_red, temperature);
                if ks == 0.0 { 0.0 } else { 2.0 * force * ks / self.sinter_adhesion }
            }
            Rate::ParhamiMcmeeking(ks) => {
                if *ks == 0.0 {
                    return 0.0;
                }
                let x = delta / (2.0 * r_red);
                force * ks / (0.375 * self.sinter_adhesion * x * x)
            }
            Rate::BouvardMcmeeking { .. } => {
                let a2 = 4.0 * r_red * delta;
                let eta_c = PI * a2 * a2 / (8.0 * self.gb_parameter(temperature));
                force / eta_c
            }
        }
    }
}

/// Linear interpolation in `(x, y)` rows with increasing x, held outside.
fn interpolate(rows: &[(f64, f64)], x: f64) -> f64 {
    let (first, last) = (rows[0], rows[rows.len() - 1]);
    if x <= first.0 {
        return first.1;
    }
    if x >= last.0 {
        return last.1;
    }
    let i = rows.partition_point(|r| r.0 <= x);
    let (a, b) = (rows[i - 1], rows[i]);
    a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0)
}

/// Reduced radius R_red = r_i·r_j/(r_i + r_j) [m] (D* = 2R_red).
pub fn reduced_radius(r_i: f64, r_j: f64) -> f64 {
    r_i * r_j / (r_i + r_j)
}

/// Per-contact state (docs/design.md: δ_p, ξ).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FrenkelState {
    /// Plastic overlap δ_p [m], 0 ≤ δ_p ≤ d_fluid_0.
    pub delta_p: f64,
    /// Tangential spring ξ [m].
    #[serde(with = "crate::io::serde_v3")]
    pub xi: Vector3<f64>,
}

/// Normal force of one step [N].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FrenkelNormal {
    /// Elastic force F_e = k̂·(δ − δ_p) after the cohesive floor [N].
    pub elastic: f64,
    /// Damping γ·δ̇ [N].
    pub damping: f64,
    /// F = F_e + γ·δ̇ [N]: the force that drives the plastic rate.
    pub force: f64,
    /// Adhesive pull f_a [N].
    pub pull: f64,
    /// Normal force on the pair F − f_a [N], positive repulsive, on i along +n.
    pub total: f64,
}

/// Step 1: the virgin-loading rule, the elastic force with its cohesive floor, damping and pull
/// (docs/frenkel.md) at overlap `delta` [m], overlap rate `delta_dot` [m/s], reduced radius `r_red` [m].
/// δ ≤ 0: zero, state kept.
pub fn normal_force(p: &FrenkelParams, s: &mut FrenkelState, r_red: f64, delta: f64, delta_dot: f64) -> FrenkelNormal {
    if !(delta > 0.0) {
        return FrenkelNormal::default();
    }
    let d_f0 = p.fluid_overlap(r_red);
    let loaded = match p.loading {
        Loading::Mercury => {
            let dk = (p.k2_max / p.k1 - 1.0) / d_f0;
            // δ/(1 + 1/(dk·δ)) written without the division by dk·δ
            dk * delta * delta / (1.0 + dk * delta)
        }
        Loading::Exact => (delta - p.k1 * d_f0 / (p.k2_max - p.k1)).max(0.0),
    };
    s.delta_p = s.delta_p.max(loaded.min(d_f0));
    let k_hat = p.unloading_stiffness(r_red, s.delta_p);
    let mut elastic = k_hat * (delta - s.delta_p);
    if elastic < -p.kc * delta {
        elastic = -p.kc * delta;
        s.delta_p = (1.0 + p.kc / k_hat) * delta;
    }
    let damping = p.damping * delta_dot;
    let force = elastic + damping;
    let pull = p.pull(r_red);
    FrenkelNormal { elastic, damping, force, pull, total: force - pull }
}

/// Step 2: `δ_p ← clamp(δ_p + ṙ·Δt, 0, d_fluid_0)` with ṙ of [`FrenkelParams::plastic_rate`] from
/// this step's force `force` (= [`FrenkelNormal::force`]) at contact temperature `temperature` [K]
/// over `dt` [s]. sinterdem's limiter: the increment does not carry δ_p across δ (the force-free
/// point); inactive while ṙ·Δt < δ − δ_p, it keeps the rates that diverge as δ → 0 bounded.
/// Returns ṙ [m/s].
pub fn advance_plastic(p: &FrenkelParams, s: &mut FrenkelState, r_red: f64, delta: f64, force: f64, temperature: f64, dt: f64) -> f64 {
    let rate = p.plastic_rate(r_red, delta, force, temperature);
    if rate == 0.0 || !(delta > 0.0) {
        return rate;
    }
    let mut next = s.delta_p + rate * dt;
    if rate > 0.0 {
        next = next.min(s.delta_p.max(delta));
    } else {
        next = next.max(s.delta_p.min(delta));
    }
    s.delta_p = next.clamp(0.0, p.fluid_overlap(r_red));
    rate
}

/// Geometry and kinematics of one contact at one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrenkelKinematics {
    /// Unit normal from j to i.
    pub normal: Vector3<f64>,
    /// Overlap δ [m].
    pub overlap: f64,
    /// δ̇ = −(v_i − v_j)·n [m/s].
    pub overlap_rate: f64,
    /// Surface velocity v_ij (luding eq. 18) [m/s].
    pub surface_velocity: Vector3<f64>,
    /// Reduced radius R_red [m].
    pub reduced_radius: f64,
}

/// The force of one contact step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrenkelForce {
    pub normal: FrenkelNormal,
    /// Tangential force on i [N].
    pub tangential: TangentialForce,
    /// Plastic rate ṙ applied this step [m/s].
    pub plastic_rate: f64,
}

/// One contact step at contact temperature `temperature` [K] over `dt` [s]: [`normal_force`], the
/// tangential spring (f_C = μ·|F − f_a|, the source's absolute normal force; off with μ = 0 or
/// k_t = 0), then [`advance_plastic`]. Force on i: `normal.total·n + tangential.force`.
pub fn contact_force(p: &FrenkelParams, s: &mut FrenkelState, k: &FrenkelKinematics, temperature: f64, dt: f64) -> FrenkelForce {
    let normal = normal_force(p, s, k.reduced_radius, k.overlap, k.overlap_rate);
    let tangential = if k.overlap > 0.0 && p.friction > 0.0 && p.tangential_stiffness > 0.0 {
        tangential_spring(&mut s.xi, &k.normal, &k.surface_velocity, p.tangential_stiffness, p.tangential_damping, p.friction * normal.total.abs(), dt)
    } else {
        TangentialForce { force: Vector3::zeros(), limit: 0.0, sliding: false }
    };
    let plastic_rate = advance_plastic(p, s, k.reduced_radius, k.overlap, normal.force, temperature, dt);
    FrenkelForce { normal, tangential, plastic_rate }
}

/// Neck radius for output and conductance [m]: the volume-conserving neck (H11) of docs/heat-model.md from
/// the overlap δ (ModelError beyond its validity limit).
pub fn neck_radius(r_i: f64, r_j: f64, delta: f64) -> Result<f64, ModelError> {
    crate::neck::solve(r_i, r_j, delta).map(|n| n.a)
}

/// MercuryDPM's neck field √(2R_red·δ_p) [m], an extra output for comparisons only.
pub fn mercury_neck_radius(r_red: f64, delta_p: f64) -> f64 {
    (2.0 * r_red * delta_p.max(0.0)).sqrt()
}

/// One sample of a free-sintering pair run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairSample {
    /// Time [s].
    pub t: f64,
    /// Overlap δ [m].
    pub delta: f64,
    /// Overlap rate δ̇ [m/s].
    pub delta_dot: f64,
    /// Plastic overlap δ_p [m].
    pub delta_p: f64,
    /// Plastic rate ṙ [m/s].
    pub rate: f64,
    /// F = F_e + γδ̇ [N].
    pub force: f64,
}

/// The plastic overlap δ_p at which a contact at overlap `delta` [m] is in force equilibrium with
/// the pull, `k̂(δ_p)·(δ − δ_p) = f_a` (fixed-point iteration), or 0 when δ < f_a/k1.
pub fn equilibrium_plastic_overlap(p: &FrenkelParams, r_red: f64, delta: f64) -> f64 {
    let f_a = p.pull(r_red);
    let d_f0 = p.fluid_overlap(r_red);
    let mut dp = (delta - f_a / p.k1).max(0.0);
    for _ in 0..100 {
        dp = (delta - f_a / p.unloading_stiffness(r_red, dp.min(d_f0))).clamp(0.0, d_f0);
    }
    dp
}

/// A free two-particle pair (radii `r_i`, `r_j` [m], masses `m_i`, `m_j` [kg]) from overlap
/// `delta0` [m] at rest with plastic overlap `delta_p0` [m] (None: the loading rule's; see
/// [`equilibrium_plastic_overlap`] for a start in force balance), at constant contact temperature
/// `temperature` [K]: velocity-Verlet in the overlap, `m_ij·δ̈ = −(F − f_a)`, with δ̇ at the half
/// step in the damping, then the plastic update; `dt` [s] until `t_end` [s], a sample every
/// `every` steps (and at the start). Masses may be scaled up freely: the closed forms are
/// quasi-static, and a larger mass only lengthens the contact period t_c = π√(m_ij/k̂).
pub fn free_sintering_pair(
    p: &FrenkelParams,
    r_i: f64,
    r_j: f64,
    m_i: f64,
    m_j: f64,
    delta0: f64,
    delta_p0: Option<f64>,
    temperature: f64,
    dt: f64,
    t_end: f64,
    every: usize,
) -> Result<Vec<PairSample>, ModelError> {
    if !(r_i > 0.0 && r_j > 0.0 && m_i > 0.0 && m_j > 0.0 && dt > 0.0 && t_end >= 0.0 && delta0 > 0.0) {
        return Err(ModelError::new("free_sintering_pair: radii, masses, dt and delta0 must be positive"));
    }
    let r_red = reduced_radius(r_i, r_j);
    let m = m_i * m_j / (m_i + m_j);
    let mut s = FrenkelState { delta_p: delta_p0.unwrap_or(0.0).clamp(0.0, p.fluid_overlap(r_red)), ..Default::default() };
    let (mut delta, mut v) = (delta0, 0.0);
    let mut nf = normal_force(p, &mut s, r_red, delta, v);
    let mut acc = -nf.total / m;
    let mut out = vec![PairSample { t: 0.0, delta, delta_dot: v, delta_p: s.delta_p, rate: 0.0, force: nf.force }];
    let steps = (t_end / dt).round() as usize;
    let every = every.max(1);
    for n in 1..=steps {
        let v_half = v + 0.5 * dt * acc;
        delta += v_half * dt;
        nf = normal_force(p, &mut s, r_red, delta, v_half);
        let rate = advance_plastic(p, &mut s, r_red, delta, nf.force, temperature, dt);
        acc = -nf.total / m;
        v = v_half + 0.5 * dt * acc;
        if !(delta.is_finite() && v.is_finite()) {
            return Err(ModelError::new(format!("free_sintering_pair: non-finite state at t = {:.6e} s", n as f64 * dt)));
        }
        if n % every == 0 || n == steps {
            out.push(PairSample { t: n as f64 * dt, delta, delta_dot: v, delta_p: s.delta_p, rate, force: nf.force });
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn interpolation_holds_outside() {
        let rows = [(300.0, 1.0), (400.0, 3.0)];
        assert_eq!(interpolate(&rows, 200.0), 1.0);
        assert_eq!(interpolate(&rows, 350.0), 2.0);
        assert_eq!(interpolate(&rows, 500.0), 3.0);
    }
    #[test]
    fn means() {
        assert_eq!(MeanTemperature::Arithmetic.of(300.0, 500.0), 400.0);
        assert_eq!(MeanTemperature::Harmonic.of(300.0, 500.0), 375.0);
    }
}

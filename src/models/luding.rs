//! Luding's hysteretic, cohesive, frictional sintering contact law (docs/luding.md;
//! Luding, Manetsberger & Müllers 2005, "A discrete model for long time sintering", 2-D there,
//! 3-D here). `(eq. N)` are the paper's numbers.
//!
//! Pure per-contact kernels for the explicit velocity-Verlet driver: parameters ([`LudingParams`],
//! resolved once from the `[luding]` case section), per-contact `Copy` history ([`LudingState`]:
//! δ_max, δ_0, ξ, k1(T,t)), and the step kernels, called once per contact and step in this order:
//!
//! 1. [`update_stiffness`]: k1(T) (eq. 10), freeze on cooling, relaxation of k1(T,t) (eqs. 11–12,
//!    closed form), and the history shift when k1(T,t) falls (heating) or rises (cooling);
//! 2. [`normal_force`]: loading / un-reloading / cohesive branches (eq. 4) with k2(δ_max) (eq. 7),
//!    kc(T,t,δ_max) (eq. 13), the cone clamp and viscous damping (eq. 5);
//! 3. [`tangential_force`]: the cohesion-shifted Coulomb limit (eqs. 14–15, 24), the tangential
//!    spring (eqs. 16–23).
//!
//! [`contact_force`] does all three. Sign conventions (docs/luding.md notation): the normal `n` points from
//! j to i, the overlap `δ = r_i + r_j − |x_i − x_j|` (eq. 3), `δ̇ = −(v_i − v_j)·n` (> 0 while
//! approaching); the normal force is positive when repulsive and acts on i along +n; the
//! tangential force returned acts on i (−f_t on j), with torques `−r_i n × f_t` on i and
//! `−r_j n × f_t` on j. SI units throughout; temperatures in kelvin.

use crate::config::from_value;
use crate::config::ranges::{Range, c, o, p};

/// Checks a key of this law's [`RANGES`] (then the shared keys).
fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(RANGES, key, v)
}
use crate::error::{ConfigError, ModelError};
use crate::models::frenkel::MeanTemperature;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Range table of the `[luding]` keys (listed through its law's entry in `kinds::explicit_sinter::laws::LAWS`).
pub static RANGES: &[Range] = &[
    p("luding.k1", 0.0, 1e12, "N/m", "cold loading stiffness k1 (eq. 4)"),
    p("luding.k2", 0.0, 1e12, "N/m", "un/reloading stiffness k2 at the fluid limit (eqs. 4, 7); k2 > k1"),
    c("luding.kc", 0.0, 1e12, "N/m", "cold cohesion stiffness kc (eqs. 4, 13)"),
    c("luding.gamma_n", 0.0, 1e6, "kg/s", "normal viscous damping gamma_0 (eq. 5)"),
    c("luding.gamma_t", 0.0, 1e6, "kg/s", "tangential viscous damping gamma_t (eq. 19)"),
    p("luding.tangential_ratio", 0.0, 10.0, "1", "alpha of k_t = alpha k2(delta_max) (eq. 23)"),
    c("luding.friction", 0.0, 10.0, "1", "cold friction coefficient mu (eqs. 14, 24)"),
    c("luding.t_melt", 1.0, 1e4, "K", "melting temperature T_melt (eqs. 9, 10)"),
    p("luding.t_var", 0.0, 1e4, "K", "width T_var of the softening (eq. 10)"),
    c("luding.expansion", 0.0, 1e-2, "1/K", "relative radius change per kelvin alpha_r (eq. 9)"),
    o("luding.fluid_overlap", 0.0, 1.0, "1", "fluid overlap delta_fluid / r_0 (eq. 7)"),
    p("luding.t0", 0.0, 1e15, "s", "relaxation time scale t_0 of k1(T,t) (eqs. 11-12)"),
];

/// Which rule moves the history when k1(T,t) rises (cooling), docs/luding.md and docs/decisions-laws.md.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CoolingRule {
    /// δ_0 stays; δ_max grows until `δ_0 = [1 − k1(T,t)/k2(δ_max)]·δ_max` with k2(δ_max) of eq. 7.
    #[default]
    Consistent,
    /// The paper's verbatim `δ_max = δ_0/[1 − k1(T,t)/k2]` with the constant k2.
    Paper,
}

/// The `[luding]` case section as written. Defaults are the paper's Table 1 (k1/k2 = kc/k2 = 0.5,
/// α = 0.2, T_melt = 120 °C = 393.15 K, …).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LudingSpec {
    /// Cold loading stiffness k1 [N/m].
    pub k1: f64,
    /// Un/reloading stiffness k2 reached at the fluid limit [N/m] (eq. 7).
    pub k2: f64,
    /// Cold cohesion stiffness kc [N/m] (eq. 13 scales it).
    pub kc: f64,
    /// Normal viscous damping γ_0 [kg/s] (eq. 5).
    pub gamma_n: f64,
    /// Tangential viscous damping γ_t [kg/s] (eq. 19).
    pub gamma_t: f64,
    /// α of `k_t = α·k2(δ_max)` [1] (eq. 23).
    pub tangential_ratio: f64,
    /// Cold friction coefficient μ [1] (eq. 24 scales it).
    pub friction: f64,
    /// Melting temperature T_melt [K].
    pub t_melt: f64,
    /// Softening width T_var [K] (eq. 10).
    pub t_var: f64,
    /// Relative radius change per kelvin α_r [1/K] (eq. 9).
    pub expansion: f64,
    /// Fluid overlap relative to the mean radius, δ_fluid/r_0 [1] (eq. 7; the paper's 0.2).
    pub fluid_overlap: f64,
    /// Relaxation time scale t_0 [s] (eqs. 11–12).
    pub t0: f64,
    /// History rule on cooling.
    pub cooling: CoolingRule,
    /// The paper's freeze: k1(T,t) jumps to k1(T) when k1(T) rises above it.
    pub freeze_on_cooling: bool,
    /// Keep the cohesive (attractive) normal force while the contact slides. `false` is the paper's
    /// choice (footnote 5: f_n ≥ 0 while sliding).
    pub cohesion_while_sliding: bool,
    /// Contact temperature from the two particle temperatures (docs/heat-model.md (H16): arithmetic default).
    pub contact_temperature: MeanTemperature,
}

impl Default for LudingSpec {
    fn default() -> Self {
        LudingSpec {
            k1: 1.0e5,
            k2: 2.0e5,
            kc: 1.0e5,
            gamma_n: 0.2,
            gamma_t: 0.05,
            tangential_ratio: 0.2,
            friction: 0.5,
            t_melt: 393.15,
            t_var: 10.0,
            expansion: 1.0e-4,
            fluid_overlap: 0.2,
            t0: 1.0e3,
            cooling: CoolingRule::Consistent,
            freeze_on_cooling: true,
            cohesion_while_sliding: true,
            contact_temperature: MeanTemperature::Arithmetic,
        }
    }
}

/// Validated parameters of Luding's law, resolved once for a scene of mean radius r_0.
#[derive(Debug, Clone, PartialEq)]
pub struct LudingParams {
    /// Cold loading stiffness k1 [N/m].
    pub k1: f64,
    /// Fluid-limit un/reloading stiffness k2 [N/m].
    pub k2: f64,
    /// Cold cohesion stiffness kc [N/m].
    pub kc: f64,
    /// Normal damping γ_0 [kg/s].
    pub gamma_n: f64,
    /// Tangential damping γ_t [kg/s].
    pub gamma_t: f64,
    /// α of k_t = α·k2(δ_max) [1].
    pub tangential_ratio: f64,
    /// Cold friction coefficient μ [1].
    pub friction: f64,
    /// T_melt [K].
    pub t_melt: f64,
    /// T_var [K].
    pub t_var: f64,
    /// α_r [1/K].
    pub expansion: f64,
    /// δ_fluid = fluid_overlap·r_0 [m] (eq. 7).
    pub delta_fluid: f64,
    /// δ_max^fluid = k2·δ_fluid/(k2 − k1) [m] (eq. 7).
    pub delta_max_fluid: f64,
    /// Default relaxation time t_0 [s] (a protocol may pass another to [`update_stiffness`]).
    pub t0: f64,
    pub cooling: CoolingRule,
    pub freeze_on_cooling: bool,
    pub cohesion_while_sliding: bool,
    pub contact_temperature: MeanTemperature,
}

impl LudingParams {
    /// Validates a spec for a scene of mean particle radius `mean_radius` [m] (r_0 of δ_fluid = 0.2·r_0).
    /// Errors name the key: ranges from [`RANGES`], `k2 > k1`, `α_r·T_melt < 1` (positive radii).
    pub fn new(s: &LudingSpec, mean_radius: f64) -> Result<Self, ConfigError> {
        let k1 = check("luding.k1", s.k1)?;
        let k2 = check("luding.k2", s.k2)?;
        if !(k2 > k1) {
            return Err(ConfigError::inconsistent(
                "luding.k2",
                format!("k2 = {k2} N/m must exceed k1 = {k1} N/m (delta_max^fluid = k2 delta_fluid/(k2 - k1), eq. 7)"),
            ));
        }
        let kc = check("luding.kc", s.kc)?;
        let gamma_n = check("luding.gamma_n", s.gamma_n)?;
        let gamma_t = check("luding.gamma_t", s.gamma_t)?;
        let tangential_ratio = check("luding.tangential_ratio", s.tangential_ratio)?;
        let friction = check("luding.friction", s.friction)?;
        let t_melt = check("luding.t_melt", s.t_melt)?;
        let t_var = check("luding.t_var", s.t_var)?;
        let expansion = check("luding.expansion", s.expansion)?;
        if expansion * t_melt >= 1.0 {
            return Err(ConfigError::inconsistent(
                "luding.expansion",
                format!("alpha_r T_melt = {} must be < 1, else eq. 9 gives non-positive radii above 0 K", expansion * t_melt),
            ));
        }
        let fluid_overlap = check("luding.fluid_overlap", s.fluid_overlap)?;
        let t0 = check("luding.t0", s.t0)?;
        if !(mean_radius > 0.0 && mean_radius.is_finite()) {
            return Err(ConfigError::inconsistent(
                "luding.fluid_overlap",
                format!("delta_fluid = fluid_overlap * r_0 needs a positive mean radius r_0, got {mean_radius} m"),
            ));
        }
        let delta_fluid = fluid_overlap * mean_radius;
        Ok(LudingParams {
            k1,
            k2,
            kc,
            gamma_n,
            gamma_t,
            tangential_ratio,
            friction,
            t_melt,
            t_var,
            expansion,
            delta_fluid,
            delta_max_fluid: k2 * delta_fluid / (k2 - k1),
            t0,
            cooling: s.cooling,
            freeze_on_cooling: s.freeze_on_cooling,
            cohesion_while_sliding: s.cohesion_while_sliding,
            contact_temperature: s.contact_temperature,
        })
    }

    /// Parses and validates the `[luding]` section (unknown keys rejected).
    pub fn from_value(value: toml::Value, mean_radius: f64) -> Result<Self, ConfigError> {
        let spec: LudingSpec = from_value(value, "luding")?;
        Self::new(&spec, mean_radius)
    }

    /// k1(T) = (k1/2)·[1 + tanh((T_melt − T)/T_var)] (eq. 10) [N/m], evaluated as
    /// k1/(1 + e^(−2τ)) (the same function, without cancellation far above T_melt).
    pub fn k1_of_temperature(&self, temperature: f64) -> f64 {
        let tau = (self.t_melt - temperature) / self.t_var;
        self.k1 / (1.0 + (-2.0 * tau).exp())
    }

    /// k2(δ_max) (eq. 7) [N/m]: k1 + (k2 − k1)·δ_max/δ_max^fluid below δ_max^fluid, k2 above.
    /// Uses the cold k1 (docs/luding.md, "Equations").
    pub fn k2_of(&self, delta_max: f64) -> f64 {
        if delta_max >= self.delta_max_fluid { self.k2 } else { self.k1 + (self.k2 - self.k1) * delta_max.max(0.0) / self.delta_max_fluid }
    }

    /// kc(T,t,δ_max) = [k1(T,t)/k1]·[k2(δ_max)/k2]·kc (eq. 13) [N/m].
    pub fn kc_of(&self, k1_t: f64, delta_max: f64) -> f64 {
        (k1_t / self.k1) * (self.k2_of(delta_max) / self.k2) * self.kc
    }

    /// μ(T,t) = μ·k1(T,t)/k1 (eq. 24) [1].
    pub fn friction_of(&self, k1_t: f64) -> f64 {
        self.friction * k1_t / self.k1
    }

    /// k_t = α·k2(δ_max) (eqs. 19, 23) [N/m].
    pub fn kt_of(&self, delta_max: f64) -> f64 {
        self.tangential_ratio * self.k2_of(delta_max)
    }

    /// δ_min = (k2(δ_max) − k1(T,t))/(k2(δ_max) + kc(T,t,δ_max))·δ_max [m]: the overlap of the
    /// largest attraction (Luding et al. 2005 §3.1.1).
    pub fn delta_min(&self, k1_t: f64, delta_max: f64) -> f64 {
        let k2 = self.k2_of(delta_max);
        let kc = self.kc_of(k1_t, delta_max);
        ((k2 - k1_t) / (k2 + kc) * delta_max).max(0.0)
    }

    /// f_min = −(k2(δ_max) − k1(T,t))/(1 + k2(δ_max)/kc(T,t,δ_max))·δ_max (eq. 15) [N], written
    /// as −kc·(k2 − k1(T,t))/(k2 + kc)·δ_max (= −kc·δ_min; 0 for kc = 0).
    pub fn f_min(&self, k1_t: f64, delta_max: f64) -> f64 {
        let kc = self.kc_of(k1_t, delta_max);
        -kc * self.delta_min(k1_t, delta_max)
    }

    /// Radius at temperature T from the radius at T_melt: `r(T) = r(T_melt)·[1 − α_r(T_melt − T)]`
    /// (eq. 9) [m]. Mass is constant, so the density follows as m/(4/3 π r³).
    pub fn radius(&self, radius_at_melt: f64, temperature: f64) -> f64 {
        radius_at_melt * (1.0 - self.expansion * (self.t_melt - temperature))
    }

    /// Radius at T of a particle whose radius is `r_ref` at `t_ref` (eq. 9 through r(T_melt)) [m].
    pub fn radius_from(&self, r_ref: f64, t_ref: f64, temperature: f64) -> f64 {
        r_ref * (1.0 - self.expansion * (self.t_melt - temperature)) / (1.0 - self.expansion * (self.t_melt - t_ref))
    }

    /// Contact half-period `t_c = π/√(k2/m_ij − η_0²)`, `η_0 = γ_0/(2 m_ij)` (eq. 6) [s] for the
    /// reduced mass `m_ij` [kg]. Over-damped contacts are a [`ModelError`]. The paper's step is t_c/50.
    pub fn contact_duration(&self, reduced_mass: f64) -> Result<f64, ModelError> {
        let eta = self.gamma_n / (2.0 * reduced_mass);
        let w2 = self.k2 / reduced_mass - eta * eta;
        if !(reduced_mass > 0.0) || !(w2 > 0.0) {
            return Err(ModelError::new(format!(
                "luding: contact with reduced mass {reduced_mass:.3e} kg is over-damped (k2/m = {:.3e} 1/s², eta_0² = {:.3e} 1/s²)",
                self.k2 / reduced_mass,
                eta * eta
            )));
        }
        Ok(PI / w2.sqrt())
    }
}

/// Per-contact history of Luding's law (docs/design.md: δ_max, δ_0, ξ, k1(T,t)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LudingState {
    /// Largest overlap reached δ_max [m] (shifted by the cohesive branch and by cooling).
    pub delta_max: f64,
    /// Force-free overlap δ_0 [m].
    pub delta_0: f64,
    /// Tangential spring ξ [m] (eqs. 16, 20, 21).
    #[serde(with = "crate::io::serde_v3")]
    pub xi: Vector3<f64>,
    /// Current effective loading stiffness k1(T,t) [N/m] (eqs. 11–12).
    pub k1_t: f64,
    /// Whether the last tangential step slid (eq. 21), for output.
    pub sliding: bool,
}

impl LudingState {
    /// A new contact at contact temperature `temperature` [K]: no history, k1(T,t) = k1(T) (docs/luding.md).
    pub fn new(p: &LudingParams, temperature: f64) -> Self {
        LudingState { delta_max: 0.0, delta_0: 0.0, xi: Vector3::zeros(), k1_t: p.k1_of_temperature(temperature), sliding: false }
    }

    /// Whether δ_0 has reached δ_fluid (the fluid branch: δ_0 frozen, slope k2, no k1 cap).
    pub fn is_fluid(&self, p: &LudingParams) -> bool {
        self.delta_0 >= p.delta_fluid
    }
}

/// Relaxation of k1(T,t) toward `k_target` = k1(T) over time `t` [s] at constant T, from
/// `k_start` (eqs. 11–12): the exact solution of `∂k/∂t = s·(k_T − k)²/(k_T·t_0)`,
/// `k = k_T·[1 − w_0/(1 + |w_0|·t/t_0)]`, `w_0 = 1 − k_start/k_T`, written as
/// `k_T + d·k_T·t_0/(k_T·t_0 + |d|·t)` with `d = k_start − k_T` (finite for k_T → 0) [N/m].
/// Both branches (down after heating, up without the freeze); unconditionally stable.
pub fn relax(k_start: f64, k_target: f64, t0: f64, t: f64) -> f64 {
    let d = k_start - k_target;
    if d == 0.0 || !(t > 0.0) {
        return k_start;
    }
    let den = k_target * t0 + d.abs() * t;
    if !(den > 0.0) {
        return k_target;
    }
    k_target + d * (k_target * t0 / den)
}

/// Positive root δ_max of `B·δ² + (k1 − k1(T,t) − B·δ_0)·δ − k1·δ_0 = 0`, `B = (k2 − k1)/δ_max^fluid`:
/// the δ_max at which `δ_0 = [1 − k1(T,t)/k2(δ_max)]·δ_max` with eq. 7 (docs/decisions-laws.md, consistent cooling).
pub fn cooling_delta_max(p: &LudingParams, k1_t: f64, delta_0: f64) -> f64 {
    let b = (p.k2 - p.k1) / p.delta_max_fluid;
    let bb = p.k1 - k1_t - b * delta_0;
    let cc = -p.k1 * delta_0;
    // q = −(bb + sign(bb)·√disc)/2 avoids cancellation; root = cc/q or q/b.
    let disc = (bb * bb - 4.0 * b * cc).max(0.0);
    let root = if bb >= 0.0 {
        let q = -0.5 * (bb + disc.sqrt());
        if q != 0.0 { cc / q } else { 0.0 }
    } else {
        0.5 * (-bb + disc.sqrt()) / b
    };
    if root < p.delta_max_fluid { root } else { delta_0 / (1.0 - k1_t / p.k2) }
}

/// The δ_max whose cohesive minimum lies at `delta` [m]: `δ_min(δ_max) = δ` with k2(δ_max) (eq. 7)
/// and kc(T,t,δ_max) (eq. 13) both taken at the new δ_max, so that the un/reloading line
/// `k2(δ_max)·(δ − δ_0)` meets `−kc·δ` exactly at δ (decisions L13). With `kc(x) = c·k2(x)`,
/// `c = (k1(T,t)/k1)·(kc/k2)`, `k2(x) = k1 + B·x`: the positive root of
/// `B·x² + (k1 − k1(T,t) − (1 + c)·B·δ)·x − (1 + c)·k1·δ = 0`, and
/// `x = (1 + c)·k2/(k2 − k1(T,t))·δ` (MercuryDPM's `(k2 + kc)/(k2 − k1)·δ`) beyond δ_max^fluid.
pub fn cohesive_delta_max(p: &LudingParams, k1_t: f64, delta: f64) -> f64 {
    let c = (k1_t / p.k1) * (p.kc / p.k2);
    let b = (p.k2 - p.k1) / p.delta_max_fluid;
    let bb = p.k1 - k1_t - (1.0 + c) * b * delta;
    let cc = -(1.0 + c) * p.k1 * delta;
    let disc = (bb * bb - 4.0 * b * cc).max(0.0);
    let root = if bb >= 0.0 {
        let q = -0.5 * (bb + disc.sqrt());
        if q != 0.0 { cc / q } else { 0.0 }
    } else {
        0.5 * (-bb + disc.sqrt()) / b
    };
    if root < p.delta_max_fluid { root } else { (1.0 + c) * p.k2 / (p.k2 - k1_t) * delta }
}

/// Step 1 of a contact step: temperature and time (eqs. 10–12, docs/luding.md).
///
/// k1(T) of the contact temperature `temperature` [K]; with `freeze_on_cooling`, k1(T,t) jumps to
/// k1(T) when k1(T) lies above it; otherwise it relaxes over `dt` [s] with time scale `t0` [s] by
/// the closed form [`relax`] from the previous step's value. Then the history follows:
/// falling k1(T,t) keeps δ_max and sets `δ_0 = [1 − k1(T,t)/k2(δ_max)]·δ_max` (capped at δ_fluid);
/// rising k1(T,t) keeps δ_0 and grows δ_max by the [`CoolingRule`].
pub fn update_stiffness(p: &LudingParams, s: &mut LudingState, temperature: f64, t0: f64, dt: f64) {
    let target = p.k1_of_temperature(temperature);
    let old = s.k1_t;
    let new = if p.freeze_on_cooling && target > old { target } else { relax(old, target, t0, dt) };
    s.k1_t = new;
    if s.delta_max <= 0.0 || new == old {
        return;
    }
    if new < old {
        s.delta_0 = ((1.0 - new / p.k2_of(s.delta_max)) * s.delta_max).min(p.delta_fluid).max(s.delta_0);
    } else {
        let grown = match p.cooling {
            CoolingRule::Consistent => cooling_delta_max(p, new, s.delta_0),
            CoolingRule::Paper => s.delta_0 / (1.0 - new / p.k2),
        };
        s.delta_max = s.delta_max.max(grown);
    }
}

/// The normal force of one contact step [N], split for output.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NormalForce {
    /// Hysteretic force inside the cone (eq. 4) [N].
    pub elastic: f64,
    /// Viscous force γ_0·δ̇ (eq. 5) [N].
    pub damping: f64,
    /// elastic + damping [N], positive repulsive, on i along +n.
    pub total: f64,
}

/// Step 2: the normal force at overlap `delta` [m] and overlap rate `delta_dot` [m/s] (eqs. 4, 5, 7, 13).
///
/// - loading (δ ≥ δ_max): δ_max ← δ, δ_0 ← [1 − k1(T,t)/k2(δ_max)]·δ_max (≤ δ_fluid), f = k1(T,t)·δ;
/// - un/reloading: f = k2(δ_max)·(δ − δ_0), clamped into the cone [−kc·δ, k1(T,t)·δ]
///   (no upper cap on the fluid branch δ_0 = δ_fluid, paper Fig. 3);
/// - cohesive limit: f = −kc(T,t,δ_max)·δ; δ_max shifts down so that δ is its new δ_min
///   ([`cohesive_delta_max`]; MercuryDPM's (k2 + kc)/(k2 − k1(T,t))·δ with k2, kc at the new
///   δ_max), δ_0 recomputed: reloading leaves the line along k2(δ_max) without a jump;
/// - damping γ_0·δ̇ added after the clamp.
///
/// δ ≤ 0 (open contact): zero force, history kept.
pub fn normal_force(p: &LudingParams, s: &mut LudingState, delta: f64, delta_dot: f64) -> NormalForce {
    if !(delta > 0.0) {
        return NormalForce::default();
    }
    let k1 = s.k1_t;
    if delta >= s.delta_max {
        s.delta_max = delta;
        let k2 = p.k2_of(delta);
        s.delta_0 = ((1.0 - k1 / k2) * delta).min(p.delta_fluid).max(s.delta_0.min(delta));
    }
    let k2 = p.k2_of(s.delta_max);
    let kc = p.kc_of(k1, s.delta_max);
    let fluid = s.is_fluid(p);
    let mut f = k2 * (delta - s.delta_0);
    if !fluid && f > k1 * delta {
        f = k1 * delta;
    }
    if f < -kc * delta {
        f = -kc * delta;
        if !fluid {
            s.delta_max = cohesive_delta_max(p, k1, delta);
            s.delta_0 = ((1.0 - k1 / p.k2_of(s.delta_max)) * s.delta_max).min(p.delta_fluid);
        }
    }
    let damping = p.gamma_n * delta_dot;
    NormalForce { elastic: f, damping, total: f + damping }
}

/// Relative velocity of the contact surfaces `v_ij = v_i − v_j + r_i n×ω_i + r_j n×ω_j` (eq. 18) [m/s].
pub fn surface_velocity(n: &Vector3<f64>, v_i: &Vector3<f64>, v_j: &Vector3<f64>, w_i: &Vector3<f64>, w_j: &Vector3<f64>, r_i: f64, r_j: f64) -> Vector3<f64> {
    v_i - v_j + r_i * n.cross(w_i) + r_j * n.cross(w_j)
}

/// Outcome of the tangential step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TangentialForce {
    /// Tangential force on i [N] (−force on j).
    pub force: Vector3<f64>,
    /// Coulomb limit f_C = μ(T,t)·(f_n − f_min) ≥ 0 [N] (eq. 14).
    pub limit: f64,
    /// Sliding (eq. 21) rather than sticking (eq. 20).
    pub sliding: bool,
}

/// The tangential spring with a Coulomb limit `f_c` [N] (eqs. 16–22), shared by the explicit laws.
///
/// Projects ξ into the plane normal to the unit vector `n` (16), takes `v_t` of `v_ij` (17), the
/// trial force `f_t° = −k_t ξ − γ_t v_t` (19); sticking (|f_t°| ≤ f_C): f_t = f_t°, ξ ← ξ + v_t·Δt (20);
/// sliding: f_t = f_C·t̂, t̂ = f_t°/|f_t°|, ξ ← −(f_C t̂ + γ_t v_t)/k_t (21–22).
pub fn tangential_spring(xi: &mut Vector3<f64>, n: &Vector3<f64>, v_ij: &Vector3<f64>, k_t: f64, gamma_t: f64, f_c: f64, dt: f64) -> TangentialForce {
    let f_c = f_c.max(0.0);
    *xi -= n * n.dot(xi);
    let v_t = v_ij - n * n.dot(v_ij);
    let trial = -k_t * *xi - gamma_t * v_t;
    let norm = trial.norm();
    if norm <= f_c {
        *xi += v_t * dt;
        TangentialForce { force: trial, limit: f_c, sliding: false }
    } else {
        let t_hat = trial / norm;
        let force = f_c * t_hat;
        *xi = if k_t > 0.0 { -(force + gamma_t * v_t) / k_t } else { Vector3::zeros() };
        TangentialForce { force, limit: f_c, sliding: true }
    }
}

/// Step 3: Luding's tangential force (eqs. 14–24) for the unit normal `n`, the surface velocity
/// `v_ij` of eq. 18 [m/s] and this step's normal force `f_n` [N] (total, damping included):
/// `f_C = μ(T,t)·(f_n − f_min)` floored at 0, `k_t = α·k2(δ_max)`, then [`tangential_spring`].
pub fn tangential_force(p: &LudingParams, s: &mut LudingState, n: &Vector3<f64>, v_ij: &Vector3<f64>, f_n: f64, dt: f64) -> TangentialForce {
    let f_min = p.f_min(s.k1_t, s.delta_max);
    let f_c = p.friction_of(s.k1_t) * (f_n - f_min);
    let out = tangential_spring(&mut s.xi, n, v_ij, p.kt_of(s.delta_max), p.gamma_t, f_c, dt);
    s.sliding = out.sliding;
    out
}

/// Geometry and kinematics of one contact at one step, computed once by the driver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactKinematics {
    /// Unit normal n from j to i.
    pub normal: Vector3<f64>,
    /// Overlap δ [m] (eq. 3).
    pub overlap: f64,
    /// Overlap rate δ̇ = −(v_i − v_j)·n [m/s].
    pub overlap_rate: f64,
    /// Relative surface velocity v_ij of eq. 18 [m/s] ([`surface_velocity`]).
    pub surface_velocity: Vector3<f64>,
}

/// The force of one contact step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LudingForce {
    /// Normal force [N], positive repulsive, on i along +n (after the sliding rule's f_n ≥ 0 if
    /// `cohesion_while_sliding = false`).
    pub normal: f64,
    /// Normal force parts before that rule.
    pub normal_parts: NormalForce,
    /// Tangential force on i [N].
    pub tangential: Vector3<f64>,
    /// Sliding this step.
    pub sliding: bool,
}

/// One contact step: [`update_stiffness`] at the contact temperature `temperature` [K] with
/// relaxation time `t0` [s] over `dt` [s], then [`normal_force`] and [`tangential_force`].
/// Total force on i: `normal·n + tangential`; on j its negative.
pub fn contact_force(p: &LudingParams, s: &mut LudingState, k: &ContactKinematics, temperature: f64, t0: f64, dt: f64) -> LudingForce {
    update_stiffness(p, s, temperature, t0, dt);
    if !(k.overlap > 0.0) {
        return LudingForce { normal: 0.0, normal_parts: NormalForce::default(), tangential: Vector3::zeros(), sliding: false };
    }
    let nf = normal_force(p, s, k.overlap, k.overlap_rate);
    let tf = tangential_force(p, s, &k.normal, &k.surface_velocity, nf.total, dt);
    let normal = if tf.sliding && !p.cohesion_while_sliding { nf.total.max(0.0) } else { nf.total };
    LudingForce { normal, normal_parts: nf, tangential: tf.force, sliding: tf.sliding }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relax_handles_zero_target_and_zero_time() {
        assert_eq!(relax(1.0, 0.0, 10.0, 1.0), 0.0);
        assert_eq!(relax(0.7, 0.5, 10.0, 0.0), 0.7);
        assert_eq!(relax(0.5, 0.5, 10.0, 3.0), 0.5);
    }

    #[test]
    fn cohesive_root_puts_delta_min_at_delta() {
        let p = LudingParams::new(&LudingSpec::default(), 1e-3).unwrap();
        for &(k1t, d) in &[(1e5, 1e-7), (0.4e5, 3e-6), (0.9e5, 1e-4), (1e5, 5e-4)] {
            let dm = cohesive_delta_max(&p, k1t, d);
            assert!((p.delta_min(k1t, dm) - d).abs() <= 1e-10 * d, "{k1t} {d}: {}", p.delta_min(k1t, dm));
        }
    }

    #[test]
    fn cooling_root_satisfies_its_equation() {
        let p = LudingParams::new(&LudingSpec::default(), 1e-3).unwrap();
        for &(k1t, d0) in &[(1e5, 1e-6), (0.7e5, 3e-5), (0.99e5, 1.5e-4)] {
            let dm = cooling_delta_max(&p, k1t, d0);
            let back = (1.0 - k1t / p.k2_of(dm)) * dm;
            assert!((back - d0).abs() <= 1e-10 * d0, "{k1t} {d0}: {back}");
        }
    }
}

//! Luding's sample history and compression test for the explicit sintering laws (case kind
//! `explicit_sinter`; docs/luding.md "Protocol", Luding et al. 2005 §4).
//!
//! History of one sample, in 3-D, in a box of six walls (x⁻, y⁻, z⁻ fixed through the origin;
//! x⁺, y⁺, z⁺ under stress control `m_w s̈ = p·A − F_w − γ_w ṡ`, eq. 1, A the current face area):
//! 1. **prepare** (0 ≤ t < t_prepare): a loose random packing is compressed by the isotropic wall
//!    pressure p at `temperature_cold` with frictionless particles (`prepare_friction`, paper: 0) and
//!    relaxes;
//! 2. **heat** (t_prepare ≤ t < t_prepare + t_heat): the law's friction switches on and T rises
//!    linearly to `temperature_hot`;
//! 3. **sinter** for t_s at `temperature_hot` with the shortened relaxation time `t0_sinter`
//!    (Luding: Table 1's 0.1 s against 10³ s);
//! 4. **cool** linearly over t_cool back to `temperature_cold`, then **relax** for t_relax;
//! 5. **compression test**: the top wall (z⁺) moves in at the constant strain rate ε̇
//!    (`ε_zz = 1 − z/z_0`), the side walls keep the stress p, until `max_strain`.
//!
//! Several sintering times and pressures run in one case: per pressure the sample is prepared and
//! heated once, and sintered once; at each t_s in increasing order a copy branches off to cool,
//! relax and be compressed, so that all branches share an identical preparation (as the paper).
//!
//! Temperature: `coupling.mode = "profile"` (default) puts every particle on the protocol's T(t);
//! `"network"` fixes the particles touching a wall at the start of heating to T(t) and solves the
//! heat network ([`crate::heat::network`]) for the others every `heat_every` steps with the
//! conductances of the volume-conserving neck of the current overlaps (docs/design.md, "Explicit
//! loop"), warning when Δt_heat > 0.1·min C_i/ΣK_ij. Luding's radii follow T by eq. 9 at constant
//! mass.
//!
//! Output: per branch a time series (`history_*.csv`: T, density ν = ΣV_i/V_box, coordination
//! number, wall stresses, force extremes, mean k1(T,t)/k1 or δ_p), the compression series
//! (`compression_*.csv`), the normal forces of all contacts after sintering and after
//! cool-down/relax (`forces_*.csv`), PNG plots of all of them, and `summary.json`.

use super::law::ContactModel;
use super::sinter::{FrenkelLaw, LudingLaw, LudingSlot};
use super::{Explicit, Settings, Wall, WallControl, time_step};
use crate::config::ranges::{Range, c, p};
use crate::config::{check, from_value};
use crate::error::{ConfigError, Error, IoError, ModelError};
use crate::heat::conductance::Conductance;
use crate::heat::network::{HeatNetwork, HeatSources, Scheme};
use crate::io::Series as Csv;
use crate::models::frenkel::{FrenkelParams, FrenkelState};
use crate::models::luding::LudingParams;
use crate::packing::Rng;
use crate::particles::Particles;
use crate::plot::{Plot, Series};
use crate::profile::Profile;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::path::Path;

type V3 = Vector3<f64>;

/// Range table of the `explicit_sinter` case keys (registered in `config::ranges::TABLES`).
pub static RANGES: &[Range] = &[
    c("sample.particles", 2.0, 1e6, "1", "number of spheres N"),
    p("sample.mean_radius", 0.0, 1.0, "m", "mean radius r_0"),
    c("sample.radius_spread", 0.0, 0.9, "1", "relative half-width w of the uniform radii r_0(1 +- w)"),
    p("sample.density", 0.0, 1e5, "kg/m^3", "particle material density rho"),
    c("sample.seed", 0.0, 1e15, "1", "seed of the random loose start"),
    c("sample.initial_fraction", 0.01, 0.4, "1", "solid fraction of the loose random start"),
    c("sample.initial_speed", 0.0, 1e3, "m/s", "rms speed of the random initial velocities"),
    p("walls.pressures", 0.0, 1e12, "Pa", "isotropic confining pressure p_3D (one run per value)"),
    p("walls.mass", 0.0, 1e6, "kg", "mass m_w of a stress-controlled wall (eq. 1)"),
    c("walls.damping", 0.0, 1e9, "kg/s", "viscous damping gamma_w of a stress-controlled wall (eq. 1)"),
    c("walls.friction", 0.0, 10.0, "1", "particle-wall friction mu_w"),
    p("protocol.t_prepare", 0.0, 1e9, "s", "compression and relaxation at temperature_cold (t_heat)"),
    p("protocol.t_heat", 0.0, 1e9, "s", "heating ramp duration (t_sinter - t_heat)"),
    c("protocol.t_sinter", 0.0, 1e9, "s", "sintering times t_s (one branch per value)"),
    p("protocol.t_cool", 0.0, 1e9, "s", "cooling ramp duration (t_relax - t_cool)"),
    c("protocol.t_relax", 0.0, 1e9, "s", "relaxation at temperature_cold after cooling (t_f - t_relax)"),
    p("protocol.t0_sinter", 0.0, 1e15, "s", "Luding's relaxation time t_0 while sintering"),
    p("protocol.temperature_cold", 1.0, 1e4, "K", "preparation and final temperature"),
    p("protocol.temperature_hot", 1.0, 1e4, "K", "sintering temperature"),
    c("protocol.prepare_friction", 0.0, 10.0, "1", "particle friction during preparation"),
    p("protocol.output_interval", 0.0, 1e9, "s", "interval of the history rows (averaged wall stress)"),
    p("compression.strain_rate", 0.0, 1e6, "1/s", "constant vertical strain rate of the top wall"),
    p("compression.max_strain", 0.0, 0.9, "1", "vertical strain at which the test stops"),
    p("compression.output_strain", 0.0, 0.5, "1", "strain interval of the compression rows"),
    c("coupling.heat_every", 1.0, 1e9, "1", "explicit steps per heat-network solve"),
    p("coupling.conductivity", 0.0, 1e4, "W/(m K)", "particle thermal conductivity (network mode)"),
    p("coupling.specific_heat", 0.0, 1e6, "J/(kg K)", "particle specific heat (network mode)"),
    p("stepping.dt_fraction", 0.0, 1.0, "1", "time step as a fraction of the shortest contact half-period t_c (eq. 6)"),
    p("stepping.skin", 0.0, 10.0, "1", "Verlet skin relative to r_0"),
    c("stepping.parallel_threshold", 0.0, 1e12, "1", "contact count above which the force sweep runs in parallel"),
];

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct CaseFile {
    kind: String,
    #[serde(default)]
    title: String,
    model: String,
    sample: SampleSpec,
    #[serde(default)]
    walls: WallSpec,
    #[serde(default)]
    protocol: ProtocolSpec,
    #[serde(default)]
    compression: CompressionSpec,
    #[serde(default)]
    coupling: CouplingSpec,
    #[serde(default)]
    stepping: SteppingSpec,
    luding: Option<toml::Value>,
    frenkel: Option<toml::Value>,
}

/// `[sample]`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SampleSpec {
    pub particles: f64,
    pub mean_radius: f64,
    pub radius_spread: f64,
    pub density: f64,
    pub seed: f64,
    pub initial_fraction: f64,
    pub initial_speed: f64,
}
impl Default for SampleSpec {
    fn default() -> Self {
        SampleSpec { particles: 100.0, mean_radius: 1e-3, radius_spread: 0.5, density: 2000.0, seed: 1.0, initial_fraction: 0.2, initial_speed: 0.0 }
    }
}

/// `[walls]`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct WallSpec {
    pub pressures: Vec<f64>,
    pub mass: f64,
    pub damping: f64,
    pub friction: f64,
}
impl Default for WallSpec {
    fn default() -> Self {
        WallSpec { pressures: vec![5.0e4], mass: 0.01, damping: 0.2, friction: 0.0 }
    }
}

/// `[protocol]` (defaults: the paper's times, Luding et al. 2005 Table 1).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProtocolSpec {
    pub t_prepare: f64,
    pub t_heat: f64,
    pub t_sinter: Vec<f64>,
    pub t_cool: f64,
    pub t_relax: f64,
    pub t0_sinter: Option<f64>,
    pub temperature_cold: f64,
    pub temperature_hot: f64,
    pub prepare_friction: f64,
    pub output_interval: Option<f64>,
}
impl Default for ProtocolSpec {
    fn default() -> Self {
        ProtocolSpec {
            t_prepare: 0.2,
            t_heat: 0.1,
            t_sinter: vec![0.1, 1.0],
            t_cool: 0.1,
            t_relax: 0.1,
            t0_sinter: None,
            temperature_cold: 353.15,
            temperature_hot: 413.15,
            prepare_friction: 0.0,
            output_interval: None,
        }
    }
}

/// `[compression]`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct CompressionSpec {
    pub enabled: bool,
    pub strain_rate: f64,
    pub max_strain: f64,
    pub output_strain: f64,
}
impl Default for CompressionSpec {
    fn default() -> Self {
        CompressionSpec { enabled: true, strain_rate: 1.0, max_strain: 0.05, output_strain: 0.001 }
    }
}

/// `coupling.mode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CouplingMode {
    /// Every particle at the protocol's T(t).
    #[default]
    Profile,
    /// Wall-touching particles at T(t), the rest by the heat network.
    Network,
}

/// `[coupling]`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct CouplingSpec {
    pub mode: CouplingMode,
    pub heat_every: f64,
    pub conductivity: Option<f64>,
    pub specific_heat: Option<f64>,
}
impl Default for CouplingSpec {
    fn default() -> Self {
        CouplingSpec { mode: CouplingMode::Profile, heat_every: 100.0, conductivity: None, specific_heat: None }
    }
}

/// `[stepping]`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SteppingSpec {
    pub dt_fraction: f64,
    pub skin: f64,
    pub parallel_threshold: f64,
}
impl Default for SteppingSpec {
    fn default() -> Self {
        SteppingSpec { dt_fraction: 0.02, skin: 0.1, parallel_threshold: 20000.0 }
    }
}

/// The law of a case.
#[derive(Debug, Clone)]
pub enum SinterModel {
    Luding(LudingParams),
    Frenkel(FrenkelParams),
}

/// A validated `explicit_sinter` case.
#[derive(Debug, Clone)]
pub struct ExplicitSinterCase {
    pub title: String,
    pub model: SinterModel,
    pub sample: SampleSpec,
    pub walls: WallSpec,
    pub protocol: ProtocolSpec,
    pub compression: CompressionSpec,
    pub coupling: CouplingSpec,
    pub stepping: SteppingSpec,
}

impl ExplicitSinterCase {
    /// Sorted sintering times [s].
    fn sinter_times(&self) -> Vec<f64> {
        let mut v = self.protocol.t_sinter.clone();
        v.sort_by(|a, b| a.total_cmp(b));
        v
    }
    /// Start of sintering (end of heating) [s].
    fn t_sinter_start(&self) -> f64 {
        self.protocol.t_prepare + self.protocol.t_heat
    }
    /// The temperature history for sintering time `ts` [s] (Fig. 7).
    fn profile(&self, ts: f64) -> Result<Profile, ConfigError> {
        let pr = &self.protocol;
        let t1 = pr.t_prepare;
        let t2 = t1 + pr.t_heat;
        let t3 = t2 + ts;
        let t4 = t3 + pr.t_cool;
        let mut rows = vec![[0.0, pr.temperature_cold], [t1, pr.temperature_cold], [t2, pr.temperature_hot]];
        if ts > 0.0 {
            rows.push([t3, pr.temperature_hot]);
        }
        rows.push([t4, pr.temperature_cold]);
        if pr.t_relax > 0.0 {
            rows.push([t4 + pr.t_relax, pr.temperature_cold]);
        }
        Profile::from_table(&rows)
    }
    fn output_interval(&self) -> f64 {
        self.protocol.output_interval.unwrap_or(0.01 * (self.protocol.t_prepare + self.protocol.t_heat))
    }
}

/// Parses and validates an `explicit_sinter` case (unknown keys rejected; every number checked
/// against [`RANGES`] and the law's table; errors name the key).
pub fn parse_explicit_case(case: &toml::Value) -> Result<ExplicitSinterCase, Error> {
    let f: CaseFile = from_value(case.clone(), "")?;
    if f.kind != "explicit_sinter" {
        return Err(ConfigError::invalid(format!("kind = \"{}\": this entry point runs kind = \"explicit_sinter\" cases", f.kind)).into());
    }
    let s = &f.sample;
    check("sample.particles", s.particles)?;
    if s.particles.fract() != 0.0 {
        return Err(ConfigError::inconsistent("sample.particles", format!("{} must be a whole number", s.particles)).into());
    }
    check("sample.mean_radius", s.mean_radius)?;
    check("sample.radius_spread", s.radius_spread)?;
    check("sample.density", s.density)?;
    check("sample.seed", s.seed)?;
    check("sample.initial_fraction", s.initial_fraction)?;
    check("sample.initial_speed", s.initial_speed)?;
    let w = &f.walls;
    if w.pressures.is_empty() {
        return Err(ConfigError::inconsistent("walls.pressures", "needs at least one pressure").into());
    }
    for &pr in &w.pressures {
        check("walls.pressures", pr)?;
    }
    check("walls.mass", w.mass)?;
    check("walls.damping", w.damping)?;
    check("walls.friction", w.friction)?;
    let pr = &f.protocol;
    check("protocol.t_prepare", pr.t_prepare)?;
    check("protocol.t_heat", pr.t_heat)?;
    if pr.t_sinter.is_empty() {
        return Err(ConfigError::inconsistent("protocol.t_sinter", "needs at least one sintering time").into());
    }
    for &t in &pr.t_sinter {
        check("protocol.t_sinter", t)?;
    }
    check("protocol.t_cool", pr.t_cool)?;
    check("protocol.t_relax", pr.t_relax)?;
    if let Some(t) = pr.t0_sinter {
        check("protocol.t0_sinter", t)?;
    }
    check("protocol.temperature_cold", pr.temperature_cold)?;
    check("protocol.temperature_hot", pr.temperature_hot)?;
    check("protocol.prepare_friction", pr.prepare_friction)?;
    if let Some(t) = pr.output_interval {
        check("protocol.output_interval", t)?;
    }
    let cp = &f.compression;
    check("compression.strain_rate", cp.strain_rate)?;
    check("compression.max_strain", cp.max_strain)?;
    check("compression.output_strain", cp.output_strain)?;
    let cu = &f.coupling;
    check("coupling.heat_every", cu.heat_every)?;
    if cu.heat_every.fract() != 0.0 {
        return Err(ConfigError::inconsistent("coupling.heat_every", format!("{} must be a whole number", cu.heat_every)).into());
    }
    if cu.mode == CouplingMode::Network {
        let k = cu.conductivity.ok_or_else(|| ConfigError::inconsistent("coupling.conductivity", "required by mode = \"network\""))?;
        check("coupling.conductivity", k)?;
        let cp = cu.specific_heat.ok_or_else(|| ConfigError::inconsistent("coupling.specific_heat", "required by mode = \"network\""))?;
        check("coupling.specific_heat", cp)?;
    } else if cu.conductivity.is_some() || cu.specific_heat.is_some() {
        return Err(ConfigError::inconsistent("coupling.conductivity", "only used by mode = \"network\"; remove it").into());
    }
    let st = &f.stepping;
    check("stepping.dt_fraction", st.dt_fraction)?;
    check("stepping.skin", st.skin)?;
    check("stepping.parallel_threshold", st.parallel_threshold)?;
    let model = match f.model.as_str() {
        "luding" => {
            if f.frenkel.is_some() {
                return Err(ConfigError::inconsistent("frenkel", "model = \"luding\" takes a [luding] section; remove [frenkel]").into());
            }
            let v = f.luding.clone().unwrap_or_else(|| toml::Value::Table(toml::Table::new()));
            SinterModel::Luding(LudingParams::from_value(v, s.mean_radius)?)
        }
        "frenkel" => {
            if f.luding.is_some() {
                return Err(ConfigError::inconsistent("luding", "model = \"frenkel\" takes a [frenkel] section; remove [luding]").into());
            }
            let v = f.frenkel.clone().ok_or_else(|| ConfigError::inconsistent("frenkel", "model = \"frenkel\" needs a [frenkel] section"))?;
            if pr.t0_sinter.is_some() {
                return Err(ConfigError::inconsistent("protocol.t0_sinter", "is Luding's relaxation time; model = \"frenkel\" does not use it").into());
            }
            SinterModel::Frenkel(FrenkelParams::from_value(v)?)
        }
        m => return Err(ConfigError::inconsistent("model", format!("\"{m}\": expected \"luding\" or \"frenkel\"")).into()),
    };
    let case = ExplicitSinterCase {
        title: f.title,
        model,
        sample: f.sample,
        walls: f.walls,
        protocol: f.protocol,
        compression: f.compression,
        coupling: f.coupling,
        stepping: f.stepping,
    };
    case.profile(case.sinter_times().last().copied().unwrap_or(0.0))?;
    Ok(case)
}

/// `sinterdem check` for `kind = "explicit_sinter"`.
pub fn check_explicit_case(case: &toml::Value) -> Result<(), Error> {
    let c = parse_explicit_case(case)?;
    check_plan(&c)
}

/// Plausibility of the protocol (issue 16): the particle count against the memory, and the steps
/// and history rows the protocol's simulated time implies at the sample's explicit step.
fn check_plan(c: &ExplicitSinterCase) -> Result<(), Error> {
    use crate::config::plausible::{BYTES_PER_PARTICLE_GENERATE, MAX_STEPS, check_memory};
    check_memory("sample.particles", c.sample.particles, BYTES_PER_PARTICLE_GENERATE)?;
    let pressure = c.walls.pressures[0];
    // the step from a small sample of the same size distribution (building a million-particle
    // sample is the run's work, not the check's)
    let mut small = c.clone();
    small.sample.particles = small.sample.particles.min(200.0);
    let dt = match &small.model {
        SinterModel::Luding(p) => Sample::new(&small, LudingLaw::new(p.clone()), pressure)?.driver.settings.dt,
        SinterModel::Frenkel(p) => Sample::new(&small, FrenkelLaw { params: p.clone() }, pressure)?.driver.settings.dt,
    };
    let pr = &c.protocol;
    let compression = if c.compression.enabled { c.compression.max_strain / c.compression.strain_rate } else { 0.0 };
    let per_pressure = pr.t_prepare + pr.t_heat + pr.t_sinter.iter().map(|ts| ts + pr.t_cool + pr.t_relax + compression).sum::<f64>();
    let total = per_pressure * c.walls.pressures.len() as f64;
    let steps = total / dt;
    if !(steps <= MAX_STEPS) {
        return Err(ConfigError::inconsistent(
            "protocol",
            format!(
                "{} s of simulated time at the explicit step {} s imply about {steps:.0e} steps (at most {MAX_STEPS:e})",
                crate::error::fmt_value(total),
                crate::error::fmt_value(dt)
            ),
        )
        .into());
    }
    let rows = per_pressure / c.output_interval();
    if !(rows <= 1e7) {
        return Err(ConfigError::inconsistent(
            "protocol.output_interval",
            format!("{} s gives about {rows:.0e} history rows per pressure (at most 1e7)", crate::error::fmt_value(c.output_interval())),
        )
        .into());
    }
    Ok(())
}

/// What the protocol needs of a sintering law beyond [`ContactModel`].
pub trait SinterLaw: ContactModel + Clone {
    /// Switches the sintering-time settings on (Luding: t_0 ← t0_sinter) or off.
    fn set_sintering(&mut self, on: bool, t0_sinter: Option<f64>);
    /// Sets the particle friction coefficient (0 during preparation).
    fn set_friction(&mut self, mu: f64);
    /// The law's friction coefficient as given.
    fn friction(&self) -> f64;
    /// Luding's thermal expansion (eq. 9): the radius at `temperature` of a particle whose radius is
    /// `r_ref` at `t_ref` [K]; identity for laws without expansion.
    fn radius(&self, r_ref: f64, t_ref: f64, temperature: f64) -> f64;
    /// A scalar state summary over the contacts and its column name.
    fn state_mean(states: &[((u32, u32), f64, Self::State)]) -> f64;
    const STATE_COLUMN: &'static str;
}

impl SinterLaw for LudingLaw {
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
    const STATE_COLUMN: &'static str = "k1_t_mean_N_per_m";
}

impl SinterLaw for FrenkelLaw {
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
    const STATE_COLUMN: &'static str = "delta_p_mean_m";
}

/// One history row.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Row {
    pub time: f64,
    pub temperature: f64,
    pub density: f64,
    pub coordination: f64,
    /// Mean normal stress on the x⁺, y⁺, z⁺ walls over the row's interval [Pa].
    pub stress: [f64; 3],
    pub box_size: [f64; 3],
    pub force_min: f64,
    pub force_mean: f64,
    pub force_max: f64,
    pub state_mean: f64,
    pub kinetic: f64,
    /// Vertical strain ε_zz (compression rows; 0 before).
    pub strain: f64,
}

const HEADER: [&str; 16] = [
    "time_s",
    "temperature_K",
    "density",
    "coordination",
    "sigma_xx_Pa",
    "sigma_yy_Pa",
    "sigma_zz_Pa",
    "lx_m",
    "ly_m",
    "lz_m",
    "force_min_N",
    "force_mean_N",
    "force_max_N",
    "state_mean",
    "kinetic_J",
    "strain_zz",
];

impl Row {
    fn values(&self) -> Vec<f64> {
        vec![
            self.time,
            self.temperature,
            self.density,
            self.coordination,
            self.stress[0],
            self.stress[1],
            self.stress[2],
            self.box_size[0],
            self.box_size[1],
            self.box_size[2],
            self.force_min,
            self.force_mean,
            self.force_max,
            self.state_mean,
            self.kinetic,
            self.strain,
        ]
    }
}

/// The state of one sample in its history.
#[derive(Clone)]
pub struct Sample<M: SinterLaw> {
    pub particles: Particles,
    pub driver: Explicit<M>,
    /// Radii at `temperature_cold` [m] (eq. 9 reference).
    pub r_ref: Vec<f64>,
    /// Particles whose temperature follows the profile in network mode.
    pub fixed: Vec<bool>,
    /// Heat network solves so far; steps since the last solve.
    pub heat_solves: u64,
    since_heat: u64,
    /// Radius change since the last neighbour rebuild request [m].
    radius_drift: f64,
    /// Stress accumulators for the row average.
    acc: [f64; 3],
    acc_n: u64,
    pub rows: Vec<Row>,
    pub warnings: Vec<String>,
    pub pressure: f64,
}

fn random_loose_sample(case: &ExplicitSinterCase) -> Result<(Particles, f64), Error> {
    let s = &case.sample;
    let n = s.particles as usize;
    let mut rng = Rng::new(s.seed as u64);
    let radii: Vec<f64> = (0..n).map(|_| s.mean_radius * (1.0 + s.radius_spread * (2.0 * rng.uniform() - 1.0))).collect();
    let vol: f64 = radii.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    let side = (vol / s.initial_fraction).cbrt();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| radii[b].total_cmp(&radii[a]));
    let mut pos = vec![V3::zeros(); n];
    let mut placed: Vec<usize> = Vec::with_capacity(n);
    for &a in &order {
        let r = radii[a];
        let mut ok = false;
        for _ in 0..100_000 {
            let x = V3::new(r + (side - 2.0 * r) * rng.uniform(), r + (side - 2.0 * r) * rng.uniform(), r + (side - 2.0 * r) * rng.uniform());
            if placed.iter().all(|&b| (pos[b] - x).norm() > radii[b] + r) {
                pos[a] = x;
                ok = true;
                break;
            }
        }
        if !ok {
            return Err(ConfigError::inconsistent(
                "sample.initial_fraction",
                format!("{}: could not place {n} spheres without overlap; lower it", s.initial_fraction),
            )
            .into());
        }
        placed.push(a);
    }
    let mut p = Particles::default();
    let t0 = case.protocol.temperature_cold;
    let cp = case.coupling.specific_heat.unwrap_or(1.0);
    for a in 0..n {
        p.push(pos[a], radii[a], 0, s.density, cp, t0);
        if s.initial_speed > 0.0 {
            let g = V3::new(rng.normal(), rng.normal(), rng.normal());
            p.velocity[a] = g * (s.initial_speed / 3f64.sqrt());
        }
    }
    Ok((p, side))
}

/// Box edge lengths from the six walls (fixed x⁻,y⁻,z⁻ at 0; walls 3..6 the moving faces).
fn box_size(walls: &[Wall]) -> [f64; 3] {
    [-walls[3].offset, -walls[4].offset, -walls[5].offset]
}

fn update_areas(walls: &mut [Wall]) {
    let l = box_size(walls);
    let a = [l[1] * l[2], l[0] * l[2], l[0] * l[1]];
    for k in 0..3 {
        walls[k].area = a[k];
        walls[k + 3].area = a[k];
    }
}

impl<M: SinterLaw> Sample<M> {
    /// A loose random sample in its box, walls under the pressure `pressure` [Pa].
    pub fn new(case: &ExplicitSinterCase, law: M, pressure: f64) -> Result<Self, Error> {
        let (particles, side) = random_loose_sample(case)?;
        let mut walls = Vec::new();
        for k in 0..3 {
            let mut e = V3::zeros();
            e[k] = 1.0;
            walls.push(Wall::new(e, V3::zeros()));
        }
        for k in 0..3 {
            let mut e = V3::zeros();
            e[k] = -1.0;
            let mut pnt = V3::zeros();
            pnt[k] = side;
            let mut w = Wall::new(e, pnt);
            w.control = WallControl::Stress { pressure, mass: case.walls.mass, damping: case.walls.damping };
            walls.push(w);
        }
        update_areas(&mut walls);
        let mut law = law;
        law.set_friction(case.protocol.prepare_friction);
        let (dt, _tc) = time_step(&law, &particles, case.stepping.dt_fraction, 0.0, true)?;
        let mut st = Settings::new(dt, case.sample.mean_radius);
        st.wall_friction = case.walls.friction;
        st.skin = case.stepping.skin * case.sample.mean_radius;
        let mut driver = Explicit::new(st, law, walls)?;
        driver.parallel_threshold = case.stepping.parallel_threshold as usize;
        let r_ref = particles.radius.clone();
        let n = particles.len();
        Ok(Sample {
            particles,
            driver,
            r_ref,
            fixed: vec![true; n],
            heat_solves: 0,
            since_heat: 0,
            radius_drift: 0.0,
            acc: [0.0; 3],
            acc_n: 0,
            rows: Vec::new(),
            warnings: Vec::new(),
            pressure,
        })
    }

    /// Solid fraction ΣV_i/(L_x L_y L_z) with the current radii.
    pub fn density(&self) -> f64 {
        let l = box_size(&self.driver.walls);
        let v: f64 = self.particles.radius.iter().map(|&r| crate::units::sphere_volume(r)).sum();
        v / (l[0] * l[1] * l[2])
    }

    fn row(&mut self, temperature: f64, strain: f64) -> Row {
        let states = self.driver.contact_states();
        let n = self.particles.len() as f64;
        let forces: Vec<f64> = states.iter().map(|s| s.1).collect();
        let (mut fmin, mut fmax, mut fsum) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
        for &f in &forces {
            fmin = fmin.min(f);
            fmax = fmax.max(f);
            fsum += f;
        }
        let stress = if self.acc_n > 0 {
            [self.acc[0] / self.acc_n as f64, self.acc[1] / self.acc_n as f64, self.acc[2] / self.acc_n as f64]
        } else {
            [self.driver.walls[3].pressure(), self.driver.walls[4].pressure(), self.driver.walls[5].pressure()]
        };
        self.acc = [0.0; 3];
        self.acc_n = 0;
        Row {
            time: self.driver.time,
            temperature,
            density: self.density(),
            coordination: 2.0 * forces.len() as f64 / n,
            stress,
            box_size: box_size(&self.driver.walls),
            force_min: if forces.is_empty() { 0.0 } else { fmin },
            force_mean: if forces.is_empty() { 0.0 } else { fsum / forces.len() as f64 },
            force_max: if forces.is_empty() { 0.0 } else { fmax },
            state_mean: M::state_mean(&states),
            kinetic: self.driver.energy.kinetic,
            strain,
        }
    }

    /// Sets the temperatures for time `t` (profile, or network solve every `heat_every` steps) and
    /// the radii (eq. 9).
    fn thermal(&mut self, case: &ExplicitSinterCase, profile: &Profile, net: &mut Option<HeatNetwork>, t: f64) -> Result<(), Error> {
        let tp = profile.temperature(t);
        let t_cold = case.protocol.temperature_cold;
        match case.coupling.mode {
            CouplingMode::Profile => {
                if self.particles.temperature.first().copied() != Some(tp) {
                    self.particles.temperature.iter_mut().for_each(|x| *x = tp);
                }
            }
            CouplingMode::Network => {
                if t < case.protocol.t_prepare {
                    self.particles.temperature.iter_mut().for_each(|x| *x = tp);
                } else {
                    if net.is_none() {
                        *net = Some(self.build_network(case, profile)?);
                        self.since_heat = case.coupling.heat_every as u64;
                    }
                    self.since_heat += 1;
                    if self.since_heat >= case.coupling.heat_every as u64 {
                        let dth = self.since_heat as f64 * self.driver.settings.dt;
                        self.since_heat = 0;
                        self.heat_solve(case, net.as_mut().unwrap(), t - dth, dth)?;
                    }
                }
            }
        }
        let mut drift: f64 = 0.0;
        for a in 0..self.particles.len() {
            let r = self.driver.law.radius(self.r_ref[a], t_cold, self.particles.temperature[a]);
            drift = drift.max((r - self.particles.radius[a]).abs());
            self.particles.radius[a] = r;
        }
        self.radius_drift += drift;
        if self.radius_drift > 0.05 * self.driver.settings.skin {
            self.driver.invalidate();
            self.radius_drift = 0.0;
        }
        Ok(())
    }

    fn build_network(&mut self, case: &ExplicitSinterCase, profile: &Profile) -> Result<HeatNetwork, Error> {
        let n = self.particles.len();
        let walls = &self.driver.walls;
        let mut fixed = vec![None; n];
        for a in 0..n {
            let x = self.particles.position[a];
            let r = self.particles.radius[a];
            if walls.iter().any(|w| w.normal.dot(&x) - w.offset - r < 0.5 * r) {
                fixed[a] = Some(0);
            }
        }
        self.fixed = fixed.iter().map(|f| f.is_some()).collect();
        let cp = case.coupling.specific_heat.unwrap_or(1.0);
        let cap: Vec<f64> = self.particles.mass.iter().map(|m| m * cp).collect();
        let sources = HeatSources { fixed, profiles: vec![profile.clone()], ..Default::default() };
        Ok(HeatNetwork::new(cap, sources, Scheme::BackwardEuler, 1e-10))
    }

    fn heat_solve(&mut self, case: &ExplicitSinterCase, net: &mut HeatNetwork, t: f64, dt: f64) -> Result<(), Error> {
        let kappa = case.coupling.conductivity.unwrap_or(0.0);
        let contacts = self.driver.contacts();
        let pipes: Vec<[u32; 2]> = contacts.iter().map(|&(i, j)| [i, j]).collect();
        let law = Conductance::default();
        let mut k = Vec::with_capacity(pipes.len());
        let n = self.particles.len();
        let mut sum_k = vec![0.0; n];
        for &[i, j] in &pipes {
            let (i, j) = (i as usize, j as usize);
            let (ri, rj) = (self.particles.radius[i], self.particles.radius[j]);
            let h = ri + rj - (self.particles.position[i] - self.particles.position[j]).norm();
            let a = if h > 0.0 {
                crate::neck::solve(ri, rj, h).map_err(|e| ModelError::new(format!("heat step at t = {t:.4e} s, contact ({i}, {j}): {e}")))?.a
            } else {
                0.0
            };
            let kk = law.pipe(kappa, kappa, ri, rj, a).pair;
            sum_k[i] += kk;
            sum_k[j] += kk;
            k.push(kk);
        }
        let mut fastest = f64::INFINITY;
        for a in 0..n {
            if !self.fixed[a] && sum_k[a] > 0.0 {
                fastest = fastest.min(self.particles.capacity[a] / sum_k[a]);
            }
        }
        if dt > 0.1 * fastest && !self.warnings.iter().any(|w| w.starts_with("heat_every")) {
            let msg = format!(
                "heat_every: Δt_heat = {dt:.3e} s exceeds 0.1·min C_i/ΣK_ij = {:.3e} s (the fastest thermal time); lower coupling.heat_every",
                0.1 * fastest
            );
            eprintln!("warning: {msg}");
            self.warnings.push(msg);
        }
        net.set_topology(&pipes)?;
        net.step(t, dt, &mut self.particles.temperature, &k)?;
        self.heat_solves += 1;
        Ok(())
    }

    /// Advances to time `until` [s] under `profile`, writing a history row every `interval`.
    fn advance(
        &mut self,
        case: &ExplicitSinterCase,
        profile: &Profile,
        net: &mut Option<HeatNetwork>,
        until: f64,
        interval: f64,
        sintering: bool,
        strain_of: Option<(f64, f64)>,
    ) -> Result<(), Error> {
        let t0s = case.protocol.t0_sinter;
        self.driver.law.set_sintering(sintering, t0s);
        let dt = self.driver.settings.dt;
        let mut next_row = self.rows.last().map(|r| r.time + interval).unwrap_or(0.0);
        while self.driver.time + 0.5 * dt < until {
            let t = self.driver.time + dt;
            self.thermal(case, profile, net, t)?;
            update_areas(&mut self.driver.walls);
            self.driver.step(&mut self.particles)?;
            for k in 0..3 {
                self.acc[k] += self.driver.walls[k + 3].pressure();
            }
            self.acc_n += 1;
            if self.driver.time + 0.5 * dt >= next_row {
                let strain = strain_of.map(|(z0, _)| 1.0 - box_size(&self.driver.walls)[2] / z0).unwrap_or(0.0);
                let r = self.row(profile.temperature(self.driver.time), strain);
                self.rows.push(r);
                next_row = self.driver.time + interval;
            }
        }
        Ok(())
    }
}

/// Results of one branch (pressure, sintering time).
#[derive(Debug, Clone, Serialize)]
pub struct Branch {
    pub pressure: f64,
    pub t_sinter: f64,
    pub history: Vec<Row>,
    pub compression: Vec<Row>,
    /// Normal forces of all contacts at the end of sintering and after cool-down and relaxation [N].
    pub forces_sintered: Vec<f64>,
    pub forces_cooled: Vec<f64>,
    pub density_prepared: f64,
    pub density_sintered: f64,
    pub density_final: f64,
    pub coordination_final: f64,
    pub min_force_sintered: f64,
    pub min_force_cooled: f64,
    pub max_force_cooled: f64,
    pub peak_stress: f64,
    pub strain_at_peak: f64,
    /// Secant stiffness dσ_zz/dε_zz over the first 20 % of the strain to the peak [Pa].
    pub stiffness: f64,
    pub heat_solves: u64,
    pub steps: u64,
}

/// Result of a whole case.
#[derive(Debug, Clone, Serialize)]
pub struct ExplicitSinterRun {
    pub title: String,
    pub model: String,
    pub particles: usize,
    pub dt: f64,
    pub branches: Vec<Branch>,
    pub warnings: Vec<String>,
    pub wall_seconds: f64,
}

fn forces_of<M: SinterLaw>(s: &Sample<M>) -> Vec<f64> {
    s.driver.contact_states().iter().map(|c| c.1).collect()
}

fn run_law<M: SinterLaw>(case: &ExplicitSinterCase, law: M, progress: bool) -> Result<(Vec<Branch>, f64, Vec<String>), Error> {
    let mut branches = Vec::new();
    let mut warnings = Vec::new();
    let mut dt_used = 0.0;
    let times = case.sinter_times();
    let interval = case.output_interval();
    let t_s0 = case.t_sinter_start();
    for &pressure in &case.walls.pressures {
        let mut s = Sample::new(case, law.clone(), pressure)?;
        dt_used = s.driver.settings.dt;
        let mut net: Option<HeatNetwork> = None;
        let profile_max = case.profile(*times.last().unwrap())?;
        if progress {
            eprintln!("explicit_sinter: p = {pressure:.3e} Pa, {} particles, dt = {:.3e} s: prepare", s.particles.len(), dt_used);
        }
        s.advance(case, &profile_max, &mut net, case.protocol.t_prepare, interval, false, None)?;
        let density_prepared = s.density();
        let mu = law.friction();
        s.driver.law.set_friction(mu);
        s.advance(case, &profile_max, &mut net, t_s0, interval, false, None)?;
        for &ts in &times {
            if progress {
                eprintln!("explicit_sinter: p = {pressure:.3e} Pa: sinter to t_s = {ts} s");
            }
            s.advance(case, &profile_max, &mut net, t_s0 + ts, interval, true, None)?;
            let density_sintered = s.density();
            let forces_sintered = forces_of(&s);
            let mut b = s.clone();
            let mut bnet: Option<HeatNetwork> = None;
            if case.coupling.mode == CouplingMode::Network && net.is_some() {
                let prof = case.profile(ts)?;
                bnet = Some(b.build_network_keep(case, &prof)?);
            }
            let profile = case.profile(ts)?;
            let t_end = t_s0 + ts + case.protocol.t_cool + case.protocol.t_relax;
            b.advance(case, &profile, &mut bnet, t_end, interval, false, None)?;
            let density_final = b.density();
            let forces_cooled = forces_of(&b);
            let coordination_final = 2.0 * forces_cooled.len() as f64 / b.particles.len() as f64;
            let history = b.rows.clone();
            let mut compression = Vec::new();
            if case.compression.enabled {
                let z0 = box_size(&b.driver.walls)[2];
                let v = case.compression.strain_rate * z0;
                b.driver.walls[5].control = WallControl::Velocity;
                b.driver.walls[5].velocity = v;
                let duration = case.compression.max_strain / case.compression.strain_rate;
                let t_start = b.driver.time;
                b.rows.clear();
                let first = b.row(profile.temperature(t_start), 0.0);
                b.rows.push(first);
                let d_int = case.compression.output_strain / case.compression.strain_rate;
                b.advance(case, &profile, &mut bnet, t_start + duration, d_int, false, Some((z0, v)))?;
                compression = b.rows.clone();
            }
            // no contact left: 0 (as in the history rows), with a warning below
            let min_f = |f: &[f64]| if f.is_empty() { 0.0 } else { f.iter().copied().fold(f64::INFINITY, f64::min) };
            let max_f = |f: &[f64]| if f.is_empty() { 0.0 } else { f.iter().copied().fold(f64::NEG_INFINITY, f64::max) };
            for (f, when) in [(&forces_sintered, "after sintering"), (&forces_cooled, "after cool-down")] {
                if f.is_empty() {
                    warnings.push(format!("p = {pressure} Pa, t_sinter = {ts} s: no contacts {when}; its force extremes are reported as 0"));
                }
            }
            let (mut peak, mut eps_peak) = (if compression.is_empty() { 0.0 } else { f64::NEG_INFINITY }, 0.0);
            for r in &compression {
                if r.stress[2] > peak {
                    peak = r.stress[2];
                    eps_peak = r.strain;
                }
            }
            let stiffness = if compression.len() > 2 && eps_peak > 0.0 {
                let e1 = 0.2 * eps_peak;
                let r1 = compression.iter().find(|r| r.strain >= e1).unwrap();
                (r1.stress[2] - compression[0].stress[2]) / r1.strain.max(f64::MIN_POSITIVE)
            } else {
                // the stress never rose above its start (or no compression test): no resistance
                if case.compression.enabled {
                    warnings.push(format!(
                        "p = {pressure} Pa, t_sinter = {ts} s: the compression stress never rose above its initial value; stiffness reported as 0"
                    ));
                }
                0.0
            };
            warnings.extend(b.warnings.iter().cloned());
            branches.push(Branch {
                pressure,
                t_sinter: ts,
                history,
                compression,
                min_force_sintered: min_f(&forces_sintered),
                min_force_cooled: min_f(&forces_cooled),
                max_force_cooled: max_f(&forces_cooled),
                forces_sintered,
                forces_cooled,
                density_prepared,
                density_sintered,
                density_final,
                coordination_final,
                peak_stress: peak,
                strain_at_peak: eps_peak,
                stiffness,
                heat_solves: b.heat_solves,
                steps: b.driver.counters.steps,
            });
            if progress {
                let br = branches.last().unwrap();
                eprintln!(
                    "  t_s = {ts}: density sintered {:.4}, final {:.4}, min force after cooling {:.3e} N, peak sigma_zz {:.4e} Pa",
                    br.density_sintered, br.density_final, br.min_force_cooled, br.peak_stress
                );
            }
        }
        warnings.extend(s.warnings.iter().cloned());
    }
    warnings.sort();
    warnings.dedup();
    Ok((branches, dt_used, warnings))
}

impl<M: SinterLaw> Sample<M> {
    /// A fresh heat network for a branch (same fixed particles, the branch's profile).
    fn build_network_keep(&mut self, case: &ExplicitSinterCase, profile: &Profile) -> Result<HeatNetwork, Error> {
        let n = self.particles.len();
        let fixed: Vec<Option<u32>> = (0..n).map(|a| if self.fixed[a] { Some(0) } else { None }).collect();
        let cp = case.coupling.specific_heat.unwrap_or(1.0);
        let cap: Vec<f64> = self.particles.mass.iter().map(|m| m * cp).collect();
        let sources = HeatSources { fixed, profiles: vec![profile.clone()], ..Default::default() };
        Ok(HeatNetwork::new(cap, sources, Scheme::BackwardEuler, 1e-10))
    }
}

/// Runs a parsed case (no files written).
pub fn run_explicit(case: &ExplicitSinterCase, progress: bool) -> Result<ExplicitSinterRun, Error> {
    let start = std::time::Instant::now();
    let n = case.sample.particles as usize;
    let (branches, dt, warnings, model) = match &case.model {
        SinterModel::Luding(p) => {
            let (b, dt, w) = run_law(case, LudingLaw::new(p.clone()), progress)?;
            (b, dt, w, "luding")
        }
        SinterModel::Frenkel(p) => {
            let (b, dt, w) = run_law(case, FrenkelLaw { params: p.clone() }, progress)?;
            (b, dt, w, "frenkel")
        }
    };
    Ok(ExplicitSinterRun { title: case.title.clone(), model: model.into(), particles: n, dt, branches, warnings, wall_seconds: start.elapsed().as_secs_f64() })
}

fn tag(b: &Branch) -> String {
    format!("p{:e}_ts{}", b.pressure, b.t_sinter)
}

fn label(b: &Branch, pressures: usize) -> String {
    if pressures > 1 { format!("p={:.0e} Pa, ts={} s", b.pressure, b.t_sinter) } else { format!("ts={} s", b.t_sinter) }
}

/// Probability density of `f/⟨|f|⟩` in `bins` bins over [−3, 5].
fn force_pdf(forces: &[f64]) -> Vec<(f64, f64)> {
    if forces.is_empty() {
        return Vec::new();
    }
    let mean = forces.iter().map(|f| f.abs()).sum::<f64>() / forces.len() as f64;
    let (lo, hi, bins) = (-3.0, 5.0, 32usize);
    let w = (hi - lo) / bins as f64;
    let mut h = vec![0usize; bins];
    for &f in forces {
        let x = f / mean;
        let k = ((x - lo) / w).floor();
        if k >= 0.0 && (k as usize) < bins {
            h[k as usize] += 1;
        }
    }
    h.iter().enumerate().map(|(k, &c)| (lo + (k as f64 + 0.5) * w, c as f64 / (forces.len() as f64 * w))).collect()
}

/// Writes the series, forces, plots and `summary.json` of a run into `out_dir`; returns the summary.
pub fn write_outputs(case: &ExplicitSinterCase, run: &ExplicitSinterRun, out_dir: &Path) -> Result<serde_json::Value, Error> {
    std::fs::create_dir_all(out_dir).map_err(|e| IoError::new(out_dir, e))?;
    let mut header: Vec<&str> = HEADER.to_vec();
    let state_col = match case.model {
        SinterModel::Luding(_) => LudingLaw::STATE_COLUMN,
        SinterModel::Frenkel(_) => FrenkelLaw::STATE_COLUMN,
    };
    header[13] = state_col;
    for b in &run.branches {
        let t = tag(b);
        let mut csv = Csv::create(&out_dir.join(format!("history_{t}.csv")), &header)?;
        for r in &b.history {
            csv.row(&r.values())?;
        }
        if !b.compression.is_empty() {
            let mut csv = Csv::create(&out_dir.join(format!("compression_{t}.csv")), &header)?;
            for r in &b.compression {
                csv.row(&r.values())?;
            }
        }
        let mut csv = Csv::create(&out_dir.join(format!("forces_{t}.csv")), &["stage", "normal_force_N"])?;
        for &f in &b.forces_sintered {
            csv.row(&[0.0, f])?;
        }
        for &f in &b.forces_cooled {
            csv.row(&[1.0, f])?;
        }
    }
    let np = case.walls.pressures.len();
    let mk = |title: &str, x: &str, y: &str, f: &dyn Fn(&Branch) -> Vec<(f64, f64)>| {
        let mut pl = Plot::new(title).labels(x, y);
        for b in &run.branches {
            pl.add(Series::new(label(b, np), f(b)));
        }
        pl
    };
    let plots = [
        (
            "density.png",
            mk("Density during the sample history", "time t [s]", "solid fraction nu [1]", &|b: &Branch| {
                b.history.iter().map(|r| (r.time, r.density)).collect()
            }),
        ),
        (
            "coordination.png",
            mk("Coordination number", "time t [s]", "contacts per particle C [1]", &|b: &Branch| b.history.iter().map(|r| (r.time, r.coordination)).collect()),
        ),
        (
            "wall_stress.png",
            mk("Top-wall stress / confining pressure", "time t [s]", "sigma_zz / p [1]", &|b: &Branch| {
                b.history.iter().map(|r| (r.time, r.stress[2] / b.pressure)).collect()
            }),
        ),
        ("temperature.png", mk("Mean temperature", "time t [s]", "T [K]", &|b: &Branch| b.history.iter().map(|r| (r.time, r.temperature)).collect())),
        (
            "state.png",
            mk(
                match case.model {
                    SinterModel::Luding(_) => "Mean k1(T,t) of the contacts",
                    SinterModel::Frenkel(_) => "Mean plastic overlap of the contacts",
                },
                "time t [s]",
                match case.model {
                    SinterModel::Luding(_) => "k1(T,t) [N/m]",
                    SinterModel::Frenkel(_) => "delta_p [m]",
                },
                &|b: &Branch| b.history.iter().map(|r| (r.time, r.state_mean)).collect(),
            ),
        ),
        (
            "force_extremes.png",
            mk("Smallest contact normal force (negative: attractive)", "time t [s]", "f_min [N]", &|b: &Branch| {
                b.history.iter().map(|r| (r.time, r.force_min)).collect()
            }),
        ),
        ("force_pdf_sintered.png", mk("Normal-force pdf after sintering", "f / <|f|> [1]", "P [1]", &|b: &Branch| force_pdf(&b.forces_sintered))),
        ("force_pdf_cooled.png", mk("Normal-force pdf after cool-down and relaxation", "f / <|f|> [1]", "P [1]", &|b: &Branch| force_pdf(&b.forces_cooled))),
        (
            "compression_stress.png",
            mk("Compression test: vertical stress", "strain eps_zz [1]", "sigma_zz [Pa]", &|b: &Branch| {
                b.compression.iter().map(|r| (r.strain, r.stress[2])).collect()
            }),
        ),
        (
            "compression_density.png",
            mk("Compression test: density", "strain eps_zz [1]", "solid fraction nu [1]", &|b: &Branch| {
                b.compression.iter().map(|r| (r.strain, r.density)).collect()
            }),
        ),
    ];
    for (name, pl) in plots.iter() {
        pl.save_png(&out_dir.join(name))?;
    }
    let summary = summary_json(run);
    crate::io::write_json(&out_dir.join("summary.json"), &summary)?;
    Ok(summary)
}

/// The `summary.json` value of a run.
pub fn summary_json(run: &ExplicitSinterRun) -> serde_json::Value {
    let branches: Vec<serde_json::Value> = run
        .branches
        .iter()
        .map(|b| {
            json!({
                "pressure_Pa": b.pressure,
                "t_sinter_s": b.t_sinter,
                "density_prepared": b.density_prepared,
                "density_sintered": b.density_sintered,
                "density_final": b.density_final,
                "coordination_final": b.coordination_final,
                "min_force_sintered_N": b.min_force_sintered,
                "min_force_cooled_N": b.min_force_cooled,
                "max_force_cooled_N": b.max_force_cooled,
                "peak_stress_Pa": b.peak_stress,
                "strain_at_peak": b.strain_at_peak,
                "stiffness_Pa": b.stiffness,
                "heat_solves": b.heat_solves,
                "steps": b.steps,
            })
        })
        .collect();
    json!({
        "title": run.title,
        "model": run.model,
        "particles": run.particles,
        "dt_s": run.dt,
        "wall_seconds": run.wall_seconds,
        "warnings": run.warnings,
        "branches": branches,
    })
}

/// Runs an `explicit_sinter` case and writes its outputs into `out_dir` (module docs); returns the
/// summary (also `summary.json`).
pub fn run_explicit_case(case: &toml::Value, out_dir: &Path, progress: bool) -> Result<serde_json::Value, Error> {
    let c = parse_explicit_case(case)?;
    let run = run_explicit(&c, progress)?;
    for w in &run.warnings {
        eprintln!("warning: {w}");
    }
    write_outputs(&c, &run, out_dir)
}

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

use crate::config::from_value;
use crate::config::ranges::{Range, c, p};
use crate::explicit::law::ContactModel;
use crate::explicit::sinter::{FrenkelLaw, LudingLaw, LudingSlot};
use crate::explicit::{Explicit, Settings, Wall, WallControl, time_step};

/// Checks a key of this kind (its own [`RANGES`], the laws' tables, then the shared keys).
fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    let own = crate::config::ranges::lookup_in(&[RANGES, crate::models::luding::RANGES, crate::models::frenkel::RANGES], key);
    match own {
        Some(r) => r.check(key, v),
        None => crate::config::check(key, v),
    }
}
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
    #[serde(default)]
    output: OutputSpec,
}

/// `[output]` of an `explicit_sinter` case.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSpec {
    /// Write `DIR/checkpoint.json` every this many explicit steps, counted over the whole protocol
    /// (all pressures and branches); 0: never (`sinterdem run --checkpoint-every N`).
    pub checkpoint_every: f64,
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
    pub output: OutputSpec,
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
    let ck = check("output.checkpoint_every", f.output.checkpoint_every)?;
    if ck.fract() != 0.0 {
        return Err(ConfigError::inconsistent("output.checkpoint_every", format!("{ck} must be a whole number of steps")).into());
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
        output: f.output,
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
pub trait SinterLaw: ContactModel<State: Serialize + serde::de::DeserializeOwned> + Clone {
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
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
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
            tracing::warn!("{msg}");
            self.warnings.push(msg);
        }
        net.set_topology(&pipes)?;
        net.step(t, dt, &mut self.particles.temperature, &k)?;
        self.heat_solves += 1;
        Ok(())
    }

    /// Advances to time `until` [s] under `profile`, writing a history row every `interval`.
    /// `clock` counts the steps of the whole protocol; when it reaches a multiple of its
    /// checkpoint interval the advance pauses and returns `Ok(false)` (call it again to go on:
    /// the continuation is the same as if it had not paused); `Ok(true)` once `until` is reached.
    fn advance(
        &mut self,
        case: &ExplicitSinterCase,
        profile: &Profile,
        net: &mut Option<HeatNetwork>,
        until: f64,
        interval: f64,
        sintering: bool,
        strain_of: Option<(f64, f64)>,
        clock: &mut StepClock,
    ) -> Result<bool, Error> {
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
            if clock.tick() {
                return Ok(false);
            }
        }
        Ok(true)
    }
}

/// Results of one branch (pressure, sintering time).
#[derive(Debug, Clone, Serialize, Deserialize)]
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

/// Counts the explicit steps of a whole protocol and says when a checkpoint is due.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepClock {
    /// Steps so far (all pressures and branches).
    pub steps: u64,
    /// Checkpoint interval [steps]; 0: never.
    pub every: u64,
}

impl StepClock {
    fn tick(&mut self) -> bool {
        self.steps += 1;
        self.every > 0 && self.steps.is_multiple_of(self.every)
    }
}

/// Where the protocol is (module docs: prepare → heat → per t_s: sinter, then a branch that
/// cools, relaxes and is compressed). Checkpoints record it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "stage", rename_all = "snake_case")]
pub enum Stage {
    /// A new sample for the pressure `pressure_index`.
    Start,
    Prepare,
    Heat,
    /// Sintering the trunk to the `k`-th sintering time.
    Sinter {
        k: usize,
    },
    /// The `k`-th branch cooling and relaxing.
    Cool {
        k: usize,
    },
    /// The `k`-th branch under the compression test.
    Compress {
        k: usize,
    },
}

/// Values of the branch in progress taken at earlier stages.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct Partial {
    density_prepared: f64,
    density_sintered: f64,
    forces_sintered: Vec<f64>,
    density_final: f64,
    forces_cooled: Vec<f64>,
    coordination_final: f64,
    history: Vec<Row>,
    /// Compression test: initial height z_0 [m], top-wall speed [m/s], start time [s].
    z0: f64,
    speed: f64,
    t_start: f64,
}

/// A [`Sample`] in a checkpoint: what is not rebuilt from the case by [`Sample::new`].
#[derive(Debug, Clone, Serialize, Deserialize)]
struct SampleState<S> {
    pressure: f64,
    #[serde(with = "crate::io::serde_v3::vec")]
    position: Vec<V3>,
    #[serde(with = "crate::io::serde_v3::vec")]
    velocity: Vec<V3>,
    #[serde(with = "crate::io::serde_v3::vec")]
    angular_velocity: Vec<V3>,
    #[serde(with = "crate::io::serde_v3::vec")]
    rotation: Vec<V3>,
    radius: Vec<f64>,
    temperature: Vec<f64>,
    /// The law's particle friction at the checkpoint (the preparation runs frictionless).
    friction: f64,
    driver: crate::explicit::DriverState<S>,
    fixed: Vec<bool>,
    heat_solves: u64,
    since_heat: u64,
    radius_drift: f64,
    acc: [f64; 3],
    acc_n: u64,
    rows: Vec<Row>,
    warnings: Vec<String>,
    /// The sample had a heat network (rebuilt on resume from `fixed`, which fully defines it).
    network: bool,
}

impl<M: SinterLaw> Sample<M> {
    fn save(&self, network: bool) -> SampleState<M::State> {
        let p = &self.particles;
        SampleState {
            pressure: self.pressure,
            position: p.position.clone(),
            velocity: p.velocity.clone(),
            angular_velocity: p.angular_velocity.clone(),
            rotation: p.rotation.clone(),
            radius: p.radius.clone(),
            temperature: p.temperature.clone(),
            friction: self.driver.law.friction(),
            driver: self.driver.save_state(),
            fixed: self.fixed.clone(),
            heat_solves: self.heat_solves,
            since_heat: self.since_heat,
            radius_drift: self.radius_drift,
            acc: self.acc,
            acc_n: self.acc_n,
            rows: self.rows.clone(),
            warnings: self.warnings.clone(),
            network,
        }
    }

    /// The sample of `st`: built again from the case (masses, radii at T_cold, step), then the
    /// saved state laid over it; `what` names it in errors.
    fn restore(case: &ExplicitSinterCase, law: M, st: SampleState<M::State>, what: &str) -> Result<Self, String> {
        let mut s = Sample::new(case, law, st.pressure).map_err(|e| format!("{what}: {e}"))?;
        let n = s.particles.len();
        let vecs = [("position", &st.position), ("velocity", &st.velocity), ("angular_velocity", &st.angular_velocity), ("rotation", &st.rotation)];
        for (k, v) in vecs {
            if v.len() != n || !v.iter().all(|x| x.iter().all(|c| c.is_finite())) {
                return Err(format!("{what}.{k}: {} values, expected {n} finite vectors (sample.particles = {n})", v.len()));
            }
        }
        if st.radius.len() != n || !st.radius.iter().all(|r| r.is_finite() && *r > 0.0) {
            return Err(format!("{what}.radius: expected {n} positive radii [m]"));
        }
        if st.temperature.len() != n || !st.temperature.iter().all(|t| t.is_finite() && *t > 0.0) {
            return Err(format!("{what}.temperature: expected {n} positive temperatures [K]"));
        }
        if st.fixed.len() != n {
            return Err(format!("{what}.fixed: {} flags, expected {n}", st.fixed.len()));
        }
        if !(st.friction.is_finite() && st.friction >= 0.0) || !(st.radius_drift.is_finite() && st.acc.iter().all(|a| a.is_finite())) {
            return Err(format!("{what}: friction, radius drift or stress accumulator out of range"));
        }
        s.driver.restore_state(st.driver, n).map_err(|e| format!("{what}.driver.{e}"))?;
        let p = &mut s.particles;
        p.position = st.position;
        p.velocity = st.velocity;
        p.angular_velocity = st.angular_velocity;
        p.rotation = st.rotation;
        p.radius = st.radius;
        p.temperature = st.temperature;
        s.driver.law.set_friction(st.friction);
        s.fixed = st.fixed;
        s.heat_solves = st.heat_solves;
        s.since_heat = st.since_heat;
        s.radius_drift = st.radius_drift;
        s.acc = st.acc;
        s.acc_n = st.acc_n;
        s.rows = st.rows;
        s.warnings = st.warnings;
        Ok(s)
    }
}

/// Format tag of `explicit_sinter` checkpoints.
pub const EXPLICIT_CHECKPOINT_FORMAT: &str = "sinterdem-explicit-checkpoint-1";

/// `DIR/checkpoint.json` of an `explicit_sinter` run: the case as run, where the protocol is, the
/// trunk sample and the branch in progress, and the finished branches.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct ExplicitCheckpoint<S> {
    format: String,
    case_toml: String,
    model: String,
    pressure_index: usize,
    stage: Stage,
    steps: u64,
    dt_used: f64,
    trunk: Option<SampleState<S>>,
    branch: Option<SampleState<S>>,
    partial: Partial,
    branches: Vec<Branch>,
    warnings: Vec<String>,
    /// Wall time before the checkpoint [s].
    wall_before: f64,
}

/// The protocol's state machine: one call of [`Machine::run`] takes the protocol from `stage` to
/// its end, pausing at every checkpoint.
struct Machine<M: SinterLaw> {
    law: M,
    pressure_index: usize,
    stage: Stage,
    trunk: Option<Sample<M>>,
    net: Option<HeatNetwork>,
    branch: Option<Sample<M>>,
    bnet: Option<HeatNetwork>,
    partial: Partial,
    branches: Vec<Branch>,
    warnings: Vec<String>,
    dt_used: f64,
    clock: StepClock,
    wall_before: f64,
}

/// Checkpoint writing of a run: where, and the case text the checkpoint carries.
pub struct CheckpointSink<'a> {
    pub dir: &'a Path,
    /// The case as run (overrides applied), TOML.
    pub case_toml: String,
    /// Stop right after the checkpoint at or after this step (as if killed there; for tests).
    pub stop_after: Option<u64>,
}

fn forces_of<M: SinterLaw>(s: &Sample<M>) -> Vec<f64> {
    s.driver.contact_states().iter().map(|c| c.1).collect()
}

impl<M: SinterLaw> Machine<M> {
    fn new(law: M, every: u64) -> Self {
        Machine {
            law,
            pressure_index: 0,
            stage: Stage::Start,
            trunk: None,
            net: None,
            branch: None,
            bnet: None,
            partial: Partial::default(),
            branches: Vec::new(),
            warnings: Vec::new(),
            dt_used: 0.0,
            clock: StepClock { steps: 0, every },
            wall_before: 0.0,
        }
    }

    fn checkpoint(&self, case_toml: &str, model: &str, wall: f64) -> ExplicitCheckpoint<M::State> {
        ExplicitCheckpoint {
            format: EXPLICIT_CHECKPOINT_FORMAT.into(),
            case_toml: case_toml.into(),
            model: model.into(),
            pressure_index: self.pressure_index,
            stage: self.stage,
            steps: self.clock.steps,
            dt_used: self.dt_used,
            trunk: self.trunk.as_ref().map(|s| s.save(self.net.is_some())),
            branch: self.branch.as_ref().map(|s| s.save(self.bnet.is_some())),
            partial: self.partial.clone(),
            branches: self.branches.clone(),
            warnings: self.warnings.clone(),
            wall_before: self.wall_before + wall,
        }
    }

    /// The machine of a checkpoint, checked against the case (the error says what does not fit).
    fn restore(case: &ExplicitSinterCase, law: M, ck: ExplicitCheckpoint<M::State>, every: u64) -> Result<Self, String> {
        let times = case.sinter_times().len();
        let np = case.walls.pressures.len();
        if ck.pressure_index > np || (ck.pressure_index == np && ck.stage != Stage::Start) {
            return Err(format!("pressure_index = {}: the case has {np} pressures", ck.pressure_index));
        }
        let k = match ck.stage {
            Stage::Sinter { k } | Stage::Cool { k } | Stage::Compress { k } => Some(k),
            _ => None,
        };
        if let Some(k) = k
            && k >= times
        {
            return Err(format!("stage {:?}: the case has {times} sintering times", ck.stage));
        }
        let needs_trunk = ck.stage != Stage::Start;
        let needs_branch = matches!(ck.stage, Stage::Cool { .. } | Stage::Compress { .. });
        if ck.trunk.is_some() != needs_trunk || ck.branch.is_some() != needs_branch {
            return Err(format!("stage {:?} does not match the samples it carries (trunk {}, branch {})", ck.stage, ck.trunk.is_some(), ck.branch.is_some()));
        }
        if ck.branches.len() != ck.pressure_index * times + k.unwrap_or(0) {
            return Err(format!("{} finished branches do not fit pressure {} at stage {:?}", ck.branches.len(), ck.pressure_index, ck.stage));
        }
        if !(ck.dt_used.is_finite() && ck.dt_used >= 0.0) {
            return Err(format!("dt_used = {}: expected a finite step [s]", ck.dt_used));
        }
        let mut m = Machine::new(law.clone(), every);
        let profile_max = case.profile(*case.sinter_times().last().unwrap()).map_err(|e| e.to_string())?;
        if let Some(st) = ck.trunk {
            let net = st.network;
            let mut s = Sample::restore(case, law.clone(), st, "trunk")?;
            if net {
                m.net = Some(s.build_network_keep(case, &profile_max).map_err(|e| e.to_string())?);
            }
            m.trunk = Some(s);
        }
        if let Some(st) = ck.branch {
            let net = st.network;
            let mut s = Sample::restore(case, law.clone(), st, "branch")?;
            if net {
                let ts = case.sinter_times()[k.unwrap_or(0)];
                m.bnet = Some(s.build_network_keep(case, &case.profile(ts).map_err(|e| e.to_string())?).map_err(|e| e.to_string())?);
            }
            m.branch = Some(s);
        }
        m.pressure_index = ck.pressure_index;
        m.stage = ck.stage;
        m.partial = ck.partial;
        m.branches = ck.branches;
        m.warnings = ck.warnings;
        m.dt_used = ck.dt_used;
        m.clock.steps = ck.steps;
        m.wall_before = ck.wall_before;
        Ok(m)
    }

    /// Runs the protocol from the current stage to its end; `Ok(false)` when stopped after a
    /// checkpoint by `sink.stop_after`.
    fn run(&mut self, case: &ExplicitSinterCase, model: &str, mut sink: Option<&mut CheckpointSink>, log: &mut dyn FnMut(&str)) -> Result<bool, Error> {
        let wall = std::time::Instant::now();
        let times = case.sinter_times();
        let interval = case.output_interval();
        let t_s0 = case.t_sinter_start();
        let profile_max = case.profile(*times.last().unwrap())?;
        while self.pressure_index < case.walls.pressures.len() {
            let pressure = case.walls.pressures[self.pressure_index];
            let done = match self.stage {
                Stage::Start => {
                    let s = Sample::new(case, self.law.clone(), pressure)?;
                    self.dt_used = s.driver.settings.dt;
                    log(&format!("explicit_sinter: p = {pressure:.3e} Pa, {} particles, dt = {:.3e} s: prepare", s.particles.len(), self.dt_used));
                    self.trunk = Some(s);
                    self.net = None;
                    self.stage = Stage::Prepare;
                    true
                }
                Stage::Prepare => {
                    let s = self.trunk.as_mut().unwrap();
                    let done = s.advance(case, &profile_max, &mut self.net, case.protocol.t_prepare, interval, false, None, &mut self.clock)?;
                    if done {
                        self.partial = Partial { density_prepared: s.density(), ..Default::default() };
                        s.driver.law.set_friction(self.law.friction());
                        self.stage = Stage::Heat;
                    }
                    done
                }
                Stage::Heat => {
                    let s = self.trunk.as_mut().unwrap();
                    let done = s.advance(case, &profile_max, &mut self.net, t_s0, interval, false, None, &mut self.clock)?;
                    if done {
                        self.stage = Stage::Sinter { k: 0 };
                        log(&format!("explicit_sinter: p = {pressure:.3e} Pa: sinter to t_s = {} s", times[0]));
                    }
                    done
                }
                Stage::Sinter { k } => {
                    let ts = times[k];
                    let s = self.trunk.as_mut().unwrap();
                    let done = s.advance(case, &profile_max, &mut self.net, t_s0 + ts, interval, true, None, &mut self.clock)?;
                    if done {
                        self.partial.density_sintered = s.density();
                        self.partial.forces_sintered = forces_of(s);
                        let mut b = s.clone();
                        self.bnet = None;
                        if case.coupling.mode == CouplingMode::Network && self.net.is_some() {
                            self.bnet = Some(b.build_network_keep(case, &case.profile(ts)?)?);
                        }
                        self.branch = Some(b);
                        self.stage = Stage::Cool { k };
                    }
                    done
                }
                Stage::Cool { k } => {
                    let ts = times[k];
                    let profile = case.profile(ts)?;
                    let t_end = t_s0 + ts + case.protocol.t_cool + case.protocol.t_relax;
                    let b = self.branch.as_mut().unwrap();
                    let done = b.advance(case, &profile, &mut self.bnet, t_end, interval, false, None, &mut self.clock)?;
                    if done {
                        let pa = &mut self.partial;
                        pa.density_final = b.density();
                        pa.forces_cooled = forces_of(b);
                        pa.coordination_final = 2.0 * pa.forces_cooled.len() as f64 / b.particles.len() as f64;
                        pa.history = b.rows.clone();
                        if case.compression.enabled {
                            pa.z0 = box_size(&b.driver.walls)[2];
                            pa.speed = case.compression.strain_rate * pa.z0;
                            b.driver.walls[5].control = WallControl::Velocity;
                            b.driver.walls[5].velocity = pa.speed;
                            pa.t_start = b.driver.time;
                            b.rows.clear();
                            let first = b.row(profile.temperature(pa.t_start), 0.0);
                            b.rows.push(first);
                            self.stage = Stage::Compress { k };
                        } else {
                            self.finish_branch(case, pressure, k, &times, log);
                        }
                    }
                    done
                }
                Stage::Compress { k } => {
                    let ts = times[k];
                    let profile = case.profile(ts)?;
                    let duration = case.compression.max_strain / case.compression.strain_rate;
                    let d_int = case.compression.output_strain / case.compression.strain_rate;
                    let (z0, v, t_start) = (self.partial.z0, self.partial.speed, self.partial.t_start);
                    let b = self.branch.as_mut().unwrap();
                    let done = b.advance(case, &profile, &mut self.bnet, t_start + duration, d_int, false, Some((z0, v)), &mut self.clock)?;
                    if done {
                        self.finish_branch(case, pressure, k, &times, log);
                    }
                    done
                }
            };
            if !done && let Some(sink) = sink.as_deref_mut() {
                let ck = self.checkpoint(&sink.case_toml, model, wall.elapsed().as_secs_f64());
                let path = sink.dir.join("checkpoint.json");
                let json = serde_json::to_string(&ck).map_err(|e| IoError::new(&path, e))?;
                crate::io::write_atomic(&path, &json)?;
                tracing::debug!(
                    "checkpoint at step {} ({:?}, pressure {}) written to {}",
                    self.clock.steps,
                    self.stage,
                    self.pressure_index + 1,
                    path.display()
                );
                if sink.stop_after.is_some_and(|k| self.clock.steps >= k) {
                    return Ok(false);
                }
            }
        }
        self.warnings.sort();
        self.warnings.dedup();
        self.wall_before += wall.elapsed().as_secs_f64();
        Ok(true)
    }

    /// The branch `k` of the current pressure is done: its results become a [`Branch`], and the
    /// protocol moves to the next sintering time or pressure.
    fn finish_branch(&mut self, case: &ExplicitSinterCase, pressure: f64, k: usize, times: &[f64], log: &mut dyn FnMut(&str)) {
        let ts = times[k];
        let b = self.branch.take().unwrap();
        self.bnet = None;
        let pa = std::mem::take(&mut self.partial);
        let compression = if case.compression.enabled { b.rows.clone() } else { Vec::new() };
        // no contact left: 0 (as in the history rows), with a warning below
        let min_f = |f: &[f64]| if f.is_empty() { 0.0 } else { f.iter().copied().fold(f64::INFINITY, f64::min) };
        let max_f = |f: &[f64]| if f.is_empty() { 0.0 } else { f.iter().copied().fold(f64::NEG_INFINITY, f64::max) };
        for (f, when) in [(&pa.forces_sintered, "after sintering"), (&pa.forces_cooled, "after cool-down")] {
            if f.is_empty() {
                self.warnings.push(format!("p = {pressure} Pa, t_sinter = {ts} s: no contacts {when}; its force extremes are reported as 0"));
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
                self.warnings
                    .push(format!("p = {pressure} Pa, t_sinter = {ts} s: the compression stress never rose above its initial value; stiffness reported as 0"));
            }
            0.0
        };
        self.warnings.extend(b.warnings.iter().cloned());
        self.branches.push(Branch {
            pressure,
            t_sinter: ts,
            history: pa.history,
            compression,
            min_force_sintered: min_f(&pa.forces_sintered),
            min_force_cooled: min_f(&pa.forces_cooled),
            max_force_cooled: max_f(&pa.forces_cooled),
            forces_sintered: pa.forces_sintered,
            forces_cooled: pa.forces_cooled,
            density_prepared: pa.density_prepared,
            density_sintered: pa.density_sintered,
            density_final: pa.density_final,
            coordination_final: pa.coordination_final,
            peak_stress: peak,
            strain_at_peak: eps_peak,
            stiffness,
            heat_solves: b.heat_solves,
            steps: b.driver.counters.steps,
        });
        let br = self.branches.last().unwrap();
        log(&format!(
            "  t_s = {ts}: density sintered {:.4}, final {:.4}, min force after cooling {:.3e} N, peak sigma_zz {:.4e} Pa",
            br.density_sintered, br.density_final, br.min_force_cooled, br.peak_stress
        ));
        // the next branch starts from the same preparation
        self.partial = Partial { density_prepared: pa.density_prepared, ..Default::default() };
        if k + 1 < times.len() {
            self.stage = Stage::Sinter { k: k + 1 };
            log(&format!("explicit_sinter: p = {pressure:.3e} Pa: sinter to t_s = {} s", times[k + 1]));
        } else {
            let s = self.trunk.take().unwrap();
            self.warnings.extend(s.warnings.iter().cloned());
            self.net = None;
            self.pressure_index += 1;
            self.stage = Stage::Start;
        }
    }
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

fn model_name(case: &ExplicitSinterCase) -> &'static str {
    match case.model {
        SinterModel::Luding(_) => "luding",
        SinterModel::Frenkel(_) => "frenkel",
    }
}

/// Runs (or continues, from `resume`: the checkpoint's text and its path) the machine of one law.
fn run_law<M: SinterLaw>(
    case: &ExplicitSinterCase,
    law: M,
    sink: Option<&mut CheckpointSink>,
    resume: Option<(&str, &Path)>,
    log: &mut dyn FnMut(&str),
) -> Result<Option<Machine<M>>, Error> {
    let every = case.output.checkpoint_every as u64;
    let mut m = match resume {
        None => Machine::new(law, every),
        Some((text, path)) => {
            let ck: ExplicitCheckpoint<M::State> = serde_json::from_str(text).map_err(|e| IoError::new(path, e))?;
            let (steps, stage) = (ck.steps, ck.stage);
            let m = Machine::restore(case, law, ck, every).map_err(|e| ConfigError::invalid(format!("{}: {e}", path.display())))?;
            log(&format!("resumed from the checkpoint at step {steps} ({stage:?}, pressure {} of {})", m.pressure_index + 1, case.walls.pressures.len()));
            m
        }
    };
    Ok(m.run(case, model_name(case), sink, log)?.then_some(m))
}

/// Runs a parsed case (no files written); with `progress` the stage lines go to stderr.
pub fn run_explicit(case: &ExplicitSinterCase, progress: bool) -> Result<ExplicitSinterRun, Error> {
    let mut log = |m: &str| {
        if progress {
            tracing::info!("{m}");
        }
    };
    run_explicit_with(case, None, None, &mut log).map(|r| r.expect("no stop without a checkpoint sink"))
}

/// Runs a parsed case, writing checkpoints into `sink` when given and continuing from `resume`
/// (a checkpoint's text and path) when given; `Ok(None)` when stopped by `sink.stop_after`.
pub fn run_explicit_with(
    case: &ExplicitSinterCase,
    sink: Option<&mut CheckpointSink>,
    resume: Option<(&str, &Path)>,
    log: &mut dyn FnMut(&str),
) -> Result<Option<ExplicitSinterRun>, Error> {
    let n = case.sample.particles as usize;
    let done = match &case.model {
        SinterModel::Luding(p) => run_law(case, LudingLaw::new(p.clone()), sink, resume, log)?.map(|m| (m.branches, m.dt_used, m.warnings, m.wall_before)),
        SinterModel::Frenkel(p) => {
            run_law(case, FrenkelLaw { params: p.clone() }, sink, resume, log)?.map(|m| (m.branches, m.dt_used, m.warnings, m.wall_before))
        }
    };
    Ok(done.map(|(branches, dt, warnings, wall)| ExplicitSinterRun {
        title: case.title.clone(),
        model: model_name(case).into(),
        particles: n,
        dt,
        branches,
        warnings,
        wall_seconds: wall,
    }))
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
/// summary (also `summary.json`). With `progress` the stage lines are logged (`tracing`).
pub fn run_explicit_case(case: &toml::Value, out_dir: &Path, progress: bool) -> Result<serde_json::Value, Error> {
    let mut log = |m: &str| {
        if progress {
            tracing::info!("{m}");
        }
    };
    run_explicit_from(case, out_dir, &mut log, None)
}

/// The run API's entry: runs `case` into `out_dir`, writing `out_dir/checkpoint.json` every
/// `output.checkpoint_every` steps; `stop_after` ends the run right after the checkpoint at or
/// after that step (as if killed there; for tests) with `Ok(Value::Null)`.
pub fn run_explicit_from(case: &toml::Value, out_dir: &Path, log: &mut dyn FnMut(&str), stop_after: Option<u64>) -> Result<serde_json::Value, Error> {
    let c = parse_explicit_case(case)?;
    crate::io::ensure_dir(out_dir)?;
    let case_toml = toml::to_string(case).map_err(|e| ConfigError::invalid(format!("case cannot be re-serialised: {e}")))?;
    let mut sink = CheckpointSink { dir: out_dir, case_toml, stop_after };
    let sink = (c.output.checkpoint_every > 0.0).then_some(&mut sink);
    match run_explicit_with(&c, sink, None, log)? {
        None => Ok(serde_json::Value::Null),
        Some(run) => finish(&c, &run, out_dir, log),
    }
}

fn finish(c: &ExplicitSinterCase, run: &ExplicitSinterRun, out_dir: &Path, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    for w in &run.warnings {
        log(&format!("warning: {w}"));
    }
    write_outputs(c, run, out_dir)
}

/// `sinterdem resume DIR` for an `explicit_sinter` run: rebuilds the case from the checkpoint's
/// text, restores the protocol's stage, samples and finished branches after checking them against
/// the case, and continues bit for bit.
pub fn resume(dir: &Path, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    #[derive(Deserialize)]
    struct Head {
        format: String,
        case_toml: String,
        model: String,
    }
    let path = dir.join("checkpoint.json");
    let text = crate::io::read_input(&path)?;
    let head: Head = serde_json::from_str(&text).map_err(|e| IoError::new(&path, e))?;
    if head.format != EXPLICIT_CHECKPOINT_FORMAT {
        return Err(ConfigError::invalid(format!("{}: format \"{}\" is not {EXPLICIT_CHECKPOINT_FORMAT}", path.display(), head.format)).into());
    }
    let value =
        toml::Value::Table(head.case_toml.parse::<toml::Table>().map_err(|e| ConfigError::invalid(format!("{}: case: {}", path.display(), e.message())))?);
    let c = parse_explicit_case(&value).map_err(|e| ConfigError::invalid(format!("{}: case: {e}", path.display())))?;
    if head.model != model_name(&c) {
        return Err(ConfigError::invalid(format!("{}: model \"{}\" does not match the case's model \"{}\"", path.display(), head.model, model_name(&c))).into());
    }
    let mut sink = CheckpointSink { dir, case_toml: head.case_toml, stop_after: None };
    let sink = (c.output.checkpoint_every > 0.0).then_some(&mut sink);
    let run = run_explicit_with(&c, sink, Some((&text, &path)), log)?.expect("no stop without stop_after");
    finish(&c, &run, dir, log)
}

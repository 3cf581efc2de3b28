//! The `explicit_sinter` case: its schema, parsing and validation, and the plausibility check of
//! `sinterdem check`.

use super::check;
use super::laws::{self, Law};
use crate::error::{ConfigError, Error};
use crate::explicit::sinter::LawInputs;
use crate::profile::Profile;
use serde::{Deserialize, Serialize};

/// The case file without its law section (`[luding]`, `[frenkel]`, …: taken out by name before,
/// [`laws::LAWS`]).
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

/// A validated `explicit_sinter` case.
#[derive(Debug, Clone)]
pub struct ExplicitSinterCase {
    pub title: String,
    /// The law of `model = "…"` with its parameters (chosen once, here).
    pub(crate) law: Box<dyn Law>,
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
    pub(super) fn sinter_times(&self) -> Vec<f64> {
        let mut v = self.protocol.t_sinter.clone();
        v.sort_by(|a, b| a.total_cmp(b));
        v
    }
    /// Start of sintering (end of heating) [s].
    pub(super) fn t_sinter_start(&self) -> f64 {
        self.protocol.t_prepare + self.protocol.t_heat
    }
    /// The temperature history for sintering time `ts` [s] (Fig. 7).
    pub(super) fn profile(&self, ts: f64) -> Result<Profile, ConfigError> {
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
    pub(super) fn output_interval(&self) -> f64 {
        self.protocol.output_interval.unwrap_or(0.01 * (self.protocol.t_prepare + self.protocol.t_heat))
    }
}

/// The case file's sections other than the laws', and the law sections present (by name). serde
/// lists the allowed keys of an unknown top-level key without the law sections, which were taken
/// out; they are put back where the case-file schema lists them, before `output`.
fn case_file(case: &toml::Value) -> Result<(CaseFile, Vec<(&'static str, toml::Value)>), ConfigError> {
    let mut rest = case.clone();
    let mut sections = Vec::new();
    if let Some(t) = rest.as_table_mut() {
        for e in laws::LAWS {
            if let Some(v) = t.remove(e.name) {
                sections.push((e.name, v));
            }
        }
    }
    let f = CaseFile::deserialize(rest).map_err(|e| {
        let names: String = laws::LAWS.iter().map(|e| format!("`{}`, ", e.name)).collect();
        let raw = e.to_string().replacen("`stepping`, `output`", &format!("`stepping`, {names}`output`"), 1);
        crate::config::messages::from_serde(&raw, "")
    })?;
    Ok((f, sections))
}

/// Parses and validates an `explicit_sinter` case (unknown keys rejected; every number checked
/// against [`RANGES`] and the law's table; errors name the key).
pub fn parse_explicit_case(case: &toml::Value) -> Result<ExplicitSinterCase, Error> {
    let (f, mut sections) = case_file(case)?;
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
    let entry = laws::find(&f.model).ok_or_else(|| ConfigError::inconsistent("model", format!("\"{}\": expected {}", f.model, laws::names())))?;
    if let Some(other) = laws::LAWS.iter().find(|e| e.name != entry.name && sections.iter().any(|(n, _)| *n == e.name)) {
        let (m, o) = (entry.name, other.name);
        return Err(ConfigError::inconsistent(o, format!("model = \"{m}\" takes a [{m}] section; remove [{o}]")).into());
    }
    let section = sections.iter().position(|(n, _)| *n == entry.name).map(|k| sections.swap_remove(k).1);
    let law = (entry.build)(section, &LawInputs { mean_radius: s.mean_radius, t0_sinter: pr.t0_sinter })?;
    let case = ExplicitSinterCase {
        title: f.title,
        law,
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

/// Plausibility of the protocol (issue 16): the particle count against the memory, and the steps
/// and history rows the protocol's simulated time implies at the sample's explicit step.
pub(super) fn check_plan(c: &ExplicitSinterCase) -> Result<(), Error> {
    use crate::config::plausible::{BYTES_PER_PARTICLE_GENERATE, MAX_STEPS, check_memory};
    check_memory("sample.particles", c.sample.particles, BYTES_PER_PARTICLE_GENERATE)?;
    let pressure = c.walls.pressures[0];
    // the step from a small sample of the same size distribution (building a million-particle
    // sample is the run's work, not the check's)
    let mut small = c.clone();
    small.sample.particles = small.sample.particles.min(200.0);
    let dt = small.law.step(&small, pressure)?;
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

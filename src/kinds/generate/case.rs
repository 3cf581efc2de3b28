//! The generate case: its schema (`[packing]`, `[packing.size]`, `[packing.protocol]`) and its
//! validation against [`RANGES`](super::RANGES).

use super::RANGES;
use crate::error::{ConfigError, Error};
use crate::packing::SizeDistribution;
use serde::Deserialize;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseFile {
    kind: String,
    #[serde(default)]
    #[allow(dead_code)]
    title: Option<String>,
    packing: toml::Value,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct PackingFile {
    particles: i64,
    #[serde(default = "one")]
    seed: i64,
    #[serde(default = "sixty")]
    target_solid_fraction: f64,
    #[serde(rename = "box")]
    box_: Vec<f64>,
    lamina_width: Option<f64>,
    boundary: Option<String>,
    size: SizeFile,
    #[serde(default)]
    protocol: ProtocolFile,
}
fn one() -> i64 {
    1
}
fn sixty() -> f64 {
    0.60
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SizeFile {
    distribution: String,
    mean_diameter: Option<f64>,
    spread: Option<f64>,
    std_diameter: Option<f64>,
    truncate: Option<f64>,
    diameters: Option<Vec<f64>>,
    cumulative: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct ProtocolFile {
    friction: Option<f64>,
    wall_friction: Option<f64>,
    restitution: Option<f64>,
    local_damping: Option<f64>,
    cloud_solid_fraction: Option<f64>,
    compaction_overlap: Option<f64>,
    max_overlap_rel: Option<f64>,
    kinetic_energy_rel: Option<f64>,
    contact_gap_rel: Option<f64>,
    dt_fraction: Option<f64>,
    max_steps: Option<f64>,
    strain_rate: Option<f64>,
    compaction: Option<String>,
}

/// Protocol parameters (dimensionless; see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Protocol {
    pub friction: f64,
    pub wall_friction: f64,
    pub restitution: f64,
    pub local_damping: f64,
    pub cloud_solid_fraction: f64,
    pub compaction_overlap: f64,
    pub max_overlap_rel: f64,
    pub kinetic_energy_rel: f64,
    pub contact_gap_rel: f64,
    pub dt_fraction: f64,
    pub max_steps: u64,
    /// Periodic packings: compaction strain rate of the box, −L̇/L in 1 per scaled time unit
    /// √(m̄/k_n) (docs/packing.md (G5)).
    pub strain_rate: f64,
    /// Periodic packings: the path of the box compaction (`packing.protocol.compaction`).
    pub compaction: Compaction,
}

/// How a periodic box is compacted (`packing.protocol.compaction`, docs/packing.md (G9)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compaction {
    /// `"isotropic"` (default): all edges strained together at `strain_rate` straight to the
    /// target box, relaxed there at fixed volume (G5).
    #[default]
    Isotropic,
    /// `"die"`: the walled recipe without walls. The footprint is held (2 % above the target's)
    /// while the height is driven at the walls' speed under the same pressure servo, friction
    /// lowering and taps as the walled box, then the box is backed off until the pressure
    /// vanishes (G9).
    Die,
}

impl Default for Protocol {
    fn default() -> Self {
        Protocol {
            friction: 0.1,
            wall_friction: 0.0,
            restitution: 0.3,
            local_damping: 0.3,
            cloud_solid_fraction: 0.3,
            compaction_overlap: 5e-3,
            max_overlap_rel: 1e-3,
            kinetic_energy_rel: 1e-10,
            contact_gap_rel: 1e-3,
            dt_fraction: 0.08,
            max_steps: 5_000_000,
            strain_rate: 1e-4,
            compaction: Compaction::Isotropic,
        }
    }
}

/// A validated `kind = "generate"` case.
#[derive(Debug, Clone, PartialEq)]
pub struct GenerateCase {
    pub particles: usize,
    pub seed: u64,
    pub target_solid_fraction: f64,
    /// Requested box [m]; its shape is kept, its size scaled to the target volume.
    pub box_size: [f64; 3],
    /// Lamina width q_s [m] (eq. 48); None: the mean radius.
    pub lamina_width: Option<f64>,
    pub size: SizeDistribution,
    pub protocol: Protocol,
    /// `packing.boundary = "periodic"`: the periodic protocol (docs/packing.md, "Periodic
    /// packings"); false: the walled box (default, `"walls"`).
    pub periodic: bool,
}

fn chk(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(RANGES, key, v)
}

/// Parses and validates a `kind = "generate"` case (for `sinterdem check`).
pub fn parse_generate_case(case: &toml::Value) -> Result<GenerateCase, Error> {
    let cf: CaseFile = crate::config::from_value(case.clone(), "")?;
    if cf.kind != "generate" {
        return Err(ConfigError::inconsistent("kind", format!("\"{}\": a packing case needs kind = \"generate\"", cf.kind)).into());
    }
    let pf: PackingFile = crate::config::from_value(cf.packing, "packing")?;
    let particles = chk("packing.particles", pf.particles as f64)? as usize;
    let seed = chk("packing.seed", pf.seed as f64).map(|_| pf.seed as u64)?;
    let target = chk("packing.target_solid_fraction", pf.target_solid_fraction)?;
    if pf.box_.len() != 3 {
        return Err(ConfigError::inconsistent("packing.box", format!("needs 3 edges [x, y, z] (m), got {}", pf.box_.len())).into());
    }
    for (a, &l) in pf.box_.iter().enumerate() {
        chk(&format!("packing.box.{a}"), l)?;
    }
    let lamina_width = pf.lamina_width.map(|w| chk("packing.lamina_width", w)).transpose()?;
    let size = size_distribution(&pf.size)?;
    size.validate()?;
    if let Some(w) = lamina_width {
        // eq. 48's laminae are cut at width w along each edge: a width far below a radius asks
        // for an absurd number of laminae (1e-12 m: 1e8 per axis) and says nothing more
        let r = 0.5 * requested_mean_diameter(&size);
        if w < 0.01 * r {
            return Err(ConfigError::inconsistent(
                "packing.lamina_width",
                format!("{} m is below 1/100 of the mean radius ({} m)", crate::error::fmt_value(w), crate::error::fmt_value(r)),
            )
            .into());
        }
    }
    crate::config::plausible::check_memory("packing.particles", particles as f64, crate::config::plausible::BYTES_PER_PARTICLE_GENERATE)?;
    let protocol = protocol(&pf.protocol)?;
    let periodic = match pf.boundary.as_deref() {
        None | Some("walls") => false,
        Some("periodic") => true,
        Some(other) => return Err(ConfigError::inconsistent("packing.boundary", format!("\"{other}\": expected \"walls\" (default) or \"periodic\"")).into()),
    };
    if pf.protocol.compaction.is_some() && !periodic {
        return Err(ConfigError::inconsistent(
            "packing.protocol.compaction",
            "is used by boundary = \"periodic\" only (the walled box always compacts as a die: its upper walls move)",
        )
        .into());
    }
    if pf.protocol.strain_rate.is_some() && protocol.compaction == Compaction::Die {
        return Err(ConfigError::inconsistent(
            "packing.protocol.strain_rate",
            "is not used by compaction = \"die\" (the box height moves at the walled protocol's wall speed, docs/packing.md (G9))",
        )
        .into());
    }
    if pf.protocol.strain_rate.is_some() && !periodic {
        return Err(
            ConfigError::inconsistent("packing.protocol.strain_rate", "is used by boundary = \"periodic\" only (the walls have their own servo)").into()
        );
    }
    if target >= 0.66 {
        // frictionless random close packing is ≈ 0.64; a few % above is reachable only with overlap
        return Err(ConfigError::inconsistent(
            "packing.target_solid_fraction",
            format!("{target} is above random close packing (≈ 0.64) and cannot be reached stress-free"),
        )
        .into());
    }
    Ok(GenerateCase { particles, seed, target_solid_fraction: target, box_size: [pf.box_[0], pf.box_[1], pf.box_[2]], lamina_width, size, protocol, periodic })
}

/// `[packing.size]`: the diameter distribution, with the keys its `distribution` needs.
fn size_distribution(s: &SizeFile) -> Result<SizeDistribution, ConfigError> {
    let need = |v: Option<f64>, k: &str| -> Result<f64, ConfigError> {
        let v = v.ok_or_else(|| ConfigError::inconsistent(format!("packing.size.{k}"), format!("required by distribution = \"{}\"", s.distribution)))?;
        chk(&format!("packing.size.{k}"), v)
    };
    let unused = |names: &[(&str, bool)]| -> Result<(), ConfigError> {
        for (k, present) in names {
            if *present {
                return Err(ConfigError::inconsistent(format!("packing.size.{k}"), format!("not used by distribution = \"{}\"", s.distribution)));
            }
        }
        Ok(())
    };
    let size = match s.distribution.as_str() {
        "uniform" => {
            unused(&[
                ("std_diameter", s.std_diameter.is_some()),
                ("truncate", s.truncate.is_some()),
                ("diameters", s.diameters.is_some()),
                ("cumulative", s.cumulative.is_some()),
            ])?;
            SizeDistribution::Uniform { mean: need(s.mean_diameter, "mean_diameter")?, spread: need(s.spread.or(Some(0.0)), "spread")? }
        }
        "normal" => {
            unused(&[("spread", s.spread.is_some()), ("diameters", s.diameters.is_some()), ("cumulative", s.cumulative.is_some())])?;
            SizeDistribution::Normal {
                mean: need(s.mean_diameter, "mean_diameter")?,
                std: need(s.std_diameter, "std_diameter")?,
                truncate: need(s.truncate.or(Some(3.0)), "truncate")?,
            }
        }
        "tabulated" => {
            unused(&[
                ("mean_diameter", s.mean_diameter.is_some()),
                ("spread", s.spread.is_some()),
                ("std_diameter", s.std_diameter.is_some()),
                ("truncate", s.truncate.is_some()),
            ])?;
            let d = s.diameters.clone().ok_or_else(|| ConfigError::inconsistent("packing.size.diameters", "required by distribution = \"tabulated\""))?;
            let c = s.cumulative.clone().ok_or_else(|| ConfigError::inconsistent("packing.size.cumulative", "required by distribution = \"tabulated\""))?;
            for (k, v) in d.iter().enumerate() {
                chk(&format!("packing.size.diameters.{k}"), *v)?;
            }
            for (k, v) in c.iter().enumerate() {
                chk(&format!("packing.size.cumulative.{k}"), *v)?;
            }
            SizeDistribution::Tabulated { diameters: d, cumulative: c }
        }
        other => {
            return Err(ConfigError::inconsistent("packing.size.distribution", format!("\"{other}\": expected uniform, normal or tabulated")));
        }
    };
    Ok(size)
}

/// `[packing.protocol]` with its defaults.
fn protocol(pr: &ProtocolFile) -> Result<Protocol, ConfigError> {
    let d = Protocol::default();
    let get = |v: Option<f64>, k: &str, def: f64| -> Result<f64, ConfigError> { chk(&format!("packing.protocol.{k}"), v.unwrap_or(def)) };
    let protocol = Protocol {
        friction: get(pr.friction, "friction", d.friction)?,
        wall_friction: get(pr.wall_friction, "wall_friction", d.wall_friction)?,
        restitution: get(pr.restitution, "restitution", d.restitution)?,
        local_damping: get(pr.local_damping, "local_damping", d.local_damping)?,
        cloud_solid_fraction: get(pr.cloud_solid_fraction, "cloud_solid_fraction", d.cloud_solid_fraction)?,
        compaction_overlap: get(pr.compaction_overlap, "compaction_overlap", d.compaction_overlap)?,
        max_overlap_rel: get(pr.max_overlap_rel, "max_overlap_rel", d.max_overlap_rel)?,
        kinetic_energy_rel: get(pr.kinetic_energy_rel, "kinetic_energy_rel", d.kinetic_energy_rel)?,
        contact_gap_rel: get(pr.contact_gap_rel, "contact_gap_rel", d.contact_gap_rel)?,
        dt_fraction: get(pr.dt_fraction, "dt_fraction", d.dt_fraction)?,
        max_steps: get(pr.max_steps, "max_steps", d.max_steps as f64)? as u64,
        strain_rate: get(pr.strain_rate, "strain_rate", d.strain_rate)?,
        compaction: match pr.compaction.as_deref() {
            None | Some("isotropic") => Compaction::Isotropic,
            Some("die") => Compaction::Die,
            Some(other) => {
                return Err(ConfigError::inconsistent("packing.protocol.compaction", format!("\"{other}\": expected \"isotropic\" (default) or \"die\"")));
            }
        },
    };
    Ok(protocol)
}

/// Mean of the requested diameter distribution [m] (tabulated: by the trapezoid rule on the CDF).
pub fn requested_mean_diameter(s: &SizeDistribution) -> f64 {
    match s {
        SizeDistribution::Uniform { mean, .. } | SizeDistribution::Normal { mean, .. } => *mean,
        SizeDistribution::Tabulated { diameters, cumulative } => {
            (1..diameters.len()).map(|k| 0.5 * (diameters[k] + diameters[k - 1]) * (cumulative[k] - cumulative[k - 1])).sum()
        }
    }
}

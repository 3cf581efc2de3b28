//! Material parameter sets for heat and mechanics (SI). Diffusion data of the 7-DOF model live
//! beside that model. A case names materials in `[[materials]]`; `preset` fills unset keys.

use crate::config::{self, from_value};
use crate::error::ConfigError;
use serde::{Deserialize, Serialize};

/// One material as written in a case file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Name other sections refer to.
    pub name: String,
    /// Built-in values to start from: "copper" or "titanium".
    pub preset: Option<String>,
    /// Mass density ρ [kg/m³].
    pub density: Option<f64>,
    /// Specific heat capacity c [J/(kg·K)].
    pub heat_capacity: Option<f64>,
    /// Thermal conductivity κ [W/(m·K)].
    pub conductivity: Option<f64>,
    /// Young's modulus E [Pa].
    pub young_modulus: Option<f64>,
    /// Poisson's ratio ν [1].
    pub poisson_ratio: Option<f64>,
    /// 7-DOF diffusion data (compact runs): a bundled set, "copper" or "titanium" (default: the
    /// preset's name). Ignored when `phases` are given.
    pub diffusion: Option<String>,
    /// Where user-defined diffusion data come from (as in pair cases).
    pub source: Option<String>,
    /// Lower end of the calibrated temperature range of user-defined diffusion data [K].
    pub calibrated_min_temperature: Option<f64>,
    /// Upper end of the calibrated temperature range of user-defined diffusion data [K].
    pub calibrated_max_temperature: Option<f64>,
    /// Melting (solidus) temperature of user-defined diffusion data [K] (default: the bundled
    /// data's of the same name).
    pub melting_temperature: Option<f64>,
    /// User-defined 7-DOF diffusion data, the `[[materials.phases]]` of pair cases.
    pub phases: Option<Vec<crate::models::diffusion7::Phase>>,
}

/// A resolved material.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Material {
    pub name: String,
    /// ρ [kg/m³].
    pub density: f64,
    /// c [J/(kg·K)].
    pub heat_capacity: f64,
    /// κ [W/(m·K)].
    pub conductivity: f64,
    /// E [Pa].
    pub young_modulus: f64,
    /// ν [1].
    pub poisson_ratio: f64,
    /// Name of the bundled 7-DOF diffusion data, if any.
    pub diffusion: Option<String>,
    /// User-defined 7-DOF diffusion data (phases given in the case or an included file); wins
    /// over `diffusion`.
    pub diffusion_data: Option<crate::models::diffusion7::Material>,
}

/// Built-in values. Copper: ρ, c, κ handbook values near room temperature (κ = 394 W/(m·K) as in
/// Rojek et al. 2022), E = 72 GPa as in Ivannikov et al. 2022 Table 2. Titanium (α, room
/// temperature): ρ = 4506, c = 523, κ = 21.9; E = 57 GPa and ν = 0.39 as in Ivannikov et al. 2022
/// Table 4 (β-Ti at 1273 K; the same values as the bundled 7-DOF titanium data).
pub fn preset(name: &str) -> Option<Material> {
    match name {
        "copper" => Some(Material {
            name: "copper".into(),
            density: 8960.0,
            heat_capacity: 385.0,
            conductivity: 394.0,
            young_modulus: 72e9,
            poisson_ratio: 0.34,
            diffusion: Some("copper".into()),
            diffusion_data: None,
        }),
        "titanium" => Some(Material {
            name: "titanium".into(),
            density: 4506.0,
            heat_capacity: 523.0,
            conductivity: 21.9,
            young_modulus: 57e9,
            poisson_ratio: 0.39,
            diffusion: Some("titanium".into()),
            diffusion_data: None,
        }),
        _ => None,
    }
}

impl MaterialSpec {
    /// Resolves presets and checks every value against the range table.
    pub fn resolve(&self) -> Result<Material, ConfigError> {
        let key = |k: &str| format!("materials.{}.{k}", self.name);
        let base = match &self.preset {
            Some(p) => Some(preset(p).ok_or_else(|| ConfigError::invalid(format!("{}: unknown preset \"{p}\" (copper, titanium)", key("preset"))))?),
            None => None,
        };
        let get = |v: Option<f64>, k: &str, from_base: Option<f64>| -> Result<f64, ConfigError> {
            match v.or(from_base) {
                Some(x) => config::check(&key(k), x),
                None => Err(ConfigError::invalid(format!("{} is required (no preset given)", key(k)))),
            }
        };
        let young = get(self.young_modulus, "young_modulus", base.as_ref().map(|b| b.young_modulus).or(Some(1e11)))?;
        let poisson = get(self.poisson_ratio, "poisson_ratio", base.as_ref().map(|b| b.poisson_ratio).or(Some(0.3)))?;
        let diffusion_name = self.diffusion.clone().or_else(|| base.as_ref().and_then(|b| b.diffusion.clone()));
        let diffusion_data = match &self.phases {
            None => {
                for (k, v) in [
                    ("calibrated_min_temperature", self.calibrated_min_temperature),
                    ("calibrated_max_temperature", self.calibrated_max_temperature),
                    ("melting_temperature", self.melting_temperature),
                ] {
                    if v.is_some() {
                        return Err(ConfigError::invalid(format!("{}: only with user-defined diffusion data ([[materials.phases]])", key(k))));
                    }
                }
                None
            }
            Some(phases) => {
                // the calibrated range defaults to that of the bundled data of the same name
                let bundled = diffusion_name.as_deref().and_then(|d| crate::models::diffusion7::Material::builtin(d).ok());
                let range = |v: Option<f64>, k: &str, b: Option<f64>| -> Result<f64, ConfigError> {
                    v.or(b).ok_or_else(|| {
                        ConfigError::invalid(format!("{} is required with [[materials.phases]] (the range the diffusion data are calibrated for)", key(k)))
                    })
                };
                let m = crate::models::diffusion7::Material {
                    name: self.name.clone(),
                    source: self.source.clone().unwrap_or_default(),
                    young_modulus: young,
                    poisson_ratio: poisson,
                    calibrated_min_temperature: range(
                        self.calibrated_min_temperature,
                        "calibrated_min_temperature",
                        bundled.as_ref().map(|b| b.calibrated_min_temperature),
                    )?,
                    calibrated_max_temperature: range(
                        self.calibrated_max_temperature,
                        "calibrated_max_temperature",
                        bundled.as_ref().map(|b| b.calibrated_max_temperature),
                    )?,
                    melting_temperature: self.melting_temperature.or_else(|| bundled.as_ref().and_then(|b| b.melting_temperature)),
                    phases: phases.clone(),
                };
                m.validate()?;
                Some(m)
            }
        };
        Ok(Material {
            name: self.name.clone(),
            density: get(self.density, "density", base.as_ref().map(|b| b.density))?,
            heat_capacity: get(self.heat_capacity, "heat_capacity", base.as_ref().map(|b| b.heat_capacity))?,
            conductivity: get(self.conductivity, "conductivity", base.as_ref().map(|b| b.conductivity))?,
            young_modulus: young,
            poisson_ratio: poisson,
            diffusion: diffusion_name,
            diffusion_data,
        })
    }
}

/// Parses `[[materials]]` from a case.
pub fn from_case(list: &[MaterialSpec]) -> Result<Vec<Material>, ConfigError> {
    if list.is_empty() {
        return Err(ConfigError::invalid("[[materials]]: at least one material is required"));
    }
    let mut out: Vec<Material> = Vec::new();
    for m in list {
        if out.iter().any(|o| o.name == m.name) {
            return Err(ConfigError::invalid(format!("materials: the name \"{}\" is used twice", m.name)));
        }
        out.push(m.resolve()?);
    }
    Ok(out)
}

/// Convenience for tests and tools: one material from a TOML table.
pub fn parse_one(v: toml::Value) -> Result<Material, ConfigError> {
    from_value::<MaterialSpec>(v, "materials")?.resolve()
}

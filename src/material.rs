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
    /// preset's name).
    pub diffusion: Option<String>,
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
}

/// Built-in values. Copper: ρ, c, κ handbook values near room temperature (κ = 394 W/(m·K) as in
/// Rojek et al. 2022), E = 72 GPa as in Ivannikov et al. 2022 Table 2. Titanium (α, room
/// temperature): ρ = 4506, c = 523, κ = 21.9; E = 57 GPa as in Ivannikov et al. 2022 Table 4.
pub fn preset(name: &str) -> Option<Material> {
    match name {
        "copper" => Some(Material { name: "copper".into(), density: 8960.0, heat_capacity: 385.0, conductivity: 394.0, young_modulus: 72e9, poisson_ratio: 0.34, diffusion: Some("copper".into()) }),
        "titanium" => Some(Material { name: "titanium".into(), density: 4506.0, heat_capacity: 523.0, conductivity: 21.9, young_modulus: 57e9, poisson_ratio: 0.32, diffusion: Some("titanium".into()) }),
        _ => None,
    }
}

impl MaterialSpec {
    /// Resolves presets and checks every value against the range table.
    pub fn resolve(&self) -> Result<Material, ConfigError> {
        let key = |k: &str| format!("materials.{}.{k}", self.name);
        let base = match &self.preset {
            Some(p) => Some(preset(p).ok_or_else(|| {
                ConfigError::invalid(format!("{}: unknown preset \"{p}\" (copper, titanium)", key("preset")))
            })?),
            None => None,
        };
        let get = |v: Option<f64>, k: &str, from_base: Option<f64>| -> Result<f64, ConfigError> {
            match v.or(from_base) {
                Some(x) => config::check(&key(k), x),
                None => Err(ConfigError::invalid(format!("{} is required (no preset given)", key(k)))),
            }
        };
        Ok(Material {
            name: self.name.clone(),
            density: get(self.density, "density", base.as_ref().map(|b| b.density))?,
            heat_capacity: get(self.heat_capacity, "heat_capacity", base.as_ref().map(|b| b.heat_capacity))?,
            conductivity: get(self.conductivity, "conductivity", base.as_ref().map(|b| b.conductivity))?,
            young_modulus: get(self.young_modulus, "young_modulus", base.as_ref().map(|b| b.young_modulus).or(Some(1e11)))?,
            poisson_ratio: get(self.poisson_ratio, "poisson_ratio", base.as_ref().map(|b| b.poisson_ratio).or(Some(0.3)))?,
            diffusion: self.diffusion.clone().or_else(|| base.as_ref().and_then(|b| b.diffusion.clone())),
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

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
    /// Built-in values to start from: a materials-library entry ("copper", "titanium", "nickel",
    /// "silver", "iron", "tungsten", "316l", "alumina"; docs/materials.md).
    pub preset: Option<String>,
    /// Mass density ρ [kg/m³].
    pub density: Option<f64>,
    /// Specific heat capacity c [J/(kg·K)].
    pub heat_capacity: Option<f64>,
    /// Thermal conductivity κ [W/(m·K)].
    pub conductivity: Option<f64>,
    /// κ(T) as a piecewise-linear table: `[[T, κ], ...]` ([K], [W/(m·K)]) or the name of a bundled
    /// table (a library entry, docs/materials.md); replaces `conductivity` in every heat path
    /// (heat-model.md eq. P3).
    pub conductivity_table: Option<toml::Value>,
    /// c(T) as a piecewise-linear table: `[[T, c], ...]` ([K], [J/(kg·K)]) or the name of a bundled
    /// table; replaces `heat_capacity` in every heat path (heat-model.md eqs. P1–P2).
    pub heat_capacity_table: Option<toml::Value>,
    /// Linear thermal expansion coefficient α [1/K] of compact runs (docs/coupled.md (X1)); 0 or
    /// absent: no thermal expansion.
    pub thermal_expansion: Option<f64>,
    /// α(T) as a piecewise-linear table `[[T, α], ...]` ([K], [1/K]) or the name of a bundled table
    /// (a library entry with an α(T) table: "copper", "titanium"); replaces `thermal_expansion`
    /// (docs/coupled.md (X1)).
    pub thermal_expansion_table: Option<toml::Value>,
    /// Electrical resistivity ρ_e [Ω·m] of `sinterdem conductivity` with `quantity = "electrical"`
    /// (default: the preset's bundled ρ_e(T) table).
    pub electrical_resistivity: Option<f64>,
    /// ρ_e(T) as a piecewise-linear table `[[T, ρ_e], ...]` ([K], [Ω·m]) or the name of a bundled
    /// table (docs/materials.md); replaces `electrical_resistivity`.
    pub electrical_resistivity_table: Option<toml::Value>,
    /// Young's modulus E [Pa].
    pub young_modulus: Option<f64>,
    /// Poisson's ratio ν [1].
    pub poisson_ratio: Option<f64>,
    /// 7-DOF diffusion data (compact runs): a materials-library entry (docs/materials.md; default:
    /// the preset's name). Ignored when `phases` are given.
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
    /// κ [W/(m·K)]; with `conductivity_table` the table's value at 293.15 K (the reference the
    /// pipe conductances are computed with, rescaled by κ(T)/κ_ref in the heat network).
    pub conductivity: f64,
    /// κ(T) [W/(m·K)], if given.
    pub conductivity_table: Option<Table>,
    /// c(T) [J/(kg·K)], if given (then `heat_capacity` is its value at 293.15 K).
    pub heat_capacity_table: Option<Table>,
    /// Linear thermal expansion α [1/K] (compact runs, docs/coupled.md (X1)); None: off.
    pub thermal_expansion: Option<Expansion>,
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

/// Built-in values of `preset = NAME`: the `[materials.preset]` constants of the materials
/// library (docs/materials.md, `src/models/diffusion7/materials.toml`) with E and ν, and the
/// entry's 7-DOF diffusion data by name. Copper: ρ, c, κ handbook values near room temperature
/// (κ = 394 W/(m·K) as in Rojek et al. 2022), E = 72 GPa as in Ivannikov et al. 2022 Table 2,
/// ν = 0.34. Titanium (α, room temperature): ρ = 4506, c = 523, κ = 21.9; E = 57 GPa, ν = 0.39 as
/// in Ivannikov et al. 2022 Table 4. The others: Incropera et al. (2007) at 300 K and handbook
/// elastic constants (the file cites each). Names are matched ignoring ASCII case.
pub fn preset(name: &str) -> Option<Material> {
    let e = crate::models::diffusion7::library::entry(name)?;
    Some(Material {
        name: e.name.clone(),
        density: e.preset.density,
        heat_capacity: e.preset.heat_capacity,
        conductivity: e.preset.conductivity,
        conductivity_table: None,
        heat_capacity_table: None,
        thermal_expansion: None,
        young_modulus: e.preset_young_modulus(),
        poisson_ratio: e.preset_poisson_ratio(),
        diffusion: Some(e.name.clone()),
        diffusion_data: None,
    })
}

impl MaterialSpec {
    /// The electrical resistivity ρ_e [Ω·m] at temperature `t` [K] (`sinterdem conductivity` with
    /// `quantity = "electrical"`): the material's `electrical_resistivity_table` at t, else its
    /// `electrical_resistivity`, else the bundled table of its preset at t (linear between the
    /// points, constant beyond the ends); an error naming the key when none is given.
    pub fn electrical_resistivity_at(&self, t: f64) -> Result<f64, ConfigError> {
        let key = |k: &str| format!("materials.{}.{k}", self.name);
        if let Some(v) = &self.electrical_resistivity_table {
            if self.electrical_resistivity.is_some() {
                return Err(ConfigError::inconsistent(
                    key("electrical_resistivity_table"),
                    format!("give either {} or electrical_resistivity_table, not both", key("electrical_resistivity")),
                ));
            }
            return Ok(Table::from_value(v, &key("electrical_resistivity_table"), Quantity::ElectricalResistivity)?.at(t));
        }
        if let Some(r) = self.electrical_resistivity {
            return config::check(&key("electrical_resistivity"), r);
        }
        match self.preset.as_deref().and_then(|p| bundled_table(p, Quantity::ElectricalResistivity)) {
            Some(tab) => Ok(tab.at(t)),
            None => Err(ConfigError::invalid(format!(
                "{} (or {}) is required for conductivity.quantity = \"electrical\": the preset has no bundled table (bundled: {})",
                key("electrical_resistivity"),
                key("electrical_resistivity_table"),
                table_names(Quantity::ElectricalResistivity)
            ))),
        }
    }

    /// Resolves presets and checks every value against the range table.
    pub fn resolve(&self) -> Result<Material, ConfigError> {
        let key = |k: &str| format!("materials.{}.{k}", self.name);
        let base = match &self.preset {
            Some(p) => Some(preset(p).ok_or_else(|| {
                ConfigError::invalid(format!("{}: unknown preset \"{p}\" ({}; docs/materials.md)", key("preset"), crate::models::diffusion7::library::names()))
            })?),
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
                    young_modulus_table: None,
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
        let table = |v: &Option<toml::Value>, k: &str, constant: Option<f64>, quantity: Quantity| -> Result<Option<Table>, ConfigError> {
            let Some(v) = v else { return Ok(None) };
            if constant.is_some() {
                return Err(ConfigError::inconsistent(key(k), format!("give either {} or {k}, not both", key(quantity.constant_key()))));
            }
            Table::from_value(v, &key(k), quantity).map(Some)
        };
        let conductivity_table = table(&self.conductivity_table, "conductivity_table", self.conductivity, Quantity::Conductivity)?;
        let heat_capacity_table = table(&self.heat_capacity_table, "heat_capacity_table", self.heat_capacity, Quantity::HeatCapacity)?;
        let from_table = |t: &Option<Table>| t.as_ref().map(|t| t.at(REFERENCE_TEMPERATURE));
        let alpha = self.thermal_expansion.map(|a| config::check(&key("thermal_expansion"), a)).transpose()?;
        let thermal_expansion = match table(&self.thermal_expansion_table, "thermal_expansion_table", alpha, Quantity::ThermalExpansion)? {
            Some(t) => Some(Expansion::Table(t)),
            None => alpha.filter(|&a| a != 0.0).map(Expansion::Constant),
        };
        Ok(Material {
            name: self.name.clone(),
            density: get(self.density, "density", base.as_ref().map(|b| b.density))?,
            heat_capacity: match from_table(&heat_capacity_table) {
                Some(c) => c,
                None => get(self.heat_capacity, "heat_capacity", base.as_ref().map(|b| b.heat_capacity))?,
            },
            conductivity: match from_table(&conductivity_table) {
                Some(k) => k,
                None => get(self.conductivity, "conductivity", base.as_ref().map(|b| b.conductivity))?,
            },
            conductivity_table,
            heat_capacity_table,
            thermal_expansion,
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

/// Temperature at which a table gives the material's constant `conductivity` and `heat_capacity`
/// (used where one value is needed: the pipe reference, the explicit limit, `sinterdem
/// conductivity`) [K].
pub const REFERENCE_TEMPERATURE: f64 = 293.15;

/// Which property a table holds (for its range check and messages).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// κ [W/(m·K)], (0, 1e4].
    Conductivity,
    /// c [J/(kg·K)], (0, 1e5].
    HeatCapacity,
    /// α [1/K], (0, 1e-3].
    ThermalExpansion,
    /// ρ_e [Ω·m], (0, 1e16].
    ElectricalResistivity,
}

impl Quantity {
    fn range(self) -> (f64, &'static str, &'static str) {
        match self {
            Quantity::Conductivity => (1e4, "W/(m K)", "conductivity"),
            Quantity::HeatCapacity => (1e5, "J/(kg K)", "heat capacity"),
            Quantity::ThermalExpansion => (1e-3, "1/K", "thermal expansion coefficient"),
            Quantity::ElectricalResistivity => (1e16, "ohm m", "electrical resistivity"),
        }
    }
    fn constant_key(self) -> &'static str {
        match self {
            Quantity::Conductivity => "conductivity",
            Quantity::HeatCapacity => "heat_capacity",
            Quantity::ThermalExpansion => "thermal_expansion",
            Quantity::ElectricalResistivity => "electrical_resistivity",
        }
    }
}

/// A piecewise-linear property table v(T) through points (T_k, v_k), T strictly increasing,
/// held constant beyond its end points (heat-model.md "Temperature-dependent properties").
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table {
    /// Temperatures T_k [K], strictly increasing, at least two.
    pub temperature: Vec<f64>,
    /// Values v_k (unit of the property), positive.
    pub value: Vec<f64>,
}

/// Bundled tables of the materials library (`[materials.tables]`, docs/materials.md): copper and
/// titanium κ(T), c(T) from Incropera, DeWitt, Bergman & Lavine (2007), *Fundamentals of Heat and
/// Mass Transfer*, 6th ed., Table A.1, 200–1200 K (copper) and 200–1500 K (titanium; the heat
/// capacity falls from 675 (1000 K) to 620 J/(kg·K) (1200 K) across the α→β transition (1155 K),
/// no latent-heat peak, docs/heat-model.md); α(T) from Kaye & Laby (NPL) §2.3.5, copper
/// 100–1100 K, titanium 293–1100 K (α phase). The other entries cite their tables in the file.
/// None when the entry has no table of this quantity.
pub fn bundled_table(name: &str, quantity: Quantity) -> Option<Table> {
    let tables = crate::models::diffusion7::library::entry(name)?.tables.as_ref()?;
    let points = match quantity {
        Quantity::Conductivity => tables.conductivity_table.as_ref(),
        Quantity::HeatCapacity => tables.heat_capacity_table.as_ref(),
        Quantity::ThermalExpansion => tables.thermal_expansion_table.as_ref(),
        Quantity::ElectricalResistivity => tables.electrical_resistivity_table.as_ref(),
    }?;
    Some(Table { temperature: points.iter().map(|p| p[0]).collect(), value: points.iter().map(|p| p[1]).collect() })
}

/// The entries of the library that have a table of `quantity` (for messages).
fn table_names(quantity: Quantity) -> String {
    crate::models::diffusion7::library::entries()
        .iter()
        .filter(|e| bundled_table(&e.name, quantity).is_some())
        .map(|e| e.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Linear thermal expansion of a material (docs/coupled.md (X1)).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Expansion {
    /// A constant α [1/K].
    Constant(f64),
    /// α(T) [1/K], piecewise linear, constant beyond its ends.
    Table(Table),
}

impl Expansion {
    /// (X1) The free thermal strain ε_th = ∫_{T_ref}^{T} α dT [1] from `t_ref` to `t` [K];
    /// exactly 0 at `t = t_ref`.
    pub fn strain(&self, t_ref: f64, t: f64) -> f64 {
        match self {
            Expansion::Constant(a) => a * (t - t_ref),
            Expansion::Table(tab) => tab.integral(t_ref, t),
        }
    }
}

impl Table {
    /// A validated table from points `[[T, v], ...]`; `key` names it in errors.
    pub fn new(points: &[[f64; 2]], key: &str, quantity: Quantity) -> Result<Table, ConfigError> {
        let (vmax, unit, what) = quantity.range();
        if points.len() < 2 {
            return Err(ConfigError::invalid(format!("{key}: {} point(s); a table needs at least 2 points [T, value]", points.len())));
        }
        for (k, &[t, v]) in points.iter().enumerate() {
            if !(t > 0.0 && t <= 1e4) {
                return Err(ConfigError::invalid(format!("{key}[{k}] = [{t}, {v}]: temperature {t} K is outside (0, 10000] K")));
            }
            if !(v > 0.0 && v <= vmax) {
                return Err(ConfigError::invalid(format!("{key}[{k}] = [{t}, {v}]: {what} {v} {unit} is outside (0, {vmax:e}] {unit}")));
            }
            if k > 0 && t <= points[k - 1][0] {
                return Err(ConfigError::invalid(format!(
                    "{key}[{k}] = [{t}, {v}]: temperatures must increase strictly ({t} K follows {} K)",
                    points[k - 1][0]
                )));
            }
        }
        Ok(Table { temperature: points.iter().map(|p| p[0]).collect(), value: points.iter().map(|p| p[1]).collect() })
    }

    /// From a case value: a bundled name or an array of `[T, v]` pairs.
    pub fn from_value(v: &toml::Value, key: &str, quantity: Quantity) -> Result<Table, ConfigError> {
        match v {
            toml::Value::String(name) => bundled_table(name, quantity).ok_or_else(|| {
                ConfigError::invalid(format!("{key} = \"{name}\": no bundled table of this name ({}), or give [[T, value], ...]", table_names(quantity)))
            }),
            toml::Value::Array(rows) => {
                let num = |x: &toml::Value| x.as_float().or_else(|| x.as_integer().map(|i| i as f64));
                let mut pts = Vec::with_capacity(rows.len());
                for (k, r) in rows.iter().enumerate() {
                    match r.as_array().map(|a| a.iter().map(num).collect::<Option<Vec<f64>>>()) {
                        Some(Some(a)) if a.len() == 2 => pts.push([a[0], a[1]]),
                        _ => return Err(ConfigError::invalid(format!("{key}[{k}] = {r}: expected a pair of numbers [T in K, value]"))),
                    }
                }
                Table::new(&pts, key, quantity)
            }
            other => Err(ConfigError::invalid(format!("{key} = {other}: expected [[T, value], ...] or a bundled name ({})", table_names(quantity)))),
        }
    }

    /// v(T), linear between points, constant beyond the ends.
    pub fn at(&self, t: f64) -> f64 {
        let (ts, vs) = (&self.temperature, &self.value);
        let n = ts.len();
        if t <= ts[0] {
            return vs[0];
        }
        if t >= ts[n - 1] {
            return vs[n - 1];
        }
        let k = ts.partition_point(|&x| x <= t) - 1;
        vs[k] + (vs[k + 1] - vs[k]) * (t - ts[k]) / (ts[k + 1] - ts[k])
    }

    /// ∫_a^b v(T) dT, exact for the piecewise-linear table (trapezoids split at the points).
    pub fn integral(&self, a: f64, b: f64) -> f64 {
        if a == b {
            return 0.0;
        }
        let (lo, hi, sign) = if a < b { (a, b, 1.0) } else { (b, a, -1.0) };
        let mut sum = 0.0;
        let mut x = lo;
        for &tk in self.temperature.iter().filter(|&&tk| tk > lo && tk < hi) {
            sum += (tk - x) * 0.5 * (self.at(x) + self.at(tk));
            x = tk;
        }
        sum += (hi - x) * 0.5 * (self.at(x) + self.at(hi));
        sign * sum
    }

    /// The mean of v over [a, b], `∫_a^b v dT / (b − a)`, and v(a) when a = b; robust when b − a
    /// is tiny (the segments' lengths cancel).
    pub fn mean(&self, a: f64, b: f64) -> f64 {
        if a == b {
            return self.at(a);
        }
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        let mut sum = 0.0;
        let mut x = lo;
        for &tk in self.temperature.iter().filter(|&&tk| tk > lo && tk < hi) {
            sum += (tk - x) / (hi - lo) * 0.5 * (self.at(x) + self.at(tk));
            x = tk;
        }
        sum + (hi - x) / (hi - lo) * 0.5 * (self.at(x) + self.at(hi))
    }
}

#[cfg(test)]
mod table_tests {
    use super::*;

    #[test]
    fn piecewise_linear_values_integrals_and_means() {
        let t = Table::new(&[[300.0, 400.0], [1300.0, 340.0]], "k", Quantity::Conductivity).unwrap();
        assert_eq!(t.at(200.0), 400.0);
        assert_eq!(t.at(2000.0), 340.0);
        assert!((t.at(800.0) - 370.0).abs() < 1e-12);
        // linear piece: mean over [a, b] is the value at the midpoint
        assert!((t.mean(400.0, 1000.0) - t.at(700.0)).abs() < 1e-12);
        assert!((t.mean(1000.0, 400.0) - t.at(700.0)).abs() < 1e-12);
        // constant extension below the first point: ∫_0^300 = 400·300
        assert!((t.integral(0.0, 300.0) - 120_000.0).abs() < 1e-9);
        assert!((t.integral(100.0, 1500.0) + t.integral(1500.0, 100.0)).abs() < 1e-9);
        let exact = 200.0 * 400.0 + 0.5 * (400.0 + 340.0) * 1000.0 + 200.0 * 340.0;
        assert!((t.integral(100.0, 1500.0) - exact).abs() < 1e-9);
        assert!((t.mean(500.0, 500.0 + 1e-12) - t.at(500.0)).abs() < 1e-9);
    }

    #[test]
    fn bad_tables_name_the_key_value_and_range() {
        let q = Quantity::HeatCapacity;
        let e = Table::new(&[[300.0, 500.0]], "materials.ti.heat_capacity_table", q).unwrap_err().to_string();
        assert!(e.contains("materials.ti.heat_capacity_table") && e.contains("at least 2"), "{e}");
        let e = Table::new(&[[300.0, 500.0], [300.0, 510.0]], "m.t", q).unwrap_err().to_string();
        assert!(e.contains("m.t[1] = [300, 510]") && e.contains("increase strictly"), "{e}");
        let e = Table::new(&[[300.0, 500.0], [400.0, -1.0]], "m.t", q).unwrap_err().to_string();
        assert!(e.contains("m.t[1]") && e.contains("-1") && e.contains("(0, 1e5]") && e.contains("J/(kg K)"), "{e}");
        let e = Table::new(&[[-3.0, 500.0], [400.0, 1.0]], "m.t", q).unwrap_err().to_string();
        assert!(e.contains("(0, 10000] K"), "{e}");
        let v: toml::Value = toml::from_str::<toml::Table>("t = [[300, 1], [400]]").unwrap()["t"].clone();
        let e = Table::from_value(&v, "m.t", q).unwrap_err().to_string();
        assert!(e.contains("m.t[1]") && e.contains("pair of numbers"), "{e}");
        let v = toml::Value::String("brass".into());
        assert!(Table::from_value(&v, "m.t", q).unwrap_err().to_string().contains("copper, titanium"));
    }

    #[test]
    fn library_presets_equal_their_own_tables_at_the_stated_temperature() {
        // every entry but the seed paper's two takes ρ, c, κ from the same handbook table as its
        // κ(T), c(T) (Incropera et al. at 300 K; 304: its MatWeb sheet at 50 °C); copper- and
        // titanium-ivannikov2022 keep their older constants
        let mut n = 0;
        for e in crate::models::diffusion7::library::entries().iter().filter(|e| !e.name.ends_with("-ivannikov2022")) {
            let p = preset(&e.name).unwrap();
            let at = |q| bundled_table(&e.name, q).unwrap().at(e.preset.temperature);
            assert_eq!(at(Quantity::Conductivity), p.conductivity, "{}", e.name);
            assert_eq!(at(Quantity::HeatCapacity), p.heat_capacity, "{}", e.name);
            n += 1;
        }
        assert_eq!(n, 12);
    }

    #[test]
    fn bundled_tables_at_300_k_match_the_constants_of_the_same_handbook() {
        // Incropera et al. (2007) Table A.1 at 300 K: copper 401 W/(m K), 385 J/(kg K); titanium 21.9, 522
        let k = |m, q| bundled_table(m, q).unwrap().at(300.0);
        assert_eq!(k("copper", Quantity::Conductivity), 401.0);
        assert_eq!(k("copper", Quantity::HeatCapacity), 385.0);
        assert_eq!(k("titanium", Quantity::Conductivity), 21.9);
        assert_eq!(k("titanium", Quantity::HeatCapacity), 522.0);
    }
}

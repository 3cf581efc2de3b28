//! The fitted parameters: `[[parameters]]` entries `key, min, max, log` where the key is
//! `PHASE.FIELD` of the starting material's phases (`beta.d0_gb`, `alpha.q_surface`, …) or
//! `model.FIELD` of the path factors (`model.path_factor_gb`, …).
//!
//! The optimiser works in unit coordinates u ∈ [0, 1]ⁿ: a linear parameter is
//! `θ = min + u·(max − min)`, a log parameter (prefactors `d0_*` by default, or `log = true`) is
//! `θ = log10(value) = log10(min) + u·(log10(max) − log10(min))`. θ are the "fit coordinates" in which
//! σ and correlations are reported.

use super::lookup;
use crate::error::ConfigError;
use crate::models::diffusion7::{Material, PathFactors, Phase};
use serde::Deserialize;

/// Fittable numeric fields of a phase (`from_temperature` is not one: it orders the phases).
pub const PHASE_FIELDS: [&str; 14] = [
    "atomic_volume",
    "gamma_surface",
    "gamma_gb",
    "delta_surface",
    "delta_gb",
    "mobile_fraction_surface",
    "mobile_fraction_gb",
    "mobile_fraction_lattice",
    "d0_surface",
    "q_surface",
    "d0_gb",
    "q_gb",
    "d0_lattice",
    "q_lattice",
];

/// Fittable path factors (`model.FIELD`).
pub const MODEL_FIELDS: [&str; 4] = ["path_factor_gb", "path_factor_neck", "path_factor_cap", "lattice_depth_factor"];

/// One `[[parameters]]` entry as written.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterEntry {
    pub key: String,
    pub min: f64,
    pub max: f64,
    #[serde(default)]
    pub log: Option<bool>,
}

/// What a parameter sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// Field `PHASE_FIELDS[field]` of phase `phase` of the material.
    Phase { phase: usize, field: usize },
    /// Field `MODEL_FIELDS[field]` of the path factors.
    Model { field: usize },
}

/// A validated parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    pub key: String,
    pub target: Target,
    /// Bounds in the parameter's own SI unit.
    pub min: f64,
    pub max: f64,
    /// Fitted as log10(value).
    pub log: bool,
    /// SI unit (from the range table).
    pub unit: &'static str,
}

fn phase_field_mut(p: &mut Phase, field: usize) -> &mut f64 {
    match PHASE_FIELDS[field] {
        "atomic_volume" => &mut p.atomic_volume,
        "gamma_surface" => &mut p.gamma_surface,
        "gamma_gb" => &mut p.gamma_gb,
        "delta_surface" => &mut p.delta_surface,
        "delta_gb" => &mut p.delta_gb,
        "mobile_fraction_surface" => &mut p.mobile_fraction_surface,
        "mobile_fraction_gb" => &mut p.mobile_fraction_gb,
        "mobile_fraction_lattice" => &mut p.mobile_fraction_lattice,
        "d0_surface" => &mut p.d0_surface,
        "q_surface" => &mut p.q_surface,
        "d0_gb" => &mut p.d0_gb,
        "q_gb" => &mut p.q_gb,
        "d0_lattice" => &mut p.d0_lattice,
        _ => &mut p.q_lattice,
    }
}

fn model_field_mut(f: &mut PathFactors, field: usize) -> &mut f64 {
    match field {
        0 => &mut f.path_factor_gb,
        1 => &mut f.path_factor_neck,
        2 => &mut f.path_factor_cap,
        _ => &mut f.lattice_depth_factor,
    }
}

/// Value of field `PHASE_FIELDS[field]` of a phase.
pub fn phase_field(p: &Phase, field: usize) -> f64 {
    let mut q = p.clone();
    *phase_field_mut(&mut q, field)
}

/// Value of field `MODEL_FIELDS[field]` of the path factors.
pub fn model_field(f: &PathFactors, field: usize) -> f64 {
    let mut g = *f;
    *model_field_mut(&mut g, field)
}

/// Every valid key for `material`, in a fixed order.
pub fn valid_keys(material: &Material) -> Vec<String> {
    let mut v: Vec<String> = material.phases.iter().flat_map(|p| PHASE_FIELDS.iter().map(move |f| format!("{}.{f}", p.name))).collect();
    v.extend(MODEL_FIELDS.iter().map(|f| format!("model.{f}")));
    v
}

impl Parameter {
    /// Validates one entry (`index` for messages) against the material.
    pub fn new(e: &ParameterEntry, index: usize, material: &Material) -> Result<Parameter, ConfigError> {
        let at = format!("parameters[{index}]");
        let unknown = || {
            ConfigError::invalid(format!(
                "{at}.key = \"{}\": unknown parameter of material \"{}\"; valid keys: {}",
                e.key,
                material.name,
                valid_keys(material).join(", ")
            ))
        };
        let (head, field) = e.key.split_once('.').ok_or_else(unknown)?;
        let (target, range_key) = if head == "model" {
            let f = MODEL_FIELDS.iter().position(|x| *x == field).ok_or_else(unknown)?;
            (Target::Model { field: f }, format!("model.{field}"))
        } else {
            let p = material.phases.iter().position(|p| p.name == head).ok_or_else(unknown)?;
            let f = PHASE_FIELDS.iter().position(|x| *x == field).ok_or_else(unknown)?;
            (Target::Phase { phase: p, field: f }, format!("materials.{}.phases.{head}.{field}", material.name))
        };
        let r = lookup(&range_key).ok_or_else(|| ConfigError::invalid(format!("internal: no range for {range_key}")))?;
        let min = r.check(&format!("{at}.min ({})", e.key), e.min)?;
        let max = r.check(&format!("{at}.max ({})", e.key), e.max)?;
        if !(min < max) {
            return Err(ConfigError::inconsistent(format!("{at}.min ({})", e.key), format!("{min} {} is not below max = {max} {}", r.unit, r.unit)));
        }
        let log = e.log.unwrap_or(field.starts_with("d0_"));
        if log && !(min > 0.0) {
            return Err(ConfigError::OutOfRange {
                key: format!("{at}.min ({}, log = true)", e.key),
                value: min,
                range: "(0, max)".into(),
                unit: r.unit.into(),
            });
        }
        Ok(Parameter { key: e.key.clone(), target, min, max, log, unit: r.unit })
    }

    /// Fit coordinate θ of a value (log10 for log parameters).
    pub fn theta(&self, value: f64) -> f64 {
        if self.log { value.log10() } else { value }
    }

    /// Bounds in θ.
    pub fn theta_bounds(&self) -> (f64, f64) {
        (self.theta(self.min), self.theta(self.max))
    }

    /// Value [SI] at unit coordinate u (clamped to [0, 1]).
    pub fn value(&self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        let (a, b) = self.theta_bounds();
        let th = a + u * (b - a);
        if u == 0.0 {
            self.min
        } else if u == 1.0 {
            self.max
        } else if self.log {
            10f64.powf(th)
        } else {
            th
        }
    }

    /// Unit coordinate of a value.
    pub fn unit_of(&self, value: f64) -> f64 {
        let (a, b) = self.theta_bounds();
        (self.theta(value) - a) / (b - a)
    }

    /// The current value in `material`/`factors`.
    pub fn get(&self, material: &Material, factors: &PathFactors) -> f64 {
        let (mut m, mut f) = (material.clone(), *factors);
        *self.slot(&mut m, &mut f)
    }

    fn slot<'a>(&self, m: &'a mut Material, f: &'a mut PathFactors) -> &'a mut f64 {
        match self.target {
            Target::Phase { phase, field } => phase_field_mut(&mut m.phases[phase], field),
            Target::Model { field } => model_field_mut(f, field),
        }
    }

    /// Sets the value [SI] in `material`/`factors`.
    pub fn set(&self, m: &mut Material, f: &mut PathFactors, value: f64) {
        *self.slot(m, f) = value;
    }
}

/// Applies values [SI] of `params` to copies of the starting material and factors.
pub fn apply(params: &[Parameter], material: &Material, factors: &PathFactors, values: &[f64]) -> (Material, PathFactors) {
    let (mut m, mut f) = (material.clone(), *factors);
    for (p, v) in params.iter().zip(values) {
        p.set(&mut m, &mut f, *v);
    }
    (m, f)
}

/// Validates all entries; a key may appear once.
pub fn parse_parameters(entries: &[ParameterEntry], material: &Material) -> Result<Vec<Parameter>, ConfigError> {
    if entries.is_empty() {
        return Err(ConfigError::invalid(format!("no [[parameters]] to fit; valid keys: {}", valid_keys(material).join(", "))));
    }
    let mut out: Vec<Parameter> = Vec::new();
    for (i, e) in entries.iter().enumerate() {
        let p = Parameter::new(e, i, material)?;
        if out.iter().any(|q| q.key == p.key) {
            return Err(ConfigError::invalid(format!("parameters[{i}].key = \"{}\" is listed twice", p.key)));
        }
        out.push(p);
    }
    Ok(out)
}

/// Refuses bounds that exclude the starting value (the material's, or the path factor's, before
/// the fit): the optimiser starts from it, and a start outside [min, max] was clamped silently to
/// the nearer bound (issue 39). The error names the parameter, the start, the bounds and the unit.
pub fn check_start(params: &[Parameter], material: &Material, factors: &PathFactors) -> Result<(), ConfigError> {
    for (i, p) in params.iter().enumerate() {
        let v = p.get(material, factors);
        if !(p.min <= v && v <= p.max) {
            let side = if v < p.min { "min" } else { "max" };
            return Err(ConfigError::Inconsistent {
                key: format!("parameters[{i}].{side} ({})", p.key),
                message: format!(
                    "the bounds [{}, {}] {} exclude the starting value {} {} of material \"{}\" (the fit starts there): widen the bounds to include it, \
                     or start from another value (a [[materials]] entry in the calibration file)",
                    crate::error::fmt_value(p.min),
                    crate::error::fmt_value(p.max),
                    p.unit,
                    crate::error::fmt_value(v),
                    p.unit,
                    material.name
                ),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(key: &str, min: f64, max: f64) -> ParameterEntry {
        ParameterEntry { key: key.into(), min, max, log: None }
    }

    #[test]
    fn keys_resolve_and_unknown_ones_list_the_valid_keys() {
        let ti = Material::titanium();
        let p = Parameter::new(&entry("beta.d0_gb", 1.0, 1e4), 0, &ti).unwrap();
        assert!(p.log && p.unit == "m^2/s");
        assert_eq!(p.get(&ti, &PathFactors::default()), 50.98);
        let q = Parameter::new(&entry("model.path_factor_gb", 0.1, 1.0), 1, &ti).unwrap();
        assert!(!q.log);
        let e = Parameter::new(&entry("gamma.d0_gb", 1.0, 2.0), 3, &ti).unwrap_err().to_string();
        assert!(
            e.contains("parameters[3].key = \"gamma.d0_gb\"")
                && e.contains("beta.q_surface")
                && e.contains("alpha.d0_gb")
                && e.contains("model.path_factor_cap"),
            "{e}"
        );
        let e = Parameter::new(&entry("beta.d0", 1.0, 2.0), 0, &ti).unwrap_err().to_string();
        assert!(e.contains("valid keys"), "{e}");
        let e = Parameter::new(&entry("beta.q_gb", 3e5, 2e5), 0, &ti).unwrap_err().to_string();
        assert!(e.contains("not below max"), "{e}");
        let e = Parameter::new(&entry("beta.q_gb", -1.0, 2e5), 2, &ti).unwrap_err().to_string();
        assert!(e.contains("parameters[2].min (beta.q_gb) = -1") && e.contains("J/mol"), "{e}");
    }

    #[test]
    fn unit_coordinates_round_trip_in_log_and_linear_space() {
        let ti = Material::titanium();
        let p = Parameter::new(&entry("beta.d0_gb", 1.0, 1e4), 0, &ti).unwrap();
        assert!((p.value(0.5) - 100.0).abs() < 1e-9);
        assert!((p.unit_of(100.0) - 0.5).abs() < 1e-15);
        let q = Parameter::new(&entry("beta.q_gb", 2e5, 2.4e5), 0, &ti).unwrap();
        assert_eq!(q.value(0.25), 2.1e5);
        let (m, _) = apply(&[p, q], &ti, &PathFactors::default(), &[10.0, 2.2e5]);
        assert_eq!(m.phases[1].d0_gb, 10.0);
        assert_eq!(m.phases[1].q_gb, 2.2e5);
    }
}

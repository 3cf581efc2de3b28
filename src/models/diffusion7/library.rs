//! The materials library (docs/materials.md): the bundled presets with their sources, read from
//! `materials.toml` beside this file. One entry gives the 7-DOF diffusion data of §9
//! ([`Entry::diffusion`]), the constants of `preset = "NAME"` ([`PresetData`]) and the κ(T), c(T),
//! α(T) tables of `conductivity_table = "NAME"` etc. ([`Tables`]); docs/materials.md is generated
//! from it ([`markdown`]).

use super::material::{Material, Phase};
use serde::Deserialize;
use std::sync::OnceLock;

/// The library file, as bundled.
pub const LIBRARY: &str = include_str!("materials.toml");

/// Constants a case's `[[materials]]` gets from `preset = "NAME"` (heat and mechanics).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PresetData {
    /// ρ [kg/m³].
    pub density: f64,
    /// c [J/(kg·K)] at `temperature`.
    pub heat_capacity: f64,
    /// κ [W/(m·K)] at `temperature`.
    pub conductivity: f64,
    /// E [Pa] (default: the entry's `young_modulus`).
    pub young_modulus: Option<f64>,
    /// ν [1] (default: the entry's `poisson_ratio`).
    pub poisson_ratio: Option<f64>,
    /// The temperature the constants hold at [K].
    pub temperature: f64,
    pub source: String,
}

/// Published property tables `[[T, value], ...]` (K and the property's SI unit).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tables {
    /// κ(T) [W/(m·K)].
    pub conductivity_table: Option<Vec<[f64; 2]>>,
    /// c(T) [J/(kg·K)].
    pub heat_capacity_table: Option<Vec<[f64; 2]>>,
    /// α(T) [1/K].
    pub thermal_expansion_table: Option<Vec<[f64; 2]>>,
    /// ρ_e(T) [Ω·m] (`sinterdem conductivity` with `quantity = "electrical"`).
    pub electrical_resistivity_table: Option<Vec<[f64; 2]>>,
    pub source: String,
}

/// One phase of an entry: the 7-DOF [`Phase`] and where its values come from.
#[derive(Debug, Clone, PartialEq)]
pub struct LibraryPhase {
    pub phase: Phase,
    pub source: String,
}

/// One library entry (a preset).
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    pub name: String,
    pub description: String,
    /// Where the diffusion data come from.
    pub source: String,
    /// E [Pa] of the 7-DOF data (virtual force (F4)).
    pub young_modulus: f64,
    /// ν [1] of the 7-DOF data.
    pub poisson_ratio: f64,
    pub elastic_source: String,
    /// The temperature E and ν hold at [K] (None: not stated).
    pub elastic_temperature: Option<f64>,
    /// E(T) `[[T, E], ...]` ([K], [Pa]) used at each contact's temperature (None: E constant).
    pub young_modulus_table: Option<Vec<[f64; 2]>>,
    /// The temperature range of the diffusion data [K].
    pub calibrated_min_temperature: f64,
    pub calibrated_max_temperature: f64,
    pub range_source: String,
    /// Melting (solidus) temperature [K].
    pub melting_temperature: f64,
    pub melting_source: String,
    /// Values fitted to sintering experiments by the cited authors.
    pub calibrated: Vec<String>,
    /// Values the model needs that no measurement gives (placeholders).
    pub unmeasured: Vec<String>,
    pub unmeasured_note: String,
    pub preset: PresetData,
    pub tables: Option<Tables>,
    pub phases: Vec<LibraryPhase>,
}

/// The entry as written (phases as tables, split into [`Phase`] and source afterwards).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEntry {
    name: String,
    description: String,
    source: String,
    young_modulus: f64,
    poisson_ratio: f64,
    elastic_source: String,
    elastic_temperature: Option<f64>,
    young_modulus_table: Option<Vec<[f64; 2]>>,
    calibrated_min_temperature: f64,
    calibrated_max_temperature: f64,
    range_source: String,
    melting_temperature: f64,
    melting_source: String,
    #[serde(default)]
    calibrated: Vec<String>,
    #[serde(default)]
    unmeasured: Vec<String>,
    #[serde(default)]
    unmeasured_note: String,
    preset: PresetData,
    tables: Option<Tables>,
    phases: Vec<toml::Table>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLibrary {
    materials: Vec<RawEntry>,
}

fn parse(text: &str) -> Result<Vec<Entry>, String> {
    let raw: RawLibrary = toml::from_str(text).map_err(|e| e.to_string())?;
    let mut out: Vec<Entry> = Vec::new();
    for r in raw.materials {
        if out.iter().any(|e| e.name == r.name) {
            return Err(format!("material \"{}\" is listed twice", r.name));
        }
        let mut phases = Vec::new();
        for mut t in r.phases {
            let source = match t.remove("source") {
                Some(toml::Value::String(s)) => s,
                _ => return Err(format!("material \"{}\": every phase needs a source = \"...\"", r.name)),
            };
            let phase: Phase = toml::Value::Table(t).try_into().map_err(|e: toml::de::Error| format!("material \"{}\": {e}", r.name))?;
            phases.push(LibraryPhase { phase, source });
        }
        let e = Entry {
            name: r.name,
            description: r.description,
            source: r.source,
            young_modulus: r.young_modulus,
            poisson_ratio: r.poisson_ratio,
            elastic_source: r.elastic_source,
            elastic_temperature: r.elastic_temperature,
            young_modulus_table: r.young_modulus_table,
            calibrated_min_temperature: r.calibrated_min_temperature,
            calibrated_max_temperature: r.calibrated_max_temperature,
            range_source: r.range_source,
            melting_temperature: r.melting_temperature,
            melting_source: r.melting_source,
            calibrated: r.calibrated,
            unmeasured: r.unmeasured,
            unmeasured_note: r.unmeasured_note,
            preset: r.preset,
            tables: r.tables,
            phases,
        };
        if let Some(t) = &e.young_modulus_table
            && (t.is_empty() || t.windows(2).any(|w| !(w[1][0] > w[0][0])) || t.iter().any(|p| !(p[0] > 0.0 && p[1] > 0.0 && p[1].is_finite())))
        {
            return Err(format!("material \"{}\": young_modulus_table needs [T, E] rows with T increasing (K) and E > 0 (Pa)", e.name));
        }
        e.diffusion().validate().map_err(|err| err.to_string())?;
        out.push(e);
    }
    Ok(out)
}

/// Every entry of the bundled library, in file order.
pub fn entries() -> &'static [Entry] {
    static LIB: OnceLock<Vec<Entry>> = OnceLock::new();
    LIB.get_or_init(|| parse(LIBRARY).unwrap_or_else(|e| panic!("internal: the bundled materials library is invalid: {e}")))
}

/// The names of the entries, comma-separated (for messages).
pub fn names() -> String {
    entries().iter().map(|e| e.name.as_str()).collect::<Vec<_>>().join(", ")
}

/// The entry called `name` (ASCII case ignored: "316L" finds "316l").
pub fn entry(name: &str) -> Option<&'static Entry> {
    entries().iter().find(|e| e.name.eq_ignore_ascii_case(name))
}

impl Entry {
    /// The 7-DOF material of the entry (docs/diffusion7.md §9).
    pub fn diffusion(&self) -> Material {
        Material {
            name: self.name.clone(),
            source: self.source.clone(),
            young_modulus: self.young_modulus,
            poisson_ratio: self.poisson_ratio,
            young_modulus_table: self.young_modulus_table.clone(),
            calibrated_min_temperature: self.calibrated_min_temperature,
            calibrated_max_temperature: self.calibrated_max_temperature,
            melting_temperature: Some(self.melting_temperature),
            phases: self.phases.iter().map(|p| p.phase.clone()).collect(),
        }
    }

    /// E [Pa] of `preset = NAME`.
    pub fn preset_young_modulus(&self) -> f64 {
        self.preset.young_modulus.unwrap_or(self.young_modulus)
    }

    /// ν [1] of `preset = NAME`.
    pub fn preset_poisson_ratio(&self) -> f64 {
        self.preset.poisson_ratio.unwrap_or(self.poisson_ratio)
    }

    /// The line a run using this entry's diffusion data writes once to `log.txt` when the model
    /// needs values no measurement gives; None when there are none.
    pub fn unmeasured_line(&self) -> Option<String> {
        let own: Vec<&str> = self.unmeasured.iter().map(String::as_str).filter(|k| !k.starts_with("model.")).collect();
        if own.is_empty() {
            return None;
        }
        Some(format!(
            "note: material \"{}\" (materials library, docs/materials.md): {} not measured ({}); fit them to your own experiments with `sinterdem calibrate` (docs/calibration.md)",
            self.name,
            own.join(", "),
            self.unmeasured_note
        ))
    }
}

/// The names of library materials a case uses for 7-DOF diffusion data: `pair.material`,
/// `pair.material_b` and `[[materials]]`' `diffusion` or `preset` (a material that defines its own
/// `[[materials.phases]]` or `name` shadows the library in a pair case is not counted).
pub fn used_by(case: &toml::Value) -> Vec<&'static Entry> {
    let mut out: Vec<&'static Entry> = Vec::new();
    let mats = case.get("materials").and_then(|m| m.as_array()).cloned().unwrap_or_default();
    let own = |name: &str| mats.iter().any(|m| m.get("name").and_then(|n| n.as_str()) == Some(name) && m.get("phases").is_some());
    let mut push = |n: Option<&str>| {
        if let Some(e) = n.and_then(entry)
            && !out.iter().any(|o| o.name == e.name)
        {
            out.push(e);
        }
    };
    if let Some(p) = case.get("pair") {
        for k in ["material", "material_b"] {
            let n = p.get(k).and_then(|v| v.as_str());
            if n.is_some_and(|n| !own(n)) {
                push(n);
            }
        }
    }
    for m in &mats {
        if m.get("phases").is_some() {
            continue;
        }
        push(m.get("diffusion").or_else(|| m.get("preset")).and_then(|v| v.as_str()));
    }
    out
}

fn fmt(v: f64) -> String {
    crate::error::fmt_value(v)
}

fn table_points(t: &[[f64; 2]]) -> String {
    t.iter().map(|[a, b]| format!("{} K: {}", fmt(*a), fmt(*b))).collect::<Vec<_>>().join("; ")
}

/// docs/materials.md's generated part: one section per entry with its values and sources.
pub fn markdown() -> String {
    let mut s = String::new();
    for e in entries() {
        s.push_str(&format!("### `{}` — {}\n\n", e.name, e.description));
        s.push_str(&format!("`preset = \"{0}\"` (heat and compact cases), `diffusion = \"{0}\"`, `pair.material = \"{0}\"`.\n\n", e.name));
        s.push_str("| quantity | value | unit | source |\n|---|---|---|---|\n");
        let p = &e.preset;
        let t = fmt(p.temperature);
        s.push_str(&format!(
            "| density ρ, heat capacity c, conductivity κ ({t} K) | {}, {}, {} | kg/m³, J/(kg·K), W/(m·K) | {} |\n",
            fmt(p.density),
            fmt(p.heat_capacity),
            fmt(p.conductivity),
            p.source
        ));
        let at = e.elastic_temperature.map_or(String::new(), |t| format!(" at {} K", fmt(t)));
        s.push_str(&format!(
            "| Young's modulus E, Poisson's ratio ν (preset){at} | {}, {} | Pa, 1 | {} |\n",
            fmt(e.preset_young_modulus()),
            fmt(e.preset_poisson_ratio()),
            e.elastic_source
        ));
        if e.preset_young_modulus() != e.young_modulus || e.preset_poisson_ratio() != e.poisson_ratio {
            s.push_str(&format!("| E, ν of the 7-DOF data{at} | {}, {} | Pa, 1 | {} |\n", fmt(e.young_modulus), fmt(e.poisson_ratio), e.elastic_source));
        }
        if let Some(tab) = &e.young_modulus_table {
            s.push_str(&format!(
                "| E(T) table (used at each contact's temperature, docs/materials.md (L1)) | {} | Pa | {} |\n",
                table_points(tab),
                e.elastic_source
            ));
        }
        s.push_str(&format!("| melting (solidus) temperature | {} | K | {} |\n", fmt(e.melting_temperature), e.melting_source));
        s.push_str(&format!(
            "| range of the diffusion data | {}–{} | K | {} |\n",
            fmt(e.calibrated_min_temperature),
            fmt(e.calibrated_max_temperature),
            e.range_source
        ));
        if let Some(tb) = &e.tables {
            // the ρ_e(T) line cites its source in its own comment in materials.toml
            let rho_source = "the comment on the line in src/models/diffusion7/materials.toml; docs/references.md";
            let rows = [
                ("κ(T) table", "W/(m·K)", &tb.conductivity_table, tb.source.as_str()),
                ("c(T) table", "J/(kg·K)", &tb.heat_capacity_table, tb.source.as_str()),
                ("α(T) table", "1/K", &tb.thermal_expansion_table, tb.source.as_str()),
                ("ρ_e(T) table", "Ω·m", &tb.electrical_resistivity_table, rho_source),
            ];
            for (what, unit, tab, source) in rows {
                if let Some(tab) = tab {
                    s.push_str(&format!("| {what} | {} | {unit} | {source} |\n", table_points(tab)));
                }
            }
        }
        s.push('\n');
        for lp in &e.phases {
            let ph = &lp.phase;
            s.push_str(&format!("Phase `{}` (from {} K), diffusion data of {}: {}.\n\n", ph.name, fmt(ph.from_temperature), e.source, lp.source));
            s.push_str("| key | value | unit |\n|---|---|---|\n");
            let rows: [(&str, f64, &str); 14] = [
                ("atomic_volume", ph.atomic_volume, "m³"),
                ("gamma_surface", ph.gamma_surface, "J/m²"),
                ("gamma_gb", ph.gamma_gb, "J/m²"),
                ("delta_surface", ph.delta_surface, "m"),
                ("delta_gb", ph.delta_gb, "m"),
                ("mobile_fraction_surface", ph.mobile_fraction_surface, "1"),
                ("mobile_fraction_gb", ph.mobile_fraction_gb, "1"),
                ("mobile_fraction_lattice", ph.mobile_fraction_lattice, "1"),
                ("d0_surface", ph.d0_surface, "m²/s"),
                ("q_surface", ph.q_surface, "J/mol"),
                ("d0_gb", ph.d0_gb, "m²/s"),
                ("q_gb", ph.q_gb, "J/mol"),
                ("d0_lattice", ph.d0_lattice, "m²/s"),
                ("q_lattice", ph.q_lattice, "J/mol"),
            ];
            for (k, v, u) in rows {
                let flag = if e.unmeasured.iter().any(|x| x == k) {
                    " (not measured)"
                } else if e.calibrated.iter().any(|x| x == k) {
                    " (fitted)"
                } else {
                    ""
                };
                s.push_str(&format!("| `{k}` | {}{flag} | {u} |\n", fmt(v)));
            }
            s.push('\n');
        }
        if !e.unmeasured.is_empty() {
            s.push_str(&format!("Not measured: {} — {}.", e.unmeasured.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", "), e.unmeasured_note));
            if !e.calibrated.is_empty() {
                s.push_str(&format!(" Fitted by the cited authors: {}.", e.calibrated.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ")));
            }
            s.push_str(" `sinterdem calibrate` fits them to your own data (docs/calibration.md).\n\n");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_entry_is_valid_and_reachable_by_name() {
        let names: Vec<&str> = entries().iter().map(|e| e.name.as_str()).collect();
        for want in [
            "copper-ivannikov2022",
            "titanium-ivannikov2022",
            "copper",
            "titanium",
            "nickel",
            "silver",
            "iron",
            "tungsten",
            "316l",
            "alumina",
            "molybdenum",
            "mar-m200",
            "304",
            "lead",
        ] {
            assert!(names.contains(&want), "{want} missing from {names:?}");
        }
        assert_eq!(entry("316L").unwrap().name, "316l");
        assert!(entry("brass").is_none());
        // iron: α only (no γ data could be read, docs/materials.md "Iron above 1184 K"); its
        // declared range ends below the α→γ transition at 1185 K
        let e = entry("iron").unwrap();
        let fe = e.diffusion();
        assert_eq!(fe.transitions().count(), 0);
        assert_eq!(fe.phases[fe.phase_at(1300.0)].name, "alpha");
        assert!(fe.calibrated_max_temperature < 1185.0 && e.range_source.contains("1185 K"));
    }

    #[test]
    fn gb_prefactors_are_the_compiled_products_over_the_layer_thickness() {
        // D0_gb = δD0b / δ_gb: every compiled phase states δD0b in its source; the stored D0_gb
        // times δ_gb must give it back to the digits written (only the product enters the model)
        let mut n = 0;
        for e in entries().iter().filter(|e| !e.name.ends_with("-ivannikov2022")) {
            for lp in &e.phases {
                let s = &lp.source;
                let i = s.find("δD0b = ").unwrap_or_else(|| panic!("{}: no δD0b in {s}", e.name)) + "δD0b = ".len();
                let num: f64 = s[i..].split_whitespace().next().unwrap().parse().unwrap();
                let prod = lp.phase.d0_gb * lp.phase.delta_gb;
                assert!((prod / num - 1.0).abs() < 5e-3, "{} {}: {prod} vs {num}", e.name, lp.phase.name);
                n += 1;
            }
        }
        assert_eq!(n, 13);
    }

    #[test]
    fn no_entry_takes_its_surface_data_from_the_unread_gjostein_correlation() {
        // [G73] was never read; its last user, iron's γ phase (typed from memory), is removed:
        // every phase names its surface data's source, and none is the correlation
        for e in entries() {
            for lp in &e.phases {
                assert!(!lp.source.contains("[G73] with T_m"), "{} {}: {}", e.name, lp.phase.name, lp.source);
                assert!(lp.phase.d0_surface != 7.4e-2 || e.name.ends_with("-ivannikov2022"), "{} {}", e.name, lp.phase.name);
            }
        }
    }

    #[test]
    fn a_library_with_an_unknown_key_or_a_phase_without_source_is_refused() {
        let good = "[[materials]]\nname = \"x\"\ndescription = \"d\"\nsource = \"s\"\nyoung_modulus = 1e11\npoisson_ratio = 0.3\nelastic_source = \"s\"\ncalibrated_min_temperature = 900.0\ncalibrated_max_temperature = 1000.0\nrange_source = \"s\"\nmelting_temperature = 1100.0\nmelting_source = \"s\"\n[materials.preset]\ndensity = 1.0\nheat_capacity = 1.0\nconductivity = 1.0\ntemperature = 300.0\nsource = \"s\"\n[[materials.phases]]\nname = \"p\"\nSOURCE\nfrom_temperature = 0.0\natomic_volume = 1e-29\ngamma_surface = 1.0\ngamma_gb = 0.3\ndelta_surface = 1e-10\ndelta_gb = 1e-10\nmobile_fraction_surface = 1.0\nmobile_fraction_gb = 1.0\nd0_surface = 1.0\nq_surface = 2e5\nd0_gb = 1.0\nq_gb = 2e5\nd0_lattice = 1.0\nq_lattice = 2e5\n";
        assert!(parse(&good.replace("SOURCE", "source = \"t\"")).is_ok());
        assert!(parse(&good.replace("SOURCE", "")).unwrap_err().contains("needs a source"));
        assert!(parse(&good.replace("SOURCE", "source = \"t\"\nq_surfce = 1.0")).unwrap_err().contains("q_surfce"));
        assert!(parse(&good.replace("SOURCE", "source = \"t\"").replace("q_gb = 2e5", "q_gb = -1.0")).unwrap_err().contains("q_gb"));
    }
}

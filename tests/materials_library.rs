//! The materials library (docs/materials.md, issue 25 item 1): every preset resolves to the values
//! written in `src/models/diffusion7/materials.toml` (read here independently with the toml
//! crate), docs/materials.md is generated from it, a short pair of every preset (every phase)
//! grows a neck, and the 316L case of docs/materials.md runs warning-free while the same case with
//! `q_surface = 220` is refused by `check` with key, line and the kJ/mol hint.

mod common;

use sinterdem::models::diffusion7::{Material as D7, library};
use std::process::Command;

const FILE: &str = "src/models/diffusion7/materials.toml";

fn raw_entries() -> Vec<toml::Table> {
    let t: toml::Table = std::fs::read_to_string(FILE).unwrap().parse().unwrap();
    t["materials"].as_array().unwrap().iter().map(|m| m.as_table().unwrap().clone()).collect()
}

fn num(v: &toml::Value) -> f64 {
    v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).unwrap()
}

fn points(v: &toml::Value) -> (Vec<f64>, Vec<f64>) {
    let rows = v.as_array().unwrap();
    (rows.iter().map(|r| num(&r[0])).collect(), rows.iter().map(|r| num(&r[1])).collect())
}

#[test]
fn every_preset_resolves_to_the_values_written_in_the_file() {
    let raw = raw_entries();
    assert_eq!(
        raw.len(),
        14,
        "copper- and titanium-ivannikov2022, nickel, silver, iron, tungsten, 316l, alumina, copper, titanium, molybdenum, mar-m200, 304, lead"
    );
    for m in &raw {
        let name = m["name"].as_str().unwrap();
        // the 7-DOF data (pair.material, diffusion = NAME)
        let d = D7::builtin(name).unwrap();
        assert_eq!(d.young_modulus, num(&m["young_modulus"]), "{name}");
        assert_eq!(d.poisson_ratio, num(&m["poisson_ratio"]), "{name}");
        assert_eq!(d.calibrated_min_temperature, num(&m["calibrated_min_temperature"]), "{name}");
        assert_eq!(d.calibrated_max_temperature, num(&m["calibrated_max_temperature"]), "{name}");
        assert_eq!(d.melting_temperature, Some(num(&m["melting_temperature"])), "{name}");
        let phases = m["phases"].as_array().unwrap();
        assert_eq!(d.phases.len(), phases.len(), "{name}");
        let mut compared = 0;
        for (p, rp) in d.phases.iter().zip(phases) {
            let json = serde_json::to_value(p).unwrap();
            for (k, v) in rp.as_table().unwrap() {
                if matches!(k.as_str(), "name" | "source") {
                    continue;
                }
                assert_eq!(json[k].as_f64().unwrap(), num(v), "{name}.{}.{k}", p.name);
                compared += 1;
            }
            assert_eq!(p.name, rp["name"].as_str().unwrap());
        }
        assert!(compared >= 15 * phases.len(), "{name}: {compared} values compared");
        // the preset of a case's [[materials]] (heat and compact cases)
        let pre = m["preset"].as_table().unwrap();
        let case: toml::Value = toml::from_str(&format!("name = \"x\"\npreset = \"{name}\"")).unwrap();
        let r = sinterdem::material::parse_one(case).unwrap();
        assert_eq!(r.density, num(&pre["density"]), "{name}");
        assert_eq!(r.heat_capacity, num(&pre["heat_capacity"]), "{name}");
        assert_eq!(r.conductivity, num(&pre["conductivity"]), "{name}");
        assert_eq!(r.young_modulus, pre.get("young_modulus").map_or(num(&m["young_modulus"]), num), "{name}");
        assert_eq!(r.poisson_ratio, pre.get("poisson_ratio").map_or(num(&m["poisson_ratio"]), num), "{name}");
        assert_eq!(r.diffusion.as_deref(), Some(name));
        assert!(r.conductivity_table.is_none() && r.heat_capacity_table.is_none() && r.thermal_expansion.is_none(), "{name}: a preset gives constants");
        // the tables by name (conductivity_table = NAME, ...)
        let tables = m.get("tables").and_then(|t| t.as_table()).unwrap_or_else(|| panic!("{name}: no tables"));
        for key in ["conductivity_table", "heat_capacity_table", "thermal_expansion_table"] {
            let case: toml::Value = toml::from_str(&format!("name = \"x\"\npreset = \"{name}\"\n{key} = \"{name}\"")).unwrap();
            match tables.get(key) {
                Some(want) => {
                    let r = sinterdem::material::parse_one(case).unwrap();
                    let got = match key {
                        "conductivity_table" => r.conductivity_table.unwrap(),
                        "heat_capacity_table" => r.heat_capacity_table.unwrap(),
                        _ => match r.thermal_expansion.unwrap() {
                            sinterdem::material::Expansion::Table(t) => t,
                            e => panic!("{e:?}"),
                        },
                    };
                    assert_eq!((got.temperature, got.value), points(want), "{name}.{key}");
                }
                None => {
                    let e = sinterdem::material::parse_one(case).unwrap_err().to_string();
                    assert!(e.contains(key) && e.contains("copper"), "{name}.{key}: {e}");
                }
            }
        }
    }
}

#[test]
fn copper_and_titanium_keep_their_values_bit_for_bit() {
    // the values of the code before the library (bundled checksums depend on them)
    let p = |n: &str| sinterdem::material::preset(n).unwrap();
    let (cu, ti) = (p("copper-ivannikov2022"), p("titanium-ivannikov2022"));
    assert_eq!([cu.density, cu.heat_capacity, cu.conductivity, cu.young_modulus, cu.poisson_ratio], [8960.0, 385.0, 394.0, 72e9, 0.34]);
    assert_eq!([ti.density, ti.heat_capacity, ti.conductivity, ti.young_modulus, ti.poisson_ratio], [4506.0, 523.0, 21.9, 57e9, 0.39]);
    let d = D7::copper();
    assert_eq!((d.young_modulus, d.poisson_ratio, d.phases[0].d0_gb, d.phases[0].q_lattice), (72e9, 0.3, 2.7e11, 207.0e3));
    let t = D7::titanium();
    assert_eq!((t.phases[1].from_temperature, t.phases[0].d0_lattice, t.phases[1].d0_lattice), (1156.0, 1.7e-8, 1.9e-7));
    let k = sinterdem::material::bundled_table("titanium-ivannikov2022", sinterdem::material::Quantity::HeatCapacity).unwrap();
    assert_eq!(k.at(1200.0), 620.0);
    // an unknown preset names the library
    let case: toml::Value = toml::from_str("name = \"x\"\npreset = \"brass\"").unwrap();
    let e = sinterdem::material::parse_one(case).unwrap_err().to_string();
    assert!(e.contains("brass") && e.contains("316l") && e.contains("alumina") && e.contains("docs/materials.md"), "{e}");
}

#[test]
fn docs_materials_md_is_generated_from_the_file() {
    let doc = std::fs::read_to_string("docs/materials.md").unwrap();
    let begin = doc.find("<!-- materials:begin").expect("marker");
    let body = doc[begin..].find('\n').unwrap() + begin + 1;
    let end = doc.find("<!-- materials:end -->").expect("marker");
    assert_eq!(&doc[body..end], library::markdown(), "docs/materials.md is out of date: regenerate with `sinterdem materials --markdown`");
    for e in library::entries() {
        assert!(doc.contains(&format!("### `{}`", e.name)), "{}", e.name);
    }
}

/// A temperature inside both the data range and phase `i`'s interval (the middle of the overlap);
/// None for a phase the declared range leaves out (issue 37: the seed paper's β titanium).
fn temperature_of_phase(m: &D7, i: usize) -> Option<f64> {
    let lo = m.phases[i].from_temperature.max(m.calibrated_min_temperature);
    let hi = m.phases.get(i + 1).map_or(f64::INFINITY, |p| p.from_temperature).min(m.calibrated_max_temperature);
    if lo >= hi {
        assert!(
            matches!((m.name.as_str(), m.phases[i].name.as_str()), ("titanium-ivannikov2022", "beta")),
            "{}: phase {} has no temperature inside the data range",
            m.name,
            m.phases[i].name
        );
        return None;
    }
    Some(0.5 * (lo + hi))
}

#[test]
fn a_short_pair_of_every_preset_and_phase_grows_a_neck_and_shrinks() {
    for e in library::entries() {
        let m = e.diffusion();
        for i in 0..m.phases.len() {
            let Some(t) = temperature_of_phase(&m, i) else { continue };
            assert_eq!(m.phase_at(t), i);
            let case: toml::Value = toml::from_str(&format!(
                "kind = \"pair\"\n[pair]\nmaterial = \"{}\"\nradius = 20.0e-6\nend_time = 100.0\n[temperature]\nconstant = {t}\n[output]\nplot = false\n",
                e.name
            ))
            .unwrap();
            let spec = sinterdem::kinds::pair::parse_pair_case(&case).unwrap();
            let run = sinterdem::kinds::pair::run_pair(&spec, true, false).unwrap();
            let y1_0 = run.states[0][0];
            let (neck, shrink) = (run.contact.neck_ratio(), run.contact.shrinkage());
            assert!(run.contact.y[0] > 2.0 * y1_0, "{} {} at {t} K: y1 {} from {}", e.name, m.phases[i].name, run.contact.y[0], y1_0);
            assert!(neck > 0.05 && neck < 1.0 && shrink > 0.0 && shrink < 0.1, "{} at {t} K: y1/R = {neck}, dL/L0 = {shrink}", e.name);
            assert!(run.warnings.is_empty(), "{} at {t} K: {:?}", e.name, run.warnings);
        }
    }
}

fn sinterdem(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_sinterdem")).args(args).env_remove("CI").output().unwrap()
}

/// The 316L pair snippet of docs/materials.md ("Using a preset").
fn doc_316l_case() -> String {
    let doc = std::fs::read_to_string("docs/materials.md").unwrap();
    let i = doc.find("material = \"316l\"").expect("docs/materials.md shows a 316l pair case");
    let a = doc[..i].rfind("```toml\n").unwrap() + 8;
    let b = a + doc[a..].find("```").unwrap();
    doc[a..b].to_string()
}

/// The 316l entry written out in full as a pair case's `[[materials]]` (the layout of the worked
/// example of docs/materials.md), from the library file read independently; `q_surface` as given.
fn written_out_316l(q_surface: &str) -> String {
    let m = raw_entries().into_iter().find(|m| m["name"].as_str() == Some("316l")).unwrap();
    let mut s = String::from("\n[[materials]]\nname = \"316l\"\n");
    for k in ["young_modulus", "poisson_ratio", "calibrated_min_temperature", "calibrated_max_temperature", "melting_temperature"] {
        s += &format!("{k} = {:e}\n", num(&m[k]));
    }
    for p in m["phases"].as_array().unwrap() {
        s += "\n[[materials.phases]]\n";
        for (k, v) in p.as_table().unwrap() {
            match k.as_str() {
                "source" => {}
                "name" => s += &format!("name = {v}\n"),
                "q_surface" => s += &format!("q_surface = {q_surface}\n"),
                _ => s += &format!("{k} = {:e}\n", num(v)),
            }
        }
    }
    s
}

#[test]
fn the_316l_case_of_the_docs_runs_warning_free_and_a_kj_per_mol_slip_is_refused_at_its_line() {
    let dir = common::tmp_dir("316l");
    let case = dir.join("pair-316l.toml");
    std::fs::write(&case, doc_316l_case()).unwrap();
    let out = dir.join("out");
    let o = sinterdem(&["run", case.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr).to_lowercase();
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("warning"), "{err}");
    // the placeholder note goes to log.txt only (console at -v)
    assert!(!err.contains("not measured"), "{err}");
    let log = std::fs::read_to_string(out.join("log.txt")).unwrap();
    assert_eq!(log.matches("not measured").count(), 1, "{log}");
    assert!(log.contains("material \"316l\"") && log.contains("sinterdem calibrate"), "{log}");
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let neck = s["neck_ratio"].as_f64().unwrap();
    assert!(neck > 0.1 && s["shrinkage"].as_f64().unwrap() > 0.0, "{s}");

    // the same material written out in full gives the same run (a case's [[materials]] of the
    // same name replaces the library entry)
    let q = num(&raw_entries().into_iter().find(|m| m["name"].as_str() == Some("316l")).unwrap()["phases"][0]["q_surface"]);
    let full = dir.join("full.toml");
    std::fs::write(&full, doc_316l_case() + &written_out_316l(&format!("{q:e}"))).unwrap();
    let o = sinterdem(&["run", full.to_str().unwrap(), "--out", dir.join("out-full").to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s2: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("out-full/summary.json")).unwrap()).unwrap();
    assert_eq!(s2["neck_ratio"], s["neck_ratio"]);
    assert_eq!(s2["shrinkage"], s["shrinkage"]);

    // q_surface = 220 (kJ/mol meant): refused by check with file, line, key and the hint
    let slip = dir.join("slip.toml");
    let text = doc_316l_case() + &written_out_316l("220");
    std::fs::write(&slip, &text).unwrap();
    let line = text.lines().position(|l| l.starts_with("q_surface = 220")).unwrap() + 1;
    let o = sinterdem(&["check", slip.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains(&format!("slip.toml:{line}:")), "line {line}: {err}");
    assert!(err.contains("q_surface") && err.contains("220 J/mol") && err.contains("kJ/mol"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

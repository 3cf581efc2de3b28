//! The materials library against its sources (issue 37): every value tagged [DFM93] equals the
//! stored DFM290 data files (validation/data/dfm290/, read here independently of the library
//! code), every source text carries tags that resolve to docs/references.md, no preset's D(T)
//! exceeds the "faster than a liquid" bound inside its declared range, and α-iron at 1100 K,
//! tungsten at 0.6 T_m and copper at 1193 K sinter as the compiled data written out as an inline
//! material do.

mod common;

use sinterdem::models::diffusion7::advance::D_IMPLAUSIBLE;
use sinterdem::models::diffusion7::library;
use std::collections::HashMap;

const DIR: &str = "validation/data/dfm290";

/// MATLPARS.DAT as (material, key) → value.
fn matlpars() -> HashMap<(String, String), f64> {
    let text = std::fs::read_to_string(format!("{DIR}/MATLPARS.DAT")).unwrap();
    let mut m = HashMap::new();
    for l in text.lines() {
        let f: Vec<&str> = l.split_whitespace().collect();
        if f.len() >= 3
            && let Ok(v) = f[2].parse::<f64>()
        {
            m.entry((f[0].to_string(), f[1].to_string())).or_insert(v);
        }
    }
    m
}

/// A `*.P` file as label → value (the first line of each label).
fn p_file(name: &str) -> HashMap<String, f64> {
    let text = std::fs::read_to_string(format!("{DIR}/{name}")).unwrap();
    let mut m = HashMap::new();
    for l in text.lines() {
        let (num, rest) = l.trim_start().split_once(' ').unwrap();
        let label = rest.trim_start().trim_start_matches('\'').split('\'').next().unwrap().trim().to_string();
        m.entry(label).or_insert_with(|| num.parse::<f64>().unwrap());
    }
    m
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a / b - 1.0).abs() <= tol
}

/// (entry, phase, DFM290 material file, MATLPARS.DAT name) of every phase taken from DFM290.
const DFM_PHASES: [(&str, &str, &str, &str); 13] = [
    ("nickel", "fcc", "NICKEL.P", "NICKEL"),
    ("silver", "fcc", "SILVER.P", "SILVER"),
    ("iron", "alpha", "ALPHA-FE.P", "FE-ALPHA"),
    ("tungsten", "bcc", "TUNGSTEN.P", "TUNGSTEN"),
    ("316l", "fcc", "SS-316.P", "SS-316"),
    ("alumina", "alpha", "ALUMINA.P", "ALUMINA"),
    ("copper", "fcc", "COPPER.P", "COPPER"),
    ("titanium", "alpha", "ALPHA-TI.P", "TI-ALPHA"),
    ("titanium", "beta", "BETA-TI.P", "TI-BETA"),
    ("molybdenum", "bcc", "MOLYBDM.P", "MOLYBDM"),
    ("mar-m200", "fcc", "MAR-M200.P", "MAR-M200"),
    ("304", "fcc", "SS-304.P", "SS-304"),
    ("lead", "fcc", "LEAD.P", "LEAD"),
];

#[test]
fn every_dfm290_value_equals_the_stored_data_files() {
    let mp = matlpars();
    let get = |m: &str, k: &str| *mp.get(&(m.to_string(), k.to_string())).unwrap_or_else(|| panic!("MATLPARS.DAT has no {m} {k}"));
    let mut compared = 0;
    for (name, phase, pfile, mname) in DFM_PHASES {
        let e = library::entry(name).unwrap();
        let lp = e.phases.iter().find(|p| p.phase.name == phase).unwrap();
        let ph = &lp.phase;
        // the phase's source names the files it was transcribed from
        assert!(lp.source.contains(&format!("[DFM93] {pfile}")), "{name} {phase}: {}", lp.source);
        assert!(lp.source.contains(&format!("MATLPARS.DAT {mname}")), "{name} {phase}: {}", lp.source);
        let p = p_file(pfile);
        let pv = |label: &str| *p.get(label).unwrap_or_else(|| panic!("{pfile}: no '{label}'"));
        // the material file and MATLPARS.DAT agree on the diffusion data used (where MATLPARS.DAT
        // has the line: its SS-304 record holds only Ω and the surface, density and modulus lines)
        for (label, key) in [
            ("Atomic Volume", "Omega"),
            ("Pre-exp. Volume Diffusion", "VolD0"),
            ("Activ. energy, Vol. Diff.", "VolErg"),
            ("Pre-exp. Bdry Diffusion", "BdyD0"),
            ("Activ. energy, Bdry. Diff.", "BdyErg"),
        ] {
            if let Some(&m) = mp.get(&(mname.to_string(), key.to_string())) {
                assert!(close(pv(label), m, 1e-9), "{pfile} '{label}' {} vs MATLPARS {mname} {key} {m}", pv(label));
            }
        }
        let ctx = format!("{name} {phase}");
        assert_eq!(ph.atomic_volume, pv("Atomic Volume"), "{ctx}: Ω");
        assert_eq!(ph.d0_lattice, pv("Pre-exp. Volume Diffusion"), "{ctx}: D0v");
        assert_eq!(ph.q_lattice, pv("Activ. energy, Vol. Diff.") * 1e3, "{ctx}: Qv");
        assert_eq!(ph.q_gb, pv("Activ. energy, Bdry. Diff.") * 1e3, "{ctx}: Qb");
        // the library splits the compiled products δ·D0 into δ and D0 (D0 written to 3–5 digits)
        assert!(
            close(ph.delta_gb * ph.d0_gb, pv("Pre-exp. Bdry Diffusion"), 1.5e-3),
            "{ctx}: δ_gb·D0_gb {} vs δD0b {}",
            ph.delta_gb * ph.d0_gb,
            pv("Pre-exp. Bdry Diffusion")
        );
        assert!(
            close(ph.delta_surface * ph.d0_surface, get(mname, "SurD0"), 1.5e-3),
            "{ctx}: δ_s·D0_s {} vs SurD0 {}",
            ph.delta_surface * ph.d0_surface,
            get(mname, "SurD0")
        );
        assert_eq!(ph.q_surface, get(mname, "SurErg") * 1e3, "{ctx}: Qs");
        assert_eq!(ph.gamma_surface, get(mname, "EnrgSr"), "{ctx}: γ_s");
        assert_eq!((ph.mobile_fraction_surface, ph.mobile_fraction_gb, ph.mobile_fraction_lattice), (1.0, 1.0, 1.0), "{ctx}: tracer data, n = 1");
        // a melting point quoted from the file ("[DFM93] X.P uses N K" or the file itself)
        let tm = pv("Melting Point");
        if let Some(i) = e.melting_source.find(&format!("{pfile} uses ")) {
            let n: f64 = e.melting_source[i + pfile.len() + 6..].split_whitespace().find_map(|w| w.parse().ok()).unwrap();
            assert_eq!(n, tm, "{ctx}: T_m quoted from {pfile}");
        } else if e.melting_source.contains(&format!("[DFM93] {pfile}")) {
            assert_eq!(e.melting_temperature, tm, "{ctx}: T_m");
        }
        // the new entries take their layer thickness from the file's 'Burgers vector' (4 digits)
        if let Some(i) = lp.source.find(", b = ") {
            let b: f64 = lp.source[i + 6..].split_whitespace().next().unwrap().parse().unwrap();
            assert!(close(b, pv("Burgers vector"), 5e-4), "{ctx}: b {b} vs {}", pv("Burgers vector"));
            assert!(close(ph.delta_gb, 2.0 * b, 1e-9) && close(ph.delta_surface, b, 1e-9), "{ctx}: δ_gb = 2b, δ_s = b");
        }
        compared += 1;
    }
    assert_eq!(compared, 13);
    // elastic and heat constants quoted from MATLPARS.DAT
    for (name, m) in [("molybdenum", "MOLYBDM"), ("mar-m200", "MAR-M200"), ("lead", "LEAD")] {
        assert_eq!(library::entry(name).unwrap().young_modulus, get(m, "YngMod") * 1e9, "{name}: E");
    }
    assert_eq!(library::entry("mar-m200").unwrap().preset.density, get("MAR-M200", "Densty"));
}

#[test]
fn the_stored_files_are_the_ones_the_provenance_note_lists() {
    // the SHA-256 of each stored file, as recorded in PROVENANCE.md when it was read
    use sha2::{Digest, Sha256};
    let note = std::fs::read_to_string(format!("{DIR}/PROVENANCE.md")).unwrap();
    let mut n = 0;
    for entry in std::fs::read_dir(DIR).unwrap().flatten() {
        let name = entry.file_name().to_string_lossy().to_string();
        if name == "PROVENANCE.md" {
            continue;
        }
        let h = Sha256::digest(std::fs::read(entry.path()).unwrap());
        let hex: String = h.iter().map(|b| format!("{b:02x}")).collect();
        assert!(note.contains(&format!("{hex}  {name}")), "{name}: {hex} not in PROVENANCE.md");
        n += 1;
    }
    assert_eq!(n, 17);
}

/// Every `[TAG]` in `s`.
fn tags(s: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = s;
    while let Some(i) = rest.find('[') {
        let after = &rest[i + 1..];
        if let Some(j) = after.find(']') {
            let t = &after[..j];
            if !t.is_empty() && t.chars().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit()) {
                out.push(t.to_string());
            }
            rest = &after[j..];
        } else {
            break;
        }
    }
    out
}

#[test]
fn every_source_text_carries_tags_that_resolve_to_the_references() {
    let refs = std::fs::read_to_string("docs/references.md").unwrap();
    let table = &refs[refs.find("## Source tags of the materials library").expect("section")..];
    let table = &table[..table[3..].find("\n## ").map_or(table.len(), |i| i + 3)];
    for e in library::entries() {
        let mut texts: Vec<(&str, &str)> = vec![
            ("source", &e.source),
            ("elastic_source", &e.elastic_source),
            ("range_source", &e.range_source),
            ("melting_source", &e.melting_source),
            ("preset.source", &e.preset.source),
        ];
        if let Some(t) = &e.tables {
            texts.push(("tables.source", &t.source));
        }
        for lp in &e.phases {
            texts.push(("phase source", &lp.source));
        }
        for (what, s) in texts {
            let t = tags(s);
            assert!(!t.is_empty(), "{} {what} has no source tag: {s}", e.name);
            for tag in t {
                assert!(table.contains(&format!("| [{tag}] |")), "{} {what}: tag [{tag}] is not in docs/references.md", e.name);
            }
        }
        assert!(e.elastic_temperature.is_some(), "{}: E and ν without their temperature", e.name);
    }
}

/// D(T) [m²/s] of the three mechanisms of a phase.
fn diffusivities(p: &sinterdem::models::diffusion7::Phase, t: f64) -> [(&'static str, f64); 3] {
    let r = sinterdem::units::GAS_CONSTANT;
    [
        ("surface", p.d0_surface * (-p.q_surface / (r * t)).exp()),
        ("gb", p.d0_gb * (-p.q_gb / (r * t)).exp()),
        ("lattice", p.d0_lattice * (-p.q_lattice / (r * t)).exp()),
    ]
}

#[test]
fn no_preset_is_faster_than_a_liquid_inside_its_declared_range() {
    // every entry, every phase, at the ends of the part of the declared range the phase covers
    // (D(T) is monotonic in T, so the upper end bounds the phase)
    let mut checked = 0;
    for e in library::entries() {
        let m = e.diffusion();
        for (i, p) in m.phases.iter().enumerate() {
            let lo = p.from_temperature.max(m.calibrated_min_temperature);
            let next = m.phases.get(i + 1).map_or(f64::INFINITY, |q| q.from_temperature);
            // the phase holds below `next`: its last temperature is just below it
            let hi = (next - 1e-6).min(m.calibrated_max_temperature);
            if lo > hi {
                continue; // the phase lies outside the declared range
            }
            for t in [lo, hi] {
                for (mech, d) in diffusivities(p, t) {
                    assert!(d <= D_IMPLAUSIBLE, "{} {} at {t} K: {mech} D = {d:e} m²/s > {D_IMPLAUSIBLE:e}", e.name, p.name);
                }
                checked += 1;
            }
            // Gjostein's correlation only within its high-temperature branch (T > 0.77 T_m)
            if e.phases[i].source.contains("Qs: [G73]") {
                assert!(lo >= 0.77 * e.melting_temperature, "{} {}: [G73] used from {lo} K < 0.77 T_m", e.name, p.name);
            }
        }
    }
    assert!(checked >= 2 * 12, "{checked}");
    // the fitted sets are declared only where they are possible: the seed paper's α-titanium
    // surface D_s passes the bound at 903 K and its β boundary D_gb at 1327 K
    let ti = library::entry("titanium-ivannikov2022").unwrap().diffusion();
    assert!(diffusivities(&ti.phases[0], 903.0)[0].1 > D_IMPLAUSIBLE && ti.calibrated_max_temperature < 903.0);
    assert!(diffusivities(&ti.phases[1], 1327.0)[1].1 > D_IMPLAUSIBLE);
}

/// The pair case of a 20 µm-radius pair of `material` held at `t` K for an hour.
fn pair_case(material: &str, t: f64, inline: &str) -> toml::Value {
    toml::from_str(&format!(
        "kind = \"pair\"\n[pair]\nmaterial = \"{material}\"\nradius = 20.0e-6\nend_time = 3600.0\n[temperature]\nconstant = {t}\n[output]\nplot = false\nseries_every = 1\n{inline}"
    ))
    .unwrap()
}

/// x/r after 1 h and the time to x/r = 0.1 (log-linear interpolation of the recorded series) [s],
/// and the run's warnings.
fn neck_figures(case: &toml::Value) -> (f64, f64, Vec<String>) {
    let spec = sinterdem::kinds::pair::parse_pair_case(case).unwrap();
    let run = sinterdem::kinds::pair::run_pair(&spec, true, false).unwrap();
    let r = spec.radius_a;
    let xr: Vec<f64> = run.states.iter().map(|y| y[0] / r).collect();
    let k = xr.iter().position(|&x| x >= 0.1).expect("x/r reaches 0.1 within the hour");
    assert!(k > 0, "x/r starts at {} ≥ 0.1", xr[0]);
    let (t0, t1) = (run.times[k - 1].max(1e-12), run.times[k]);
    let f = (0.1f64.ln() - xr[k - 1].ln()) / (xr[k].ln() - xr[k - 1].ln());
    let t_01 = (t0.ln() + f * (t1.ln() - t0.ln())).exp();
    (*xr.last().unwrap(), t_01, run.warnings)
}

/// The compiled [DFM93] data of one MATLPARS.DAT material written out as a one-phase inline
/// material named `name` (n = 1, δ_s = b, δ_gb = 2b with the library's b; only δ·D0 matters).
fn inline_compiled(name: &str, m: &str, b: f64, gamma_gb: f64, tm: f64) -> String {
    let mp = matlpars();
    let g = |k: &str| mp[&(m.to_string(), k.to_string())];
    format!(
        "[[materials]]\nname = \"{name}\"\nyoung_modulus = 2.0e11\npoisson_ratio = 0.3\ncalibrated_min_temperature = 300.0\ncalibrated_max_temperature = {tm}\n\
         [[materials.phases]]\nname = \"p\"\nfrom_temperature = 0.0\natomic_volume = {:e}\ngamma_surface = {:e}\ngamma_gb = {gamma_gb:e}\n\
         delta_surface = {b:e}\ndelta_gb = {:e}\nmobile_fraction_surface = 1.0\nmobile_fraction_gb = 1.0\n\
         d0_surface = {:e}\nq_surface = {:e}\nd0_gb = {:e}\nq_gb = {:e}\nd0_lattice = {:e}\nq_lattice = {:e}\n",
        g("Omega"),
        g("EnrgSr"),
        2.0 * b,
        g("SurD0") / b,
        g("SurErg") * 1e3,
        g("BdyD0") / (2.0 * b),
        g("BdyErg") * 1e3,
        g("VolD0"),
        g("VolErg") * 1e3,
    )
}

#[test]
fn iron_tungsten_and_copper_pairs_sinter_as_the_compiled_data_do() {
    // issue 37: α-iron at 1100 K, tungsten at 0.6 T_m, copper at 1193 K; the library preset
    // against the compiled data of the stored MATLPARS.DAT written out as an inline material
    let w_t = 0.6 * library::entry("tungsten").unwrap().melting_temperature;
    for (preset, m, t) in [("iron", "FE-ALPHA", 1100.0), ("tungsten", "TUNGSTEN", w_t), ("copper", "COPPER", 1193.0)] {
        let e = library::entry(preset).unwrap();
        let ph = &e.phases[e.diffusion().phase_at(t)].phase;
        let lib = neck_figures(&pair_case(preset, t, ""));
        let inline = inline_compiled("compiled", m, ph.delta_surface, ph.gamma_gb, 4000.0);
        let comp = neck_figures(&pair_case("compiled", t, &inline));
        let (dx, dt) = (common::rel(lib.0, comp.0), common::rel(lib.1, comp.1));
        assert!(dx <= 0.3 && dt <= 0.3, "{preset} at {t} K: x/r(1 h) {} vs {}, t(x/r = 0.1) {} vs {} s", lib.0, comp.0, lib.1, comp.1);
        assert!(lib.2.is_empty(), "{preset} at {t} K is inside its declared range: {:?}", lib.2);
    }
    // the seed paper's fitted copper is declared only where its boundary transport is within a
    // factor 5 of the compiled one: at 1193 K a run says it leaves the range
    let (_, _, warn) = neck_figures(&pair_case("copper-ivannikov2022", 1193.0, ""));
    assert!(warn.iter().any(|w| w.contains("leaves the calibrated range") && w.contains("copper-ivannikov2022")), "{warn:?}");
    // iron has no γ data (docs/materials.md "Iron above 1184 K"): a run at 1250 K falls back to
    // the α data and says that it leaves the declared range
    let (_, _, warn) = neck_figures(&pair_case("iron", 1250.0, ""));
    assert!(warn.iter().any(|w| w.contains("leaves the calibrated range") && w.contains("\"iron\"") && w.contains("1184.0 K")), "{warn:?}");
}

#[test]
fn every_e_of_t_table_follows_the_shear_modulus_law_of_the_stored_files() {
    // (L1): E(T) = E(T_e)·(1 − a·T/T_m)/(1 − a·T_e/T_m), a and T_m of the entry's first DFM290
    // material (MATLPARS.DAT 'T-dep', 'T-melt'); points written to 4 digits
    let mp = matlpars();
    let mut n = 0;
    for e in library::entries() {
        let Some(tab) = &e.young_modulus_table else {
            assert!(e.name.ends_with("-ivannikov2022"), "{}: a compiled entry without E(T)", e.name);
            continue;
        };
        let (_, _, pfile, m) = DFM_PHASES.iter().find(|d| d.0 == e.name).unwrap_or_else(|| panic!("{}: no DFM290 material", e.name));
        // MATLPARS.DAT's 'T-dep', 'T-melt', else the material file's (SS-304 has them only there)
        let p = p_file(pfile);
        let from = |k: &str, label: &str| mp.get(&(m.to_string(), k.to_string())).copied().unwrap_or_else(|| p[label]);
        let (a, tm) = (from("T-dep", "T-dependence of Modulus"), from("T-melt", "Melting Point"));
        let te = e.elastic_temperature.unwrap();
        assert_eq!(tab[0], [te, e.young_modulus], "{}: the table starts at E(T_e)", e.name);
        let d = e.diffusion();
        for &[t, v] in tab {
            let want = e.young_modulus * (1.0 - a * t / tm) / (1.0 - a * te / tm);
            assert!(close(v, want, 5e-4), "{} at {t} K: {v} vs (L1) {want}", e.name);
            // the 7-DOF material interpolates the table
            assert!(close(d.young_modulus_at(t), v, 1e-12), "{}", e.name);
        }
        assert!(tab.last().unwrap()[0] <= e.calibrated_max_temperature, "{}", e.name);
        // piecewise linear between the points, held beyond the ends
        let ([t0, e0], [t1, e1]) = (tab[0], tab[1]);
        assert!(close(d.young_modulus_at(0.5 * (t0 + t1)), 0.5 * (e0 + e1), 1e-12), "{}", e.name);
        assert_eq!(d.young_modulus_at(1.0), e0);
        assert_eq!(d.young_modulus_at(1e5), tab.last().unwrap()[1]);
        n += 1;
    }
    assert_eq!(n, 12);
}

/// The handbook values read for the library (validation/data/handbook/values.csv, PROVENANCE.md
/// there): (tag, material, quantity, value, temperature or None).
fn handbook() -> Vec<(String, String, String, f64, Option<f64>)> {
    let text = std::fs::read_to_string("validation/data/handbook/values.csv").unwrap();
    text.lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.splitn(7, ',').collect();
            let t = f[4].trim();
            (f[0].to_string(), f[1].to_string(), f[2].to_string(), f[3].parse().unwrap(), (!t.is_empty()).then(|| t.parse().unwrap()))
        })
        .collect()
}

#[test]
fn every_handbook_value_equals_the_library() {
    // each row of the stored transcription equals the library value it names (or the value the
    // library derives from it), and the entry's source texts carry the row's tag
    let rows = handbook();
    let mut molar: HashMap<String, (f64, f64)> = HashMap::new();
    for (tag, name, q, v, t) in &rows {
        let e = library::entry(name).unwrap_or_else(|| panic!("{name}: no library entry"));
        let texts = [&e.elastic_source, &e.melting_source, &e.preset.source, &e.range_source]
            .into_iter()
            .chain(e.tables.as_ref().map(|t| &t.source))
            .chain(e.phases.iter().map(|p| &p.source))
            .any(|s| s.contains(&format!("[{tag}]")));
        assert!(texts, "{name}: no source text cites [{tag}] for {q}");
        let ctx = format!("{tag} {name} {q} {v}");
        let ph = &e.phases[0].phase;
        let table_point = |tab: Option<&Vec<[f64; 2]>>| tab.is_some_and(|tab| tab.iter().any(|p| p[0] == t.unwrap() && p[1] == *v));
        match q.as_str() {
            "young_modulus" => assert_eq!(e.young_modulus, *v, "{ctx}"),
            "poisson_ratio" => assert_eq!(e.poisson_ratio, *v, "{ctx}"),
            "poisson_ratio_estimate" => assert!(e.poisson_ratio == *v && e.elastic_source.contains("[EST]"), "{ctx}"),
            // written to two digits
            "preset_poisson_ratio" => assert_eq!(e.preset_poisson_ratio(), (v * 100.0).round() / 100.0, "{ctx}"),
            // b = a/√2 (fcc) or a·√3/2 (bcc), written to 3–4 digits; δ_s = b, δ_gb = 2b
            "lattice_fcc" | "lattice_bcc" => {
                let b = if q == "lattice_fcc" { v / 2f64.sqrt() } else { v * 3f64.sqrt() / 2.0 };
                assert!(close(ph.delta_surface, b, 2e-3), "{ctx}: δ_s {} vs b {b}", ph.delta_surface);
                assert!(close(ph.delta_gb, 2.0 * ph.delta_surface, 1e-12), "{ctx}: δ_gb = 2b");
            }
            "density" => assert_eq!(e.preset.density, *v, "{ctx}"),
            "melting_k" => assert_eq!(e.melting_temperature, *v, "{ctx}"),
            "solidus_celsius" => assert!((e.melting_temperature - (v + 273.15)).abs() <= 0.5, "{ctx}: {}", e.melting_temperature),
            "conductivity" => match t {
                None => assert_eq!(e.preset.conductivity, *v, "{ctx}"),
                Some(t) => {
                    assert!(table_point(e.tables.as_ref().and_then(|x| x.conductivity_table.as_ref())), "{ctx}: κ({t}) not in the table");
                    assert!(e.preset.temperature != *t || e.preset.conductivity == *v, "{ctx}: preset");
                }
            },
            "heat_capacity" => {
                let in_table = table_point(e.tables.as_ref().and_then(|x| x.heat_capacity_table.as_ref()));
                assert!(in_table || (e.preset.temperature == t.unwrap() && e.preset.heat_capacity == *v), "{ctx}");
            }
            // α at 25 °C: the one point of the table (docs/materials.md "Thermal expansion")
            "alpha" => {
                let tab = e.tables.as_ref().and_then(|x| x.thermal_expansion_table.as_ref()).unwrap();
                assert_eq!(tab, &vec![[t.unwrap(), *v]], "{ctx}");
            }
            "molar_heat_capacity" => molar.entry(name.clone()).or_insert((0.0, 0.0)).0 = *v,
            "molar_mass" => molar.entry(name.clone()).or_insert((0.0, 0.0)).1 = *v,
            other => panic!("{ctx}: unknown quantity {other}"),
        }
    }
    // c = C_m / M, written to three digits (titanium: 523.5 J/(kg K) written 523)
    assert_eq!(molar.len(), 1);
    for (name, (cm, m)) in molar {
        let c = library::entry(&name).unwrap().preset.heat_capacity;
        assert!((c - cm / m).abs() < 1.0, "{name}: c {c} vs {}", cm / m);
    }
    assert!(rows.len() >= 40, "{}", rows.len());
}

#[test]
fn no_source_text_is_typed_from_memory() {
    // issue 37: no value is marked [UNV] or "from memory" any more; the tag is not in the
    // references either
    let refs = std::fs::read_to_string("docs/references.md").unwrap();
    assert!(!refs.contains("| [UNV] |"));
    for e in library::entries() {
        let mut texts = vec![&e.source, &e.elastic_source, &e.range_source, &e.melting_source, &e.preset.source, &e.unmeasured_note, &e.description];
        texts.extend(e.tables.as_ref().map(|t| &t.source));
        texts.extend(e.phases.iter().map(|p| &p.source));
        for s in texts {
            assert!(!s.contains("[UNV]") && !s.to_lowercase().contains("unverified"), "{}: {s}", e.name);
            // "typed from memory" may only describe what was removed
            assert!(!s.contains("from memory") || s.contains("removed"), "{}: {s}", e.name);
        }
    }
}

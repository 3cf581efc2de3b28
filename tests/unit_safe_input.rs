//! Unit-safe input (issue 25 items 2 and 3): values typical of the wrong unit are refused by
//! `check` with the key's own line, the value, the likely slip and the plausible range with its
//! unit; errors inside `[[materials]]` point at the key, not at the table header; a collapsed
//! contact integration names the diffusion data in physical terms; an end time before a heating
//! profile's peak (or before its end) warns with the temperature reached.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

/// A 316L-like pair (two 20 µm spheres at 1573 K) written with its own `[[materials.phases]]`;
/// a second material before it, so that the material at fault is not the first table.
const STEEL: &str = r#"kind = "pair"
title = "316L pair"

[pair]
material = "steel"
radius = 20.0e-6
neck_epsilon = 0.01
cone_eta = 0.1
end_time = 100.0

[temperature]
constant = 1573.0

[[materials]]
name = "other"
young_modulus = 100e9
poisson_ratio = 0.3
calibrated_min_temperature = 1000.0
calibrated_max_temperature = 1600.0

[[materials.phases]]
name = "fcc"
from_temperature = 0.0
atomic_volume = 1.2e-29
gamma_surface = 2.0
gamma_gb = 0.6
delta_surface = 0.25e-9
delta_gb = 0.5e-9
mobile_fraction_surface = 0.2
mobile_fraction_gb = 0.1
d0_surface = 4.0e-4
q_surface = 220e3
d0_gb = 2.0e-4
q_gb = 167e3
d0_lattice = 3.7e-5
q_lattice = 280e3

[[materials]]
name = "steel"
young_modulus = 193e9
poisson_ratio = 0.3
calibrated_min_temperature = 1200.0
calibrated_max_temperature = 1650.0

[[materials.phases]]
name = "fcc"
from_temperature = 0.0
atomic_volume = 1.21e-29
gamma_surface = 2.0
gamma_gb = 0.6
delta_surface = 0.25e-9
delta_gb = 0.5e-9
mobile_fraction_surface = 0.2
mobile_fraction_gb = 0.1
d0_surface = 4.0e-4
q_surface = 220e3
d0_gb = 2.0e-4
q_gb = 167e3
d0_lattice = 3.7e-5
q_lattice = 280e3
"#;

/// `STEEL` with the `n`-th (0-based) occurrence of `from` replaced by `to`, written to `dir`.
fn steel(dir: &Path, name: &str, from: &str, n: usize, to: &str) -> PathBuf {
    let mut text = STEEL.to_string();
    let at = text.match_indices(from).nth(n).unwrap_or_else(|| panic!("{from:?} #{n}")).0;
    text.replace_range(at..at + from.len(), to);
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn line_of(path: &Path, start: &str, n: usize) -> usize {
    std::fs::read_to_string(path).unwrap().lines().enumerate().filter(|(_, l)| l.starts_with(start)).nth(n).unwrap().0 + 1
}

fn sinterdem(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_sinterdem")).args(args).env_remove("CI").output().unwrap()
}

fn check_err(path: &Path, sets: &[&str]) -> String {
    let mut a = vec!["check", path.to_str().unwrap()];
    for s in sets {
        a.extend(["--set", s]);
    }
    let out = sinterdem(&a);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "{} {sets:?} was accepted", path.display());
    assert_eq!(out.status.code(), Some(1), "{err}");
    err
}

fn has(e: &str, want: &[&str]) {
    for w in want {
        assert!(e.contains(w), "expected {w:?} in:\n{e}");
    }
}

#[test]
fn unit_slips_are_refused_at_check_with_key_line_value_slip_and_range() {
    let d = common::tmp_dir("unit_slips");
    // the case as written passes
    let p = steel(&d, "ok.toml", "x", 0, "x");
    let out = sinterdem(&["check", p.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Q in kJ/mol, in the second material
    let p = steel(&d, "q.toml", "q_surface = 220e3", 1, "q_surface = 220");
    has(
        &check_err(&p, &[]),
        &[
            &format!(
                "q.toml:{}:1: materials.1.phases.0.q_surface: 220 J/mol (material \"steel\", phase \"fcc\") is implausibly small",
                line_of(&p, "q_surface", 1)
            ),
            "did you write kJ/mol? Q is in J/mol",
            "[1e4, 1e6] J/mol",
        ],
    );
    // Young's modulus in GPa, density in g/cm^3 (a heat case), from a file and from --set
    let p = steel(&d, "e.toml", "young_modulus = 193e9", 0, "young_modulus = 193");
    has(
        &check_err(&p, &[]),
        &[&format!("e.toml:{}:1: materials.1.young_modulus: 193 Pa", line_of(&p, "young_modulus", 1)), "did you write GPa", "[1e9, 1e12] Pa"],
    );
    has(
        &check_err(Path::new("cases/hot-plate.toml"), &["materials.0.density=7.99"]),
        &["materials.0.density: 7.99 kg/m^3", "did you write g/cm^3?", "7990", "(set by --set materials.0.density=7.99)"],
    );
    // a sintering temperature in °C, constant or inside a schedule
    has(
        &check_err(&p, &["materials.1.young_modulus=193e9", "temperature.constant=20"]),
        &["temperature.constant: 20 K is implausibly low", "did you write °C?"],
    );
    has(
        &check_err(Path::new("cases/furnace-compact.toml"), &["thermal.furnace.profile.schedule=\"start 20 K, heat 50 K/min to 1293 K\""]),
        &["thermal.furnace.profile.schedule: the profile reaches 20 K", "did you write °C?"],
    );
    // a heat case may be cryogenic: a warning, not a refusal
    let out = sinterdem(&["check", "cases/hot-plate.toml", "--set", "particles.initial_temperature=77"]);
    assert!(out.status.success());
    has(&String::from_utf8_lossy(&out.stderr), &["particles.initial_temperature: 77 K is implausibly low"]);
    // zero activation energy is a temperature-independent coefficient, not a slip
    let out = sinterdem(&["check", steel(&d, "z.toml", "x", 0, "x").to_str().unwrap(), "--set", "materials.1.phases.0.q_gb=0"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn errors_inside_materials_point_at_the_key_not_at_the_table_header() {
    let d = common::tmp_dir("material_lines");
    // a misspelt key in the second material's phase
    let p = steel(&d, "typo.toml", "q_gb = 167e3", 1, "q_gbb = 167e3");
    has(
        &check_err(&p, &[]),
        &[&format!("typo.toml:{}:1: materials.phases.q_gbb: unknown key; did you mean `materials.phases.q_gb`?", line_of(&p, "q_gbb", 0))],
    );
    // an out-of-range value, named by the material's and phase's names
    let p = steel(&d, "range.toml", "gamma_surface = 2.0", 1, "gamma_surface = 50.0");
    has(&check_err(&p, &[]), &[&format!("range.toml:{}:1: materials.steel.phases.fcc.gamma_surface = 50 is out of range", line_of(&p, "gamma_surface", 1))]);
    let p = steel(&d, "e.toml", "poisson_ratio = 0.3", 1, "poisson_ratio = 0.7");
    has(&check_err(&p, &[]), &[&format!("e.toml:{}:1: materials.steel.poisson_ratio = 0.7 is out of range", line_of(&p, "poisson_ratio", 1))]);
}

#[test]
fn a_collapsed_contact_integration_names_the_diffusion_data() {
    let d = common::tmp_dir("collapse");
    // surface diffusion 1e4 m^2/s * exp(-220 kJ/mol / (R 1573 K)) = 5e-4 m^2/s: far faster than any solid
    let p = steel(&d, "fast.toml", "d0_surface = 4.0e-4", 1, "d0_surface = 1.0e4");
    let out = sinterdem(&["-q", "run", p.to_str().unwrap(), "--out", d.join("o").to_str().unwrap()]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{e}");
    has(
        &e,
        &[
            "the contact's neck growth outran the integrator at t = ",
            "The suspect is surface diffusion of material \"steel\" (phase \"fcc\"): D = 4.950e-4 m²/s at 1573.0 K from d0_surface = 1e4 m²/s",
            "faster than diffusion in a liquid metal",
            "check the diffusion data of material \"steel\"",
        ],
    );
    assert!(!e.contains("y = ["), "a raw state vector: {e}");
}

#[test]
fn an_end_time_before_the_profile_peak_warns_with_the_temperature_reached() {
    let d = common::tmp_dir("schedule_end");
    // copper pair heated at 10 K/min from 1200 K to 1300 K (600 s), held 1 h: ends at 4200 s
    let sets = ["temperature={ schedule = \"start 1200 K, heat 10 K/min to 1300 K, hold 60 min\" }"];
    let run = |end: &str, out: &str| {
        let mut a = vec!["run", "cases/pair-copper.toml", "--out"];
        let o = d.join(out);
        a.push(o.to_str().unwrap());
        a.extend(["--set", sets[0], "--set", end, "--set", "output.plot=false"]);
        let out = sinterdem(&a);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        (String::from_utf8_lossy(&out.stderr).to_string(), std::fs::read_to_string(o.join("log.txt")).unwrap())
    };
    // 1.5 min at 10 K/min: 1215 K, below the 1300 K peak reached at 600 s
    let (console, log) = run("time.end=90", "before");
    let want = "warning: pair.end_time = 90 s ends before the heating profile temperature (which ends at 4200 s): the run stops at 1215.0 K, below the profile's peak 1300.0 K (reached at 600 s)";
    assert_eq!(log.matches(want).count(), 1, "{log}");
    assert_eq!(console.matches("ends before the heating profile").count(), 1, "{console}");
    // past the peak, in the hold: a warning too (issue 25: any explicit end before the schedule's)
    let (console, log) = run("time.end=1000", "after");
    assert_eq!(console.matches("ends before the heating profile").count(), 1, "{console}");
    assert!(
        log.contains(
            "warning: pair.end_time = 1000 s ends before the heating profile temperature (which ends at 4200 s): the run stops at 1300.0 K, after the profile's peak 1300.0 K, without the rest of its hold or cooling; set pair.end_time = 4200 or leave it out to run the whole schedule"
        ),
        "{log}"
    );
    // the whole schedule: nothing
    let (_, log) = run("time.end=4200", "whole");
    assert!(!log.contains("ends before"), "{log}");
}

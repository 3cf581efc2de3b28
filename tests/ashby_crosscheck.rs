//! Issue 37 item 7, the cross-check of the 7-DOF neck growth against the classical neck-growth
//! equations behind Ashby's sintering diagrams (Ashby 1974; Swinkels & Ashby 1981): the 7-DOF half.
//!
//! The classical side is **blocked**: neither paper, nor any open text restating their rate
//! equations, could be read (docs/validation-ashby.md "Status" lists what was searched). No
//! equation is written from memory, so no Ashby x/r is computed here.
//!
//! What this file does: the pair of every library preset (every entry of
//! `src/models/diffusion7/materials.toml`) at 0.6, 0.7 and 0.8 T_m, clipped to the preset's
//! declared range, and at radii 1 µm and 20 µm, integrated isothermally until x/r = 0.3 (or the
//! longest end time a pair case accepts, 1e9 s). The test asserts what the cross-check needs from
//! the 7-DOF side and what the "Done means" ask of the library inside its declared
//! ranges: every run starts, integrates without a ModelError and without a range warning (the
//! temperature is inside the range), conserves the solid volume, keeps the equal pair symmetric
//! and its free energy non-increasing (docs/diffusion7.md §8, (M10)), and its neck grows
//! monotonically through the window x/r = 0.05–0.3 of the comparison (reached in every case).
//!
//! `cargo test --release --features h5 --test ashby_crosscheck -- --ignored --nocapture` prints the
//! table of docs/validation-ashby.md (times to x/r = 0.05, 0.1, 0.2, 0.3 and the transport data
//! the classical equations would be fed with), which is the left half of the comparison.

use sinterdem::kinds::pair::{PairRun, PairSpec, parse_pair_case, run_pair};
use sinterdem::models::diffusion7::library;
use sinterdem::models::diffusion7::material::Material;
use sinterdem::units::{BOLTZMANN, arrhenius};

mod common;

/// The radii of the comparison [m].
const RADII: [f64; 2] = [1e-6, 20e-6];
/// The homologous temperatures of the comparison [1].
const FRACTIONS: [f64; 3] = [0.6, 0.7, 0.8];
/// The neck ratios at which the times are reported; the comparison window is 0.05–0.3.
const LEVELS: [f64; 4] = [0.05, 0.1, 0.2, 0.3];
/// The longest end time a pair case accepts (`pair.end_time`, src/models/diffusion7/ranges.rs) [s].
const MAX_END: f64 = 1e9;

/// One case: preset, homologous fraction asked, temperature used (clipped), radius.
#[derive(Debug, Clone)]
struct Case {
    name: String,
    fraction: f64,
    temperature: f64,
    clipped: bool,
    radius: f64,
}

/// Every case of the comparison, one per distinct (preset, temperature, radius).
fn cases() -> Vec<Case> {
    let mut out: Vec<Case> = Vec::new();
    for e in library::entries() {
        for &radius in &RADII {
            for &f in &FRACTIONS {
                let want = f * e.melting_temperature;
                let t = want.clamp(e.calibrated_min_temperature, e.calibrated_max_temperature);
                // a clipped temperature equal to one already listed adds no case
                if out.iter().any(|c| c.name == e.name && c.radius == radius && (c.temperature - t).abs() < 1e-9) {
                    continue;
                }
                out.push(Case { name: e.name.clone(), fraction: f, temperature: t, clipped: (t - want).abs() > 1e-9, radius });
            }
        }
    }
    out
}

fn case_toml(c: &Case, end: f64) -> toml::Value {
    let text = format!(
        "kind = \"pair\"\ntitle = \"ashby cross-check\"\n[pair]\nmaterial = \"{}\"\nradius = {:e}\nend_time = {:e}\n\
         [temperature]\nconstant = {}\n[output]\nseries_every = 1\nplot = false\n",
        c.name, c.radius, end, c.temperature
    );
    text.parse::<toml::Table>().map(toml::Value::Table).unwrap()
}

/// Runs the case until x/r ≥ 0.3 or the longest end time, growing the end time by factors of 10
/// from 1 ms. Returns the spec, the run and its end time.
fn run_case(c: &Case) -> (PairSpec, PairRun, f64) {
    let mut end = 1e-3;
    loop {
        let spec = parse_pair_case(&case_toml(c, end)).unwrap_or_else(|e| panic!("{c:?}: {e}"));
        let run = run_pair(&spec, true, false).unwrap_or_else(|e| panic!("{c:?}, end {end:e} s: {e}"));
        if run.contact.neck_ratio() >= LEVELS[3] || end >= MAX_END {
            return (spec, run, end);
        }
        end = (end * 10.0).min(MAX_END);
    }
}

/// The first time the neck ratio y1/R reaches `level`, linear in log t between recorded states.
fn time_at(run: &PairRun, r: f64, level: f64) -> Option<f64> {
    let x: Vec<f64> = run.states.iter().map(|y| y[0] / r).collect();
    let i = x.iter().position(|&v| v >= level)?;
    if i == 0 {
        return Some(run.times[0]);
    }
    let (t0, t1) = (run.times[i - 1], run.times[i]);
    let (x0, x1) = (x[i - 1], x[i]);
    if t0 <= 0.0 {
        return Some(t1);
    }
    let w = (level - x0) / (x1 - x0);
    Some((t0.ln() + w * (t1.ln() - t0.ln())).exp())
}

/// The transport data the classical equations take (per phase at T): δ_s·D_s, δ_gb·D_gb [m³/s],
/// D_v [m²/s], Ω [m³], γ_s [J/m²], and kT [J]. The 7-DOF model multiplies surface and GB
/// diffusivities by the mobile fractions n_s, n_gb (docs/diffusion7.md (M4)); both products are
/// given so the two readings can be compared.
fn transport(c: &Case) -> [f64; 8] {
    let m = Material::builtin(&c.name).unwrap();
    let p = &m.phases[m.phase_at(c.temperature)];
    let ds = arrhenius(p.d0_surface, p.q_surface, c.temperature);
    let dgb = arrhenius(p.d0_gb, p.q_gb, c.temperature);
    let dv = arrhenius(p.d0_lattice, p.q_lattice, c.temperature);
    [
        p.delta_surface * ds,
        p.delta_surface * ds * p.mobile_fraction_surface,
        p.delta_gb * dgb,
        p.delta_gb * dgb * p.mobile_fraction_gb,
        dv * p.mobile_fraction_lattice,
        p.atomic_volume,
        p.gamma_surface,
        BOLTZMANN * c.temperature,
    ]
}

/// Every preset at 0.6/0.7/0.8 T_m (clipped to its range) and 1 µm / 20 µm integrates cleanly
/// through the comparison window: no error, no warning, volume kept, symmetric, free energy
/// non-increasing, y1 monotone.
#[test]
fn every_preset_pair_runs_through_the_comparison_window() {
    let all = cases();
    // 14 presets × 2 radii × the distinct clipped temperatures (at least one per preset)
    assert!(all.len() >= 28, "{} cases", all.len());
    for c in &all {
        let (spec, run, end) = run_case(c);
        let w: Vec<&String> = run.warnings.iter().filter(|w| !w.contains("not measured")).collect();
        assert!(w.is_empty(), "{c:?}: warnings {w:?}");
        assert!(run.volume_drift() < 1e-4, "{c:?}: volume drift {:e}", run.volume_drift());
        // §8: equal particles stay symmetric; (M10): the free energy never rises (one phase)
        let params = spec.materials().params_at(c.temperature);
        let mut g_prev = f64::INFINITY;
        for y in &run.states {
            for i in 1..4 {
                assert!((y[i] - y[i + 3]).abs() <= 1e-12 * c.radius, "{c:?}: asymmetry in y{}", i + 1);
            }
            let (_, g) = sinterdem::models::diffusion7::invariants(y, &params).unwrap();
            assert!(g <= g_prev * (1.0 + 1e-14), "{c:?}: the free energy rose");
            g_prev = g;
        }
        for pair in run.states.windows(2) {
            assert!(pair[1][0] >= pair[0][0] * (1.0 - 1e-12), "{c:?}: the neck receded");
        }
        let x = run.contact.neck_ratio();
        assert!(x >= LEVELS[3] || end >= MAX_END, "{c:?}: stopped at x/r = {x} before 1e9 s");
    }
}

/// Prints the 7-DOF half of docs/validation-ashby.md.
#[test]
#[ignore = "prints the table of docs/validation-ashby.md; run with --ignored --nocapture"]
fn print_the_seven_dof_table() {
    println!(
        "| preset | T [K] | T/T_m | R [µm] | t(0.05) [s] | t(0.1) [s] | t(0.2) [s] | t(0.3) [s] | ΔL/L0 at 0.3 | δ_s·D_s [m³/s] | n_s·δ_s·D_s | δ_gb·D_gb [m³/s] | n_gb·δ_gb·D_gb | D_v [m²/s] | Ω [m³] | γ_s [J/m²] |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let fmt = |v: Option<f64>| v.map_or("> 1e9 s".to_string(), |t| format!("{t:.3e}"));
    for c in cases() {
        let (_, run, _) = run_case(&c);
        let ts: Vec<Option<f64>> = LEVELS.iter().map(|&l| time_at(&run, c.radius, l)).collect();
        let shr = ts[3].map(|t3| {
            let i = run.times.iter().position(|&t| t >= t3).unwrap();
            let y = run.states[i];
            let l0 = run.states[0][3] + run.states[0][6];
            (l0 - (y[3] + y[6])) / l0
        });
        let tr = transport(&c);
        let m = library::entry(&c.name).unwrap().melting_temperature;
        println!(
            "| {} | {:.1}{} | {:.3} | {} | {} | {} | {} | {} | {} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {} |",
            c.name,
            c.temperature,
            if c.clipped { format!(" (asked {:.1})", c.fraction * m) } else { String::new() },
            c.temperature / m,
            c.radius * 1e6,
            fmt(ts[0]),
            fmt(ts[1]),
            fmt(ts[2]),
            fmt(ts[3]),
            shr.map_or("–".into(), |s| format!("{s:.3e}")),
            tr[0],
            tr[1],
            tr[2],
            tr[3],
            tr[4],
            tr[5],
            tr[6],
        );
        let _ = tr[7];
    }
}

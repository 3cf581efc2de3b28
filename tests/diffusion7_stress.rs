//! Stress (issue 3): heating rates up to 1e4 K/min, radii 1 µm – 1 mm, unequal radii up to 10:1,
//! tolerances over 7 decades, mixed materials: every run finishes or stops with a clear ModelError,
//! never a NaN or a panic. Also the force (F4) and the correction (C1)–(C4) of docs/diffusion7.md §5–6.

use sinterdem::error::ModelError;
use sinterdem::kinds::pair::{PairRun, PairSpec, PairTemperature, ramp_profile, run_pair};
use sinterdem::models::diffusion7::material::{Material, PathFactors};
use sinterdem::models::diffusion7::{ContactParams, SolverOptions, correct_y4_y7, load_increment, rates, sintering_force};
use sinterdem::models::ode::Method;

fn spec(a: Material, b: Material, ra: f64, rb: f64, temp: PairTemperature, end: f64, rtol: f64) -> PairSpec {
    PairSpec {
        title: "stress".into(),
        material_a: a,
        material_b: b,
        radius_a: ra,
        radius_b: rb,
        overlap: 0.0,
        neck_epsilon: 0.01,
        cone_eta: 0.1,
        end_time: end,
        temperature: temp,
        factors: PathFactors::default(),
        solver: SolverOptions { rtol, ..SolverOptions::default() },
        series_every: 1,
        plot: false,
        normal_force: 0.0,
    }
}

/// Finished with finite, admissible, volume-conserving states, or a ModelError with a message.
#[track_caller]
fn outcome(label: &str, r: Result<PairRun, ModelError>, rtol: f64) -> bool {
    match r {
        Ok(run) => {
            for y in &run.states {
                assert!(y.iter().all(|v| v.is_finite() && *v > 0.0), "{label}: non-finite state {y:?}");
            }
            let c = &run.contact;
            assert!(c.neck_ratio().is_finite() && c.shrinkage().is_finite(), "{label}");
            assert!(run.volume_drift() < 50.0 * rtol, "{label}: volume drift {}", run.volume_drift());
            true
        }
        Err(e) => {
            let m = e.to_string();
            eprintln!("{label}: {m}");
            assert!(m.starts_with("model error") && m.len() > 20, "{label}: {m}");
            false
        }
    }
}

#[test]
fn heating_rates_up_to_1e4_k_per_min() {
    let ti = Material::titanium();
    let cu = Material::copper();
    for kmin in [20.0, 1e3, 1e4] {
        let r = kmin / 60.0;
        let p = ramp_profile(313.0, 1573.0, r, 600.0, Some(r), 313.0).unwrap();
        let end = p.duration();
        let s = spec(ti.clone(), ti.clone(), 33e-6, 33e-6, PairTemperature::Profile(p), end, 1e-6);
        assert!(outcome(&format!("Ti {kmin} K/min"), run_pair(&s, true, false), 1e-6), "titanium at {kmin} K/min must finish");
        let p = ramp_profile(300.0, 1293.0, r, 1000.0, Some(r), 300.0).unwrap();
        let end = p.duration();
        let s = spec(cu.clone(), cu.clone(), 25e-6, 25e-6, PairTemperature::Profile(p), end, 1e-6);
        assert!(outcome(&format!("Cu {kmin} K/min"), run_pair(&s, true, false), 1e-6), "copper at {kmin} K/min must finish");
    }
}

#[test]
fn radii_from_1_um_to_1_mm() {
    let cu = Material::copper();
    for r in [1e-6, 3e-6, 1e-5, 1e-4, 1e-3] {
        let s = spec(cu.clone(), cu.clone(), r, r, PairTemperature::Constant(1293.0), 5000.0, 1e-6);
        let done = outcome(&format!("R = {r}"), run_pair(&s, true, false), 1e-6);
        if r >= 1e-5 {
            assert!(done, "R = {r} must finish");
        }
    }
}

#[test]
fn unequal_radii_mixed_materials_and_seven_decades_of_tolerance() {
    let cu = Material::copper();
    let ti = Material::titanium();
    for ratio in [1.0, 2.0, 5.0, 10.0] {
        for rtol in [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10] {
            for m in [Method::Dopri5, Method::Rk4Doubling] {
                let mut s = spec(cu.clone(), cu.clone(), 25e-6, 25e-6 / ratio, PairTemperature::Constant(1293.0), 5000.0, rtol);
                s.solver.method = m;
                let done = outcome(&format!("{ratio}:1 rtol {rtol} {m:?}"), run_pair(&s, false, false), rtol);
                assert!(done || ratio >= 10.0, "{ratio}:1 at rtol {rtol} must finish");
                if !done {
                    // 10:1 at 1293 K: the 2.5 µm particle is absorbed by the neck within 5000 s;
                    // the run must stop with that diagnosis, and run cleanly up to 100 s
                    let e = run_pair(&s, false, false).unwrap_err().to_string();
                    assert!(e.contains("absorbed"), "{e}");
                    s.end_time = 100.0;
                    assert!(outcome("10:1 to 100 s", run_pair(&s, false, false), rtol), "10:1 to 100 s at rtol {rtol}");
                }
            }
        }
    }
    // copper against titanium (β at 1300 K), 3:1, with 2 % overlap
    let mut s = spec(cu.clone(), ti.clone(), 30e-6, 10e-6, PairTemperature::Constant(1300.0), 3000.0, 1e-6);
    s.overlap = 0.02;
    assert!(outcome("Cu-Ti", run_pair(&s, true, false), 1e-6));
}

/// The unequal 25/15 µm copper pair at 1293 K: the model's own split of the approach, w4 = 0.50 at
/// creation and 0.43 accumulated over 1000 s (docs/diffusion7.md §6), i.e. the larger particle takes the smaller
/// share; the isolated-pair correction (ξ = Δy4 + Δy7) leaves y4, y7 unchanged (§8).
#[test]
fn correction_split_and_isolated_pair() {
    let cu = Material::copper();
    let s = spec(cu.clone(), cu.clone(), 25e-6, 15e-6, PairTemperature::Constant(1293.0), 1000.0, 1e-8);
    let c0 = s.new_contact().unwrap();
    let p = ContactParams::single(&cu, 0, PathFactors::default());
    let r = rates(&c0.y, &p, 1293.0).unwrap();
    let w0 = r[3] / (r[3] + r[6]);
    assert!((w0 - 0.50).abs() < 0.01, "w4 at creation {w0}");
    let run = run_pair(&s, false, false).unwrap();
    let (dy4, dy7) = (c0.y[3] - run.contact.y[3], c0.y[6] - run.contact.y[6]);
    let w = dy4 / (dy4 + dy7);
    assert!((w - 0.43).abs() < 0.01, "accumulated w4 {w}");
    let corr = correct_y4_y7((c0.y[3], c0.y[6]), (run.contact.y[3], run.contact.y[6]), (0.0, 0.0), dy4 + dy7, 40e-6);
    assert!((corr.y4 - run.contact.y[3]).abs() < 1e-18 && (corr.y7 - run.contact.y[6]).abs() < 1e-18 && corr.dl_bar.abs() < 1e-18);
    assert!((corr.w4 - w).abs() < 1e-12);
    // (C3) fallback: no approach predicted, split by the current rates; clamp with opposite signs
    let f = correct_y4_y7((1.0, 1.0), (1.0, 1.0), (-3.0, -1.0), 0.4, 2.0);
    assert!((f.w4 - 0.75).abs() < 1e-15 && (f.y4 - 0.7).abs() < 1e-15 && (f.y7 - 0.9).abs() < 1e-15);
    let f = correct_y4_y7((1.0, 1.0), (1.0, 1.0), (-1.0, 1.0), 0.4, 2.0);
    assert_eq!((f.w4, f.w7), (1.0, 0.0));
    let f = correct_y4_y7((1.0, 1.0), (1.0, 1.0), (0.0, 0.0), 0.4, 2.0);
    assert_eq!(f.w4, 0.5);
    // (F4) = accumulated (F5) for an isolated pair; copper 50 µm at 5000 s gives 4.25 N (§11)
    let e = 72e9;
    assert!((sintering_force(2.0, 0.9, 0.95, 1e-5, e) - load_increment(0.1, 0.05, 1e-5, e)).abs() < 1e-9);
    let s = spec(cu.clone(), cu, 25e-6, 25e-6, PairTemperature::Constant(1293.0), 5000.0, 1e-8);
    let run = run_pair(&s, false, false).unwrap();
    let c = run.contact;
    let fn_ = sintering_force(c.l0, c.y[3], c.y[6], c.r_mean(), e);
    assert!((fn_ - 4.25).abs() < 0.01, "F_n = {fn_} N");
}

//! Error-controlled heat steps (docs/heat-model.md eqs. E1–E3) on the hot plate switched on at
//! t = 0 (the `sinterdem bench heat-step` case, smaller): the error against a tight reference falls
//! with the tolerance as the per-step control predicts (global ≈ Σ local ∝ tol^{2/3} for BDF2),
//! the adaptive run needs several times fewer steps than a fixed Δt of the same error, and it
//! lands exactly on the output times and the end.

use sinterdem::bench::heat::{max_error, run_step_case, step_bench_case};

mod common;

#[test]
fn adaptive_error_follows_the_tolerance_and_beats_fixed_steps() {
    let end = 0.05;
    let base = step_bench_case([3, 3, 6], end).unwrap();
    let out = common::tmp_dir("wp");
    let (_, reference, _) = run_step_case(&base, &["time.heat_tolerance=1e-7".into(), "time.dt=1e-7".into()], &out).unwrap();
    assert_eq!(reference.len(), sinterdem::bench::heat::STEP_BENCH_OUTPUTS);
    let mut adaptive = Vec::new();
    for tol in [1e-1, 1e-2, 1e-3, 1e-4] {
        let (s, temps, _) = run_step_case(&base, &[format!("time.heat_tolerance={tol:e}"), "time.dt=1e-7".into()], &out).unwrap();
        let (err, common) = max_error(&temps, &reference);
        assert_eq!(common, reference.len(), "the run lands on every output time");
        assert_eq!(s["final_time_s"].as_f64().unwrap(), end);
        assert_eq!(s["time_step_control"], "error");
        let steps = s["steps_accepted"].as_u64().unwrap() as usize;
        assert!(s["steps_above_tolerance_at_dt_min"].as_u64().unwrap() == 0);
        assert!(s["max_local_error_estimate_K"].as_f64().unwrap() <= tol);
        adaptive.push((tol, err, steps));
    }
    // error ≤ C tol^{2/3} over three decades (per-step control: N ∝ tol^{-1/3} steps, each adding
    // at most tol), with C = 6 K^{1/3} (measured 2.1–3.9), and the error falls monotonically
    for &(tol, err, _) in &adaptive {
        assert!(err <= 6.0 * tol.powf(2.0 / 3.0), "tol {tol:e}: error {err:e} ({adaptive:?})");
    }
    for w in adaptive.windows(2) {
        assert!(w[1].1 < 0.5 * w[0].1, "{adaptive:?}");
    }
    let slope = (adaptive[0].1 / adaptive[3].1).log10() / 3.0;
    assert!((0.5..=0.9).contains(&slope), "error ∝ tol^{slope} ({adaptive:?})");
    // fixed Δt (dividing the output interval): the cheapest one reaching each adaptive error
    let mut fixed = Vec::new();
    for k in 0..8 {
        let dt = end / 50.0 / f64::powi(2.0, k);
        let (s, temps, _) = run_step_case(&base, &[format!("time.dt={dt:e}")], &out).unwrap();
        fixed.push((s["steps"].as_u64().unwrap() as usize, max_error(&temps, &reference).0));
    }
    for &(tol, err, steps) in &adaptive[1..] {
        let need = fixed.iter().find(|f| f.1 <= err).map(|f| f.0).unwrap_or(usize::MAX);
        assert!(2 * steps <= need, "tol {tol:e}: adaptive {steps} steps for {err:e} K, fixed needs {need} ({fixed:?})");
    }
    let _ = std::fs::remove_dir_all(&out);
}

/// Step-control keys: dt_max bounds every step (series dt_s), dt_min/dt_max are refused without
/// time.heat_tolerance, and the tolerance's range is checked.
#[test]
fn step_control_bounds_and_keys() {
    let base = step_bench_case([2, 2, 3], 0.02).unwrap();
    let out = common::tmp_dir("keys");
    let (s, _, _) = run_step_case(&base, &["time.heat_tolerance=1e-2".into(), "time.dt_max=1e-3".into(), "output.series_every=1".into()], &out).unwrap();
    let text = std::fs::read_to_string(out.join("series.csv")).unwrap();
    let dts: Vec<f64> = text.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect();
    assert_eq!(dts.len(), s["steps_accepted"].as_u64().unwrap() as usize);
    assert!(dts.iter().all(|&d| d <= 1e-3 * (1.0 + 1e-12)), "{dts:?}");
    let tsum: f64 = dts.iter().sum();
    assert!((tsum - 0.02).abs() < 1e-12);
    for (sets, needle) in [
        (vec!["time.dt_max=1e-3"], "time.dt_max"),
        (vec!["time.heat_tolerance=-1"], "time.heat_tolerance"),
        (vec!["time.heat_tolerance=1e-2", "time.dt_min=1.0", "time.dt_max=1e-3"], "time.dt_min"),
    ] {
        let mut v = base.clone();
        for s in sets {
            sinterdem::config::apply_override(&mut v, s).unwrap();
        }
        let e = sinterdem::scene::prepare(v, std::path::Path::new(".")).err().expect(needle).to_string();
        assert!(e.contains(needle), "{e}");
    }
    let _ = std::fs::remove_dir_all(&out);
}

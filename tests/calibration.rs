//! `sinterdem calibrate` (docs/calibration.md): recovery of known β-phase diffusion data from
//! synthetic titanium pair data, σ and χ² on noisy data, rejection of bad input, determinism.
//! Run times are kept to seconds: subsets of the 28 experiments, small swarms.

use sinterdem::calibrate::synthetic::{BUNDLED_SEED, TRUTH, generate, titanium_csv, titanium_experiments, truth_material};
use sinterdem::calibrate::{parse, run, synthetic::csv_text};
use sinterdem::config::load_case;
use sinterdem::models::diffusion7::PathFactors;
use std::path::{Path, PathBuf};

mod common;

/// The four β parameters with the ranges of the bundled example.
const PARAMS: &str = r#"
[[parameters]]
key = "beta.d0_gb"
min = 1.0
max = 1.0e4

[[parameters]]
key = "beta.q_gb"
min = 190.0e3
max = 260.0e3

[[parameters]]
key = "beta.d0_surface"
min = 1.0e-4
max = 10.0

[[parameters]]
key = "beta.q_surface"
min = 170.0e3
max = 240.0e3
"#;

/// Writes `data.csv` (synthetic, noise-free or seeded) for `ids` and `calib.toml` with `extra` keys.
fn setup(dir: &Path, ids: &[&str], noise: Option<u64>, extra: &str) -> PathBuf {
    let mut ex = titanium_experiments(Some(ids));
    generate(&mut ex, &truth_material(), PathFactors::default(), None, noise).unwrap();
    std::fs::write(dir.join("data.csv"), csv_text(&ex, "test data")).unwrap();
    let calib = dir.join("calib.toml");
    std::fs::write(&calib, format!("data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\n{extra}\n{PARAMS}")).unwrap();
    calib
}

fn calibrate(calib: &Path, sets: &[String], out: &Path) -> sinterdem::calibrate::report::CalibrationReport {
    let v = load_case(calib, sets).unwrap();
    let s = parse(&v, calib.parent().unwrap()).unwrap();
    run(s, out, &mut |m| eprintln!("{m}")).unwrap()
}

fn param(rep: &sinterdem::calibrate::report::CalibrationReport, key: &str, field: &str) -> f64 {
    rep.parameters[key][field].as_f64().unwrap_or(f64::NAN)
}

/// Noise-free data of 8 experiments (all three peak temperatures, both rates, short and long holds),
/// generated and fitted at rtol 1e-9: the four β parameters come back to 1e-4 relative.
#[test]
fn noise_free_data_recover_the_four_beta_parameters() {
    let dir = common::tmp_dir("noise-free");
    let ids = ["E3B", "E5B", "E8B", "E11B", "E14B", "E18B", "E21B", "E23B", "E28B"];
    let calib = setup(
        &dir,
        &ids,
        None,
        "seed = 3\n[optimiser]\nswarm_size = 8\nswarm_iterations = 6\nlocal_iterations = 80\ntolerance = 1e-12\n[solver]\nrtol = 1e-9\n",
    );
    let rep = calibrate(&calib, &[], &dir.join("out"));
    for (k, t) in TRUTH {
        let v = param(&rep, k, "value");
        eprintln!("{k}: fitted {v:e}, truth {t:e}, relative error {:.2e}", (v - t).abs() / t);
        assert!((v - t).abs() <= 1e-4 * t, "{k}: fitted {v:e}, truth {t:e}");
    }
    assert!(rep.chi2 < 1e-6, "chi2 {}", rep.chi2);
    for f in ["calibration.json", "material.toml", "residuals.csv", "neck_ratio.png", "shrinkage.png", "residuals.png"] {
        assert!(dir.join("out").join(f).exists(), "{f}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The bundled noisy file (28 experiments, rtol 1e-6, a small swarm): every parameter within 2σ
/// of the truth (θ = log10 for the prefactors) and χ²/ν near 1; the calibrated material.toml is
/// accepted by a pair case; the D0–Q correlations are flagged.
#[test]
fn noisy_data_fit_within_two_sigma_with_reduced_chi2_near_one() {
    let dir = common::tmp_dir("noisy");
    let calib = Path::new("cases/calibration/titanium-synthetic.toml");
    let sets = ["optimiser.swarm_size=8", "optimiser.swarm_iterations=4"].map(String::from);
    let rep = calibrate(calib, &sets, &dir);
    eprintln!("chi2 = {}, dof = {}, chi2/dof = {}, evaluations {}", rep.chi2, rep.dof, rep.reduced_chi2, rep.evaluations);
    assert_eq!(rep.dof, 56 - 4);
    assert!(rep.reduced_chi2 > 0.6 && rep.reduced_chi2 < 1.5, "chi2/dof = {}", rep.reduced_chi2);
    for (k, t) in TRUTH {
        let (v, log) = (param(&rep, k, "value"), rep.parameters[k]["log"].as_bool().unwrap());
        let (d, s) = if log { (v.log10() - t.log10(), param(&rep, k, "sigma_log10")) } else { (v - t, param(&rep, k, "sigma")) };
        eprintln!("{k}: fitted {v:e}, truth {t:e}, deviation {:.3} sigma", d / s);
        assert!(d.abs() <= 2.0 * s, "{k}: fitted {v:e}, truth {t:e}, sigma {s:e}");
    }
    // grain-boundary data are well determined, surface data of the β phase are not (docs/calibration.md)
    assert!(param(&rep, "beta.d0_gb", "sigma_log10") < 0.3);
    assert!(param(&rep, "beta.q_gb", "sigma") < 1.0e4);
    assert!(rep.warnings.iter().any(|w| w.contains("beta.d0_gb and beta.q_gb correlate")), "{:?}", rep.warnings);
    let mat = std::fs::read_to_string(dir.join("material.toml")).unwrap();
    let case = format!(
        "kind = \"pair\"\n[pair]\nmaterial = \"titanium-ivannikov2022\"\nradius = 3.3e-5\nend_time = 100.0\n[temperature]\nconstant = 1373.0\n[output]\nplot = false\n{mat}"
    );
    let spec = sinterdem::kinds::pair::parse_pair_case(&toml::Value::Table(case.parse().unwrap())).unwrap();
    assert_eq!(spec.material_a.phases[1].d0_gb, param(&rep, "beta.d0_gb", "value"));
    let csv = std::fs::read_to_string(dir.join("residuals.csv")).unwrap();
    assert!(csv.starts_with("id,time_s,end,quantity,measured,sigma,fitted,residual\n") && csv.lines().count() == 57);
    std::fs::remove_dir_all(&dir).ok();
}

/// Same seed, 1 and 2 threads: bit-identical parameters, χ² and residuals.
#[test]
fn result_is_deterministic_for_any_thread_count() {
    let dir = common::tmp_dir("determinism");
    let calib = setup(&dir, &["E2B", "E14B", "E23B"], Some(5), "seed = 11\n[optimiser]\nswarm_size = 6\nswarm_iterations = 3\nlocal_iterations = 4\n");
    let mut out = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let o = dir.join(format!("out{threads}"));
        let rep = pool.install(|| calibrate(&calib, &[], &o));
        assert_eq!(rep.threads, threads);
        out.push((serde_json::to_string(&rep.parameters).unwrap(), rep.chi2.to_bits(), rep.evaluations, std::fs::read(o.join("residuals.csv")).unwrap()));
    }
    assert_eq!(out[0], out[1]);
    std::fs::remove_dir_all(&dir).ok();
}

fn parse_err(dir: &Path, calib_text: &str, data: Option<&str>) -> String {
    if let Some(d) = data {
        std::fs::write(dir.join("data.csv"), d).unwrap();
    }
    let p = dir.join("calib.toml");
    std::fs::write(&p, calib_text).unwrap();
    let v = load_case(&p, &[]).unwrap();
    parse(&v, dir).unwrap_err().to_string()
}

/// Bad rows name file, line and column; unknown keys list the valid ones; model = "compact"
/// without a packing, an unknown model and bad ranges are refused with key, value, range and unit.
#[test]
fn bad_input_is_rejected_with_file_line_column_and_key() {
    let dir = common::tmp_dir("bad");
    let head = "id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n";
    let row = "E1B,6.75e-5,\"start 793 K, heat 20 K/min to 1203 K, hold 0 min, cool 20 K/min to 313 K\",0.48,0.01,1e-4,3e-4\n";
    let ok = format!("data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\n{PARAMS}");
    let e = parse_err(&dir, &ok, Some(&format!("# c\n{head}{row}E2B,6.6e-5,\"start 793 K, heat 20 K/min to 1203 K\",0.5,0.01,-2,3e-4\n")));
    assert!(e.contains("data.csv line 4, column 6 (shrinkage) = -2 is out of range") && e.contains("[-1, 1]"), "{e}");
    let e = parse_err(&dir, &ok, Some(&format!("{head}{row}E2B,6.6e-5,\"start 793 K, hold 5 fortnights\",0.5,0.01,,\n")));
    assert!(e.contains("data.csv line 3, column 3 (schedule)") && e.contains("fortnights"), "{e}");
    std::fs::write(dir.join("data.csv"), format!("{head}{row}")).unwrap();
    let e = parse_err(&dir, &ok.replace("beta.q_surface", "beta.q_surf"), None);
    assert!(
        e.contains("parameters[3].key = \"beta.q_surf\"")
            && e.contains("valid keys: alpha.atomic_volume")
            && e.contains("beta.q_surface")
            && e.contains("model.path_factor_gb"),
        "{e}"
    );
    let e = parse_err(&dir, &format!("model = \"compact\"\n{ok}"), None);
    assert!(e.contains("model = \"compact\" needs [compact] case"), "{e}");
    let e = parse_err(&dir, &format!("model = \"packing\"\n{ok}"), None);
    assert!(e.contains("model = \"packing\": expected \"pair\" or \"compact\""), "{e}");
    let e = parse_err(&dir, &format!("{ok}\n[optimiser]\nswarm_size = 0\n"), None);
    assert!(e.contains("optimiser.swarm_size = 0 is out of range"), "{e}");
    let e = parse_err(&dir, &ok.replace("min = 1.0e-4", "min = -1.0"), None);
    assert!(e.contains("parameters[2].min (beta.d0_surface) = -1") && e.contains("m^2/s"), "{e}");
    let e = parse_err(&dir, &format!("{ok}\nswarm = 3\n"), None);
    assert!(e.contains("swarm: unknown key"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `cases/calibration/titanium-synthetic.csv` is what the generator writes (SINTERDEM_WRITE_CASES=1
/// rewrites it).
#[test]
fn bundled_synthetic_data_match_the_generator() {
    let path = "cases/calibration/titanium-synthetic.csv";
    let text = titanium_csv(BUNDLED_SEED).unwrap();
    if std::env::var("SINTERDEM_WRITE_CASES").is_ok() {
        std::fs::write(path, &text).unwrap();
    }
    assert_eq!(std::fs::read_to_string(path).unwrap(), text, "{path} differs from the generator");
}

/// A time-series file (exact model values at three times of two experiments, no end values): the
/// local phase alone recovers D0_gb and Q_gb, the series appear in residuals.csv and series_<id>.png.
#[test]
fn time_series_points_are_fitted() {
    use sinterdem::calibrate::data::{Observation, SeriesPoint};
    use sinterdem::calibrate::forward::{PairGeometry, run_experiment};
    use sinterdem::models::diffusion7::SolverOptions;
    let dir = common::tmp_dir("series");
    let mut ex = titanium_experiments(Some(&["E14B", "E23B"]));
    let solver = SolverOptions { rtol: 1e-9, ..SolverOptions::default() };
    // the truth's grain-boundary data, bundled surface data (those are not fitted here)
    let mut truth = truth_material();
    let bundled = sinterdem::models::diffusion7::Material::titanium();
    truth.phases[1].d0_surface = bundled.phases[1].d0_surface;
    truth.phases[1].q_surface = bundled.phases[1].q_surface;
    let head = "id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n";
    let mut data = head.to_string();
    let mut series = "id,time_s,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n".to_string();
    for e in ex.iter_mut() {
        let d = e.profile.duration();
        e.series = [0.3, 0.6, 0.9].iter().map(|f| SeriesPoint { time: (f * d).round(), observation: Observation::default() }).collect();
        let p = run_experiment(e, &truth, PathFactors::default(), &solver, &PairGeometry::default()).unwrap();
        data.push_str(&format!("{},{:e},\"{}\",,,,\n", e.id, e.diameter, e.schedule));
        for (s, q) in e.series.iter().zip(&p.series) {
            series.push_str(&format!("{},{},{:e},0.01,{:e},0.001\n", e.id, s.time, q.neck_ratio, q.shrinkage));
        }
    }
    std::fs::write(dir.join("data.csv"), data).unwrap();
    std::fs::write(dir.join("series.csv"), series).unwrap();
    let calib = dir.join("calib.toml");
    std::fs::write(
        &calib,
        "data = \"data.csv\"\nseries = \"series.csv\"\nmaterial = \"titanium-ivannikov2022\"\n[optimiser]\nswarm_iterations = 0\ntolerance = 1e-12\n[solver]\nrtol = 1e-9\n\
         [[parameters]]\nkey = \"beta.d0_gb\"\nmin = 1.0\nmax = 1.0e4\n[[parameters]]\nkey = \"beta.q_gb\"\nmin = 190.0e3\nmax = 260.0e3\n",
    )
    .unwrap();
    let rep = calibrate(&calib, &[], &dir.join("out"));
    assert_eq!(rep.values, 12);
    for (k, t) in &TRUTH[..2] {
        let v = param(&rep, k, "value");
        eprintln!("{k}: fitted {v:e}, truth {t:e}");
        assert!((v - t).abs() <= 1e-6 * t, "{k}: fitted {v:e}, truth {t:e}");
    }
    assert!(rep.experiments.iter().all(|e| e.series_points == 3 && e.neck_ratio.is_none()));
    let csv = std::fs::read_to_string(dir.join("out/residuals.csv")).unwrap();
    assert_eq!(csv.lines().filter(|l| l.contains(",0,")).count(), 12, "{csv}");
    assert!(dir.join("out/series_E14B.png").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// Runs that fail (here: too few substeps allowed) are a penalty, not a crash: the optimiser
/// goes through all its evaluations; and since here every run fails, even at the optimum, the
/// calibration ends with a ModelError naming the experiment and the cause instead of a "fit" of
/// penalties (issue 26 class 6: before, it exited 0 with chi2 = 2e6).
#[test]
fn failed_runs_are_a_penalty_not_a_crash() {
    let dir = common::tmp_dir("failed");
    let calib = setup(&dir, &["E1B"], None, "[optimiser]\nswarm_size = 2\nswarm_iterations = 1\nlocal_iterations = 1\n[solver]\nmax_substeps = 5\n");
    let v = load_case(&calib, &[]).unwrap();
    let s = parse(&v, calib.parent().unwrap()).unwrap();
    let mut log = Vec::new();
    let err = run(s, &dir.join("out"), &mut |m| log.push(m.to_string())).unwrap_err();
    assert!(matches!(err, sinterdem::error::Error::Model(_)), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("every run of the calibration fails") && msg.contains("E1B") && msg.contains("substeps"), "{msg}");
    // the penalty carried the optimiser through both phases
    assert!(log.iter().any(|l| l.starts_with("global phase")) && log.iter().any(|l| l.starts_with("local phase")), "{log:?}");
    assert!(log.iter().any(|l| l.contains("chi2 = 2.000000e6")), "{log:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The bundled calibration's `[compact]` validation case names its material "titanium" with
/// `preset = "titanium-ivannikov2022"`, the calibration's material: `check` finds it by the preset
/// (it failed with "has no material named" after the presets were renamed, issue 38 note).
#[test]
fn the_bundled_calibration_finds_its_compact_material_by_preset() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let o =
        std::process::Command::new(env!("CARGO_BIN_EXE_sinterdem")).arg("check").arg(root.join("cases/calibration/titanium-synthetic.toml")).output().unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{text}");
    assert!(text.contains("[compact]") && text.contains("3619 particles"), "{text}");
}

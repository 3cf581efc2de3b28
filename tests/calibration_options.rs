//! Calibration options and validation (docs/calibration.md): the Nelder–Mead local phase
//! recovers noise-free β grain-boundary data, and `sinterdem check CALIB.toml` validates a
//! calibration file without fitting: data files, parameter keys and bounds, material, optimiser,
//! and the packing of `[compact]`.

use sinterdem::calibrate::synthetic::{TRUTH, csv_text, generate, titanium_experiments, truth_material};
use sinterdem::calibrate::{parse, run};
use sinterdem::config::load_case;
use sinterdem::models::diffusion7::{Material, PathFactors};
use std::path::Path;

mod common;

/// Noise-free pair data at three peak temperatures (1203, 1373, 1573 K) from the truth's
/// grain-boundary data (bundled surface data), fitted from the bundled material with Nelder–Mead
/// alone. The simplex stops when the standard deviation of χ² over its vertices is below 1e-14;
/// near the minimum χ² ≈ |J δθ|², so the vertices are then within |J δθ| ≲ 1e-7 of the truth in
/// σ units, which for these data is a few 1e-7 relative in D0 (its log10 column is the smaller
/// one) and less in Q. Measured: see the eprintln; asserted with a factor ~10 of margin.
#[test]
fn nelder_mead_recovers_the_noise_free_truth() {
    let dir = common::tmp_dir("nm");
    let mut ex = titanium_experiments(Some(&["E5B", "E14B", "E23B"]));
    let mut truth = truth_material();
    let bundled = Material::titanium();
    truth.phases[1].d0_surface = bundled.phases[1].d0_surface;
    truth.phases[1].q_surface = bundled.phases[1].q_surface;
    generate(&mut ex, &truth, PathFactors::default(), None, None).unwrap();
    std::fs::write(dir.join("data.csv"), csv_text(&ex, "noise-free")).unwrap();
    let calib = dir.join("calib.toml");
    std::fs::write(
        &calib,
        "data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\n\
         [[parameters]]\nkey = \"beta.d0_gb\"\nmin = 1.0\nmax = 1.0e4\n[[parameters]]\nkey = \"beta.q_gb\"\nmin = 190.0e3\nmax = 260.0e3\n\
         [optimiser]\nswarm_iterations = 0\nlocal = \"nelder_mead\"\nlocal_iterations = 1000\nsimplex_scale = 0.05\nsimplex_tolerance = 1.0e-14\n\
         [solver]\nrtol = 1.0e-9\n",
    )
    .unwrap();
    let s = parse(&load_case(&calib, &[]).unwrap(), &dir).unwrap();
    let rep = run(s, &dir.join("out"), &mut |m| eprintln!("{m}")).unwrap();
    assert_eq!(rep.local_method, "nelder_mead");
    assert!(rep.local_iterations < 1000, "stopped by its iteration limit, not by its tolerance: {}", rep.local_stop);
    let mut errs = Vec::new();
    for (k, t) in &TRUTH[..2] {
        let v = rep.parameters[*k]["value"].as_f64().unwrap();
        let rel = (v - t).abs() / t;
        eprintln!("{k}: fitted {v:e}, truth {t:e}, relative error {rel:.2e}");
        errs.push(rel);
    }
    eprintln!("chi2 = {:e} after {} Nelder-Mead iterations ({}), {} evaluations", rep.chi2, rep.local_iterations, rep.local_stop, rep.evaluations);
    assert!(errs[0] < 1e-5 && errs[1] < 1e-6, "{errs:?}");
    assert!(rep.chi2 < 1e-12, "chi2 = {}", rep.chi2);
    // σ still comes from the finite-difference Jacobian at the optimum
    assert!(rep.parameters["beta.q_gb"]["sigma"].as_f64().is_some_and(|s| s > 0.0 && s < 1e4), "{:?}", rep.parameters);
    assert_eq!(rep.batches.last().map(|b| b.label.as_str()), Some("covariance"));
    std::fs::remove_dir_all(&dir).ok();
}

/// A titanium corner and an isothermal compact case on it.
fn packing(dir: &Path) {
    let text = std::fs::read_to_string("cases/data/green-titanium.csv").unwrap();
    let mut csv = String::from("x,y,z,r\n");
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.starts_with('x')) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        if v[0] < 1.6e-4 && v[1] < 1.6e-4 && v[2] < 1.6e-4 {
            csv.push_str(line);
            csv.push('\n');
        }
    }
    std::fs::write(dir.join("corner.csv"), csv).unwrap();
    let case = "kind = \"compact\"\n[time]\nend = 100.0\ndt = 1.0e-3\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n\
                [[materials]]\nname = \"titanium-ivannikov2022\"\npreset = \"titanium-ivannikov2022\"\n[particles]\nsource = \"file\"\nfile = \"corner.csv\"\n\
                [thermal]\nmode = \"isothermal\"\nfurnace = { profile = { constant = 1373.0 } }\n";
    std::fs::write(dir.join("compact.toml"), case).unwrap();
    std::fs::write(dir.join("heat.toml"), case.replace("kind = \"compact\"", "kind = \"heat\"")).unwrap();
    std::fs::write(dir.join("model.toml"), format!("{case}[model]\npath_factor_gb = 0.3\n")).unwrap();
}

const HEAD: &str = "id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n";
const ROW: &str = "E1,6.4e-5,\"start 1273 K, heat 50 K/min to 1373 K, hold 5 min\",0.4,0.01,0.02,0.001\n";
// the seed paper's titanium, the compact case's material: the fit starts from its β data (the
// plain `titanium` is the compiled DFM290 set, whose d0_gb = 1.1e-7 m²/s these bounds exclude)
const OK: &str = "data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\nmodel = \"compact\"\n[[parameters]]\nkey = \"beta.d0_gb\"\nmin = 1.0\nmax = 1.0e4\n\
                  [[parameters]]\nkey = \"beta.q_gb\"\nmin = 190.0e3\nmax = 260.0e3\n[compact]\ncase = \"compact.toml\"\n";

/// `sinterdem check` on a calibration file (library entry `run::check`, as the command).
fn check(dir: &Path, calib: &str, data: &str) -> Result<String, String> {
    std::fs::write(dir.join("data.csv"), data).unwrap();
    let p = dir.join("calib.toml");
    std::fs::write(&p, calib).unwrap();
    let v = load_case(&p, &[]).map_err(|e| e.to_string())?;
    sinterdem::calibrate::check_file(&v, &[], dir).map_err(|e| e.to_string())
}

/// A good file is recognised and described (packing built, nothing run); every kind of bad input
/// is refused naming file, line, column, key, value or the valid choices.
#[test]
fn check_validates_calibration_files_without_running() {
    let dir = common::tmp_dir("check");
    packing(&dir);
    let data = format!("{HEAD}{ROW}");
    let ok = check(&dir, OK, &data).unwrap();
    assert!(
        ok.contains("calibration file, model = \"compact\", 2 parameters (beta.d0_gb, beta.q_gb), 1 experiment with 2 measured values")
            && ok.contains("compact case, 17 particles"),
        "{ok}"
    );
    assert!(!dir.join("out").exists() && !dir.join("compact-fit").exists());
    // also with kind = "calibration", and a pair model without a packing
    let pair = OK.replace("model = \"compact\"", "kind = \"calibration\"").replace("[compact]\ncase = \"compact.toml\"\n", "");
    assert!(check(&dir, &pair, &data).unwrap().contains("model = \"pair\""));
    let bad: Vec<(String, String, &[&str])> = vec![
        // data file: file, line, column
        (OK.into(), format!("{HEAD}{ROW}E2,abc,\"start 1273 K, hold 5 min\",0.4,0.01,,\n"), &["data.csv line 3, column 2 (diameter_m)", "not a number"]),
        (OK.into(), format!("{HEAD}E1,6.4e-5,\"start 1273 K, hold 5 fortnights\",0.4,0.01,,\n"), &["data.csv line 2, column 3 (schedule)", "fortnights"]),
        // parameters
        (
            OK.replace("beta.q_gb", "beta.q_gbx"),
            data.clone(),
            &["parameters[1].key = \"beta.q_gbx\"", "valid keys: alpha.atomic_volume", "model.path_factor_gb"],
        ),
        (OK.replace("min = 190.0e3", "min = 270.0e3"), data.clone(), &["parameters[1].min (beta.q_gb)", "not below max"]),
        (
            OK.replace("key = \"beta.q_gb\"\nmin = 190.0e3\nmax = 260.0e3", "key = \"beta.q_gb\"\nmin = 0.0\nmax = 260.0e3\nlog = true"),
            data.clone(),
            &["parameters[1].min (beta.q_gb, log = true) = 0", "(0, max)"],
        ),
        // material
        (OK.replace("material = \"titanium-ivannikov2022\"", "material = \"unobtainium\""), data.clone(), &["material", "unobtainium"]),
        // optimiser
        (format!("{OK}[optimiser]\nlocal = \"simplex\"\n"), data.clone(), &["optimiser.local = \"simplex\"", "nelder_mead"]),
        (format!("{OK}[optimiser]\nsimplex_scale = 2.0\n"), data.clone(), &["optimiser.simplex_scale = 2 is out of range"]),
        // the packing
        (OK.replace("case = \"compact.toml\"", "case = \"nope.toml\""), data.clone(), &["[compact] case =", "nope.toml"]),
        (OK.replace("case = \"compact.toml\"", "case = \"heat.toml\""), data.clone(), &["heat.toml", "needs kind = \"compact\""]),
        (format!("{OK}engine = \"cloud\"\n"), data.clone(), &["compact.engine = \"cloud\"", "\"local\" or \"slurm\""]),
        (format!("{OK}jobs = 0\n"), data.clone(), &["compact.jobs = 0 is out of range"]),
        (format!("{OK}experiments = [\"E9\"]\n"), data.clone(), &["no experiment \"E9\"", "it has: E1"]),
        (format!("{OK}[compact.slurm]\nchunk = 0\n"), data.clone(), &["compact.slurm.chunk = 0 is out of range"]),
        (format!("{OK}[compact.slurm]\nqueue = \"x\"\n"), data.clone(), &["queue"]),
        (format!("{OK}overrides = [\"time.dt=-1\"]\n"), data.clone(), &["time.dt = -1 is out of range"]),
        (
            OK.replace("case = \"compact.toml\"", "case = \"model.toml\""),
            data.clone(),
            &["model.path_factor_gb = 0.3", "path_factor_gb = 0.25", "[path_factors]"],
        ),
        (OK.replace("[compact]\ncase = \"compact.toml\"\n", ""), data.clone(), &["model = \"compact\" needs [compact] case"]),
    ];
    for (i, (calib, d, want)) in bad.iter().enumerate() {
        let e = check(&dir, calib, d).expect_err(&format!("case {i} passed"));
        assert!(want.iter().all(|w| e.contains(w)), "case {i}: {e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The command line: `sinterdem check` names the calibration file, line and column of a bad key
/// and exits with failure; `sinterdem run` on a calibration file says what to do instead.
#[test]
fn check_command_locates_bad_keys_of_a_calibration_file() {
    let dir = common::tmp_dir("cli");
    packing(&dir);
    std::fs::write(dir.join("data.csv"), format!("{HEAD}{ROW}")).unwrap();
    std::fs::write(dir.join("calib.toml"), format!("{OK}[optimiser]\nswarm_size = 0\n")).unwrap();
    let exe = env!("CARGO_BIN_EXE_sinterdem");
    let o = std::process::Command::new(exe).arg("check").arg(dir.join("calib.toml")).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("calib.toml:15:1: optimiser.swarm_size = 0 is out of range"), "{err}");
    std::fs::write(dir.join("calib.toml"), OK.replace("model = \"compact\"", "kind = \"calibration\"\nmodel = \"compact\"")).unwrap();
    let o = std::process::Command::new(exe).arg("check").arg(dir.join("calib.toml")).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("ok (calibration file"));
    let o = std::process::Command::new(exe).args(["-q", "run"]).arg(dir.join("calib.toml")).arg("--out").arg(dir.join("o")).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("sinterdem calibrate"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

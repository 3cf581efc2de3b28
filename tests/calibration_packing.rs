//! Calibration on a packing (`model = "compact"`, docs/calibration.md "Fitting on a packing"):
//! noise-free data that the packing itself produced at a known β grain-boundary D0 are fitted back,
//! every optimiser generation is one study of the study engine, a re-run into the same directory
//! reuses the finished runs, a failing run is a penalty; and the `[model]` path factors of an
//! included material file reach a compact case (with the case's own value winning).
//!
//! The packing is a 31-particle corner of the bundled green titanium body and the schedules are
//! short β-phase holds, so one compact run takes about 0.1 s.

use sinterdem::calibrate::compact::{CompactModel, CompactSection};
use sinterdem::calibrate::data::{Experiment, Observation};
use sinterdem::calibrate::model::{ForwardModel, Point, Problem};
use sinterdem::calibrate::params::{ParameterEntry, parse_parameters};
use sinterdem::calibrate::{parse, report::CalibrationReport, run};
use sinterdem::config::load_case;
use sinterdem::models::diffusion7::{Material, PathFactors};
use sinterdem::profile::Profile;
use std::path::Path;

mod common;

/// The particles of the bundled green titanium body with x, y, z < `edge` into `dir/corner.csv`;
/// returns their number.
fn corner(dir: &Path, edge: f64) -> usize {
    let text = std::fs::read_to_string("cases/data/green-titanium.csv").unwrap();
    let mut csv = String::from("x,y,z,r\n");
    let mut n = 0;
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.starts_with('x')) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        if v[0] < edge && v[1] < edge && v[2] < edge {
            csv.push_str(line);
            csv.push('\n');
            n += 1;
        }
    }
    std::fs::write(dir.join("corner.csv"), csv).unwrap();
    n
}

/// An isothermal titanium compact on `corner.csv` (its furnace profile and end are replaced per
/// experiment by the calibration).
fn compact_case(dir: &Path, model: &str) {
    std::fs::write(
        dir.join("compact.toml"),
        format!(
            "kind = \"compact\"\n[time]\nend = 100.0\ndt = 1.0e-3\ndt_max = 10.0\nsubsteps_allowed = 100\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n\
             [[materials]]\nname = \"titanium-ivannikov2022\"\npreset = \"titanium-ivannikov2022\"\n[particles]\nsource = \"file\"\nfile = \"corner.csv\"\n\
             [thermal]\nmode = \"isothermal\"\nfurnace = {{ profile = {{ constant = 1373.0 }} }}\n{model}"
        ),
    )
    .unwrap();
}

/// β-phase schedules of a few minutes (the α/β transition is at 1156 K).
const SCHEDULES: [(&str, &str); 2] = [("A", "start 1273 K, heat 50 K/min to 1373 K, hold 5 min"), ("B", "start 1173 K, heat 50 K/min to 1323 K, hold 8 min")];

/// The truth: twice the bundled β grain-boundary prefactor (50.98 m²/s).
const TRUTH_D0_GB: f64 = 101.96;
const NECK_SIGMA: f64 = 0.01;
const SHRINK_SIGMA: f64 = 0.001;

fn experiments() -> Vec<Experiment> {
    SCHEDULES
        .iter()
        .map(|(id, s)| Experiment {
            id: id.to_string(),
            diameter: 6.4e-5,
            schedule: s.to_string(),
            profile: Profile::from_schedule(s).unwrap(),
            end: Observation::default(),
            series: vec![],
        })
        .collect()
}

fn d0_gb_problem(experiments: Vec<Experiment>) -> Problem {
    let ti = Material::titanium();
    let params = parse_parameters(&[ParameterEntry { key: "beta.d0_gb".into(), min: 1.0, max: 1.0e4, log: None }], &ti).unwrap();
    Problem { experiments, material: ti, factors: PathFactors::default(), params }
}

/// `data.csv` with the packing's own shrinkage and neck ratio at the truth, computed by the fit's
/// forward model (one study), written in shortest round-trip form: noise-free.
fn truth_data(dir: &Path) {
    let problem = d0_gb_problem(experiments());
    let section = CompactSection { case: Some("compact.toml".into()), jobs: Some(2.0), ..Default::default() };
    let (material, factors) = problem.configured(&[TRUTH_D0_GB]);
    let model = CompactModel::new(&section, dir, problem, &dir.join("truth")).unwrap();
    let (preds, executed) = model.run_batch(0, "truth", &[Point { values: vec![TRUTH_D0_GB], material, factors }]).unwrap();
    assert_eq!(executed, 2);
    let mut csv = String::from("id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n");
    for (e, p) in model.problem().experiments.iter().zip(&preds[0]) {
        let p = p.as_ref().unwrap();
        eprintln!("truth {}: neck ratio {}, shrinkage {}", e.id, p.end.neck_ratio, p.end.shrinkage);
        assert!(p.end.shrinkage > 0.005 && p.end.neck_ratio > 0.2, "{p:?}");
        csv.push_str(&format!("{},{},\"{}\",{},{NECK_SIGMA},{},{SHRINK_SIGMA}\n", e.id, e.diameter, e.schedule, p.end.neck_ratio, p.end.shrinkage));
    }
    std::fs::write(dir.join("data.csv"), csv).unwrap();
}

fn calibrate(calib: &Path, out: &Path) -> CalibrationReport {
    let v = load_case(calib, &[]).unwrap();
    let s = parse(&v, calib.parent().unwrap()).unwrap();
    run(s, out, &mut |m| eprintln!("{m}")).unwrap()
}

fn done_lines(fit: &Path) -> usize {
    let mut n = 0;
    for d in std::fs::read_dir(fit).unwrap().flatten().filter(|d| d.path().is_dir()) {
        let log = std::fs::read_to_string(d.path().join("executions.log")).unwrap_or_default();
        n += log.lines().filter(|l| l.starts_with("done ")).count();
    }
    n
}

/// The fit recovers the β grain-boundary D0 from the packing's own noise-free data; each optimiser
/// generation is one study (`compact-fit/gen-NNNN-LABEL/`, its runs = sets × experiments); a
/// re-run into the same directory reuses every run, and after deleting the last two generations
/// it recomputes exactly those.
#[test]
fn packing_fit_recovers_the_truth_one_study_per_generation_and_resumes() {
    let dir = common::tmp_dir("fit");
    assert_eq!(corner(&dir, 2.0e-4), 31);
    compact_case(&dir, "");
    truth_data(&dir);
    let calib = dir.join("calib.toml");
    std::fs::write(
        &calib,
        "data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\nmodel = \"compact\"\nseed = 3\n\
         [[parameters]]\nkey = \"beta.d0_gb\"\nmin = 1.0\nmax = 1.0e4\n\
         [optimiser]\nswarm_size = 3\nswarm_iterations = 2\nlocal_iterations = 20\ntolerance = 1.0e-10\nstall = 2\n\
         [compact]\ncase = \"compact.toml\"\njobs = 2\n",
    )
    .unwrap();
    let out = dir.join("out");
    let t0 = std::time::Instant::now();
    let rep = calibrate(&calib, &out);
    let wall = t0.elapsed().as_secs_f64();
    let v = rep.parameters["beta.d0_gb"]["value"].as_f64().unwrap();
    let rel = (v - TRUTH_D0_GB).abs() / TRUTH_D0_GB;
    eprintln!(
        "fitted beta.d0_gb = {v}, truth {TRUTH_D0_GB}, relative error {rel:.2e}; chi2 = {:e}; {} batches, {} runs, {wall:.1} s",
        rep.chi2,
        rep.batches.len(),
        rep.runs
    );
    // noise-free: the residuals vanish at the truth, and a packing run is deterministic, so the
    // Gauss-Newton steps land on it (measured: 5e-13 relative, χ² 2e-23); 1e-8 leaves room for
    // the tolerance-level kinks of the adaptive steps in another build
    assert!(rel < 1e-8, "beta.d0_gb = {v}, truth {TRUTH_D0_GB}");
    assert!(rep.chi2 < 1e-6, "chi2 = {}", rep.chi2);
    assert_eq!((rep.model.as_str(), rep.pair_runs, rep.failed_runs), ("compact", 0, 0));
    // one study per generation
    let fit = out.join("compact-fit");
    let mut dirs: Vec<String> =
        std::fs::read_dir(&fit).unwrap().flatten().filter(|d| d.path().is_dir()).map(|d| d.file_name().to_string_lossy().to_string()).collect();
    dirs.sort();
    assert_eq!(dirs.len(), rep.batches.len(), "{dirs:?}");
    for (b, d) in rep.batches.iter().zip(&dirs) {
        assert_eq!(d, &format!("gen-{:04}-{}", b.batch, b.label));
        assert_eq!(b.runs, 2 * b.points);
        let plan: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(fit.join(d).join("plan.json")).unwrap()).unwrap();
        assert_eq!(plan.as_array().unwrap().len(), b.runs, "{d}");
    }
    // the swarm: its initial population and each of its 2 iterations, 3 particles each
    let swarm: Vec<usize> = rep.batches.iter().filter(|b| b.label == "swarm").map(|b| b.points).collect();
    assert_eq!(swarm, vec![3, 3, 3]);
    assert_eq!(rep.runs_executed, rep.runs);
    assert_eq!(done_lines(&fit) as u64, rep.runs);
    // the same command again: every run is found in the store, the result is bit-identical
    let again = calibrate(&calib, &out);
    assert_eq!(again.runs_executed, 0);
    assert_eq!(again.batches.len(), rep.batches.len());
    assert_eq!((again.chi2.to_bits(), again.parameters["beta.d0_gb"]["value"].as_f64().unwrap().to_bits()), (rep.chi2.to_bits(), v.to_bits()));
    // as if killed before the last two generations: only their runs are computed
    let last: Vec<&sinterdem::calibrate::model::BatchInfo> = rep.batches.iter().rev().take(2).collect();
    for b in &last {
        std::fs::remove_dir_all(fit.join(format!("gen-{:04}-{}", b.batch, b.label))).unwrap();
    }
    let resumed = calibrate(&calib, &out);
    assert_eq!(resumed.runs_executed as usize, last.iter().map(|b| b.runs).sum::<usize>());
    assert_eq!(resumed.chi2.to_bits(), rep.chi2.to_bits());
    std::fs::remove_dir_all(&dir).ok();
}

/// A run that fails on the packing (the schedule melts titanium) is a penalty, not a crash; since
/// every run fails, the calibration ends with a ModelError naming the experiment and the melting
/// instead of a "fit" of penalties (issue 26 class 6: before, it exited 0 with chi2 = 2e6).
#[test]
fn a_failed_packing_run_is_a_penalty() {
    let dir = common::tmp_dir("fail");
    corner(&dir, 1.6e-4);
    compact_case(&dir, "");
    // titanium melts at 1941 K
    std::fs::write(
        dir.join("data.csv"),
        "id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\nM,6.4e-5,\"start 1900 K, heat 100 K/min to 2000 K\",0.4,0.01,0.02,0.001\n",
    )
    .unwrap();
    let calib = dir.join("calib.toml");
    std::fs::write(
        &calib,
        "data = \"data.csv\"\nmaterial = \"titanium-ivannikov2022\"\nmodel = \"compact\"\n[[parameters]]\nkey = \"beta.d0_gb\"\nmin = 1.0\nmax = 1.0e4\n\
         [optimiser]\nswarm_iterations = 0\nlocal_iterations = 0\n[compact]\ncase = \"compact.toml\"\n",
    )
    .unwrap();
    let v = load_case(&calib, &[]).unwrap();
    let s = parse(&v, calib.parent().unwrap()).unwrap();
    let err = run(s, &dir.join("out"), &mut |m| eprintln!("{m}")).unwrap_err();
    assert!(matches!(err, sinterdem::error::Error::Model(_)), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("every run of the calibration fails") && msg.contains("melting") && msg.contains("experiment M on the packing"), "{msg}");
    std::fs::remove_dir_all(&dir).ok();
}

fn shrinkage(dir: &Path, name: &str) -> [f64; 3] {
    let v = load_case(&dir.join("compact.toml"), &[]).unwrap();
    let p = sinterdem::kinds::RunParams { base_dir: dir.to_path_buf(), plots: false, ..Default::default() };
    let s = sinterdem::kinds::run(&v, &["time.end=300".into()], &dir.join(name), &p).unwrap();
    [s.f64("shrinkage_x").unwrap(), s.f64("shrinkage_y").unwrap(), s.f64("shrinkage_z").unwrap()]
}

/// The `[model]` of an included material file (what `sinterdem calibrate` writes when it fitted
/// path factors) sets the compact's path factors: the result differs from the same file without it
/// and equals the case setting the factor itself; the case's own `[model]` wins over the file; two
/// included files that disagree are refused naming both. A calibration file's `include` gives its
/// starting path factors the same way, below its own `[path_factors]`.
#[test]
fn included_material_path_factors_reach_the_compact() {
    let dir = common::tmp_dir("model");
    corner(&dir, 2.0e-4);
    let mut ti = Material::titanium();
    ti.source = "test".into();
    let fitted = PathFactors { path_factor_gb: 0.5, ..PathFactors::default() };
    sinterdem::calibrate::report::write_material(&dir.join("with-model.toml"), &ti, Some(&fitted), "test").unwrap();
    sinterdem::calibrate::report::write_material(&dir.join("plain.toml"), &ti, None, "test").unwrap();
    let inc = |file: &str| format!("include = \"{file}\"\n");
    let with = |file: &str, model: &str| {
        std::fs::write(
            dir.join("compact.toml"),
            format!(
                "kind = \"compact\"\n[time]\nend = 100.0\ndt = 1.0e-3\ndt_max = 10.0\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n\
                 [[materials]]\nname = \"titanium-ivannikov2022\"\npreset = \"titanium-ivannikov2022\"\n{}[particles]\nsource = \"file\"\nfile = \"corner.csv\"\n\
                 [thermal]\nmode = \"isothermal\"\nfurnace = {{ profile = {{ constant = 1373.0 }} }}\n{model}",
                inc(file)
            ),
        )
        .unwrap();
    };
    with("plain.toml", "");
    let plain = shrinkage(&dir, "plain");
    with("with-model.toml", "");
    let included = shrinkage(&dir, "included");
    with("plain.toml", "[model]\npath_factor_gb = 0.5\n");
    let case_level = shrinkage(&dir, "case");
    with("with-model.toml", "[model]\npath_factor_gb = 0.25\n");
    let case_wins = shrinkage(&dir, "case-wins");
    eprintln!("plain {plain:?}, included [model] {included:?}, case [model] {case_level:?}, case 0.25 over file 0.5 {case_wins:?}");
    // a longer grain-boundary path (λ_gb 0.25 → 0.5) halves the GB flux: less shrinkage
    for a in 0..3 {
        assert!(included[a] < 0.9 * plain[a], "axis {a}: {} vs {}", included[a], plain[a]);
    }
    assert_eq!(included, case_level);
    assert_eq!(case_wins, plain);
    // two files that disagree
    let other = PathFactors { path_factor_gb: 0.3, ..PathFactors::default() };
    sinterdem::calibrate::report::write_material(&dir.join("other.toml"), &ti, Some(&other), "test").unwrap();
    std::fs::write(
        dir.join("two.toml"),
        "kind = \"compact\"\n[time]\nend = 1.0\ndt = 1.0e-3\n[[materials]]\nname = \"titanium\"\ninclude = \"with-model.toml\"\n\
         [[materials]]\nname = \"titanium2\"\npreset = \"titanium-ivannikov2022\"\ninclude = \"other.toml\"\n[particles]\nsource = \"file\"\nfile = \"corner.csv\"\n",
    )
    .unwrap();
    let e = load_case(&dir.join("two.toml"), &[]).unwrap_err().to_string();
    assert!(
        e.contains("materials.1.include = \"other.toml\"") && e.contains("materials.0.include = \"with-model.toml\"") && e.contains("path_factor_gb"),
        "{e}"
    );
    // a calibration file: the included [model] starts the path factors, [path_factors] wins (the
    // bounds hold the included material's q_gb = 153 kJ/mol, the fit's start)
    std::fs::write(
        dir.join("data.csv"),
        format!("id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\nA,6.4e-5,\"{}\",0.4,0.01,,\n", SCHEDULES[0].1),
    )
    .unwrap();
    let calib = |extra: &str| {
        let p = dir.join("calib.toml");
        std::fs::write(&p, format!("data = \"data.csv\"\nmaterial = \"titanium\"\ninclude = \"with-model.toml\"\n[[parameters]]\nkey = \"beta.q_gb\"\nmin = 1.0e5\nmax = 2.4e5\n{extra}")).unwrap();
        parse(&load_case(&p, &[]).unwrap(), &dir).unwrap().factors
    };
    assert_eq!(calib("").path_factor_gb, 0.5);
    assert_eq!(calib("[path_factors]\npath_factor_gb = 0.3\n").path_factor_gb, 0.3);
    std::fs::remove_dir_all(&dir).ok();
}

/// `cases/calibration/titanium-packing.csv` holds the bundled packing's own values at the truth
/// (the β grain-boundary data of the synthetic titanium example), computed by the fit's forward
/// model from the bundled calibration file; `SINTERDEM_WRITE_CASES=1` rewrites it.
#[test]
fn bundled_packing_data_match_the_packing() {
    use sinterdem::calibrate::synthetic::{NECK_SIGMA as NS, SHRINK_SIGMA_ABS, SHRINK_SIGMA_REL, TRUTH};
    let path = Path::new("cases/calibration/titanium-packing.csv");
    let calib = Path::new("cases/calibration/titanium-packing.toml");
    let s = parse(&load_case(calib, &[]).unwrap(), calib.parent().unwrap()).unwrap();
    let truth: Vec<f64> = s.params.iter().map(|p| TRUTH.iter().find(|(k, _)| *k == p.key).unwrap().1).collect();
    let problem = Problem { experiments: s.experiments.clone(), material: s.material.clone(), factors: s.factors, params: s.params.clone() };
    let (material, factors) = problem.configured(&truth);
    let out = common::tmp_dir("bundled");
    let model = CompactModel::new(&s.compact, &s.base, problem, &out).unwrap();
    let (preds, _) = model.run_batch(0, "truth", &[Point { values: truth.clone(), material, factors }]).unwrap();
    let mut text = String::from(
        "# Synthetic packing data generated by sinterdem (tests/calibration_packing.rs, bundled_packing_data_match_the_packing):\n\
         # the compact titanium-corner-compact.toml under each schedule with bundled titanium except\n",
    );
    text.push_str(&format!(
        "# {}; noise-free, sigma(neck_ratio) = {NS}, sigma(shrinkage) = {SHRINK_SIGMA_REL}*shrinkage + {SHRINK_SIGMA_ABS:e}.\n",
        s.params.iter().zip(&truth).map(|(p, v)| format!("{} = {v:e}", p.key)).collect::<Vec<_>>().join(", ")
    ));
    text.push_str("id,diameter_m,schedule,neck_ratio,neck_ratio_sigma,shrinkage,shrinkage_sigma\n");
    for (e, p) in s.experiments.iter().zip(&preds[0]) {
        let p = p.as_ref().unwrap();
        let ss = SHRINK_SIGMA_REL * p.end.shrinkage.abs() + SHRINK_SIGMA_ABS;
        text.push_str(&format!("{},{:.4e},\"{}\",{:.10e},{NS:.4e},{:.10e},{ss:.4e}\n", e.id, e.diameter, e.schedule, p.end.neck_ratio, p.end.shrinkage));
    }
    if std::env::var("SINTERDEM_WRITE_CASES").is_ok() {
        std::fs::write(path, &text).unwrap();
    }
    assert_eq!(std::fs::read_to_string(path).unwrap(), text, "{} differs from the packing's values", path.display());
    std::fs::remove_dir_all(&out).ok();
}

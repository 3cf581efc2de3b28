//! Issue 25 items 3, 5, 6 and 8 end to end: clean output directories (a run never mixes with
//! another command's outputs; `--force`; a rerun of the same case), `time.end` that follows the
//! schedule, the flagship without isolated particles or warnings, the calibrated-range verdict on
//! a furnace heat-up, the title from the file name, and the small things (empty case, `resume` of a finished run, `run --threads`,
//! `titanium` from any directory, the `--set` help of generate and calibrate).

use std::path::Path;
use std::process::{Command, Output};

mod common;

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sinterdem"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn sinterdem(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

fn ok(o: &Output) -> String {
    let e = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "exit {:?}: {e}", o.status.code());
    e
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A small heat case (the bundled hot plate on 3 x 3 x 4 cells, 5 s).
const SMALL: &[&str] = &["cases/hot-plate.toml", "--set", "time.end=5", "--set", "particles.cells=[3, 3, 4]"];

fn run_small(out: &Path, extra: &[&str]) -> Output {
    let mut c = bin();
    c.arg("-q").arg("run").args(SMALL).arg("--out").arg(out).args(extra);
    c.output().unwrap()
}

#[test]
fn every_command_refuses_a_directory_holding_another_commands_outputs_without_force() {
    let d = common::tmp_dir("refuse");
    let run = d.join("run");
    ok(&run_small(&run, &[]));
    let before = std::fs::read_to_string(run.join("summary.json")).unwrap();
    // another case (another end time), a generate, a study, a calibration, the titanium study run
    // from another working directory (which also shows that it finds its bundled study file)
    let study = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/studies/titanium-28.toml");
    let calib = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/calibration/titanium-synthetic.toml");
    let attempts: Vec<(&str, Output)> = vec![
        ("run", run_small(&run, &["--set", "time.end=6"])),
        ("generate", sinterdem(&["-q", "generate", "cases/green-copper.toml", "--out", s(&run)])),
        ("study", sinterdem(&["-q", "study", s(&study), "--out", s(&run)])),
        ("calibrate", sinterdem(&["-q", "calibrate", s(&calib), "--out", s(&run)])),
        (
            "titanium",
            Command::new(env!("CARGO_BIN_EXE_sinterdem")).current_dir(std::env::temp_dir()).args(["-q", "titanium", "--out", s(&run)]).output().unwrap(),
        ),
    ];
    for (cmd, o) in attempts {
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(5), "{cmd}: {e}");
        assert!(
            e.contains("holds the outputs of a run (series.csv, ") && e.contains("summary.json, 14 snapshot files)") && e.contains("add --force"),
            "{cmd}: {e}"
        );
    }
    assert_eq!(std::fs::read_to_string(run.join("summary.json")).unwrap(), before, "refused commands change nothing");
    // a run into a study's directory is refused too
    let st = d.join("study");
    std::fs::create_dir_all(&st).unwrap();
    std::fs::write(st.join("plan.json"), "[]").unwrap();
    let o = run_small(&st, &[]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("holds the outputs of a study (plan.json)"), "{}", String::from_utf8_lossy(&o.stderr));
    // with --force: a generate replaces the run, and only the generate's files are left
    ok(&sinterdem(&["-q", "generate", "cases/green-copper.toml", "--out", s(&run), "--set", "packing.particles=60", "--force"]));
    let names: Vec<String> = std::fs::read_dir(&run).unwrap().flatten().map(|e| e.file_name().to_string_lossy().to_string()).collect();
    assert!(!names.iter().any(|n| n.ends_with(".vtu") && n.starts_with("particles_") || n == "series.csv" || n == "sinterdem.h5"), "{names:?}");
    assert_eq!(json(&run.join("summary.json"))["particles"], 60);
    let log = std::fs::read_to_string(run.join("log.txt")).unwrap();
    assert!(log.contains("--force: removed the outputs of a run (series.csv, ") && log.contains("summary.json, 14 snapshot files)"), "{log}");
}

/// The same case again (same resolved case and inputs: `run.json`) replaces its own outputs
/// without `--force`; a run refused at its start (a bad key) leaves nothing that blocks the next.
#[test]
fn a_rerun_of_the_same_case_needs_no_force_and_a_refused_start_blocks_nothing() {
    let d = common::tmp_dir("same");
    let out = d.join("out");
    ok(&run_small(&out, &[]));
    let first = std::fs::read_to_string(out.join("series.csv")).unwrap();
    ok(&run_small(&out, &[]));
    assert_eq!(std::fs::read_to_string(out.join("series.csv")).unwrap(), first);
    let log = std::fs::read_to_string(out.join("log.txt")).unwrap();
    assert!(log.contains("a rerun of the same case (run.json: the same resolved case and input files)"), "{log}");
    let fresh = d.join("fresh");
    let o = run_small(&fresh, &["--set", "time.dt=-1"]);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    ok(&run_small(&fresh, &[]));
}

#[test]
fn time_end_defaults_to_the_end_of_the_schedule_in_every_kind_with_one() {
    let d = common::tmp_dir("end");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // heat: hot plate, 293.15 K → 1273 K at 100 K/min (587.91 s), hold 5 min: ends at 887.91 s
    let heat = d.join("heat.toml");
    let text = std::fs::read_to_string(root.join("cases/hot-plate.toml")).unwrap();
    let text: String = text.lines().filter(|l| !l.trim_start().starts_with("end ")).map(|l| format!("{l}\n")).collect();
    std::fs::write(&heat, text).unwrap();
    let out = d.join("heat");
    ok(&sinterdem(&["-q", "run", s(&heat), "--out", s(&out), "--set", "particles.cells=[2, 2, 2]", "--set", "time.dt=20"]));
    let t = json(&out.join("summary.json"))["final_time_s"].as_f64().unwrap();
    let expected = (1273.0 - 293.15) / (100.0 / 60.0) + 300.0;
    assert!((t - expected).abs() < 1e-9 * expected, "{t} vs {expected}");
    assert!(
        std::fs::read_to_string(out.join("log.txt")).unwrap().contains("time.end not given: the end of the heating profile thermal.fixed.0.profile, 887.91 s")
    );
    // pair: 1000 K → 1293 K at 10 K/min (1758 s), hold 2 min: 1878 s
    let pair = d.join("pair.toml");
    let text = std::fs::read_to_string(root.join("cases/pair-copper.toml")).unwrap();
    let text: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with("end_time"))
        .map(|l| {
            if l.trim_start().starts_with("constant") {
                "schedule = \"start 1000 K, heat 10 K/min to 1293 K, hold 2 min\"\n".to_string()
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    std::fs::write(&pair, text).unwrap();
    let out = d.join("pair");
    ok(&sinterdem(&["-q", "run", s(&pair), "--out", s(&out), "--set", "output.plot=false"]));
    assert_eq!(json(&out.join("summary.json"))["final_time_s"].as_f64().unwrap(), 1878.0);
    // a compact whose heating is constant has no end to take: refused naming the key
    let compact = d.join("compact.toml");
    let text = std::fs::read_to_string(root.join("cases/copper-compact.toml")).unwrap().replace("\"data/", &format!("\"{}/cases/data/", root.display()));
    let text: String = text.lines().filter(|l| !l.trim_start().starts_with("end ")).map(|l| format!("{l}\n")).collect();
    std::fs::write(&compact, text).unwrap();
    let o = sinterdem(&["check", s(&compact)]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("time.end: missing, and no heating profile of the case ends (all constant)"), "{e}");
}

#[test]
fn an_explicit_end_before_the_schedule_warns_once_and_no_bundled_case_does() {
    // after the peak, in the hold: 1200 s of the hot plate's 60 min hold
    let o = sinterdem(&[
        "check",
        "cases/hot-plate-compact.toml",
        "--set",
        "thermal.fixed.0.profile.schedule=start 293.15 K, heat 1000 K/min to 1373 K, hold 60 min",
    ]);
    let e = ok(&o);
    assert_eq!(e.matches("ends before the heating profile").count(), 1, "{e}");
    assert!(
        e.contains("time.end = 1200 s ends before the heating profile thermal.fixed.0.profile (which ends at 3664.791 s): the run stops at 1373.0 K, after the profile's peak 1373.0 K"),
        "{e}"
    );
    // before the peak: T at the end from the ramp, (1373 - 293.15) K in 64.791 s
    let e = ok(&sinterdem(&["check", "cases/hot-plate-compact.toml", "--set", "time.end=30"]));
    let t30 = 293.15 + 1000.0 / 60.0 * 30.0;
    let at: f64 =
        e.split("the run stops at ").nth(1).and_then(|r| r.split(" K, below the profile's peak 1373.0 K").next()).and_then(|x| x.parse().ok()).unwrap();
    assert!((at - t30).abs() <= 0.06, "{at} K vs {t30} K: {e}");
    for dir in ["cases", "cases/titanium"] {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
        for f in std::fs::read_dir(root).unwrap().flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|x| x == "toml")) {
            let o = sinterdem(&["check", s(&f)]);
            let e = String::from_utf8_lossy(&o.stderr);
            assert!(!e.contains("ends before the heating profile"), "{}: {e}", f.display());
        }
    }
}

/// The README's flagship: the gas-gap model reaches the 5 rattlers of the green body, so no
/// particle lacks a conductive path, none keeps 293 K, and no snapshot carries an `isolated` field;
/// it prints no warning at all: its heat-up from 293 K puts about 1.4·10⁻³ of titanium's diffusion
/// dose below the calibrated range (docs/diffusion7.md (V3)), far under the 1 % that warns, and
/// series.csv holds no column of physics the case lacks (no load, cell or thermal expansion).
/// Its one warning (issue 37): the seed paper's fitted titanium is declared only up to 902 K,
/// where its α surface diffusion becomes faster than a liquid, and the plate heats to 1373 K.
#[test]
fn the_flagship_warns_only_that_the_fitted_titanium_leaves_its_range_and_has_no_isolated_particle() {
    let d = common::tmp_dir("flagship");
    let out = d.join("out");
    let e = ok(&sinterdem(&["-q", "run", "cases/hot-plate-compact.toml", "--out", s(&out), "--set", "output.snapshots=2"]));
    assert!(!e.contains("without a conductive path"), "{e}");
    let warn: Vec<&str> = e.lines().filter(|l| l.starts_with("warning:")).collect();
    assert_eq!(warn.len(), 1, "{e}");
    assert!(warn[0].contains("material \"titanium-ivannikov2022\": contact temperature above the calibrated range 793.0–902.0 K"), "{e}");
    let v = json(&out.join("summary.json"));
    assert_eq!(v["warnings"].as_array().map(|w| w.len()), Some(1), "{}", v["warnings"]);
    let share = v["extrapolated_below_range"]["titanium-ivannikov2022"]["share"].as_f64().unwrap();
    assert!(share > 0.0 && share < 1e-2, "{share}");
    assert!(v["extrapolated_below_range"]["titanium-ivannikov2022"]["lowest_temperature_K"].as_f64().unwrap() < 400.0);
    let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
    let head: Vec<&str> = series.lines().next().unwrap().split(',').collect();
    let rows: Vec<Vec<f64>> = series.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    for (k, name) in head.iter().enumerate() {
        // subdivided_fraction: zero while no contact needs more substeps than allowed (a state)
        if *name != "subdivided_fraction" {
            assert!(rows.iter().any(|r| r[k] != 0.0), "{name} is zero in every row");
        }
    }
    for gone in ["thermal_strain", "sintering_shrinkage_x", "applied_stress_Pa", "sigma_xx_Pa", "normal_force_mean_N"] {
        assert!(!head.contains(&gone), "{gone}: {head:?}");
    }
    assert_eq!(v["isolated_particles"], 0);
    assert!(v["min_temperature_K"].as_f64().unwrap() > 1300.0, "{}", v["min_temperature_K"]);
    let log = std::fs::read_to_string(out.join("log.txt")).unwrap();
    assert!(log.contains("5 particle(s) reach a heat source only across gaps"), "{log}");
    let vtu = std::fs::read_to_string(out.join("particles_000001.vtu")).unwrap();
    assert!(vtu.contains("Name=\"temperature_K\"") && !vtu.contains("Name=\"isolated\""));
}

/// The calibrated-range verdict on a furnace heat-up (copper-ivannikov2022, declared 1273–1353 K): stopped
/// at 600 s (furnace at 793 K) every contact sintered wholly below the range, share 1, and the
/// end of the run warns once (console and log.txt), after a log.txt detail line at the first
/// time below; stopped at 1250 s (furnace at its 1293 K hold) part of the dose was made inside the range,
/// and the share is the one summary.json reports, between the two.
#[test]
fn the_calibrated_range_verdict_weighs_the_dose_made_below_the_range_on_a_heat_up() {
    let d = common::tmp_dir("range");
    let go = |end: &str, name: &str| -> (serde_json::Value, String, String) {
        let out = d.join(name);
        let sets = ["time.end", "output.snapshots=0", "output.checkpoint_every=0", "output.conductivity_at=[]"];
        let mut c = bin();
        c.args(["-q", "run", "cases/furnace-compact.toml", "--out", s(&out)]);
        for x in sets {
            c.arg("--set").arg(if x == "time.end" { format!("time.end={end}") } else { x.to_string() });
        }
        let e = ok(&c.output().unwrap());
        (json(&out.join("summary.json")), e, std::fs::read_to_string(out.join("log.txt")).unwrap())
    };
    let (v, e, log) = go("600", "cold");
    let warn: Vec<&str> = e.lines().filter(|l| l.starts_with("warning: material \"copper-ivannikov2022\"")).collect();
    assert_eq!(warn.len(), 1, "{e}");
    assert!(warn[0].contains("100.000 % of the diffusion dose") && warn[0].contains("below the calibrated range 1273.0–1353.0 K"), "{e}");
    assert_eq!(v["extrapolated_below_range"]["copper-ivannikov2022"]["share"].as_f64(), Some(1.0));
    assert!(log.contains("material \"copper-ivannikov2022\": contact temperature below the calibrated range 1273.0–1353.0 K (293."), "{log}");
    assert_eq!(log.matches("warning: material \"copper-ivannikov2022\"").count(), 1, "{log}");
    let (v, _, _) = go("1250", "hot");
    let share = v["extrapolated_below_range"]["copper-ivannikov2022"]["share"].as_f64().unwrap();
    assert!(share > 0.05 && share < 0.95, "{share}");
}

/// A compact case without `title` is titled by its file's stem in the plots.
#[test]
fn a_case_without_a_title_is_titled_by_its_file_name() {
    let d = common::tmp_dir("title");
    let case = d.join("my-fcc-compact.toml");
    std::fs::write(&case, common::compact_text(&common::time_to(0.01), &[common::COPPER], &common::fcc(1), common::AT_1293_K)).unwrap();
    ok(&sinterdem(&["-q", "run", s(&case), "--out", s(&d.join("out"))]));
    let svg = std::fs::read_to_string(d.join("out/shrinkage.svg")).unwrap();
    assert!(svg.contains("my-fcc-compact: shrinkage along each axis"), "{svg}");
}

#[test]
fn small_things() {
    let d = common::tmp_dir("small");
    // an empty case file is refused, not read as a heat case
    let empty = d.join("empty.toml");
    std::fs::write(&empty, "# nothing yet\n").unwrap();
    for cmd in ["check", "run"] {
        let o = sinterdem(&[cmd, s(&empty), "--out", s(&d.join("e"))][..if cmd == "check" { 2 } else { 4 }]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains("empty.toml: the file is empty") && !e.contains("time: missing"), "{e}");
    }
    // resume of a finished run says so and changes nothing
    let out = d.join("compact");
    let short = ["--set", "time.end=2", "--set", "output.snapshots=0", "--set", "output.checkpoint_every=5", "--set", "output.conductivity_at=[]"];
    let mut c = bin();
    c.args(["-q", "run", "cases/copper-compact.toml", "--out", s(&out), "--threads", "1"]).args(short);
    ok(&c.output().unwrap());
    let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
    assert!(out.join("checkpoint.json").exists());
    let e = ok(&sinterdem(&["resume", s(&out)]));
    assert!(e.contains("the run finished (summary.json: completed at t = 2 s); nothing to resume"), "{e}");
    assert_eq!(std::fs::read_to_string(out.join("series.csv")).unwrap(), series);
    // run --threads: the same result on 1 and 2 threads; 0 refused
    let two = d.join("two");
    let mut c = bin();
    c.args(["-q", "run", "cases/copper-compact.toml", "--out", s(&two), "--threads", "2"]).args(short);
    ok(&c.output().unwrap());
    assert_eq!(std::fs::read_to_string(two.join("series.csv")).unwrap(), series);
    let o = sinterdem(&["run", "cases/copper-compact.toml", "--out", s(&d.join("zero")), "--threads", "0"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--threads"), "{}", String::from_utf8_lossy(&o.stderr));
    // the --set help of generate and calibrate names their own keys
    for (cmd, key) in [("generate", "packing.particles"), ("calibrate", "optimiser.")] {
        let h = String::from_utf8_lossy(&sinterdem(&[cmd, "--help"]).stdout).to_string();
        assert!(!h.contains("time.end") && h.contains(key), "{cmd}: {h}");
    }
}

/// A study says what its runs warned about (their log.txt) and why a collected series cell is
/// empty (a time past the runs' end), on the console (issue 25).
#[test]
fn a_study_reports_its_runs_warnings_and_collect_times_past_their_end() {
    let d = common::tmp_dir("study");
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/pair-copper.toml");
    let study = d.join("study.toml");
    std::fs::write(
        &study,
        format!(
            "base = {:?}\n[[parameters]]\nkey = \"pair.radius\"\nvalues = [2.5e-5, 3.0e-5]\n[collect]\nsummary = [\"neck_ratio\"]\nseries = [{{ column = \"neck_ratio\", times = [50.0, 500.0] }}]\n",
            base.display().to_string()
        ),
    )
    .unwrap();
    // each run ends at 100 s, 10 min before its heating schedule does: a warning per run
    let o = sinterdem(&[
        "-q",
        "study",
        s(&study),
        "--out",
        s(&d.join("out")),
        "--set",
        "pair.end_time=100",
        "--set",
        "temperature={ schedule = \"start 1200 K, heat 10 K/min to 1300 K, hold 1 min\" }",
    ]);
    let e = ok(&o);
    assert!(e.contains("2 runs (first run 0000, runs/0000/log.txt): pair.end_time = 100 s ends before the heating profile temperature"), "{e}");
    assert!(
        e.contains(
            "study.csv column neck_ratio_at_500s is empty for 2 of 2 successful runs (first run 0000): t = 500 s is outside the run's series, 0 s to 100 s"
        ),
        "{e}"
    );
    assert!(!e.contains("neck_ratio_at_50s is empty"), "{e}");
}

/// A walled packing that jams short of its target solid fraction says so (the issue: 0.62 asked,
/// 0.58 reported with thresholds_met and nothing else).
#[test]
fn a_packing_short_of_its_target_warns() {
    let d = common::tmp_dir("generate");
    let out = d.join("g");
    let e = ok(&sinterdem(&[
        "-q",
        "generate",
        "cases/green-copper.toml",
        "--out",
        s(&out),
        "--set",
        "packing.particles=200",
        "--set",
        "packing.target_solid_fraction=0.64",
    ]));
    let v = json(&out.join("summary.json"));
    let got = v["solid_fraction"].as_f64().unwrap();
    assert!(got < 0.63, "{got}");
    assert_eq!(v["target_reached"], false);
    assert!(e.contains("is short of packing.target_solid_fraction = 0.6400"), "{e}");
}

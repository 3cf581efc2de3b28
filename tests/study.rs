//! Studies on the local engine: the titanium-28 study reproduces the compiled-in titanium table,
//! each row equals the same run done alone, failures are recorded without stopping the study, a
//! study killed with SIGKILL and started again loses nothing and runs nothing twice, bad study
//! files are rejected naming key, value and range.

use sinterdem::kinds::titanium::{TRUNCATED_START, run_all_titanium};
use sinterdem::kinds::{self, RunParams};
use sinterdem::study::{self, StudyOptions};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

/// Reads study.csv into (header, rows) with a plain comma split (fields here hold no commas
/// except error messages, which sit in quoted fields near the end).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines.map(split_csv).collect();
    (header, rows)
}

fn split_csv(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                out.last_mut().unwrap().push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(String::new()),
            (c, _) => out.last_mut().unwrap().push(c),
        }
    }
    out
}

fn col(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

/// study.csv without the wall-time column (the only column allowed to differ between executions).
fn csv_without_wall(path: &Path) -> String {
    let (h, rows) = read_csv(path);
    let w = col(&h, "wall_seconds");
    let keep = |r: &Vec<String>| r.iter().enumerate().filter(|(i, _)| *i != w).map(|(_, v)| v.clone()).collect::<Vec<_>>().join("|");
    std::iter::once(keep(&h)).chain(rows.iter().map(keep)).collect::<Vec<_>>().join("\n")
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn titanium_28_study_reproduces_the_titanium_table() {
    let dir = common::tmp_dir("ti28");
    let opts = StudyOptions { out: Some(dir.join("study")), ..Default::default() };
    let info = study::run_study(&repo().join("cases/studies/titanium-28.toml"), &opts, &mut |_| {}).unwrap();
    assert_eq!((info.counts.runs, info.counts.ok), (28, 28));
    let table = run_all_titanium(&dir.join("table"), TRUNCATED_START, None).unwrap();
    let (h, rows) = read_csv(&dir.join("study/study.csv"));
    let (c_case, c_neck, c_shr) = (col(&h, "case"), col(&h, "neck_ratio"), col(&h, "shrinkage"));
    for (r, t) in rows.iter().zip(&table) {
        assert_eq!(r[c_case], t.experiment.id);
        let neck: f64 = r[c_neck].parse().unwrap();
        let shr: f64 = r[c_shr].parse().unwrap();
        assert!((neck / t.neck_ratio - 1.0).abs() <= 1e-9, "{}: neck {neck} vs {}", t.experiment.id, t.neck_ratio);
        assert!((shr / t.shrinkage - 1.0).abs() <= 1e-9, "{}: shrinkage {shr} vs {}", t.experiment.id, t.shrinkage);
    }
    assert_eq!(rows.len(), 28);
}

fn write_small_study(dir: &Path, extra: &str) -> PathBuf {
    let case = repo().join("cases/titanium/E14B.toml");
    let text = format!(
        "title = \"small\"\nbase = \"{}\"\n[[parameters]]\nkey = \"pair.radius\"\nrange = [30e-6, 36e-6]\nnum = 3\n[[parameters]]\nkey = \"temperature.peak_temperature\"\nvalues = [1273.0, 1373.0]\n[collect]\nsummary = [\"neck_ratio\", \"shrinkage\", \"steps\"]\nseries = [{{ column = \"shrinkage\", times = [3000.0, 1e9] }}]\n{extra}",
        case.display()
    );
    let p = dir.join("small.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn each_row_equals_the_run_done_alone_and_series_values_interpolate() {
    let dir = common::tmp_dir("alone");
    let s = write_small_study(&dir, "");
    let opts = StudyOptions { out: Some(dir.join("study")), jobs: Some(2), ..Default::default() };
    let info = study::run_study(&s, &opts, &mut |_| {}).unwrap();
    assert_eq!((info.counts.runs, info.counts.ok, info.executed), (6, 6, 6));
    let (h, rows) = read_csv(&dir.join("study/study.csv"));
    let case = sinterdem::config::load_case(&repo().join("cases/titanium/E14B.toml"), &[]).unwrap();
    let radii = [30e-6, 33e-6, 36e-6];
    for (k, r) in rows.iter().enumerate() {
        // grid order: the last parameter varies fastest
        let (rad, peak) = (radii[k / 2], [1273.0, 1373.0][k % 2]);
        assert_eq!(r[col(&h, "pair.radius")].parse::<f64>().unwrap(), rad);
        let alone = kinds::run(
            &case,
            &[format!("pair.radius={rad:?}"), format!("temperature.peak_temperature={peak:?}")],
            &dir.join(format!("alone{k}")),
            &RunParams { base_dir: repo().join("cases/titanium"), ..Default::default() },
        )
        .unwrap();
        for key in ["neck_ratio", "shrinkage", "steps"] {
            assert_eq!(r[col(&h, key)].parse::<f64>().unwrap(), alone.f64(key).unwrap(), "run {k} {key}");
        }
        // series.csv of the run, interpolated by hand at t = 3000 s
        let text = std::fs::read_to_string(dir.join(format!("alone{k}/series.csv"))).unwrap();
        let pts: Vec<(f64, f64)> = text
            .lines()
            .skip(1)
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                (v[0], v[3])
            })
            .collect();
        let i = pts.iter().position(|p| p.0 >= 3000.0).unwrap();
        let (a, b) = (pts[i - 1], pts[i]);
        let want = a.1 + (b.1 - a.1) * (3000.0 - a.0) / (b.0 - a.0);
        let got: f64 = r[col(&h, "shrinkage_at_3000s")].parse().unwrap();
        assert!((got - want).abs() <= 1e-15 * want.abs().max(1e-30), "run {k}: {got} vs {want}");
        // beyond the end of the run: empty, not NaN
        assert_eq!(r[col(&h, "shrinkage_at_1000000000s")], "");
        assert_eq!(r[col(&h, "status")], "ok");
    }
    // a second invocation finds every run done, executes nothing and writes the same study.csv
    let before = std::fs::read_to_string(dir.join("study/study.csv")).unwrap();
    let again = study::run_study(&s, &opts, &mut |_| {}).unwrap();
    assert_eq!(again.executed, 0);
    assert_eq!(std::fs::read_to_string(dir.join("study/study.csv")).unwrap(), before);
}

#[test]
fn a_failing_run_is_recorded_and_the_others_finish_and_retry_reruns_only_it() {
    let dir = common::tmp_dir("fail");
    let case = repo().join("cases/titanium/E14B.toml");
    let text = format!(
        "base = \"{}\"\n[[parameters]]\nkey = \"pair.radius\"\nvalues = [3.0e-5, -1.0, 3.5e-5]\n[collect]\nsummary = [\"neck_ratio\"]\n",
        case.display()
    );
    let s = dir.join("f.toml");
    std::fs::write(&s, text).unwrap();
    let opts = StudyOptions { out: Some(dir.join("study")), ..Default::default() };
    let info = study::run_study(&s, &opts, &mut |_| {}).unwrap();
    assert_eq!((info.counts.ok, info.counts.failed), (2, 1));
    let (h, rows) = read_csv(&dir.join("study/study.csv"));
    assert_eq!(rows[1][col(&h, "status")], "failed");
    let err = &rows[1][col(&h, "error")];
    assert!(err.contains("pair.radius") && err.contains("-1"), "{err}");
    assert_eq!(rows[1][col(&h, "neck_ratio")], "");
    assert_eq!(rows[0][col(&h, "status")], "ok");
    assert_eq!(rows[2][col(&h, "status")], "ok");
    // without --retry-failed nothing runs again; with it only the failed run
    assert_eq!(study::run_study(&s, &opts, &mut |_| {}).unwrap().executed, 0);
    let retry = StudyOptions { retry_failed: true, ..opts.clone() };
    assert_eq!(study::run_study(&s, &retry, &mut |_| {}).unwrap().executed, 1);
}

fn done_counts(dir: &Path) -> HashMap<String, usize> {
    let text = std::fs::read_to_string(dir.join("executions.log")).unwrap_or_default();
    let mut m = HashMap::new();
    for l in text.lines().filter(|l| l.starts_with("done ")) {
        *m.entry(l.split(' ').nth(2).unwrap().to_string()).or_insert(0) += 1;
    }
    m
}

#[test]
fn sigkill_midway_and_rerun_gives_the_same_study_with_no_run_executed_twice() {
    let dir = common::tmp_dir("kill");
    // slow runs (tight tolerance) so that the kill lands midway
    let case = repo().join("cases/titanium/E14B.toml");
    let text = format!(
        "base = \"{}\"\noverrides = [\"solver.rtol=1e-10\"]\n[[parameters]]\nkey = \"pair.radius\"\nrange = [30e-6, 36e-6]\nnum = 40\n[collect]\nsummary = [\"neck_ratio\", \"shrinkage\"]\n",
        case.display()
    );
    let s = dir.join("k.toml");
    std::fs::write(&s, &text).unwrap();
    let exe = env!("CARGO_BIN_EXE_sinterdem");
    let out = dir.join("killed");
    let mut child = Command::new(exe).args(["study", s.to_str().unwrap(), "--jobs", "1", "--quiet", "--out", out.to_str().unwrap()]).spawn().unwrap();
    // wait until some runs are done, then SIGKILL
    let t0 = std::time::Instant::now();
    loop {
        let done = done_counts(&out).len();
        if done >= 5 || t0.elapsed().as_secs() > 120 {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = done_counts(&out).len();
    assert!((5..40).contains(&before), "the kill should land midway ({before} of 40 done)");
    assert!(!out.join("study.csv").exists(), "the killed driver had not gathered yet");
    let st = Command::new(exe).args(["study", s.to_str().unwrap(), "--jobs", "1", "--quiet", "--out", out.to_str().unwrap()]).status().unwrap();
    assert!(st.success());
    let counts = done_counts(&out);
    assert_eq!(counts.len(), 40, "every run has a result");
    assert!(counts.values().all(|&c| c == 1), "no completed run executed twice: {counts:?}");
    // the same study run without interruption gives the same study.csv (wall times aside)
    let clean = dir.join("clean");
    let st = Command::new(exe).args(["study", s.to_str().unwrap(), "--quiet", "--out", clean.to_str().unwrap()]).status().unwrap();
    assert!(st.success());
    assert_eq!(csv_without_wall(&out.join("study.csv")), csv_without_wall(&clean.join("study.csv")));
}

#[test]
fn designs_lhs_and_sobol_give_seeded_points_within_bounds() {
    let dir = common::tmp_dir("designs");
    let case = repo().join("cases/titanium/E14B.toml");
    for kind in ["lhs", "sobol"] {
        let text = format!(
            "base = \"{}\"\n[design]\nkind = \"{kind}\"\nsamples = 8\nseed = 5\n[[parameters]]\nkey = \"pair.radius\"\nmin = 30e-6\nmax = 36e-6\n[[parameters]]\nkey = \"temperature.hold_time\"\nmin = 60.0\nmax = 6000.0\nlog = true\n[collect]\nsummary = [\"shrinkage\"]\n",
            case.display()
        );
        let s = dir.join(format!("{kind}.toml"));
        std::fs::write(&s, &text).unwrap();
        let opts = StudyOptions { out: Some(dir.join(kind)), ..Default::default() };
        let (_, _, plan) = study::prepare(&s, &opts).unwrap();
        let (_, _, plan2) = study::prepare(&s, &opts).unwrap();
        assert_eq!(plan, plan2, "{kind}: same seed, same plan");
        assert_eq!(plan.len(), 8);
        for r in &plan {
            let rad: f64 = r.parameters[0].1.parse().unwrap();
            let hold: f64 = r.parameters[1].1.parse().unwrap();
            assert!((30e-6..=36e-6).contains(&rad) && (60.0..=6000.0).contains(&hold), "{kind}: {r:?}");
        }
        // one point per stratum in each dimension: 8 points, 8 strata (LHS by construction, Sobol as a net)
        let mut strata: Vec<usize> = plan.iter().map(|r| ((r.parameters[1].1.parse::<f64>().unwrap() / 60.0).ln() / 100f64.ln() * 8.0) as usize).collect();
        strata.sort();
        assert_eq!(strata, (0..8).collect::<Vec<_>>(), "{kind}: log-scaled strata");
        let info = study::run_study(&s, &opts, &mut |_| {}).unwrap();
        assert_eq!(info.counts.ok, 8);
    }
}

#[test]
fn bad_study_files_name_key_value_and_range() {
    let dir = common::tmp_dir("bad");
    let case = repo().join("cases/titanium/E14B.toml");
    let cases = [
        (
            "[design]\nkind = \"lhs\"\nsamples = 0\n[[parameters]]\nkey = \"pair.radius\"\nmin = 1e-6\nmax = 2e-6\n",
            &["design.samples", "0", "[1, 1000000]"][..],
        ),
        ("[engine]\njobs = 2.5\n", &["engine.jobs", "whole number"][..]),
        ("[engin]\njobs = 2\n", &["engin: unknown key", "did you mean `engine`?"][..]),
        ("[design]\nkind = \"random\"\n", &["design.kind", "random", "grid, zip, lhs or sobol"][..]),
        ("[[parameters]]\nkey = \"pair.radius\"\nrange = [1e-6, 2e-6]\n", &["parameters.0.num", "missing"][..]),
        ("[[parameters]]\nkey = \"a\"\nvalues = [1, 2]\n[[parameters]]\nkey = \"b\"\nvalues = [1]\n[design]\nkind = \"zip\"\n", &["zip", "equal length"][..]),
        ("[slurm]\npoll_seconds = -1\n", &["slurm.poll_seconds", "-1", "s"][..]),
    ];
    for (k, (extra, want)) in cases.iter().enumerate() {
        let collect = if extra.contains("[collect]") { "" } else { "[collect]\nsummary = [\"shrinkage\"]\n" };
        let text = format!("base = \"{}\"\n{collect}{extra}", case.display());
        let s = dir.join(format!("bad{k}.toml"));
        std::fs::write(&s, &text).unwrap();
        let e = study::run_study(&s, &StudyOptions { out: Some(dir.join("o")), ..Default::default() }, &mut |_| {}).unwrap_err().to_string();
        for w in *want {
            assert!(e.contains(w), "case {k}: error \"{e}\" should contain \"{w}\"");
        }
    }
    // a syntax error names its line
    let s = dir.join("syntax.toml");
    std::fs::write(&s, "base = \"x.toml\"\n[collect\n").unwrap();
    let e = study::run_study(&s, &StudyOptions::default(), &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("line 2"), "{e}");
    // no base and no cases
    std::fs::write(&s, "[collect]\nsummary = [\"x\"]\n").unwrap();
    let e = study::run_study(&s, &StudyOptions::default(), &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("base") && e.contains("cases"), "{e}");
}

#[test]
fn slurm_engine_without_slurm_commands_says_so() {
    let dir = common::tmp_dir("noslurm");
    let s = write_small_study(&dir, "");
    let exe = env!("CARGO_BIN_EXE_sinterdem");
    let out = Command::new(exe)
        .args(["study", s.to_str().unwrap(), "--engine", "slurm", "--out", dir.join("o").to_str().unwrap()])
        .env("PATH", "/nonexistent")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("sbatch") && err.contains("not on PATH") && err.contains("--engine local"), "{err}");
}

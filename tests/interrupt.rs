//! SIGINT and SIGTERM to `sinterdem run` (a compact case; SIGINT also pair, generate and
//! explicit_sinter cases): the run stops after its current step,
//! writes its outputs with `completed = false` and `stop_reason = "interrupted"`, and exits with
//! 128 + the signal's number (docs/outputs.md "Exit codes").

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn series_rows(out: &Path) -> usize {
    std::fs::read_to_string(out.join("series.csv")).map(|s| s.lines().count()).unwrap_or(0)
}

/// Starts the flagship case (5000 s: far longer than the test), sends `signal` once the run is
/// stepping, and checks what it leaves.
fn interrupted_by(signal: &str, code: i32) {
    let out = std::env::temp_dir().join(format!("sinterdem-interrupt-{signal}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut child = Command::new(env!("CARGO_BIN_EXE_sinterdem"))
        .current_dir(root())
        .args(["run", "cases/copper-compact.toml", "-q", "--out"])
        .arg(&out)
        .args(["--set", "output.checkpoint_every=0", "--set", "output.conductivity_at=[]"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sinterdem runs");
    let t0 = Instant::now();
    while series_rows(&out) < 6 {
        assert!(t0.elapsed() < Duration::from_secs(120), "the run wrote no series rows in 120 s");
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().expect("kill runs");
    assert!(status.success());
    let t1 = Instant::now();
    let out_status = child.wait().expect("the run ends");
    assert!(t1.elapsed() < Duration::from_secs(60), "the run took {:?} to stop", t1.elapsed());
    let mut err = String::new();
    use std::io::Read;
    child.stderr.take().map(|mut e| e.read_to_string(&mut err));
    assert_eq!(out_status.code(), Some(code), "exit status {out_status:?}; stderr: {err}");
    assert!(err.contains("interrupted by signal"), "{err}");
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["completed"], serde_json::json!(false));
    assert_eq!(summary["stop_reason"], serde_json::json!("interrupted"));
    let t = summary["final_time_s"].as_f64().unwrap();
    assert!(t > 0.0 && t < 5000.0, "final time {t}");
    // series.csv ends with the row of the final state; a snapshot of it was written
    let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
    let last: f64 = series.lines().last().unwrap().split(',').next().unwrap().parse().unwrap();
    assert_eq!(last, t);
    let pvd = std::fs::read_to_string(out.join("particles.pvd")).unwrap();
    assert!(pvd.matches("<DataSet").count() >= 2, "{pvd}");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn sigint_writes_the_outputs_and_exits_130() {
    interrupted_by("INT", 130);
}

#[test]
fn sigterm_writes_the_outputs_and_exits_143() {
    interrupted_by("TERM", 143);
}

/// Starts `sinterdem run CASE` with `sets`, waits until `ready(out)`, sends SIGINT, and checks
/// the common part: exit code 130, the message, `completed = false` and `stop_reason =
/// "interrupted"` in `summary.json`. Returns the output directory and the summary.
fn sigint_after(tag: &str, case: &str, sets: &[&str], ready: impl Fn(&Path) -> bool) -> (PathBuf, serde_json::Value) {
    let out = std::env::temp_dir().join(format!("sinterdem-interrupt-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_sinterdem"));
    cmd.current_dir(root()).args(["run", case, "-q", "--out"]).arg(&out);
    for s in sets {
        cmd.args(["--set", s]);
    }
    let mut child = cmd.stdout(Stdio::null()).stderr(Stdio::piped()).spawn().expect("sinterdem runs");
    let t0 = Instant::now();
    while !ready(&out) {
        assert!(t0.elapsed() < Duration::from_secs(120), "{tag}: the run did not start in 120 s");
        std::thread::sleep(Duration::from_millis(20));
    }
    let status = Command::new("kill").args(["-INT", &child.id().to_string()]).status().expect("kill runs");
    assert!(status.success());
    let t1 = Instant::now();
    let out_status = child.wait().expect("the run ends");
    assert!(t1.elapsed() < Duration::from_secs(60), "{tag}: the run took {:?} to stop", t1.elapsed());
    let mut err = String::new();
    use std::io::Read;
    child.stderr.take().map(|mut e| e.read_to_string(&mut err));
    assert_eq!(out_status.code(), Some(130), "{tag}: exit status {out_status:?}; stderr: {err}");
    assert!(err.contains("interrupted by signal"), "{err}");
    let summary: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["completed"], serde_json::json!(false), "{tag}: {summary}");
    assert_eq!(summary["stop_reason"], serde_json::json!("interrupted"), "{tag}: {summary}");
    (out, summary)
}

fn log_has(out: &Path, text: &str) -> bool {
    std::fs::read_to_string(out.join("log.txt")).is_ok_and(|l| l.contains(text))
}

#[test]
fn sigint_stops_a_pair_run_with_its_last_state_written() {
    // Rosenbrock at rtol 1e-12 over 5e4 s: a few seconds of substeps
    let sets = ["pair.end_time=50000.0", "solver.method=\"rosenbrock4\"", "solver.rtol=1e-12", "output.plot=false"];
    let (out, s) = sigint_after("pair", "cases/pair-copper.toml", &sets, |o| o.join("log.txt").exists());
    let t = s["final_time_s"].as_f64().unwrap();
    assert!(t > 0.0 && t < 50000.0, "final time {t}");
    // series.csv ends with the state the run stopped in (written with 10 significant digits)
    let series = std::fs::read_to_string(out.join("series.csv")).unwrap();
    let last: Vec<f64> = series.lines().last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
    assert!((last[0] - t).abs() <= 1e-9 * t, "{} vs {t}", last[0]);
    let ratio = s["neck_ratio"].as_f64().unwrap();
    assert!((last[2] - ratio).abs() <= 1e-9 * ratio, "{} vs {ratio}", last[2]);
    // the neck grew from its start y1/R = 0.01 (I2, touching spheres) and is short of its end
    // (0.77 at 3.6e5 s)
    assert!(ratio > 0.010001 && ratio < 0.77, "{ratio}");
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn sigint_stops_packing_generation_with_the_packing_as_it_is() {
    let (out, s) = sigint_after("generate", "cases/green-copper.toml", &[], |o| o.join("log.txt").exists());
    assert_eq!(s["particles"], serde_json::json!(805));
    assert_eq!(s["thresholds_met"], serde_json::json!(false));
    // the packing file has every particle, with finite positions
    let packing = std::fs::read_to_string(out.join("packing.csv")).unwrap();
    let rows: Vec<&str> = packing.lines().filter(|l| !l.starts_with('#') && l.chars().next().is_some_and(|c| c.is_ascii_digit() || c == '-')).collect();
    assert_eq!(rows.len(), 805, "{}", &packing[..packing.len().min(400)]);
    assert!(rows.iter().all(|r| r.split(',').all(|x| x.trim().parse::<f64>().is_ok_and(f64::is_finite))));
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn sigint_stops_an_explicit_sinter_protocol_where_it_is() {
    let (out, s) = sigint_after("explicit", "cases/luding-sintering-time.toml", &["output.checkpoint_every=0"], |o| log_has(o, ": prepare"));
    let at = &s["stopped_at"];
    let stage = at["stage"].as_str().unwrap();
    assert!(["prepare", "heat", "sinter", "cool", "compress"].contains(&stage), "{at}");
    assert_eq!(at["pressure_Pa"], serde_json::json!(5e4));
    let steps = at["steps"].as_u64().unwrap();
    assert!(steps > 0, "{at}");
    // the history of the sample in progress: rows every 0.5 ms of its time up to where it stopped
    let name = if stage == "compress" { "compression_stopped.csv" } else { "history_stopped.csv" };
    let hist = std::fs::read_to_string(out.join(name)).unwrap();
    let rows: Vec<Vec<f64>> = hist.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect();
    assert!(!rows.is_empty(), "{hist}");
    let t_stop = at["time_s"].as_f64().unwrap();
    let t_last = rows.last().unwrap()[0];
    assert!(t_last <= t_stop && t_stop - t_last < 0.0005 + 1e-9, "last row at {t_last} s, stopped at {t_stop} s");
    // solid fractions of a loose start (0.3) compressed towards a packing
    assert!(rows.iter().all(|r| r[2] > 0.25 && r[2] < 0.75), "density column out of range");
    // the branches finished before the stop (none, unless the machine was fast) are complete
    assert!(s["branches"].as_array().unwrap().len() < 3);
    let _ = std::fs::remove_dir_all(&out);
}

/// SIGINT to `sinterdem study` (one run at a time): the run in progress stops, no new run
/// starts, the interrupted run leaves no record (it is not a result), `study.csv` is written with
/// the runs not done missing, the exit code is 130; the same command again runs exactly the
/// missing runs and ends with every run ok.
#[test]
fn sigint_stops_a_study_and_the_next_invocation_finishes_it() {
    let out = std::env::temp_dir().join(format!("sinterdem-interrupt-study-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let study = |out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_sinterdem"))
            .current_dir(root())
            .args(["study", "cases/studies/copper-temperatures.toml", "-q", "--jobs", "1", "--out"])
            .arg(out)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("sinterdem runs")
    };
    let records = |out: &Path| (0..6).filter(|i| out.join(format!("runs/{i:04}/result.json")).exists()).count();
    let mut child = study(&out);
    let t0 = Instant::now();
    while records(&out) < 1 {
        assert!(t0.elapsed() < Duration::from_secs(300), "no run record in 300 s");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{status:?}");
    let done = records(&out);
    assert!((1..6).contains(&done), "{done} records after the interrupt");
    let log = std::fs::read_to_string(out.join("executions.log")).unwrap();
    let interrupted = log.lines().filter(|l| l.starts_with("interrupted")).count();
    assert!(interrupted <= 1, "{log}");
    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    assert_eq!(csv.lines().count(), 7, "{csv}");
    let mut again = study(&out);
    assert_eq!(again.wait().unwrap().code(), Some(0));
    assert_eq!(records(&out), 6);
    let log = std::fs::read_to_string(out.join("executions.log")).unwrap();
    assert_eq!(log.lines().filter(|l| l.starts_with("start")).count(), 6 + interrupted, "each missing run once, nothing twice: {log}");
    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    let status_col = csv.lines().next().unwrap().split(',').position(|c| c == "status").unwrap();
    assert!(csv.lines().skip(1).all(|l| l.split(',').nth(status_col) == Some("ok")), "{csv}");
    let _ = std::fs::remove_dir_all(&out);
}

/// SIGINT to `sinterdem calibrate` (the bundled synthetic titanium fit, far longer than the
/// test waits): the batch in progress ends, no fit is written (no calibration.json, no
/// material.toml), the error says it was interrupted, and the exit code is 130.
#[test]
fn sigint_stops_a_calibration_without_a_fit() {
    let out = std::env::temp_dir().join(format!("sinterdem-interrupt-calib-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut child = Command::new(env!("CARGO_BIN_EXE_sinterdem"))
        .current_dir(root())
        .args(["calibrate", "cases/calibration/titanium-synthetic.toml", "-q", "--out"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sinterdem runs");
    // the output lock is taken when the fit starts
    let t0 = Instant::now();
    while !out.join(".sinterdem.lock").exists() {
        assert!(t0.elapsed() < Duration::from_secs(60), "the calibration did not start in 60 s");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    assert!(Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    let t1 = Instant::now();
    let status = child.wait().unwrap();
    assert!(t1.elapsed() < Duration::from_secs(120), "the calibration took {:?} to stop", t1.elapsed());
    let mut err = String::new();
    use std::io::Read;
    child.stderr.take().map(|mut e| e.read_to_string(&mut err));
    assert_eq!(status.code(), Some(130), "{status:?}: {err}");
    assert!(err.contains("interrupted"), "{err}");
    assert!(!out.join("calibration.json").exists() && !out.join("material.toml").exists());
    let _ = std::fs::remove_dir_all(&out);
}

/// An embedding's stop request is scoped to the call that received it (issue 38 item 3): a poll
/// saying "stop" on a thread in scope `a` stops `a`, not a run computing in scope `b` on another
/// thread, and sets nothing process-wide.
#[test]
fn a_poll_in_a_scope_stops_that_scope_only() {
    use sinterdem::interrupt::{POLL_INTERVAL, Scope, requested, set_poll};
    let (a, b) = (Scope::new(), Scope::new());
    let other = std::thread::spawn({
        let b = b.clone();
        move || {
            let _in = b.enter();
            std::thread::sleep(Duration::from_secs_f64(POLL_INTERVAL * 4.0));
            requested()
        }
    });
    {
        let _in = a.enter();
        let _poll = set_poll(Box::new(|| true));
        std::thread::sleep(Duration::from_secs_f64(POLL_INTERVAL * 1.2));
        assert!(requested(), "the poll asked");
        assert!(requested(), "the scope keeps the request");
    }
    assert!(a.requested() && !b.requested());
    assert!(!other.join().unwrap(), "the other scope's thread saw no request");
    assert!(!requested(), "nothing process-wide (this thread, out of any scope)");
}

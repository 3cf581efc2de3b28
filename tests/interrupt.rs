//! SIGINT and SIGTERM to `sinterdem run` on a compact case: the run stops after its current step,
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

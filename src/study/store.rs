//! The study directory as a store (docs/studies.md "Resuming"): the plan of runs
//! (`DIR/plan.json`), each run's output and its result record (`DIR/runs/NNNN/result.json`,
//! written atomically when the run ends, keyed by the SHA-256 of the resolved case), and the
//! execution log (`DIR/executions.log`, one `start`/`done` line per execution, appended).
//!
//! A run counts as done when its result record exists with the planned hash; a killed driver or
//! SLURM task leaves no record for the run it was executing, so that run (and only it) is run again.

use super::design::Point;
use crate::error::{Error, IoError};
use crate::kinds::{self, RunParams};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One planned run of a study.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PlannedRun {
    pub index: usize,
    /// The case file (absolute) and its label in study.csv (file stem).
    pub case_path: PathBuf,
    pub case_label: String,
    /// Parameter column → value as written in TOML.
    pub parameters: Vec<(String, String)>,
    /// Every override of the run, in order: the study's, the command line's, the parameters'.
    pub overrides: Vec<String>,
    /// SHA-256 (hex) of the resolved case, its base directory and the sinterdem version.
    pub hash: String,
}

/// The result record of one run.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunRecord {
    pub index: usize,
    pub hash: String,
    /// `ok` or `failed`.
    pub status: String,
    pub error: Option<String>,
    /// Wall time of the run API call (outputs included) [s].
    pub wall_seconds: f64,
    /// The run's summary (`summary.json`); null when it failed before one existed.
    pub summary: serde_json::Value,
}

impl RunRecord {
    pub fn ok(&self) -> bool {
        self.status == "ok"
    }
}

/// Hex SHA-256 of a byte string.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// Builds the plan: every case × every design point, with the hash of each resolved case.
pub fn plan(cases: &[PathBuf], labels_from_cases: bool, base_overrides: &[String], points: &[Point]) -> Result<Vec<PlannedRun>, Error> {
    let mut out = Vec::new();
    for case_path in cases {
        let case = crate::config::load_case(case_path, &[])?;
        let label = if labels_from_cases { case_path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default() } else { String::new() };
        for pt in points {
            let mut overrides = base_overrides.to_vec();
            let mut parameters = Vec::new();
            for (name, key, v) in pt {
                overrides.push(format!("{key}={v}"));
                parameters.push((name.clone(), value_text(v)));
            }
            let base = case_path.parent().unwrap_or(Path::new("/"));
            // the resolved case when the overrides apply; otherwise its inputs (the run then
            // fails with the override's message, recorded like any failure)
            let key = match kinds::resolve(&case, &overrides) {
                Ok(v) => toml::to_string(&v).unwrap_or_default(),
                Err(_) => format!("{}\n{}", toml::to_string(&case).unwrap_or_default(), overrides.join("\n")),
            };
            let hash = sha256_hex(format!("sinterdem {}\nbase {}\n{key}", env!("CARGO_PKG_VERSION"), base.display()).as_bytes());
            out.push(PlannedRun { index: out.len(), case_path: case_path.clone(), case_label: label.clone(), parameters, overrides, hash });
        }
    }
    Ok(out)
}

/// A TOML value as a CSV cell: numbers in shortest round-trip form, strings bare.
pub fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        toml::Value::Float(x) => format!("{x:?}"),
        other => other.to_string(),
    }
}

/// The output directory of run `index`.
pub fn run_dir(dir: &Path, index: usize) -> PathBuf {
    dir.join("runs").join(format!("{index:04}"))
}

pub use crate::io::write_atomic;

/// Writes the plan to `DIR/plan.json`.
pub fn write_plan(dir: &Path, plan: &[PlannedRun]) -> Result<(), IoError> {
    let path = dir.join("plan.json");
    let text = serde_json::to_string_pretty(plan).map_err(|e| IoError::new(&path, e))?;
    write_atomic(&path, &text)
}

/// Reads `DIR/plan.json`.
pub fn read_plan(dir: &Path) -> Result<Vec<PlannedRun>, Error> {
    let path = dir.join("plan.json");
    let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
    Ok(serde_json::from_str(&text).map_err(|e| IoError::new(&path, e))?)
}

/// The record of a run if it exists and belongs to the planned case (same hash).
pub fn read_record(dir: &Path, run: &PlannedRun) -> Option<RunRecord> {
    let text = std::fs::read_to_string(run_dir(dir, run.index).join("result.json")).ok()?;
    let rec: RunRecord = serde_json::from_str(&text).ok()?;
    (rec.hash == run.hash).then_some(rec)
}

/// Whether a run needs executing: no record, or a failed one when failures are retried.
pub fn pending(dir: &Path, run: &PlannedRun, retry_failed: bool) -> bool {
    match read_record(dir, run) {
        None => true,
        Some(r) => !r.ok() && retry_failed,
    }
}

fn log_execution(dir: &Path, line: &str) {
    let path = dir.join("executions.log");
    let _ = crate::io::manifest::record(&path);
    if let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(path) {
        // one write per line: appends of a short line are not interleaved between processes
        let _ = f.write_all(format!("{line}\n").as_bytes());
    }
}

/// Executes one run through the run API into `DIR/runs/NNNN/` and writes its record. A failure
/// (bad override, model error, even a panic) is recorded with its message, never propagated.
pub fn execute(dir: &Path, run: &PlannedRun) -> RunRecord {
    log_execution(dir, &format!("start {} {}", run.index, run.hash));
    let out = run_dir(dir, run.index);
    let _ = std::fs::remove_dir_all(&out);
    let wall = Instant::now();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| -> Result<kinds::RunSummary, Error> {
        let case = crate::config::load_case(&run.case_path, &[])?;
        let params = RunParams {
            base_dir: run.case_path.parent().unwrap_or(Path::new("/")).to_path_buf(),
            progress: false,
            echo_log: false,
            plots: false,
            wall_limit: None,
            // the study owns its run directories (removed above; a leftover is this run's own)
            force: true,
        };
        kinds::run(&case, &run.overrides, &out, &params)
    }));
    let (status, error, summary) = match result {
        Ok(Ok(s)) => ("ok", None, s.summary),
        Ok(Err(e)) => ("failed", Some(e.to_string()), serde_json::Value::Null),
        Err(p) => {
            let msg = p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_else(|| "unknown panic".into());
            ("failed", Some(format!("internal error (panic): {msg}")), serde_json::Value::Null)
        }
    };
    let rec = RunRecord { index: run.index, hash: run.hash.clone(), status: status.into(), error, wall_seconds: wall.elapsed().as_secs_f64(), summary };
    // a run stopped by Ctrl-C/SIGTERM (its summary says completed = false, or its error is the
    // stop) is not a result: no record, so the next invocation of the study runs it again
    if crate::interrupt::requested() {
        log_execution(dir, &format!("interrupted {} {}", run.index, run.hash));
        return RunRecord { status: "interrupted".into(), ..rec };
    }
    let _ = std::fs::create_dir_all(&out);
    match serde_json::to_string(&rec) {
        Ok(text) => {
            if let Err(e) = write_atomic(&out.join("result.json"), &text) {
                log_execution(dir, &format!("error {} {}: {e}", run.index, run.hash));
            }
        }
        Err(e) => log_execution(dir, &format!("error {} {}: {e}", run.index, run.hash)),
    }
    log_execution(dir, &format!("done {} {} {}", run.index, run.hash, status));
    rec
}

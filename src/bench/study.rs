//! `sinterdem bench study`: a pair study of N runs (the E14B titanium pair over a range of
//! radii) on the local engine, from scratch; prints the wall time and where it goes per run:
//! the integration itself, the rest of the run API (parsing, series.csv, summary.json, log) and
//! the engine around it (planning, hashing, result records, gathering, study.csv, plots).

use crate::error::{Error, IoError};
use crate::study::{StudyOptions, run_study, store};
use std::fmt::Write as _;
use std::path::Path;

/// Runs the benchmark study in `out` (emptied first) and returns the report.
pub fn bench_study(runs: usize, jobs: Option<usize>, out: &Path) -> Result<String, Error> {
    let _ = std::fs::remove_dir_all(out);
    crate::io::ensure_dir(out)?;
    let case = crate::kinds::titanium::Experiment::by_id("E14B").map(|e| e.case_toml()).unwrap_or_default();
    let case_path = out.join("e14b.toml");
    std::fs::write(&case_path, case).map_err(|e| IoError::new(&case_path, e))?;
    let study = format!(
        "title = \"bench: {runs} E14B pairs\"\nbase = \"e14b.toml\"\n[[parameters]]\nkey = \"pair.radius\"\nrange = [30e-6, 36e-6]\nnum = {runs}\n[collect]\nsummary = [\"neck_ratio\", \"shrinkage\"]\nseries = [{{ column = \"neck_ratio\", times = [3600.0] }}]\n"
    );
    let study_path = out.join("study.toml");
    std::fs::write(&study_path, study).map_err(|e| IoError::new(&study_path, e))?;
    let dir = out.join("study");
    let opts = StudyOptions { jobs, out: Some(dir.clone()), ..Default::default() };
    let info = run_study(&study_path, &opts, &mut |_| {})?;
    let plan = store::read_plan(&dir)?;
    let recs: Vec<store::RunRecord> = plan.iter().filter_map(|r| store::read_record(&dir, r)).collect();
    let n = recs.len().max(1) as f64;
    let api: f64 = recs.iter().map(|r| r.wall_seconds).sum();
    let integ: f64 = recs.iter().filter_map(|r| r.summary["wall_seconds"].as_f64()).sum();
    let jobs_used = jobs.filter(|&j| j > 0).unwrap_or_else(|| crate::study::local::default_jobs(1)) as f64;
    let mut s = String::new();
    let _ = writeln!(s, "# sinterdem bench study: {runs} E14B pair runs, local engine, {jobs_used} at a time");
    let _ = writeln!(s, "runs ok/failed            {}/{}", info.counts.ok, info.counts.failed);
    let _ = writeln!(s, "wall                      {:.3} s ({:.0} runs/s)", info.wall_seconds, n / info.wall_seconds);
    let _ = writeln!(s, "integration per run       {:.1} µs", 1e6 * integ / n);
    let _ = writeln!(s, "run API around it per run {:.1} µs (parse, series.csv, summary.json, log.txt)", 1e6 * (api - integ) / n);
    let _ = writeln!(
        s,
        "engine overhead per run   {:.1} µs (wall × jobs − Σ run API, over runs: plan, hash, records, gather, csv, plots)",
        1e6 * (info.wall_seconds * jobs_used - api) / n
    );
    Ok(s)
}

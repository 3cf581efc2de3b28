//! The SLURM engine against a real single-node SLURM cluster on localhost (slurmctld, slurmd,
//! munged), started by `scripts/slurm-local.sh` (which installs Debian's packages when root):
//! the same study through `--engine slurm --wait` gives the local engine's study.csv, and an array
//! task cancelled with `scancel` is resubmitted and the study completes with no run done twice.
//!
//! `scripts/test-all.sh` starts the cluster once and passes `SINTERDEM_SLURM_DIR`; run alone, the
//! test starts (and stops) its own. Where the cluster cannot be started (not root, no apt-get),
//! the test says why and is skipped; the test command prints that line too.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
mod slurm_cluster;
use slurm_cluster::{Cluster, repo};

fn cluster() -> Option<Cluster> {
    slurm_cluster::cluster("slurm engine test", "slurm")
}

fn csv_without_wall(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let w = header.iter().position(|h| *h == "wall_seconds").unwrap();
    assert_eq!(w, header.len() - 1, "wall_seconds is the last column");
    text.lines().map(|l| l.rsplit_once(',').map(|x| x.0.to_string()).unwrap_or_default()).collect()
}

fn done_counts(dir: &Path) -> HashMap<String, usize> {
    let text = std::fs::read_to_string(dir.join("executions.log")).unwrap_or_default();
    let mut m = HashMap::new();
    for l in text.lines().filter(|l| l.starts_with("done ")) {
        *m.entry(l.split(' ').nth(2).unwrap().to_string()).or_insert(0) += 1;
    }
    m
}

fn study_file(dir: &Path, runs: usize) -> PathBuf {
    let case = repo().join("cases/titanium/E14B.toml");
    let text = format!(
        "title = \"slurm test\"\nbase = \"{}\"\noverrides = [\"solver.rtol=1e-9\"]\n[[parameters]]\nkey = \"pair.radius\"\nrange = [30e-6, 36e-6]\nnum = {runs}\n[collect]\nsummary = [\"neck_ratio\", \"shrinkage\", \"steps\"]\nseries = [{{ column = \"neck_ratio\", times = [2000.0] }}]\n[slurm]\npoll_seconds = 0.5\npartition = \"debug\"\ntime = \"00:10:00\"\n",
        case.display()
    );
    let p = dir.join(format!("study{runs}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

fn sinterdem(cluster: &Cluster, args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_sinterdem")).args(args).env("SLURM_CONF", cluster.conf()).output().unwrap();
    eprintln!("$ sinterdem {}\n{}", args.join(" "), String::from_utf8_lossy(&out.stderr));
    out
}

#[test]
fn slurm_engine_matches_local_and_resubmits_a_cancelled_task() {
    let Some(cluster) = cluster() else { return };
    let dir = common::tmp_dir("engines");

    // 1. the same study on both engines: byte-identical study.csv apart from wall times
    let s = study_file(&dir, 6);
    let local = dir.join("local");
    let out = sinterdem(&cluster, &["study", s.to_str().unwrap(), "--quiet", "--out", local.to_str().unwrap()]);
    assert!(out.status.success());
    let remote = dir.join("slurm");
    let t0 = std::time::Instant::now();
    let out = sinterdem(&cluster, &["study", s.to_str().unwrap(), "--engine", "slurm", "--wait", "--chunk", "2", "--out", remote.to_str().unwrap()]);
    assert!(out.status.success());
    eprintln!("slurm engine: 6 runs in 3 array tasks, {:.1} s", t0.elapsed().as_secs_f64());
    assert_eq!(csv_without_wall(&remote.join("study.csv")), csv_without_wall(&local.join("study.csv")));
    let batch: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(remote.join("slurm/batch-0.json")).unwrap()).unwrap();
    assert_eq!(batch["chunks"].as_array().unwrap().len(), 3, "chunk = 2 over 6 runs gives 3 array tasks");
    assert!(done_counts(&remote).values().all(|&c| c == 1));

    // 2. submit without waiting, cancel one (still pending) array task, then wait: the lost
    // runs are resubmitted and the study completes, each run done once
    let s = study_file(&dir, 8);
    let d2 = dir.join("cancel");
    let out = sinterdem(&cluster, &["study", s.to_str().unwrap(), "--engine", "slurm", "--chunk", "1", "--out", d2.to_str().unwrap()]);
    assert!(out.status.success());
    assert!(!d2.join("study.csv").exists(), "without --wait nothing is gathered while the job runs");
    let batch: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d2.join("slurm/batch-0.json")).unwrap()).unwrap();
    let job = batch["job_id"].as_str().unwrap().to_string();
    let st = Command::new("scancel").arg(format!("{job}_7")).env("SLURM_CONF", cluster.conf()).status().unwrap();
    assert!(st.success());
    let out = sinterdem(&cluster, &["study", s.to_str().unwrap(), "--engine", "slurm", "--wait", "--chunk", "1", "--out", d2.to_str().unwrap()]);
    assert!(out.status.success());
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(log.contains("resubmitted"), "the cancelled task's run is resubmitted: {log}");
    assert!(d2.join("slurm/batch-1.json").exists());
    let counts = done_counts(&d2);
    assert_eq!(counts.len(), 8, "every run has a result");
    assert!(counts.values().all(|&c| c == 1), "no run done twice: {counts:?}");
    let text = std::fs::read_to_string(d2.join("study.csv")).unwrap();
    assert_eq!(text.lines().count(), 9);
    assert_eq!(text.lines().skip(1).filter(|l| l.contains(",ok,")).count(), 8);
}

//! The SLURM engine: the unfinished runs of a study go out as one job array (`sbatch --array`),
//! each array task running a chunk of runs through the hidden `sinterdem study-task` subcommand,
//! which writes into the study directory on the shared file system exactly what the local engine
//! writes. With `--wait` the driver polls `squeue` until the array has left the queue, then
//! resubmits the runs that still have no result record (a task cancelled, killed by its time
//! limit or lost with its node) up to `slurm.max_resubmit` times, and gathers. No accounting
//! daemon (`sacct`) is needed: the result records are the truth.

use super::StudyOptions;
use super::spec::Study;
use super::store::{self, PlannedRun};
use crate::error::{ConfigError, Error, IoError, SolveError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// SLURM settings from the command line (each overrides the study file's `[slurm]` key).
#[derive(Debug, Clone, Default)]
pub struct SlurmOverrides {
    pub partition: Option<String>,
    pub time: Option<String>,
    pub account: Option<String>,
    pub cpus_per_task: Option<usize>,
    pub chunk: Option<usize>,
    pub extra: Vec<String>,
}

/// One submission: a job array over chunks of runs (`DIR/slurm/batch-N.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Batch {
    pub batch: usize,
    pub job_id: String,
    /// Run indices of each array task.
    pub chunks: Vec<Vec<usize>>,
    pub retry_failed: bool,
}

/// Target wall time of one array task [s]: long enough that scheduling overhead is small.
const TASK_SECONDS: f64 = 300.0;

fn which(cmd: &str) -> Option<PathBuf> {
    std::env::var_os("PATH").and_then(|p| std::env::split_paths(&p).map(|d| d.join(cmd)).find(|f| f.is_file()))
}

/// Estimated wall time of one run [s]: the mean of the runs done so far, else by kind.
fn estimate_run_seconds(dir: &Path, plan: &[PlannedRun]) -> f64 {
    let walls: Vec<f64> = plan.iter().filter_map(|r| store::read_record(dir, r)).map(|r| r.wall_seconds).collect();
    if !walls.is_empty() {
        return walls.iter().sum::<f64>() / walls.len() as f64;
    }
    let kind = plan.first().and_then(|r| crate::config::load_case(&r.case_path, &[]).ok()).and_then(|v| crate::kinds::Kind::of(&v).ok());
    match kind {
        Some(crate::kinds::Kind::Pair) => 0.01,
        _ => 60.0,
    }
}

fn slurm_dir(dir: &Path) -> PathBuf {
    dir.join("slurm")
}

fn read_batches(dir: &Path) -> Vec<Batch> {
    let mut out = Vec::new();
    for n in 0.. {
        let p = slurm_dir(dir).join(format!("batch-{n}.json"));
        match std::fs::read_to_string(&p).ok().and_then(|t| serde_json::from_str::<Batch>(&t).ok()) {
            Some(b) => out.push(b),
            None => break,
        }
    }
    out
}

/// Job ids of `ids` still known to `squeue` (pending, running, completing).
fn active_jobs(ids: &[String]) -> Result<Vec<String>, Error> {
    if ids.is_empty() {
        return Ok(vec![]);
    }
    let out = Command::new("squeue")
        .args(["-h", "-o", "%F", "-j", &ids.join(",")])
        .output()
        .map_err(|e| SolveError::new("slurm", format!("squeue could not be started: {e}")))?;
    let text = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        // jobs purged from the controller are reported as invalid: they are gone
        if err.contains("Invalid job id") {
            return Ok(vec![]);
        }
        return Err(SolveError::new("slurm", format!("squeue failed: {}", err.trim())).into());
    }
    let mut act: Vec<String> = text.lines().map(|l| l.trim().to_string()).filter(|l| !l.is_empty()).collect();
    act.sort();
    act.dedup();
    Ok(act)
}

/// Writes the job script and submits it; returns the batch.
fn submit(study: &Study, dir: &Path, todo: &[usize], chunk: usize, retry_failed: bool, opts: &StudyOptions, n: usize) -> Result<Batch, Error> {
    let sdir = slurm_dir(dir);
    crate::io::ensure_dir(&sdir)?;
    let chunks: Vec<Vec<usize>> = todo.chunks(chunk.max(1)).map(|c| c.to_vec()).collect();
    let s = &study.slurm;
    let o = &opts.slurm;
    let exe = std::env::current_exe().map_err(|e| SolveError::new("slurm", format!("cannot locate the sinterdem binary: {e}")))?;
    let cpus = o.cpus_per_task.unwrap_or(s.cpus_per_task);
    let mut script = String::from("#!/bin/bash\n");
    script.push_str(&format!("#SBATCH --job-name=sinterdem-study\n#SBATCH --array=0-{}\n", chunks.len() - 1));
    script.push_str(&format!("#SBATCH --output={}/task-{n}-%a.out\n", sdir.display()));
    script.push_str(&format!("#SBATCH --cpus-per-task={cpus}\n"));
    for (flag, v) in [
        ("partition", o.partition.as_ref().or(s.partition.as_ref())),
        ("time", o.time.as_ref().or(s.time.as_ref())),
        ("account", o.account.as_ref().or(s.account.as_ref())),
    ] {
        if let Some(v) = v.filter(|v| !v.is_empty()) {
            if v.contains(['\n', ' ']) {
                return Err(ConfigError::invalid(format!("slurm.{flag} = \"{v}\": must be one word")).into());
            }
            script.push_str(&format!("#SBATCH --{flag}={v}\n"));
        }
    }
    for line in s.extra.iter().chain(&o.extra) {
        let l = line.trim();
        if l.contains('\n') {
            return Err(ConfigError::invalid(format!("slurm.extra line \"{l}\": one line each")).into());
        }
        script.push_str(&if l.starts_with("#SBATCH") { format!("{l}\n") } else { format!("#SBATCH {l}\n") });
    }
    script.push_str(&format!(
        "exec \"{}\" study-task \"{}\" --batch {n} --task \"$SLURM_ARRAY_TASK_ID\" --threads \"${{SLURM_CPUS_PER_TASK:-{cpus}}}\"\n",
        exe.display(),
        dir.display()
    ));
    let job = sdir.join(format!("job-{n}.sh"));
    crate::io::manifest::record(&job)?;
    std::fs::write(&job, &script).map_err(|e| IoError::new(&job, e))?;
    // the batch file exists before the tasks can start
    let mut batch = Batch { batch: n, job_id: String::new(), chunks, retry_failed };
    let bpath = sdir.join(format!("batch-{n}.json"));
    store::write_atomic(&bpath, &serde_json::to_string_pretty(&batch).map_err(|e| IoError::new(&bpath, e))?)?;
    let out = Command::new("sbatch")
        .args(["--parsable", "--chdir"])
        .arg(dir)
        .arg(&job)
        .output()
        .map_err(|e| SolveError::new("slurm", format!("sbatch could not be started: {e}")))?;
    if !out.status.success() {
        let _ = std::fs::remove_file(&bpath);
        return Err(SolveError::new("slurm", format!("sbatch {} failed: {}", job.display(), String::from_utf8_lossy(&out.stderr).trim())).into());
    }
    batch.job_id = String::from_utf8_lossy(&out.stdout).trim().split(';').next().unwrap_or("").to_string();
    store::write_atomic(&bpath, &serde_json::to_string_pretty(&batch).map_err(|e| IoError::new(&bpath, e))?)?;
    Ok(batch)
}

/// Submits the unfinished runs (unless a job of this study is still queued) and, with `--wait`,
/// waits, resubmits lost work and reports that the study can be gathered. Returns (runs
/// submitted, gather now).
pub fn run(study: &Study, dir: &Path, plan: &[PlannedRun], todo: &[usize], opts: &StudyOptions, log: &mut dyn FnMut(&str)) -> Result<(usize, bool), Error> {
    for cmd in ["sbatch", "squeue"] {
        if which(cmd).is_none() {
            return Err(SolveError::new(
                "slurm",
                format!("`{cmd}` is not on PATH: the SLURM client commands are needed for --engine slurm (Debian: slurm-client), or use --engine local"),
            )
            .into());
        }
    }
    let dir = dir.canonicalize().map_err(|e| IoError::new(dir, e))?;
    let dir = dir.as_path();
    let chunk = opts
        .slurm
        .chunk
        .or(study.slurm.chunk)
        .unwrap_or_else(|| ((TASK_SECONDS / estimate_run_seconds(dir, plan)).ceil() as usize).clamp(1, todo.len().max(1)));
    let mut batches = read_batches(dir);
    let ids: Vec<String> = batches.iter().map(|b| b.job_id.clone()).collect();
    let mut active = active_jobs(&ids)?;
    let mut submitted = 0;
    if !active.is_empty() {
        log(&format!("slurm: job(s) {} of this study are still queued: not submitting again", active.join(", ")));
    } else if !todo.is_empty() {
        let b = submit(study, dir, todo, chunk, opts.retry_failed, opts, batches.len())?;
        log(&format!("slurm: submitted job {} ({} array tasks of ≤ {chunk} runs, {} runs)", b.job_id, b.chunks.len(), todo.len()));
        submitted = todo.len();
        active = vec![b.job_id.clone()];
        batches.push(b);
    }
    if !opts.wait {
        if !active.is_empty() {
            log("slurm: not waiting (no --wait); run the same command with --wait to wait, resubmit lost tasks and gather study.csv");
            return Ok((submitted, false));
        }
        return Ok((submitted, true));
    }
    let poll = Duration::from_secs_f64(study.slurm.poll_seconds.max(0.05));
    let mut resubmits = 0;
    let start = Instant::now();
    loop {
        let ids: Vec<String> = batches.iter().map(|b| b.job_id.clone()).collect();
        while !active_jobs(&ids)?.is_empty() {
            std::thread::sleep(poll);
        }
        let left: Vec<usize> = plan.iter().filter(|r| store::pending(dir, r, false)).map(|r| r.index).collect();
        if left.is_empty() {
            log(&format!(
                "slurm: all runs have results after {:.1} s ({} submission{})",
                start.elapsed().as_secs_f64(),
                batches.len(),
                if batches.len() == 1 { "" } else { "s" }
            ));
            return Ok((submitted, true));
        }
        if resubmits >= study.slurm.max_resubmit {
            log(&format!(
                "slurm: {} runs still have no result after {resubmits} resubmissions (slurm.max_resubmit): gathering what there is; see DIR/slurm/task-*.out",
                left.len()
            ));
            return Ok((submitted, true));
        }
        resubmits += 1;
        let b = submit(study, dir, &left, chunk, false, opts, batches.len())?;
        log(&format!(
            "slurm: {} runs had no result (task cancelled, timed out or lost): resubmitted as job {} ({} tasks)",
            left.len(),
            b.job_id,
            b.chunks.len()
        ));
        submitted += left.len();
        batches.push(b);
    }
}

/// The hidden `sinterdem study-task DIR --batch N --task K`: runs chunk K of batch N (skipping
/// runs that already have a result) with `threads` rayon threads.
pub fn run_task(dir: &Path, batch: usize, task: usize, threads: usize) -> Result<usize, Error> {
    let bpath = slurm_dir(dir).join(format!("batch-{batch}.json"));
    let text = std::fs::read_to_string(&bpath).map_err(|e| IoError::new(&bpath, e))?;
    let b: Batch = serde_json::from_str(&text).map_err(|e| IoError::new(&bpath, e))?;
    let chunk = b.chunks.get(task).ok_or_else(|| ConfigError::invalid(format!("{}: no task {task} (the batch has {})", bpath.display(), b.chunks.len())))?;
    let plan = store::read_plan(dir)?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build().map_err(|e| SolveError::new("study task", e.to_string()))?;
    let mut n = 0;
    for &i in chunk {
        let run = plan.get(i).ok_or_else(|| ConfigError::invalid(format!("run {i} is not in {}", dir.join("plan.json").display())))?;
        if store::pending(dir, run, b.retry_failed) {
            let rec = pool.install(|| store::execute(dir, run));
            tracing::info!("run {i}: {}{}", rec.status, rec.error.map(|e| format!(": {e}")).unwrap_or_default());
            n += 1;
        }
    }
    Ok(n)
}

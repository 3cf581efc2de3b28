//! Studies: many runs of one or more cases over a design of parameters, executed through the run
//! API ([`crate::kinds`]) by the embedded local engine or as a SLURM job array, resumable and
//! idempotent (docs/studies.md).
//!
//! `sinterdem study STUDY.toml [--engine local|slurm] [--jobs N] [--out DIR] [--wait] [--retry-failed]`:
//! 1. [`spec::load`] validates the study file; [`design::points`] expands the design;
//! 2. [`store::plan`] resolves every run (case × point) and hashes it; `DIR/plan.json`;
//! 3. the runs without a result record are executed ([`local`] or [`slurm`]);
//! 4. [`report`] gathers `study.csv`, `study.json` and the plots.

pub mod design;
pub mod local;
pub mod report;
pub mod slurm;
pub mod spec;
pub mod store;

use crate::error::{ConfigError, Error, IoError};
use std::path::{Path, PathBuf};

/// Which engine executes the runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Engine {
    /// In-process, N runs at a time (default).
    Local,
    /// A SLURM job array on the study directory's (shared) file system.
    Slurm,
}

/// Command-line options of `sinterdem study`.
#[derive(Debug, Clone)]
pub struct StudyOptions {
    pub engine: Engine,
    /// Runs at a time on the local engine (overrides `engine.jobs`).
    pub jobs: Option<usize>,
    /// Output directory (default `out/<study file stem>`).
    pub out: Option<PathBuf>,
    /// SLURM: wait for the array, resubmit lost tasks and gather.
    pub wait: bool,
    /// Run failed runs again.
    pub retry_failed: bool,
    /// `--set` overrides applied to every run (after the study's own).
    pub overrides: Vec<String>,
    /// Progress bar on a terminal.
    pub progress: bool,
    /// SLURM settings given on the command line (override the study file's).
    pub slurm: slurm::SlurmOverrides,
    /// Write `DIR/plots/` when gathering (default true; a calibration's batches turn it off).
    pub plots: bool,
    /// Remove the outputs of an earlier command in the directory first (`--force`); without it a
    /// directory holding a run's or calibration's outputs is refused, a study's own continued.
    pub force: bool,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            engine: Engine::Local,
            jobs: None,
            out: None,
            wait: false,
            retry_failed: false,
            overrides: vec![],
            progress: false,
            slurm: Default::default(),
            plots: true,
            force: false,
        }
    }
}

/// What a study reports when it returns.
#[derive(Debug, Clone)]
pub struct StudyInfo {
    pub dir: PathBuf,
    pub counts: report::Counts,
    /// Runs executed by this invocation (not those found done).
    pub executed: usize,
    /// Whether study.csv was (re)written.
    pub gathered: bool,
    pub wall_seconds: f64,
}

/// The plan of a study file: validated study, output directory and planned runs.
pub fn prepare(path: &Path, opts: &StudyOptions) -> Result<(spec::Study, PathBuf, Vec<store::PlannedRun>), Error> {
    let study = spec::load(path)?;
    let dir = opts.out.clone().unwrap_or_else(|| PathBuf::from("out").join(path.file_stem().unwrap_or_default()));
    for o in &opts.overrides {
        if !o.contains('=') {
            return Err(ConfigError::invalid(format!("--set {o}: expected key.path=value")).into());
        }
    }
    let points = design::points(&study.parameters, study.design);
    let mut overrides = study.overrides.clone();
    overrides.extend(opts.overrides.iter().cloned());
    let plan = store::plan(&study.cases, study.case_column, &overrides, &points)?;
    Ok((study, dir, plan))
}

/// Runs (or continues) a study and gathers its results.
pub fn run_study(path: &Path, opts: &StudyOptions, log: &mut dyn FnMut(&str)) -> Result<StudyInfo, Error> {
    let wall = std::time::Instant::now();
    let (study, dir, plan) = prepare(path, opts)?;
    let lock = crate::io::lock::OutputLock::acquire(&dir, "study")?;
    if let Some(note) = lock.takeover_note() {
        log(&note);
    }
    // a study continues its own directory; another command's outputs need --force
    // (docs/outputs.md "Guarantees")
    if let Some(note) = crate::io::outdir::claim(&dir, crate::io::outdir::Claimant::Study, opts.force, None, &study.cases)? {
        log(&note);
    }
    store::write_plan(&dir, &plan)?;
    let todo: Vec<usize> = plan.iter().filter(|r| store::pending(&dir, r, opts.retry_failed)).map(|r| r.index).collect();
    log(&format!(
        "study \"{}\": {} runs ({} case file{} × {} point{}), {} to run, {} done before → {}",
        study.title,
        plan.len(),
        study.cases.len(),
        if study.cases.len() == 1 { "" } else { "s" },
        plan.len() / study.cases.len().max(1),
        if plan.len() / study.cases.len().max(1) == 1 { "" } else { "s" },
        todo.len(),
        plan.len() - todo.len(),
        dir.display()
    ));
    let (executed, gather) = match opts.engine {
        Engine::Local => {
            let jobs = opts.jobs.filter(|&j| j > 0).unwrap_or(study.jobs);
            let n = local::run(&dir, &plan, &todo, jobs, study.threads, opts.progress, log)?;
            (n, true)
        }
        Engine::Slurm => slurm::run(&study, &dir, &plan, &todo, opts, log)?,
    };
    let mut counts = report::Counts::default();
    if gather {
        let rows = report::gather(&study, &dir, &plan);
        counts = report::write(&study, &dir, &rows, opts.plots)?;
        log(&format!(
            "study.csv: {} runs, {} ok, {} failed, {} missing ({} executed now) in {:.2} s",
            counts.runs,
            counts.ok,
            counts.failed,
            counts.missing,
            executed,
            wall.elapsed().as_secs_f64()
        ));
        // what the runs warned about (each run's log.txt) and collected cells left empty
        for w in run_warnings(&dir, &rows).into_iter().chain(empty_series_cells(&study, &dir, &rows)) {
            log(&format!("warning: {w}"));
        }
        for r in rows.iter().filter(|r| r.record.as_ref().is_some_and(|x| !x.ok())).take(5) {
            log(&format!("  run {} failed: {}", r.run.index, r.record.as_ref().and_then(|x| x.error.clone()).unwrap_or_default()));
        }
        // the local engine executed every pending run: a run without its record is a record that
        // could not be written (a full disk, permissions), an error and not a study that ended well
        // (an interrupted study: the runs not done are missing by design, and rerunning the study
        // runs them; the command line exits with the signal's code)
        if crate::interrupt::requested() {
            log(&format!("study interrupted: {} of {} runs have no record yet; run the study again to finish them", counts.missing, counts.runs));
        } else if matches!(opts.engine, Engine::Local) && counts.missing > 0 {
            return Err(IoError::new(
                dir.join("runs"),
                format!("{} of {} run records (runs/NNNN/result.json) could not be written; see executions.log", counts.missing, counts.runs),
            )
            .into());
        }
    }
    Ok(StudyInfo { dir, counts, executed, gathered: gather, wall_seconds: wall.elapsed().as_secs_f64() })
}

/// The distinct warnings of the study's runs (the `warning: …` lines of each `runs/NNNN/log.txt`),
/// each with the number of runs and the first run that gave it; at most 10 (issue 25: the runs of a
/// study log to their own files, so their warnings would otherwise never reach the console).
fn run_warnings(dir: &Path, rows: &[report::Row]) -> Vec<String> {
    let mut seen: Vec<(String, usize, usize)> = Vec::new();
    for r in rows.iter().filter(|r| r.record.is_some()) {
        let Ok(text) = std::fs::read_to_string(store::run_dir(dir, r.run.index).join("log.txt")) else { continue };
        let mut mine: Vec<&str> = text.lines().filter_map(|l| l.strip_prefix("warning: ")).collect();
        mine.dedup();
        for w in mine {
            match seen.iter_mut().find(|(x, _, _)| x == w) {
                Some(e) => e.1 += 1,
                None => seen.push((w.to_string(), 1, r.run.index)),
            }
        }
    }
    let total = seen.len();
    let mut out: Vec<String> = seen
        .into_iter()
        .take(10)
        .map(|(w, n, first)| format!("{n} run{} (first run {first:04}, runs/{first:04}/log.txt): {w}", if n == 1 { "" } else { "s" }))
        .collect();
    if total > 10 {
        out.push(format!("{} more distinct run warnings in runs/*/log.txt", total - 10));
    }
    out
}

/// A message per collected series column and time whose cell is empty in some runs that
/// succeeded: the time lies past the end of their series (or before its start), or the column
/// is not in their series.csv (issue 25: an empty column and no word about it before).
fn empty_series_cells(study: &spec::Study, dir: &Path, rows: &[report::Row]) -> Vec<String> {
    let ok: Vec<&report::Row> = rows.iter().filter(|r| r.record.as_ref().is_some_and(|x| x.ok())).collect();
    let mut out = Vec::new();
    for s in &study.collect_series {
        for &t in &s.times {
            let key = format!("{}_at_{t}s", s.column);
            let empty: Vec<&&report::Row> = ok.iter().filter(|r| r.outputs.iter().any(|(k, v)| *k == key && v.is_empty())).collect();
            let Some(first) = empty.first() else { continue };
            let why = match report::read_series(&store::run_dir(dir, first.run.index).join("series.csv")) {
                None => "the run wrote no series.csv".to_string(),
                Some((h, _)) if !h.contains(&s.column) => format!("series.csv has no column `{}` (columns: {})", s.column, h.join(", ")),
                Some((_, rows)) => {
                    let (a, b) = (rows.first().map_or(f64::NAN, |r| r[0]), rows.last().map_or(f64::NAN, |r| r[0]));
                    format!(
                        "t = {} s is outside the run's series, {} s to {} s (its time.end): collect at most the runs' end time",
                        crate::error::fmt_value(t),
                        crate::error::fmt_value(a),
                        crate::error::fmt_value(b)
                    )
                }
            };
            out.push(format!("study.csv column {key} is empty for {} of {} successful runs (first run {:04}): {why}", empty.len(), ok.len(), first.run.index));
        }
    }
    out
}

//! One run API for every kind of case (docs/studies.md "The run API").
//!
//! [`run`] takes a parsed case, the `key.path=value` overrides of `--set` and an output directory,
//! runs the case whatever its `kind` (`heat`, `pair`, `compact`, `explicit_sinter`, `generate`) and
//! returns a [`RunSummary`]: the fields that `DIR/summary.json` gets, with the kind and wall time.
//! `sinterdem run`, `resume`, `check`, `study`, the benches and `calibrate` all go through here,
//! so a run inside a study is exactly the run a user starts alone.

pub mod compact;
pub mod conductivity;
pub mod explicit_sinter;
pub mod generate;
pub mod heat;
pub mod keys;
pub mod pair;
pub mod rve;
pub mod state;
pub mod stepper;
pub mod titanium;

use crate::config;
use crate::error::{ConfigError, Error, IoError};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

pub use stepper::Stepper;

/// The kind of a case (`kind = "…"`, default `heat`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    Heat,
    Pair,
    Compact,
    ExplicitSinter,
    Generate,
}

impl Kind {
    /// The kind named by a case's `kind` key.
    pub fn of(case: &toml::Value) -> Result<Kind, ConfigError> {
        let name = match case.get("kind") {
            None => "heat",
            Some(toml::Value::String(s)) => s.as_str(),
            Some(v) => return Err(ConfigError::invalid(format!("kind = {v}: expected a string (heat, compact, pair, generate or explicit_sinter)"))),
        };
        Ok(match name {
            "heat" => Kind::Heat,
            "pair" => Kind::Pair,
            "compact" => Kind::Compact,
            "explicit_sinter" => Kind::ExplicitSinter,
            "generate" => Kind::Generate,
            "calibration" => {
                return Err(ConfigError::invalid(
                    "kind = \"calibration\": a calibration file, not a case: fit it with `sinterdem calibrate FILE --out DIR`, validate it with `sinterdem check FILE`",
                ));
            }
            k => return Err(ConfigError::invalid(format!("kind = \"{k}\": expected heat, compact, pair, generate or explicit_sinter"))),
        })
    }

    /// The name as written in a case file.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Heat => "heat",
            Kind::Pair => "pair",
            Kind::Compact => "compact",
            Kind::ExplicitSinter => "explicit_sinter",
            Kind::Generate => "generate",
        }
    }
}

/// How a run is carried out (not what is simulated: that is the case).
#[derive(Debug, Clone)]
pub struct RunParams {
    /// Directory that relative paths in the case (packing files, includes) resolve against:
    /// the case file's folder.
    pub base_dir: PathBuf,
    /// Show a progress bar (on a terminal only).
    pub progress: bool,
    /// Copy log lines to stderr as well as to `DIR/log.txt`.
    pub echo_log: bool,
    /// Write PNG plots. Studies turn them off: a plot costs more than a pair run.
    pub plots: bool,
    /// Wall-time budget [s] of a compact run: it stops with `completed = false` and the reason
    /// in `stop_reason` once exceeded (None: unlimited).
    pub wall_limit: Option<f64>,
    /// Remove the outputs of an earlier command in the output directory before writing (`--force`);
    /// without it such a directory is refused ([`crate::io::outdir::claim`]).
    pub force: bool,
}

impl Default for RunParams {
    fn default() -> Self {
        RunParams { base_dir: PathBuf::from("."), progress: false, echo_log: false, plots: true, wall_limit: None, force: false }
    }
}

/// What a run returns: the fields of its `summary.json`, its kind and its wall time.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunSummary {
    pub kind: Kind,
    /// Wall time of the whole run, outputs included [s].
    pub wall_seconds: f64,
    /// The summary (as written to `DIR/summary.json`).
    pub summary: serde_json::Value,
}

impl RunSummary {
    /// A summary value by dotted path (`mechanics.factorizations`, `layer_neck_ratio.2`).
    pub fn get(&self, path: &str) -> Option<&serde_json::Value> {
        lookup(&self.summary, path)
    }

    /// A numeric summary value by dotted path.
    pub fn f64(&self, path: &str) -> Option<f64> {
        self.get(path).and_then(|v| v.as_f64())
    }
}

pub use crate::config::is_calibration;

/// A value of a JSON tree by dotted path; array elements by index.
pub fn lookup<'a>(v: &'a serde_json::Value, path: &str) -> Option<&'a serde_json::Value> {
    path.split('.').try_fold(v, |cur, k| match cur {
        serde_json::Value::Object(m) => m.get(k),
        serde_json::Value::Array(a) => k.parse::<usize>().ok().and_then(|i| a.get(i)),
        _ => None,
    })
}

/// The case with the overrides applied (what a run actually runs).
pub fn resolve(case: &toml::Value, overrides: &[String]) -> Result<toml::Value, ConfigError> {
    resolve_noting(case, overrides).map(|(v, _)| v)
}

/// [`resolve`], with the log line of a defaulted end time (`time.end` omitted: the end of the
/// heating profile, [`config::plausible::default_end`]).
pub fn resolve_noting(case: &toml::Value, overrides: &[String]) -> Result<(toml::Value, Option<String>), ConfigError> {
    let mut v = case.clone();
    for o in overrides {
        config::apply_override(&mut v, o)?;
    }
    config::apply_aliases(&mut v)?;
    let note = config::plausible::default_end(&mut v)?;
    // values typical of the wrong unit (docs/case-file.md "Unit slips"); the warnings are logged
    // by `open_run` and `check`
    config::plausible::unit_slips(&v)?;
    Ok((v, note))
}

/// A run's log: every line goes to `DIR/log.txt` (appending), and with `echo` to the console as a
/// `tracing` event (info; warn for lines starting with "warning: "), see [`crate::logging`].
/// While it lives, `tracing` events of this thread are copied into the same `log.txt`.
pub struct RunLog {
    file: Option<Arc<Mutex<std::fs::File>>>,
    echo: bool,
    _route: Option<crate::logging::RunFile>,
    /// The output directory's lock (docs/outputs.md "Guarantees"), held as long as the run's log.
    lock: Option<crate::io::lock::OutputLock>,
}

impl RunLog {
    /// Opens `dir/log.txt`; `append` keeps earlier lines (resume).
    pub fn open(dir: &Path, append: bool, echo: bool) -> RunLog {
        let path = dir.join("log.txt");
        // a log that cannot be recorded is not opened: the run's first output write reports why
        let recorded = crate::io::manifest::record(&path).is_ok();
        let file = recorded
            .then(|| std::fs::OpenOptions::new().create(true).write(true).append(append).truncate(!append).open(&path).ok())
            .flatten()
            .map(|f| Arc::new(Mutex::new(f)));
        let route = file.clone().map(crate::logging::RunFile::enter);
        RunLog { file, echo, _route: route, lock: None }
    }

    /// Keeps the output directory's lock until the log is dropped (the end of the run).
    pub fn hold(&mut self, lock: crate::io::lock::OutputLock) {
        self.lock = Some(lock);
    }

    /// Writes one line; a line starting with [`crate::logging::DETAIL`] is detail (console at `-v`).
    pub fn line(&mut self, msg: &str) {
        let detail = msg.strip_prefix(crate::logging::DETAIL);
        let msg = detail.unwrap_or(msg);
        if let Some(f) = self.file.as_ref() {
            let mut g = f.lock().unwrap_or_else(|e| e.into_inner());
            let _ = writeln!(g, "{msg}");
        }
        if self.echo && detail.is_some() {
            tracing::debug!(target: "sinterdem::kinds", "{msg}");
        } else if self.echo {
            match msg.strip_prefix("warning: ") {
                Some(w) => tracing::warn!(target: "sinterdem::kinds", "{w}"),
                None => tracing::info!(target: "sinterdem::kinds", "{msg}"),
            }
        }
    }
}

/// Runs `case` with `overrides` into `out` and returns its summary. The output directory is
/// created; `log.txt` in it receives the run's log. Heat, compact and explicit_sinter runs are a
/// [`Stepper`] stepped to the end (so the stepping API gives the same files); a stop request
/// ([`crate::interrupt`]) ends them early with `completed = false`.
pub fn run(case: &toml::Value, overrides: &[String], out: &Path, params: &RunParams) -> Result<RunSummary, Error> {
    let wall = Instant::now();
    let (value, kind, mut log) = open_run(case, overrides, out, params)?;
    if matches!(kind, Kind::Heat | Kind::Compact | Kind::ExplicitSinter) {
        let mut s = Stepper::opened(value, kind, log, out, params, wall)?;
        loop {
            match s.step() {
                Ok(true) => {}
                Ok(false) => return s.finish(),
                Err(e) => return Err(s.fail(e, out)),
            }
        }
    }
    let result = run_unstepped(kind, &value, out, params, &mut log);
    if let Err(e) = &result {
        // the error in log.txt too (issue 39)
        log.line(&format!("error: {e}"));
    }
    Ok(RunSummary { kind, wall_seconds: wall.elapsed().as_secs_f64(), summary: result? })
}

/// The body of a pair or generate run (their summary).
fn run_unstepped(kind: Kind, value: &toml::Value, out: &Path, params: &RunParams, log: &mut RunLog) -> Result<serde_json::Value, Error> {
    let mut logf = |m: &str| log.line(m);
    let summary = match kind {
        Kind::Pair => {
            let mut spec = crate::kinds::pair::parse_pair_case(value)?;
            if !params.plots && spec.plot {
                spec.plot = false;
                logf("plot skipped (turned off by the caller)");
            }
            let s = crate::kinds::pair::run_pair_spec(&spec, out, params.progress, &mut |w| logf(&format!("warning: {w}")))?;
            logf(&format!(
                "done: {} to t = {} s in {} steps ({} rejected): neck ratio y1/R = {:.6}, shrinkage ΔL/L0 = {:.6e}",
                s.title, s.final_time_s, s.steps, s.rejected_steps, s.neck_ratio, s.shrinkage
            ));
            serde_json::to_value(&s).map_err(|e| IoError::new(out.join("summary.json"), e))?
        }
        Kind::Generate => {
            let s = crate::kinds::generate::generate_case(value, out, params.progress)?;
            logf(&format!("done: {} particles, solid fraction {:.4}, coordination {:.3}", s.particles, s.solid_fraction, s.coordination_mean));
            let mut v = serde_json::to_value(&s).map_err(|e| IoError::new(out.join("summary.json"), e))?;
            // a packing that stops short of its target (the jamming limit, the wall layers of a
            // small box: docs/packing.md) is usable but not what was asked: say so (issue 25)
            if let Some(w) = crate::kinds::generate::target_shortfall(s.solid_fraction, s.target_solid_fraction, s.boundary.is_some()) {
                logf(&format!("warning: {w}"));
                v["target_reached"] = serde_json::json!(false);
                v["warnings"] = serde_json::json!([w]);
                crate::io::write_json(&out.join("summary.json"), &v)?;
            }
            v
        }
        Kind::Heat | Kind::Compact | Kind::ExplicitSinter => {
            return Err(ConfigError::invalid("internal: heat, compact and explicit_sinter runs are stepped").into());
        }
    };
    Ok(summary)
}

/// The checks of `sinterdem check` that a kind's run path does not make by itself (the step-count
/// and output-interval limits of an explicit_sinter protocol, `case::check_plan`), so that `run`
/// refuses exactly what `check` refuses. Heat, compact, pair and generate runs parse and validate
/// through the same functions as `check` (prepare, parse_pair_case, parse_generate_case).
fn validate_before_run(kind: Kind, value: &toml::Value) -> Result<(), Error> {
    match kind {
        Kind::ExplicitSinter => crate::kinds::explicit_sinter::check_explicit_case(value),
        Kind::Pair | Kind::Generate | Kind::Heat | Kind::Compact => Ok(()),
    }
}

pub use crate::io::outdir::is_snapshot_file;

/// A compact case read from `path` without a `title` gets the file's stem as its title (the
/// plots' heading: "copper-compact", not a generic "compact"); other kinds and titled cases are
/// returned as they are.
pub fn title_from_file(mut case: toml::Value, path: &Path) -> toml::Value {
    let compact = case.get("kind").and_then(|k| k.as_str()) == Some("compact");
    if let (true, Some(t), Some(stem)) = (compact, case.as_table_mut(), path.file_stem()) {
        t.entry("title").or_insert_with(|| toml::Value::String(stem.to_string_lossy().into_owned()));
    }
    case
}

/// The start of every run: includes expanded, overrides applied, the kind, the output directory
/// and `log.txt` opened with the first lines (version, overrides, warnings about keys the kind
/// ignores).
pub(crate) fn open_run(case: &toml::Value, overrides: &[String], out: &Path, params: &RunParams) -> Result<(toml::Value, Kind, RunLog), Error> {
    let mut case = case.clone();
    config::expand_includes(&mut case, &params.base_dir)?;
    let (value, end_note) = resolve_noting(&case, overrides)?;
    let kind = Kind::of(&value)?;
    // the holder's command as the user typed it (issue 38: a generate was named "sinterdem run")
    let lock = crate::io::lock::OutputLock::acquire(out, if kind == Kind::Generate { "generate" } else { crate::io::lock::command_or("run") })?;
    // a new run owns its directory: it refuses one holding another run's outputs (a checkpoint
    // `resume` would continue, a snapshot series ParaView would mix with this run's) unless
    // `force`, which removes them first (docs/outputs.md "Guarantees")
    let fingerprint = crate::io::outdir::case_fingerprint(&value, &params.base_dir);
    // the files the case reads are never removed, even when an earlier run wrote them
    let inputs: Vec<PathBuf> = crate::io::inputs::referenced_files(&value, &params.base_dir).into_iter().map(|(_, p)| p).collect();
    let cleared = crate::io::outdir::claim(out, crate::io::outdir::Claimant::Run, params.force, Some(&fingerprint), &inputs)?;
    crate::io::outdir::write_marker(out, kind.name(), &fingerprint)?;
    let mut log = RunLog::open(out, false, params.echo_log);
    log.line(&format!("sinterdem {}: {} case → {}", env!("CARGO_PKG_VERSION"), kind.name(), out.display()));
    if let Some(note) = lock.takeover_note() {
        log.line(&note);
    }
    if let Some(note) = cleared {
        log.line(&note);
    }
    log.hold(lock);
    // the files the case names, fingerprinted for `resume` (docs/outputs.md "Guarantees")
    crate::io::inputs::record(out, &value, &params.base_dir)?;
    if !overrides.is_empty() {
        log.line(&format!("overrides: {}", overrides.join(" ")));
    }
    let (later, notes) = config::plausible::schedule_end_warnings(&value);
    for w in compact_only_keys(&value).into_iter().chain(config::plausible::unit_slips(&value)?).chain(later) {
        log.line(&format!("warning: {w}"));
    }
    for n in end_note.into_iter().chain(notes) {
        log.line(&n);
    }
    // library materials whose 7-DOF data hold placeholders: said once, in log.txt (docs/materials.md)
    if matches!(kind, Kind::Pair | Kind::Compact) {
        for line in crate::models::diffusion7::library::used_by(&value).iter().filter_map(|e| e.unmeasured_line()) {
            log.line(&format!("{}{line}", crate::logging::DETAIL));
        }
    }
    validate_before_run(kind, &value)?;
    Ok((value, kind, log))
}

/// Keys set in `case` that only compact runs use (thermal expansion, docs/coupled.md "Thermal
/// expansion"): one sentence per key when `case` is not a compact case (for a warning), else none.
pub fn compact_only_keys(case: &toml::Value) -> Vec<String> {
    let mut out = Vec::new();
    let kind = case.get("kind").and_then(|k| k.as_str()).unwrap_or("heat");
    if kind == "compact" {
        return out;
    }
    if let Some(mats) = case.get("materials").and_then(|m| m.as_array()) {
        for (i, m) in mats.iter().enumerate() {
            for key in ["thermal_expansion", "thermal_expansion_table"] {
                let set = match m.get(key) {
                    Some(toml::Value::Float(v)) => *v != 0.0,
                    Some(toml::Value::Integer(v)) => *v != 0,
                    Some(_) => true,
                    None => false,
                };
                if set {
                    out.push(format!("materials.{i}.{key} is used by compact runs only; this {kind} run ignores it (no thermal expansion)"));
                }
            }
        }
    }
    out
}

/// Continues the interrupted run in `dir` from its checkpoint (compact, heat and explicit_sinter
/// runs): the checkpoint's `format` names the kind.
pub fn resume(dir: &Path, params: &RunParams) -> Result<RunSummary, Error> {
    let wall = Instant::now();
    let path = dir.join("checkpoint.json");
    if !path.exists() && dir.is_dir() {
        // a kind without checkpoints (pair, generate, titanium), checkpoints turned off, or killed
        // before its first: nothing to continue from (issue 38: refused, never exit 0)
        let kind = std::fs::read_to_string(dir.join(crate::io::outdir::RUN_MARKER))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v.get("kind").and_then(|k| k.as_str()).map(str::to_string));
        let what = kind.map(|k| format!("this {k} run")).unwrap_or_else(|| "this directory".into());
        return Err(IoError::new(
            &path,
            format!(
                "is missing: {what} has no checkpoint to continue from (pair and generate runs write none; compact, heat, explicit_sinter and rve runs write one every output.checkpoint_every steps, unless 0): run the case again with --force"
            ),
        )
        .into());
    }
    let text = crate::io::read_checkpoint_json(&path)?;
    #[derive(serde::Deserialize)]
    struct Head {
        format: Option<String>,
    }
    let format = serde_json::from_str::<Head>(&text).map_err(|e| IoError::new(&path, format!("not a sinterdem checkpoint: {e}")))?.format.unwrap_or_default();
    // a run that finished has nothing to continue: say so instead of running again from its last
    // checkpoint (issue 25); an interrupted or stopped run's summary says `completed = false`
    if let Some((kind, summary, t)) = finished_run(dir) {
        let command = if summary.get("kind").and_then(|k| k.as_str()) == Some("rve") { "rve" } else { "run" };
        let line = format!(
            "{}: the run finished (summary.json: completed{}); nothing to resume — `sinterdem {command} CASE --out {} --force` runs it again",
            dir.display(),
            t.map(|t| format!(" at t = {} s", crate::error::fmt_value(t))).unwrap_or_default(),
            dir.display()
        );
        tracing::info!(target: "sinterdem::kinds", "{line}");
        return Ok(RunSummary { kind, wall_seconds: wall.elapsed().as_secs_f64(), summary });
    }
    let lock = crate::io::lock::OutputLock::acquire(dir, "resume")?;
    // the resumed run's files join those its start recorded (crate::io::manifest)
    crate::io::manifest::begin(dir, true)?;
    let mut log = RunLog::open(dir, true, params.echo_log);
    if let Some(note) = lock.takeover_note() {
        log.line(&note);
    }
    if let Some(n) = crate::io::inputs::verify(dir)? {
        log.line(&format!("inputs unchanged since the run started ({n} file{} checked)", if n == 1 { "" } else { "s" }));
    }
    // an rve run continues with its branch points, table, fit and plots (issue 38)
    if format == crate::kinds::compact::CHECKPOINT_FORMAT && rve::is_rve_dir(dir) {
        let mut s = rve::resume(dir, params, log)?;
        s.wall_seconds = wall.elapsed().as_secs_f64();
        return Ok(s);
    }
    let mut logf = |m: &str| log.line(m);
    let (kind, summary) = match format.as_str() {
        crate::kinds::heat::HEAT_CHECKPOINT_FORMAT => (Kind::Heat, crate::kinds::heat::resume(dir, params.progress, &mut logf)?),
        crate::kinds::explicit_sinter::EXPLICIT_CHECKPOINT_FORMAT => (Kind::ExplicitSinter, crate::kinds::explicit_sinter::resume(dir, &mut logf)?),
        crate::kinds::compact::CHECKPOINT_FORMAT => (Kind::Compact, crate::kinds::compact::resume(dir, params.progress, &mut logf)?),
        f => {
            return Err(ConfigError::invalid(format!(
                "{}: format \"{f}\" is not a checkpoint this sinterdem continues ({}, {} or {})",
                path.display(),
                crate::kinds::compact::CHECKPOINT_FORMAT,
                crate::kinds::heat::HEAT_CHECKPOINT_FORMAT,
                crate::kinds::explicit_sinter::EXPLICIT_CHECKPOINT_FORMAT
            ))
            .into());
        }
    };
    Ok(RunSummary { kind, wall_seconds: wall.elapsed().as_secs_f64(), summary })
}

/// The summary of a run in `dir` that finished: `summary.json` present, not `completed = false`,
/// of a kind that resumes (heat, compact, explicit_sinter); with its final time when it has one.
fn finished_run(dir: &Path) -> Option<(Kind, serde_json::Value, Option<f64>)> {
    let text = std::fs::read_to_string(dir.join("summary.json")).ok()?;
    let summary: serde_json::Value = serde_json::from_str(&text).ok()?;
    if summary.get("completed").and_then(|c| c.as_bool()) == Some(false) {
        return None;
    }
    // an rve run is finished only when its own summary (kind "rve") is written, after the free
    // run's (kind "compact")
    let kind_name = summary.get("kind").and_then(|k| k.as_str());
    if rve::is_rve_dir(dir) && kind_name != Some("rve") {
        return None;
    }
    let kind = match kind_name {
        Some("heat") => Kind::Heat,
        Some("compact") | Some("rve") => Kind::Compact,
        Some("explicit_sinter") => Kind::ExplicitSinter,
        _ => return None,
    };
    let t = summary.get("final_time_s").and_then(|t| t.as_f64());
    Some((kind, summary, t))
}

/// Validates a case without running it; returns a one-line description. (A calibration file,
/// recognised by [`config::is_calibration`], is checked by `crate::calibrate::check`.)
pub fn check(case: &toml::Value, overrides: &[String], base: &Path) -> Result<String, Error> {
    let mut case = case.clone();
    config::expand_includes(&mut case, base)?;
    let (value, end_note) = resolve_noting(&case, overrides)?;
    let (later, notes) = config::plausible::schedule_end_warnings(&value);
    for w in config::plausible::unit_slips(&value)?.into_iter().chain(later) {
        tracing::warn!(target: "sinterdem::kinds", "{w}");
    }
    for n in end_note.into_iter().chain(notes) {
        tracing::info!(target: "sinterdem::kinds", "{n}");
    }
    Ok(match Kind::of(&value)? {
        Kind::Heat => {
            let prep = crate::scene::prepare(value, base)?;
            format!("heat case, {} particles, {} contacts", prep.scene.particles.len(), prep.pipes.pairs.len())
        }
        Kind::Compact => {
            let rve = value.get("rve").is_some();
            let at = value.clone();
            let sim = crate::coupled::prepare(value, base, &mut |_| {})?;
            // an rve case: [rve] checked as `sinterdem rve` checks it (issue 38)
            if rve {
                rve::RveSettings::from_case(&at, sim.settings.end)?;
                rve::check_free_periodic(&sim)?;
            }
            format!("{} case, {} particles, {} contacts", if rve { "compact (rve)" } else { "compact" }, sim.prep.scene.particles.len(), sim.contacts.len())
        }
        Kind::Generate => {
            crate::kinds::generate::check_generate_case(&value)?;
            "packing generation case".into()
        }
        Kind::Pair => {
            crate::kinds::pair::check_pair_case(&value)?;
            "pair case".into()
        }
        Kind::ExplicitSinter => {
            crate::kinds::explicit_sinter::check_explicit_case(&value)?;
            "explicit_sinter case".into()
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_follows_objects_and_arrays() {
        let v = serde_json::json!({"a": {"b": [1.5, 2.5]}, "c": 3});
        assert_eq!(lookup(&v, "a.b.1").and_then(|x| x.as_f64()), Some(2.5));
        assert_eq!(lookup(&v, "c").and_then(|x| x.as_f64()), Some(3.0));
        assert!(lookup(&v, "a.x").is_none());
        assert!(lookup(&v, "a.b.7").is_none());
    }

    #[test]
    fn kind_defaults_to_heat_and_rejects_unknown() {
        let v: toml::Value = toml::Value::Table("title = \"x\"".parse().unwrap());
        assert_eq!(Kind::of(&v).unwrap(), Kind::Heat);
        let v: toml::Value = toml::Value::Table("kind = \"plasma\"".parse().unwrap());
        let e = Kind::of(&v).unwrap_err().to_string();
        assert!(e.contains("plasma") && e.contains("explicit_sinter"), "{e}");
    }
}

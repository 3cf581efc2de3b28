//! The packing level of a calibration (docs/calibration.md, "Fitting on a packing" and "From
//! pairs to a packing"):
//!
//! - `model = "compact"`: [`CompactModel`], a forward model that runs every experiment's schedule
//!   on the compact case named in `[compact]` and sends each optimiser generation through the
//!   study engine as one study (`DIR/compact-fit/gen-NNNN-LABEL/`, local engine or SLURM). The
//!   fitted parameters are case overrides of the derived case `DIR/compact-fit/case.toml`
//!   (`materials.M.phases.P.FIELD`, `model.FIELD`), so a run is keyed in the study store by its
//!   resolved case: re-running a calibration with the same `--out` reuses every finished run.
//! - `--validate-compact`: [`validate`], the fitted material on the packing for the chosen
//!   experiments, as one study; `compact_validation.csv` sets the compact's shrinkage beside the
//!   measured one and the pair's.
//!
//! Observables of a compact run: shrinkage = the mean of `shrinkage_x`, `shrinkage_y`,
//! `shrinkage_z` (ΔL/L0 of the packing's extent along each axis), neck ratio = `neck_ratio`, the
//! mean y1/R over the contacts; at the end of the schedule from `summary.json`, at series times
//! interpolated linearly in `series.csv` (a row every step).

use super::data::Experiment;
use super::forward::{Predicted, Prediction};
use super::model::{ForwardModel, Point, Predictions, Problem};
use super::params::{MODEL_FIELDS, PHASE_FIELDS, Target, model_field};
use crate::error::{ConfigError, Error, IoError, ModelError};
use crate::models::diffusion7::{Material, PathFactors};
use crate::study::{self, Engine, StudyOptions, store};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// `[compact.slurm]`: the SLURM settings of every generation's study (the `[slurm]` keys of a
/// study file, docs/studies.md).
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SlurmSection {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub partition: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub account: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpus_per_task: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chunk: Option<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_resubmit: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub poll_seconds: Option<f64>,
}

/// `[compact]` of a calibration file.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompactSection {
    /// A compact case (`kind = "compact"`, `thermal.mode = "isothermal"`), relative to the
    /// calibration file.
    pub case: Option<String>,
    /// Experiment ids to run (default: all): those validated by `--validate-compact`, those
    /// fitted with `model = "compact"`.
    #[serde(default)]
    pub experiments: Vec<String>,
    /// Overrides of the compact case (`key.path=value`), e.g. to shorten it.
    #[serde(default)]
    pub overrides: Vec<String>,
    /// `model = "compact"`: the study engine of each generation, `local` (default) or `slurm`.
    pub engine: Option<String>,
    /// Local engine: runs at a time (default: cores / threads).
    pub jobs: Option<f64>,
    /// Local engine: rayon threads of each run (default 1).
    pub threads: Option<f64>,
    /// SLURM engine settings.
    #[serde(default)]
    pub slurm: SlurmSection,
}

/// The validated engine settings of a packing-level fit.
#[derive(Debug, Clone, PartialEq)]
pub struct EngineSettings {
    pub engine: Engine,
    /// Runs at a time (0: cores / threads).
    pub jobs: usize,
    pub threads: usize,
    pub slurm: SlurmSection,
}

fn whole(key: &str, shown: &str, v: f64) -> Result<usize, ConfigError> {
    let v = study::spec::check(key, shown, v)?;
    if v.fract() != 0.0 {
        return Err(ConfigError::invalid(format!("{shown} = {v}: must be a whole number")));
    }
    Ok(v as usize)
}

impl CompactSection {
    /// Validates the engine keys (ranges of the study file's `engine.*` and `slurm.*`).
    pub fn engine_settings(&self) -> Result<EngineSettings, ConfigError> {
        let engine = match self.engine.as_deref().unwrap_or("local") {
            "local" => Engine::Local,
            "slurm" => Engine::Slurm,
            e => return Err(ConfigError::invalid(format!("compact.engine = \"{e}\": expected \"local\" or \"slurm\""))),
        };
        let jobs = self.jobs.map(|j| whole("engine.jobs", "compact.jobs", j)).transpose()?.unwrap_or(0);
        let threads = whole("engine.threads", "compact.threads", self.threads.unwrap_or(1.0))?;
        let s = &self.slurm;
        for (k, v) in [("cpus_per_task", s.cpus_per_task), ("chunk", s.chunk), ("max_resubmit", s.max_resubmit)] {
            if let Some(v) = v {
                whole(&format!("slurm.{k}"), &format!("compact.slurm.{k}"), v)?;
            }
        }
        if let Some(p) = s.poll_seconds {
            study::spec::check("slurm.poll_seconds", "compact.slurm.poll_seconds", p)?;
        }
        for (k, v) in [("partition", &s.partition), ("time", &s.time), ("account", &s.account)] {
            if let Some(v) = v
                && (v.is_empty() || v.contains([' ', '\n']))
            {
                return Err(ConfigError::invalid(format!("compact.slurm.{k} = \"{v}\": must be one word")));
            }
        }
        Ok(EngineSettings { engine, jobs, threads, slurm: s.clone() })
    }

    /// The indices of the chosen experiments (all when the list is empty).
    pub fn chosen(&self, experiments: &[Experiment]) -> Result<Vec<usize>, ConfigError> {
        if self.experiments.is_empty() {
            return Ok((0..experiments.len()).collect());
        }
        self.experiments
            .iter()
            .map(|id| {
                experiments.iter().position(|e| &e.id == id).ok_or_else(|| {
                    ConfigError::invalid(format!(
                        "compact.experiments: no experiment \"{id}\" in the data (it has: {})",
                        experiments.iter().map(|e| e.id.as_str()).collect::<Vec<_>>().join(", ")
                    ))
                })
            })
            .collect()
    }

    /// The compact case's path (relative to `calib_dir`), or the error `what` needs it for.
    pub fn case_path(&self, calib_dir: &Path, what: &str) -> Result<PathBuf, ConfigError> {
        let rel = self.case.as_ref().ok_or_else(|| ConfigError::invalid(format!("{what} needs [compact] case = \"compact.toml\" in the calibration file")))?;
        Ok(calib_dir.join(rel))
    }
}

/// A derived compact case: the case of `[compact]` with `material`'s phases in its material of the
/// same name and `factors` as its `[model]`, a furnace schedule to be replaced per experiment and
/// the overrides applied. Refuses a case that is not an isothermal compact, has no such material,
/// or whose `[model]` (its own or from an included material file) sets a path factor other than
/// `start_factors`, the calibration's starting ones. Returns the case and the material's index.
pub fn derived_case(
    case_path: &Path,
    material: &Material,
    factors: &PathFactors,
    start_factors: &PathFactors,
    overrides: &[String],
) -> Result<(toml::Value, usize), Error> {
    let case_path = &case_path.canonicalize().map_err(|e| ConfigError::invalid(format!("[compact] case = {}: {e}", case_path.display())))?;
    let mut case = crate::config::load_case(case_path, &[])?;
    let base = case_path.parent().unwrap_or(Path::new("/")).to_path_buf();
    let at = |m: &str| ConfigError::invalid(format!("[compact] case = {}: {m}", case_path.display()));
    if case.get("kind").and_then(|k| k.as_str()) != Some("compact") {
        return Err(at("needs kind = \"compact\"").into());
    }
    let mode = case.get("thermal").and_then(|t| t.get("mode")).and_then(|m| m.as_str()).unwrap_or("");
    if mode != "isothermal" {
        return Err(at("needs thermal.mode = \"isothermal\": each experiment's schedule replaces the furnace profile").into());
    }
    // the packing file, absolute (the derived case lives elsewhere)
    if let Some(f) = case.get_mut("particles").and_then(|p| p.get_mut("file"))
        && let Some(s) = f.as_str()
        && Path::new(s).is_relative()
    {
        *f = toml::Value::String(base.join(s).to_string_lossy().to_string());
    }
    let mats = case.get_mut("materials").and_then(|m| m.as_array_mut()).ok_or_else(|| at("has no [[materials]]"))?;
    let names: Vec<String> = mats.iter().filter_map(|m| m.get("name").and_then(|n| n.as_str()).map(String::from)).collect();
    // the entry named as the fitted material, else the one built from the preset of that name
    // (a compact case names its material "titanium" with preset = "titanium-ivannikov2022")
    let key = |k: &str| mats.iter().position(|m| m.get(k).and_then(|n| n.as_str()) == Some(material.name.as_str()));
    let index = key("name").or_else(|| key("preset")).ok_or_else(|| {
        at(&format!("has no material named \"{}\" nor one with preset = \"{}\" (it has: {})", material.name, material.name, names.join(", ")))
    })?;
    let entry = mats[index].as_table_mut().ok_or_else(|| at(&format!("materials.{index} is not a table")))?;
    let phases = toml::Value::try_from(&material.phases).map_err(|e| at(&format!("fitted phases: {e}")))?;
    entry.insert("phases".into(), phases);
    entry.insert("calibrated_min_temperature".into(), toml::Value::Float(material.calibrated_min_temperature));
    entry.insert("calibrated_max_temperature".into(), toml::Value::Float(material.calibrated_max_temperature));
    entry.insert("source".into(), toml::Value::String(material.source.clone()));
    if let Some(tm) = material.melting_temperature {
        entry.insert("melting_temperature".into(), toml::Value::Float(tm));
    }
    // one set of path factors: the calibration's
    let root = case.as_table_mut().ok_or_else(|| at("is not a table"))?;
    let mut model = toml::Table::new();
    if let Some(m) = root.get("model") {
        let m = m.as_table().ok_or_else(|| at("[model] is not a table"))?;
        for (k, v) in m {
            let i = MODEL_FIELDS.iter().position(|f| f == k).ok_or_else(|| at(&format!("model.{k}: unknown key (valid: {})", MODEL_FIELDS.join(", "))))?;
            let x = v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).ok_or_else(|| at(&format!("model.{k} = {v}: expected a number")))?;
            let want = model_field(start_factors, i);
            if x != want {
                return Err(at(&format!(
                    "model.{k} = {x} (in the case or a material file it includes), but the calibration starts from {k} = {want} ([path_factors] of the calibration file, or its included material file): give the same value in both, or remove one"
                ))
                .into());
            }
        }
    }
    for (i, k) in MODEL_FIELDS.iter().enumerate() {
        model.insert(k.to_string(), toml::Value::Float(model_field(factors, i)));
    }
    root.insert("model".into(), toml::Value::Table(model));
    let mut profile = toml::Table::new();
    profile.insert("schedule".into(), toml::Value::String("start 293 K".into()));
    let thermal = root.get_mut("thermal").and_then(|t| t.as_table_mut()).ok_or_else(|| at("has no [thermal]"))?;
    let furnace = thermal.entry("furnace").or_insert_with(|| toml::Value::Table(toml::Table::new()));
    let furnace = furnace.as_table_mut().ok_or_else(|| at("thermal.furnace is not a table"))?;
    furnace.insert("profile".into(), toml::Value::Table(profile));
    for o in overrides {
        crate::config::apply_override(&mut case, o).map_err(|e| at(&format!("overrides: {e}")))?;
    }
    Ok((case, index))
}

/// Turns off the outputs a fit does not read (snapshots, VTU, HDF5, checkpoints, conductivity and
/// histogram analyses) and asks for a series row every step; the calibration's `overrides` come
/// after and may turn them on again.
fn quiet_outputs(case: &mut toml::Value) {
    for (k, v) in [
        ("snapshots", toml::Value::Integer(0)),
        ("vtu", toml::Value::Boolean(false)),
        ("hdf5", toml::Value::Boolean(false)),
        ("checkpoint_every", toml::Value::Integer(0)),
        ("series_every", toml::Value::Integer(1)),
        ("conductivity_at", toml::Value::Array(vec![])),
        ("correction_histogram_at", toml::Value::Array(vec![])),
    ] {
        let _ = crate::config::apply_override(case, &format!("output.{k}={v}"));
    }
}

/// The case every run of a packing-level fit starts from: [`derived_case`] with the starting
/// material and path factors, the fit's outputs turned off, then `[compact] overrides`. Returns the
/// case and the index of the fitted material in it.
pub fn fit_case(section: &CompactSection, calib_dir: &Path, material: &Material, factors: &PathFactors) -> Result<(toml::Value, usize), Error> {
    let case_path = section.case_path(calib_dir, "model = \"compact\"")?;
    let (mut case, mi) = derived_case(&case_path, material, factors, factors, &[])?;
    quiet_outputs(&mut case);
    for o in &section.overrides {
        crate::config::apply_override(&mut case, o).map_err(|e| ConfigError::invalid(format!("[compact] overrides: {e}")))?;
    }
    Ok((case, mi))
}

/// The packing-level forward model (`model = "compact"`).
pub struct CompactModel {
    problem: Problem,
    /// `DIR/compact-fit` (absolute).
    dir: PathBuf,
    /// Case key of each fitted parameter (`materials.M.phases.P.FIELD`, `model.FIELD`).
    keys: Vec<String>,
    engine: EngineSettings,
}

/// A number in a TOML study file: exact round trip.
fn float(x: f64) -> toml::Value {
    toml::Value::Float(x)
}

fn study_param(key: &str, name: &str, values: Vec<toml::Value>) -> toml::Value {
    let mut t = toml::Table::new();
    t.insert("key".into(), toml::Value::String(key.into()));
    t.insert("name".into(), toml::Value::String(name.into()));
    t.insert("values".into(), toml::Value::Array(values));
    toml::Value::Table(t)
}

/// The prediction of experiment `e` from its run's record (and series.csv).
fn prediction(dir: &Path, run: &store::PlannedRun, e: &Experiment) -> Result<Prediction, ModelError> {
    let ctx = |m: String| ModelError::new(m).with_context(format!("experiment {} on the packing, {}", e.id, store::run_dir(dir, run.index).display()));
    let rec = store::read_record(dir, run).ok_or_else(|| ctx("the run has no result (lost or cancelled)".into()))?;
    if !rec.ok() {
        return Err(ctx(rec.error.unwrap_or_else(|| "failed".into())));
    }
    let s = &rec.summary;
    if s["completed"].as_bool() != Some(true) {
        return Err(ctx(format!("the run stopped before the end of the schedule: {}", s["stop_reason"].as_str().unwrap_or("no reason given"))));
    }
    let f = |k: &str| s[k].as_f64().filter(|x| x.is_finite()).ok_or_else(|| ctx(format!("summary.json has no finite {k}")));
    let end = Predicted { neck_ratio: f("neck_ratio")?, shrinkage: (f("shrinkage_x")? + f("shrinkage_y")? + f("shrinkage_z")?) / 3.0 };
    let mut series = Vec::with_capacity(e.series.len());
    if !e.series.is_empty() {
        let path = store::run_dir(dir, run.index).join("series.csv");
        let (head, rows) = study::report::read_series(&path).ok_or_else(|| ctx(format!("cannot read {}", path.display())))?;
        let col = |k: &str| head.iter().position(|h| h == k).ok_or_else(|| ctx(format!("{} has no column {k}", path.display())));
        let cols = [col("shrinkage_x")?, col("shrinkage_y")?, col("shrinkage_z")?, col("neck_ratio_mean")?];
        for p in &e.series {
            let v: Vec<f64> = cols
                .iter()
                .map(|&c| {
                    study::report::interpolate(&rows, c, p.time)
                        .filter(|x| x.is_finite())
                        .ok_or_else(|| ctx(format!("no value at {} s in {}", p.time, path.display())))
                })
                .collect::<Result<_, _>>()?;
            series.push(Predicted { neck_ratio: v[3], shrinkage: (v[0] + v[1] + v[2]) / 3.0 });
        }
    }
    Ok(Prediction { series, end, steps: s["steps"].as_u64().unwrap_or(0) })
}

impl CompactModel {
    /// Derives the fit's case into `out/compact-fit/case.toml` (starting material, the
    /// calibration's path factors, outputs turned off, `[compact] overrides`) and checks that
    /// every fitted parameter is a key of it.
    pub fn new(section: &CompactSection, calib_dir: &Path, problem: Problem, out: &Path) -> Result<CompactModel, Error> {
        let case_path = section.case_path(calib_dir, "model = \"compact\"")?;
        let engine = section.engine_settings()?;
        crate::io::ensure_dir(out)?;
        let dir = out.canonicalize().map_err(|e| IoError::new(out, e))?.join("compact-fit");
        crate::io::ensure_dir(&dir)?;
        let (case, mi) = fit_case(section, calib_dir, &problem.material, &problem.factors)?;
        let keys = problem
            .params
            .iter()
            .map(|p| match p.target {
                Target::Phase { phase, field } => format!("materials.{mi}.phases.{phase}.{}", PHASE_FIELDS[field]),
                Target::Model { field } => format!("model.{}", MODEL_FIELDS[field]),
            })
            .collect();
        let file = dir.join("case.toml");
        let text = toml::to_string(&case).map_err(|e| IoError::new(&file, e))?;
        crate::io::write_atomic(
            &file,
            &format!(
                "# {} with the calibration's starting material (sinterdem calibrate, model = \"compact\"); each generation's study sets the fitted keys\n{text}",
                case_path.display()
            ),
        )?;
        Ok(CompactModel { problem, dir, keys, engine })
    }

    /// The directory of the fit's studies (`DIR/compact-fit`).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The study file of one batch (every set × every experiment, zipped).
    fn study_text(&self, label: &str, batch: usize, points: &[Point]) -> Result<String, Error> {
        let ex = &self.problem.experiments;
        let each = |f: &dyn Fn(usize, &Experiment) -> toml::Value| -> Vec<toml::Value> {
            points.iter().enumerate().flat_map(|(i, _)| ex.iter().map(move |e| (i, e))).map(|(i, e)| f(i, e)).collect()
        };
        let mut params = vec![study_param("title", "label", each(&|i, e| toml::Value::String(format!("set {i}, {}", e.id))))];
        for (j, (p, key)) in self.problem.params.iter().zip(&self.keys).enumerate() {
            params.push(study_param(key, &p.key, each(&|i, _| float(points[i].values[j]))));
        }
        params.push(study_param("thermal.furnace.profile.schedule", "schedule", each(&|_, e| toml::Value::String(e.schedule.clone()))));
        params.push(study_param("time.end", "end_s", each(&|_, e| float(e.profile.duration()))));
        let mut t = toml::Table::new();
        t.insert("title".into(), toml::Value::String(format!("calibration batch {batch} ({label})")));
        t.insert("base".into(), toml::Value::String("../case.toml".into()));
        let mut design = toml::Table::new();
        design.insert("kind".into(), toml::Value::String("zip".into()));
        t.insert("design".into(), toml::Value::Table(design));
        t.insert("parameters".into(), toml::Value::Array(params));
        let mut collect = toml::Table::new();
        let summary = ["shrinkage_x", "shrinkage_y", "shrinkage_z", "neck_ratio", "relative_density", "completed", "steps"];
        collect.insert("summary".into(), toml::Value::Array(summary.iter().map(|s| toml::Value::String(s.to_string())).collect()));
        t.insert("collect".into(), toml::Value::Table(collect));
        let mut engine = toml::Table::new();
        if self.engine.jobs > 0 {
            engine.insert("jobs".into(), toml::Value::Integer(self.engine.jobs as i64));
        }
        engine.insert("threads".into(), toml::Value::Integer(self.engine.threads as i64));
        t.insert("engine".into(), toml::Value::Table(engine));
        let slurm = toml::Value::try_from(&self.engine.slurm).map_err(|e| ConfigError::invalid(format!("compact.slurm: {e}")))?;
        t.insert("slurm".into(), slurm);
        Ok(toml::to_string(&t).map_err(|e| ConfigError::invalid(format!("batch study file: {e}")))?)
    }
}

impl ForwardModel for CompactModel {
    fn problem(&self) -> &Problem {
        &self.problem
    }

    fn name(&self) -> &'static str {
        "compact"
    }

    /// One study per batch in `DIR/compact-fit/gen-NNNN-LABEL/`: run `k·E + e` is set k on
    /// experiment e. The directory is named by the batch's sequence number, which a deterministic
    /// fit reproduces, so a re-run finds the finished runs (the store checks each run's hash).
    fn run_batch(&self, batch: usize, label: &str, points: &[Point]) -> Result<(Vec<Predictions>, usize), Error> {
        let wall = std::time::Instant::now();
        let gdir = self.dir.join(format!("gen-{batch:04}-{label}"));
        crate::io::ensure_dir(&gdir)?;
        let file = gdir.join("study.toml");
        crate::io::write_atomic(&file, &self.study_text(label, batch, points)?)?;
        let opts = StudyOptions { engine: self.engine.engine, out: Some(gdir.clone()), wait: true, progress: false, plots: false, ..Default::default() };
        let info = study::run_study(&file, &opts, &mut |m| tracing::debug!("{m}"))?;
        let plan = store::read_plan(&gdir)?;
        let ex = &self.problem.experiments;
        if plan.len() != points.len() * ex.len() {
            return Err(ConfigError::invalid(format!(
                "{}: {} runs planned, {} expected",
                gdir.join("plan.json").display(),
                plan.len(),
                points.len() * ex.len()
            ))
            .into());
        }
        let out: Vec<Predictions> =
            (0..points.len()).map(|i| ex.iter().enumerate().map(|(k, e)| prediction(&gdir, &plan[i * ex.len() + k], e)).collect()).collect();
        let failed: usize = out.iter().map(|p| p.iter().filter(|r| r.is_err()).count()).sum();
        tracing::info!(
            "batch {batch} ({label}): {} set{} × {} experiment{} = {} runs ({} run now, {} found done, {failed} failed) in {:.2} s",
            points.len(),
            if points.len() == 1 { "" } else { "s" },
            ex.len(),
            if ex.len() == 1 { "" } else { "s" },
            plan.len(),
            info.executed,
            plan.len() - info.executed,
            wall.elapsed().as_secs_f64()
        );
        Ok((out, info.executed))
    }

    /// A generation through a study costs latency (a queue, the slowest run), so the local
    /// phase's Jacobian points ride along with each cost evaluation.
    fn speculative_jacobian(&self) -> bool {
        true
    }
}

/// Runs the chosen experiments on the compact and writes `compact_validation.csv`.
pub fn validate(
    section: &CompactSection,
    calib_dir: &Path,
    material: &Material,
    factors: &PathFactors,
    start_factors: &PathFactors,
    experiments: &[Experiment],
    predictions: &[Result<Prediction, ModelError>],
    out: &Path,
    log: &mut dyn FnMut(&str),
) -> Result<PathBuf, Error> {
    let case_path = section.case_path(calib_dir, "--validate-compact")?;
    let chosen = section.chosen(experiments)?;
    let dir = out.join("compact");
    crate::io::ensure_dir(&dir)?;
    let (case, _) = derived_case(&case_path, material, factors, start_factors, &section.overrides)?;
    let case_file = dir.join("case.toml");
    let text = toml::to_string(&case).map_err(|e| IoError::new(&case_file, e))?;
    crate::io::manifest::record(&case_file)?;
    std::fs::write(&case_file, format!("# {} with the pair-calibrated material (sinterdem calibrate --validate-compact)\n{text}", case_path.display()))
        .map_err(|e| IoError::new(&case_file, e))?;
    let list = |f: &dyn Fn(&Experiment) -> String| chosen.iter().map(|&i| f(&experiments[i])).collect::<Vec<_>>().join(", ");
    let q = |s: &str| toml::Value::String(s.to_string()).to_string();
    let study_text = format!(
        "title = \"compact validation\"\nbase = \"case.toml\"\n[design]\nkind = \"zip\"\n\
         [[parameters]]\nkey = \"title\"\nname = \"id\"\nvalues = [{}]\n\
         [[parameters]]\nkey = \"thermal.furnace.profile.schedule\"\nname = \"schedule\"\nvalues = [{}]\n\
         [[parameters]]\nkey = \"time.end\"\nname = \"end_s\"\nvalues = [{}]\n\
         [collect]\nsummary = [\"shrinkage_x\", \"shrinkage_y\", \"shrinkage_z\", \"relative_density\", \"neck_ratio\", \"completed\"]\n",
        list(&|e| q(&e.id)),
        list(&|e| q(&e.schedule)),
        list(&|e| format!("{:?}", e.profile.duration()))
    );
    let study_file = dir.join("study.toml");
    crate::io::manifest::record(&study_file)?;
    std::fs::write(&study_file, study_text).map_err(|e| IoError::new(&study_file, e))?;
    log(&format!("validate-compact: {} experiment(s) on {} ({})", chosen.len(), case_path.display(), study_file.display()));
    let opts = StudyOptions { out: Some(dir.join("study")), progress: true, ..Default::default() };
    let info = study::run_study(&study_file, &opts, log)?;
    let (_, _, plan) = study::prepare(&study_file, &opts)?;
    let mut csv = String::from(
        "id,measured_shrinkage,measured_shrinkage_sigma,pair_shrinkage,compact_shrinkage_mean,compact_shrinkage_x,compact_shrinkage_y,compact_shrinkage_z,compact_relative_density,compact_neck_ratio,status,error\n",
    );
    for (k, run) in plan.iter().enumerate() {
        let e = &experiments[chosen[k]];
        let rec = study::store::read_record(&info.dir, run);
        let s = rec.as_ref().map(|r| &r.summary);
        let f = |key: &str| s.and_then(|s| s[key].as_f64());
        let sh = [f("shrinkage_x"), f("shrinkage_y"), f("shrinkage_z")];
        let mean = if sh.iter().all(Option::is_some) { Some(sh.iter().flatten().sum::<f64>() / 3.0) } else { None };
        let cell = |v: Option<f64>| v.map(|x| format!("{x:?}")).unwrap_or_default();
        let meas = e.end.shrinkage;
        let pair = predictions.get(chosen[k]).and_then(|p| p.as_ref().ok()).map(|p| p.end.shrinkage);
        let (status, err) = match &rec {
            Some(r) => (r.status.clone(), r.error.clone().unwrap_or_default()),
            None => ("missing".into(), String::new()),
        };
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{}\n",
            crate::io::csv_text(&e.id),
            cell(meas.map(|m| m.value)),
            cell(meas.map(|m| m.sigma)),
            cell(pair),
            cell(mean),
            cell(sh[0]),
            cell(sh[1]),
            cell(sh[2]),
            cell(f("relative_density")),
            cell(f("neck_ratio")),
            status,
            crate::io::csv_text(&err)
        ));
        log(&format!(
            "  {}: measured shrinkage {}, pair {}, compact {} (x/y/z {}/{}/{})",
            e.id,
            cell(meas.map(|m| m.value)),
            cell(pair),
            cell(mean),
            cell(sh[0]),
            cell(sh[1]),
            cell(sh[2])
        ));
    }
    let path = out.join("compact_validation.csv");
    crate::io::manifest::record(&path)?;
    std::fs::write(&path, csv).map_err(|e| IoError::new(&path, e))?;
    Ok(path)
}

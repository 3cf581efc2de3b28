//! The study file (docs/studies.md): a base case or a list of case files, parameters over any case
//! key, a design, what to collect and how to run. Parsed with `deny_unknown_fields`; every number is
//! checked against [`RANGES`], whose error names the key, value, allowed range and unit.

use crate::config::from_value;
use crate::config::ranges::{Range, c, p};
use crate::error::{ConfigError, Error, IoError};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// Every numeric key of a study file with its allowed interval and unit (docs/studies.md is
/// checked against this table by a test).
pub const RANGES: &[Range] = &[
    c("parameters.*.num", 1.0, 1e6, "1", "number of values of a `range` (linear or logarithmic spacing)"),
    c("design.samples", 1.0, 1e6, "1", "number of Latin-hypercube or Sobol points"),
    c("design.seed", 0.0, 4294967295.0, "1", "seed of the Latin-hypercube permutation or the Sobol scrambling"),
    c("engine.jobs", 1.0, 1024.0, "1", "local engine: runs at a time"),
    c("engine.threads", 1.0, 1024.0, "1", "local engine: rayon threads of each run"),
    c("slurm.chunk", 1.0, 1e6, "1", "runs per SLURM array task"),
    c("slurm.cpus_per_task", 1.0, 1024.0, "1", "`--cpus-per-task` of each array task (also its rayon threads)"),
    c("slurm.max_resubmit", 0.0, 100.0, "1", "`--wait`: how often tasks with unfinished runs are resubmitted"),
    p("slurm.poll_seconds", 0.0, 3600.0, "s", "`--wait`: interval between `squeue` polls"),
    c("collect.series.*.times.*", 0.0, 1e12, "s", "times at which a series column is interpolated"),
];

/// Checks `v` of `key` (the `*` form of the table) as `shown` (the concrete key, e.g. with index).
pub fn check(key: &str, shown: &str, v: f64) -> Result<f64, ConfigError> {
    let r = RANGES.iter().find(|r| r.key == key).ok_or_else(|| ConfigError::invalid(format!("internal: study key {key} has no range")))?;
    r.check(shown, v)
}

fn check_int(key: &str, shown: &str, v: f64) -> Result<u64, ConfigError> {
    let v = check(key, shown, v)?;
    if v.fract() != 0.0 {
        return Err(ConfigError::invalid(format!("{shown} = {v}: must be a whole number")));
    }
    Ok(v as u64)
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyFile {
    title: Option<String>,
    /// One base case (path relative to the study file).
    base: Option<String>,
    /// Case files or glob patterns (relative to the study file); the design runs on each.
    cases: Option<Vec<String>>,
    /// Overrides applied to every run before the parameters (`key.path=value`).
    #[serde(default)]
    overrides: Vec<String>,
    #[serde(default)]
    parameters: Vec<ParameterFile>,
    #[serde(default)]
    design: DesignFile,
    #[serde(default)]
    collect: CollectFile,
    #[serde(default)]
    engine: EngineFile,
    #[serde(default)]
    slurm: SlurmFile,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ParameterFile {
    key: String,
    values: Option<Vec<toml::Value>>,
    range: Option<[f64; 2]>,
    num: Option<f64>,
    min: Option<f64>,
    max: Option<f64>,
    #[serde(default)]
    log: bool,
    /// Column name in study.csv (default: the key).
    name: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct DesignFile {
    kind: Option<String>,
    samples: Option<f64>,
    seed: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct CollectFile {
    #[serde(default)]
    summary: Vec<String>,
    #[serde(default)]
    series: Vec<SeriesFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SeriesFile {
    column: String,
    times: Vec<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct EngineFile {
    jobs: Option<f64>,
    threads: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct SlurmFile {
    partition: Option<String>,
    time: Option<String>,
    account: Option<String>,
    cpus_per_task: Option<f64>,
    chunk: Option<f64>,
    #[serde(default)]
    extra: Vec<String>,
    max_resubmit: Option<f64>,
    poll_seconds: Option<f64>,
}

/// How a parameter's values are given.
#[derive(Debug, Clone, PartialEq)]
pub enum Values {
    /// Explicit list (any TOML value: numbers, strings, booleans).
    List(Vec<toml::Value>),
    /// `num` values from `lo` to `hi` inclusive, linearly or logarithmically spaced.
    Range { lo: f64, hi: f64, num: usize, log: bool },
    /// Bounds for Latin-hypercube and Sobol designs (log: uniform in ln).
    Bounds { lo: f64, hi: f64, log: bool },
}

/// One study parameter: a case key and its values.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    pub key: String,
    /// Column name in study.csv.
    pub name: String,
    pub values: Values,
}

/// How parameter values combine into runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DesignKind {
    /// Cartesian product of every parameter's values (last parameter varies fastest).
    Grid,
    /// The i-th run takes the i-th value of every parameter (equal lengths).
    Zip,
    /// Seeded Latin hypercube over the parameters' bounds.
    Lhs { samples: usize, seed: u64 },
    /// Owen-scrambled Sobol points over the parameters' bounds (seed = scrambling).
    Sobol { samples: usize, seed: u64 },
}

/// A series column interpolated at given times.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesCollect {
    pub column: String,
    /// Times [s].
    pub times: Vec<f64>,
}

/// SLURM settings of a study.
#[derive(Debug, Clone, PartialEq)]
pub struct SlurmSettings {
    pub partition: Option<String>,
    /// `--time` (SLURM syntax, e.g. `00:30:00`).
    pub time: Option<String>,
    pub account: Option<String>,
    pub cpus_per_task: usize,
    /// Runs per array task (None: chosen so a task lasts minutes, see docs/studies.md).
    pub chunk: Option<usize>,
    /// Extra `#SBATCH` lines (with or without the `#SBATCH` prefix).
    pub extra: Vec<String>,
    pub max_resubmit: u32,
    /// Interval between `squeue` polls [s].
    pub poll_seconds: f64,
}

/// A validated study.
#[derive(Debug, Clone)]
pub struct Study {
    pub title: String,
    /// The study file (absolute).
    pub path: PathBuf,
    /// The case files the design runs on, in order (absolute paths).
    pub cases: Vec<PathBuf>,
    /// Whether the case files came from the `cases` form (then `case` is a column).
    pub case_column: bool,
    pub overrides: Vec<String>,
    pub parameters: Vec<Parameter>,
    pub design: DesignKind,
    pub collect_summary: Vec<String>,
    pub collect_series: Vec<SeriesCollect>,
    /// Runs at a time on the local engine (0: cores / threads).
    pub jobs: usize,
    /// Rayon threads of each run.
    pub threads: usize,
    pub slurm: SlurmSettings,
}

fn glob_sorted(dir: &Path, pattern: &str) -> Result<Vec<PathBuf>, ConfigError> {
    let full = if Path::new(pattern).is_absolute() { pattern.to_string() } else { dir.join(pattern).to_string_lossy().to_string() };
    let found: Vec<PathBuf> = glob::glob(&full)
        .map_err(|e| ConfigError::invalid(format!("cases = \"{pattern}\": bad pattern: {e}")))?
        .filter_map(Result::ok)
        .filter(|p| p.is_file())
        .collect();
    if found.is_empty() {
        return Err(ConfigError::invalid(format!("cases = \"{pattern}\": no case file matches (looked in {})", dir.display())));
    }
    let mut found = found;
    // natural order: E2B before E10B
    found.sort_by_key(|p| natural_key(&p.to_string_lossy()));
    Ok(found)
}

/// A sort key that orders digit runs by value ("E2B" < "E10B").
fn natural_key(s: &str) -> Vec<(u8, u64, String)> {
    let mut out = Vec::new();
    let mut chars = s.chars().peekable();
    while let Some(&ch) = chars.peek() {
        if ch.is_ascii_digit() {
            let mut n = String::new();
            while let Some(&d) = chars.peek().filter(|d| d.is_ascii_digit()) {
                n.push(d);
                chars.next();
            }
            out.push((0, n.parse().unwrap_or(u64::MAX), n));
        } else {
            let mut t = String::new();
            while let Some(&d) = chars.peek().filter(|d| !d.is_ascii_digit()) {
                t.push(d);
                chars.next();
            }
            out.push((1, 0, t));
        }
    }
    out
}

/// Reads and validates a study file.
pub fn load(path: &Path) -> Result<Study, Error> {
    let f = read_file(path)?;
    let abs = path.canonicalize().map_err(|e| IoError::new(path, e))?;
    let dir = abs.parent().unwrap_or(Path::new("/")).to_path_buf();
    let (cases, case_column) = case_files(&f, &dir)?;
    let (kind, design) = design_of(&f.design)?;
    let sampled = matches!(design, DesignKind::Lhs { .. } | DesignKind::Sobol { .. });
    let parameters = f.parameters.iter().enumerate().map(|(i, pf)| parameter(i, pf, sampled, &kind)).collect::<Result<Vec<_>, _>>()?;
    check_design(design, &kind, &parameters)?;
    check_size(design, &parameters, cases.len())?;
    let series = collect_series(&f.collect)?;
    for o in &f.overrides {
        if !o.contains('=') {
            return Err(ConfigError::invalid(format!("overrides: \"{o}\": expected key.path=value")).into());
        }
    }
    let slurm = slurm_settings(&f.slurm)?;
    Ok(Study {
        title: f.title.clone().unwrap_or_else(|| path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default()),
        path: abs,
        cases,
        case_column,
        overrides: f.overrides.clone(),
        parameters,
        design,
        collect_summary: f.collect.summary.clone(),
        collect_series: series,
        jobs: f.engine.jobs.map(|j| check_int("engine.jobs", "engine.jobs", j)).transpose()?.unwrap_or(0) as usize,
        threads: check_int("engine.threads", "engine.threads", f.engine.threads.unwrap_or(1.0))? as usize,
        slurm,
    })
}

/// The study file parsed (TOML errors with their line).
fn read_file(path: &Path) -> Result<StudyFile, Error> {
    let text = std::fs::read_to_string(path).map_err(|e| IoError::new(path, e))?;
    let table: toml::Table = text.parse().map_err(|e: toml::de::Error| {
        let pos = e.span().map(|s| {
            let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
            format!(" (line {line})")
        });
        ConfigError::invalid(format!("{}{}: {}", path.display(), pos.unwrap_or_default(), e.message()))
    })?;
    Ok(from_value(toml::Value::Table(table), "").map_err(|e| ConfigError::invalid(format!("{}: {e}", path.display())))?)
}

/// The case files of `base` or `cases` (relative to `dir`), and whether `case` is a column.
fn case_files(f: &StudyFile, dir: &Path) -> Result<(Vec<PathBuf>, bool), ConfigError> {
    match (&f.base, &f.cases) {
        (Some(b), None) => {
            let p = dir.join(b);
            if !p.is_file() {
                return Err(ConfigError::invalid(format!("base = \"{b}\": no such case file ({})", p.display())));
            }
            Ok((vec![p], false))
        }
        (None, Some(list)) if !list.is_empty() => {
            let mut all = Vec::new();
            for pat in list {
                for p in glob_sorted(dir, pat)? {
                    if !all.contains(&p) {
                        all.push(p);
                    }
                }
            }
            Ok((all, true))
        }
        (None, Some(_)) => Err(ConfigError::invalid("cases = []: name at least one case file or pattern")),
        (Some(_), Some(_)) => Err(ConfigError::invalid("base and cases are exclusive: give one base case or a list of cases")),
        (None, None) => Err(ConfigError::invalid("a study needs base = \"case.toml\" or cases = [\"pattern\", …]")),
    }
}

/// `[design]`: its kind as written (default grid) and the design.
fn design_of(d: &DesignFile) -> Result<(String, DesignKind), ConfigError> {
    let kind = d.kind.clone().unwrap_or_else(|| "grid".into());
    let samples = |def: Option<f64>| -> Result<usize, ConfigError> {
        Ok(check_int("design.samples", "design.samples", def.ok_or_else(|| ConfigError::invalid(format!("design.kind = \"{kind}\" needs design.samples")))?)?
            as usize)
    };
    let seed = check_int("design.seed", "design.seed", d.seed.unwrap_or(1.0))?;
    let design = match kind.as_str() {
        "grid" => DesignKind::Grid,
        "zip" => DesignKind::Zip,
        "lhs" => DesignKind::Lhs { samples: samples(d.samples)?, seed },
        "sobol" => DesignKind::Sobol { samples: samples(d.samples)?, seed },
        k => return Err(ConfigError::invalid(format!("design.kind = \"{k}\": expected grid, zip, lhs or sobol"))),
    };
    Ok((kind, design))
}

/// The `i`-th `[[parameters]]` entry: values, a range or (`sampled` designs) bounds.
fn parameter(i: usize, pf: &ParameterFile, sampled: bool, kind: &str) -> Result<Parameter, ConfigError> {
    let at = |field: &str| format!("parameters.{i}.{field} (key {})", pf.key);
    if pf.key.trim().is_empty() || pf.key.split('.').any(|k| k.is_empty()) {
        return Err(ConfigError::invalid(format!("parameters.{i}.key = \"{}\": expected a dotted case key such as time.end", pf.key)));
    }
    let values = match (&pf.values, pf.range, pf.min, pf.max) {
        (Some(v), None, None, None) if !sampled => {
            if v.is_empty() {
                return Err(ConfigError::invalid(format!("{} = []: give at least one value", at("values"))));
            }
            Values::List(v.clone())
        }
        (None, Some([lo, hi]), None, None) if !sampled => {
            let num =
                check_int("parameters.*.num", &at("num"), pf.num.ok_or_else(|| ConfigError::invalid(format!("{} is missing: a range needs num", at("num"))))?)?
                    as usize;
            for v in [lo, hi] {
                if !v.is_finite() || (pf.log && v <= 0.0) {
                    return Err(ConfigError::OutOfRange {
                        key: at("range"),
                        value: v,
                        range: if pf.log { "(0, inf) with log = true".into() } else { "finite".into() },
                        unit: "key's unit".into(),
                    });
                }
            }
            Values::Range { lo, hi, num, log: pf.log }
        }
        (None, None, Some(lo), Some(hi)) if sampled => {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) || (pf.log && lo <= 0.0) {
                return Err(ConfigError::invalid(format!(
                    "{} = {lo}, max = {hi}: need finite min < max{}",
                    at("min"),
                    if pf.log { " and min > 0 (log = true)" } else { "" }
                )));
            }
            Values::Bounds { lo, hi, log: pf.log }
        }
        _ if sampled => {
            return Err(ConfigError::invalid(format!("{}: design.kind = \"{kind}\" needs min and max (and optional log) for every parameter", at("min"))));
        }
        _ => {
            return Err(ConfigError::invalid(format!(
                "{}: give either values = [..] or range = [start, stop] with num (min/max are for lhs and sobol designs)",
                at("values")
            )));
        }
    };
    Ok(Parameter { key: pf.key.clone(), name: pf.name.clone().unwrap_or_else(|| pf.key.clone()), values })
}

/// What the design asks of the parameters: Sobol limits, at least one sampled parameter, equal
/// lengths for zip, distinct names.
fn check_design(design: DesignKind, kind: &str, parameters: &[Parameter]) -> Result<(), ConfigError> {
    let sampled = matches!(design, DesignKind::Lhs { .. } | DesignKind::Sobol { .. });
    if let DesignKind::Sobol { samples, .. } = design {
        // sobol_burley's sequence: at most 2^16 points in at most 256 dimensions
        if samples > 65536 {
            return Err(ConfigError::OutOfRange {
                key: "design.samples".into(),
                value: samples as f64,
                range: "[1, 65536] for kind = \"sobol\"".into(),
                unit: "1".into(),
            });
        }
        if parameters.len() > sobol_burley::NUM_DIMENSIONS as usize {
            return Err(ConfigError::invalid(format!(
                "design.kind = \"sobol\": at most {} parameters, got {}",
                sobol_burley::NUM_DIMENSIONS,
                parameters.len()
            )));
        }
    }
    if sampled && parameters.is_empty() {
        return Err(ConfigError::invalid(format!("design.kind = \"{kind}\" needs at least one [[parameters]] with min and max")));
    }
    if let DesignKind::Zip = design {
        let lens: Vec<usize> = parameters.iter().map(|p| super::design::count(&p.values)).collect();
        if lens.windows(2).any(|w| w[0] != w[1]) {
            return Err(ConfigError::invalid(format!("design.kind = \"zip\" needs parameters of equal length; got {lens:?}")));
        }
    }
    let mut names: Vec<&str> = parameters.iter().map(|p| p.name.as_str()).collect();
    names.sort();
    if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
        return Err(ConfigError::invalid(format!("parameter \"{}\" is given twice", w[0])));
    }
    // one key set by two parameters: only the last would be applied, study.csv would show both
    let mut keys: Vec<&str> = parameters.iter().map(|p| p.key.as_str()).collect();
    keys.sort();
    if let Some(w) = keys.windows(2).find(|w| w[0] == w[1]) {
        return Err(ConfigError::invalid(format!("key \"{}\" is set by two [[parameters]]: give it once (values of one parameter)", w[0])));
    }
    if let Some(p) = parameters.iter().find(|p| FIXED_COLUMNS.contains(&p.name.as_str())) {
        return Err(ConfigError::invalid(format!(
            "parameter name \"{}\" (key {}) is a fixed column of study.csv ({}): give it another name = \"…\"",
            p.name,
            p.key,
            FIXED_COLUMNS.join(", ")
        )));
    }
    // values that overflow: a linear range or bounds whose width is not finite (±1.7e308 gives
    // inf at every interior point)
    for (i, p) in parameters.iter().enumerate() {
        if let Values::Range { lo, hi, log: false, .. } | Values::Bounds { lo, hi, log: false } = p.values
            && !(hi - lo).is_finite()
        {
            return Err(ConfigError::invalid(format!(
                "parameters.{i} (key {}): the width {hi:e} - {lo:e} of the range overflows (not finite): the values in between would be inf; use log = true or narrower bounds",
                p.key
            )));
        }
    }
    Ok(())
}

/// The columns of study.csv that a parameter name cannot take.
pub const FIXED_COLUMNS: &[&str] = &["run", "case", "status", "error", "wall_seconds"];

/// The largest design a study expands: runs (points × case files) and values (runs × parameters).
pub const MAX_RUNS: f64 = 1e6;
pub const MAX_VALUES: f64 = 1e8;

/// The size of the design before it is expanded (issue 26, class 7: a 10⁶ × 10³ grid was expanded
/// in memory until the allocator aborted): at most [`MAX_RUNS`] runs and [`MAX_VALUES`] values.
fn check_size(design: DesignKind, parameters: &[Parameter], cases: usize) -> Result<(), ConfigError> {
    let points: f64 = match design {
        DesignKind::Grid => parameters.iter().map(|p| super::design::count(&p.values) as f64).product(),
        DesignKind::Zip => parameters.first().map_or(1.0, |p| super::design::count(&p.values) as f64),
        DesignKind::Lhs { samples, .. } | DesignKind::Sobol { samples, .. } => samples as f64,
    };
    let runs = points * cases.max(1) as f64;
    let values = runs * parameters.len().max(1) as f64;
    if runs > MAX_RUNS || values > MAX_VALUES {
        return Err(ConfigError::invalid(format!(
            "the design has {points:e} points × {cases} case file(s) = {runs:e} runs of {} parameter(s) ({values:e} values); a study holds at most {MAX_RUNS:e} runs and {MAX_VALUES:e} values (docs/studies.md): split it into several studies",
            parameters.len()
        )));
    }
    Ok(())
}

/// `[collect]`: the series columns with their times; something must be collected.
fn collect_series(c: &CollectFile) -> Result<Vec<SeriesCollect>, ConfigError> {
    let mut series = Vec::new();
    for (i, s) in c.series.iter().enumerate() {
        if s.times.is_empty() {
            return Err(ConfigError::invalid(format!("collect.series.{i}.times = []: give at least one time")));
        }
        for (j, &t) in s.times.iter().enumerate() {
            check("collect.series.*.times.*", &format!("collect.series.{i}.times.{j}"), t)?;
        }
        series.push(SeriesCollect { column: s.column.clone(), times: s.times.clone() });
    }
    if c.summary.is_empty() && series.is_empty() {
        return Err(ConfigError::invalid("[collect] names nothing: give summary = [\"key\", …] and/or series = [{ column = …, times = […] }]"));
    }
    Ok(series)
}

/// `[slurm]` with its defaults.
fn slurm_settings(s: &SlurmFile) -> Result<SlurmSettings, ConfigError> {
    Ok(SlurmSettings {
        partition: s.partition.clone(),
        time: s.time.clone(),
        account: s.account.clone(),
        cpus_per_task: check_int("slurm.cpus_per_task", "slurm.cpus_per_task", s.cpus_per_task.unwrap_or(1.0))? as usize,
        chunk: s.chunk.map(|c| check_int("slurm.chunk", "slurm.chunk", c)).transpose()?.map(|c| c as usize),
        extra: s.extra.clone(),
        max_resubmit: check_int("slurm.max_resubmit", "slurm.max_resubmit", s.max_resubmit.unwrap_or(3.0))? as u32,
        poll_seconds: check("slurm.poll_seconds", "slurm.poll_seconds", s.poll_seconds.unwrap_or(5.0))?,
    })
}

/// Markdown table of the study keys (docs/studies.md).
pub fn markdown() -> String {
    let mut s = String::from("| key | range | unit | meaning |\n|---|---|---|---|\n");
    for r in RANGES {
        s.push_str(&format!("| `{}` | {} | {} | {} |\n", r.key, r.describe(), r.unit, r.meaning));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_puts_e2_before_e10() {
        let mut v = vec!["E10B.toml", "E2B.toml", "E1B.toml"];
        v.sort_by_key(|s| natural_key(s));
        assert_eq!(v, vec!["E1B.toml", "E2B.toml", "E10B.toml"]);
    }
}

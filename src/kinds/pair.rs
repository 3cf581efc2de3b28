//! Two-particle runs (`kind = "pair"` case files): one 7-DOF contact between two spheres under a
//! heating profile. This is how diffusion data are calibrated against neck and shrinkage
//! measurements before simulating a compact. Entry points for the CLI: [`run_pair_case`] and
//! [`check_pair_case`]. Schema: `docs/diffusion7.md`.

use crate::config::from_value;
use crate::models::diffusion7::advance::{PairMaterials, SolverOptions, TemperaturePath, advance_while, calibrated_range_warning};
use crate::models::diffusion7::contact::{Contact7, sintering_force};
use crate::models::diffusion7::kinetics::invariants;
use crate::models::diffusion7::material::{Material, PathFactors};

/// Checks a pair-case key (the 7-DOF model's table, then the shared keys).
fn check(key: &str, v: f64) -> Result<f64, ConfigError> {
    crate::config::ranges::check_in(crate::models::diffusion7::RANGES, key, v)
}

fn check_opt(key: &str, v: Option<f64>) -> Result<Option<f64>, ConfigError> {
    v.map(|v| check(key, v)).transpose()
}
use crate::error::{ConfigError, Error, IoError, ModelError};
use crate::models::ode::OdeStats;
use crate::plot::{Plot, Series};
use crate::profile::Profile;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseFile {
    kind: String,
    #[serde(default)]
    title: Option<String>,
    #[serde(default)]
    description: Option<String>,
    pair: PairSection,
    temperature: TemperatureSection,
    #[serde(default)]
    model: PathFactors,
    #[serde(default)]
    solver: SolverOptions,
    #[serde(default)]
    output: OutputSection,
    #[serde(default)]
    materials: Vec<toml::Value>,
    #[serde(default)]
    load: Option<LoadSection>,
}

/// `[load]`: a constant mechanical normal force on the pair's grain boundary (docs/pressure.md).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct LoadSection {
    /// F_n [N], compressive positive (pushes the centres together), negative: tension.
    force: f64,
}

/// `[pair]`: the two spheres and the run length.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct PairSection {
    material: String,
    #[serde(default)]
    material_b: Option<String>,
    radius: f64,
    #[serde(default)]
    radius_b: Option<f64>,
    #[serde(default)]
    overlap: f64,
    #[serde(default = "default_eps")]
    neck_epsilon: f64,
    #[serde(default = "default_eta")]
    cone_eta: f64,
    #[serde(default)]
    end_time: Option<f64>,
}

fn default_eps() -> f64 {
    crate::models::diffusion7::contact::DEFAULT_EPSILON
}
fn default_eta() -> f64 {
    crate::models::diffusion7::contact::DEFAULT_ETA
}

/// `[temperature]`: exactly one of `constant`, `schedule`, `table`, or the ramp keys.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct TemperatureSection {
    constant: Option<f64>,
    schedule: Option<String>,
    table: Option<Vec<[f64; 2]>>,
    start_temperature: Option<f64>,
    peak_temperature: Option<f64>,
    heating_rate: Option<f64>,
    hold_time: Option<f64>,
    cooling_rate: Option<f64>,
    end_temperature: Option<f64>,
}

/// `[output]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct OutputSection {
    /// Write every n-th accepted substep to `series.csv`.
    series_every: f64,
    /// Write `neck_shrinkage.png`.
    plot: bool,
}

impl Default for OutputSection {
    fn default() -> Self {
        OutputSection { series_every: 1.0, plot: true }
    }
}

/// The contact temperature of a pair run.
#[derive(Debug, Clone, PartialEq)]
pub enum PairTemperature {
    Constant(f64),
    Profile(Profile),
}

impl PairTemperature {
    pub fn path(&self) -> TemperaturePath<'_> {
        match self {
            PairTemperature::Constant(t) => TemperaturePath::Constant(*t),
            PairTemperature::Profile(p) => TemperaturePath::Profile(p),
        }
    }
}

/// A validated pair case.
#[derive(Debug, Clone, PartialEq)]
pub struct PairSpec {
    pub title: String,
    pub material_a: Material,
    pub material_b: Material,
    /// Radii R_A, R_B [m].
    pub radius_a: f64,
    pub radius_b: f64,
    /// Centre distance = (R_A + R_B)(1 − overlap) [1].
    pub overlap: f64,
    /// ε, η of (I2) [1].
    pub neck_epsilon: f64,
    pub cone_eta: f64,
    /// Simulated time [s].
    pub end_time: f64,
    pub temperature: PairTemperature,
    pub factors: PathFactors,
    pub solver: SolverOptions,
    pub series_every: usize,
    pub plot: bool,
    /// Constant normal force on the grain boundary [N], compressive positive (`load.force`;
    /// docs/diffusion7.md (M11)); 0 without a `[load]` section.
    pub normal_force: f64,
}

/// The ramp of docs/diffusion7.md §9: heat from `start` to `peak` at `heat` K/s, hold `hold` s, cool at `cool` K/s
/// to `end` (no cooling branch when `cool` is None). Returns a piecewise-linear profile.
pub fn ramp_profile(start: f64, peak: f64, heat: f64, hold: f64, cool: Option<f64>, end: f64) -> Result<Profile, ConfigError> {
    if start > peak {
        return Err(ConfigError::inconsistent("temperature.start_temperature", format!("{start} K is above peak_temperature {peak} K")));
    }
    let mut rows = vec![[0.0, start]];
    let t1 = (peak - start) / heat;
    if t1 > 0.0 {
        rows.push([t1, peak]);
    }
    let t2 = t1 + hold;
    if hold > 0.0 {
        rows.push([t2, peak]);
    }
    if let Some(c) = cool {
        if end > peak {
            return Err(ConfigError::inconsistent("temperature.end_temperature", format!("{end} K is above peak_temperature {peak} K")));
        }
        if end < peak {
            rows.push([t2 + (peak - end) / c, end]);
        }
    }
    Profile::from_table(&rows)
}

fn build_temperature(t: &TemperatureSection) -> Result<PairTemperature, ConfigError> {
    let ramp = t.peak_temperature.is_some()
        || t.start_temperature.is_some()
        || t.heating_rate.is_some()
        || t.hold_time.is_some()
        || t.cooling_rate.is_some()
        || t.end_temperature.is_some();
    let n = t.constant.is_some() as u8 + t.schedule.is_some() as u8 + t.table.is_some() as u8 + ramp as u8;
    if n != 1 {
        return Err(ConfigError::inconsistent(
            "temperature",
            "give exactly one of: constant, schedule, table, or the ramp keys (start_temperature, peak_temperature, heating_rate, hold_time, cooling_rate, end_temperature)",
        ));
    }
    if let Some(c) = t.constant {
        return Ok(PairTemperature::Constant(check("temperature.constant", c)?));
    }
    if let Some(s) = &t.schedule {
        return Ok(PairTemperature::Profile(Profile::from_schedule(s).map_err(|e| prefix(e, "temperature"))?));
    }
    if let Some(tab) = &t.table {
        return Ok(PairTemperature::Profile(Profile::from_table(tab).map_err(|e| prefix(e, "temperature"))?));
    }
    let need = |k: &str, v: Option<f64>| v.ok_or_else(|| ConfigError::inconsistent(format!("temperature.{k}"), "required by the ramp form"));
    let start = check("temperature.start_temperature", need("start_temperature", t.start_temperature)?)?;
    let peak = check("temperature.peak_temperature", need("peak_temperature", t.peak_temperature)?)?;
    let heat = check("temperature.heating_rate", need("heating_rate", t.heating_rate)?)?;
    let hold = check("temperature.hold_time", t.hold_time.unwrap_or(0.0))?;
    let cool = check_opt("temperature.cooling_rate", t.cooling_rate)?;
    let end = check("temperature.end_temperature", t.end_temperature.unwrap_or(313.0))?;
    if cool.is_none() && t.end_temperature.is_some() {
        return Err(ConfigError::inconsistent("temperature.end_temperature", "needs cooling_rate"));
    }
    Ok(PairTemperature::Profile(ramp_profile(start, peak, heat, hold, cool, end)?))
}

fn prefix(e: ConfigError, p: &str) -> ConfigError {
    match e {
        ConfigError::OutOfRange { key, value, range, unit } => ConfigError::OutOfRange { key: format!("{p}.{key}"), value, range, unit },
        ConfigError::Invalid(m) => ConfigError::Invalid(format!("{p}: {m}")),
        other => other,
    }
}

/// Parses and validates a pair case (`kind = "pair"`).
pub fn parse_pair_case(case: &toml::Value) -> Result<PairSpec, Error> {
    let f: CaseFile = from_value(case.clone(), "")?;
    if f.kind != "pair" {
        return Err(ConfigError::invalid(format!("kind = \"{}\": this entry point runs kind = \"pair\" cases", f.kind)).into());
    }
    let mut inline = Vec::new();
    for (i, v) in f.materials.into_iter().enumerate() {
        // range errors already name `materials.NAME.…` (located by the material's name)
        let m = Material::from_value(v).map_err(|e| match e {
            ConfigError::OutOfRange { ref key, .. } if key.starts_with("materials.") => e,
            e => prefix(e, &format!("materials[{i}]")),
        })?;
        inline.push(m);
    }
    let find = |name: &str| -> Result<Material, ConfigError> {
        match inline.iter().find(|m| m.name == name) {
            Some(m) => Ok(m.clone()),
            None => Material::builtin(name).map_err(|e| prefix(e, "pair.material")),
        }
    };
    let p = &f.pair;
    let material_a = find(&p.material)?;
    let material_b = match &p.material_b {
        Some(n) => find(n)?,
        None => material_a.clone(),
    };
    let radius_a = check("pair.radius", p.radius)?;
    let radius_b = check("pair.radius_b", p.radius_b.unwrap_or(radius_a))?;
    let overlap = check("pair.overlap", p.overlap)?;
    let neck_epsilon = check("pair.neck_epsilon", p.neck_epsilon)?;
    let cone_eta = check("pair.cone_eta", p.cone_eta)?;
    let temperature = build_temperature(&f.temperature)?;
    let end_time = match (p.end_time, &temperature) {
        (Some(t), _) => check("pair.end_time", t)?,
        (None, PairTemperature::Profile(pr)) if pr.duration() > 0.0 => pr.duration(),
        _ => {
            return Err(ConfigError::inconsistent("pair.end_time", "required when the temperature history has no end").into());
        }
    };
    f.model.validate()?;
    f.solver.validate()?;
    let series_every = check("output.series_every", f.output.series_every)?;
    let spec = PairSpec {
        title: f.title.or(f.description).unwrap_or_else(|| "pair".into()),
        material_a,
        material_b,
        radius_a,
        radius_b,
        overlap,
        neck_epsilon,
        cone_eta,
        end_time,
        temperature,
        factors: f.model,
        solver: f.solver,
        series_every: series_every as usize,
        plot: f.output.plot,
        normal_force: match &f.load {
            Some(l) => check("load.force", l.force)?,
            None => 0.0,
        },
    };
    spec.new_contact()?;
    spec.below_solidus().map_err(|m| ConfigError::inconsistent("pair.end_time", m))?;
    Ok(spec)
}

impl PairSpec {
    /// Refuses a temperature history that reaches the melting (solidus) temperature of either
    /// material before `end_time`: solid-state sintering no longer applies there, and compact runs
    /// stop at the same limit (docs/diffusion7.md "Materials").
    pub fn below_solidus(&self) -> Result<(), String> {
        let tm =
            [&self.material_a, &self.material_b].iter().filter_map(|m| m.melting_temperature.map(|t| (t, m.name.clone()))).min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((tm, name)) = tm else { return Ok(()) };
        let reached = match &self.temperature {
            PairTemperature::Constant(t) => (*t >= tm).then_some(0.0),
            PairTemperature::Profile(p) => p.first_reaching(tm, self.end_time),
        };
        match reached {
            Some(t) => Err(format!(
                "= {} s: the temperature history reaches {tm} K, the melting (solidus) temperature of \"{name}\", at t = {} s; solid-state sintering no longer applies there (end the run before, or lower the peak)",
                crate::error::fmt_value(self.end_time),
                crate::error::fmt_value(t)
            )),
            None => Ok(()),
        }
    }

    /// The contact at t = 0 (I1)–(I4).
    pub fn new_contact(&self) -> Result<Contact7, ModelError> {
        let d_ab = (self.radius_a + self.radius_b) * (1.0 - self.overlap);
        let mut c = Contact7::new(self.radius_a, self.radius_b, d_ab, 0.0, self.neck_epsilon, self.cone_eta)?;
        c.normal_force = self.normal_force;
        Ok(c)
    }

    /// Materials and factors of the contact.
    pub fn materials(&self) -> PairMaterials<'_> {
        PairMaterials { a: &self.material_a, b: &self.material_b, factors: self.factors }
    }
}

/// The result of a pair run.
#[derive(Debug, Clone)]
pub struct PairRun {
    /// Recorded times [s], states [m] and temperatures [K] (t = 0 first); empty if not recorded.
    pub times: Vec<f64>,
    pub states: Vec<[f64; 7]>,
    pub temperatures: Vec<f64>,
    /// Final contact.
    pub contact: Contact7,
    /// Initial solid volume V(Y0) [m³].
    pub volume0: f64,
    pub stats: OdeStats,
    /// Wall time of the integration alone [s].
    pub wall_seconds: f64,
    pub warnings: Vec<String>,
    /// The time the run was interrupted at ([`crate::interrupt`]) [s]; None: it reached its end.
    pub interrupted_at: Option<f64>,
}

impl PairRun {
    /// Relative volume drift |V(Y_end) − V(Y0)|/V(Y0) [1].
    pub fn volume_drift(&self) -> f64 {
        let v = crate::models::diffusion7::geometry::volume_and_areas(&self.contact.y).map(|x| x.0).unwrap_or(f64::NAN);
        (v - self.volume0).abs() / self.volume0
    }
}

/// Integrates the pair of `spec` from 0 to its end time. `record` keeps every `series_every`-th
/// accepted substep; `progress` prints a line every 10 % of the simulated time to stderr.
pub fn run_pair(spec: &PairSpec, record: bool, progress: bool) -> Result<PairRun, ModelError> {
    run_pair_keeping(spec, record, progress).map_err(|(e, _)| e)
}

/// [`run_pair`] that, when the integration fails part-way, returns with the error the run up to
/// the failure (its rows so far; `interrupted_at`: the last accepted time), so that a failed run
/// keeps what it computed (issue 39).
pub fn run_pair_keeping(spec: &PairSpec, record: bool, progress: bool) -> Result<PairRun, (ModelError, Option<Box<PairRun>>)> {
    let mut contact = spec.new_contact().map_err(|e| (e, None))?;
    let (v0, _) = crate::models::diffusion7::geometry::volume_and_areas(&contact.y).map(|(v, a, g)| (v, a + g)).map_err(|e| (e, None))?;
    let mats = spec.materials();
    let path = spec.temperature.path();
    let mut times = Vec::new();
    let mut states = Vec::new();
    let mut temps = Vec::new();
    if record {
        times.push(0.0);
        states.push(contact.y);
        temps.push(path.at(0.0));
    }
    let (mut tlo, mut thi) = (path.at(0.0), path.at(0.0));
    let mut stats = OdeStats::default();
    let every = spec.series_every.max(1) as u64;
    let mut count: u64 = 0;
    let end = spec.end_time;
    let bar = crate::io::progress::Progress::new(end, progress);
    let start = std::time::Instant::now();
    let res = advance_while(&mut contact, &mats, &path, 0.0, end, &spec.solver, &mut stats, |t, y, temp| {
        count += 1;
        tlo = tlo.min(temp);
        thi = thi.max(temp);
        // a stop request ends the run after this substep, whose state is then the series' last row
        let go_on = t >= end || !crate::interrupt::requested();
        if record && (count.is_multiple_of(every) || t >= end || !go_on) {
            times.push(t);
            states.push(*y);
            temps.push(temp);
        }
        if count.is_multiple_of(64) || t >= end {
            bar.set(t, &format!("T = {temp:.1} K, y1/R = {:.5}", y[0] / spec.radius_a.min(spec.radius_b)));
        }
        go_on
    });
    bar.finish();
    let wall_seconds = start.elapsed().as_secs_f64();
    let interrupted_at = match res {
        Ok(t) => t,
        Err(e) => {
            let last = times.last().copied().unwrap_or(0.0);
            // the contact as at the last row (the summary's neck ratio, shrinkage, drift)
            if let Some(y) = states.last() {
                contact.y = *y;
            }
            let run =
                PairRun { times, states, temperatures: temps, contact, volume0: v0, stats, wall_seconds, warnings: Vec::new(), interrupted_at: Some(last) };
            return Err((e, Some(Box::new(run))));
        }
    };
    let mut warnings = Vec::new();
    for m in [&spec.material_a, &spec.material_b] {
        if let Some(w) = calibrated_range_warning(m, tlo, thi)
            && !warnings.contains(&w)
        {
            warnings.push(w);
        }
    }
    Ok(PairRun { times, states, temperatures: temps, contact, volume0: v0, stats, wall_seconds, warnings, interrupted_at })
}

/// `summary.json` of a pair run.
#[derive(Debug, Clone, Serialize)]
pub struct PairSummary {
    pub title: String,
    pub final_time_s: f64,
    /// Accepted substeps.
    pub steps: u64,
    pub rejected_steps: u64,
    pub rhs_evaluations: u64,
    pub wall_seconds: f64,
    /// y1/R_min at the end [1].
    pub neck_ratio: f64,
    /// ΔL/L0 at the end [1].
    pub shrinkage: f64,
    /// |V − V0|/V0 at the end [1].
    pub volume_drift_rel: f64,
    /// Virtual sintering force (F4) at the end [N] (not a physical force, docs/diffusion7.md §5).
    pub virtual_force_n: f64,
    pub method: String,
    pub rtol: f64,
    pub warnings: Vec<String>,
    /// false when the run stopped before `end_time` (absent: it reached it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub completed: Option<bool>,
    /// Why it stopped early ("interrupted"; "error": a model error, in `error`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_reason: Option<String>,
    /// The error that ended a failed run (absent: none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// Validates a pair case without running it (`sinterdem check`).
pub fn check_pair_case(case: &toml::Value) -> Result<(), Error> {
    parse_pair_case(case).map(|_| ())
}

/// Runs a pair case and writes `series.csv`, `summary.json` and `neck_shrinkage.png` into `out_dir`.
pub fn run_pair_case(case: &toml::Value, out_dir: &Path, progress: bool) -> Result<PairSummary, Error> {
    let spec = parse_pair_case(case)?;
    run_pair_spec(&spec, out_dir, progress, &mut |w| tracing::warn!("{w}"))
}

/// Runs a parsed pair case and writes its outputs into `out_dir` (as [`run_pair_case`]); warnings
/// go to `warn`.
pub fn run_pair_spec(spec: &PairSpec, out_dir: &Path, progress: bool, warn: &mut dyn FnMut(&str)) -> Result<PairSummary, Error> {
    std::fs::create_dir_all(out_dir).map_err(|e| IoError::new(out_dir, e))?;
    let run = match run_pair_keeping(spec, true, progress) {
        Ok(run) => run,
        Err((e, partial)) => {
            // a failed run keeps what it computed: the rows up to the failure and a summary
            // with completed = false and the error (issue 39); the error is the run's result
            if let Some(run) = partial {
                let _ = write_series(spec, &run, &out_dir.join("series.csv"));
                let mut summary = summarize(spec, &run);
                summary.stop_reason = Some(format!("model error after t = {} s", run.interrupted_at.unwrap_or(0.0)));
                summary.error = Some(e.to_string());
                if let Ok(json) = serde_json::to_string_pretty(&summary) {
                    let _ = crate::io::write_atomic(&out_dir.join("summary.json"), &(json + "\n"));
                }
            }
            return Err(e.into());
        }
    };
    for w in &run.warnings {
        warn(w);
    }
    write_series(spec, &run, &out_dir.join("series.csv"))?;
    let summary = summarize(spec, &run);
    let json = serde_json::to_string_pretty(&summary).map_err(|e| IoError::new(out_dir.join("summary.json"), e))?;
    crate::io::write_atomic(&out_dir.join("summary.json"), &(json + "\n"))?;
    if spec.plot {
        plot_run(spec, &run).save_png_or_warn(&out_dir.join("neck_shrinkage.png"));
    }
    Ok(summary)
}

/// The summary of a finished run.
pub fn summarize(spec: &PairSpec, run: &PairRun) -> PairSummary {
    let c = &run.contact;
    // E at the pair's last temperature (the library's E(T), docs/materials.md (L1))
    let t_end = run.temperatures.last().copied().unwrap_or(f64::NAN);
    let e_at = |m: &crate::models::diffusion7::Material| if t_end.is_finite() { m.young_modulus_at(t_end) } else { m.young_modulus };
    let e = 0.5 * (e_at(&spec.material_a) + e_at(&spec.material_b));
    PairSummary {
        title: spec.title.clone(),
        final_time_s: run.interrupted_at.unwrap_or(spec.end_time),
        steps: run.stats.steps,
        rejected_steps: run.stats.rejected,
        rhs_evaluations: run.stats.rhs,
        wall_seconds: run.wall_seconds,
        neck_ratio: c.neck_ratio(),
        shrinkage: c.shrinkage(),
        volume_drift_rel: run.volume_drift(),
        virtual_force_n: sintering_force(c.l0, c.y[3], c.y[6], c.r_mean(), e),
        method: spec.solver.method.name().into(),
        rtol: spec.solver.rtol,
        warnings: run.warnings.clone(),
        completed: run.interrupted_at.map(|_| false),
        stop_reason: run.interrupted_at.map(|_| "interrupted".to_string()),
        error: None,
    }
}

fn write_series(spec: &PairSpec, run: &PairRun, path: &Path) -> Result<(), Error> {
    let io = |e: std::io::Error| IoError::new(path, e);
    crate::io::manifest::record(path)?;
    let f = std::fs::File::create(path).map_err(io)?;
    let mut w = std::io::BufWriter::new(f);
    writeln!(w, "time_s,temperature_K,neck_ratio,shrinkage,y1_m,y2_m,y3_m,y4_m,y5_m,y6_m,y7_m,free_energy_J,volume_drift_rel").map_err(io)?;
    let mats = spec.materials();
    let rmin = spec.radius_a.min(spec.radius_b);
    let l0 = run.contact.l0;
    for ((t, y), temp) in run.times.iter().zip(&run.states).zip(&run.temperatures) {
        let (v, g) = invariants(y, &mats.params_at(*temp))?;
        write!(w, "{t:.10e},{temp:.6},{:.10e},{:.10e}", y[0] / rmin, (l0 - y[3] - y[6]) / l0).map_err(io)?;
        for v in y {
            write!(w, ",{v:.12e}").map_err(io)?;
        }
        writeln!(w, ",{g:.10e},{:.3e}", (v - run.volume0) / run.volume0).map_err(io)?;
    }
    w.flush().map_err(io)?;
    Ok(())
}

/// The key settings of a pair run for its plots' subtitle: materials, radii, peak temperature,
/// simulated time and load.
pub fn plot_subtitle(spec: &PairSpec, peak_temperature: f64) -> String {
    use crate::plot::{fmt_length, fmt_time};
    let mat = if spec.material_a.name == spec.material_b.name {
        spec.material_a.name.clone()
    } else {
        format!("{} and {}", spec.material_a.name, spec.material_b.name)
    };
    let radii = if spec.radius_a == spec.radius_b {
        format!("two spheres of radius {}", fmt_length(spec.radius_a))
    } else {
        format!("radii {} and {}", fmt_length(spec.radius_a), fmt_length(spec.radius_b))
    };
    let mut s = format!("{mat}, {radii}, up to {peak_temperature:.0} K, {}", fmt_time(spec.end_time));
    if spec.normal_force != 0.0 {
        s.push_str(&format!(", load {:.3e} N", spec.normal_force));
    }
    s
}

/// The neck-and-shrinkage plot of a pair run: both on log axes against time [s] (the neck grows
/// by decades), in plain words.
fn plot_run(spec: &PairSpec, run: &PairRun) -> Plot {
    let rmin = spec.radius_a.min(spec.radius_b);
    let l0 = run.contact.l0;
    let peak = run.temperatures.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut p = Plot::new(format!("{}: neck growth and shrinkage", spec.title))
        .subtitle(plot_subtitle(spec, peak))
        .labels("time [s] (log scale)", "ratio (log scale)")
        .log_x(true)
        .log_y(true);
    p.add(Series::new("neck radius / smaller particle radius", run.times.iter().zip(&run.states).map(|(t, y)| (*t, y[0] / rmin)).collect()));
    p.add(Series::new(
        "shrinkage: approach / initial centre distance",
        run.times.iter().zip(&run.states).map(|(t, y)| (*t, (l0 - y[3] - y[6]) / l0)).collect(),
    ));
    p
}

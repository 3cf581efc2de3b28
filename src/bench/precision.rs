//! `sinterdem bench precision`: run time against error of the coupled loop (docs/coupled.md,
//! "Run time against error").
//!
//! Each case runs once with tight settings (the reference) and then over a ladder of settings, one
//! knob at a time away from the defaults: the 7-DOF `solver.rtol`, `time.dt_max`, the strategy-2
//! subdivision thresholds `time.grow_below`/`time.shrink_above`, `contacts.detect_every`, and
//! strategy 1. The error of each run is the relative difference to the reference at the end time
//! in shrinkage per axis, mean neck ratio and relative density; with its wall time it gives a
//! work-precision diagram (CSV + PNG per case). A run is on the Pareto front when no other run of
//! the case is both faster and more accurate (largest shrinkage error).

use crate::error::{Error, IoError};
use crate::plot::{Plot, Series};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One rung of the ladder: a family (the knob), a label and its `--set` overrides.
#[derive(Debug, Clone)]
pub struct Variant {
    pub family: &'static str,
    pub label: String,
    pub sets: Vec<String>,
}

impl Variant {
    fn new(family: &'static str, label: impl Into<String>, sets: &[&str]) -> Variant {
        Variant { family, label: label.into(), sets: sets.iter().map(|s| s.to_string()).collect() }
    }
}

/// The tight reference settings: 7-DOF rtol 1e-9, mechanics rtol 1e-12, Δt ≤ 1 s, grow below 1 % and shrink above 5 %
/// of contacts subdivided, detection every step.
pub fn reference_sets() -> Vec<String> {
    [
        "solver.rtol=1e-9",
        "mechanics.rtol=1e-12",
        "time.dt_max=1.0",
        "time.grow_below=0.01",
        "time.shrink_above=0.05",
        "time.strategy=2",
        "contacts.detect_every=1",
    ]
    .map(String::from)
    .to_vec()
}

/// The ladder: the case's own settings, then one knob at a time.
pub fn ladder() -> Vec<Variant> {
    let mut v = vec![Variant::new("defaults", "case settings", &[])];
    for r in ["1e-4", "1e-5", "1e-7", "1e-8"] {
        v.push(Variant::new("7-DOF rtol", format!("rtol {r}"), &[&format!("solver.rtol={r}")]));
    }
    for r in ["1e-6", "1e-8"] {
        v.push(Variant::new("mechanics rtol", format!("mechanics rtol {r}"), &[&format!("mechanics.rtol={r}")]));
    }
    for d in ["2.0", "5.0", "20.0", "50.0"] {
        v.push(Variant::new("dt_max", format!("dt_max {d} s"), &[&format!("time.dt_max={d}")]));
    }
    for (g, s) in [("0.02", "0.06"), ("0.1", "0.3"), ("0.2", "0.5")] {
        v.push(Variant::new("thresholds", format!("grow < {g}, shrink > {s}"), &[&format!("time.grow_below={g}"), &format!("time.shrink_above={s}")]));
    }
    for d in ["2", "5", "10", "20"] {
        v.push(Variant::new("detect_every", format!("detect every {d}"), &[&format!("contacts.detect_every={d}")]));
    }
    v.push(Variant::new("strategy 1", "strategy 1, dt_max 100 s", &["time.strategy=1", "time.dt_max=100.0"]));
    v.push(Variant::new("strategy 1", "strategy 1, dt_max 10 s", &["time.strategy=1", "time.dt_max=10.0"]));
    v
}

/// The measured outcome of one run.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The knob of the ladder and the rung's label.
    pub family: String,
    pub label: String,
    /// Wall time of the run [s].
    pub wall_seconds: f64,
    /// Accepted global steps and numeric factorisations [1].
    pub steps: u64,
    pub factorizations: u64,
    /// Shrinkage per axis (docs/coupled.md (S6) box), mean neck ratio y1/R, relative density
    /// (S6) at the end [1].
    pub shrinkage: [f64; 3],
    pub neck_ratio: f64,
    pub relative_density: f64,
    /// Relative errors |v − v_ref|/|v_ref| against the reference [1] (filled after the reference
    /// is known).
    pub err_shrinkage: [f64; 3],
    pub err_neck_ratio: f64,
    pub err_relative_density: f64,
    /// No other run of the case is both faster and more accurate (largest shrinkage error).
    pub pareto: bool,
    /// Failure message, if the run failed.
    pub error: Option<String>,
}

impl Outcome {
    /// Largest relative shrinkage error over the three axes [1].
    pub fn err_shrinkage_max(&self) -> f64 {
        self.err_shrinkage.iter().copied().fold(0.0, f64::max)
    }
}

fn run_one(value: &toml::Value, base: &Path, sets: &[String], dir: &Path, family: &str, label: &str, wall_limit: Option<f64>) -> Outcome {
    let mut all: Vec<String> =
        ["output.snapshots=0", "output.vtu=false", "output.hdf5=false", "output.checkpoint_every=0", "output.conductivity_at=[]"].map(String::from).to_vec();
    all.extend(sets.iter().cloned());
    let params = crate::kinds::RunParams { base_dir: base.to_path_buf(), plots: false, wall_limit, force: true, ..Default::default() };
    let mut o = Outcome {
        family: family.into(),
        label: label.into(),
        wall_seconds: f64::NAN,
        steps: 0,
        factorizations: 0,
        shrinkage: [f64::NAN; 3],
        neck_ratio: f64::NAN,
        relative_density: f64::NAN,
        err_shrinkage: [f64::NAN; 3],
        err_neck_ratio: f64::NAN,
        err_relative_density: f64::NAN,
        pareto: false,
        error: None,
    };
    match crate::kinds::run(value, &all, dir, &params) {
        Ok(r) => {
            let s = &r.summary;
            let f = |k: &str| s[k].as_f64().unwrap_or(f64::NAN);
            o.wall_seconds = r.wall_seconds;
            o.steps = s["steps"].as_u64().unwrap_or(0);
            o.factorizations = s["mechanics"]["factorizations"].as_u64().unwrap_or(0);
            o.shrinkage = [f("shrinkage_x"), f("shrinkage_y"), f("shrinkage_z")];
            o.neck_ratio = f("neck_ratio");
            o.relative_density = f("relative_density");
            if s["completed"].as_bool() != Some(true) {
                o.error = Some(format!("stopped early: {}", s["stop_reason"]));
            }
        }
        Err(e) => o.error = Some(e.to_string()),
    }
    let _ = std::fs::remove_dir_all(dir);
    o
}

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

/// Marks the runs of `runs` that no other run beats in both wall time and largest shrinkage error.
pub fn mark_pareto(runs: &mut [Outcome]) {
    let keys: Vec<(f64, f64)> = runs.iter().map(|o| (o.wall_seconds, o.err_shrinkage_max())).collect();
    for (i, o) in runs.iter_mut().enumerate() {
        let (w, e) = keys[i];
        o.pareto = o.error.is_none()
            && w.is_finite()
            && e.is_finite()
            && !keys.iter().enumerate().any(|(j, &(w2, e2))| j != i && w2 <= w && e2 <= e && (w2 < w || e2 < e));
    }
}

/// A corner of the packing file of `case` (particles with x, y below `edge` and z below `height`
/// [m]) written to `dir/corner.csv`; returns its path and particle count.
pub fn corner_packing(case: &toml::Value, base: &Path, edge: f64, height: f64, dir: &Path) -> Result<(PathBuf, usize), Error> {
    let file = case
        .get("particles")
        .and_then(|p| p.get("file"))
        .and_then(|f| f.as_str())
        .ok_or_else(|| crate::error::ConfigError::invalid("bench precision: the E14B corner needs a case with particles.source = \"file\"".to_string()))?;
    let path = base.join(file);
    let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
    let mut out = String::from("x,y,z,r\n");
    let mut n = 0;
    for line in text.lines().filter(|l| !l.starts_with('#') && !l.starts_with('x')) {
        let v: Vec<f64> = line.split(',').filter_map(|s| s.trim().parse().ok()).collect();
        if v.len() >= 4 && v[0] < edge && v[1] < edge && v[2] < height {
            out.push_str(line);
            out.push('\n');
            n += 1;
        }
    }
    crate::io::ensure_dir(dir)?;
    let corner = dir.join("corner.csv");
    crate::io::write_atomic(&corner, &out)?;
    Ok((corner, n))
}

/// Runs the reference and the ladder on one case (`extra` overrides apply to every run, e.g. the
/// corner packing) and returns the outcomes with errors and the Pareto front. A rung gets a
/// wall-time budget of 5× the default settings' run (at least 60 s): beyond it, it is reported as
/// stopped (strategy 1 with new contacts can take a hundred times longer, as in the paper).
/// `partial(reference, runs so far)` is called after every run, so that a killed benchmark keeps
/// what it measured.
pub fn measure(
    name: &str,
    value: &toml::Value,
    base: &Path,
    extra: &[String],
    out: &Path,
    progress: &mut dyn FnMut(&str),
    partial: &mut dyn FnMut(&Outcome, &[Outcome]) -> Result<(), Error>,
) -> Result<(Outcome, Vec<Outcome>), Error> {
    let work = out.join(format!("runs-{name}"));
    let mut sets = extra.to_vec();
    sets.extend(reference_sets());
    progress(&format!("{name}: reference ({})", reference_sets().join(" ")));
    let reference = run_one(value, base, &sets, &work.join("reference"), "reference", "reference", None);
    if let Some(e) = &reference.error {
        return Err(crate::error::ModelError::new(format!("bench precision: the reference run of {name} failed: {e}")).into());
    }
    let mut runs: Vec<Outcome> = Vec::new();
    let mut budget = None;
    for (k, v) in ladder().iter().enumerate() {
        progress(&format!("{name}: {} ({})", v.label, if v.sets.is_empty() { "no overrides".into() } else { v.sets.join(" ") }));
        let mut sets = extra.to_vec();
        sets.extend(v.sets.iter().cloned());
        let mut o = run_one(value, base, &sets, &work.join(format!("{k:02}")), v.family, &v.label, budget);
        if budget.is_none() {
            budget = Some((5.0 * o.wall_seconds).max(60.0));
        }
        for a in 0..3 {
            o.err_shrinkage[a] = rel(o.shrinkage[a], reference.shrinkage[a]);
        }
        o.err_neck_ratio = rel(o.neck_ratio, reference.neck_ratio);
        o.err_relative_density = rel(o.relative_density, reference.relative_density);
        runs.push(o);
        mark_pareto(&mut runs);
        partial(&reference, &runs)?;
    }
    let _ = std::fs::remove_dir_all(&work);
    Ok((reference, runs))
}

/// Header of `precision.csv` (plain, units in the names).
pub const CSV_HEADER: &str = "case,family,settings,wall_s,steps,factorizations,shrinkage_x,shrinkage_y,shrinkage_z,neck_ratio,relative_density,err_shrinkage_x,err_shrinkage_y,err_shrinkage_z,err_shrinkage_max,err_neck_ratio,err_relative_density,pareto,error\n";

/// CSV rows (no header, [`CSV_HEADER`]) of the outcomes of one case.
pub fn csv_rows(case: &str, reference: &Outcome, runs: &[Outcome]) -> String {
    let mut s = String::new();
    for o in std::iter::once(reference).chain(runs) {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            crate::io::csv_text(case),
            crate::io::csv_text(&o.family),
            crate::io::csv_text(&o.label),
            o.wall_seconds,
            o.steps,
            o.factorizations,
            o.shrinkage[0],
            o.shrinkage[1],
            o.shrinkage[2],
            o.neck_ratio,
            o.relative_density,
            cell(o.err_shrinkage[0]),
            cell(o.err_shrinkage[1]),
            cell(o.err_shrinkage[2]),
            cell(o.err_shrinkage_max()),
            cell(o.err_neck_ratio),
            cell(o.err_relative_density),
            o.pareto,
            crate::io::csv_text(o.error.as_deref().unwrap_or("")),
        );
    }
    s
}

fn cell(v: f64) -> String {
    if v.is_finite() { format!("{v}") } else { String::new() }
}

/// The work-precision diagram of one case: largest shrinkage error against wall time, one series
/// per knob; the Pareto front as a line.
pub fn diagram(case: &str, runs: &[Outcome]) -> Plot {
    let mut plot = Plot::new(format!("{case}: run time against error (reference: tight settings)"))
        .labels("wall time [s]", "largest relative shrinkage error [1]")
        .log_x(true)
        .log_y(true);
    let floor = 1e-9;
    let mut families: Vec<&str> = Vec::new();
    for o in runs {
        if !families.contains(&o.family.as_str()) {
            families.push(&o.family);
        }
    }
    for f in families {
        let pts: Vec<(f64, f64)> = runs
            .iter()
            .filter(|o| o.family == f && o.error.is_none() && o.wall_seconds > 0.0)
            .map(|o| (o.wall_seconds, o.err_shrinkage_max().max(floor)))
            .collect();
        if !pts.is_empty() {
            plot.add(Series::new(f, pts).points_only());
        }
    }
    let mut front: Vec<(f64, f64)> = runs.iter().filter(|o| o.pareto).map(|o| (o.wall_seconds, o.err_shrinkage_max().max(floor))).collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    if front.len() > 1 {
        plot.add(Series::new("Pareto front", front));
    }
    plot
}

/// Printed table of one case.
pub fn table(case: &str, reference: &Outcome, runs: &[Outcome]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{case}: reference {:.2} s, {} steps, shrinkage {:.5e} {:.5e} {:.5e}, neck ratio {:.5}, relative density {:.5}",
        reference.wall_seconds,
        reference.steps,
        reference.shrinkage[0],
        reference.shrinkage[1],
        reference.shrinkage[2],
        reference.neck_ratio,
        reference.relative_density
    );
    let _ = writeln!(
        s,
        "  {:<28} {:>8} {:>6} {:>6} {:>10} {:>10} {:>10} {:>10} {:>10} {:>6}",
        "settings", "wall s", "steps", "fact", "err sx", "err sy", "err sz", "err neck", "err rho", "pareto"
    );
    for o in runs {
        match &o.error {
            Some(e) => {
                let _ = writeln!(s, "  {:<28} failed: {e}", o.label);
            }
            None => {
                let _ = writeln!(
                    s,
                    "  {:<28} {:>8.2} {:>6} {:>6} {:>10.2e} {:>10.2e} {:>10.2e} {:>10.2e} {:>10.2e} {:>6}",
                    o.label,
                    o.wall_seconds,
                    o.steps,
                    o.factorizations,
                    o.err_shrinkage[0],
                    o.err_shrinkage[1],
                    o.err_shrinkage[2],
                    o.err_neck_ratio,
                    o.err_relative_density,
                    if o.pareto { "*" } else { "" }
                );
            }
        }
    }
    s
}

/// `sinterdem bench precision`: the copper compact and a corner of the E14B titanium packing
/// (`None` skips one), results in `out/precision.csv` and `out/precision-CASE.png`/`.svg`.
pub fn bench_precision(copper: Option<&Path>, e14b: Option<&Path>, corner_edge: f64, out: &Path, progress: &mut dyn FnMut(&str)) -> Result<String, Error> {
    crate::io::ensure_dir(out)?;
    let mut report = format!("# sinterdem bench precision ({} rayon threads)\n", rayon::current_num_threads());
    let mut all_csv = String::from(CSV_HEADER);
    let mut jobs: Vec<(String, toml::Value, PathBuf, Vec<String>)> = Vec::new();
    if let Some(c) = copper {
        jobs.push(("copper".into(), crate::config::load_case(c, &[])?, c.parent().unwrap_or(Path::new(".")).to_path_buf(), vec![]));
    }
    if let Some(c) = e14b {
        let value = crate::config::load_case(c, &[])?;
        let base = c.parent().unwrap_or(Path::new(".")).to_path_buf();
        let (corner, n) = corner_packing(&value, &base, corner_edge, 2.0 * corner_edge, out)?;
        let abs = std::fs::canonicalize(&corner).map_err(|e| IoError::new(&corner, e))?;
        let _ = writeln!(report, "# E14B corner: {n} particles (x, y < {corner_edge:e} m, z < {:e} m) in {}", 2.0 * corner_edge, corner.display());
        jobs.push(("e14b-corner".into(), value, base, vec![format!("particles.file=\"{}\"", abs.display())]));
    }
    let csv_path = out.join("precision.csv");
    for (name, value, base, extra) in jobs {
        // the earlier cases' rows plus this case's so far, rewritten after every run
        let mut partial = |reference: &Outcome, runs: &[Outcome]| -> Result<(), Error> {
            crate::io::write_atomic(&csv_path, &format!("{all_csv}{}", csv_rows(&name, reference, runs)))?;
            Ok(())
        };
        let (reference, runs) = measure(&name, &value, &base, &extra, out, progress, &mut partial)?;
        report.push_str(&table(&name, &reference, &runs));
        all_csv.push_str(&csv_rows(&name, &reference, &runs));
        let plot = diagram(&name, &runs);
        plot.save_png(&out.join(format!("precision-{name}.png")))?;
        plot.save_svg(&out.join(format!("precision-{name}.svg")))?;
    }
    let _ = writeln!(report, "# written: {}", out.join("precision.csv").display());
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn o(w: f64, e: f64) -> Outcome {
        Outcome {
            family: "f".into(),
            label: "l".into(),
            wall_seconds: w,
            steps: 1,
            factorizations: 0,
            shrinkage: [0.0; 3],
            neck_ratio: 0.0,
            relative_density: 0.0,
            err_shrinkage: [e, 0.5 * e, 0.0],
            err_neck_ratio: 0.0,
            err_relative_density: 0.0,
            pareto: false,
            error: None,
        }
    }

    /// The Pareto front keeps exactly the runs that no other run beats in both time and error.
    #[test]
    fn pareto_front() {
        let mut runs = vec![o(1.0, 1e-2), o(2.0, 1e-3), o(3.0, 2e-3), o(4.0, 1e-5), o(0.5, 1e-1), o(2.0, 1e-3)];
        runs[5].error = Some("failed".into());
        mark_pareto(&mut runs);
        let front: Vec<bool> = runs.iter().map(|r| r.pareto).collect();
        assert_eq!(front, vec![true, true, false, true, true, false]);
    }

    /// Every rung differs from the defaults in exactly the keys its family names.
    #[test]
    fn ladder_is_one_knob_at_a_time() {
        let l = ladder();
        assert_eq!(l[0].sets.len(), 0);
        for v in &l[1..] {
            let keys: Vec<&str> = v.sets.iter().map(|s| s.split('=').next().unwrap()).collect();
            let ok = match v.family {
                "7-DOF rtol" => keys == ["solver.rtol"],
                "mechanics rtol" => keys == ["mechanics.rtol"],
                "dt_max" => keys == ["time.dt_max"],
                "thresholds" => keys == ["time.grow_below", "time.shrink_above"],
                "detect_every" => keys == ["contacts.detect_every"],
                "strategy 1" => keys == ["time.strategy", "time.dt_max"],
                _ => false,
            };
            assert!(ok, "{v:?}");
        }
    }
}

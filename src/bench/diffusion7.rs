//! Work-precision benchmark of the pair runs (`sinterdem bench pair`): the copper pair and the E14B
//! titanium pair at tolerances 1e-3 … 1e-10 with every integrator; each run's error in y1/R and
//! ΔL/L0 against the tightest Dormand–Prince run (rtol 1e-10), against wall time and right-hand-side
//! count. Writes `work_precision.csv` and PNG diagrams; returns the printed table.

use crate::error::{ConfigError, Error, IoError};
use crate::kinds::pair::{PairSpec, parse_pair_case, run_pair};
use crate::kinds::titanium::{Experiment, TRUNCATED_START};
use crate::models::ode::Method;
use crate::plot::{Plot, Series};
use std::fmt::Write as _;
use std::path::Path;

/// The bundled copper pair case text.
pub const COPPER_CASE: &str = include_str!("../../cases/pair-copper.toml");

/// One benchmark run.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchRow {
    pub case: String,
    pub method: Method,
    pub rtol: f64,
    pub steps: u64,
    pub rejected: u64,
    pub rhs: u64,
    /// Best wall time of the repetitions [s].
    pub wall_seconds: f64,
    /// |Δ y1/R| and |Δ ΔL/L0| against the reference [1] (NaN if the run failed).
    pub err_neck: f64,
    pub err_shrinkage: f64,
    /// The error message if the run stopped with a ModelError.
    pub failure: Option<String>,
}

/// The copper pair spec of `cases/pair-copper.toml`.
pub fn copper_spec() -> Result<PairSpec, Error> {
    let v = toml::Value::Table(COPPER_CASE.parse::<toml::Table>().map_err(|e| ConfigError::invalid(e.to_string()))?);
    parse_pair_case(&v)
}

/// Runs `spec` with `method` at `rtol`, repeating until at least `min_time` [s] has passed
/// (at most 50 times), and returns the best wall time with the result.
pub fn timed_run(spec: &PairSpec, method: Method, rtol: f64, min_time: f64) -> BenchRow {
    let mut sp = spec.clone();
    sp.solver.method = method;
    sp.solver.rtol = rtol;
    let mut best = f64::INFINITY;
    let mut total = 0.0;
    let mut reps = 0;
    loop {
        match run_pair(&sp, false, false) {
            Ok(run) => {
                best = best.min(run.wall_seconds);
                total += run.wall_seconds;
                reps += 1;
                if total >= min_time || reps >= 50 {
                    return BenchRow {
                        case: sp.title.clone(),
                        method,
                        rtol,
                        steps: run.stats.steps,
                        rejected: run.stats.rejected,
                        rhs: run.stats.rhs,
                        wall_seconds: best,
                        err_neck: run.contact.neck_ratio(),
                        err_shrinkage: run.contact.shrinkage(),
                        failure: None,
                    };
                }
            }
            Err(e) => {
                return BenchRow {
                    case: sp.title.clone(),
                    method,
                    rtol,
                    steps: 0,
                    rejected: 0,
                    rhs: 0,
                    wall_seconds: f64::NAN,
                    err_neck: f64::NAN,
                    err_shrinkage: f64::NAN,
                    failure: Some(e.to_string()),
                };
            }
        }
    }
}

/// Benchmarks one case over `tolerances` and `methods`; errors against the Dormand–Prince run at
/// the tightest tolerance.
pub fn work_precision(spec: &PairSpec, methods: &[Method], tolerances: &[f64], min_time: f64) -> Vec<BenchRow> {
    let tight = tolerances.iter().copied().fold(f64::INFINITY, f64::min);
    let reference = timed_run(spec, Method::Dopri5, tight, 0.0);
    let mut rows = Vec::new();
    for &m in methods {
        for &tol in tolerances {
            let mut r = timed_run(spec, m, tol, min_time);
            if r.failure.is_none() {
                r.err_neck = (r.err_neck - reference.err_neck).abs();
                r.err_shrinkage = (r.err_shrinkage - reference.err_shrinkage).abs();
            }
            rows.push(r);
        }
    }
    rows
}

/// Formats rows as a text table.
pub fn table(rows: &[BenchRow]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<26} {:<13} {:>7} {:>7} {:>5} {:>8} {:>10} {:>10} {:>10}",
        "case", "method", "rtol", "steps", "rej", "rhs", "wall [ms]", "err y1/R", "err dL/L0"
    );
    for r in rows {
        match &r.failure {
            None => {
                let _ = writeln!(
                    s,
                    "{:<26} {:<13} {:>7.0e} {:>7} {:>5} {:>8} {:>10.3} {:>10.2e} {:>10.2e}",
                    r.case,
                    r.method.name(),
                    r.rtol,
                    r.steps,
                    r.rejected,
                    r.rhs,
                    r.wall_seconds * 1e3,
                    r.err_neck,
                    r.err_shrinkage
                );
            }
            Some(e) => {
                let _ = writeln!(s, "{:<26} {:<13} {:>7.0e} failed: {e}", r.case, r.method.name(), r.rtol);
            }
        }
    }
    s
}

/// `sinterdem bench pair`: copper pair and E14B at rtol 1e-3 … 1e-10 with every integrator; writes
/// `work_precision.csv`, `work_precision_<case>_wall.png` and `..._rhs.png` to `out_dir` and returns
/// the printed table.
pub fn bench_pair(out_dir: &Path) -> Result<String, Error> {
    std::fs::create_dir_all(out_dir).map_err(|e| IoError::new(out_dir, e))?;
    let tolerances: Vec<f64> = (3..=10).map(|k| 10f64.powi(-k)).collect();
    let cases = [("copper", copper_spec()?), ("E14B", Experiment::by_id("E14B").expect("E14B").spec(TRUNCATED_START)?)];
    let mut all = Vec::new();
    let mut text = String::new();
    for (name, spec) in &cases {
        let rows = work_precision(spec, &Method::ALL, &tolerances, 0.05);
        for (what, xlabel) in [("wall", "wall time per run [s]"), ("rhs", "right-hand-side evaluations")] {
            let mut p = Plot::new(format!("work-precision, {} pair", name)).labels(xlabel, "error vs DOPRI5 rtol 1e-10 [1]").log_x(true).log_y(true);
            for m in Method::ALL {
                for (q, qn) in [(0, "y1/R"), (1, "dL/L0")] {
                    let pts = rows
                        .iter()
                        .filter(|r| r.method == m && r.failure.is_none())
                        .map(|r| {
                            let x = if what == "wall" { r.wall_seconds } else { r.rhs as f64 };
                            (x, if q == 0 { r.err_neck } else { r.err_shrinkage })
                        })
                        .collect();
                    p.add(Series::new(format!("{} {}", m.name(), qn), pts).with_markers());
                }
            }
            p.save_png(&out_dir.join(format!("work_precision_{name}_{what}.png")))?;
        }
        text.push_str(&table(&rows));
        all.extend(rows);
    }
    let path = out_dir.join("work_precision.csv");
    let mut csv = String::from("case,method,rtol,steps,rejected,rhs,wall_seconds,err_neck_ratio,err_shrinkage,failure\n");
    for r in &all {
        let _ = writeln!(
            csv,
            "{},{},{:e},{},{},{},{:e},{:e},{:e},{}",
            r.case,
            r.method.name(),
            r.rtol,
            r.steps,
            r.rejected,
            r.rhs,
            r.wall_seconds,
            r.err_neck,
            r.err_shrinkage,
            r.failure.as_deref().unwrap_or("").replace(',', ";")
        );
    }
    std::fs::write(&path, csv).map_err(|e| IoError::new(&path, e))?;
    Ok(text)
}

/// `sinterdem bench sweep`: the 7-DOF sweep of the coupled loop on `contacts` copper contacts
/// (radii 20–30 µm, touching, 1293 K) over `steps` intervals of `dt` [s], integrated one contact
/// at a time (the scalar path) and in lanes ([`crate::models::diffusion7::lanes`]), each on the current rayon pool.
/// The first interval is the new contacts' start; the table shows it apart. Both paths must end in
/// the same state bit for bit (checked, reported).
pub fn bench_sweep(contacts: usize, steps: usize, dt: f64) -> Result<String, Error> {
    use crate::models::diffusion7::advance::{PairMaterials, SolverOptions, TemperaturePath, advance};
    use crate::models::diffusion7::contact::Contact7;
    use crate::models::diffusion7::lanes::{LANES, advance_lanes};
    use crate::models::diffusion7::material::{Material, PathFactors};
    use crate::models::ode::OdeStats;
    use rayon::prelude::*;
    use std::time::Instant;
    let m = Material::copper();
    let pm = PairMaterials { a: &m, b: &m, factors: PathFactors::default() };
    let opts = SolverOptions { rtol: 1e-5, ..Default::default() };
    let temp = TemperaturePath::Constant(1293.0);
    let r = 25e-6;
    let fresh: Vec<Contact7> = (0..contacts)
        .map(|k| {
            // a deterministic spread of radii and overlaps
            let u = ((k as u64).wrapping_mul(2654435761) % 1000) as f64 / 1000.0;
            let rb = r * (0.8 + 0.4 * u);
            Contact7::new(r, rb, (r + rb) * (1.0 - 0.002 * u), 0.0, 0.01, 0.1)
        })
        .collect::<Result<_, _>>()?;
    let mut out = String::new();
    let _ =
        writeln!(out, "# sinterdem bench sweep: {contacts} copper contacts, 1293 K, rtol 1e-5, Δt = {dt} s, {} rayon threads", rayon::current_num_threads());
    let _ = writeln!(out, "{:>10} {:>8} {:>14} {:>12} {:>14} {:>12} {:>8}", "interval", "path", "rhs/contact", "wall s", "rhs/s", "speed-up", "same");
    let mut scalar = fresh.clone();
    let mut lanes = fresh;
    let mats = [pm; LANES];
    let temps = [temp; LANES];
    for step in 0..steps {
        let (t0, t1) = (step as f64 * dt, (step + 1) as f64 * dt);
        let tic = Instant::now();
        let st: Vec<OdeStats> = scalar
            .par_iter_mut()
            .map(|c| {
                let mut st = OdeStats::default();
                advance(c, &pm, &temp, t0, t1, &opts, &mut st, |_, _, _| {}).map(|_| st)
            })
            .collect::<Result<_, _>>()?;
        let w_scalar = tic.elapsed().as_secs_f64();
        let tic = Instant::now();
        let sl: Vec<OdeStats> = lanes
            .par_chunks_mut(LANES)
            .map(|cs| {
                let n = cs.len();
                advance_lanes(cs, &mats[..n], &temps[..n], t0, t1, &opts).0.into_iter().collect::<Result<Vec<_>, _>>()
            })
            .collect::<Result<Vec<Vec<_>>, _>>()?
            .into_iter()
            .flatten()
            .collect();
        let w_lanes = tic.elapsed().as_secs_f64();
        let rhs: u64 = st.iter().map(|s| s.rhs).sum();
        let same =
            st == sl && scalar.iter().zip(&lanes).all(|(a, b)| a.y.map(f64::to_bits) == b.y.map(f64::to_bits) && a.h_last.to_bits() == b.h_last.to_bits());
        let label = if step == 0 { "1 (start)".to_string() } else { (step + 1).to_string() };
        let per = rhs as f64 / contacts as f64;
        let _ = writeln!(out, "{label:>10} {:>8} {per:>14.1} {w_scalar:>12.4} {:>14.3e} {:>12} {:>8}", "scalar", rhs as f64 / w_scalar, "", "");
        let _ = writeln!(
            out,
            "{:>10} {:>8} {per:>14.1} {w_lanes:>12.4} {:>14.3e} {:>12.2} {:>8}",
            "",
            "lanes",
            rhs as f64 / w_lanes,
            w_scalar / w_lanes,
            if same { "yes" } else { "NO" }
        );
    }
    Ok(out)
}

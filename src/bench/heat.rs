//! `sinterdem bench heat`: assembly, symbolic analysis, factorisation and solve times of one
//! implicit heat step on random packings of N particles (the test matrices used when faer was chosen: random
//! points at unit density connected within a radius giving a mean degree ≈ 6, pipe conductances
//! from volume-conserving necks, Δt = 1000 × the explicit limit).

use crate::error::Error;
use crate::heat::{Conductance, HeatNetwork, HeatSources, Scheme};
use crate::particles::Particles;
use nalgebra::Vector3;
use std::time::Instant;

fn rng(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

/// A random overlapping packing of `n` copper spheres of radius 50 µm ± 10 % with mean
/// coordination ≈ 6 (centres uniform in a cube, radii scaled so that neighbours overlap).
pub fn random_packing(n: usize, seed: u64) -> Particles {
    let mut s = seed.max(1);
    let r0: f64 = 50e-6;
    // number density chosen so that spheres of radius r0·1.12 have ~6 neighbours within 2r
    let reach = 2.0 * r0 * 1.1;
    let density = 6.0 / (4.0 / 3.0 * std::f64::consts::PI * reach.powi(3));
    let side = (n as f64 / density).cbrt();
    let mut p = Particles::default();
    for _ in 0..n {
        let x = Vector3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * side;
        let r = r0 * 1.1 * (1.0 + 0.1 * (2.0 * rng(&mut s) - 1.0));
        p.push(x, r, 0, 8960.0, 385.0, 300.0);
    }
    p
}

/// Prints the benchmark table.
pub fn bench_heat(sizes: &[usize], repeat: usize) -> Result<(), Error> {
    let mat = crate::material::preset("copper-ivannikov2022").unwrap();
    println!("# one implicit heat step (backward Euler, Δt = 1000 × explicit limit), {} rayon threads", rayon::current_num_threads());
    println!(
        "{:>9} {:>9} {:>11} {:>11} {:>11} {:>11} {:>11} {:>11} {:>10}",
        "particles", "contacts", "detect_s", "necks_s", "symbolic_s", "assemble_s", "factor_s", "solve_s", "residual"
    );
    for &n in sizes {
        let p = random_packing(n, 42 + n as u64);
        let mut rows = Vec::new();
        for _ in 0..repeat {
            let t0 = Instant::now();
            let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&p.position, &p.radius, 0.0).into_iter().map(|(i, j)| [i, j]).collect();
            let t_detect = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            // random points are not a sintered packing: overlaps are clipped to half the neck
            // model's limit so that every pair has a valid volume-conserving neck
            let law = Conductance::default();
            let conductance: Vec<f64> = pairs
                .iter()
                .map(|&[i, j]| {
                    let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
                    let d = (p.position[j as usize] - p.position[i as usize]).norm();
                    let h = (ri + rj - d).min(0.5 * crate::neck::max_overlap(ri, rj));
                    let a = crate::neck::solve(ri, rj, h).map(|n| n.a)?;
                    Ok(law.pipe(mat.conductivity, mat.conductivity, ri, rj, a).pair)
                })
                .collect::<Result<_, crate::error::ModelError>>()?;
            let pipes = crate::heat::Pipes { pairs, conductance, ..Default::default() };
            let q = &p;
            let t_necks = t1.elapsed().as_secs_f64();
            let kmax = pipes.conductance.iter().copied().fold(0.0, f64::max);
            let cmin = q.capacity.iter().copied().fold(f64::INFINITY, f64::min);
            let dt = 1000.0 * cmin / (2.0 * 6.0 * kmax);
            let mut net = HeatNetwork::new(q.capacity.clone(), HeatSources::default(), Scheme::BackwardEuler, 1e-9);
            let t_sym = net.set_topology(&pipes.pairs)?;
            let mut temps: Vec<f64> = (0..n).map(|i| 300.0 + 100.0 * (q.position[i].x * 1e3).sin()).collect();
            let info = net.step(0.0, dt, &mut temps, &pipes.conductance)?;
            rows.push((
                pipes.pairs.len(),
                t_detect,
                t_necks,
                t_sym,
                info.assemble_seconds,
                info.solve.factor_seconds,
                info.solve.solve_seconds,
                info.solve.residual,
            ));
        }
        rows.sort_by(|a, b| a.5.total_cmp(&b.5));
        let r = rows[rows.len() / 2];
        println!("{:>9} {:>9} {:>11.4} {:>11.4} {:>11.4} {:>11.4} {:>11.4} {:>11.4} {:>10.1e}", n, r.0, r.1, r.2, r.3, r.4, r.5, r.6, r.7);
    }
    Ok(())
}

/// One row of the work-precision table of [`bench_heat_step`].
#[derive(Debug, Clone, serde::Serialize)]
pub struct StepRow {
    /// "fixed" or "error".
    pub control: String,
    /// Δt [s] (fixed) or time.heat_tolerance [K] (error).
    pub parameter: f64,
    /// Accepted steps.
    pub steps: usize,
    /// Rejected steps.
    pub rejected: usize,
    /// max over the output times and particles of |T_i(t_k) − T_i,ref(t_k)| [K].
    pub error_kelvin: f64,
    /// Wall time of the run [s].
    pub wall_s: f64,
}

/// Output times of the bench case (evenly spaced, t = 0 included).
pub const STEP_BENCH_OUTPUTS: usize = 51;

/// The bench case: cases/hot-plate.toml on `cells` (a titanium FCC compact), its plate switched
/// on at t = 0 (held at 1273 K while the compact starts at 293.15 K), radiation and convection on
/// top, BDF2, until `end` [s], temperatures recorded at [`STEP_BENCH_OUTPUTS`] evenly spaced times:
/// a fast transient after the switch, then a slower approach.
pub fn step_bench_case(cells: [u32; 3], end: f64) -> Result<toml::Value, Error> {
    let sets: Vec<String> = vec![
        format!("particles.cells=[{}, {}, {}]", cells[0], cells[1], cells[2]),
        format!("output.snapshots={STEP_BENCH_OUTPUTS}"),
        "output.vtu=false".into(),
        "output.hdf5=false".into(),
        "output.series_every=1000000".into(),
        "thermal.fixed.0.profile={ constant = 1273.0 }".into(),
        format!("time.end={end:e}"),
    ];
    let text = include_str!("../../cases/hot-plate.toml");
    let mut v = toml::Value::Table(text.parse::<toml::Table>().map_err(|e| crate::error::ConfigError::invalid(format!("hot-plate.toml: {e}")))?);
    for s in &sets {
        crate::config::apply_override(&mut v, s)?;
    }
    Ok(v)
}

/// Runs a heat case with `sets` applied; returns (summary, temperatures at the output times, wall s).
pub fn run_step_case(base: &toml::Value, sets: &[String], out: &std::path::Path) -> Result<(serde_json::Value, Vec<(f64, Vec<f64>)>, f64), Error> {
    let mut v = base.clone();
    for s in sets {
        crate::config::apply_override(&mut v, s)?;
    }
    let prep = crate::scene::prepare(v, std::path::Path::new("."))?;
    let t0 = Instant::now();
    let (s, temps) = crate::kinds::heat::run_returning_temperatures(prep, out, false, &mut |_| {}, None, None, true)?;
    Ok((s, temps, t0.elapsed().as_secs_f64()))
}

/// max over the common output times (within 1e-9 of the last time) and particles of |a − b| [K],
/// and the number of common times.
pub fn max_error(a: &[(f64, Vec<f64>)], b: &[(f64, Vec<f64>)]) -> (f64, usize) {
    let scale = a.last().map_or(1.0, |x| x.0.abs()).max(1e-300);
    let mut common = 0;
    let mut err: f64 = 0.0;
    for (ta, x) in a {
        if let Some((_, y)) = b.iter().find(|(tb, _)| (ta - tb).abs() <= 1e-9 * scale) {
            common += 1;
            err = err.max(x.iter().zip(y).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max));
        }
    }
    (err, common)
}

/// `sinterdem bench heat-step`: work-precision of fixed Δt against error-controlled Δt
/// (time.heat_tolerance) on [`step_bench_case`]; the reference is an error-controlled run at
/// 1e-7 K. Prints the table and writes `out/work_precision.csv`.
pub fn bench_heat_step(out: &std::path::Path, cells: [u32; 3], end: f64) -> Result<Vec<StepRow>, Error> {
    crate::io::ensure_dir(out)?;
    let base = step_bench_case(cells, end)?;
    let scratch = out.join("runs");
    let (_, reference, _) = run_step_case(&base, &["time.heat_tolerance=1e-7".into(), "time.dt=1e-7".into()], &scratch)?;
    let mut rows = Vec::new();
    let intervals = (STEP_BENCH_OUTPUTS - 1) as f64;
    for k in 0..9 {
        let dt = end / intervals / f64::powi(2.0, k);
        let (s, t, wall) = run_step_case(&base, &[format!("time.dt={dt:e}")], &scratch)?;
        rows.push(StepRow {
            control: "fixed".into(),
            parameter: dt,
            steps: s["steps"].as_u64().unwrap_or(0) as usize,
            rejected: 0,
            error_kelvin: max_error(&t, &reference).0,
            wall_s: wall,
        });
    }
    for k in 0..7 {
        let tol = 10f64.powi(1 - k);
        let (s, t, wall) = run_step_case(&base, &[format!("time.heat_tolerance={tol:e}"), "time.dt=1e-7".into()], &scratch)?;
        rows.push(StepRow {
            control: "error".into(),
            parameter: tol,
            steps: s["steps_accepted"].as_u64().unwrap_or(0) as usize,
            rejected: s["steps_rejected"].as_u64().unwrap_or(0) as usize,
            error_kelvin: max_error(&t, &reference).0,
            wall_s: wall,
        });
    }
    let _ = std::fs::remove_dir_all(&scratch);
    let mut csv = String::from("control,parameter,steps,rejected,error_K,wall_s\n");
    println!("# heat step work-precision: hot plate (titanium FCC {cells:?}), plate at 1273 K from t = 0, BDF2, end {end} s");
    println!(
        "# parameter: Δt [s] (fixed) or time.heat_tolerance [K] (error); error: max |T − T_ref| over particles and {STEP_BENCH_OUTPUTS} output times, T_ref at 1e-7 K"
    );
    println!("{:>8} {:>10} {:>8} {:>9} {:>11} {:>9}", "control", "parameter", "steps", "rejected", "error_K", "wall_s");
    for r in &rows {
        println!("{:>8} {:>10.3e} {:>8} {:>9} {:>11.3e} {:>9.4}", r.control, r.parameter, r.steps, r.rejected, r.error_kelvin, r.wall_s);
        csv.push_str(&format!("{},{:e},{},{},{:e},{:e}\n", r.control, r.parameter, r.steps, r.rejected, r.error_kelvin, r.wall_s));
    }
    crate::io::write_atomic(&out.join("work_precision.csv"), &csv)?;
    Ok(rows)
}

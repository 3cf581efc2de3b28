//! `sinterdem bench mechanics`: the cost of one mechanical step on random bonded packings of N
//! particles: topology analysis, assembly, symbolic analysis, numeric Cholesky, triangular solves,
//! and the block-Jacobi PCG alternative, so that the automatic solver choice
//! ([`crate::mechanics::PCG_ABOVE_EQUATIONS`]) rests on measurements.
//!
//! Packing: an FCC lattice with nearest-neighbour distance 2R (R = 50 µm) and radii
//! R·(1 ± 5 %) uniform, bonds between the overlapping neighbours (about half of them: mean
//! coordination ≈ 6, irregular graph with some rattlers and floating clusters), plane
//! constraints, nested-dissection ordering of the Cholesky factor, copper links (E = 110 GPa, ν = 0.34), load increments (F5) for random approaches
//! of 1e-4·R_m ± 50 %.

use crate::error::Error;
use crate::mechanics::fixtures::{fcc_packing, rng};
use crate::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, StepInput};
use nalgebra::Vector3;
use std::fmt::Write;
use std::time::Instant;

/// Process CPU time (user + system, all threads) [s] from /proc/self/stat (0 where unavailable).
pub fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return 0.0 };
    let Some(rest) = stat.rfind(')').map(|k| &stat[k + 2..]) else { return 0.0 };
    let f: Vec<&str> = rest.split_whitespace().collect();
    // fields 14 and 15 of stat (utime, stime) are 11 and 12 after the state field
    let ticks = f.get(11).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0) + f.get(12).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    ticks / 100.0
}

/// AMG parameters with the overrides of `MECH_AMG` (experiments), e.g.
/// `MECH_AMG=smooth_p=false,sweeps=2,max_coarse=3000,strength=0.08,reuse=false,smoother_omega=1.0`.
pub fn amg_params_from_env() -> Result<crate::mechanics::amg::AmgParams, Error> {
    let mut a = crate::mechanics::amg::AmgParams::default();
    let Ok(spec) = std::env::var("MECH_AMG") else { return Ok(a) };
    for kv in spec.split(',').filter(|s| !s.is_empty()) {
        let (k, v) = kv.split_once('=').ok_or_else(|| crate::error::ConfigError::invalid(format!("MECH_AMG: {kv}")))?;
        let bad = || crate::error::ConfigError::invalid(format!("MECH_AMG: {kv}"));
        match k {
            "smooth_p" => a.smooth_p = v.parse().map_err(|_| bad())?,
            "reuse" => a.reuse = v.parse().map_err(|_| bad())?,
            "sweeps" => a.sweeps = v.parse().map_err(|_| bad())?,
            "max_coarse" => a.max_coarse = v.parse().map_err(|_| bad())?,
            "max_levels" => a.max_levels = v.parse().map_err(|_| bad())?,
            "strength" => a.strength = v.parse().map_err(|_| bad())?,
            "smoother_omega" => a.smoother_omega = v.parse().map_err(|_| bad())?,
            _ => return Err(bad().into()),
        }
    }
    Ok(a)
}

/// The bonded problem of the mechanics benches: an FCC packing of about `n` particles, its bonds,
/// load increments ((F5) with Δy4 = 0.5e-4·r̄ and a random Δy7) [N], the principal-plane
/// constraints, the parameters (E = 110 GPa, ν = 0.34, the AMG of `MECH_AMG`, `solver`) and a
/// noise in [0, 1) per particle for the moved second step.
struct Problem {
    pos: Vec<Vector3<f64>>,
    rad: Vec<f64>,
    pairs: Vec<[u32; 2]>,
    y: Vec<[f64; 2]>,
    params: MechParams,
    load: Vec<f64>,
    cons: Constraints,
    noise: Vec<f64>,
}

impl Problem {
    fn fcc(n: usize, solver: LinearSolver) -> Result<Self, Error> {
        let (pos, rad, pairs, y) = fcc_packing(n, 7 + n as u64);
        let params = MechParams { young_modulus: 110e9, poisson_ratio: 0.34, amg: amg_params_from_env()?, solver, ..Default::default() };
        let mut s = 99u64;
        let load: Vec<f64> = pairs
            .iter()
            .map(|&[i, j]| {
                let rm = 0.5 * (rad[i as usize] + rad[j as usize]);
                crate::models::diffusion7::load_increment(0.5e-4 * rm, 0.5e-4 * rm * (0.5 + rng(&mut s)), rm, params.young_modulus)
            })
            .collect();
        let cons = Constraints::principal_planes(&pos, &rad, 0.01)?;
        let noise: Vec<f64> = (0..pos.len()).map(|_| rng(&mut s)).collect();
        Ok(Problem { pos, rad, pairs, y, params, load, cons, noise })
    }
}

/// The packing of the second bench step: each particle moved by 10 × its first-step increment
/// `du` plus `1e-3·r₀·noise` along (1, 1, 1) [m].
fn moved(pos: &[Vector3<f64>], du: &[Vector3<f64>], noise: &[f64], r0: f64) -> Vec<Vector3<f64>> {
    pos.iter().zip(du).zip(noise).map(|((x, d), e)| x + d * 10.0 + Vector3::repeat(1e-3 * r0 * e)).collect()
}

/// Runs the benchmark for packings of about `sizes[k]` particles and returns the table.
pub fn bench_mechanics(sizes: &[usize]) -> Result<String, Error> {
    bench_mechanics_with(sizes, usize::MAX)
}

/// [`bench_mechanics`], the Cholesky columns only up to `cholesky_max` particles.
pub fn bench_mechanics_with(sizes: &[usize], cholesky_max: usize) -> Result<String, Error> {
    let mut out = String::new();
    let _ = writeln!(out, "# one bonded quasi-static step (6 DOF/particle, scaled rotations, rtol 1e-10), {} rayon threads", rayon::current_num_threads());
    let _ = writeln!(
        out,
        "# times in s (wall; cpu = process CPU time); chol = numeric factorisation of a second step (symbolic reused); *_reuse / *_stale = a third step after 1e-3 relative geometry change"
    );
    let _ = writeln!(
        out,
        "# reuse = stale Cholesky factor as modified-Newton operator; reuse_cg = stale factor as CG preconditioner; amg_stale = AMG hierarchy of the first step reused (fine smoother refreshed)"
    );
    let _ = writeln!(
        out,
        "{:>7} {:>7} {:>7} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} | {:>5} {:>8} {:>8} {:>7} | {:>8} {:>5} {:>8} {:>8} {:>8} {:>7} {:>8} {:>5}",
        "nodes",
        "bonds",
        "eqs",
        "rattl",
        "assemble",
        "symbolic",
        "chol",
        "solve",
        "stepchol",
        "reuse",
        "reuse_cg",
        "cg_it",
        "pcg_it",
        "step_pcg",
        "cpu_pcg",
        "res_pcg",
        "amg_set",
        "amg_it",
        "amg_sol",
        "step_amg",
        "cpu_amg",
        "res_amg",
        "amg_stal",
        "st_it"
    );
    let mut notes = String::new();
    for &n in sizes {
        let Problem { pos, rad, pairs, y, params, load, cons, noise } = Problem::fcc(n, LinearSolver::Auto)?;
        let inp = StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None };
        // AMG first (fresh hierarchy), then a step with the stale hierarchy
        let mut sys_a = BondedSystem::new(pos.len(), MechParams { solver: LinearSolver::Amg, ..params }, cons.clone())?;
        sys_a.set_topology(&pairs)?;
        let (t0, c0) = (Instant::now(), cpu_seconds());
        let amg = sys_a.step(&inp)?;
        let (t_amg, c_amg) = (t0.elapsed().as_secs_f64(), cpu_seconds() - c0);
        let pos2 = moved(&pos, &amg.du, &noise, rad[0]);
        let amg_stale = sys_a.step(&StepInput { positions: &pos2, ..inp })?;
        drop(sys_a);
        // PCG (MECH_BENCH_NO_PCG=1 skips it, for experiments)
        let skip_pcg = std::env::var("MECH_BENCH_NO_PCG").is_ok();
        let mut sys_p = BondedSystem::new(pos.len(), MechParams { solver: LinearSolver::Pcg, ..params }, cons.clone())?;
        sys_p.set_topology(&pairs)?;
        let (t0, c0) = (Instant::now(), cpu_seconds());
        let pcg = if skip_pcg { amg.clone() } else { sys_p.step(&inp)? };
        let (t_pcg, c_pcg) = (t0.elapsed().as_secs_f64(), cpu_seconds() - c0);
        drop(sys_p);
        let scale = amg.du.iter().map(|a| a.norm()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let diff_pa = amg.du.iter().zip(&pcg.du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        let ia = &amg.info;
        let chol_cols = if pos.len() <= cholesky_max {
            cholesky_columns(&pairs, &inp, &pos2, params, &cons, &amg.du, scale, &mut notes)?
        } else {
            format!("{:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}", "-", "-", "-", "-", "-", "-", "-")
        };
        let _ = writeln!(
            out,
            "{:>7} {:>7} {:>7} {:>5} {:>8.4} {} | {:>5} {:>8.4} {:>8.2} {:>7.1e} | {:>8.4} {:>5} {:>8.4} {:>8.4} {:>8.2} {:>7.1e} {:>8.4} {:>5}",
            pos.len(),
            pairs.len(),
            ia.equations,
            ia.rattlers,
            ia.assemble_seconds,
            chol_cols,
            pcg.info.pcg_iterations,
            t_pcg,
            c_pcg,
            pcg.info.residuals.last().copied().unwrap_or(0.0),
            ia.factor_seconds,
            ia.pcg_iterations,
            ia.solve_seconds,
            t_amg,
            c_amg,
            ia.residuals.last().copied().unwrap_or(0.0),
            amg_stale.info.total_seconds,
            amg_stale.info.pcg_iterations,
        );
        let _ = writeln!(
            notes,
            "#   n = {}: AMG {:?}, Newton {} / stale step Newton {} (rebuilds {}); PCG vs AMG max |Δu| difference {:.1e} of max |Δu| {:.2e} m",
            pos.len(),
            ia.amg,
            ia.newton_iterations,
            amg_stale.info.newton_iterations,
            amg_stale.info.amg_builds,
            diff_pa / scale,
            scale
        );
    }
    out.push_str(&notes);
    Ok(out)
}

/// The Cholesky columns of one row (first step: analysis + symbolic; second: numeric only; the
/// moved packing `pos2` with the stale factor as modified Newton and as CG preconditioner) and the
/// orderings' fill in `notes`; `amg_du` and `scale` compare against the AMG step.
fn cholesky_columns(
    pairs: &[[u32; 2]],
    inp: &StepInput,
    pos2: &[Vector3<f64>],
    params: MechParams,
    cons: &Constraints,
    amg_du: &[Vector3<f64>],
    scale: f64,
    notes: &mut String,
) -> Result<String, Error> {
    // Cholesky: first step (analysis + symbolic), second step (numeric only)
    let mut sys = BondedSystem::new(inp.positions.len(), MechParams { solver: LinearSolver::Cholesky, ..params }, cons.clone())?;
    sys.set_topology(pairs)?;
    let first = sys.step(inp)?;
    let second = sys.step(inp)?;
    let fill = sys.factor_nnz().unwrap_or(0);
    // factor reuse: the moved packing with the old factor, as modified Newton and as CG preconditioner
    sys.set_params(MechParams { solver: LinearSolver::Cholesky, reuse_factor: true, ..params })?;
    let third = sys.step(&StepInput { positions: pos2, ..*inp })?;
    let mut sys_cg = BondedSystem::new(inp.positions.len(), MechParams { solver: LinearSolver::Cholesky, ..params }, cons.clone())?;
    sys_cg.set_topology(pairs)?;
    sys_cg.step(inp)?;
    sys_cg.set_params(MechParams { solver: LinearSolver::Cholesky, reuse_factor: true, stale_factor_cg: true, ..params })?;
    let fourth = sys_cg.step(&StepInput { positions: pos2, ..*inp })?;
    // orderings: fill and cost of the symbolic analysis and of the numeric factorisation
    let mut ord = String::new();
    for o in [crate::mechanics::cholesky::Ordering::Amd, crate::mechanics::cholesky::Ordering::BlockAmd] {
        let mut s = BondedSystem::new(inp.positions.len(), MechParams { solver: LinearSolver::Cholesky, ordering: o, ..params }, cons.clone())?;
        s.set_topology(pairs)?;
        let st = s.step(inp)?;
        let _ = write!(
            ord,
            " {o:?}: nnz(L) {:.3e}, symbolic {:.4} s, factor {:.4} s;",
            s.factor_nnz().unwrap_or(0) as f64,
            st.info.symbolic_seconds,
            st.info.factor_seconds
        );
    }
    let _ = writeln!(*notes, "#   n = {}: orderings{ord}", inp.positions.len());
    let diff = first.du.iter().zip(amg_du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    let diff3 = third.du.iter().zip(&fourth.du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    let i1 = &first.info;
    let i2 = &second.info;
    let _ = writeln!(
        notes,
        "#   n = {}: nnz(L) = {:.3e}, chol residual {:.1e}; reuse step {} Newton iterations, {} factorisations; reuse_cg {} CG iterations, {} factorisations, |Δu| difference to reuse {:.1e}; AMG vs Cholesky max |Δu| difference {:.1e} of max |Δu| {:.2e} m",
        inp.positions.len(),
        fill as f64,
        i2.residuals.last().copied().unwrap_or(0.0),
        third.info.newton_iterations,
        third.info.factorizations,
        fourth.info.pcg_iterations,
        fourth.info.factorizations,
        diff3 / scale,
        diff / scale,
        scale
    );
    Ok(format!(
        "{:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8.4} {:>8}",
        i1.symbolic_seconds,
        i2.factor_seconds,
        i2.solve_seconds,
        i2.total_seconds,
        third.info.total_seconds,
        fourth.info.total_seconds,
        fourth.info.pcg_iterations
    ))
}

/// `sinterdem bench mechanics --solver S`: one solver alone on the packings of [`bench_mechanics`]
/// (so that `/usr/bin/time -v` gives its peak memory): a first step (setup: AMG hierarchy, hypre
/// BoomerAMG setup or Cholesky analysis and factorisation; iterations; solve) and a second step on
/// the moved packing (1e-3·R noise, same bonds: our AMG keeps its hierarchy, hypre sets up afresh,
/// Cholesky refactorises), at the tolerance of [`MechParams::default`] (rtol 1e-10, (B10)).
pub fn bench_solver(sizes: &[usize], solver: LinearSolver) -> Result<String, Error> {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# one bonded quasi-static step with solver {solver:?} alone (rtol 1e-10), {} rayon threads; setup = AMG build / BoomerAMG setup / factorisation [s]",
        rayon::current_num_threads()
    );
    let _ = writeln!(
        out,
        "{:>7} {:>7} {:>7} {:>8} {:>6} {:>8} {:>8} {:>8} {:>9} | {:>8} {:>6} {:>8} {:>8}",
        "nodes", "bonds", "eqs", "setup", "its", "solve", "s/it", "step", "res", "setup2", "its2", "solve2", "step2"
    );
    for &n in sizes {
        let Problem { pos, rad, pairs, y, params, load, cons, noise } = Problem::fcc(n, solver)?;
        let inp = StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None };
        let mut sys = BondedSystem::new(pos.len(), params, cons)?;
        sys.set_topology(&pairs)?;
        let first = sys.step(&inp)?;
        let pos2 = moved(&pos, &first.du, &noise, rad[0]);
        let second = sys.step(&StepInput { positions: &pos2, ..inp })?;
        let (a, b) = (&first.info, &second.info);
        let _ = writeln!(
            out,
            "{:>7} {:>7} {:>7} {:>8.4} {:>6} {:>8.4} {:>8.5} {:>8.4} {:>9.2e} | {:>8.4} {:>6} {:>8.4} {:>8.4}",
            pos.len(),
            pairs.len(),
            a.equations,
            a.factor_seconds + a.symbolic_seconds,
            a.pcg_iterations,
            a.solve_seconds,
            a.solve_seconds / a.pcg_iterations.max(1) as f64,
            a.total_seconds,
            a.residuals.last().copied().unwrap_or(0.0),
            b.factor_seconds + b.symbolic_seconds,
            b.pcg_iterations,
            b.solve_seconds,
            b.total_seconds
        );
    }
    Ok(out)
}

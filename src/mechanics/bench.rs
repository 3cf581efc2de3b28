//! `sinterdem bench mechanics`: the cost of one mechanical step on random bonded packings of N
//! particles: topology analysis, assembly, symbolic analysis, numeric Cholesky, triangular solves,
//! and the block-Jacobi PCG alternative, so that the automatic solver choice
//! ([`super::PCG_ABOVE_EQUATIONS`]) rests on measurements.
//!
//! Packing: an FCC lattice with nearest-neighbour distance 2R (R = 50 µm) and radii
//! R·(1 ± 5 %) uniform, bonds between the overlapping neighbours (about half of them: mean
//! coordination ≈ 6, irregular graph with some rattlers and floating clusters), plane
//! constraints, nested-dissection ordering of the Cholesky factor, copper links (E = 110 GPa, ν = 0.34), load increments (F5) for random approaches
//! of 1e-4·R_m ± 50 %.

use super::{BondedSystem, Constraints, LinearSolver, MechParams, StepInput};
use crate::error::Error;
use nalgebra::Vector3;
use std::fmt::Write;
use std::time::Instant;

fn rng(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

/// A bonded packing of about `n` particles (see the module doc): positions [m], radii [m],
/// bonds, and `[y4, y7]` per bond from the two-sphere overlap (I1) [m].
pub fn fcc_packing(n: usize, seed: u64) -> (Vec<Vector3<f64>>, Vec<f64>, Vec<[u32; 2]>, Vec<[f64; 2]>) {
    let r0 = 50e-6;
    let a = 2.0 * r0 * std::f64::consts::SQRT_2;
    let m = ((n as f64 / 4.0).cbrt().round() as usize).max(1);
    let basis = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]];
    let mut s = seed.max(1);
    let (mut pos, mut rad) = (Vec::new(), Vec::new());
    for i in 0..m {
        for j in 0..m {
            for k in 0..m {
                for bvec in &basis {
                    pos.push(Vector3::new(i as f64 + bvec[0], j as f64 + bvec[1], k as f64 + bvec[2]) * a + Vector3::repeat(r0));
                    rad.push(r0 * (1.0 + 0.05 * (2.0 * rng(&mut s) - 1.0)));
                }
            }
        }
    }
    let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&pos, &rad, 0.0).into_iter().map(|(i, j)| [i, j]).collect();
    let y = pairs
        .iter()
        .map(|&[i, j]| {
            let (ra, rb) = (rad[i as usize], rad[j as usize]);
            let d = (pos[j as usize] - pos[i as usize]).norm();
            [(d * d + ra * ra - rb * rb) / (2.0 * d), (d * d + rb * rb - ra * ra) / (2.0 * d)]
        })
        .collect();
    (pos, rad, pairs, y)
}

/// Runs the benchmark for packings of about `sizes[k]` particles and returns the table.
pub fn bench_mechanics(sizes: &[usize]) -> Result<String, Error> {
    let mut out = String::new();
    let _ = writeln!(out, "# one bonded quasi-static step (6 DOF/particle, scaled rotations, rtol 1e-10), {} rayon threads", rayon::current_num_threads());
    let _ = writeln!(out, "# times in s; chol = numeric factorisation of a second step (symbolic reused); step_reuse = a third step reusing the factor (modified Newton) after 1e-3 relative geometry change");
    let _ = writeln!(
        out,
        "{:>8} {:>8} {:>8} {:>5} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>6} {:>9} {:>9}",
        "nodes", "bonds", "eqs", "rattl", "pins", "analysis", "assemble", "symbolic", "chol", "solve", "step_chol", "res_chol", "step_reuse", "pcg_it", "step_pcg", "res_pcg"
    );
    for &n in sizes {
        let (pos, rad, pairs, y) = fcc_packing(n, 7 + n as u64);
        let params = MechParams { young_modulus: 110e9, poisson_ratio: 0.34, ..Default::default() };
        let mut s = 99u64;
        let load: Vec<f64> = pairs
            .iter()
            .map(|&[i, j]| {
                let rm = 0.5 * (rad[i as usize] + rad[j as usize]);
                crate::models::diffusion7::load_increment(0.5e-4 * rm, 0.5e-4 * rm * (0.5 + rng(&mut s)), rm, params.young_modulus)
            })
            .collect();
        let cons = Constraints::principal_planes(&pos, &rad, 0.01)?;
        let inp = StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None };
        // Cholesky: first step (analysis + symbolic), second step (numeric only)
        let mut sys = BondedSystem::new(pos.len(), MechParams { solver: LinearSolver::Cholesky, ..params }, cons.clone())?;
        sys.set_topology(&pairs)?;
        let first = sys.step(&inp)?;
        let second = sys.step(&inp)?;
        let fill = sys.factor_nnz().unwrap_or(0);
        // factor reuse: move the particles by 10 increments plus 1e-3·R noise, step with the old factor
        sys.set_params(MechParams { solver: LinearSolver::Cholesky, reuse_factor: true, ..params })?;
        let pos2: Vec<Vector3<f64>> =
            pos.iter().zip(&first.du).map(|(x, d)| x + d * 10.0 + Vector3::repeat(1e-3 * rad[0] * rng(&mut s))).collect();
        let third = sys.step(&StepInput { positions: &pos2, ..inp })?;
        // PCG
        let mut sys_p = BondedSystem::new(pos.len(), MechParams { solver: LinearSolver::Pcg, ..params }, cons)?;
        sys_p.set_topology(&pairs)?;
        let t0 = Instant::now();
        let pcg = sys_p.step(&inp)?;
        let t_pcg = t0.elapsed().as_secs_f64();
        let diff = first.du.iter().zip(&pcg.du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        let scale = first.du.iter().map(|a| a.norm()).fold(0.0, f64::max);
        let i1 = &first.info;
        let i2 = &second.info;
        let _ = writeln!(
            out,
            "{:>8} {:>8} {:>8} {:>5} {:>5} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.1e} {:>10.4} {:>6} {:>9.4} {:>9.1e}",
            pos.len(),
            pairs.len(),
            i1.equations,
            i1.rattlers,
            i1.pinned,
            i1.analysis_seconds,
            i2.assemble_seconds,
            i1.symbolic_seconds,
            i2.factor_seconds,
            i2.solve_seconds,
            i2.total_seconds,
            i2.residuals.last().copied().unwrap_or(0.0),
            third.info.total_seconds,
            pcg.info.pcg_iterations,
            t_pcg,
            pcg.info.residuals.last().copied().unwrap_or(0.0),
        );
        let _ = writeln!(
            out,
            "#   n = {}: nnz(L) = {:.3e}; reuse step {} Newton iterations, {} factorisations; PCG vs Cholesky max |Δu| difference {:.1e} of max |Δu| {:.2e} m",
            pos.len(),
            fill as f64,
            third.info.newton_iterations,
            third.info.factorizations,
            diff / scale.max(f64::MIN_POSITIVE),
            scale
        );
    }
    Ok(out)
}

//! The Newton drivers shared by the solvers of [`super::BondedSystem`]: Newton on a (possibly
//! stale) Cholesky factor, CG preconditioned by a stale factor, the initial residual and the
//! warm start (B12) (docs/mechanics.md "Solve").

use super::cholesky::BondCholesky;
use super::constraints::TopologyReport;
use super::lowrank::LowRank;
use super::solve::{self, MechParams};
use super::{BlockMatrix, MechInfo, amg, cg};
use crate::error::{Error, SolveError};
use rayon::prelude::*;
use std::time::Instant;

/// `red[eq[d]] = full[d]` for every free DOF `d` (`eq[d] ≠ u32::MAX`): a full-length vector on
/// the reduced equations.
fn gather_free(eq: &[u32], full: &[f64], red: &mut [f64]) {
    for (d, &e) in eq.iter().enumerate() {
        if e != u32::MAX {
            red[e as usize] = full[d];
        }
    }
}

/// `full[d] += red[eq[d]]` for every free DOF `d`: a reduced increment added to a full vector.
fn add_free(eq: &[u32], red: &[f64], full: &mut [f64]) {
    for (d, &e) in eq.iter().enumerate() {
        if e != u32::MAX {
            full[d] += red[e as usize];
        }
    }
}

/// Newton with the factor `chol` of the current topology, refactorised when it is not
/// factored, not to be reused or slow (stale).
pub(super) fn newton_on_factor(
    params: &MechParams,
    refresh: &mut bool,
    rep: &TopologyReport,
    op: &amg::FineOp,
    chol: &mut BondCholesky,
    b: &[f64],
    b_norm: f64,
    x: &mut [f64],
    info: &mut MechInfo,
) -> Result<(), Error> {
    // the reduced lower-triangle values, gathered only when a factorisation needs them
    let mut values: Vec<f64> = Vec::new();
    let gather = |values: &mut Vec<f64>, info: &mut MechInfo| {
        if values.is_empty() {
            let t0 = Instant::now();
            op.blocks.for_each_lower(op.pairs, rep, |_, _, v| values.push(v));
            info.assemble_seconds += t0.elapsed().as_secs_f64();
        }
    };
    let mut fresh = false;
    if !params.reuse_factor || !chol.is_factored() || *refresh {
        gather(&mut values, info);
        info.factor_seconds += chol.factorize(&values)?;
        info.factorizations += 1;
        fresh = true;
        *refresh = false;
    }
    let (mut r, mut rel) = initial_residual(op, b, b_norm, x, None);
    let mut red = vec![0.0; rep.n_eq];
    while info.newton_iterations < params.max_newton {
        gather_free(&rep.eq, &r, &mut red);
        info.solve_seconds += chol.solve_in_place(&mut red)?;
        add_free(&rep.eq, &red, x);
        info.newton_iterations += 1;
        let new_rel = op.residual(b, b_norm, x, &mut r);
        info.residuals.push(new_rel);
        if !new_rel.is_finite() {
            return Err(not_finite(info).into());
        }
        if new_rel <= params.rtol {
            return Ok(());
        }
        // a stale factor that converges slowly (or diverges) is replaced by a fresh one
        if !fresh && new_rel > 0.1 * rel {
            gather(&mut values, info);
            info.factor_seconds += chol.factorize(&values)?;
            info.factorizations += 1;
            fresh = true;
        }
        rel = new_rel;
    }
    Err(solve::not_converged(info, params.rtol, "Cholesky").into())
}

/// Newton with the kept factor `chol` of an earlier bond set and the low-rank update `update` of
/// the bonds added since ([`super::lowrank`]), never refactorising (the factor's pattern is not
/// the current one). `Ok(true)`: converged; `Ok(false)`: an iteration reduced the residual by
/// less than 10× (the rule of [`newton_on_factor`] for a stale factor; an iterate that does not
/// reduce it at all is not taken) or the iterations ran out, and the caller continues from `x`
/// with a fresh analysis and factor.
#[allow(clippy::too_many_arguments)]
pub(super) fn newton_on_update(
    params: &MechParams,
    rep: &TopologyReport,
    op: &amg::FineOp,
    chol: &mut BondCholesky,
    update: &LowRank,
    b: &[f64],
    b_norm: f64,
    x: &mut [f64],
    info: &mut MechInfo,
) -> Result<bool, Error> {
    let (mut r, mut rel) = initial_residual(op, b, b_norm, x, None);
    let mut red = vec![0.0; rep.n_eq];
    while info.newton_iterations < params.max_newton {
        gather_free(&rep.eq, &r, &mut red);
        info.solve_seconds += chol.solve_in_place(&mut red)?;
        let t0 = Instant::now();
        update.correct(&mut red);
        info.solve_seconds += t0.elapsed().as_secs_f64();
        if !red.iter().all(|v| v.is_finite()) {
            return Ok(false);
        }
        let mut trial = x.to_vec();
        add_free(&rep.eq, &red, &mut trial);
        let mut r_trial = vec![0.0; r.len()];
        let new_rel = op.residual(b, b_norm, &trial, &mut r_trial);
        if !(new_rel.is_finite() && new_rel < rel) {
            // not taken: the fresh factor starts from the last good iterate
            return Ok(false);
        }
        x.copy_from_slice(&trial);
        r = r_trial;
        info.newton_iterations += 1;
        info.residuals.push(new_rel);
        if new_rel <= params.rtol {
            return Ok(true);
        }
        if new_rel > 0.1 * rel {
            return Ok(false);
        }
        rel = new_rel;
    }
    Ok(false)
}

/// CG iterations at most with a stale factor before a fresh factorisation takes over [1].
pub(super) const STALE_CG_MAX_ITER: usize = 40;
/// A stale-factor CG that needed more iterations than this triggers a fresh factorisation at the
/// next step [1] (one factorisation costs about as much as 20 iterations at 10³ particles).
pub(super) const STALE_CG_REFRESH: usize = 12;

/// CG on the current stiffness `op` preconditioned by the factor `chol` of an earlier stiffness
/// with equation map `chol_eq` (DOF of the current map `eq` that it lacks get the inverse of
/// their particle's diagonal block). `Some(iterations)` when the true scaled residual reaches
/// `rtol`, `None` when CG does not converge within [`STALE_CG_MAX_ITER`] iterations. The
/// preconditioner is block diagonal over the two DOF sets, each block SPD, so CG applies.
pub(super) fn stale_factor_cg(
    chol: &mut BondCholesky,
    chol_eq: &[u32],
    op: &amg::FineOp,
    eq: &[u32],
    blocks: &BlockMatrix,
    b: &[f64],
    b_norm: f64,
    rtol: f64,
    x: &mut [f64],
    info: &mut MechInfo,
) -> Result<Option<usize>, Error> {
    let n_old = chol_eq.iter().filter(|&&e| e != u32::MAX).count();
    // particles with DOF that the factor does not know: their block-Jacobi inverse on those DOF
    let mut extra: Vec<(usize, u8, nalgebra::Matrix6<f64>)> = Vec::new();
    for i in 0..eq.len() / 6 {
        let new_only = (0..6).fold(0u8, |m, k| if eq[6 * i + k] != u32::MAX && chol_eq[6 * i + k] == u32::MAX { m | (1 << k) } else { m });
        if new_only == 0 {
            continue;
        }
        let mut d = blocks.diag[i];
        for k in 0..6 {
            if new_only & (1 << k) == 0 {
                d.row_mut(k).fill(0.0);
                d.column_mut(k).fill(0.0);
                d[(k, k)] = 1.0;
            }
        }
        match d.cholesky() {
            Some(c) => extra.push((i, new_only, c.inverse())),
            None => return Ok(None),
        }
    }
    let mut red = vec![0.0; n_old];
    let mut solve_s = 0.0;
    let res = {
        let mut prec = |r: &[f64], z: &mut [f64]| -> Result<(), SolveError> {
            gather_free(chol_eq, r, &mut red);
            solve_s += chol.solve_in_place(&mut red)?;
            for d in 0..z.len() {
                z[d] = if eq[d] != u32::MAX && chol_eq[d] != u32::MAX { red[chol_eq[d] as usize] } else { 0.0 };
            }
            for (i, m, inv) in &extra {
                let v = inv * nalgebra::Vector6::from_column_slice(&r[6 * i..6 * i + 6]);
                for k in 0..6 {
                    if m & (1 << k) != 0 {
                        z[6 * i + k] = v[k];
                    }
                }
            }
            Ok(())
        };
        cg::pcg_with(|v, out| op.matvec(v, out), &mut prec, b, x, 0.5 * rtol, STALE_CG_MAX_ITER)
    };
    info.solve_seconds += solve_s;
    match res {
        Ok(pi) => {
            info.pcg_iterations += pi.iterations;
            info.newton_iterations += 1;
            let mut r = vec![0.0; b.len()];
            let rel = op.residual(b, b_norm, x, &mut r);
            info.residuals.push(rel);
            if rel <= rtol {
                return Ok(Some(pi.iterations));
            }
        }
        // not converged (or the stale operator lost definiteness): a fresh factor takes over
        Err(_) => info.pcg_iterations += STALE_CG_MAX_ITER,
    }
    Ok(None)
}

/// Inexact Newton on the current stiffness (B10) from `x` (whose residual is `r0` when known):
/// each iteration solves `K·dx = r` from `dx = 0` to the relative tolerance min(0.1, 0.5·rtol/rel)
/// with `inner(r, dx, tol, info)`, so that the outer scaled residual lands below rtol with a
/// margin, adds `dx` and tests the residual; `what` names the solver in the error.
#[allow(clippy::too_many_arguments)]
pub(super) fn newton_inexact<S>(
    params: &MechParams,
    op: &amg::FineOp,
    b: &[f64],
    b_norm: f64,
    x: &mut [f64],
    r0: Option<Vec<f64>>,
    info: &mut MechInfo,
    what: &str,
    mut inner: S,
) -> Result<(), Error>
where
    S: FnMut(&[f64], &mut [f64], f64, &mut MechInfo) -> Result<(), Error>,
{
    let (mut r, mut rel) = initial_residual(op, b, b_norm, x, r0);
    if rel <= params.rtol {
        return Ok(());
    }
    let mut dx = vec![0.0; x.len()];
    while info.newton_iterations < params.max_newton {
        let tol = (0.5 * params.rtol / rel).min(0.1);
        dx.iter_mut().for_each(|v| *v = 0.0);
        inner(&r, &mut dx, tol, info)?;
        x.par_iter_mut().zip(dx.par_iter()).for_each(|(xi, d)| *xi += d);
        info.newton_iterations += 1;
        rel = op.residual(b, b_norm, x, &mut r);
        info.residuals.push(rel);
        if !rel.is_finite() {
            return Err(not_finite(info).into());
        }
        if rel <= params.rtol {
            return Ok(());
        }
    }
    Err(solve::not_converged(info, params.rtol, what).into())
}

/// `(b − K x, ‖b − K x‖₂/‖b‖₂)`: `known` when the warm start computed it, no product when `x`
/// is zero.
pub(super) fn initial_residual(op: &amg::FineOp, b: &[f64], b_norm: f64, x: &[f64], known: Option<Vec<f64>>) -> (Vec<f64>, f64) {
    if let Some(r) = known {
        let rel = cg::dot(&r, &r).sqrt() / b_norm;
        return (r, rel);
    }
    let mut r = b.to_vec();
    if x.iter().all(|&v| v == 0.0) {
        return (r, 1.0);
    }
    let rel = op.residual(b, b_norm, x, &mut r);
    (r, rel)
}

/// The warm start (docs/mechanics.md (B12)): the Galerkin projection of `K x = b` onto the span of
/// the earlier solutions `history` (fixed DOF of the current topology zeroed), `x₀ = V c` with
/// `(VᵀKV) c = Vᵀb`, the K-norm-optimal start in that span. The directions are made
/// K-orthonormal newest first and projected one by one; one that keeps less than 1e-12 of its
/// K-norm² after orthogonalisation (parallel to those kept) is dropped, and the older ones are
/// not needed once the relative residual is at most `rtol` (the step is then solved). Writes `x`
/// and returns the relative residual ‖b − K x₀‖₂/‖b‖₂ with the residual (1, None and `x = 0`
/// when no direction lowers it).
pub(super) fn warm_start(op: &amg::FineOp, history: &[Vec<f64>], b: &[f64], b_norm: f64, rtol: f64, x: &mut [f64]) -> (f64, Option<Vec<f64>>) {
    let n = b.len();
    let mut kept = false;
    let mut basis: Vec<(Vec<f64>, Vec<f64>)> = Vec::with_capacity(history.len());
    x.iter_mut().for_each(|v| *v = 0.0);
    let mut r = b.to_vec();
    let mut rel = 1.0;
    for h in history.iter().rev() {
        let mut v = h.clone();
        for (i, m) in op.fixed.iter().enumerate() {
            for k in 0..6 {
                if m & (1 << k) != 0 {
                    v[6 * i + k] = 0.0;
                }
            }
        }
        let mut kv = vec![0.0; n];
        op.matvec(&v, &mut kv);
        let vkv0 = cg::dot(&v, &kv);
        for (u, ku) in &basis {
            let c = cg::dot(&v, ku);
            v.par_iter_mut().zip(u.par_iter()).for_each(|(vi, ui)| *vi -= c * ui);
            kv.par_iter_mut().zip(ku.par_iter()).for_each(|(vi, ui)| *vi -= c * ui);
        }
        let vkv = cg::dot(&v, &kv);
        if !(vkv.is_finite() && vkv > 1e-12 * vkv0) {
            continue;
        }
        let s = 1.0 / vkv.sqrt();
        v.par_iter_mut().for_each(|vi| *vi *= s);
        kv.par_iter_mut().for_each(|vi| *vi *= s);
        // K-orthonormal basis: x₀ = Σ (uᵢ·b) uᵢ, r₀ = b − Σ (uᵢ·b) K uᵢ, one direction at a time
        let c = cg::dot(&v, b);
        x.par_iter_mut().zip(v.par_iter()).for_each(|(xi, ui)| *xi += c * ui);
        r.par_iter_mut().zip(kv.par_iter()).for_each(|(ri, ki)| *ri -= c * ki);
        kept = true;
        rel = cg::dot(&r, &r).sqrt() / b_norm;
        if rel <= rtol {
            break;
        }
        basis.push((v, kv));
    }
    if !kept || !(rel.is_finite() && rel < 1.0) {
        x.iter_mut().for_each(|v| *v = 0.0);
        return (1.0, None);
    }
    (rel, Some(r))
}

pub(super) fn not_finite(info: &MechInfo) -> SolveError {
    SolveError { stage: "mechanics Newton".into(), message: "non-finite residual (singular or ill-posed stiffness)".into(), residuals: info.residuals.clone() }
}

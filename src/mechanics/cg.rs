//! Conjugate gradients with a block-Jacobi preconditioner (one 6×6 block per particle, the
//! particle's translations and scaled rotations together), the iterative alternative to the sparse
//! Cholesky for large packings (docs/mechanics.md (B10): iterate to
//! `‖S(ΔF − K·Δy)‖₂ ≤ rtol·‖S·ΔF‖₂` or return a [`SolveError`]).
//!
//! Vectors are the full `6n` scaled unknowns; fixed DOF are kept at zero (their rows and columns
//! of the preconditioner are the identity and the operator zeroes them), which is the reduced
//! system without renumbering. Dot products are summed in fixed-size chunks in a fixed order, so
//! the iteration is bit-identical for any thread count.

use crate::error::SolveError;
use nalgebra::{Matrix6, Vector6};
use rayon::prelude::*;

const CHUNK: usize = 4096;

/// Deterministic parallel dot product.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let partial: Vec<f64> = a.par_chunks(CHUNK).zip(b.par_chunks(CHUNK)).map(|(x, y)| x.iter().zip(y).map(|(p, q)| p * q).sum()).collect();
    partial.iter().sum()
}

/// Inverses of the 6×6 diagonal blocks (fixed DOF: identity).
#[derive(Debug, Clone)]
pub struct BlockJacobi {
    inv: Vec<Matrix6<f64>>,
}

impl BlockJacobi {
    /// From the diagonal blocks `diag` and the fixed-DOF masks `fixed` (bits 0–5).
    pub fn new(diag: &[Matrix6<f64>], fixed: &[u8]) -> Result<Self, SolveError> {
        let inv: Result<Vec<Matrix6<f64>>, SolveError> = diag
            .par_iter()
            .zip(fixed.par_iter())
            .enumerate()
            .map(|(i, (d, &m))| {
                let mut d = *d;
                for k in 0..6 {
                    if m & (1 << k) != 0 {
                        d.row_mut(k).fill(0.0);
                        d.column_mut(k).fill(0.0);
                        d[(k, k)] = 1.0;
                    }
                }
                d.cholesky()
                    .map(|c| c.inverse())
                    .ok_or_else(|| SolveError::new("block-Jacobi preconditioner", format!("diagonal block of particle {i} is not positive definite")))
            })
            .collect();
        Ok(BlockJacobi { inv: inv? })
    }

    /// Number of blocks (particles).
    pub fn len(&self) -> usize {
        self.inv.len()
    }

    pub fn is_empty(&self) -> bool {
        self.inv.is_empty()
    }

    /// The inverse block of particle `i`.
    pub fn inv(&self, i: usize) -> &Matrix6<f64> {
        &self.inv[i]
    }

    /// `x += ω M⁻¹ r`.
    pub fn apply_add(&self, r: &[f64], x: &mut [f64], omega: f64) {
        x.par_chunks_mut(6).zip(r.par_chunks(6)).zip(self.inv.par_iter()).for_each(|((xi, ri), m)| {
            let v = m * Vector6::from_column_slice(ri);
            for k in 0..6 {
                xi[k] += omega * v[k];
            }
        });
    }

    /// `z = M⁻¹ r`.
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        z.par_chunks_mut(6).zip(r.par_chunks(6)).zip(self.inv.par_iter()).for_each(|((zi, ri), m)| {
            let v = m * Vector6::from_column_slice(ri);
            zi.copy_from_slice(v.as_slice());
        });
    }
}

/// What a PCG solve did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PcgInfo {
    /// Iterations [1].
    pub iterations: usize,
    /// Final recursive relative residual ‖r‖₂/‖b‖₂ [1].
    pub residual: f64,
}

/// Solves `A x = b` by preconditioned CG from the initial `x` to `‖b − A x‖₂ ≤ rtol·‖b‖₂` (recursive
/// residual), at most `max_iter` iterations. `apply_a(x, y)` computes `y = A x`.
pub fn pcg<F>(apply_a: F, prec: &BlockJacobi, b: &[f64], x: &mut [f64], rtol: f64, max_iter: usize) -> Result<PcgInfo, SolveError>
where
    F: Fn(&[f64], &mut [f64]),
{
    pcg_with(
        apply_a,
        |r, z| {
            prec.apply(r, z);
            Ok(())
        },
        b,
        x,
        rtol,
        max_iter,
    )
}

/// [`pcg`] with any symmetric positive definite preconditioner `apply_m(r, z)`: `z = M⁻¹ r`. A
/// non-positive `rᵀM⁻¹r` (a preconditioner that is not SPD) is a [`SolveError`].
pub fn pcg_with<F, M>(apply_a: F, mut apply_m: M, b: &[f64], x: &mut [f64], rtol: f64, max_iter: usize) -> Result<PcgInfo, SolveError>
where
    F: Fn(&[f64], &mut [f64]),
    M: FnMut(&[f64], &mut [f64]) -> Result<(), SolveError>,
{
    let n = b.len();
    let b_norm = dot(b, b).sqrt();
    if b_norm == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        return Ok(PcgInfo { iterations: 0, residual: 0.0 });
    }
    let mut r = vec![0.0; n];
    apply_a(x, &mut r);
    r.par_iter_mut().zip(b.par_iter()).for_each(|(ri, bi)| *ri = bi - *ri);
    let mut z = vec![0.0; n];
    apply_m(&r, &mut z)?;
    let mut p = z.clone();
    let mut q = vec![0.0; n];
    let mut rz = dot(&r, &z);
    let mut history: Vec<f64> = Vec::new();
    let mut rel = dot(&r, &r).sqrt() / b_norm;
    for it in 0..=max_iter {
        if rel <= rtol {
            return Ok(PcgInfo { iterations: it, residual: rel });
        }
        if !rel.is_finite() {
            break;
        }
        if it == max_iter {
            break;
        }
        apply_a(&p, &mut q);
        let pq = dot(&p, &q);
        if !(pq > 0.0) {
            history.push(rel);
            return Err(SolveError {
                stage: "mechanics PCG".into(),
                message: format!("the stiffness is not positive definite (pᵀKp = {pq:.3e} at iteration {it})"),
                residuals: history,
            });
        }
        let alpha = rz / pq;
        x.par_iter_mut().zip(p.par_iter()).for_each(|(xi, pi)| *xi += alpha * pi);
        r.par_iter_mut().zip(q.par_iter()).for_each(|(ri, qi)| *ri -= alpha * qi);
        apply_m(&r, &mut z)?;
        let rz_new = dot(&r, &z);
        if !(rz_new > 0.0) && dot(&r, &r) > 0.0 {
            history.push(rel);
            return Err(SolveError {
                stage: "mechanics PCG".into(),
                message: format!("the preconditioner is not positive definite (rᵀM⁻¹r = {rz_new:.3e} at iteration {it})"),
                residuals: history,
            });
        }
        let beta = rz_new / rz;
        rz = rz_new;
        p.par_iter_mut().zip(z.par_iter()).for_each(|(pi, zi)| *pi = zi + beta * *pi);
        rel = dot(&r, &r).sqrt() / b_norm;
        if it % 50 == 0 {
            history.push(rel);
        }
    }
    history.push(rel);
    let keep = history.len().saturating_sub(12);
    Err(SolveError {
        stage: "mechanics PCG".into(),
        message: format!("no convergence to {rtol:.1e} in {max_iter} iterations (relative residual {rel:.3e})"),
        residuals: history.split_off(keep),
    })
}

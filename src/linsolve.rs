//! Sparse symmetric positive-definite solves with faer's Cholesky (docs/decisions.md "Foundation").
//!
//! [`SpdPattern`] holds the lower-triangle sparsity pattern of a matrix and its symbolic
//! factorisation (AMD ordering, elimination tree, supernodes), computed once per topology; each
//! [`SpdPattern::factorize`] only scatters new values and runs the numeric factorisation. Every
//! solve reports a [`SolveInfo`] with its scaled residual.

use crate::error::SolveError;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use faer::{MatMut, Side};
use std::time::Instant;

/// What a linear solve did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SolveInfo {
    /// Wall time of the numeric factorisation [s].
    pub factor_seconds: f64,
    /// Wall time of the triangular solves [s].
    pub solve_seconds: f64,
    /// Scaled residual ‖A x − b‖∞ / (‖A‖∞‖x‖∞ + ‖b‖∞) [1].
    pub residual: f64,
}

/// Lower-triangle pattern + symbolic Cholesky factorisation, reused while the topology is unchanged.
pub struct SpdPattern {
    n: usize,
    rows: Vec<u32>,
    cols: Vec<u32>,
    symbolic: SymbolicSparseColMat<usize>,
    argsort: Argsort<usize>,
    llt: SymbolicLlt<usize>,
    /// Wall time of the symbolic analysis [s].
    pub symbolic_seconds: f64,
}

impl SpdPattern {
    /// `entries`: the `(row, col)` positions, `row ≥ col` (lower triangle, duplicates allowed and
    /// summed), in the order in which [`factorize`](Self::factorize) will receive their values.
    pub fn new(n: usize, entries: &[(u32, u32)]) -> Result<Self, SolveError> {
        let t0 = Instant::now();
        if let Some(&(r, c)) = entries.iter().find(|&&(r, c)| r < c || r as usize >= n) {
            return Err(SolveError::new("sparse pattern", format!("entry ({r}, {c}) is not in the lower triangle of a {n}×{n} matrix")));
        }
        let idx: Vec<Pair<usize, usize>> = entries.iter().map(|&(r, c)| Pair::new(r as usize, c as usize)).collect();
        let (symbolic, argsort) = SymbolicSparseColMat::try_new_from_indices(n, n, &idx).map_err(|e| SolveError::new("sparse pattern", format!("{e:?}")))?;
        let llt = SymbolicLlt::try_new(symbolic.as_ref(), Side::Lower).map_err(|e| SolveError::new("symbolic Cholesky", format!("{e:?}")))?;
        Ok(SpdPattern {
            n,
            rows: entries.iter().map(|e| e.0).collect(),
            cols: entries.iter().map(|e| e.1).collect(),
            symbolic,
            argsort,
            llt,
            symbolic_seconds: t0.elapsed().as_secs_f64(),
        })
    }

    /// Dimension.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of entries given at construction.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Numeric factorisation for `values` (one per entry, in construction order).
    pub fn factorize(&self, values: &[f64]) -> Result<SpdFactor, SolveError> {
        if values.len() != self.rows.len() {
            return Err(SolveError::new("Cholesky", format!("{} values for {} entries", values.len(), self.rows.len())));
        }
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(SolveError::new("Cholesky", format!("matrix entry ({}, {}) is {}", self.rows[k], self.cols[k], values[k])));
        }
        let t0 = Instant::now();
        let mat = SparseColMat::new_from_argsort(self.symbolic.clone(), &self.argsort, values).map_err(|e| SolveError::new("Cholesky", format!("{e:?}")))?;
        let llt = Llt::try_new_with_symbolic(self.llt.clone(), mat.as_ref(), Side::Lower)
            .map_err(|e| SolveError::new("Cholesky", format!("matrix is not positive definite ({e:?})")))?;
        Ok(SpdFactor { values: values.to_vec(), llt, factor_seconds: t0.elapsed().as_secs_f64() })
    }

    /// `y = A x` for the symmetric matrix whose lower triangle is `values`.
    pub fn matvec(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for k in 0..values.len() {
            let (r, c) = (self.rows[k] as usize, self.cols[k] as usize);
            y[r] += values[k] * x[c];
            if r != c {
                y[c] += values[k] * x[r];
            }
        }
    }
}

/// A numeric Cholesky factor of the matrix with the given values on an [`SpdPattern`].
pub struct SpdFactor {
    /// The factored values (lower triangle, construction order).
    pub values: Vec<f64>,
    llt: Llt<usize, f64>,
    /// Wall time of the numeric factorisation [s].
    pub factor_seconds: f64,
}

impl SpdFactor {
    /// Solves `A x = b` in place (`b` becomes `x`) and checks the residual; `pattern` is the one
    /// that produced this factor.
    pub fn solve_in_place(&self, pattern: &SpdPattern, b: &mut [f64]) -> Result<SolveInfo, SolveError> {
        let n = pattern.n;
        let rhs = b.to_vec();
        let t0 = Instant::now();
        self.llt.solve_in_place(MatMut::from_column_major_slice_mut(b, n, 1));
        let solve_seconds = t0.elapsed().as_secs_f64();
        let mut ax = vec![0.0; n];
        pattern.matvec(&self.values, b, &mut ax);
        let mut row_abs = vec![0.0; n];
        for k in 0..self.values.len() {
            let (r, c) = (pattern.rows[k] as usize, pattern.cols[k] as usize);
            row_abs[r] += self.values[k].abs();
            if r != c {
                row_abs[c] += self.values[k].abs();
            }
        }
        let a_norm = row_abs.iter().copied().fold(0.0, f64::max);
        let x_norm = b.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let b_norm = rhs.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let r_norm = ax.iter().zip(&rhs).map(|(a, r)| (a - r).abs()).fold(0.0, f64::max);
        let denom = a_norm * x_norm + b_norm;
        let residual = if denom > 0.0 { r_norm / denom } else { r_norm };
        if !residual.is_finite() || b.iter().any(|v| !v.is_finite()) {
            return Err(SolveError { stage: "Cholesky solve".into(), message: "non-finite solution".into(), residuals: vec![residual] });
        }
        if residual > 1e-8 {
            return Err(SolveError { stage: "Cholesky solve".into(), message: "scaled residual above 1e-8".into(), residuals: vec![residual] });
        }
        Ok(SolveInfo { factor_seconds: self.factor_seconds, solve_seconds, residual })
    }
}

/// Chooses faer's parallelism for a system of `n` unknowns: sequential below 1e5 (measured when faer was chosen:
/// two threads are neutral or slower there), rayon above.
pub fn set_parallelism_for(n: usize) {
    let par = if n >= 100_000 && rayon::current_num_threads() > 1 { faer::Par::rayon(rayon::current_num_threads()) } else { faer::Par::Seq };
    faer::set_global_parallelism(par);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_laplacian_plus_diagonal_and_reuses_the_pattern() {
        // 1-D chain: tridiagonal (2 + s) on the diagonal, −1 off it.
        let n = 50;
        let mut e = Vec::new();
        for i in 0..n as u32 {
            e.push((i, i));
            if i > 0 {
                e.push((i, i - 1));
            }
        }
        let p = SpdPattern::new(n, &e).unwrap();
        for s in [1e-6, 1.0] {
            let vals: Vec<f64> = e.iter().map(|&(r, c)| if r == c { 2.0 + s } else { -1.0 }).collect();
            let x_true: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
            let mut b = vec![0.0; n];
            p.matvec(&vals, &x_true, &mut b);
            let f = p.factorize(&vals).unwrap();
            let info = f.solve_in_place(&p, &mut b).unwrap();
            assert!(info.residual < 1e-14, "{info:?}");
            let err = b.iter().zip(&x_true).map(|(a, t)| (a - t).abs()).fold(0.0, f64::max);
            assert!(err < 1e-8 / s.max(1e-3), "s = {s}: {err}");
        }
    }

    #[test]
    fn rejects_indefinite_and_nonfinite() {
        let e = [(0, 0), (1, 1), (1, 0)];
        let p = SpdPattern::new(2, &e).unwrap();
        assert!(p.factorize(&[1.0, 1.0, 2.0]).is_err());
        assert!(p.factorize(&[1.0, f64::NAN, 0.0]).is_err());
        assert!(SpdPattern::new(2, &[(0, 1)]).is_err());
    }
}

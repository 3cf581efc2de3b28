//! Low-rank update of a kept Cholesky factor for new bonds (issue 40 lever 1; docs/coupled.md
//! "Low-rank update of the factor").
//!
//! A new bond between A and B adds its element matrix `Bᵀ·diag(k)·B` ([`super::bond`], scaled)
//! to the stiffness: with `V = Bᵀ·diag(√k)` restricted to the free DOF (12 × 6, rank ≤ 6) the
//! stiffness after the change is `K₀ + U·Uᵀ`, `U` the columns of all bonds added since the factor
//! `L·Lᵀ = K₀` was computed. The Woodbury identity solves with it from the kept factor:
//!
//! ```text
//! (K₀ + U Uᵀ)⁻¹ b = y − Z·G⁻¹·(Uᵀ y),   y = K₀⁻¹ b,   Z = K₀⁻¹ U,   G = I + Uᵀ Z  (SPD, r × r)
//! ```
//!
//! `Z` is computed once per column (one multi-right-hand-side solve per change of the bond set),
//! `G` is kept as its lower Cholesky factor, grown row by row as columns are added (rows of
//! earlier columns do not change). The operator serves the modified Newton iteration of
//! [`super::newton`] exactly as the stale factor of one topology does: the residual is always
//! that of the current stiffness, so the converged equilibrium is the same within the tolerance.
//! All loops are sequential in a fixed order (bit-identical for any thread count).

use super::bond::{BondGeometry, kinematics};
use super::cholesky::BondCholesky;
use crate::error::SolveError;
use std::time::Instant;

/// A kept factor's low-rank update: the columns `U` of the bonds `base..bonds`, `Z = K₀⁻¹U` and
/// the Cholesky factor of the capacitance `G = I + UᵀZ`.
pub struct LowRank {
    /// Bonds covered (factor and update): the first `bonds` of the bond list [1].
    pub bonds: usize,
    n_eq: usize,
    /// Sparse columns of `U`: column j has entries `u_idx/u_val[u_start[j]..u_start[j+1]]`.
    u_start: Vec<usize>,
    u_idx: Vec<u32>,
    u_val: Vec<f64>,
    /// `Z = K₀⁻¹U`, column-major `n_eq × r`.
    z: Vec<f64>,
    /// Lower Cholesky factor of `G`, row i holding `L[i][0..=i]` at `g_l[i(i+1)/2..]`.
    g_l: Vec<f64>,
}

impl LowRank {
    /// No update yet on a factor of the first `bonds` bonds with `n_eq` equations.
    pub fn new(bonds: usize, n_eq: usize) -> Self {
        LowRank { bonds, n_eq, u_start: vec![0], u_idx: Vec::new(), u_val: Vec::new(), z: Vec::new(), g_l: Vec::new() }
    }

    /// Rank of the update (columns of `U`) [1].
    pub fn rank(&self) -> usize {
        self.u_start.len() - 1
    }

    /// The (up to) six columns `V = Bᵀ·diag(√k)` of a bond between `a` and `b` with geometry `g`,
    /// links `k` [N/m, N·m] and rotation scale `r_scale` [m], on the free DOF of `eq`
    /// (equation of DOF `6i + d`, `u32::MAX` if fixed). Columns without a free DOF are left out.
    pub fn bond_columns(a: u32, b: u32, g: &BondGeometry, k: &[f64; 6], r_scale: f64, eq: &[u32]) -> Vec<Vec<(u32, f64)>> {
        let bm = kinematics(g, r_scale);
        let mut cols = Vec::with_capacity(6);
        for (l, &kl) in k.iter().enumerate() {
            let s = kl.sqrt();
            let mut col = Vec::with_capacity(12);
            for d in 0..12 {
                let p = if d < 6 { a } else { b } as usize;
                let e = eq[6 * p + d % 6];
                let v = bm[(l, d)] * s;
                if e != u32::MAX && v != 0.0 {
                    col.push((e, v));
                }
            }
            if !col.is_empty() {
                cols.push(col);
            }
        }
        cols
    }

    /// Adds the columns `cols` (entries `(equation, value)`) for the bonds up to `bonds`: their
    /// `Z` by one solve with the kept factor `chol`, then the new rows of the capacitance factor.
    /// Returns the wall time [s]; an error when `G` is not positive definite (round-off on a
    /// nearly singular `K₀`), after which this update must not be used.
    pub fn extend(&mut self, chol: &mut BondCholesky, cols: Vec<Vec<(u32, f64)>>, bonds: usize) -> Result<f64, SolveError> {
        let t0 = Instant::now();
        let (n, r0, m) = (self.n_eq, self.rank(), cols.len());
        let mut zn = vec![0.0; n * m];
        for (j, col) in cols.iter().enumerate() {
            for &(e, v) in col {
                zn[j * n + e as usize] += v;
            }
        }
        if m > 0 {
            chol.solve_many_in_place(&mut zn, m)?;
        }
        for col in &cols {
            for &(e, v) in col {
                self.u_idx.push(e);
                self.u_val.push(v);
            }
            self.u_start.push(self.u_idx.len());
        }
        self.z.extend_from_slice(&zn);
        // rows r0..r0+m of L with G_ik = U_kᵀ Z_i (k ≤ i), I on the diagonal
        for i in r0..r0 + m {
            let zi = &self.z[i * n..(i + 1) * n];
            let base = i * (i + 1) / 2;
            self.g_l.resize(base + i + 1, 0.0);
            for k in 0..=i {
                let mut g = (self.u_start[k]..self.u_start[k + 1]).map(|p| self.u_val[p] * zi[self.u_idx[p] as usize]).sum::<f64>();
                if k == i {
                    g += 1.0;
                }
                let bk = k * (k + 1) / 2;
                let dot: f64 = (0..k).map(|q| self.g_l[base + q] * self.g_l[bk + q]).sum();
                if k < i {
                    self.g_l[base + k] = (g - dot) / self.g_l[bk + k];
                } else {
                    let d = g - dot;
                    if !(d.is_finite() && d > 0.0) {
                        return Err(SolveError::new("low-rank update", format!("capacitance not positive definite at column {i} ({d:e})")));
                    }
                    self.g_l[base + i] = d.sqrt();
                }
            }
        }
        self.bonds = bonds;
        Ok(t0.elapsed().as_secs_f64())
    }

    /// `y ← y − Z·G⁻¹·(Uᵀ y)`: with `y = K₀⁻¹ b` on entry, `(K₀ + U Uᵀ)⁻¹ b` on return.
    pub fn correct(&self, y: &mut [f64]) {
        let (n, r) = (self.n_eq, self.rank());
        if r == 0 {
            return;
        }
        let mut s: Vec<f64> = (0..r).map(|j| (self.u_start[j]..self.u_start[j + 1]).map(|p| self.u_val[p] * y[self.u_idx[p] as usize]).sum()).collect();
        // L w = t, then Lᵀ s = w
        for i in 0..r {
            let base = i * (i + 1) / 2;
            let dot: f64 = (0..i).map(|q| self.g_l[base + q] * s[q]).sum();
            s[i] = (s[i] - dot) / self.g_l[base + i];
        }
        for i in (0..r).rev() {
            s[i] /= self.g_l[i * (i + 1) / 2 + i];
            let si = s[i];
            for q in 0..i {
                s[q] -= self.g_l[i * (i + 1) / 2 + q] * si;
            }
        }
        for (j, &sj) in s.iter().enumerate() {
            let zj = &self.z[j * n..(j + 1) * n];
            y.iter_mut().zip(zj).for_each(|(yi, zi)| *yi -= sj * zi);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::LowRank;
    use crate::mechanics::bond::{BondGeometry, element_matrix, link_stiffness};
    use crate::mechanics::cholesky::BondCholesky;
    use nalgebra::{DMatrix, DVector, Vector3};

    /// Two bonds added to a factored chain of three particles (one clamped): the updated solve
    /// equals the dense solve of the assembled stiffness with all bonds to round-off.
    #[test]
    fn woodbury_matches_the_assembled_stiffness() {
        let r = 25e-6;
        let x = [Vector3::new(0.0, 0.0, 0.0), Vector3::new(1.9 * r, 0.0, 0.0), Vector3::new(3.8 * r, 0.3 * r, 0.0), Vector3::new(1.9 * r, 1.8 * r, 0.2 * r)];
        let k = link_stiffness(72e9, 0.34, r);
        // particle 0 clamped: equations of particles 1..3
        let eq: Vec<u32> = (0..24).map(|d| if d < 6 { u32::MAX } else { d as u32 - 6 }).collect();
        let n = 18;
        let bonds = [[0u32, 1], [1, 2], [2, 3], [0, 3], [1, 3]];
        let dense = |upto: usize| {
            let mut kk = DMatrix::<f64>::zeros(n, n);
            for &[a, b] in &bonds[..upto] {
                let g = BondGeometry::new(&x[a as usize], &x[b as usize], 0.9 * r, 0.9 * r).unwrap();
                let ke = element_matrix(&g, &k, r);
                for p in 0..12 {
                    for q in 0..12 {
                        let (ep, eq_) = (eq[6 * [a, b][p / 6] as usize + p % 6], eq[6 * [a, b][q / 6] as usize + q % 6]);
                        if ep != u32::MAX && eq_ != u32::MAX {
                            kk[(ep as usize, eq_ as usize)] += ke[(p, q)];
                        }
                    }
                }
            }
            kk
        };
        let k0 = dense(3);
        let mut entries = Vec::new();
        let mut values = Vec::new();
        for c in 0..n {
            for rr in c..n {
                entries.push((rr as u32, c as u32));
                values.push(k0[(rr, c)]);
            }
        }
        let mut chol = BondCholesky::new(n, &entries, None).unwrap();
        chol.factorize(&values).unwrap();
        let mut up = LowRank::new(3, n);
        for (c, &[a, b]) in bonds.iter().enumerate().skip(3) {
            let g = BondGeometry::new(&x[a as usize], &x[b as usize], 0.9 * r, 0.9 * r).unwrap();
            let cols = LowRank::bond_columns(a, b, &g, &k, r, &eq);
            up.extend(&mut chol, cols, c + 1).unwrap();
        }
        // bond (0, 3) has A clamped: 6 columns on B's DOF only; bond (1, 3): 6 columns
        assert_eq!(up.rank(), 12);
        let rhs: Vec<f64> = (0..n).map(|i| 1e-3 * ((i as f64) * 0.7).sin()).collect();
        let mut y = rhs.clone();
        chol.solve_in_place(&mut y).unwrap();
        up.correct(&mut y);
        let exact = dense(5).lu().solve(&DVector::from_vec(rhs)).unwrap();
        let err = exact.iter().zip(&y).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let scale = exact.amax();
        assert!(err <= 1e-9 * scale, "{err:e} of {scale:e}");
    }
}

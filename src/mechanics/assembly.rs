//! Assembly of the bonded stiffness `S·K·S` (docs/mechanics.md (B10)) in 6×6 node
//! blocks: one diagonal block per particle, one off-diagonal block `K_AB` per bond. The element
//! blocks are computed in parallel (each bond writes its own slot) and gathered onto particles
//! through a particle→bond incidence table in bond order, so the result is bit-identical for any
//! thread count. The same blocks give the matrix–vector product of the residual and of the PCG,
//! and the lower-triangle entries handed to the sparse Cholesky.

use super::bond::{BondGeometry, element_blocks};
use super::constraints::TopologyReport;
use nalgebra::{Matrix6, Vector6};
use rayon::prelude::*;

/// Particle→bond incidence (CSR): for particle `i`, `bonds[start[i]..start[i+1]]` lists
/// `(bond, side)` with side 0 = the particle is A, 1 = it is B, in increasing bond order.
#[derive(Debug, Clone, Default)]
pub struct Incidence {
    pub start: Vec<u32>,
    pub bonds: Vec<(u32, u8)>,
}

impl Incidence {
    pub fn new(n: usize, pairs: &[[u32; 2]]) -> Self {
        let mut count = vec![0u32; n + 1];
        for p in pairs {
            count[p[0] as usize + 1] += 1;
            count[p[1] as usize + 1] += 1;
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut bonds = vec![(0u32, 0u8); 2 * pairs.len()];
        for (b, p) in pairs.iter().enumerate() {
            for side in 0..2 {
                let i = p[side] as usize;
                bonds[fill[i] as usize] = (b as u32, side as u8);
                fill[i] += 1;
            }
        }
        Incidence { start: count, bonds }
    }

    pub(crate) fn of(&self, i: usize) -> &[(u32, u8)] {
        &self.bonds[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

/// The assembled stiffness in node blocks (scaled unknowns, all entries in N/m).
#[derive(Debug, Clone, Default)]
pub struct BlockMatrix {
    /// Diagonal block per particle.
    pub diag: Vec<Matrix6<f64>>,
    /// `K_AB` per bond (rows: A's DOF, columns: B's DOF).
    pub off: Vec<Matrix6<f64>>,
}

impl BlockMatrix {
    /// Assembles the element matrices of all bonds: `geom[b]`, link stiffness `k[b]`, rotation
    /// scale `r_scale` [m].
    pub fn assemble(n: usize, pairs: &[[u32; 2]], inc: &Incidence, geom: &[BondGeometry], k: &[[f64; 6]], r_scale: f64) -> Self {
        let (ends, off): (Vec<[Matrix6<f64>; 2]>, Vec<Matrix6<f64>>) = geom
            .par_iter()
            .zip(k.par_iter())
            .map(|(g, kk)| {
                let (aa, ab, bb) = element_blocks(g, kk, r_scale);
                ([aa, bb], ab)
            })
            .unzip();
        let diag: Vec<Matrix6<f64>> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut d = Matrix6::zeros();
                for &(b, side) in inc.of(i) {
                    d += ends[b as usize][side as usize];
                }
                d
            })
            .collect();
        debug_assert_eq!(pairs.len(), geom.len());
        BlockMatrix { diag, off }
    }

    /// `y = K x` on the full 6n vectors, then zeroes the fixed DOF of `fixed` (`x` must be zero on them).
    pub fn matvec(&self, pairs: &[[u32; 2]], inc: &Incidence, fixed: &[u8], x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(6).enumerate().for_each(|(i, yi)| {
            let xi = Vector6::from_column_slice(&x[6 * i..6 * i + 6]);
            let mut acc = self.diag[i] * xi;
            for &(b, side) in inc.of(i) {
                let p = pairs[b as usize];
                if side == 0 {
                    let j = p[1] as usize;
                    acc += self.off[b as usize] * Vector6::from_column_slice(&x[6 * j..6 * j + 6]);
                } else {
                    let j = p[0] as usize;
                    acc += self.off[b as usize].tr_mul(&Vector6::from_column_slice(&x[6 * j..6 * j + 6]));
                }
            }
            let m = fixed[i];
            for k in 0..6 {
                yi[k] = if m & (1 << k) != 0 { 0.0 } else { acc[k] };
            }
        });
    }

    /// Visits the lower-triangle entries of the reduced (free-DOF) matrix in a fixed order:
    /// `f(row, col, value)` with `row ≥ col`. Used once for the pattern and every step for values.
    pub fn for_each_lower<F: FnMut(u32, u32, f64)>(&self, pairs: &[[u32; 2]], rep: &TopologyReport, mut f: F) {
        let eq = &rep.eq;
        for (i, d) in self.diag.iter().enumerate() {
            if rep.fixed[i] == 63 {
                continue;
            }
            for p in 0..6 {
                let rp = eq[6 * i + p];
                if rp == u32::MAX {
                    continue;
                }
                for q in 0..=p {
                    let rq = eq[6 * i + q];
                    if rq != u32::MAX {
                        f(rp, rq, d[(p, q)]);
                    }
                }
            }
        }
        for (b, &[a, bb]) in pairs.iter().enumerate() {
            let (a, bb) = (a as usize, bb as usize);
            if rep.fixed[a] == 63 || rep.fixed[bb] == 63 {
                continue;
            }
            let kab = &self.off[b];
            for p in 0..6 {
                let rp = eq[6 * a + p];
                if rp == u32::MAX {
                    continue;
                }
                for q in 0..6 {
                    let rq = eq[6 * bb + q];
                    if rq != u32::MAX {
                        f(rp.max(rq), rp.min(rq), kab[(p, q)]);
                    }
                }
            }
        }
    }
}

//! Aggregation multigrid (smoothed aggregation, SA) preconditioner for the bonded 6-DOF stiffness,
//! used inside CG ([`super::cg::pcg_with`]).
//!
//! - **Aggregates**: greedy SA aggregation over the bond graph (phase 1: a node whose neighbours are
//!   all free forms an aggregate with them; phase 2: leftovers join the neighbouring aggregate they
//!   are most connected to; phase 3: the rest form aggregates with their free neighbours), in node
//!   order, so deterministic. Fully fixed nodes (rattlers, pins) are left out. On coarse levels the
//!   graph is the block pattern of the coarse matrix with a strength threshold.
//! - **Tentative prolongator**: the six rigid-body modes per aggregate in the scaled unknowns
//!   `ỹ = [u, r̄θ]`: translations, and rotations `w = r̄ω` about the aggregate centroid `c`,
//!   `u_i = (w/r̄) × (x_i − c)`, rows of fixed DOF zero, orthonormalised per aggregate by modified
//!   Gram–Schmidt (two passes); a mode that the fixed DOF remove (column norm drops below 1e-6 of its
//!   initial value) becomes a fixed coarse DOF (zero column). The R factor is the coarse node's
//!   near-null-space block, so the coarse levels carry the same rigid modes (standard SA recursion).
//! - **Smoothing of P** (optional, default on): `P = (I − ω D⁻¹A) P_tent`, `ω = 4/(3 λ_max(D⁻¹A))`
//!   with `D` the 6×6 block diagonal and λ_max by a power iteration.
//! - **Coarse operators** `A_c = Pᵀ A P` (sparse block products, symmetrised), until the level has at
//!   most `max_coarse` equations; the coarsest is factorised by the faer sparse Cholesky
//!   ([`super::cholesky::BondCholesky`], sequential).
//! - **V-cycle**: `sweeps` damped block-Jacobi sweeps before and after the coarse correction with the
//!   same damping, so the preconditioner is symmetric; it is positive definite when the smoother
//!   converges in the energy norm (`ω_s·λ_max < 2`; `ω_s = 4/(3 λ_est)` leaves a 1.5× margin on the
//!   estimate).
//!
//! Every parallel loop writes its own rows; reductions use [`super::cg::dot`] (fixed chunks), block
//! products accumulate in a fixed order, so the result is bit-identical for any thread count.

use super::assembly::{BlockMatrix, Incidence};
use super::cg::{self, BlockJacobi};
use super::cholesky::BondCholesky;
use crate::error::SolveError;
use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

type B6 = Matrix6<f64>;

/// Parameters of the AMG preconditioner.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AmgParams {
    /// Smooth the tentative prolongator by one damped block-Jacobi step (smoothed aggregation;
    /// default off: fewer iterations but denser coarse levels, slower at 10⁴–10⁵ particles, docs/mechanics.md).
    pub smooth_p: bool,
    /// Block-Jacobi sweeps before and after the coarse correction [1].
    pub sweeps: usize,
    /// Smoother damping as a multiple of 1/λ_max(D⁻¹A) [1] (4/3 = the usual 2/3 for λ_max ≈ 2).
    pub smoother_omega: f64,
    /// Direct solve of a level with at most this many equations [1].
    pub max_coarse: usize,
    /// Levels at most (the last one is factorised) [1].
    pub max_levels: usize,
    /// Strength threshold on coarse levels: `‖A_ij‖_F ≥ θ·√(‖A_ii‖_F‖A_jj‖_F)` [1] (the fine level uses every bond).
    pub strength: f64,
    /// Keep the hierarchy (prolongators, coarse factor) across steps of one topology and refresh only
    /// the fine smoother; rebuild when CG needs more than `1.5×` the iterations of the last fresh
    /// build plus 5.
    pub reuse: bool,
}

impl Default for AmgParams {
    fn default() -> Self {
        AmgParams { smooth_p: false, sweeps: 1, smoother_omega: 4.0 / 3.0, max_coarse: 30_000, max_levels: 6, strength: 0.08, reuse: true }
    }
}

/// Square or rectangular sparse matrix of 6×6 blocks, rows in CSR order, columns sorted per row.
#[derive(Debug, Clone, Default)]
pub struct BlockCsr {
    pub n_cols: usize,
    pub start: Vec<u32>,
    pub col: Vec<u32>,
    pub val: Vec<B6>,
}

impl BlockCsr {
    pub fn n_rows(&self) -> usize {
        self.start.len() - 1
    }

    pub fn row(&self, i: usize) -> impl Iterator<Item = (u32, &B6)> {
        let (a, b) = (self.start[i] as usize, self.start[i + 1] as usize);
        self.col[a..b].iter().copied().zip(&self.val[a..b])
    }

    fn from_rows(n_cols: usize, rows: Vec<Vec<(u32, B6)>>) -> Self {
        let mut start = Vec::with_capacity(rows.len() + 1);
        start.push(0u32);
        let nnz: usize = rows.iter().map(|r| r.len()).sum();
        let (mut col, mut val) = (Vec::with_capacity(nnz), Vec::with_capacity(nnz));
        for r in rows {
            for (c, v) in r {
                col.push(c);
                val.push(v);
            }
            start.push(col.len() as u32);
        }
        BlockCsr { n_cols, start, col, val }
    }

    /// `y = A x`, then zeroes the DOF of `fixed` in `y`.
    pub fn matvec(&self, fixed: &[u8], x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(6).enumerate().for_each(|(i, yi)| {
            let mut acc = Vector6::zeros();
            for (j, b) in self.row(i) {
                let j = j as usize;
                acc += b * Vector6::from_column_slice(&x[6 * j..6 * j + 6]);
            }
            for k in 0..6 {
                yi[k] = if fixed[i] & (1 << k) != 0 { 0.0 } else { acc[k] };
            }
        });
    }

    /// The transpose (blocks transposed), rows in column order of the original: deterministic.
    pub fn transpose(&self) -> BlockCsr {
        let n = self.n_rows();
        let mut count = vec![0u32; self.n_cols + 1];
        for &c in &self.col {
            count[c as usize + 1] += 1;
        }
        for j in 0..self.n_cols {
            count[j + 1] += count[j];
        }
        let mut fill = count.clone();
        let mut col = vec![0u32; self.col.len()];
        let mut val = vec![B6::zeros(); self.col.len()];
        for i in 0..n {
            for (j, b) in self.row(i) {
                let p = fill[j as usize] as usize;
                col[p] = i as u32;
                val[p] = b.transpose();
                fill[j as usize] += 1;
            }
        }
        BlockCsr { n_cols: n, start: count, col, val }
    }
}

/// Sorted merge of `(col, block)` products in push order: blocks with the same column are summed in
/// the order they were pushed (stable sort), so the result does not depend on scheduling.
fn merge(mut acc: Vec<(u32, B6)>) -> Vec<(u32, B6)> {
    acc.sort_by_key(|e| e.0);
    let mut out: Vec<(u32, B6)> = Vec::with_capacity(acc.len());
    for (c, v) in acc {
        match out.last_mut() {
            Some(l) if l.0 == c => l.1 += v,
            _ => out.push((c, v)),
        }
    }
    out
}

/// The operator of one level: the fine level is the assembled bond matrix, coarse levels block CSR.
#[derive(Clone, Copy)]
pub struct FineOp<'a> {
    pub blocks: &'a BlockMatrix,
    pub pairs: &'a [[u32; 2]],
    pub inc: &'a Incidence,
    pub fixed: &'a [u8],
}

impl FineOp<'_> {
    /// Visits row `i`: the diagonal block, then the bond blocks in bond order.
    fn for_row(&self, i: usize, mut f: impl FnMut(u32, &B6)) {
        f(i as u32, &self.blocks.diag[i]);
        for &(b, side) in self.inc.of(i) {
            let p = self.pairs[b as usize];
            if side == 0 {
                f(p[1], &self.blocks.off[b as usize]);
            } else {
                f(p[0], &self.blocks.off[b as usize].transpose());
            }
        }
    }

    fn n(&self) -> usize {
        self.blocks.diag.len()
    }

    /// `y = K x` (fixed DOF zero).
    pub fn matvec(&self, x: &[f64], y: &mut [f64]) {
        self.blocks.matvec(self.pairs, self.inc, self.fixed, x, y);
    }

    /// The scaled residual `r = b − K x` (docs/mechanics.md (B10)) and its norm relative
    /// to `b_norm = ‖b‖₂` [1], the Newton acceptance measure.
    pub fn residual(&self, b: &[f64], b_norm: f64, x: &[f64], r: &mut [f64]) -> f64 {
        self.matvec(x, r);
        r.par_iter_mut().zip(b.par_iter()).for_each(|(ri, bi)| *ri = bi - *ri);
        cg::dot(r, r).sqrt() / b_norm
    }
}

enum LevelA<'a> {
    Fine(FineOp<'a>),
    Csr(&'a BlockCsr, &'a [u8]),
}

impl LevelA<'_> {
    fn n(&self) -> usize {
        match self {
            LevelA::Fine(f) => f.n(),
            LevelA::Csr(a, _) => a.n_rows(),
        }
    }
    fn fixed(&self) -> &[u8] {
        match self {
            LevelA::Fine(f) => f.fixed,
            LevelA::Csr(_, m) => m,
        }
    }
    fn matvec(&self, x: &[f64], y: &mut [f64]) {
        match self {
            LevelA::Fine(f) => f.matvec(x, y),
            LevelA::Csr(a, m) => a.matvec(m, x, y),
        }
    }
    fn diag(&self) -> Vec<B6> {
        match self {
            LevelA::Fine(f) => f.blocks.diag.clone(),
            LevelA::Csr(a, _) => (0..a.n_rows()).map(|i| a.row(i).find(|e| e.0 as usize == i).map(|e| *e.1).unwrap_or_else(B6::zeros)).collect(),
        }
    }
    /// `A·P` row by row (Gustavson: per-thread column markers; products summed in visit order, so
    /// the result is independent of the scheduling).
    fn times(&self, p: &BlockCsr) -> BlockCsr {
        let nc = p.n_cols;
        let rows: Vec<Vec<(u32, B6)>> = (0..self.n())
            .into_par_iter()
            .map_init(
                || vec![u32::MAX; nc],
                |marker, i| {
                    let mut acc: Vec<(u32, B6)> = Vec::new();
                    let mut visit = |k: u32, a: &B6| {
                        for (j, b) in p.row(k as usize) {
                            let m = &mut marker[j as usize];
                            if *m == u32::MAX {
                                *m = acc.len() as u32;
                                acc.push((j, a * b));
                            } else {
                                acc[*m as usize].1 += a * b;
                            }
                        }
                    };
                    match self {
                        LevelA::Fine(f) => f.for_row(i, &mut visit),
                        LevelA::Csr(a, _) => a.row(i).for_each(|(k, b)| visit(k, b)),
                    }
                    for e in &acc {
                        marker[e.0 as usize] = u32::MAX;
                    }
                    acc.sort_unstable_by_key(|e| e.0);
                    acc
                },
            )
            .collect();
        BlockCsr::from_rows(p.n_cols, rows)
    }
    /// Strong neighbours of every node (CSR), excluding fully fixed nodes.
    fn graph(&self, theta: f64) -> (Vec<u32>, Vec<u32>) {
        let n = self.n();
        let fixed = self.fixed();
        let fine = matches!(self, LevelA::Fine(_));
        let dnorm: Vec<f64> = self.diag().iter().map(|d| d.norm()).collect();
        let rows: Vec<Vec<u32>> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut v = Vec::new();
                if fixed[i] == 63 {
                    return v;
                }
                let mut visit = |j: u32, b: &B6| {
                    let ju = j as usize;
                    if ju != i && fixed[ju] != 63 && (fine || b.norm() >= theta * (dnorm[i] * dnorm[ju]).sqrt()) {
                        v.push(j);
                    }
                };
                match self {
                    LevelA::Fine(f) => f.for_row(i, &mut visit),
                    LevelA::Csr(a, _) => a.row(i).for_each(|(k, b)| visit(k, b)),
                }
                v.sort_unstable();
                v.dedup();
                v
            })
            .collect();
        let mut start = vec![0u32];
        let mut adj = Vec::new();
        for r in rows {
            adj.extend(r);
            start.push(adj.len() as u32);
        }
        (start, adj)
    }
}

/// Greedy SA aggregation (phases 1–3, node order) of the graph `(start, adj)`; `active[i]` false
/// for nodes left out. Returns the aggregate of every node (`u32::MAX`: none) and their number.
pub fn aggregate(start: &[u32], adj: &[u32], active: &[bool]) -> (Vec<u32>, usize) {
    let n = active.len();
    let nb = |i: usize| &adj[start[i] as usize..start[i + 1] as usize];
    let mut agg = vec![u32::MAX; n];
    let mut n_agg = 0u32;
    // phase 1: root + all neighbours, when none of them is taken
    for i in 0..n {
        if !active[i] || agg[i] != u32::MAX || nb(i).is_empty() {
            continue;
        }
        if nb(i).iter().all(|&j| agg[j as usize] == u32::MAX) {
            agg[i] = n_agg;
            for &j in nb(i) {
                agg[j as usize] = n_agg;
            }
            n_agg += 1;
        }
    }
    // phase 2: join the phase-1 aggregate with most connections (ties: lower index)
    let phase1 = agg.clone();
    for i in 0..n {
        if !active[i] || phase1[i] != u32::MAX {
            continue;
        }
        let mut best: Option<(usize, u32)> = None;
        let mut cands: Vec<u32> = nb(i).iter().map(|&j| phase1[j as usize]).filter(|&a| a != u32::MAX).collect();
        cands.sort_unstable();
        let mut k = 0;
        while k < cands.len() {
            let a = cands[k];
            let mut m = k;
            while m < cands.len() && cands[m] == a {
                m += 1;
            }
            if best.is_none_or(|(c, _)| m - k > c) {
                best = Some((m - k, a));
            }
            k = m;
        }
        if let Some((_, a)) = best {
            agg[i] = a;
        }
    }
    // phase 3: the rest with their free neighbours
    for i in 0..n {
        if !active[i] || agg[i] != u32::MAX {
            continue;
        }
        agg[i] = n_agg;
        for &j in nb(i) {
            if agg[j as usize] == u32::MAX {
                agg[j as usize] = n_agg;
            }
        }
        n_agg += 1;
    }
    (agg, n_agg as usize)
}

fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// `T(d)`: rigid mode `[t, w]` about a point → `[t', w]` about the point moved by `d·r̄`
/// (`t' = t + (w/r̄) × d·r̄ = t − skew(d)·w`), `d` already divided by r̄.
fn shift(d: &Vector3<f64>) -> B6 {
    let mut t = B6::identity();
    t.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(d)));
    t
}

/// Tentative prolongator of one level: per aggregate, the near-null-space blocks `bns[i]·T(x_i − c)`
/// of its nodes (rows of fixed DOF zero) orthonormalised. Returns P (one block per active node),
/// the coarse nodes' positions, near-null-space blocks and fixed masks.
fn tentative(agg: &[u32], n_agg: usize, pos: &[Vector3<f64>], bns: &[B6], fixed: &[u8], r_scale: f64) -> (BlockCsr, Vec<Vector3<f64>>, Vec<B6>, Vec<u8>) {
    let n = agg.len();
    let mut members: Vec<Vec<u32>> = vec![Vec::new(); n_agg];
    for i in 0..n {
        if agg[i] != u32::MAX {
            members[agg[i] as usize].push(i as u32);
        }
    }
    let per: Vec<(Vector3<f64>, Vec<B6>, B6, u8)> = members
        .par_iter()
        .map(|m| {
            let c = m.iter().map(|&i| pos[i as usize]).sum::<Vector3<f64>>() / m.len() as f64;
            // B rows, node by node
            let mut b: Vec<B6> = m
                .iter()
                .map(|&i| {
                    let mut blk = bns[i as usize] * shift(&((pos[i as usize] - c) / r_scale));
                    for k in 0..6 {
                        if fixed[i as usize] & (1 << k) != 0 {
                            blk.row_mut(k).fill(0.0);
                        }
                    }
                    blk
                })
                .collect();
            // modified Gram–Schmidt over the stacked columns, two passes
            let mut r = B6::zeros();
            let mut mask = 0u8;
            let col_dot = |b: &[B6], p: usize, q: usize| b.iter().map(|x| x.column(p).dot(&x.column(q))).sum::<f64>();
            for k in 0..6 {
                let n0 = col_dot(&b, k, k).sqrt();
                for _pass in 0..2 {
                    for j in 0..k {
                        if mask & (1 << j) != 0 {
                            continue;
                        }
                        let s = col_dot(&b, j, k);
                        r[(j, k)] += s;
                        for x in b.iter_mut() {
                            let cj = x.column(j).into_owned();
                            let mut ck = x.column_mut(k);
                            ck -= s * cj;
                        }
                    }
                }
                let nk = col_dot(&b, k, k).sqrt();
                if n0 > 0.0 && nk > 1e-6 * n0 {
                    r[(k, k)] = nk;
                    for x in b.iter_mut() {
                        let mut ck = x.column_mut(k);
                        ck /= nk;
                    }
                } else {
                    mask |= 1 << k;
                    r.row_mut(k).fill(0.0);
                    for x in b.iter_mut() {
                        x.column_mut(k).fill(0.0);
                    }
                }
            }
            (c, b, r, mask)
        })
        .collect();
    let mut rows: Vec<Vec<(u32, B6)>> = vec![Vec::new(); n];
    let (mut cpos, mut cbns, mut cfix) = (Vec::with_capacity(n_agg), Vec::with_capacity(n_agg), Vec::with_capacity(n_agg));
    for (a, (m, (c, b, r, mask))) in members.iter().zip(per).enumerate() {
        for (&i, blk) in m.iter().zip(b) {
            rows[i as usize].push((a as u32, blk));
        }
        cpos.push(c);
        cbns.push(r);
        cfix.push(mask);
    }
    (BlockCsr::from_rows(n_agg, rows), cpos, cbns, cfix)
}

/// λ_max of D⁻¹A by a power iteration with the generalised Rayleigh quotient `xᵀAx / xᵀDx`.
fn lambda_max(a: &LevelA, d: &[B6], jac: &BlockJacobi, iters: usize) -> f64 {
    let n = a.n();
    let fixed = a.fixed();
    let mut x: Vec<f64> = (0..6 * n)
        .map(|k| {
            // deterministic pseudo-random start, zero on fixed DOF
            let h = (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
            if fixed[k / 6] & (1 << (k % 6)) != 0 { 0.0 } else { 0.5 + (h as f64) / (1u64 << 53) as f64 }
        })
        .collect();
    let mut ax = vec![0.0; 6 * n];
    let mut dx = vec![0.0; 6 * n];
    let mut lam = 0.0;
    for _ in 0..iters {
        a.matvec(&x, &mut ax);
        dx.par_chunks_mut(6).zip(x.par_chunks(6)).zip(d.par_iter()).enumerate().for_each(|(i, ((o, xi), di))| {
            let v = di * Vector6::from_column_slice(xi);
            for k in 0..6 {
                o[k] = if fixed[i] & (1 << k) != 0 { 0.0 } else { v[k] };
            }
        });
        let xdx = cg::dot(&x, &dx);
        if xdx <= 0.0 {
            break;
        }
        lam = cg::dot(&x, &ax) / xdx;
        jac.apply(&ax, &mut x);
        let nx = cg::dot(&x, &x).sqrt();
        if !(nx > 0.0) {
            break;
        }
        x.par_iter_mut().for_each(|v| *v /= nx);
    }
    lam
}

struct Level {
    /// Operator of this level (None for the fine level: given at apply time).
    a: Option<BlockCsr>,
    fixed: Vec<u8>,
    jac: BlockJacobi,
    omega: f64,
    /// Prolongator to this level from the next coarser one, and its transpose.
    p: BlockCsr,
    pt: BlockCsr,
    /// Fixed masks of the next coarser level.
    cfixed: Vec<u8>,
}

struct Coarsest {
    fixed: Vec<u8>,
    eq: Vec<u32>,
    chol: BondCholesky,
    pattern: Vec<(u32, u32)>,
}

/// Setup report.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AmgInfo {
    /// Equations per level, fine first (free DOF) [1].
    pub equations: Vec<usize>,
    /// Block non-zeros of the coarse operators [1].
    pub coarse_blocks: Vec<usize>,
    /// Stored values of the coarsest factor [1].
    pub coarse_factor_nnz: usize,
    /// Wall time of the setup [s], of it: prolongators and Galerkin products, coarsest factorisation.
    pub setup_seconds: f64,
    pub galerkin_seconds: f64,
    pub coarse_factor_seconds: f64,
}

/// Aggregates per level, kept for the topology.
#[derive(Debug, Clone, Default)]
pub struct Aggregates {
    levels: Vec<(Vec<u32>, usize)>,
}

/// The hierarchy.
pub struct Amg {
    params: AmgParams,
    levels: Vec<Level>,
    coarsest: Coarsest,
    aggs: Aggregates,
    stale: bool,
    pub info: AmgInfo,
}

fn n_free(fixed: &[u8]) -> usize {
    fixed.iter().map(|m| 6 - m.count_ones() as usize).sum()
}

impl Amg {
    /// Builds the hierarchy for the fine operator `fine` at positions `pos` [m] with rotation scale
    /// `r_scale` [m]. `reuse`: aggregates (and the coarsest symbolic factorisation) of an earlier
    /// build of the same topology.
    pub fn build(fine: FineOp, pos: &[Vector3<f64>], r_scale: f64, params: AmgParams, reuse: Option<Amg>) -> Result<Amg, SolveError> {
        let t0 = Instant::now();
        let (old_aggs, mut old_coarse) = match reuse {
            Some(a) => (Some(a.aggs), Some(a.coarsest)),
            None => (None, None),
        };
        let mut aggs = Aggregates::default();
        let mut levels: Vec<Level> = Vec::new();
        let mut info = AmgInfo::default();
        let mut cur_a: Option<BlockCsr> = None;
        let mut cur_fixed: Vec<u8> = fine.fixed.to_vec();
        let mut cur_pos: Vec<Vector3<f64>> = pos.to_vec();
        let mut cur_bns: Vec<B6> = vec![B6::identity(); fine.n()];
        let mut lvl = 0;
        loop {
            let neq = n_free(&cur_fixed);
            info.equations.push(neq);
            let la = match &cur_a {
                None => LevelA::Fine(fine),
                Some(a) => LevelA::Csr(a, &cur_fixed),
            };
            // the fine level is always coarsened once (a direct solve is the Cholesky solver's job)
            let stop = (lvl > 0 && neq <= params.max_coarse) || lvl + 1 >= params.max_levels;
            // aggregates
            let (agg, n_agg) = if stop {
                (Vec::new(), 0)
            } else if let Some(a) = old_aggs.as_ref().and_then(|o| o.levels.get(lvl)) {
                a.clone()
            } else {
                let (start, adj) = la.graph(if lvl == 0 { 0.0 } else { params.strength * 0.5f64.powi(lvl as i32 - 1) });
                let active: Vec<bool> = cur_fixed.iter().map(|&m| m != 63).collect();
                aggregate(&start, &adj, &active)
            };
            if stop || 6 * n_agg >= neq * 9 / 10 || n_agg == 0 {
                // coarsest: direct solve
                let coarse_a = match cur_a {
                    Some(a) => a,
                    None => {
                        // fine level small enough: its own CSR
                        let rows: Vec<Vec<(u32, B6)>> = (0..fine.n())
                            .map(|i| {
                                let mut v = Vec::new();
                                fine.for_row(i, |j, b| v.push((j, *b)));
                                merge(v)
                            })
                            .collect();
                        BlockCsr::from_rows(fine.n(), rows)
                    }
                };
                let tf = Instant::now();
                let coarsest = Coarsest::new(&coarse_a, cur_fixed, old_coarse.take())?;
                info.coarse_factor_seconds = tf.elapsed().as_secs_f64();
                info.coarse_factor_nnz = coarsest.chol.nnz_l();
                aggs.levels.truncate(lvl);
                return Ok(Amg { params, levels, coarsest, aggs, stale: false, info: AmgInfo { setup_seconds: t0.elapsed().as_secs_f64(), ..info } });
            }
            aggs.levels.push((agg.clone(), n_agg));
            let tg = Instant::now();
            let d = la.diag();
            let jac = BlockJacobi::new(&d, &cur_fixed)?;
            let lam = lambda_max(&la, &d, &jac, 15).max(f64::MIN_POSITIVE);
            let (ptent, cpos, cbns, cfix) = tentative(&agg, n_agg, &cur_pos, &cur_bns, &cur_fixed, r_scale);
            let p = if params.smooth_p {
                let w = 4.0 / (3.0 * lam);
                let ap = la.times(&ptent);
                let rows: Vec<Vec<(u32, B6)>> = (0..la.n())
                    .into_par_iter()
                    .map(|i| {
                        let dinv = jac.inv(i);
                        let mut v: Vec<(u32, B6)> = ptent.row(i).map(|(c, b)| (c, *b)).collect();
                        v.extend(ap.row(i).map(|(c, b)| (c, -w * dinv * b)));
                        let mut v = merge(v);
                        for (_, b) in v.iter_mut() {
                            for k in 0..6 {
                                if cur_fixed[i] & (1 << k) != 0 {
                                    b.row_mut(k).fill(0.0);
                                }
                            }
                        }
                        v
                    })
                    .collect();
                BlockCsr::from_rows(n_agg, rows)
            } else {
                ptent
            };
            let ap = la.times(&p);
            let pt = p.transpose();
            let ac = LevelA::Csr(&pt, &[]).times(&ap);
            let ac = symmetrise(ac);
            info.coarse_blocks.push(ac.val.len());
            info.galerkin_seconds += tg.elapsed().as_secs_f64();
            levels.push(Level { a: cur_a.take(), fixed: cur_fixed, jac, omega: params.smoother_omega / lam, p, pt, cfixed: cfix.clone() });
            cur_a = Some(ac);
            cur_fixed = cfix;
            cur_pos = cpos;
            cur_bns = cbns;
            lvl += 1;
        }
    }

    /// Replaces the fine level's smoother by the block Jacobi of `diag` (stale hierarchy reuse).
    pub fn refresh_fine_smoother(&mut self, diag: &[B6]) -> Result<(), SolveError> {
        if let Some(l) = self.levels.first_mut() {
            l.jac = BlockJacobi::new(diag, &l.fixed)?;
        }
        Ok(())
    }

    /// The fixed-DOF masks of the fine level the hierarchy was built for.
    pub fn fine_fixed(&self) -> &[u8] {
        self.levels.first().map_or(&self.coarsest.fixed, |l| &l.fixed)
    }

    /// Marks the hierarchy for a rebuild (aggregates and symbolic factor kept).
    pub fn into_stale(mut self) -> Self {
        self.stale = true;
        self
    }

    /// Whether the hierarchy was marked for a rebuild.
    pub fn is_stale(&self) -> bool {
        self.stale
    }

    pub fn params(&self) -> &AmgParams {
        &self.params
    }

    /// Scratch vectors for [`Amg::apply`].
    pub fn work(&self) -> AmgWork {
        let mut v = Vec::new();
        for l in &self.levels {
            let n = 6 * l.jac.len();
            v.push([vec![0.0; n], vec![0.0; n], vec![0.0; n]]);
        }
        let nc = 6 * self.coarsest.fixed.len();
        v.push([vec![0.0; nc], vec![0.0; nc], vec![0.0; nc]]);
        AmgWork { v, red: vec![0.0; self.coarsest.chol_n()] }
    }

    /// `z = M⁻¹ r`: one V-cycle from zero.
    pub fn apply(&mut self, fine: FineOp, r: &[f64], z: &mut [f64], w: &mut AmgWork) -> Result<(), SolveError> {
        w.v[0][0].copy_from_slice(r);
        self.cycle(0, fine, w)?;
        z.copy_from_slice(&w.v[0][1]);
        Ok(())
    }

    /// V-cycle on level `l`: right-hand side `w.v[l][0]`, result in `w.v[l][1]`.
    fn cycle(&mut self, l: usize, fine: FineOp, w: &mut AmgWork) -> Result<(), SolveError> {
        if l == self.levels.len() {
            let (b, x) = {
                let s = &mut w.v[l];
                let (b, rest) = s.split_at_mut(1);
                (&b[0], &mut rest[0])
            };
            return self.coarsest.solve(b, x, &mut w.red);
        }
        let lev = &self.levels[l];
        let a = match &lev.a {
            None => LevelA::Fine(fine),
            Some(a) => LevelA::Csr(a, &lev.fixed),
        };
        let sweeps = self.params.sweeps;
        let omega = lev.omega;
        {
            let [b, x, t] = &mut w.v[l];
            // pre-smoothing from x = 0
            lev.jac.apply(b, x);
            x.par_iter_mut().for_each(|v| *v *= omega);
            for _ in 1..sweeps {
                smooth(&a, &lev.jac, omega, b, x, t);
            }
            // residual, restriction
            a.matvec(x, t);
            t.par_iter_mut().zip(b.par_iter()).for_each(|(ti, bi)| *ti = bi - *ti);
        }
        {
            let (lo, hi) = w.v.split_at_mut(l + 1);
            let t = &lo[l][2];
            let bc = &mut hi[0][0];
            lev.pt.matvec(&lev.cfixed, t, bc);
        }
        self.cycle(l + 1, fine, w)?;
        let lev = &self.levels[l];
        let a = match &lev.a {
            None => LevelA::Fine(fine),
            Some(a) => LevelA::Csr(a, &lev.fixed),
        };
        {
            let (lo, hi) = w.v.split_at_mut(l + 1);
            let xc = &hi[0][1];
            let [b, x, t] = &mut lo[l];
            lev.p.matvec(&lev.fixed, xc, t);
            x.par_iter_mut().zip(t.par_iter()).for_each(|(xi, ti)| *xi += ti);
            for _ in 0..sweeps {
                smooth(&a, &lev.jac, omega, b, x, t);
            }
        }
        Ok(())
    }
}

/// One damped block-Jacobi sweep `x += ω D⁻¹ (b − A x)`, `t` scratch.
fn smooth(a: &LevelA, jac: &BlockJacobi, omega: f64, b: &[f64], x: &mut [f64], t: &mut [f64]) {
    a.matvec(x, t);
    t.par_iter_mut().zip(b.par_iter()).for_each(|(ti, bi)| *ti = bi - *ti);
    jac.apply_add(t, x, omega);
}

fn symmetrise(a: BlockCsr) -> BlockCsr {
    let at = a.transpose();
    debug_assert_eq!(at.col, a.col);
    let val = a.val.par_iter().zip(at.val.par_iter()).map(|(x, y)| 0.5 * (x + y)).collect();
    BlockCsr { val, ..a }
}

impl Coarsest {
    fn new(a: &BlockCsr, fixed: Vec<u8>, old: Option<Coarsest>) -> Result<Coarsest, SolveError> {
        let n = a.n_rows();
        let mut eq = vec![u32::MAX; 6 * n];
        let mut m = 0u32;
        for i in 0..n {
            for k in 0..6 {
                if fixed[i] & (1 << k) == 0 {
                    eq[6 * i + k] = m;
                    m += 1;
                }
            }
        }
        let mut pattern = Vec::new();
        let mut values = Vec::new();
        for i in 0..n {
            for (j, b) in a.row(i) {
                let j = j as usize;
                if j > i {
                    continue;
                }
                for p in 0..6 {
                    let rp = eq[6 * i + p];
                    if rp == u32::MAX {
                        continue;
                    }
                    for q in 0..6 {
                        let rq = eq[6 * j + q];
                        if rq == u32::MAX || (j == i && q > p) {
                            continue;
                        }
                        pattern.push((rp, rq));
                        values.push(b[(p, q)]);
                    }
                }
            }
        }
        crate::linsolve::set_parallelism_for(m as usize);
        let mut chol = match old {
            Some(o) if o.pattern == pattern && o.eq == eq => o.chol,
            _ => BondCholesky::new(m as usize, &pattern, None)?,
        };
        chol.factorize(&values).map_err(|e| SolveError::new("AMG coarse Cholesky", e.message))?;
        Ok(Coarsest { fixed, eq, chol, pattern })
    }

    fn chol_n(&self) -> usize {
        self.eq.iter().filter(|&&e| e != u32::MAX).count()
    }

    fn solve(&mut self, b: &[f64], x: &mut [f64], red: &mut [f64]) -> Result<(), SolveError> {
        for (d, &e) in self.eq.iter().enumerate() {
            if e != u32::MAX {
                red[e as usize] = b[d];
            }
        }
        crate::linsolve::set_parallelism_for(red.len());
        self.chol.solve_in_place(red)?;
        for (d, &e) in self.eq.iter().enumerate() {
            x[d] = if e != u32::MAX { red[e as usize] } else { 0.0 };
        }
        Ok(())
    }
}

/// Scratch of [`Amg::apply`]: per level `[b, x, t]`, and the reduced coarsest vector.
pub struct AmgWork {
    v: Vec<[Vec<f64>; 3]>,
    red: Vec<f64>,
}

/// The six rigid-body modes (scaled unknowns) about `c` of the particles at `pos`, rows of `fixed`
/// DOF zero, as 6 full vectors (tests).
pub fn rigid_modes(pos: &[Vector3<f64>], fixed: &[u8], c: &Vector3<f64>, r_scale: f64) -> Vec<Vec<f64>> {
    let mut out = vec![vec![0.0; 6 * pos.len()]; 6];
    for (i, x) in pos.iter().enumerate() {
        let b = shift(&((x - c) / r_scale));
        for k in 0..6 {
            for p in 0..6 {
                if fixed[i] & (1 << p) == 0 {
                    out[k][6 * i + p] = b[(p, k)];
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mechanics::fixtures::fcc_packing;
    use crate::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, StepInput};

    struct Case {
        pos: Vec<Vector3<f64>>,
        rad: Vec<f64>,
        pairs: Vec<[u32; 2]>,
        y: Vec<[f64; 2]>,
        load: Vec<f64>,
        cons: Constraints,
    }

    fn case(n: usize, seed: u64) -> Case {
        let (pos, rad, pairs, y) = fcc_packing(n, seed);
        let mut s = seed | 1;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let load = pairs.iter().map(|_| 1e-3 * (0.5 + rnd())).collect();
        let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
        Case { pos, rad, pairs, y, load, cons }
    }

    fn params(solver: LinearSolver, amg: AmgParams) -> MechParams {
        MechParams { young_modulus: 110e9, poisson_ratio: 0.34, solver, amg, ..Default::default() }
    }

    /// Small coarse limit so that even small packings get several levels.
    fn multilevel() -> AmgParams {
        AmgParams { max_coarse: 600, ..Default::default() }
    }

    fn solve(c: &Case, p: MechParams) -> crate::mechanics::MechStep {
        let mut sys = BondedSystem::new(c.pos.len(), p, c.cons.clone()).unwrap();
        sys.set_topology(&c.pairs).unwrap();
        sys.step(&StepInput { positions: &c.pos, radii: &c.rad, y4_y7: &c.y, load: &c.load, external: None }).unwrap()
    }

    #[test]
    fn rigid_modes_are_in_the_kernel_of_the_unconstrained_stiffness() {
        let c = case(300, 3);
        let mut sys = BondedSystem::new(c.pos.len(), params(LinearSolver::Cholesky, AmgParams::default()), Constraints::none(c.pos.len())).unwrap();
        sys.set_topology(&c.pairs).unwrap();
        let inp = StepInput { positions: &c.pos, radii: &c.rad, y4_y7: &c.y, load: &c.load, external: None };
        let (blocks, _, r_scale, _, inc) = sys.assembled(&inp).unwrap();
        let free = vec![0u8; c.pos.len()];
        let centre = c.pos.iter().sum::<Vector3<f64>>() / c.pos.len() as f64;
        let kmax = blocks.diag.iter().map(|d| d.amax()).fold(0.0, f64::max);
        for (k, m) in rigid_modes(&c.pos, &free, &centre, r_scale).iter().enumerate() {
            let mut y = vec![0.0; m.len()];
            blocks.matvec(&c.pairs, &inc, &free, m, &mut y);
            let rel = y.iter().fold(0.0f64, |a, v| a.max(v.abs())) / (kmax * m.iter().fold(0.0f64, |a, v| a.max(v.abs())));
            assert!(rel < 1e-10, "mode {k}: ‖K·b‖∞ / (‖K‖‖b‖) = {rel:.2e}");
        }
    }

    #[test]
    fn amg_pcg_equals_cholesky_and_is_cheaper_than_block_jacobi() {
        let c = case(2000, 11);
        let chol = solve(&c, params(LinearSolver::Cholesky, AmgParams::default()));
        for amg in [multilevel(), AmgParams { smooth_p: true, ..multilevel() }] {
            let a = solve(&c, params(LinearSolver::Amg, amg));
            assert_eq!(a.info.solver, crate::mechanics::SolverUsed::Amg);
            assert!(a.info.amg_levels.len() >= 3, "levels {:?}", a.info.amg_levels);
            let res = *a.info.residuals.last().unwrap();
            assert!(res <= 1e-10, "AMG residual {res:.2e}");
            let scale = chol.du.iter().map(|v| v.norm()).fold(0.0, f64::max);
            let diff = chol.du.iter().zip(&a.du).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
            // the residual tolerance 1e-10 bounds the error by cond(K)·1e-10; measured ≈ 1e-10 relative
            assert!(diff <= 1e-8 * scale, "max |Δu| difference {diff:.2e} of {scale:.2e}");
            let xi = chol.xi.iter().zip(&a.xi).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
            assert!(xi <= 1e-8 * scale, "ξ difference {xi:.2e}");
            // block-Jacobi needs ≈ 330 iterations here, AMG ≈ 20–40
            assert!(a.info.pcg_iterations <= 60, "AMG-PCG iterations {}", a.info.pcg_iterations);
        }
        let bj = solve(&c, params(LinearSolver::Pcg, AmgParams::default()));
        assert!(bj.info.pcg_iterations > 200, "block-Jacobi iterations {}", bj.info.pcg_iterations);
    }

    #[test]
    fn iterations_stay_bounded_as_the_packing_grows() {
        // default parameters (two levels up to ≈ 2.5·10⁵ equations, three at 10⁵ particles);
        // measured 2026-11-26: 864 particles → 34 iterations, 19 652 → 30 (bench at 97 556: 42,
        // three levels); block-Jacobi: 314 → ≈ 700 → 1036. The three-level variant (coarse
        // limit 600) grows more, 41 → 62: plain aggregation loses with every level.
        let mut its = Vec::new();
        for n in [1000usize, 20_000] {
            let c = case(n, 5);
            let a = solve(&c, params(LinearSolver::Amg, AmgParams::default()));
            assert!(*a.info.residuals.last().unwrap() <= 1e-10);
            its.push((c.pos.len(), a.info.pcg_iterations, a.info.amg_levels.len()));
        }
        eprintln!("AMG iterations (particles, iterations, levels): {its:?}");
        let growth = its[1].1 as f64 / its[0].1 as f64;
        assert!(its[1].0 > 15 * its[0].0, "{its:?}");
        assert!(growth < 1.25, "iterations {its:?}: growth {growth:.2} for 18× the particles");
        assert!(its[1].1 <= 45, "{its:?}");
    }

    /// Symmetry and positivity of the V-cycle as an operator, with planes, rattlers, extra fixed
    /// DOF (coarse modes removed) and a pinned floating cluster.
    #[test]
    fn preconditioner_is_symmetric_positive_definite_with_constraints() {
        let mut c = case(1500, 21);
        // a floating cluster: a pair far away (pinned), particles partly fixed inside
        let n0 = c.pos.len();
        c.pos.push(Vector3::new(1.0, 1.0, 1.0));
        c.pos.push(Vector3::new(1.0 + 1e-4, 1.0, 1.0));
        c.rad.push(50e-6);
        c.rad.push(50e-6);
        c.pairs.push([n0 as u32, n0 as u32 + 1]);
        c.y.push([50e-6, 50e-6]);
        c.load.push(1e-3);
        let mut cons = Constraints::principal_planes(&c.pos, &c.rad, 0.01).unwrap();
        for i in (0..n0).step_by(37) {
            cons.fix(i, if i % 2 == 0 { crate::mechanics::dof::ALL } else { crate::mechanics::dof::U | crate::mechanics::dof::RX }).unwrap();
        }
        c.cons = cons;
        let mut sys = BondedSystem::new(c.pos.len(), params(LinearSolver::Amg, multilevel()), c.cons.clone()).unwrap();
        sys.set_topology(&c.pairs).unwrap();
        let inp = StepInput { positions: &c.pos, radii: &c.rad, y4_y7: &c.y, load: &c.load, external: None };
        let (blocks, rhs, r_scale, rep, inc) = sys.assembled(&inp).unwrap();
        assert!(!rep.rattlers.is_empty() && !rep.pinned.is_empty(), "rattlers {} pinned {}", rep.rattlers.len(), rep.pinned.len());
        let fine = FineOp { blocks: &blocks, pairs: &c.pairs, inc: &inc, fixed: &rep.fixed };
        let mut amg = Amg::build(fine, &c.pos, r_scale, multilevel(), None).unwrap();
        assert!(amg.info.equations.len() >= 3, "{:?}", amg.info);
        let mut w = amg.work();
        let mut s = 77u64;
        let mut vecs = Vec::new();
        for _ in 0..4 {
            let v: Vec<f64> = (0..rhs.len())
                .map(|k| {
                    s ^= s << 13;
                    s ^= s >> 7;
                    s ^= s << 17;
                    if rep.fixed[k / 6] & (1 << (k % 6)) != 0 { 0.0 } else { (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5 }
                })
                .collect();
            let mut z = vec![0.0; v.len()];
            amg.apply(fine, &v, &mut z, &mut w).unwrap();
            // positive: vᵀ M⁻¹ v > 0, fixed DOF untouched
            let vz = cg::dot(&v, &z);
            assert!(vz > 0.0, "vᵀM⁻¹v = {vz}");
            assert!(z.iter().enumerate().all(|(k, &x)| rep.fixed[k / 6] & (1 << (k % 6)) == 0 || x == 0.0));
            vecs.push((v, z));
        }
        for i in 0..vecs.len() {
            for j in 0..i {
                let a = cg::dot(&vecs[i].0, &vecs[j].1);
                let b = cg::dot(&vecs[j].0, &vecs[i].1);
                let scale = (cg::dot(&vecs[i].0, &vecs[i].1) * cg::dot(&vecs[j].0, &vecs[j].1)).sqrt();
                assert!((a - b).abs() <= 1e-10 * scale, "asymmetry {:.2e} of {scale:.2e}", (a - b).abs());
            }
        }
        // and CG converges with it (no breakdown) to the tolerance of (B10), agreeing with Cholesky
        let a = solve(&c, params(LinearSolver::Amg, multilevel()));
        assert!(*a.info.residuals.last().unwrap() <= 1e-10);
        let ch = solve(&c, params(LinearSolver::Cholesky, AmgParams::default()));
        let scale = ch.du.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let diff = ch.du.iter().zip(&a.du).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(diff <= 1e-8 * scale, "{diff:.2e} of {scale:.2e}");
    }

    #[test]
    fn bit_identical_on_one_and_two_threads() {
        let c = case(3000, 9);
        let run = |threads: usize, amg: AmgParams| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| solve(&c, params(LinearSolver::Amg, amg)))
        };
        for amg in [multilevel(), AmgParams { smooth_p: true, ..multilevel() }] {
            let (a, b) = (run(1, amg), run(2, amg));
            assert!(a.info.pcg_iterations > 0);
            assert_eq!(a.info.pcg_iterations, b.info.pcg_iterations);
            assert!(a.du == b.du && a.dtheta == b.dtheta && a.xi == b.xi, "1 vs 2 threads differ");
        }
    }

    #[test]
    fn stale_hierarchy_still_converges() {
        let c = case(2000, 13);
        let p = params(LinearSolver::Amg, multilevel());
        let mut sys = BondedSystem::new(c.pos.len(), p, c.cons.clone()).unwrap();
        sys.set_topology(&c.pairs).unwrap();
        let inp = StepInput { positions: &c.pos, radii: &c.rad, y4_y7: &c.y, load: &c.load, external: None };
        let first = sys.step(&inp).unwrap();
        assert_eq!(first.info.amg_builds, 1);
        // move the particles (1 % of the radius): same topology, stale hierarchy
        let pos2: Vec<Vector3<f64>> = c.pos.iter().enumerate().map(|(i, x)| x + Vector3::new(1.0, -0.5, 0.3) * 5e-7 * ((i % 7) as f64 - 3.0)).collect();
        let second = sys.step(&StepInput { positions: &pos2, ..inp }).unwrap();
        assert_eq!(second.info.amg_builds, 0);
        assert!(*second.info.residuals.last().unwrap() <= 1e-10);
        let ch = solve(&Case { pos: pos2.clone(), ..case(2000, 13) }, params(LinearSolver::Cholesky, AmgParams::default()));
        let scale = ch.du.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let diff = ch.du.iter().zip(&second.du).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(diff <= 1e-8 * scale, "{diff:.2e} of {scale:.2e}");
        assert!(second.info.pcg_iterations <= first.info.pcg_iterations * 3 / 2 + 5, "{} vs {}", second.info.pcg_iterations, first.info.pcg_iterations);
    }
}

#[cfg(test)]
mod stale_factor_tests {
    use crate::mechanics::fixtures::fcc_packing;
    use crate::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, StepInput};
    use nalgebra::Vector3;

    /// The stale Cholesky factor as CG preconditioner (`stale_factor_cg`) meets the tolerance
    /// without a factorisation and agrees with modified Newton on the same stale factor.
    #[test]
    fn stale_factor_as_cg_preconditioner() {
        let (pos, rad, pairs, y) = fcc_packing(1500, 3);
        let load: Vec<f64> = (0..pairs.len()).map(|c| 1e-3 * (1.0 + (c % 5) as f64 * 0.1)).collect();
        let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
        let inp = StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None };
        let pos2: Vec<Vector3<f64>> = pos.iter().enumerate().map(|(i, x)| x + Vector3::new(0.3, -0.2, 0.5) * 2e-7 * ((i % 5) as f64 - 2.0)).collect();
        let mut out = Vec::new();
        for cg in [false, true] {
            let p = MechParams { solver: LinearSolver::Cholesky, reuse_factor: true, stale_factor_cg: cg, ..Default::default() };
            let mut sys = BondedSystem::new(pos.len(), p, cons.clone()).unwrap();
            sys.set_topology(&pairs).unwrap();
            sys.step(&inp).unwrap();
            let s = sys.step(&StepInput { positions: &pos2, ..inp }).unwrap();
            assert_eq!(s.info.factorizations, 0);
            assert!(*s.info.residuals.last().unwrap() <= 1e-10);
            if cg {
                assert!(s.info.pcg_iterations >= 1 && s.info.pcg_iterations <= 10, "{}", s.info.pcg_iterations);
            }
            out.push(s);
        }
        let scale = out[0].du.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let diff = out[0].du.iter().zip(&out[1].du).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(diff <= 1e-8 * scale, "{diff:.2e} of {scale:.2e}");
    }
}

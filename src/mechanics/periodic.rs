//! The bonded system on a periodic cell (docs/mechanics.md "Periodic cell", (B13)–(B20)).
//!
//! The cell is the matrix `L` whose columns are the cell vectors [m]. A particle's displacement
//! increment is a periodic fluctuation plus the homogeneous strain of the cell (B13),
//! `Δx_i = Δu_i + ΔE·x_i`, with `ΔE = Σ_k Δe_k G_k` symmetric over the three normal components
//! (`xx, yy, zz`) or all six (`… yz, xz, xy`, engineering shears γ). A bond's branch vector is
//! the minimum image of `x_B − x_A` in the current cell (B14), and its element sees node B
//! displaced by `ΔE·l` beyond B's fluctuation (B15). The cell strain is solved beside the
//! particle DOF by static condensation (B17)–(B18) with the solvers of the walled system: the
//! fluctuation stiffness `K_uu` is solved for the load and for one coupling column per
//! component, the ≤ 6×6 Schur complement for the stress-controlled components, the
//! strain-controlled ones being given. `K_uu` of a network that wraps the cell in three
//! independent directions has exactly the three uniform translations as null modes: they are
//! fixed by a gauge (one particle's translation held, then the mean fluctuation of the
//! component removed, (B19)), which carries no reaction because every load is self-equilibrated.

use super::bond::{BondGeometry, element_blocks};
use super::constraints::{TopologyReport, dof};
use super::{BondedSystem, MechInfo, MechStep, StepInput};
use crate::error::{ConfigError, Error, ModelError, SolveError};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Vector3};
use rayon::prelude::*;
use std::time::Instant;

/// The component names in the order of the cell unknowns: the normal strains, then the shears.
pub const COMPONENTS: [&str; 6] = ["xx", "yy", "zz", "yz", "xz", "xy"];

/// The basis matrix `G_k` of component `k` (B13): `e_a e_aᵀ` for a normal component,
/// `(e_a e_bᵀ + e_b e_aᵀ)/2` for a shear, so that `Δe_k` is the engineering shear γ and its work
/// conjugate is the shear stress Σ_ab.
pub fn basis(k: usize) -> Matrix3<f64> {
    let mut g = Matrix3::zeros();
    match k {
        0..=2 => g[(k, k)] = 1.0,
        _ => {
            let (a, b) = [(1, 2), (0, 2), (0, 1)][k - 3];
            g[(a, b)] = 0.5;
            g[(b, a)] = 0.5;
        }
    }
    g
}

/// The strain increment tensor `ΔE = Σ_k Δe_k G_k` of the components `e` [1].
pub fn strain_tensor(e: &[f64]) -> Matrix3<f64> {
    e.iter().enumerate().fold(Matrix3::zeros(), |m, (k, &v)| m + basis(k) * v)
}

/// What is prescribed for one cell component over a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CellControl {
    /// The increment of the mean stress ΔΣ_k [Pa] (tension positive); the strain is solved for.
    Stress(f64),
    /// The strain increment Δe_k [1] (engineering shear for a shear); the stress is the reaction.
    Strain(f64),
}

/// The cell of one periodic step.
#[derive(Debug, Clone, Copy)]
pub struct CellInput<'a> {
    /// The cell vectors as columns [m], at the start of the step.
    pub cell: &'a Matrix3<f64>,
    /// One control per solved component: 3 (normal) or 6 (all), in the order of [`COMPONENTS`].
    pub controls: &'a [CellControl],
}

/// The cell's part of the result of a periodic step.
#[derive(Debug, Clone, Default)]
pub struct CellStep {
    /// Strain increment per component [1] (unsolved components 0).
    pub strain: [f64; 6],
    /// Increment of the mean (virial) stress (B20) `[xx, yy, zz, yz, xz, xy]` [Pa], tension
    /// positive: the stress-controlled components equal their control to solver tolerance.
    pub stress: [f64; 6],
    /// Axial force increment of each link, `k_ax·ξ` [N], compression positive (as `F3` of
    /// [`super::bond::link_forces`]).
    pub axial_force: Vec<f64>,
    /// Largest force on a gauge particle's held translation [N] (zero to solver tolerance).
    pub gauge_reaction: f64,
    /// Largest load increment |ΔF| of a bond [N] (the scale of `gauge_reaction`).
    pub load_scale: f64,
}

/// The minimum image of the difference `d` [m] in the cell `l` (columns) with inverse `inv`
/// (B14): `d − L·round(L⁻¹d)`. Exact for an orthorhombic cell whose lengths exceed twice the
/// largest reach; a sheared cell keeps it while the shear stays small.
pub fn minimum_image(d: &Vector3<f64>, l: &Matrix3<f64>, inv: &Matrix3<f64>) -> Vector3<f64> {
    let s = inv * d;
    d - l * s.map(|v| v.round())
}

/// The branch vector `x_B − x_A` (minimum image, (B14)) of every pair [m].
pub fn branch_vectors(positions: &[Vector3<f64>], pairs: &[[u32; 2]], cell: &Matrix3<f64>) -> Result<Vec<Vector3<f64>>, ModelError> {
    let inv = cell_inverse(cell)?;
    Ok(pairs.iter().map(|&[a, b]| minimum_image(&(positions[b as usize] - positions[a as usize]), cell, &inv)).collect())
}

/// `L⁻¹` of a cell with a positive finite volume.
pub fn cell_inverse(cell: &Matrix3<f64>) -> Result<Matrix3<f64>, ModelError> {
    let det = cell.determinant();
    if !(det.is_finite() && det > 0.0) {
        return Err(ModelError::new(format!("periodic cell: volume det(L) = {det} m³ is not positive and finite (cell vectors {:?} m)", cell.as_slice())));
    }
    cell.try_inverse().ok_or_else(|| ModelError::new("periodic cell: the cell matrix is singular"))
}

/// Members of each bonded component (particles with bonds, in particle order; rattlers left out).
fn components(n: usize, pairs: &[[u32; 2]]) -> Vec<Vec<u32>> {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut i: u32) -> u32 {
        while p[i as usize] != i {
            p[i as usize] = p[p[i as usize] as usize];
            i = p[i as usize];
        }
        i
    }
    let mut bonded = vec![false; n];
    for &[a, b] in pairs {
        bonded[a as usize] = true;
        bonded[b as usize] = true;
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    let mut index = vec![u32::MAX; n];
    let mut out: Vec<Vec<u32>> = Vec::new();
    for i in 0..n {
        if !bonded[i] {
            continue;
        }
        let r = find(&mut parent, i as u32) as usize;
        if index[r] == u32::MAX {
            index[r] = out.len() as u32;
            out.push(Vec::new());
        }
        out[index[r] as usize].push(i as u32);
    }
    out
}

/// The lattice vectors (in cell units) by which the component `members` wraps the cell: the
/// closure defects of its cycles, walked along a spanning tree with the branch vectors.
/// Returns the rank of their span (0 a floating cluster, 3 a network spanning the cell in all
/// directions) and, for rank 1, the wrap axis [m].
fn wrap_rank(
    members: &[u32],
    pairs: &[[u32; 2]],
    branch: &[Vector3<f64>],
    inc: &super::Incidence,
    cell: &Matrix3<f64>,
    inv: &Matrix3<f64>,
) -> (usize, Vector3<f64>) {
    let mut unwrapped: std::collections::HashMap<u32, Vector3<f64>> = std::collections::HashMap::with_capacity(members.len());
    let mut basis: Vec<Vector3<f64>> = Vec::new();
    let mut first_axis = Vector3::zeros();
    let root = members[0];
    unwrapped.insert(root, Vector3::zeros());
    let mut queue = std::collections::VecDeque::from([root]);
    while let Some(i) = queue.pop_front() {
        let pi = unwrapped[&i];
        for &(c, side) in inc.of(i as usize) {
            let [a, b] = pairs[c as usize];
            let (j, step) = if side == 0 { (b, branch[c as usize]) } else { (a, -branch[c as usize]) };
            match unwrapped.get(&j) {
                None => {
                    unwrapped.insert(j, pi + step);
                    queue.push_back(j);
                }
                Some(&pj) => {
                    let n = (inv * (pi + step - pj)).map(|v| v.round());
                    if n.norm() == 0.0 || basis.len() == 3 {
                        continue;
                    }
                    // Gram–Schmidt against the lattice vectors found so far
                    let mut v = n;
                    for q in &basis {
                        v -= q * q.dot(&v);
                    }
                    if v.norm() > 1e-9 * n.norm() {
                        if basis.is_empty() {
                            first_axis = cell * n;
                        }
                        basis.push(v.normalize());
                    }
                }
            }
        }
    }
    (basis.len(), first_axis)
}

/// The topology analysis of a periodic cell (B19): rattlers left out; per bonded component a
/// gauge on its lowest-numbered particle holding exactly its zero-energy modes: a component
/// that wraps the cell in three (or two) independent directions has only the three uniform
/// translations (gauge: the particle's translation); one that wraps in one direction also the
/// rotation about that axis (the rotation about the axis is held when it is a coordinate axis,
/// all three otherwise); a floating cluster all six (a pin, as in the walled system).
pub fn analyse(n: usize, pairs: &[[u32; 2]], branch: &[Vector3<f64>], cell: &Matrix3<f64>) -> Result<TopologyReport, Error> {
    let inv = cell_inverse(cell)?;
    let inc = super::Incidence::new(n, pairs);
    let comps = components(n, pairs);
    let mut fixed = vec![0u8; n];
    let mut bonded = vec![false; n];
    let mut gauges = Vec::with_capacity(comps.len());
    for m in &comps {
        m.iter().for_each(|&i| bonded[i as usize] = true);
        let (rank, axis) = wrap_rank(m, pairs, branch, &inc, cell, &inv);
        let mask = match rank {
            2 | 3 => dof::U,
            1 => {
                let a = axis.abs();
                let k = a.imax();
                if a[k] > 0.0 && (a.sum() - a[k]) <= 1e-12 * a[k] { dof::U | (dof::RX << k) } else { dof::ALL }
            }
            _ => dof::ALL,
        };
        fixed[m[0] as usize] = mask;
        gauges.push(m[0]);
    }
    let rattlers: Vec<u32> = (0..n as u32).filter(|&i| !bonded[i as usize]).collect();
    for &i in &rattlers {
        fixed[i as usize] = dof::ALL;
    }
    let mut eq = vec![u32::MAX; 6 * n];
    let mut n_eq = 0usize;
    for i in 0..n {
        for k in 0..6 {
            if fixed[i] & (1 << k) == 0 {
                eq[6 * i + k] = n_eq as u32;
                n_eq += 1;
            }
        }
    }
    Ok(TopologyReport { components: comps.len(), rattlers, pinned: gauges, fixed, eq, n_eq })
}

/// What the condensation (B16)–(B18) needs per bond beside the assembled fluctuation stiffness.
struct Coupling {
    /// `K_AB` and `K_BB` of each element (scaled unknowns).
    ends: Vec<(Matrix6<f64>, Matrix6<f64>)>,
    /// Axial link stiffness `E·A/L_b` of each bond [N/m].
    k_axial: Vec<f64>,
    /// `K_ue`: one column per component, 6n entries, fixed DOF zero [N].
    columns: Vec<Vec<f64>>,
    /// `K_ee` [N·m].
    k_ee: DMatrix<f64>,
    /// Generalised cell force of the sintering loads, `−Σ ΔF e3·G_k l` [N·m].
    f_sinter: DVector<f64>,
}

impl BondedSystem {
    /// One quasi-static step of the bonded packing on the periodic cell `cell` (B13)–(B20):
    /// solves the fluctuations and the cell strain increment under the sintering loads and the
    /// cell controls. The returned `du` is the whole displacement increment `Δu_i + ΔE·x_i`
    /// (rattlers move with the cell), so [`MechStep::apply`] moves the particles; the cell
    /// becomes `(I + ΔE)·L` (the caller updates it). `external` loads are not accepted (the
    /// cell stress is the periodic cell's load).
    pub fn step_periodic(&mut self, inp: &StepInput, cell: &CellInput) -> Result<(MechStep, CellStep), Error> {
        let t_start = Instant::now();
        self.check_input(inp)?;
        let nc = cell.controls.len();
        if nc != 3 && nc != 6 {
            return Err(ConfigError::invalid(format!("periodic mechanics: {nc} cell controls given, 3 (normal components) or 6 (all) expected")).into());
        }
        if inp.external.is_some() {
            return Err(ConfigError::invalid(
                "periodic mechanics: nodal external loads are not taken on a periodic cell; load the cell by its stress controls",
            )
            .into());
        }
        if let Some(k) = cell.controls.iter().position(|c| !matches!(c, CellControl::Stress(v) | CellControl::Strain(v) if v.is_finite())) {
            return Err(ModelError::new(format!("periodic mechanics: the control of component {} is not finite", COMPONENTS[k])).into());
        }
        let branch = branch_vectors(inp.positions, &self.pairs, cell.cell)?;
        let mut info = MechInfo { bonds: self.pairs.len(), ..Default::default() };
        let rep = match self.report.take() {
            Some(r) if self.periodic_report => r,
            _ => {
                let t0 = Instant::now();
                let r = analyse(self.n, &self.pairs, &branch, cell.cell)?;
                info.topology_rebuilt = true;
                info.analysis_seconds = t0.elapsed().as_secs_f64();
                r
            }
        };
        self.periodic_report = true;
        let out = self.periodic_with(&rep, inp, cell, &branch, info, t_start);
        self.report = Some(rep);
        out
    }

    /// The coupling blocks of (B16): element ends, coupling columns, `K_ee` and the cell force of
    /// the sintering loads, for `nc` components.
    #[allow(clippy::too_many_arguments)]
    fn coupling(
        &self,
        rep: &TopologyReport,
        inp: &StepInput,
        geom: &[BondGeometry],
        branch: &[Vector3<f64>],
        r_scale: f64,
        nc: usize,
        release: Option<&[(Vector3<f64>, Vector3<f64>)]>,
    ) -> Coupling {
        let k = self.link_stiffnesses(inp.radii);
        let ends: Vec<(Matrix6<f64>, Matrix6<f64>)> = geom
            .par_iter()
            .zip(k.par_iter())
            .map(|(g, kk)| {
                let (_, ab, bb) = element_blocks(g, kk, r_scale);
                (ab, bb)
            })
            .collect();
        let g: Vec<Matrix3<f64>> = (0..nc).map(basis).collect();
        // (B16): the force on the fluctuation DOF of a unit strain of component m, per particle
        // from its bonds in bond order (deterministic for any thread count)
        let columns: Vec<Vec<f64>> = (0..nc)
            .map(|m| {
                let mut col = vec![0.0; 6 * self.n];
                col.par_chunks_mut(6).enumerate().for_each(|(i, f)| {
                    let mut acc = nalgebra::Vector6::zeros();
                    for &(c, side) in self.inc.of(i) {
                        let (ab, bb) = &ends[c as usize];
                        let cm = g[m] * branch[c as usize];
                        let blk = if side == 0 { ab } else { bb };
                        acc += blk.fixed_view::<6, 3>(0, 0) * cm;
                    }
                    let mask = rep.fixed[i];
                    for d in 0..6 {
                        f[d] = if mask & (1 << d) != 0 { 0.0 } else { acc[d] };
                    }
                });
                col
            })
            .collect();
        let mut k_ee = DMatrix::zeros(nc, nc);
        let mut f_sinter = DVector::zeros(nc);
        for (c, (l, (_, bb))) in branch.iter().zip(&ends).enumerate() {
            let kbb = bb.fixed_view::<3, 3>(0, 0);
            let cs: Vec<Vector3<f64>> = g.iter().map(|gm| gm * l).collect();
            for a in 0..nc {
                f_sinter[a] -= inp.load[c] * geom[c].e3.dot(&cs[a]);
                if let Some(q) = release {
                    // (B26): the release load on B, −q, works on ΔE·l like the sintering load
                    f_sinter[a] -= q[c].0.dot(&cs[a]);
                }
                for b in 0..nc {
                    k_ee[(a, b)] += cs[a].dot(&(kbb * cs[b]));
                }
            }
        }
        Coupling { ends, k_axial: k.iter().map(|kk| kk[2]).collect(), columns, k_ee, f_sinter }
    }

    /// [`Self::step_periodic`] with the analysis `rep` and the branch vectors.
    fn periodic_with(
        &mut self,
        rep: &TopologyReport,
        inp: &StepInput,
        cell: &CellInput,
        branch: &[Vector3<f64>],
        mut info: MechInfo,
        t_start: Instant,
    ) -> Result<(MechStep, CellStep), Error> {
        let n = self.n;
        let nc = cell.controls.len();
        let volume = cell.cell.determinant();
        let (geom, blocks, rhs, r_scale, k) = self.prepare(rep, inp, Some(branch), &mut info)?;
        let links = super::Links { geom: &geom, k: &k, r_scale };
        let release = self.release_loads(&geom, inp.radii);
        let cp = self.coupling(rep, inp, &geom, branch, r_scale, nc, release.as_deref());
        // (B17): K_uu X0 = f_u and K_uu Y_m = K_ue[:, m]
        // each right-hand side is its own solve with its own counters (the stale-hierarchy and
        // Newton limits are per solve) and its own warm-start history (B12)
        let mut sub = MechInfo::default();
        let x0 = self.solve_rhs(rep, inp.positions, links, &blocks, &rhs, Some(0), &mut sub);
        info.absorb(sub);
        let x0 = x0?;
        let mut y = Vec::with_capacity(nc);
        for (m, col) in cp.columns.iter().enumerate() {
            let mut sub = MechInfo::default();
            let ym = self.solve_rhs(rep, inp.positions, links, &blocks, col, Some(1 + m), &mut sub);
            info.absorb(sub);
            y.push(ym?);
        }
        // (B18): the Schur complement S = K_ee − K_eu Y, right side g = f_e − K_eu X0
        let mut s = cp.k_ee.clone();
        let mut g = cp.f_sinter.clone();
        for a in 0..nc {
            g[a] -= super::cg::dot(&cp.columns[a], &x0);
            for b in 0..nc {
                s[(a, b)] -= super::cg::dot(&cp.columns[a], &y[b]);
            }
        }
        let s = (&s + s.transpose()) * 0.5;
        let e = solve_cell(&s, &g, cell.controls, volume)?;
        // the fluctuation u = X0 − Σ Y_m e_m
        let mut x = x0;
        for (ym, &em) in y.iter().zip(e.iter()) {
            x.par_iter_mut().zip(ym.par_iter()).for_each(|(xi, yi)| *xi -= yi * em);
        }
        // (B19): the mean translation of each wrapping component's fluctuation removed (a null
        // mode: nothing else changes)
        for m in components(n, &self.pairs) {
            if rep.fixed[m[0] as usize] & dof::ALL != dof::U {
                continue;
            }
            let mean = m.iter().fold(Vector3::zeros(), |acc, &i| acc + Vector3::from_column_slice(&x[6 * i as usize..6 * i as usize + 3])) / m.len() as f64;
            for &i in &m {
                for d in 0..3 {
                    x[6 * i as usize + d] -= mean[d];
                }
            }
        }
        let de = strain_tensor(e.as_slice());
        let mut cs = CellStep { axial_force: Vec::with_capacity(self.pairs.len()), ..Default::default() };
        cs.strain[..nc].copy_from_slice(e.as_slice());
        let (xi, net) = self.periodic_forces(&cp, &geom, branch, &x, &de, inp.load, release.as_deref(), volume, &mut cs);
        for &gp in &rep.pinned {
            if rep.fixed[gp as usize] == dof::U {
                cs.gauge_reaction = cs.gauge_reaction.max(net[gp as usize].norm());
            }
        }
        cs.load_scale = inp.load.iter().fold(0.0, |a, f| a.max(f.abs()));
        if let Some(c) = xi.iter().position(|v| !v.is_finite()) {
            return Err(SolveError::new("periodic mechanics", format!("non-finite approach at contact {c}")).into());
        }
        let du: Vec<Vector3<f64>> = (0..n).map(|i| Vector3::new(x[6 * i], x[6 * i + 1], x[6 * i + 2]) + de * inp.positions[i]).collect();
        let dtheta: Vec<Vector3<f64>> = x.chunks(6).map(|c| Vector3::new(c[3], c[4], c[5]) / r_scale).collect();
        let (tangential, moment) = if self.relaxation.is_some() {
            let k = self.link_stiffnesses(inp.radii);
            self.relaxed_state(&geom, &k, release.as_deref(), r_scale, |c| {
                let [a, b] = self.pairs[c];
                let v = |i: u32, o: usize| Vector3::from_column_slice(&x[6 * i as usize + o..6 * i as usize + o + 3]);
                // (B15): node B carries the cell's ΔE·l
                [v(a, 0), v(a, 3), v(b, 0) + de * branch[c], v(b, 3)]
            })
        } else {
            (Vec::new(), Vec::new())
        };
        info.total_seconds = t_start.elapsed().as_secs_f64();
        Ok((MechStep { du, dtheta, xi, e3: geom.iter().map(|g| g.e3).collect(), tangential, moment, info }, cs))
    }

    /// Per bond: ξ = (Δu_A − Δu_B − ΔE·l)·e3 (B15), the axial force `k_ax·ξ`, and the virial
    /// increment (B20) of the bond's total force (elastic plus sintering load) into `cs`; returns
    /// ξ and the net force on every particle [N] (the gauge reactions at the gauges).
    #[allow(clippy::too_many_arguments)]
    fn periodic_forces(
        &self,
        cp: &Coupling,
        geom: &[BondGeometry],
        branch: &[Vector3<f64>],
        x: &[f64],
        de: &Matrix3<f64>,
        load: &[f64],
        release: Option<&[(Vector3<f64>, Vector3<f64>)]>,
        volume: f64,
        cs: &mut CellStep,
    ) -> (Vec<f64>, Vec<Vector3<f64>>) {
        let mut xi = Vec::with_capacity(self.pairs.len());
        let mut net = vec![Vector3::zeros(); self.n];
        let mut virial = Matrix3::zeros();
        for (c, &[a, b]) in self.pairs.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            let ya = nalgebra::Vector6::from_column_slice(&x[6 * a..6 * a + 6]);
            let mut yb = nalgebra::Vector6::from_column_slice(&x[6 * b..6 * b + 6]);
            let shift = de * branch[c];
            for d in 0..3 {
                yb[d] += shift[d];
            }
            let (ab, bb) = &cp.ends[c];
            let el = -(ab.tr_mul(&ya) + bb * yb);
            // the bond's total force on B: elastic restoring force and the sintering pair load
            let mut f_b = Vector3::new(el[0], el[1], el[2]) - geom[c].e3 * load[c];
            if let Some(q) = release {
                // (B26): the release of the stored tangential force is part of the bond's force
                f_b -= q[c].0;
            }
            net[b] += f_b;
            net[a] -= f_b;
            virial -= f_b * branch[c].transpose();
            let x_c = (Vector3::new(ya[0] - yb[0], ya[1] - yb[1], ya[2] - yb[2])).dot(&geom[c].e3);
            xi.push(x_c);
            cs.axial_force.push(cp.k_axial[c] * x_c);
        }
        let v = (virial + virial.transpose()) * (0.5 / volume);
        cs.stress = [v[(0, 0)], v[(1, 1)], v[(2, 2)], v[(1, 2)], v[(0, 2)], v[(0, 1)]];
        (xi, net)
    }
}

/// (B18): the cell strain increments from the Schur complement `s`, the right side `g` [N·m]
/// and the controls: strain-controlled components given, the stress-controlled ones solved from
/// `S_ss e_s = g_s + V·ΔΣ_s − S_sc e_c`.
fn solve_cell(s: &DMatrix<f64>, g: &DVector<f64>, controls: &[CellControl], volume: f64) -> Result<DVector<f64>, Error> {
    let nc = controls.len();
    let mut e = DVector::zeros(nc);
    let free: Vec<usize> = (0..nc).filter(|&k| matches!(controls[k], CellControl::Stress(_))).collect();
    for (k, c) in controls.iter().enumerate() {
        if let CellControl::Strain(v) = c {
            e[k] = *v;
        }
    }
    if free.is_empty() {
        return Ok(e);
    }
    let m = free.len();
    let mut sss = DMatrix::zeros(m, m);
    let mut rhs = DVector::zeros(m);
    for (p, &a) in free.iter().enumerate() {
        let CellControl::Stress(ds) = controls[a] else { continue };
        rhs[p] = g[a] + volume * ds;
        for k in 0..nc {
            if matches!(controls[k], CellControl::Strain(_)) {
                rhs[p] -= s[(a, k)] * e[k];
            }
        }
        for (q, &b) in free.iter().enumerate() {
            sss[(p, q)] = s[(a, b)];
        }
    }
    let scale = (0..m).map(|p| sss[(p, p)].abs()).fold(0.0, f64::max);
    let chol = nalgebra::Cholesky::new(sss.clone());
    let small = (0..m).map(|p| sss[(p, p)]).fold(f64::INFINITY, f64::min);
    let Some(chol) = chol.filter(|_| small > 1e-12 * scale && scale.is_finite() && scale > 0.0) else {
        let names: Vec<&str> = free.iter().map(|&k| COMPONENTS[k]).collect();
        // the diagonal as numbers, not the matrix's debug dump (issue 38)
        let diag: Vec<String> = (0..m).map(|p| format!("{:.3e}", sss[(p, p)])).collect();
        return Err(SolveError::new(
            "periodic mechanics",
            format!(
                "the cell has no stiffness against the stress-controlled components {} (Schur complement diagonal [{}] N·m): the bonded network does not span the cell in those directions",
                names.join(", "),
                diag.join(", ")
            ),
        )
        .into());
    };
    let es = chol.solve(&rhs);
    for (p, &a) in free.iter().enumerate() {
        e[a] = es[p];
    }
    Ok(e)
}

#[cfg(test)]
mod tests;

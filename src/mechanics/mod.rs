//! Bonded quasi-static mechanics (docs/mechanics.md; Ivannikov et al. 2022 §2.3–2.4, §3.3).
//!
//! Every particle is a node with 6 DOF (displacement, small rotation); every contact a bonded link
//! ([`bond`]). Each step solves the **increment** `K·Δy = ΔF` caused by the step's sintering-load
//! increments `ΔF = (π/2)·E·R_m·(Δy4 + Δy7)` (F5) along the contacts' e3, with rotations scaled by
//! the mean radius, rattlers left out and rigid modes held by plane constraints or pins
//! ([`constraints`]), by Newton iteration on a sparse Cholesky or block-Jacobi PCG ([`solve`],
//! [`cg`]). It returns the displacement and rotation increments and, per contact, the axial
//! approach `ξ = (Δu_A − Δu_B)·e3` (C1) for the y4/y7 correction of docs/diffusion7.md §6.
//!
//! ```text
//! let mut sys = BondedSystem::new(n, MechParams { young_modulus, poisson_ratio, ..Default::default() },
//!                                 Constraints::principal_planes(&pos, &r0, 0.01)?)?;
//! sys.set_topology(&pairs)?;                    // whenever contacts appear
//! let out = sys.step(&StepInput { positions: &pos, radii: &r0, y4_y7: &y, load: &df, external: None })?;
//! // out.du, out.dtheta per particle; out.xi per contact → correct_y4_y7(.., out.xi[c], ..)
//! ```
//!
//! Modules: [`bond`] element, [`assembly`] block assembly, [`constraints`] rattlers/planes/pins,
//! [`solve`] parameters, Newton report, solver choice, [`cg`] PCG, `newton` the Newton drivers and
//! the warm start, [`periodic`] the periodic cell (cell strain by static condensation, gauge,
//! virial stress; docs/mechanics.md (B13)–(B22)).

pub mod amg;
pub mod assembly;
pub mod bond;
pub mod cg;
pub mod cholesky;
pub mod constraints;
pub mod fixtures;
pub mod hypre;
pub mod lowrank;
mod newton;
pub mod periodic;
pub mod sliding;
pub mod solve;

pub use bond::{BondGeometry, element_matrix, frame, h_matrix, kinematics, link_stiffness, skew};
pub use constraints::{Constraints, TopologyReport, dof};
pub use solve::{AMG_ABOVE_EQUATIONS, AMG_ABOVE_EQUATIONS_FRESH, LinearSolver, MechInfo, MechParams, SolverUsed, WARM_START_DEPTH};

use crate::error::{ConfigError, Error, ModelError, SolveError};
pub use assembly::{BlockMatrix, Incidence};
use cholesky::BondCholesky;
use nalgebra::Vector3;
use newton::{STALE_CG_REFRESH, initial_residual, newton_on_factor, not_finite, stale_factor_cg, warm_start};
use rayon::prelude::*;
use solve::Kept;
use std::time::Instant;

/// An external force [N] and moment [N·m] on a particle (tests, gravity, a press; the sintering
/// loads come per contact through [`StepInput::load`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NodalLoad {
    pub force: Vector3<f64>,
    pub moment: Vector3<f64>,
}

/// The data of one mechanical step.
#[derive(Debug, Clone, Copy)]
pub struct StepInput<'a> {
    /// Current centre positions at the start of the step [m] (one per particle).
    pub positions: &'a [Vector3<f64>],
    /// Initial radii [m] (R_m of (F3) per contact, and the rotation scale r̄ = their mean).
    pub radii: &'a [f64],
    /// Current corrected `[y4, y7]` per contact, in the order of [`BondedSystem::set_topology`] [m].
    pub y4_y7: &'a [[f64; 2]],
    /// Load increment ΔF (F5) per contact [N], > 0 pulls the centres together.
    pub load: &'a [f64],
    /// Optional external load increments per particle.
    pub external: Option<&'a [NodalLoad]>,
}

/// The result of one step.
#[derive(Debug, Clone, Default)]
pub struct MechStep {
    /// Displacement increment per particle [m] (zero for rattlers and fixed DOF).
    pub du: Vec<Vector3<f64>>,
    /// Rotation increment (small-rotation vector) per particle [rad].
    pub dtheta: Vec<Vector3<f64>>,
    /// Axial approach `ξ = (Δu_A − Δu_B)·e3` per contact (C1) [m], > 0: closer. Equal to the
    /// axial component of the relative displacement of the two bond points (the rotation terms of
    /// ε are normal to e3).
    pub xi: Vec<f64>,
    /// The step's frame axis e3 per contact (unit, A → B).
    pub e3: Vec<Vector3<f64>>,
    /// With sliding ([`BondedSystem::set_relaxation`]): the stored tangential link force per
    /// contact at the step's end, global axes [N] ((B27)); empty otherwise.
    pub tangential: Vec<Vector3<f64>>,
    /// With rolling viscosities (B30): the stored link moment per contact at the step's end,
    /// global axes [N·m]; empty otherwise.
    pub moment: Vec<Vector3<f64>>,
    /// Solver report.
    pub info: MechInfo,
}

impl MechStep {
    /// Adds the increments to positions [m] and accumulated rotations [rad].
    pub fn apply(&self, positions: &mut [Vector3<f64>], rotations: &mut [Vector3<f64>]) {
        for (x, d) in positions.iter_mut().zip(&self.du) {
            *x += d;
        }
        for (t, d) in rotations.iter_mut().zip(&self.dtheta) {
            *t += d;
        }
    }
}

/// Per bond, what the low-rank update of a new bond needs: its geometry, its links and r̄ [m].
#[derive(Clone, Copy)]
struct Links<'a> {
    geom: &'a [BondGeometry],
    k: &'a [[f64; 6]],
    r_scale: f64,
}

/// The bonded packing: topology, constraints, reusable pattern and factor.
pub struct BondedSystem {
    n: usize,
    params: MechParams,
    constraints: Constraints,
    pairs: Vec<[u32; 2]>,
    inc: Incidence,
    /// The topology analysis of the current bonds (None: made at the next step).
    report: Option<TopologyReport>,
    /// The factor or hierarchy of the solver in use, kept between steps.
    kept: Kept,
    /// The last stale-factor CG was slow: factorise afresh at the next step.
    refresh: bool,
    /// CG iterations of the first solve after the last AMG build (the stale-reuse yardstick).
    amg_fresh_iterations: usize,
    /// Per-particle (E [Pa], ν [1]) when particles differ in material; None: `params` for all.
    elastic: Option<Vec<[f64; 2]>>,
    /// The last solutions (newest last) of each right-hand-side slot for the warm start (B12):
    /// slot 0 the load, slots 1… a periodic cell's strain columns (B17); emptied by
    /// [`Self::drop_factor`].
    history: Vec<Vec<Vec<f64>>>,
    /// `report` is a periodic cell's analysis ([`periodic::analyse`]), not the constraints'.
    periodic_report: bool,
    /// Viscous sliding of the next steps (docs/mechanics.md (B24)–(B30)); None: elastic links.
    relaxation: Option<sliding::Relaxation>,
}

impl BondedSystem {
    /// A system of `n_particles` without bonds.
    pub fn new(n_particles: usize, params: MechParams, constraints: Constraints) -> Result<Self, Error> {
        params.validate()?;
        if constraints.fixed.len() != n_particles {
            return Err(ConfigError::invalid(format!("mechanics: constraints for {} particles, system has {n_particles}", constraints.fixed.len())).into());
        }
        Ok(BondedSystem {
            n: n_particles,
            params,
            constraints,
            pairs: Vec::new(),
            inc: Incidence::new(n_particles, &[]),
            report: None,
            kept: Kept::Nothing,
            refresh: false,
            amg_fresh_iterations: 0,
            elastic: None,
            history: Vec::new(),
            periodic_report: false,
            relaxation: None,
        })
    }

    /// Viscous sliding (docs/mechanics.md (B24)–(B30)) for the following steps: each link's two
    /// shear springs become Maxwell elements with the viscosities and step of `relaxation`, and a
    /// step returns the new stored tangential forces in [`MechStep::tangential`]. None: the elastic
    /// link (bit for bit the system without this call). Checked against the bonds at each step.
    pub fn set_relaxation(&mut self, relaxation: Option<sliding::Relaxation>) {
        self.relaxation = relaxation;
    }

    /// The elastic link stiffnesses (B5) of bond `c` between `a` and `b` for the radii `radii` [m].
    fn elastic_link(&self, a: u32, b: u32, radii: &[f64]) -> [f64; 6] {
        let [e, nu] = self.link_elastic(a, b);
        link_stiffness(e, nu, 0.5 * (radii[a as usize] + radii[b as usize]))
    }

    /// The link stiffnesses of every bond as the next step assembles them, for the radii `radii`
    /// [m]: the elastic links (B5), with sliding multiplied by the Maxwell factors (B25), (B30), or
    /// a load distribution's viscous network (B29).
    pub fn link_stiffnesses(&self, radii: &[f64]) -> Vec<[f64; 6]> {
        if let Some(r) = self.relaxation.as_ref().filter(|r| !r.network.is_empty()) {
            return r.network.clone();
        }
        self.pairs
            .iter()
            .enumerate()
            .map(|(c, &[a, b])| {
                let mut k = self.elastic_link(a, b, radii);
                if let Some(r) = &self.relaxation {
                    let f = r.link_factors(c, &k);
                    k.iter_mut().zip(f).for_each(|(k, f)| *k *= f);
                }
                k
            })
            .collect()
    }

    /// The release loads (B26) of the stored link forces, per bond: `q = (1 − φ)·P_t` (global
    /// axes, ⟂ e3) [N], the force on A (−q on B) with the moments `l × q` at the bond point, and
    /// the release moment (B30) `m = (1 − φ_b)·M_⟂ + (1 − φ_tw)·M_∥` [N·m] on A (−m on B); None
    /// without sliding or with nothing stored.
    fn release_loads(&self, geom: &[BondGeometry], radii: &[f64]) -> Option<Vec<(Vector3<f64>, Vector3<f64>)>> {
        let r = self.relaxation.as_ref().filter(|r| !(r.stored.is_empty() && r.stored_moment.is_empty()))?;
        Some(
            self.pairs
                .iter()
                .enumerate()
                .map(|(c, &[a, b])| {
                    let [phi, _, _, pb, _, pt] = r.link_factors(c, &self.elastic_link(a, b, radii));
                    let q = r.stored_tangential(c, &geom[c].e3) * (1.0 - phi);
                    let (m, e3) = (r.stored_moment(c), geom[c].e3);
                    let m_axial = e3 * m.dot(&e3);
                    (q, (m - m_axial) * (1.0 - pb) + m_axial * (1.0 - pt))
                })
                .collect(),
        )
    }

    /// The stored tangential force of every bond after the step (B27), `P_t − q + φk_t·Δε_t`
    /// [N], and the stored moment (B30), `M − m + φ_b k_b Δθ_⟂ + φ_tw k_tw Δθ_∥` [N·m] with the
    /// relative rotation Δθ = Δθ_A − Δθ_B, from the scaled element vectors `y_e(c)` =
    /// `[Δu_A, r̄θ_A, Δu_B(+ΔE·l), r̄θ_B]` and the step's links `k` (Maxwell factors applied);
    /// empty without sliding (the moments also without rolling viscosities).
    fn relaxed_state(
        &self,
        geom: &[BondGeometry],
        k: &[[f64; 6]],
        release: Option<&[(Vector3<f64>, Vector3<f64>)]>,
        r_scale: f64,
        y_e: impl Fn(usize) -> [Vector3<f64>; 4],
    ) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
        let Some(r) = &self.relaxation else { return (Vec::new(), Vec::new()) };
        let rolling = !r.rolling.is_empty();
        let (force, mut moment): (Vec<_>, Vec<_>) = (0..self.pairs.len())
            .map(|c| {
                let g = &geom[c];
                let [ua, ta, ub, tb] = y_e(c);
                // (B3): ε = u_A − u_B − l_A0 × θ_A + l_B0 × θ_B, its part ⟂ e3
                let eps = ua - ub - g.l_a.cross(&(ta / r_scale)) + g.l_b.cross(&(tb / r_scale));
                let eps_t = eps - g.e3 * eps.dot(&g.e3);
                let (q, m) = release.map_or((Vector3::zeros(), Vector3::zeros()), |q| q[c]);
                let force = r.stored_tangential(c, &g.e3) - q + eps_t * k[c][0];
                let moment = if rolling {
                    let dth = (ta - tb) / r_scale;
                    let dth_axial = g.e3 * dth.dot(&g.e3);
                    r.stored_moment(c) - m + (dth - dth_axial) * k[c][3] + dth_axial * k[c][5]
                } else {
                    Vector3::zeros()
                };
                (force, moment)
            })
            .unzip();
        if !rolling {
            moment.clear();
        }
        (force, moment)
    }

    /// Gives each particle its own elastic constants `[E, ν]` ([Pa], [1]); a link takes
    /// [`bond::series_elastic`] of its two particles'. `None` restores the common `params`.
    pub fn set_particle_elastic(&mut self, elastic: Option<Vec<[f64; 2]>>) -> Result<(), Error> {
        if let Some(el) = &elastic {
            if el.len() != self.n {
                return Err(ConfigError::invalid(format!("mechanics: elastic constants for {} particles, system has {}", el.len(), self.n)).into());
            }
            if let Some((i, m)) = el.iter().enumerate().find(|(_, m)| !(m[0].is_finite() && m[0] > 0.0 && m[1] > -1.0 && m[1] <= 0.5)) {
                return Err(ConfigError::invalid(format!("mechanics: particle {i} has E = {} Pa, ν = {} (need E > 0, −1 < ν ≤ 0.5)", m[0], m[1])).into());
            }
        }
        self.elastic = elastic;
        self.kept = Kept::Nothing;
        Ok(())
    }

    /// Elastic constants `[E, ν]` of the link between particles `a` and `b`.
    pub fn link_elastic(&self, a: u32, b: u32) -> [f64; 2] {
        match &self.elastic {
            Some(el) => bond::series_elastic(el[a as usize], el[b as usize]),
            None => [self.params.young_modulus, self.params.poisson_ratio],
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The solver parameters.
    pub fn params(&self) -> &MechParams {
        &self.params
    }

    /// Replaces the solver parameters; the topology analysis, pattern and factor are kept.
    pub fn set_params(&mut self, params: MechParams) -> Result<(), Error> {
        params.validate()?;
        self.params = params;
        Ok(())
    }

    /// The bonds, in contact order.
    pub fn pairs(&self) -> &[[u32; 2]] {
        &self.pairs
    }

    /// Replaces the bond list (`[A, B]` per contact, A ≠ B, no pair twice). The next step redoes the
    /// topology analysis, the sparsity pattern and the symbolic factorisation.
    pub fn set_topology(&mut self, pairs: &[[u32; 2]]) -> Result<(), Error> {
        let mut seen: Vec<(u32, u32)> = Vec::with_capacity(pairs.len());
        for (c, &[a, b]) in pairs.iter().enumerate() {
            if a as usize >= self.n || b as usize >= self.n {
                return Err(ConfigError::invalid(format!("mechanics: contact {c} joins particles ({a}, {b}), but there are {} particles", self.n)).into());
            }
            if a == b {
                return Err(ConfigError::invalid(format!("mechanics: contact {c} joins particle {a} to itself")).into());
            }
            seen.push((a.min(b), a.max(b)));
        }
        seen.sort_unstable();
        if let Some(w) = seen.windows(2).find(|w| w[0] == w[1]) {
            return Err(ConfigError::invalid(format!("mechanics: particles ({}, {}) are bonded twice", w[0].0, w[0].1)).into());
        }
        // with `update_rank`, a factor of bonds that the new list extends survives with a low-rank
        // update of the added bonds (made at the next step, when their geometry is known)
        let old_bonds = self.pairs.len();
        let extends = pairs.len() >= old_bonds && pairs[..old_bonds] == self.pairs[..];
        let update = self.params.reuse_factor && self.params.update_rank > 0 && extends;
        self.pairs = pairs.to_vec();
        self.inc = Incidence::new(self.n, pairs);
        self.report = None;
        // with `stale_factor_cg`, the last factor survives as the preconditioner of CG on the new
        // stiffness (a few new bonds are a low-rank change); otherwise it is dropped
        let keep = self.params.reuse_factor && self.params.stale_factor_cg;
        self.kept = match std::mem::replace(&mut self.kept, Kept::Nothing) {
            Kept::Cholesky { chol, eq, current: true } if update && chol.is_factored() => {
                let n_eq = eq.iter().filter(|&&e| e != u32::MAX).count();
                Kept::Updated { chol, eq, update: Box::new(lowrank::LowRank::new(old_bonds, n_eq)) }
            }
            Kept::Updated { chol, eq, update: u } if update => Kept::Updated { chol, eq, update: u },
            Kept::Cholesky { chol, eq, .. } if keep && chol.is_factored() => Kept::Cholesky { chol, eq, current: false },
            // the hierarchy serves the new stiffness while the free DOF stay the same (checked at the solve)
            Kept::Amg(h) if self.params.amg_keep_on_new_bonds => Kept::Amg(h),
            _ => Kept::Nothing,
        };
        Ok(())
    }

    /// Forgets the topology analysis, the factor and the AMG hierarchy: the next step analyses and
    /// factorises afresh, as a system built anew with these bonds would (checkpoints rely on it).
    pub fn drop_factor(&mut self) {
        self.report = None;
        self.kept = Kept::Nothing;
        self.refresh = false;
        self.history.clear();
    }

    /// Replaces the constraints (same length); the next step redoes the topology analysis.
    pub fn set_constraints(&mut self, constraints: Constraints) -> Result<(), Error> {
        if constraints.fixed.len() != self.n {
            return Err(ConfigError::invalid(format!("mechanics: constraints for {} particles, system has {}", constraints.fixed.len(), self.n)).into());
        }
        self.constraints = constraints;
        self.report = None;
        self.kept = Kept::Nothing;
        Ok(())
    }

    /// Stored values of the current Cholesky factor (None before the first Cholesky step of a topology).
    pub fn factor_nnz(&self) -> Option<usize> {
        match &self.kept {
            Kept::Cholesky { chol, .. } | Kept::Updated { chol, .. } => Some(chol.nnz_l()),
            _ => None,
        }
    }

    /// The topology analysis of the last step (rattlers, pins, equations), if any.
    pub fn report(&self) -> Option<&TopologyReport> {
        self.report.as_ref()
    }

    fn check_input(&self, inp: &StepInput) -> Result<(), Error> {
        let (n, m) = (self.n, self.pairs.len());
        let lens = [("positions", inp.positions.len(), n), ("radii", inp.radii.len(), n), ("y4_y7", inp.y4_y7.len(), m), ("load", inp.load.len(), m)];
        for (what, got, want) in lens {
            if got != want {
                return Err(ConfigError::invalid(format!("mechanics step: {got} {what} given, {want} expected")).into());
            }
        }
        if let Some(e) = inp.external {
            if e.len() != n {
                return Err(ConfigError::invalid(format!("mechanics step: {} external loads given, {n} expected", e.len())).into());
            }
            if let Some(i) = e.iter().position(|l| !(l.force.iter().chain(l.moment.iter()).all(|v| v.is_finite()))) {
                return Err(ModelError::new(format!("mechanics step: external load on particle {i} is not finite")).into());
            }
        }
        if let Some(i) = inp.positions.iter().position(|x| !x.iter().all(|v| v.is_finite())) {
            return Err(ModelError::new(format!("mechanics step: position of particle {i} is not finite")).into());
        }
        if let Some(i) = inp.radii.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(ModelError::new(format!("mechanics step: radius of particle {i} = {} m is not positive and finite", inp.radii[i])).into());
        }
        if let Some(c) = inp.load.iter().position(|f| !f.is_finite()) {
            return Err(ModelError::new(format!("mechanics step: load increment of contact {c} is {}", inp.load[c])).into());
        }
        if let Some(r) = &self.relaxation {
            r.validate(m)?;
        }
        Ok(())
    }

    /// One quasi-static step: assembles the links at the current geometry, applies the load
    /// increments, solves for the increments by Newton with the scaled residual check and returns
    /// them with ξ per contact. Positions are not changed (see [`MechStep::apply`]).
    pub fn step(&mut self, inp: &StepInput) -> Result<MechStep, Error> {
        let t_start = Instant::now();
        self.check_input(inp)?;
        let mut info = MechInfo { bonds: self.pairs.len(), ..Default::default() };
        let rep = self.analysis(inp.positions, &mut info)?;
        let out = self.step_with(&rep, inp, info, t_start);
        self.report = Some(rep);
        out
    }

    /// The topology analysis of the current bonds, taken out of the system (the caller puts it
    /// back): the kept one, or made now (once per topology).
    fn analysis(&mut self, positions: &[Vector3<f64>], info: &mut MechInfo) -> Result<TopologyReport, Error> {
        if let Some(rep) = self.report.take()
            && !self.periodic_report
        {
            return Ok(rep);
        }
        self.periodic_report = false;
        let t0 = Instant::now();
        let rep = constraints::analyse(self.n, &self.pairs, positions, &self.constraints)?;
        info.topology_rebuilt = true;
        info.analysis_seconds = t0.elapsed().as_secs_f64();
        Ok(rep)
    }

    /// [`Self::step`] with the topology analysis `rep`.
    fn step_with(&mut self, rep: &TopologyReport, inp: &StepInput, mut info: MechInfo, t_start: Instant) -> Result<MechStep, Error> {
        let (geom, blocks, rhs, r_scale, k) = self.prepare(rep, inp, None, &mut info)?;
        let links = Links { geom: &geom, k: &k, r_scale };
        let x = self.solve_rhs(rep, inp.positions, links, &blocks, &rhs, Some(0), &mut info)?;
        let du: Vec<Vector3<f64>> = x.chunks(6).map(|c| Vector3::new(c[0], c[1], c[2])).collect();
        let dtheta: Vec<Vector3<f64>> = x.chunks(6).map(|c| Vector3::new(c[3], c[4], c[5]) / r_scale).collect();
        let xi: Vec<f64> = self.pairs.iter().zip(&geom).map(|(&[a, b], g)| (du[a as usize] - du[b as usize]).dot(&g.e3)).collect();
        if let Some(c) = xi.iter().position(|v| !v.is_finite()) {
            return Err(SolveError::new("mechanics", format!("non-finite approach at contact {c}")).into());
        }
        let (tangential, moment) = if self.relaxation.is_some() {
            let k = self.link_stiffnesses(inp.radii);
            let release = self.release_loads(&geom, inp.radii);
            self.relaxed_state(&geom, &k, release.as_deref(), r_scale, |c| {
                let [a, b] = self.pairs[c];
                let v = |i: u32, o: usize| Vector3::from_column_slice(&x[6 * i as usize + o..6 * i as usize + o + 3]);
                [v(a, 0), v(a, 3), v(b, 0), v(b, 3)]
            })
        } else {
            (Vec::new(), Vec::new())
        };
        info.total_seconds = t_start.elapsed().as_secs_f64();
        Ok(MechStep { du, dtheta, xi, e3: geom.iter().map(|g| g.e3).collect(), tangential, moment, info })
    }

    /// Solves the assembled system `blocks` (topology `rep`) for the scaled right-hand side `rhs`
    /// with the solver of the parameters (B10); `slot`: the warm-start history (B12) this
    /// right-hand side uses and joins (0: the load; 1…: a periodic cell's strain columns, which
    /// change little from step to step); None: neither. Returns the scaled solution on all 6n DOF.
    #[allow(clippy::too_many_arguments)]
    fn solve_rhs(
        &mut self,
        rep: &TopologyReport,
        positions: &[Vector3<f64>],
        links: Links,
        blocks: &BlockMatrix,
        rhs: &[f64],
        slot: Option<usize>,
        info: &mut MechInfo,
    ) -> Result<Vec<f64>, Error> {
        let r_scale = links.r_scale;
        let b_norm = cg::dot(rhs, rhs).sqrt();
        let mut x = vec![0.0; 6 * self.n];
        let above = match (self.params.reuse_factor, self.params.warm_start) {
            (true, true) => solve::AMG_ABOVE_EQUATIONS_WARM,
            (true, false) => AMG_ABOVE_EQUATIONS,
            (false, _) => AMG_ABOVE_EQUATIONS_FRESH,
        };
        let solver = match self.params.solver {
            LinearSolver::Auto if rep.n_eq > above => LinearSolver::Amg,
            LinearSolver::Auto => LinearSolver::Cholesky,
            s => s,
        };
        // the warm start (B12) serves the CG-based solvers; a Cholesky step is a direct solve (with
        // a reused factor, it saved 17 % of the Newton iterations of the copper compact and cost as
        // much time as it saved, docs/mechanics.md)
        let warm = slot.is_some() && self.params.warm_start && matches!(solver, LinearSolver::Amg | LinearSolver::Pcg | LinearSolver::Hypre);
        let slot = slot.unwrap_or(0);
        if warm && self.history.len() <= slot {
            self.history.resize(slot + 1, Vec::new());
        }
        // the residual b − K x₀ of the warm start, handed to the solver
        let mut r0 = None;
        if b_norm > 0.0 && rep.n_eq > 0 && warm && !self.history[slot].is_empty() {
            let t0 = Instant::now();
            let op = amg::FineOp { blocks, pairs: &self.pairs, inc: &self.inc, fixed: &rep.fixed };
            let (rel, r) = warm_start(&op, &self.history[slot], rhs, b_norm, self.params.rtol, &mut x);
            info.warm_start = rel;
            r0 = r;
            info.solve_seconds += t0.elapsed().as_secs_f64();
        }
        if b_norm > 0.0 && rep.n_eq > 0 {
            match solver {
                LinearSolver::Pcg => self.newton_pcg(rep, blocks, rhs, b_norm, &mut x, r0, info)?,
                LinearSolver::Amg => self.newton_amg(rep, positions, r_scale, blocks, rhs, b_norm, &mut x, r0, info)?,
                LinearSolver::Hypre => self.newton_hypre(rep, positions, r_scale, blocks, rhs, b_norm, &mut x, r0, info)?,
                _ => self.newton_cholesky(rep, positions, links, blocks, rhs, b_norm, &mut x, info)?,
            }
        }
        if warm && b_norm > 0.0 {
            let h = &mut self.history[slot];
            while h.len() >= self.params.warm_start_depth {
                h.remove(0);
            }
            h.push(x.clone());
        }
        Ok(x)
    }

    /// Geometry, assembly and the scaled load vector with the topology analysis `rep`:
    /// `(geometry per bond, blocks, rhs, r̄, link stiffnesses per bond)`. `branch`: the branch vector `x_B − x_A` of each bond
    /// (a periodic cell's minimum image, docs/mechanics.md (B13)); None: the difference of the centres.
    fn prepare(
        &self,
        rep: &TopologyReport,
        inp: &StepInput,
        branch: Option<&[Vector3<f64>]>,
        info: &mut MechInfo,
    ) -> Result<(Vec<BondGeometry>, BlockMatrix, Vec<f64>, f64, Vec<[f64; 6]>), Error> {
        let n = self.n;
        info.equations = rep.n_eq;
        info.components = rep.components;
        info.rattlers = rep.rattlers.len();
        info.pinned = rep.pinned.len();

        // geometry, link stiffness, assembly, loads
        let t0 = Instant::now();
        let r_scale = inp.radii.iter().sum::<f64>() / n.max(1) as f64;
        let geom: Result<Vec<BondGeometry>, Error> = self
            .pairs
            .par_iter()
            .zip(inp.y4_y7.par_iter())
            .enumerate()
            .map(|(c, (&[a, b], &[y4, y7]))| {
                let x_a = inp.positions[a as usize];
                let x_b = branch.map_or(inp.positions[b as usize], |l| x_a + l[c]);
                BondGeometry::new(&x_a, &x_b, y4, y7).map_err(|err| Error::from(err.with_context(format!("contact {c} between particles {a} and {b}"))))
            })
            .collect();
        let geom = geom?;
        let k = self.link_stiffnesses(inp.radii);
        let blocks = BlockMatrix::assemble(n, &self.pairs, &self.inc, &geom, &k, r_scale);
        let release = self.release_loads(&geom, inp.radii);
        let mut rhs = vec![0.0; 6 * n];
        rhs.par_chunks_mut(6).enumerate().for_each(|(i, f)| {
            let mut force = Vector3::zeros();
            for &(c, side) in &self.inc.bonds[self.inc.start[i] as usize..self.inc.start[i + 1] as usize] {
                let g = geom[c as usize].e3 * inp.load[c as usize];
                if side == 0 { force += g } else { force -= g }
            }
            let mut moment = Vector3::zeros();
            if let Some(q) = &release {
                // (B26): the release of the stored tangential force, (B7) at the bond point, and
                // of the stored moment (B30)
                for &(c, side) in &self.inc.bonds[self.inc.start[i] as usize..self.inc.start[i + 1] as usize] {
                    let (g, (qc, mc)) = (&geom[c as usize], q[c as usize]);
                    if side == 0 {
                        force += qc;
                        moment += (g.l_a.cross(&qc) + mc) / r_scale;
                    } else {
                        force -= qc;
                        moment -= (g.l_b.cross(&qc) + mc) / r_scale;
                    }
                }
            }
            if let Some(ext) = inp.external {
                force += ext[i].force;
                moment += ext[i].moment / r_scale;
            }
            let m = rep.fixed[i];
            for k in 0..3 {
                f[k] = if m & (1 << k) != 0 { 0.0 } else { force[k] };
                f[3 + k] = if m & (8 << k) != 0 { 0.0 } else { moment[k] };
            }
        });
        info.assemble_seconds = t0.elapsed().as_secs_f64();

        Ok((geom, blocks, rhs, r_scale, k))
    }

    /// The assembled scaled system of `inp` (tests and experiments): blocks, right-hand side, r̄,
    /// the topology report and the incidence.
    pub fn assembled(&mut self, inp: &StepInput) -> Result<(BlockMatrix, Vec<f64>, f64, TopologyReport, Incidence), Error> {
        self.check_input(inp)?;
        let mut info = MechInfo::default();
        let rep = self.analysis(inp.positions, &mut info)?;
        let prepared = self.prepare(&rep, inp, None, &mut info);
        self.report = Some(rep.clone());
        let (_, blocks, rhs, r_scale, _) = prepared?;
        Ok((blocks, rhs, r_scale, rep, self.inc.clone()))
    }

    #[allow(clippy::too_many_arguments)]
    fn newton_cholesky(
        &mut self,
        rep: &TopologyReport,
        positions: &[Vector3<f64>],
        links: Links,
        blocks: &BlockMatrix,
        b: &[f64],
        b_norm: f64,
        x: &mut [f64],
        info: &mut MechInfo,
    ) -> Result<(), Error> {
        info.solver = SolverUsed::Cholesky;
        let op = amg::FineOp { blocks, pairs: &self.pairs, inc: &self.inc, fixed: &rep.fixed };
        crate::linsolve::set_parallelism_for(rep.n_eq);
        let stale_usable = self.params.reuse_factor && !self.refresh;
        if let Kept::Cholesky { chol, eq: chol_eq, current } = &mut self.kept
            && stale_usable
            && chol.is_factored()
            && (self.params.stale_factor_cg || !*current)
        {
            // CG on the current stiffness, preconditioned by the last factor (possibly of an
            // older topology: DOF that were not in it get their block-Jacobi inverse)
            if let Some(iterations) = stale_factor_cg(chol, chol_eq, &op, &rep.eq, blocks, b, b_norm, self.params.rtol, x, info)? {
                if iterations > STALE_CG_REFRESH {
                    self.refresh = true;
                }
                return Ok(());
            }
            // too stale: a fresh factor, Newton from where CG stopped (or from zero)
            if !x.iter().all(|v| v.is_finite()) {
                x.iter_mut().for_each(|v| *v = 0.0);
            }
            self.refresh = true;
        }
        // a factor of fewer bonds with the low-rank update of the added ones (same equations)
        if let Kept::Updated { eq: chol_eq, update, .. } = &self.kept
            && (!stale_usable || *chol_eq != rep.eq || update.rank() + 6 * (self.pairs.len() - update.bonds) > self.params.update_rank)
        {
            self.kept = Kept::Nothing;
        }
        if let Kept::Updated { chol, update, .. } = &mut self.kept {
            let mut outcome: Result<bool, Error> = Ok(true);
            if update.bonds < self.pairs.len() {
                let t0 = Instant::now();
                let mut cols = Vec::new();
                for c in update.bonds..self.pairs.len() {
                    let [a, b] = self.pairs[c];
                    cols.extend(lowrank::LowRank::bond_columns(a, b, &links.geom[c], &links.k[c], links.r_scale, &rep.eq));
                }
                outcome = update.extend(chol, cols, self.pairs.len()).map(|_| true).map_err(Error::from);
                info.factor_seconds += t0.elapsed().as_secs_f64();
                info.updates += 1;
            }
            if let Ok(true) = outcome {
                outcome = newton::newton_on_update(&self.params, rep, &op, chol, update, b, b_norm, x, info);
            }
            info.update_rank = update.rank();
            match outcome {
                Ok(true) => return Ok(()),
                // slow (or a capacitance that lost definiteness): a fresh analysis and factor,
                // Newton from where it stopped
                _ => {
                    self.kept = Kept::Nothing;
                    if !x.iter().all(|v| v.is_finite()) {
                        x.iter_mut().for_each(|v| *v = 0.0);
                    }
                }
            }
        }
        // the factor of the current topology: the kept one, or a new symbolic factorisation
        let mut chol = match std::mem::replace(&mut self.kept, Kept::Nothing) {
            Kept::Cholesky { chol, current: true, .. } => chol,
            old => {
                let t0 = Instant::now();
                let mut entries = Vec::new();
                blocks.for_each_lower(&self.pairs, rep, |r, c, _| entries.push((r, c)));
                let symbolic = match self.params.ordering {
                    cholesky::Ordering::NestedDissection => Ok(Some(cholesky::equation_order(positions, &self.pairs, &rep.fixed, &rep.eq, rep.n_eq))),
                    cholesky::Ordering::BlockAmd => cholesky::block_amd_order(self.n, &self.pairs, &rep.eq, rep.n_eq).map(Some),
                    cholesky::Ordering::Amd => Ok(None),
                }
                .and_then(|perm| BondCholesky::new(rep.n_eq, &entries, perm));
                match symbolic {
                    Ok(c) => {
                        info.symbolic_seconds = t0.elapsed().as_secs_f64();
                        Box::new(c)
                    }
                    Err(e) => {
                        self.kept = old;
                        return Err(e.into());
                    }
                }
            }
        };
        let result = newton_on_factor(&self.params, &mut self.refresh, rep, &op, &mut chol, b, b_norm, x, info);
        self.kept = Kept::Cholesky { chol, eq: rep.eq.clone(), current: true };
        result
    }

    /// Newton with block-Jacobi PCG from `x` (the warm start, whose residual is `r0` when given).
    fn newton_pcg(
        &mut self,
        rep: &TopologyReport,
        blocks: &BlockMatrix,
        b: &[f64],
        b_norm: f64,
        x: &mut [f64],
        r0: Option<Vec<f64>>,
        info: &mut MechInfo,
    ) -> Result<(), Error> {
        info.solver = SolverUsed::Pcg;
        let op = amg::FineOp { blocks, pairs: &self.pairs, inc: &self.inc, fixed: &rep.fixed };
        let t0 = Instant::now();
        let prec = cg::BlockJacobi::new(&blocks.diag, &rep.fixed)?;
        info.factor_seconds += t0.elapsed().as_secs_f64();
        let max_iter = self.params.pcg_max_iter;
        newton::newton_inexact(&self.params, &op, b, b_norm, x, r0, info, "PCG", |r, dx, tol, info| {
            let t1 = Instant::now();
            let pi = cg::pcg(|v, out| op.matvec(v, out), &prec, r, dx, tol, max_iter)?;
            info.solve_seconds += t1.elapsed().as_secs_f64();
            info.pcg_iterations += pi.iterations;
            Ok(())
        })
    }
}

impl BondedSystem {
    /// Newton with CG preconditioned by the AMG hierarchy ([`amg`]): built once per topology and,
    /// with `amg.reuse`, kept as a (stale, still SPD) preconditioner across steps with only the fine
    /// smoother refreshed, until CG needs more than 1.5× the iterations of the last fresh build + 5.
    fn newton_amg(
        &mut self,
        rep: &TopologyReport,
        positions: &[Vector3<f64>],
        r_scale: f64,
        blocks: &BlockMatrix,
        b: &[f64],
        b_norm: f64,
        x: &mut [f64],
        r0: Option<Vec<f64>>,
        info: &mut MechInfo,
    ) -> Result<(), Error> {
        info.solver = SolverUsed::Amg;
        let fine = amg::FineOp { blocks, pairs: &self.pairs, inc: &self.inc, fixed: &rep.fixed };
        let ap = self.params.amg;
        let t0 = Instant::now();
        // a kept hierarchy gets the fine smoother of this step's stiffness, but only when CG
        // runs (a step that its warm start solves needs none)
        let (h, fresh) = match std::mem::replace(&mut self.kept, Kept::Nothing) {
            Kept::Amg(h) if ap.reuse && !h.is_stale() && h.fine_fixed() == rep.fixed.as_slice() => (*h, false),
            old => {
                // aggregates (and the coarse symbolic factor) of the last build serve while the
                // free DOF are the same
                let old = match old {
                    Kept::Amg(h) if h.fine_fixed() == rep.fixed.as_slice() => Some(*h),
                    _ => None,
                };
                let h = amg::Amg::build(fine, positions, r_scale, ap, old)?;
                info.amg_builds += 1;
                (h, true)
            }
        };
        info.factor_seconds += t0.elapsed().as_secs_f64();
        let hierarchy = AmgSolve { fine, positions, r_scale, params: &self.params };
        let (kept, result) = hierarchy.newton(h, fresh, &mut self.amg_fresh_iterations, b, b_norm, x, r0, info);
        if let Some(h) = kept {
            self.kept = Kept::Amg(Box::new(h));
        }
        result
    }
}

/// What the Newton iterations of [`BondedSystem::newton_amg`] read: the fine operator, the
/// positions and r̄ a rebuild of the hierarchy needs, the parameters.
struct AmgSolve<'a> {
    fine: amg::FineOp<'a>,
    positions: &'a [Vector3<f64>],
    r_scale: f64,
    params: &'a MechParams,
}

impl AmgSolve<'_> {
    /// Newton from `x` (the warm start, whose residual is `r0` when given) with the hierarchy `h`
    /// (`fresh`: just built); `fresh_iterations`: the CG iterations of the first solve after the
    /// last build (set here after a build, the yardstick of a reused one). Returns the hierarchy
    /// to keep (None when a rebuild failed) and the outcome.
    fn newton(
        &self,
        mut h: amg::Amg,
        mut fresh: bool,
        fresh_iterations: &mut usize,
        b: &[f64],
        b_norm: f64,
        x: &mut [f64],
        r0: Option<Vec<f64>>,
        info: &mut MechInfo,
    ) -> (Option<amg::Amg>, Result<(), Error>) {
        let (fine, params) = (self.fine, self.params);
        let (mut r, mut rel) = initial_residual(&fine, b, b_norm, x, r0);
        if rel <= params.rtol {
            return (Some(h), Ok(()));
        }
        if !fresh {
            let t0 = Instant::now();
            if let Err(e) = h.refresh_fine_smoother(&fine.blocks.diag) {
                return (None, Err(e.into()));
            }
            info.factor_seconds += t0.elapsed().as_secs_f64();
        }
        let mut dx = vec![0.0; x.len()];
        while info.newton_iterations < params.max_newton {
            let inner = (0.5 * params.rtol / rel).min(0.1);
            dx.iter_mut().for_each(|v| *v = 0.0);
            let t1 = Instant::now();
            info.amg_levels = h.info.equations.clone();
            info.amg = Some(h.info.clone());
            let mut work = h.work();
            let pi = cg::pcg_with(|v, out| fine.matvec(v, out), |rr, z| h.apply(fine, rr, z, &mut work), &r, &mut dx, inner, params.pcg_max_iter);
            info.solve_seconds += t1.elapsed().as_secs_f64();
            let pi = match pi {
                Ok(pi) => pi,
                Err(_) if !fresh => {
                    // a stale hierarchy that fails: rebuild it and retry this Newton iteration
                    let t2 = Instant::now();
                    h = match amg::Amg::build(fine, self.positions, self.r_scale, params.amg, Some(h)) {
                        Ok(h) => h,
                        Err(e) => return (None, Err(e.into())),
                    };
                    info.amg_builds += 1;
                    info.factor_seconds += t2.elapsed().as_secs_f64();
                    fresh = true;
                    continue;
                }
                Err(e) => return (Some(h), Err(e.into())),
            };
            info.pcg_iterations += pi.iterations;
            if fresh && info.newton_iterations == 0 {
                *fresh_iterations = pi.iterations;
            }
            x.par_iter_mut().zip(dx.par_iter()).for_each(|(xi, d)| *xi += d);
            info.newton_iterations += 1;
            rel = fine.residual(b, b_norm, x, &mut r);
            info.residuals.push(rel);
            if !rel.is_finite() {
                return (Some(h), Err(not_finite(info).into()));
            }
            if rel <= params.rtol {
                // a stale hierarchy that has become slow is rebuilt at the next step
                if !fresh && info.pcg_iterations * 2 > 3 * *fresh_iterations + 10 {
                    h = h.into_stale();
                }
                return (Some(h), Ok(()));
            }
        }
        (Some(h), Err(solve::not_converged(info, params.rtol, "AMG-PCG").into()))
    }
}

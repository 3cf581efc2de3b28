//! Newton iteration for the quasi-static equilibrium `S·K·S·ỹ = S·ΔF` with a scaled residual check
//! (docs/mechanics.md (B10): accept when `‖S(ΔF − K·Δy)‖₂ ≤ rtol·‖S·ΔF‖₂`, rtol = 1e-10)
//! and the choice of linear solver: faer sparse Cholesky ([`super::cholesky`], geometric nested
//! dissection or AMD; symbolic analysis reused while the topology is unchanged, optionally the numeric factor reused across
//! steps as a modified-Newton operator) or block-Jacobi PCG ([`super::cg`]).
//!
//! Within a step the links are linear, so one Newton iteration with a fresh factor meets the
//! tolerance; further iterations happen only with a reused (stale) factor, an inexact PCG solve,
//! or, later, nonlinear links.

use crate::error::{ConfigError, SolveError};
use serde::{Deserialize, Serialize};

/// Which linear solver a step uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LinearSolver {
    /// Cholesky up to [`AMG_ABOVE_EQUATIONS`] equations ([`AMG_ABOVE_EQUATIONS_FRESH`] without
    /// `reuse_factor`), AMG-preconditioned CG above (the measured crossovers, docs/mechanics.md).
    #[default]
    Auto,
    /// Sparse Cholesky (faer).
    Cholesky,
    /// Conjugate gradients with a 6×6 block-Jacobi preconditioner.
    Pcg,
    /// Conjugate gradients with the smoothed-aggregation multigrid preconditioner ([`super::amg`]).
    Amg,
    /// hypre's PCG with BoomerAMG (nodal coarsening, rigid-body interpolation vectors;
    /// [`super::hypre`]); only in builds with the cargo feature `hypre`.
    Hypre,
}

/// Automatic choice with `reuse_factor`: AMG-preconditioned CG above this many equations, Cholesky
/// below. Measured 2026-11-26 (`sinterdem bench mechanics`, random FCC bonded packings,
/// docs/mechanics.md; loaded 2-core machine): a step with the previous factor (modified Newton,
/// 4 triangular solves) costs 0.003 / 0.01–0.025 / 0.05–0.06 / 0.23–0.37 s at 4.6·10³ / 1.1·10⁴ /
/// 2.2·10⁴ / 6.0·10⁴ equations, an AMG step with the previous hierarchy 0.013 / 0.03 / 0.10–0.12 /
/// 0.34–0.75 s; but every new topology costs the Cholesky a fresh factorisation (1.1–2.1 s at
/// 6·10⁴, ≈ 400 s and 14 GB at 5.4·10⁵) against an AMG setup of 0.17–0.25 s (2.4 s at 5.4·10⁵).
/// In the coupled loop at 1.1·10⁴ particles (6.5·10⁴ equations) the two were within the noise
/// (0.33 vs 0.28–0.41 s per step). So the switch stays at 5·10⁴ equations (≈ 8·10³ particles).
pub const AMG_ABOVE_EQUATIONS: usize = 50_000;

/// Automatic choice with `reuse_factor` and `warm_start` (docs/mechanics.md (B12)): AMG-preconditioned
/// CG above this many equations. Measured 2026-12-02 on the same machine, back to back: the E14B
/// compact (3619 particles, 2.2·10⁴ equations, 1055 steps) took 122 s with Cholesky (mechanics
/// 93.5 s: 74 factorisations 31 s, 2243 triangular solves 43 s) and 64 s with warm-started AMG
/// (mechanics 40.4 s, 8099 CG iterations); the copper compact (4.8·10³ equations) 10.7 s against
/// 10.5 s, a tie. So warm-started AMG takes over at 10⁴ equations (≈ 1700 particles).
pub const AMG_ABOVE_EQUATIONS_WARM: usize = 10_000;

/// Automatic choice without `reuse_factor` (a fresh factor every step): AMG above this many
/// equations. Measured with the same benchmark: Cholesky step 0.006 / 0.03–0.06 / 0.18 / 1.5–2.2 s
/// at 4.6·10³ / 1.1·10⁴ / 2.2·10⁴ / 6.0·10⁴ equations, AMG step (fresh hierarchy) 0.02 / 0.04 /
/// 0.13–0.14 / 0.55–0.57 s: even at ≈ 1.1·10⁴, AMG ahead above.
pub const AMG_ABOVE_EQUATIONS_FRESH: usize = 15_000;

/// The solver that was used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SolverUsed {
    /// Nothing to solve (zero load or no equations).
    #[default]
    None,
    Cholesky,
    Pcg,
    Amg,
    Hypre,
}

/// Parameters of the mechanical solve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MechParams {
    /// Young's modulus E of the links [Pa] (it cancels from the shrinkage when the load (F5) uses
    /// the same E; only ν shapes the response).
    pub young_modulus: f64,
    /// Poisson ratio ν [1], in (−1, 0.5].
    pub poisson_ratio: f64,
    /// `mechanics_rtol`: accept when ‖S(ΔF − KΔy)‖₂ ≤ rtol·‖SΔF‖₂ [1].
    pub rtol: f64,
    /// Newton iterations at most [1].
    pub max_newton: usize,
    /// Linear solver.
    pub solver: LinearSolver,
    /// Fill-reducing ordering of the Cholesky factor.
    pub ordering: super::cholesky::Ordering,
    /// Reuse the previous step's Cholesky factor (same topology) as the Newton operator and
    /// refactorise only when an iteration reduces the residual by less than 10× [flag].
    pub reuse_factor: bool,
    /// PCG iterations at most per Newton iteration [1].
    pub pcg_max_iter: usize,
    /// With `reuse_factor`: use the stale Cholesky factor as the preconditioner of CG instead of
    /// as a modified-Newton operator [flag].
    pub stale_factor_cg: bool,
    /// The AMG preconditioner.
    pub amg: super::amg::AmgParams,
    /// CG-based solvers (AMG, PCG): start each step from the Galerkin projection of the current
    /// system onto the last [`WARM_START_DEPTH`] solutions (docs/mechanics.md (B12)) instead of
    /// from zero [flag]. Cholesky steps do not use it.
    pub warm_start: bool,
    /// Earlier solutions spanning the warm start (B12) [1], in [1, 8].
    pub warm_start_depth: usize,
    /// Keep the AMG hierarchy across a change of the bond set while the free DOF stay the same:
    /// the fine level (smoother, residual) is the new stiffness, the coarse levels those of the
    /// last build, rebuilt by the rule of `amg.reuse` [flag] (docs/coupled.md "Scaling", 2026-12-04).
    pub amg_keep_on_new_bonds: bool,
    /// With `reuse_factor` and the Cholesky solver: serve a change of the bond set that only adds
    /// bonds (same equations) by a low-rank (Woodbury) update of the kept factor
    /// ([`super::lowrank`]) while its rank stays at most this [1]; 0: a new symbolic analysis and
    /// factorisation at every change (docs/coupled.md "Low-rank update of the factor").
    pub update_rank: usize,
}

/// Largest `update_rank` accepted [1] (the capacitance factor grows as its square).
pub const MAX_UPDATE_RANK: usize = 2000;

/// Solutions of earlier steps kept for the warm start by default [1].
pub const WARM_START_DEPTH: usize = 2;

impl Default for MechParams {
    fn default() -> Self {
        MechParams {
            young_modulus: 110e9,
            poisson_ratio: 0.34,
            rtol: 1e-10,
            max_newton: 8,
            solver: LinearSolver::Auto,
            ordering: super::cholesky::Ordering::BlockAmd,
            reuse_factor: false,
            pcg_max_iter: 50_000,
            stale_factor_cg: false,
            amg: Default::default(),
            warm_start: false,
            warm_start_depth: WARM_START_DEPTH,
            amg_keep_on_new_bonds: false,
            update_rank: 0,
        }
    }
}

impl MechParams {
    /// Range checks (no panic, no NaN downstream).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |key: &str, value: f64, range: &str, unit: &str| {
            Err(ConfigError::OutOfRange { key: format!("mechanics.{key}"), value, range: range.into(), unit: unit.into() })
        };
        if !(self.young_modulus.is_finite() && self.young_modulus > 0.0) {
            return bad("young_modulus", self.young_modulus, "(0, ∞)", "Pa");
        }
        if !(self.poisson_ratio > -1.0 && self.poisson_ratio <= 0.5) {
            return bad("poisson_ratio", self.poisson_ratio, "(-1, 0.5]", "1");
        }
        if !(self.rtol >= 1e-15 && self.rtol <= 1e-2) {
            return bad("rtol", self.rtol, "[1e-15, 1e-2]", "1");
        }
        if !(1..=100).contains(&self.max_newton) {
            return bad("max_newton", self.max_newton as f64, "[1, 100]", "1");
        }
        if !(1..=8).contains(&self.warm_start_depth) {
            return bad("warm_start_depth", self.warm_start_depth as f64, "[1, 8]", "1");
        }
        if self.update_rank > MAX_UPDATE_RANK {
            return bad("update_rank", self.update_rank as f64, "[0, 2000]", "1");
        }
        if self.solver == LinearSolver::Hypre {
            super::hypre::check_available("mechanics.solver")?;
        }
        if self.pcg_max_iter == 0 {
            return bad("pcg_max_iter", 0.0, "[1, ∞)", "1");
        }
        let a = &self.amg;
        if !(1..=10).contains(&a.sweeps) {
            return bad("amg.sweeps", a.sweeps as f64, "[1, 10]", "1");
        }
        if !(a.smoother_omega > 0.0 && a.smoother_omega < 2.0) {
            return bad("amg.smoother_omega", a.smoother_omega, "(0, 2)", "1");
        }
        if !(6..100_000).contains(&a.max_coarse) {
            return bad("amg.max_coarse", a.max_coarse as f64, "[6, 1e5)", "1");
        }
        if !(1..=20).contains(&a.max_levels) {
            return bad("amg.max_levels", a.max_levels as f64, "[1, 20]", "1");
        }
        if !(a.strength >= 0.0 && a.strength < 1.0) {
            return bad("amg.strength", a.strength, "[0, 1)", "1");
        }
        Ok(())
    }
}

/// What a mechanical step did (docs/design.md: solvers report).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MechInfo {
    /// Linear solver used.
    pub solver: SolverUsed,
    /// Newton iterations [1].
    pub newton_iterations: usize,
    /// Scaled residual ‖S(ΔF − KΔy)‖₂/‖SΔF‖₂ after each Newton iteration [1].
    pub residuals: Vec<f64>,
    /// PCG iterations summed over Newton iterations [1].
    pub pcg_iterations: usize,
    /// Numeric Cholesky factorisations in this step [1].
    pub factorizations: usize,
    /// AMG hierarchies built in this step [1], and the equations per AMG level (fine first).
    pub amg_builds: usize,
    pub amg_levels: Vec<usize>,
    /// The last AMG setup's report (levels, coarse sizes, setup times).
    pub amg: Option<super::amg::AmgInfo>,
    /// Equations (free DOF) [1].
    pub equations: usize,
    /// Bonds [1].
    pub bonds: usize,
    /// Bonded components, rattlers and pinned components of the current topology [1].
    pub components: usize,
    pub rattlers: usize,
    pub pinned: usize,
    /// Relative residual ‖b − K x₀‖₂/‖b‖₂ of the warm start (B12) [1]; 0 without one.
    pub warm_start: f64,
    /// Changes of the bond set served by the low-rank update of the kept factor in this step [1],
    /// and the update's rank after the step [1] (0 without one).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub updates: usize,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub update_rank: usize,
    /// True when the topology analysis (components, pattern, symbolic factorisation) ran in this step.
    pub topology_rebuilt: bool,
    /// Wall times [s]: topology analysis, symbolic factorisation, assembly (geometry, element
    /// matrices, loads, reduced values), numeric factorisation, triangular solves or PCG, whole step.
    pub analysis_seconds: f64,
    pub symbolic_seconds: f64,
    pub assemble_seconds: f64,
    pub factor_seconds: f64,
    pub solve_seconds: f64,
    pub total_seconds: f64,
}

impl MechInfo {
    /// Adds the counters and times of one right-hand side's solve `sub` to this step's (a
    /// periodic cell solves several, docs/mechanics.md (B17)); the solver, the AMG report and the
    /// warm-start residual are the first solve's when set, the residuals are concatenated.
    pub fn absorb(&mut self, sub: MechInfo) {
        if self.newton_iterations == 0 && self.residuals.is_empty() {
            self.solver = sub.solver;
            self.warm_start = sub.warm_start;
        }
        self.newton_iterations += sub.newton_iterations;
        self.residuals.extend(sub.residuals);
        self.pcg_iterations += sub.pcg_iterations;
        self.factorizations += sub.factorizations;
        self.updates += sub.updates;
        self.update_rank = self.update_rank.max(sub.update_rank);
        self.amg_builds += sub.amg_builds;
        if sub.amg.is_some() {
            self.amg_levels = sub.amg_levels;
            self.amg = sub.amg;
        }
        self.symbolic_seconds += sub.symbolic_seconds;
        self.assemble_seconds += sub.assemble_seconds;
        self.factor_seconds += sub.factor_seconds;
        self.solve_seconds += sub.solve_seconds;
    }
}

fn is_zero(v: &usize) -> bool {
    *v == 0
}

/// Checks a Newton residual history against `rtol`; the error carries the history.
pub(crate) fn not_converged(info: &MechInfo, rtol: f64, what: &str) -> SolveError {
    SolveError {
        stage: "mechanics Newton".into(),
        message: format!("{what}: scaled residual did not reach {rtol:.1e} in {} iteration(s)", info.newton_iterations),
        residuals: info.residuals.clone(),
    }
}

/// What the solver in use keeps between steps: a Cholesky factor or an AMG hierarchy, never both
/// (block-Jacobi PCG keeps nothing).
pub(super) enum Kept {
    /// Nothing kept: a new system, changed elastic constants or constraints, a dropped factor.
    Nothing,
    /// A sparse Cholesky factor built for the equation map `eq` (`eq` of the topology report).
    /// `current`: it belongs to the current topology; otherwise it was kept across a topology
    /// change as the preconditioner of CG on the new stiffness (`stale_factor_cg`), and `eq`
    /// differs from the current map.
    Cholesky { chol: Box<super::cholesky::BondCholesky>, eq: Vec<u32>, current: bool },
    /// A sparse Cholesky factor of an earlier bond set with the equation map `eq`, and the
    /// low-rank update of the bonds added since (`update_rank`, [`super::lowrank`]).
    Updated { chol: Box<super::cholesky::BondCholesky>, eq: Vec<u32>, update: Box<super::lowrank::LowRank> },
    /// An AMG hierarchy of the current topology (possibly marked stale, rebuilt at the next step).
    Amg(Box<super::amg::Amg>),
}

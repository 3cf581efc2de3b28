//! Newton iteration for the quasi-static equilibrium `S·K·S·ỹ = S·ΔF` with a scaled residual check
//! (bonded-mechanics.md, "Scaling": accept when `‖S(ΔF − K·Δy)‖₂ ≤ rtol·‖S·ΔF‖₂`, rtol = 1e-10)
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
    /// Cholesky up to [`PCG_ABOVE_EQUATIONS`] equations, PCG above (the measured crossover, see
    /// docs/mechanics.md).
    #[default]
    Auto,
    /// Sparse Cholesky (faer).
    Cholesky,
    /// Conjugate gradients with a 6×6 block-Jacobi preconditioner.
    Pcg,
}

/// Automatic choice: PCG above this many equations. Measured by `bench_mechanics` (random FCC
/// bonded packings, docs/mechanics.md), one step with a fresh factor: Cholesky 2–3× faster than
/// block-Jacobi PCG at 4.6·10³ equations, 1.2× slower at 6·10⁴, 3–5× slower at 5.4·10⁵
/// (nnz(L) grows ≈ N^1.5, its factorisation ≈ N²; PCG iterations only ≈ N^0.25). The crossover,
/// ≈ 4–5·10⁴ equations (≈ 8·10³ particles), is where this switch sits. With `reuse_factor` the
/// Cholesky stays ahead for as long as one factor serves many steps.
pub const PCG_ABOVE_EQUATIONS: usize = 50_000;

/// The solver that was used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SolverUsed {
    /// Nothing to solve (zero load or no equations).
    #[default]
    None,
    Cholesky,
    Pcg,
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
}

impl Default for MechParams {
    fn default() -> Self {
        MechParams {
            young_modulus: 110e9,
            poisson_ratio: 0.34,
            rtol: 1e-10,
            max_newton: 8,
            solver: LinearSolver::Auto,
            ordering: super::cholesky::Ordering::Amd,
            reuse_factor: false,
            pcg_max_iter: 50_000,
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
        if self.pcg_max_iter == 0 {
            return bad("pcg_max_iter", 0.0, "[1, ∞)", "1");
        }
        Ok(())
    }
}

/// What a mechanical step did (architecture map: solvers report).
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
    /// Equations (free DOF) [1].
    pub equations: usize,
    /// Bonds [1].
    pub bonds: usize,
    /// Bonded components, rattlers and pinned components of the current topology [1].
    pub components: usize,
    pub rattlers: usize,
    pub pinned: usize,
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

/// Checks a Newton residual history against `rtol`; the error carries the history.
pub(crate) fn not_converged(info: &MechInfo, rtol: f64, what: &str) -> SolveError {
    SolveError {
        stage: "mechanics Newton".into(),
        message: format!("{what}: scaled residual did not reach {rtol:.1e} in {} iteration(s)", info.newton_iterations),
        residuals: info.residuals.clone(),
    }
}

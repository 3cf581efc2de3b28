//! The optimisers, all from the `argmin` crate, in unit coordinates u ∈ [0, 1]ⁿ (see [`super::params`]):
//!
//! 1. global: particle swarm ([`ParticleSwarm`], seeded `Xoshiro256PlusPlus`) on χ²(u);
//! 2. local: trust region ([`TrustRegion`] with the [`Steihaug`] CG subproblem) on
//!    `f(u) = ½ χ²(u)` with gradient `Jᵀr` and the Gauss–Newton Hessian `JᵀJ`, J the central
//!    finite-difference Jacobian of the residual vector r(u): a Levenberg–Marquardt-type method.
//!    The bound box is kept by evaluating r at clamp(u) plus a quadratic penalty
//!    `½·w·|u − clamp(u)|²` outside it; the local phase stops after `stall` iterations in a row
//!    that lower f by less than `tolerance·f` ([`Stall`], a stopping rule around argmin's solver).
//!
//! Determinism: the swarm's random numbers come from one seeded generator in a fixed order, every
//! evaluation is deterministic (see [`super::forward`]), and the finite-difference points are
//! collected in order; results do not depend on the number of threads.

use super::forward::Forward;
use super::loss::{chi2, residual_vector};
use argmin::core::{
    CostFunction, Error as ArgminError, Executor, Gradient, Hessian, IterState, KV, Problem, Solver, State, TerminationReason, TerminationStatus,
};
use argmin::solver::particleswarm::ParticleSwarm;
use argmin::solver::trustregion::{Steihaug, TrustRegion};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use std::sync::Mutex;

/// Weight of the bound penalty of the local phase [1].
const BOUND_WEIGHT: f64 = 1.0e6;

/// Optimiser settings (`[optimiser]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Particles of the swarm.
    pub swarm_size: usize,
    /// Swarm iterations (0: no global phase; the local phase starts from the starting material).
    pub swarm_iterations: u64,
    /// Largest number of trust-region iterations.
    pub local_iterations: u64,
    /// Relative decrease of ½χ² below which an iteration counts as stalled [1].
    pub tolerance: f64,
    /// Stalled iterations in a row that end the local phase.
    pub stall: u64,
    /// Finite-difference step in unit coordinates [1].
    pub fd_step: f64,
    /// Seed of the swarm.
    pub seed: u64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings { swarm_size: 16, swarm_iterations: 25, local_iterations: 50, tolerance: 1e-8, stall: 4, fd_step: 1e-4, seed: 1 }
    }
}

/// Residual vector r at unit coordinates (clamped).
pub fn residuals_at(fwd: &Forward, u: &[f64]) -> Vec<f64> {
    let uc: Vec<f64> = u.iter().map(|x| x.clamp(0.0, 1.0)).collect();
    let values = fwd.values(&uc);
    residual_vector(&fwd.experiments, &fwd.predict(&values))
}

/// Finite-difference Jacobian ∂r/∂u (m rows of n) at `u` ∈ [0,1]ⁿ with step `h`: central
/// `(r(u + h eᵢ) − r(u − h eᵢ))/2h` (2n evaluations, one-sided at a bound) when `r0` is None, else
/// forward `(r(u ± h eᵢ) − r0)/±h` from the known `r0 = r(u)` (n evaluations, backward at the upper
/// bound). The evaluations run in parallel and are collected in order.
pub fn jacobian(fwd: &Forward, u: &[f64], h: f64, r0: Option<&[f64]>) -> Vec<Vec<f64>> {
    let n = u.len();
    let uc: Vec<f64> = u.iter().map(|x| x.clamp(0.0, 1.0)).collect();
    let cols: Vec<Vec<f64>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let at = |x: f64| {
                let mut a = uc.clone();
                a[i] = x;
                residuals_at(fwd, &a)
            };
            match r0 {
                Some(r0) => {
                    let step = if uc[i] + h <= 1.0 { h } else { -h };
                    let r = at(uc[i] + step);
                    r.iter().zip(r0).map(|(y, x)| (y - x) / step).collect()
                }
                None => {
                    let (hi, lo) = ((uc[i] + h).min(1.0), (uc[i] - h).max(0.0));
                    let (ra, rb) = rayon::join(|| at(lo), || at(hi));
                    ra.iter().zip(&rb).map(|(x, y)| (y - x) / (hi - lo)).collect()
                }
            }
        })
        .collect();
    let m = cols.first().map(|c| c.len()).unwrap_or(0);
    (0..m).map(|k| (0..n).map(|i| cols[i][k]).collect()).collect()
}

/// A point u with its residuals r and, once computed, its Jacobian J.
type Cached = Option<(Vec<f64>, Vec<f64>, Option<Vec<Vec<f64>>>)>;

/// The calibration problem for argmin.
struct Calib<'a> {
    fwd: &'a Forward,
    fd_step: f64,
    /// Last (u, r, J) of the local phase.
    cache: Mutex<Cached>,
}

impl Calib<'_> {
    fn r(&self, u: &[f64]) -> Vec<f64> {
        let mut c = self.cache.lock().unwrap();
        if let Some((cu, r, _)) = c.as_ref()
            && cu == u
        {
            return r.clone();
        }
        let r = residuals_at(self.fwd, u);
        *c = Some((u.to_vec(), r.clone(), None));
        r
    }
    fn rj(&self, u: &[f64]) -> (Vec<f64>, Vec<Vec<f64>>) {
        let r = self.r(u);
        let mut c = self.cache.lock().unwrap();
        if let Some((_, _, Some(j))) = c.as_ref() {
            return (r, j.clone());
        }
        let j = jacobian(self.fwd, u, self.fd_step, Some(&r));
        // out-of-box components do not move r
        let j: Vec<Vec<f64>> = j.into_iter().map(|row| row.iter().zip(u).map(|(x, ui)| if (0.0..=1.0).contains(ui) { *x } else { 0.0 }).collect()).collect();
        *c = Some((u.to_vec(), r.clone(), Some(j.clone())));
        (r, j)
    }
}

fn excess(u: &[f64]) -> Vec<f64> {
    u.iter().map(|x| x - x.clamp(0.0, 1.0)).collect()
}

/// χ²(u) for the swarm.
struct SwarmCost<'a>(&'a Forward);

impl CostFunction for SwarmCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, u: &Vec<f64>) -> Result<f64, ArgminError> {
        Ok(chi2(&residuals_at(self.0, u)))
    }
}

impl CostFunction for Calib<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    /// f(u) = ½ χ²(clamp u) + ½ w |u − clamp u|².
    fn cost(&self, u: &Vec<f64>) -> Result<f64, ArgminError> {
        let pen: f64 = excess(u).iter().map(|e| e * e).sum();
        Ok(0.5 * chi2(&self.r(u)) + 0.5 * BOUND_WEIGHT * pen)
    }
}

impl Gradient for Calib<'_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    /// ∇f = Jᵀr + w (u − clamp u).
    fn gradient(&self, u: &Vec<f64>) -> Result<Vec<f64>, ArgminError> {
        let (r, j) = self.rj(u);
        let ex = excess(u);
        Ok((0..u.len()).map(|i| j.iter().zip(&r).map(|(row, rk)| row[i] * rk).sum::<f64>() + BOUND_WEIGHT * ex[i]).collect())
    }
}

impl Hessian for Calib<'_> {
    type Param = Vec<f64>;
    type Hessian = Vec<Vec<f64>>;
    /// Gauss–Newton Hessian JᵀJ (+ w on the diagonal of out-of-box components).
    fn hessian(&self, u: &Vec<f64>) -> Result<Vec<Vec<f64>>, ArgminError> {
        let (_, j) = self.rj(u);
        let n = u.len();
        let mut h = vec![vec![0.0; n]; n];
        for row in &j {
            for a in 0..n {
                for b in 0..n {
                    h[a][b] += row[a] * row[b];
                }
            }
        }
        for (i, x) in u.iter().enumerate() {
            if !(0.0..=1.0).contains(x) {
                h[i][i] += BOUND_WEIGHT;
            }
        }
        Ok(h)
    }
}

/// A stopping rule around an argmin solver: stop after `stall` iterations in a row whose cost
/// decrease is below `tol·cost`, or when the cost is exactly zero.
#[derive(Clone)]
struct Stall<S> {
    inner: S,
    tol: f64,
    stall: u64,
    last: f64,
    count: u64,
    /// Cost after every iteration.
    history: Vec<f64>,
}

impl<O, S, P, G, H> Solver<O, IterState<P, G, (), H, (), f64>> for Stall<S>
where
    S: Solver<O, IterState<P, G, (), H, (), f64>>,
    P: Clone,
    G: Clone,
    H: Clone,
{
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn init(&mut self, problem: &mut Problem<O>, state: IterState<P, G, (), H, (), f64>) -> Result<(IterState<P, G, (), H, (), f64>, Option<KV>), ArgminError> {
        self.inner.init(problem, state)
    }
    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        state: IterState<P, G, (), H, (), f64>,
    ) -> Result<(IterState<P, G, (), H, (), f64>, Option<KV>), ArgminError> {
        self.inner.next_iter(problem, state)
    }
    fn terminate(&mut self, state: &IterState<P, G, (), H, (), f64>) -> TerminationStatus {
        let c = state.get_cost();
        self.history.push(c);
        if c == 0.0 {
            return TerminationStatus::Terminated(TerminationReason::TargetCostReached);
        }
        if self.last - c <= self.tol * c.abs() {
            self.count += 1;
        } else {
            self.count = 0;
        }
        self.last = self.last.min(c);
        if self.count >= self.stall { TerminationStatus::Terminated(TerminationReason::SolverConverged) } else { TerminationStatus::NotTerminated }
    }
}

/// Result of the two phases.
#[derive(Debug, Clone, PartialEq)]
pub struct Optimum {
    /// Best unit coordinates.
    pub u: Vec<f64>,
    /// χ² after the swarm and at the end [1].
    pub chi2_global: f64,
    pub chi2: f64,
    /// Iterations run.
    pub swarm_iterations: u64,
    pub local_iterations: u64,
    /// Why the local phase stopped.
    pub local_stop: String,
    /// χ² at the start of the local phase and after each of its iterations.
    pub local_history: Vec<f64>,
}

fn argmin_err(e: ArgminError) -> crate::error::SolveError {
    crate::error::SolveError::new("calibration optimiser (argmin)", e.to_string())
}

/// Runs the swarm (if any iterations) and then the local phase from its best particle (or from `u0`).
pub fn optimise(fwd: &Forward, u0: &[f64], s: &Settings, log: &mut dyn FnMut(&str)) -> Result<Optimum, crate::error::SolveError> {
    let n = u0.len();
    let (mut u, mut chi2_global, mut swarm_iters) = (u0.to_vec(), chi2(&residuals_at(fwd, u0)), 0);
    if s.swarm_iterations > 0 {
        let pso = ParticleSwarm::new((vec![0.0; n], vec![1.0; n]), s.swarm_size).with_rng_generator(Xoshiro256PlusPlus::seed_from_u64(s.seed));
        let res = Executor::new(SwarmCost(fwd), pso).configure(|st| st.max_iters(s.swarm_iterations)).run().map_err(argmin_err)?;
        let st = res.state();
        swarm_iters = st.get_iter();
        if let Some(best) = st.get_best_param()
            && best.cost < chi2_global
        {
            u = best.position.clone();
            chi2_global = best.cost;
        }
        log(&format!("global phase (particle swarm, {} particles, {swarm_iters} iterations): chi2 = {chi2_global:.6e}", s.swarm_size));
    }
    let mut chi2_final = chi2_global;
    let mut local_iters = 0;
    let mut local_stop = "not run".to_string();
    let mut local_history = Vec::new();
    if s.local_iterations > 0 {
        let problem = Calib { fwd, fd_step: s.fd_step, cache: Mutex::new(None) };
        let tr =
            TrustRegion::new(Steihaug::new().with_max_iters(10 * n as u64 + 10)).with_radius(0.05).and_then(|t| t.with_max_radius(1.0)).map_err(argmin_err)?;
        let solver = Stall { inner: tr, tol: s.tolerance, stall: s.stall, last: f64::INFINITY, count: 0, history: Vec::new() };
        let res = Executor::new(problem, solver).configure(|st| st.param(u.clone()).max_iters(s.local_iterations)).run().map_err(argmin_err)?;
        local_history = res.solver.history.iter().map(|c| 2.0 * c).collect();
        let st = res.state();
        local_iters = st.get_iter();
        local_stop = st.get_termination_reason().map(|r| r.text().to_string()).unwrap_or_else(|| "unknown".into());
        if let Some(best) = st.get_best_param() {
            let b: Vec<f64> = best.iter().map(|x| x.clamp(0.0, 1.0)).collect();
            let c = chi2(&residuals_at(fwd, &b));
            if c <= chi2_global {
                u = b;
                chi2_final = c;
            }
        }
        log(&format!("local phase (trust region, Gauss-Newton Hessian, {local_iters} iterations, {local_stop}): chi2 = {chi2_final:.6e}"));
    }
    Ok(Optimum { u, chi2_global, chi2: chi2_final, swarm_iterations: swarm_iters, local_iterations: local_iters, local_stop, local_history })
}

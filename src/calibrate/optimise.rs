//! The optimisers, all from the `argmin` crate, in unit coordinates u ∈ [0, 1]ⁿ (see [`super::params`]):
//!
//! 1. global: particle swarm ([`ParticleSwarm`], seeded `Xoshiro256PlusPlus`) on χ²(u); each
//!    iteration's particles go to the forward model as one batch (argmin's `bulk_cost`);
//! 2. local, one of
//!    - `trust_region` (default): trust region ([`TrustRegion`] with the [`Steihaug`] CG
//!      subproblem) on `f(u) = ½ χ²(u)` with gradient `Jᵀr` and the Gauss–Newton Hessian `JᵀJ`,
//!      J the forward finite-difference Jacobian of the residual vector r(u) (its n points one
//!      batch): a Levenberg–Marquardt-type method. It stops after `stall` iterations in a row that
//!      lower f by less than `tolerance·f` ([`Stall`], a stopping rule around argmin's solver);
//!    - `nelder_mead`: argmin's [`NelderMead`] on the same f from a simplex of u and u + s·eᵢ
//!      (s = `simplex_scale`, the n + 1 vertices one batch), stopping when the standard deviation
//!      of χ² over the vertices falls below `simplex_tolerance` (argmin's rule).
//!
//!    Both keep the bound box by evaluating r at clamp(u) plus a quadratic penalty
//!    `½·w·|u − clamp(u)|²` outside it.
//!
//! Every evaluation goes through the [`Evaluator`] (memo, batches). Determinism: the swarm's random
//! numbers come from one seeded generator in a fixed order, every evaluation is deterministic (see
//! [`super::forward`], [`super::compact`]), and batches are collected in order; results do not
//! depend on the number of threads of the optimiser.

use super::loss::chi2;
use super::model::Evaluator;
use crate::error::Error;
use argmin::core::{
    CostFunction, Error as ArgminError, Executor, Gradient, Hessian, IterState, KV, Problem, SendAlias, Solver, State, SyncAlias, TerminationReason,
    TerminationStatus,
};
use argmin::solver::neldermead::NelderMead;
use argmin::solver::particleswarm::ParticleSwarm;
use argmin::solver::trustregion::{Steihaug, TrustRegion};
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::sync::Mutex;

/// Weight of the bound penalty of the local phase [1].
const BOUND_WEIGHT: f64 = 1.0e6;

/// The method of the local phase (`optimiser.local`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LocalMethod {
    /// Trust region with the Gauss–Newton Hessian (`trust_region`, default).
    TrustRegion,
    /// Nelder–Mead simplex (`nelder_mead`).
    NelderMead,
}

impl LocalMethod {
    /// The name in calibration files.
    pub fn name(self) -> &'static str {
        match self {
            LocalMethod::TrustRegion => "trust_region",
            LocalMethod::NelderMead => "nelder_mead",
        }
    }
}

/// Optimiser settings (`[optimiser]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Particles of the swarm.
    pub swarm_size: usize,
    /// Swarm iterations (0: no global phase; the local phase starts from the starting material).
    pub swarm_iterations: u64,
    /// Largest number of local iterations.
    pub local_iterations: u64,
    /// Trust region: relative decrease of ½χ² below which an iteration counts as stalled [1].
    pub tolerance: f64,
    /// Trust region: stalled iterations in a row that end the local phase.
    pub stall: u64,
    /// Finite-difference step in unit coordinates [1].
    pub fd_step: f64,
    /// Seed of the swarm.
    pub seed: u64,
    /// Method of the local phase.
    pub local: LocalMethod,
    /// Nelder–Mead: edge of the initial simplex in unit coordinates [1].
    pub simplex_scale: f64,
    /// Nelder–Mead: standard deviation of χ² over the simplex below which it stops [1].
    pub simplex_tolerance: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            swarm_size: 16,
            swarm_iterations: 25,
            local_iterations: 50,
            tolerance: 1e-8,
            stall: 4,
            fd_step: 1e-4,
            seed: 1,
            local: LocalMethod::TrustRegion,
            simplex_scale: 0.05,
            simplex_tolerance: 1e-6,
        }
    }
}

fn clamped(u: &[f64]) -> Vec<f64> {
    u.iter().map(|x| x.clamp(0.0, 1.0)).collect()
}

/// Residual vector r at unit coordinates (clamped); `label` names the batch if it must run.
pub fn residuals_at(ev: &Evaluator, u: &[f64], label: &str) -> Result<Vec<f64>, Error> {
    Ok(ev.residuals(&[clamped(u)], label)?.remove(0))
}

/// The finite-difference points around `u` ∈ [0,1]ⁿ with step `h`: forward (n points
/// u + sᵢeᵢ, sᵢ = h, or −h where u + h leaves the box) or central (2n points, u − h eᵢ and
/// u + h eᵢ for each i, each clamped to the box).
pub fn fd_points(u: &[f64], h: f64, central: bool) -> Vec<Vec<f64>> {
    let uc = clamped(u);
    let at = |i: usize, x: f64| {
        let mut a = uc.clone();
        a[i] = x;
        a
    };
    let mut out = Vec::new();
    for i in 0..uc.len() {
        if central {
            out.push(at(i, (uc[i] - h).max(0.0)));
            out.push(at(i, (uc[i] + h).min(1.0)));
        } else {
            out.push(at(i, if uc[i] + h <= 1.0 { uc[i] + h } else { uc[i] - h }));
        }
    }
    out
}

/// Finite-difference Jacobian ∂r/∂u (m rows of n) at `u` ∈ [0,1]ⁿ with step `h`: central
/// `(r(u + h eᵢ) − r(u − h eᵢ))/2h` (2n evaluations, one-sided at a bound) when `r0` is None, else
/// forward `(r(u ± h eᵢ) − r0)/±h` from the known `r0 = r(u)` (n evaluations, backward at the upper
/// bound). The points run as one batch (`label`) and are collected in order.
pub fn jacobian(ev: &Evaluator, u: &[f64], h: f64, r0: Option<&[f64]>, label: &str) -> Result<Vec<Vec<f64>>, Error> {
    let uc = clamped(u);
    let pts = fd_points(&uc, h, r0.is_none());
    let rs = ev.residuals(&pts, label)?;
    let n = uc.len();
    let cols: Vec<Vec<f64>> = (0..n)
        .map(|i| match r0 {
            Some(r0) => {
                let step = pts[i][i] - uc[i];
                rs[i].iter().zip(r0).map(|(y, x)| (y - x) / step).collect()
            }
            None => {
                let (lo, hi) = (&pts[2 * i], &pts[2 * i + 1]);
                let d = hi[i] - lo[i];
                rs[2 * i].iter().zip(&rs[2 * i + 1]).map(|(a, b)| (b - a) / d).collect()
            }
        })
        .collect();
    let m = cols.first().map(|c| c.len()).unwrap_or(0);
    Ok((0..m).map(|k| (0..n).map(|i| cols[i][k]).collect()).collect())
}

/// A point u with its residuals r and, once computed, its Jacobian J.
type Cached = Option<(Vec<f64>, Vec<f64>, Option<Vec<Vec<f64>>>)>;

/// Keeps the first error of the forward model (a batch that could not run at all) while argmin,
/// which only knows its own error type, unwinds.
#[derive(Default)]
struct Fatal(Mutex<Option<Error>>);

impl Fatal {
    fn wrap<T>(&self, r: Result<T, Error>) -> Result<T, ArgminError> {
        r.map_err(|e| {
            let msg = e.to_string();
            let mut slot = self.0.lock().unwrap_or_else(|p| p.into_inner());
            if slot.is_none() {
                *slot = Some(e);
            }
            ArgminError::msg(msg)
        })
    }
    /// The forward model's error if there was one, else argmin's.
    fn take(&self, e: ArgminError) -> Error {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).take().unwrap_or_else(|| argmin_err(e).into())
    }
}

/// The calibration problem of the local phase for argmin.
struct Calib<'a> {
    ev: &'a Evaluator<'a>,
    fd_step: f64,
    /// Label of the cost evaluations' batches.
    label: &'static str,
    /// Run the forward-difference points with each new cost evaluation (trust region on a model
    /// whose batches cost latency; see [`super::model::ForwardModel::speculative_jacobian`]).
    speculative: bool,
    /// Last (u, r, J) of the local phase.
    cache: Mutex<Cached>,
    fatal: &'a Fatal,
}

impl Calib<'_> {
    fn r(&self, u: &[f64]) -> Result<Vec<f64>, ArgminError> {
        let mut c = self.cache.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((cu, r, _)) = c.as_ref()
            && cu == u
        {
            return Ok(r.clone());
        }
        let r = if self.speculative {
            // the point and its forward-difference points in one batch
            let mut pts = vec![clamped(u)];
            pts.extend(fd_points(u, self.fd_step, false));
            self.fatal.wrap(self.ev.residuals(&pts, self.label))?.remove(0)
        } else {
            self.fatal.wrap(residuals_at(self.ev, u, self.label))?
        };
        *c = Some((u.to_vec(), r.clone(), None));
        Ok(r)
    }
    fn rj(&self, u: &[f64]) -> Result<(Vec<f64>, Vec<Vec<f64>>), ArgminError> {
        let r = self.r(u)?;
        let mut c = self.cache.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, _, Some(j))) = c.as_ref() {
            return Ok((r, j.clone()));
        }
        let j = self.fatal.wrap(jacobian(self.ev, u, self.fd_step, Some(&r), "jacobian"))?;
        // out-of-box components do not move r
        let j: Vec<Vec<f64>> = j.into_iter().map(|row| row.iter().zip(u).map(|(x, ui)| if (0.0..=1.0).contains(ui) { *x } else { 0.0 }).collect()).collect();
        *c = Some((u.to_vec(), r.clone(), Some(j.clone())));
        Ok((r, j))
    }
}

fn excess(u: &[f64]) -> Vec<f64> {
    u.iter().map(|x| x - x.clamp(0.0, 1.0)).collect()
}

/// χ²(u) for the swarm; a population is one batch.
struct SwarmCost<'a> {
    ev: &'a Evaluator<'a>,
    fatal: &'a Fatal,
}

impl CostFunction for SwarmCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, u: &Vec<f64>) -> Result<f64, ArgminError> {
        Ok(chi2(&self.fatal.wrap(residuals_at(self.ev, u, "swarm"))?))
    }
    /// The whole population as one batch of the forward model.
    fn bulk_cost<P>(&self, params: &[P]) -> Result<Vec<f64>, ArgminError>
    where
        P: std::borrow::Borrow<Self::Param> + SyncAlias,
        Self::Output: SendAlias,
        Self: SyncAlias,
    {
        let us: Vec<Vec<f64>> = params.iter().map(|p| clamped(p.borrow())).collect();
        Ok(self.fatal.wrap(self.ev.residuals(&us, "swarm"))?.iter().map(|r| chi2(r)).collect())
    }
}

impl CostFunction for Calib<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    /// f(u) = ½ χ²(clamp u) + ½ w |u − clamp u|².
    fn cost(&self, u: &Vec<f64>) -> Result<f64, ArgminError> {
        let pen: f64 = excess(u).iter().map(|e| e * e).sum();
        Ok(0.5 * chi2(&self.r(u)?) + 0.5 * BOUND_WEIGHT * pen)
    }
}

impl Gradient for Calib<'_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    /// ∇f = Jᵀr + w (u − clamp u).
    fn gradient(&self, u: &Vec<f64>) -> Result<Vec<f64>, ArgminError> {
        let (r, j) = self.rj(u)?;
        let ex = excess(u);
        Ok((0..u.len()).map(|i| j.iter().zip(&r).map(|(row, rk)| row[i] * rk).sum::<f64>() + BOUND_WEIGHT * ex[i]).collect())
    }
}

impl Hessian for Calib<'_> {
    type Param = Vec<f64>;
    type Hessian = Vec<Vec<f64>>;
    /// Gauss–Newton Hessian JᵀJ (+ w on the diagonal of out-of-box components).
    fn hessian(&self, u: &Vec<f64>) -> Result<Vec<Vec<f64>>, ArgminError> {
        let (_, j) = self.rj(u)?;
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

/// A stopping rule around an argmin solver: stop when the inner solver's own rule says so, after
/// `stall` iterations in a row whose cost decrease is below `tol·cost`, or when the cost is
/// exactly zero. Records the cost after every iteration.
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
        let inner = self.inner.terminate(state);
        if inner.terminated() {
            return inner;
        }
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
pub fn optimise(ev: &Evaluator, u0: &[f64], s: &Settings, log: &mut dyn FnMut(&str)) -> Result<Optimum, Error> {
    let n = u0.len();
    let (mut u, mut chi2_global, mut swarm_iters) = (u0.to_vec(), chi2(&residuals_at(ev, u0, "start")?), 0);
    if s.swarm_iterations > 0 {
        let fatal = Fatal::default();
        let pso = ParticleSwarm::new((vec![0.0; n], vec![1.0; n]), s.swarm_size).with_rng_generator(Xoshiro256PlusPlus::seed_from_u64(s.seed));
        let res = Executor::new(SwarmCost { ev, fatal: &fatal }, pso).configure(|st| st.max_iters(s.swarm_iterations)).run();
        let res = res.map_err(|e| fatal.take(e))?;
        let st = res.state();
        swarm_iters = st.get_iter();
        if let Some(best) = st.get_best_param()
            && best.cost < chi2_global
        {
            u = clamped(&best.position);
            chi2_global = best.cost;
        }
        log(&format!("global phase (particle swarm, {} particles, {swarm_iters} iterations): chi2 = {chi2_global:.6e}", s.swarm_size));
    }
    let mut chi2_final = chi2_global;
    let mut local_iters = 0;
    let mut local_stop = "not run".to_string();
    let mut local_history = Vec::new();
    if s.local_iterations > 0 {
        let fatal = Fatal::default();
        // Nelder-Mead uses no Jacobian: nothing to run ahead for it
        let speculative = s.local == LocalMethod::TrustRegion && ev.model.speculative_jacobian();
        let problem = Calib { ev, fd_step: s.fd_step, label: "local", speculative, cache: Mutex::new(None), fatal: &fatal };
        let (best, history, iters, stop) = match s.local {
            LocalMethod::TrustRegion => {
                let tr = TrustRegion::new(Steihaug::new().with_max_iters(10 * n as u64 + 10))
                    .with_radius(0.05)
                    .and_then(|t| t.with_max_radius(1.0))
                    .map_err(argmin_err)?;
                let solver = Stall { inner: tr, tol: s.tolerance, stall: s.stall, last: f64::INFINITY, count: 0, history: Vec::new() };
                let res = Executor::new(problem, solver).configure(|st| st.param(u.clone()).max_iters(s.local_iterations)).run();
                let res = res.map_err(|e| fatal.take(e))?;
                let st = res.state();
                let stop = st.get_termination_reason().map(|r| r.text().to_string()).unwrap_or_else(|| "unknown".into());
                (st.get_best_param().cloned(), res.solver.history.clone(), st.get_iter(), stop)
            }
            LocalMethod::NelderMead => {
                // u and u + s eᵢ (− s eᵢ where that leaves the box): the n + 1 vertices as one batch
                let mut simplex = vec![u.clone()];
                for i in 0..n {
                    let mut v = u.clone();
                    v[i] = if u[i] + s.simplex_scale <= 1.0 { u[i] + s.simplex_scale } else { u[i] - s.simplex_scale };
                    simplex.push(v);
                }
                ev.residuals(&simplex, "simplex")?;
                let nm = NelderMead::new(simplex).with_sd_tolerance(0.5 * s.simplex_tolerance).map_err(argmin_err)?;
                // the simplex's own rule (and the iteration limit) ends it, not the stall count
                let solver = Stall { inner: nm, tol: s.tolerance, stall: u64::MAX, last: f64::INFINITY, count: 0, history: Vec::new() };
                let res = Executor::new(problem, solver).configure(|st| st.max_iters(s.local_iterations)).run();
                let res = res.map_err(|e| fatal.take(e))?;
                let st = res.state();
                let stop = st.get_termination_reason().map(|r| r.text().to_string()).unwrap_or_else(|| "unknown".into());
                (st.get_best_param().cloned(), res.solver.history.clone(), st.get_iter(), stop)
            }
        };
        local_history = history.iter().map(|c| 2.0 * c).collect();
        local_iters = iters;
        local_stop = stop;
        if let Some(best) = best {
            let b = clamped(&best);
            let c = chi2(&residuals_at(ev, &b, "local")?);
            if c <= chi2_global {
                u = b;
                chi2_final = c;
            }
        }
        let what = match s.local {
            LocalMethod::TrustRegion => "trust region, Gauss-Newton Hessian",
            LocalMethod::NelderMead => "Nelder-Mead",
        };
        log(&format!("local phase ({what}, {local_iters} iterations, {local_stop}): chi2 = {chi2_final:.6e}"));
    }
    Ok(Optimum { u, chi2_global, chi2: chi2_final, swarm_iterations: swarm_iters, local_iterations: local_iters, local_stop, local_history })
}

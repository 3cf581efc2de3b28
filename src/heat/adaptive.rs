//! Error-controlled time steps of the heat network (heat-model.md "Error control", eqs. E1–E4).
//!
//! The local error of a step from t_n to t_{n+1} = t_n + h is estimated by comparing its result
//! y with the polynomial extrapolation P of degree p through the last p+1 accepted points
//! (p the order of the step). Both differ from the exact solution by multiples of y^{(p+1)}:
//! `y − y(t_{n+1}) = E y^{(p+1)}` (the step's own error) and `y(t_{n+1}) − P = D y^{(p+1)}`
//! (the extrapolation's), so `e = E/(E + D) (y − P)` (eq. E1) with
//! - backward Euler (p = 1): `E = h²/2`, `D = h(h + h₁)/2`;
//! - Crank–Nicolson (p = 2): `E = h³/12`;
//! - BDF2 (p = 2, ω = h/h₁): `E = (1+ω)² h³ / (6ω(1+2ω))`;
//! - p = 2: `D = h(h + h₁)(h + h₁ + h₂)/6` (eq. E2).
//!
//! With fewer points the first-order estimate is used (conservative for a second-order step), and
//! with the start point only, the predictor `P = y_n + h ẏ_n` (`e = (y − P)/2`).
//! Step control (eq. E3): accept when `max_i |e_i| ≤ tol`, then
//! `h_new = h · clamp(0.9 (tol/est)^{1/(q+1)}, 0.2, 2)` with q the order of the estimate
//! (q + 1 = 2 for backward Euler, 3 for BDF2 and Crank–Nicolson); otherwise reject and retry
//! with the same formula (factor ≤ 1).

use crate::error::SolveError;
use crate::heat::{HeatNetwork, HeatStepInfo, PipeConductance, Scheme};

/// Step-control settings of the heat network [K, s].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepControl {
    /// Local error tolerance per step, max over free particles [K].
    pub tolerance: f64,
    /// Smallest step [s]: a step at dt_min is accepted whatever its estimate (and counted).
    pub dt_min: f64,
    /// Largest step [s].
    pub dt_max: f64,
}

/// Safety factor of eq. E3 [1].
pub const SAFETY: f64 = 0.9;
/// Largest growth of the step per accepted step [1].
pub const GROW_MAX: f64 = 2.0;
/// Largest shrink per step [1].
pub const SHRINK_MIN: f64 = 0.2;

impl StepControl {
    /// The factor h_new/h for an estimate `est` [K] of order `q` (eq. E3).
    pub fn factor(&self, est: f64, q: u32) -> f64 {
        if !(est > 0.0) {
            return GROW_MAX;
        }
        (SAFETY * (self.tolerance / est).powf(1.0 / (q as f64 + 1.0))).clamp(SHRINK_MIN, GROW_MAX)
    }
}

/// An error estimate [K] and the order q of the method it measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub error: f64,
    pub order: u32,
}

/// Eqs. E1–E2: local error of the step that produced `y` at `t1` from the accepted points
/// `(times, values)` (oldest first, the last one the step's start). `bdf2_step`: the step was a
/// BDF2 step (the network had history); `ydot` the start's dT/dt [K/s], used when only the start
/// point is known. `free(i)`: whether particle i is a free unknown. `None`: nothing to compare.
pub fn estimate(
    scheme: Scheme,
    bdf2_step: bool,
    times: &[f64],
    values: &[&[f64]],
    t1: f64,
    y: &[f64],
    ydot: Option<&[f64]>,
    free: impl Fn(usize) -> bool,
) -> Option<Estimate> {
    let m = times.len();
    let tn = *times.last()?;
    let h = t1 - tn;
    if !(h > 0.0) {
        return None;
    }
    let p = match scheme {
        Scheme::BackwardEuler => 1,
        Scheme::CrankNicolson => 2,
        Scheme::Bdf2 => {
            if bdf2_step {
                2
            } else {
                1
            }
        }
    };
    let max_over = |f: &dyn Fn(usize) -> f64| (0..y.len()).filter(|&i| free(i)).map(f).fold(0.0, f64::max);
    if p == 2 && m >= 3 {
        let (t0, t_1, t_2) = (times[m - 1], times[m - 2], times[m - 3]);
        let (h1, h2) = (t0 - t_1, t_1 - t_2);
        let e = match scheme {
            Scheme::CrankNicolson => h.powi(3) / 12.0,
            _ => {
                let om = h / h1;
                (1.0 + om).powi(2) * h.powi(3) / (6.0 * om * (1.0 + 2.0 * om))
            }
        };
        let d = h * (h + h1) * (h + h1 + h2) / 6.0;
        let c = e / (e + d);
        // Lagrange extrapolation through (t_2, t_1, t0) to t1
        let l0 = (t1 - t_1) * (t1 - t_2) / ((t0 - t_1) * (t0 - t_2));
        let l1 = (t1 - t0) * (t1 - t_2) / ((t_1 - t0) * (t_1 - t_2));
        let l2 = (t1 - t0) * (t1 - t_1) / ((t_2 - t0) * (t_2 - t_1));
        let (v0, v1, v2) = (values[m - 1], values[m - 2], values[m - 3]);
        let err = max_over(&|i| c * (y[i] - (l0 * v0[i] + l1 * v1[i] + l2 * v2[i])).abs());
        return Some(Estimate { error: err, order: 2 });
    }
    if m >= 2 {
        let h1 = tn - times[m - 2];
        let (v0, v1) = (values[m - 1], values[m - 2]);
        let c = h / (2.0 * h + h1);
        let err = max_over(&|i| c * (y[i] - (v0[i] + h * (v0[i] - v1[i]) / h1)).abs());
        return Some(Estimate { error: err, order: 1 });
    }
    let yd = ydot?;
    let v0 = values[m - 1];
    let err = max_over(&|i| 0.5 * (y[i] - (v0[i] + h * yd[i])).abs());
    Some(Estimate { error: err, order: 1 })
}

/// Accumulates the report of several substeps into one.
pub fn add_info(total: &mut HeatStepInfo, s: &HeatStepInfo) {
    total.heat_in += s.heat_in;
    total.stored_change += s.stored_change;
    total.stored_change_plain += s.stored_change_plain;
    total.iterations = total.iterations.max(s.iterations);
    total.reused_factor = s.reused_factor;
    total.assemble_seconds += s.assemble_seconds;
    total.symbolic_seconds += s.symbolic_seconds;
    let f = total.solve.factor_seconds + s.solve.factor_seconds;
    let sv = total.solve.solve_seconds + s.solve.solve_seconds;
    total.solve = s.solve;
    total.solve.factor_seconds = f;
    total.solve.solve_seconds = sv;
}

/// Substep counts of one [`advance`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Substeps {
    pub accepted: usize,
    pub rejected: usize,
}

/// The coupled loop's heat stage: advances `temps` from `t0` by `dt` [s]. Without `control`, one
/// step (as before). With it, the step is tried whole and subdivided while its estimate exceeds
/// the tolerance (eq. E3), the substeps bounded by `[control.dt_min, dt]`; the history for the
/// estimate is the network's BDF2 point and the substeps of this call.
pub fn advance(
    net: &mut HeatNetwork,
    t0: f64,
    dt: f64,
    temps: &mut [f64],
    pipes: &[PipeConductance],
    control: Option<StepControl>,
) -> Result<(HeatStepInfo, Substeps), SolveError> {
    let Some(ctrl) = control else {
        return Ok((net.step_pipes(t0, dt, temps, pipes)?, Substeps { accepted: 1, rejected: 0 }));
    };
    let t1 = t0 + dt;
    let mut times = Vec::new();
    let mut values: Vec<Vec<f64>> = Vec::new();
    if let Some((tp, dtp)) = net.history() {
        times.push(t0 - dtp);
        values.push(tp.clone());
    }
    times.push(t0);
    values.push(temps.to_vec());
    let mut total = HeatStepInfo::default();
    let mut count = Substeps::default();
    let (mut t, mut h) = (t0, dt);
    while t < t1 - 1e-12 * dt {
        let left = t1 - t;
        let hh = if h >= left * (1.0 - 1e-12) { left } else { h };
        let saved_hist = net.history().cloned();
        let saved = temps.to_vec();
        let ydot = (times.len() == 1).then(|| net.rate_of_change(t, temps, pipes));
        let bdf2 = net.scheme() == Scheme::Bdf2 && saved_hist.is_some();
        let info = match net.step_pipes(t, hh, temps, pipes) {
            Ok(i) => i,
            Err(e) if hh > ctrl.dt_min => {
                // a failed solve (radiation or property iteration) on a long step: shorter
                temps.copy_from_slice(&saved);
                net.set_history(saved_hist);
                count.rejected += 1;
                h = (hh * SHRINK_MIN).max(ctrl.dt_min);
                let _ = e;
                continue;
            }
            Err(e) => return Err(e),
        };
        let vals: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
        let est = estimate(net.scheme(), bdf2, &times, &vals, t + hh, temps, ydot.as_deref(), |i| !net.is_fixed(i));
        if let Some(e) = est
            && e.error > ctrl.tolerance
            && hh > ctrl.dt_min * (1.0 + 1e-9)
        {
            temps.copy_from_slice(&saved);
            net.set_history(saved_hist);
            count.rejected += 1;
            h = (hh * ctrl.factor(e.error, e.order).min(1.0)).max(ctrl.dt_min);
            continue;
        }
        add_info(&mut total, &info);
        count.accepted += 1;
        t += hh;
        times.push(t);
        values.push(temps.to_vec());
        if times.len() > 3 {
            times.remove(0);
            values.remove(0);
        }
        h = match est {
            Some(e) => (hh * ctrl.factor(e.error, e.order)).clamp(ctrl.dt_min, ctrl.dt_max),
            None => hh,
        };
    }
    Ok((total, count))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimators against the exact local error of y' = −λ y (one free particle, no pipes):
    /// the ratio estimate/actual tends to 1 as h → 0, for every scheme and unequal steps.
    #[test]
    fn estimates_match_the_exact_local_error() {
        use crate::heat::HeatSources;
        let lam = 1.0; // C = 1 J/K, K = 1 W/K to a Dirichlet particle at 0 K... use an exponential decay
        for scheme in [Scheme::BackwardEuler, Scheme::CrankNicolson, Scheme::Bdf2] {
            let mut ratios = Vec::new();
            for h in [0.02, 0.01, 0.005] {
                // pair: free particle 0 (C = 1) tied to particle 1 held at 0 K... temperatures must be
                // positive: hold at 100 K, start at 200 K; T − 100 decays as exp(−λ t)
                let sources =
                    HeatSources { fixed: vec![None, Some(0)], profiles: vec![crate::profile::Profile::constant(100.0).unwrap()], ..Default::default() };
                let mut net = HeatNetwork::new(vec![1.0, 1.0], sources, scheme, 1e-12);
                net.set_topology(&[[0, 1]]).unwrap();
                let pipes = [PipeConductance { half_i: 2.0 * lam, half_j: 2.0 * lam, pair: lam, boundary: 0.0 }];
                let exact = |t: f64| 100.0 + 100.0 * (-lam * t).exp();
                // three exact history points with unequal spacing, then one step of size h
                let ts = [0.0, 0.7 * h, 1.5 * h, 2.5 * h];
                let hist: Vec<Vec<f64>> = ts[..3].iter().map(|&t| vec![exact(t), 100.0]).collect();
                net.set_history(Some((hist[1].clone(), ts[2] - ts[1])));
                let mut y = hist[2].clone();
                net.step_pipes(ts[2], ts[3] - ts[2], &mut y, &pipes).unwrap();
                let vals: Vec<&[f64]> = hist.iter().map(|v| v.as_slice()).collect();
                let est = estimate(scheme, true, &ts[..3], &vals, ts[3], &y, None, |i| i == 0).unwrap();
                ratios.push(est.error / (y[0] - exact(ts[3])).abs());
            }
            let last = ratios[ratios.len() - 1];
            assert!((last - 1.0).abs() < 0.05, "{scheme:?}: estimate/actual {ratios:?}");
        }
    }
}

//! Small fixed-size adaptive ODE integrators for per-contact models (docs/diffusion7.md §7).
//!
//! - [`Method::Dopri5`]: Dormand–Prince 5(4) with FSAL and local extrapolation (Hairer, Nørsett,
//!   Wanner, *Solving ODEs I*, II.4–5); the default (measured, `docs/decisions-diffusion7.md`).
//! - [`Method::Rk4Doubling`]: classical RK4, error by step doubling (Richardson, 1/15), the
//!   paper's option ([IV22] §2).
//! - [`Method::Rosenbrock4`]: a 4-stage L-stable Rosenbrock method of order 4(3) (Shampine's
//!   parameters of the Kaps–Rentrop family) with a finite-difference Jacobian and ∂f/∂t, for stiff
//!   states.
//!
//! Error norm (docs/diffusion7.md (T1)): `e = max_i |err_i| / (rtol·max(|y_i|, |y_new,i|, floor_i))`; a step is
//! accepted when `e ≤ 1`. A right-hand side that fails (inadmissible trial state) rejects the step
//! and quarters it. The ModelError rule of §7: a step proposed by the error control below
//! `min_step_rel·t` (t = the contact's own time, its age) stops the integration with an error, as do
//! a step that no longer advances t and more than `max_substeps` substeps.

use crate::error::ModelError;
use serde::{Deserialize, Serialize};

/// Integration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Dormand–Prince 5(4), explicit.
    #[default]
    Dopri5,
    /// Classical RK4 with step doubling.
    Rk4Doubling,
    /// Rosenbrock 4(3), linearly implicit.
    Rosenbrock4,
}

impl Method {
    /// All methods, for benchmarks.
    pub const ALL: [Method; 3] = [Method::Dopri5, Method::Rk4Doubling, Method::Rosenbrock4];

    /// Case-file name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Dopri5 => "dopri5",
            Method::Rk4Doubling => "rk4_doubling",
            Method::Rosenbrock4 => "rosenbrock4",
        }
    }

    /// Exponent of the step-size controller (1 / (order of the error estimate + 1)).
    fn exponent(self) -> f64 {
        match self {
            Method::Dopri5 | Method::Rk4Doubling => 0.2,
            Method::Rosenbrock4 => 0.25,
        }
    }
}

/// Step control of one integration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Control<const N: usize> {
    pub method: Method,
    /// Relative tolerance [1] ((T1) `rtol`).
    pub rtol: f64,
    /// Per-component floor of the scale, in the units of y ((T1): 1e-4·R_min).
    pub floor: [f64; N],
    /// Largest substep [s].
    pub h_max: f64,
    /// ModelError when the controller proposes a step below `min_step_rel · t` (docs/diffusion7.md §7: 1e-12).
    pub min_step_rel: f64,
    /// ModelError after this many substeps in one call.
    pub max_substeps: u64,
    /// A trial step (docs/coupled.md (S1), strategy 1): the first rejected step ends the call with the
    /// ModelError [`STEP_REJECTED`] instead of retrying with a smaller step.
    pub stop_on_reject: bool,
}

/// Message of the ModelError that ends a [`Control::stop_on_reject`] call at a rejected step.
pub const STEP_REJECTED: &str = "trial step rejected by the error control (e > 1)";

/// Work counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct OdeStats {
    /// Accepted steps.
    pub steps: u64,
    /// Rejected steps (error too large or inadmissible trial state).
    pub rejected: u64,
    /// Right-hand-side evaluations (including those of finite-difference Jacobians).
    pub rhs: u64,
    /// Jacobian evaluations / LU factorisations.
    pub jacobians: u64,
    /// Intervals not integrated because the contact cannot change within the tolerance over
    /// them (docs/diffusion7.md (T2)); their one evaluation of the bound is counted in `rhs`.
    #[serde(default)]
    pub skipped: u64,
}

impl OdeStats {
    pub fn add(&mut self, o: &OdeStats) {
        self.steps += o.steps;
        self.rejected += o.rejected;
        self.rhs += o.rhs;
        self.jacobians += o.jacobians;
        self.skipped += o.skipped;
    }
}

// Dormand–Prince 5(4) tableau.
pub(crate) const C2: f64 = 1.0 / 5.0;
pub(crate) const C3: f64 = 3.0 / 10.0;
pub(crate) const C4: f64 = 4.0 / 5.0;
pub(crate) const C5: f64 = 8.0 / 9.0;
pub(crate) const A21: f64 = 1.0 / 5.0;
pub(crate) const A31: f64 = 3.0 / 40.0;
pub(crate) const A32: f64 = 9.0 / 40.0;
pub(crate) const A41: f64 = 44.0 / 45.0;
pub(crate) const A42: f64 = -56.0 / 15.0;
pub(crate) const A43: f64 = 32.0 / 9.0;
pub(crate) const A51: f64 = 19372.0 / 6561.0;
pub(crate) const A52: f64 = -25360.0 / 2187.0;
pub(crate) const A53: f64 = 64448.0 / 6561.0;
pub(crate) const A54: f64 = -212.0 / 729.0;
pub(crate) const A61: f64 = 9017.0 / 3168.0;
pub(crate) const A62: f64 = -355.0 / 33.0;
pub(crate) const A63: f64 = 46732.0 / 5247.0;
pub(crate) const A64: f64 = 49.0 / 176.0;
pub(crate) const A65: f64 = -5103.0 / 18656.0;
pub(crate) const A71: f64 = 35.0 / 384.0;
pub(crate) const A73: f64 = 500.0 / 1113.0;
pub(crate) const A74: f64 = 125.0 / 192.0;
pub(crate) const A75: f64 = -2187.0 / 6784.0;
pub(crate) const A76: f64 = 11.0 / 84.0;
pub(crate) const E1: f64 = 71.0 / 57600.0;
pub(crate) const E3: f64 = -71.0 / 16695.0;
pub(crate) const E4: f64 = 71.0 / 1920.0;
pub(crate) const E5: f64 = -17253.0 / 339200.0;
pub(crate) const E6: f64 = 22.0 / 525.0;
pub(crate) const E7: f64 = -1.0 / 40.0;

// Rosenbrock 4(3), Shampine's parameter set (Kaps–Rentrop form).
const RGAM: f64 = 0.5;
const RA21: f64 = 2.0;
const RA31: f64 = 48.0 / 25.0;
const RA32: f64 = 6.0 / 25.0;
const RC21: f64 = -8.0;
const RC31: f64 = 372.0 / 25.0;
const RC32: f64 = 12.0 / 5.0;
const RC41: f64 = -112.0 / 125.0;
const RC42: f64 = -54.0 / 125.0;
const RC43: f64 = -2.0 / 5.0;
const RB1: f64 = 19.0 / 9.0;
const RB2: f64 = 1.0 / 2.0;
const RB3: f64 = 25.0 / 108.0;
const RB4: f64 = 125.0 / 108.0;
const RE1: f64 = 17.0 / 54.0;
const RE2: f64 = 7.0 / 36.0;
const RE3: f64 = 0.0;
const RE4: f64 = 125.0 / 108.0;
const RC1X: f64 = 1.0 / 2.0;
const RC2X: f64 = -3.0 / 2.0;
const RC3X: f64 = 121.0 / 50.0;
const RC4X: f64 = 29.0 / 250.0;
const RA2X: f64 = 1.0;
const RA3X: f64 = 3.0 / 5.0;

#[inline]
fn lin<const N: usize>(y: &[f64; N], terms: &[(f64, &[f64; N])]) -> [f64; N] {
    let mut out = *y;
    for (c, k) in terms {
        if *c != 0.0 {
            for i in 0..N {
                out[i] += c * k[i];
            }
        }
    }
    out
}

/// Error norm (T1), max over components.
#[inline]
pub(crate) fn err_norm<const N: usize>(err: &[f64; N], y0: &[f64; N], y1: &[f64; N], ctl: &Control<N>) -> f64 {
    let mut e: f64 = 0.0;
    for i in 0..N {
        let sc = ctl.rtol * y0[i].abs().max(y1[i].abs()).max(ctl.floor[i]);
        e = e.max((err[i] / sc).abs());
    }
    if e.is_nan() { f64::INFINITY } else { e }
}

/// Starting step (Hairer–Nørsett–Wanner II.4, scipy's `select_initial_step`), RMS norm with the
/// (T1) scale.
pub(crate) fn initial_step<const N: usize, F>(
    f: &mut F,
    t0: f64,
    y0: &[f64; N],
    f0: &[f64; N],
    ctl: &Control<N>,
    order: f64,
    span: f64,
    stats: &mut OdeStats,
) -> f64
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
{
    let sc: Vec<f64> = (0..N).map(|i| ctl.rtol * y0[i].abs().max(ctl.floor[i])).collect();
    let rms = |v: &[f64; N]| ((0..N).map(|i| (v[i] / sc[i]).powi(2)).sum::<f64>() / N as f64).sqrt();
    let d0 = rms(y0);
    let d1 = rms(f0);
    let mut h0 = if d0 < 1e-5 || d1 < 1e-5 { 1e-6 } else { 0.01 * d0 / d1 };
    h0 = h0.min(span).min(ctl.h_max);
    let y1 = lin(y0, &[(h0, f0)]);
    stats.rhs += 1;
    let d2 = match f(t0 + h0, &y1) {
        Ok(f1) => {
            let mut df = [0.0; N];
            for i in 0..N {
                df[i] = f1[i] - f0[i];
            }
            rms(&df) / h0
        }
        Err(_) => return h0 * 1e-3,
    };
    let h1 = if d1 <= 1e-15 && d2 <= 1e-15 { (h0 * 1e-3).max(1e-6 * h0) } else { (0.01 / d1.max(d2)).powf(1.0 / (order + 1.0)) };
    (100.0 * h0).min(h1).min(span).min(ctl.h_max)
}

/// Step-size factor after an accepted step with error norm `e` (T1) [1]: 0.9·e^(−1/(q+1)), within
/// [0.2, 5].
#[inline]
pub(crate) fn accepted_factor(method: Method, e: f64) -> f64 {
    // below `CLAMPED_AT_5` the factor is the upper clamp whatever the exponent (0.9·e^(−1/4) ≥
    // 0.9·e^(−1/5) > 5 there): the same value without the power, which the coupled sweep's
    // single easy steps would otherwise spend a good part of their step control on
    if e < CLAMPED_AT_5 { 5.0 } else { (0.9 * e.powf(-method.exponent())).clamp(0.2, 5.0) }
}

/// Error norms below this give the factor 5 of [`accepted_factor`] for every method [1]:
/// 0.9·(1.8e-4)^(−1/5) = 5.04 > 5 (and the exponent 1/4 gives more).
const CLAMPED_AT_5: f64 = 1.8e-4;

/// Step-size factor after a step rejected with error norm `e` [1]: 0.9·e^(−1/(q+1)) within
/// [0.1, 0.9], or 0.25 when `e` is not finite.
#[inline]
pub(crate) fn rejected_factor(method: Method, e: f64) -> f64 {
    if e.is_finite() { (0.9 * e.powf(-method.exponent())).clamp(0.1, 0.9) } else { 0.25 }
}

/// The substep proposed after an accepted `step` [s] with factor `fac`: a step shortened to land
/// on the interval end (`truncated`) keeps the controller's earlier proposal `hh` [s] unless the
/// error asks for less; never above `h_max` [s].
#[inline]
pub(crate) fn proposal_after_accept(step: f64, fac: f64, truncated: bool, hh: f64, h_max: f64) -> f64 {
    let proposal = (step * fac).min(h_max);
    if truncated && fac >= 1.0 { hh.max(proposal).min(h_max) } else { proposal }
}

/// Integrates `y' = f(t, y)` from `t0` to `t1` (own time of the contact, `t0 ≥ 0`), starting with
/// the step `*h` (≤ 0: estimated). On return `*h` is the step proposed for the continuation.
/// `on_step(t, y)` is called after every accepted step.
pub fn integrate<const N: usize, F, G>(
    f: &mut F,
    t0: f64,
    t1: f64,
    y0: [f64; N],
    h: &mut f64,
    ctl: &Control<N>,
    stats: &mut OdeStats,
    mut on_step: G,
) -> Result<[f64; N], ModelError>
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
    G: FnMut(f64, &[f64; N]),
{
    let go_on = |t: f64, y: &[f64; N]| {
        on_step(t, y);
        true
    };
    integrate_while(f, t0, t1, y0, h, ctl, stats, go_on).map(|(y, _)| y)
}

/// [`integrate`] whose `on_step(t, y)` returns whether to go on: `false` ends the integration
/// after that accepted step. Returns the state and whether `t1` was reached.
pub fn integrate_while<const N: usize, F, G>(
    f: &mut F,
    t0: f64,
    t1: f64,
    y0: [f64; N],
    h: &mut f64,
    ctl: &Control<N>,
    stats: &mut OdeStats,
    mut on_step: G,
) -> Result<([f64; N], bool), ModelError>
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
    G: FnMut(f64, &[f64; N]) -> bool,
{
    if !(t1 >= t0) || !t0.is_finite() || !t1.is_finite() {
        return Err(ModelError::new(format!("integration interval [{t0}, {t1}] s is not valid")));
    }
    if !(ctl.rtol > 0.0 && ctl.rtol < 1.0) {
        return Err(ModelError::new(format!("rtol = {} must lie in (0, 1)", ctl.rtol)));
    }
    if t1 == t0 {
        return Ok((y0, true));
    }
    let mut t = t0;
    let mut y = y0;
    stats.rhs += 1;
    let mut k1 = f(t, &y).map_err(|e| e.with_context(format!("at the start of a substep, t = {t} s")))?;
    if !(*h > 0.0) || !h.is_finite() {
        let order = if ctl.method == Method::Rosenbrock4 { 3.0 } else { 4.0 };
        *h = initial_step(f, t, &y, &k1, ctl, order, t1 - t0, stats);
    }
    let mut hh = h.min(ctl.h_max);
    let mut substeps: u64 = 0;
    let mut jac: Option<([[f64; N]; N], [f64; N])> = None;
    let mut stop = false;
    while t < t1 {
        substeps += 1;
        if substeps > ctl.max_substeps {
            return Err(ModelError::new(format!("integrator gave up: more than {} substeps (stiff or singular state)", ctl.max_substeps))
                .with_context(format!("t = {t} s, h = {hh} s, y = {y:?}")));
        }
        let remaining = t1 - t;
        let truncated = hh >= remaining;
        let step = if truncated { remaining } else { hh };
        if t + step == t {
            return Err(ModelError::new("integrator gave up: step no longer advances time").with_context(format!("t = {t} s, h = {step} s, y = {y:?}")));
        }
        let trial = match ctl.method {
            Method::Dopri5 => dopri_step(f, t, &y, &k1, step, stats),
            Method::Rk4Doubling => rk4_doubling_step(f, t, &y, &k1, step, stats),
            Method::Rosenbrock4 => {
                if jac.is_none() {
                    jac = fd_jacobian(f, t, &y, &k1, ctl, step, stats);
                }
                match &jac {
                    Some((j, dfdt)) => rosenbrock_step(f, t, &y, &k1, j, dfdt, step, stats),
                    None => Err(ModelError::new("Jacobian not available")),
                }
            }
        };
        let (accepted, fac) = match trial {
            Ok((ynew, err, knext)) => {
                let e = err_norm(&err, &y, &ynew, ctl);
                if e <= 1.0 && ynew.iter().all(|v| v.is_finite()) {
                    // the next step starts from y_new: it must be admissible (FSAL stage or fresh RHS)
                    let kn = match knext {
                        Some(k) => Ok(k),
                        None => {
                            stats.rhs += 1;
                            f(t + step, &ynew)
                        }
                    };
                    match kn {
                        Ok(k) => {
                            t = if truncated { t1 } else { t + step };
                            y = ynew;
                            k1 = k;
                            jac = None;
                            stats.steps += 1;
                            stop = !on_step(t, &y);
                            (true, accepted_factor(ctl.method, e))
                        }
                        Err(_) => (false, 0.25),
                    }
                } else {
                    (false, rejected_factor(ctl.method, e))
                }
            }
            Err(_) => (false, 0.25),
        };
        if accepted {
            hh = proposal_after_accept(step, fac, truncated, hh, ctl.h_max);
            if stop {
                *h = hh;
                return Ok((y, t >= t1));
            }
        } else {
            stats.rejected += 1;
            hh = step * fac;
            if ctl.stop_on_reject {
                *h = hh;
                return Err(ModelError::new(STEP_REJECTED));
            }
            if hh < ctl.min_step_rel * t || !(hh > 0.0) {
                return Err(ModelError::new(format!(
                    "step size collapsed: proposed substep {hh:.3e} s is below {:.0e} of the contact age {t:.6e} s",
                    ctl.min_step_rel
                ))
                .with_context(format!("y = {y:?}")));
            }
        }
    }
    *h = hh;
    Ok((y, true))
}

type Trial<const N: usize> = Result<([f64; N], [f64; N], Option<[f64; N]>), ModelError>;

#[inline]
fn dopri_step<const N: usize, F>(f: &mut F, t: f64, y: &[f64; N], k1: &[f64; N], h: f64, st: &mut OdeStats) -> Trial<N>
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
{
    st.rhs += 6;
    let k2 = f(t + C2 * h, &lin(y, &[(h * A21, k1)]))?;
    let k3 = f(t + C3 * h, &lin(y, &[(h * A31, k1), (h * A32, &k2)]))?;
    let k4 = f(t + C4 * h, &lin(y, &[(h * A41, k1), (h * A42, &k2), (h * A43, &k3)]))?;
    let k5 = f(t + C5 * h, &lin(y, &[(h * A51, k1), (h * A52, &k2), (h * A53, &k3), (h * A54, &k4)]))?;
    let k6 = f(t + h, &lin(y, &[(h * A61, k1), (h * A62, &k2), (h * A63, &k3), (h * A64, &k4), (h * A65, &k5)]))?;
    let ynew = lin(y, &[(h * A71, k1), (h * A73, &k3), (h * A74, &k4), (h * A75, &k5), (h * A76, &k6)]);
    let k7 = f(t + h, &ynew)?; // FSAL: counted with the next step's first stage
    let mut err = [0.0; N];
    for i in 0..N {
        err[i] = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
    }
    st.rhs += 1;
    Ok((ynew, err, Some(k7)))
}

#[inline]
fn rk4<const N: usize, F>(f: &mut F, t: f64, y: &[f64; N], k1: &[f64; N], h: f64, st: &mut OdeStats) -> Result<[f64; N], ModelError>
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
{
    st.rhs += 3;
    let k2 = f(t + 0.5 * h, &lin(y, &[(0.5 * h, k1)]))?;
    let k3 = f(t + 0.5 * h, &lin(y, &[(0.5 * h, &k2)]))?;
    let k4 = f(t + h, &lin(y, &[(h, &k3)]))?;
    Ok(lin(y, &[(h / 6.0, k1), (h / 3.0, &k2), (h / 3.0, &k3), (h / 6.0, &k4)]))
}

fn rk4_doubling_step<const N: usize, F>(f: &mut F, t: f64, y: &[f64; N], k1: &[f64; N], h: f64, st: &mut OdeStats) -> Trial<N>
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
{
    let big = rk4(f, t, y, k1, h, st)?;
    let half = rk4(f, t, y, k1, 0.5 * h, st)?;
    st.rhs += 1;
    let km = f(t + 0.5 * h, &half)?;
    let two = rk4(f, t + 0.5 * h, &half, &km, 0.5 * h, st)?;
    let mut err = [0.0; N];
    let mut ynew = two;
    for i in 0..N {
        err[i] = (two[i] - big[i]) / 15.0;
        ynew[i] = two[i] + err[i];
    }
    Ok((ynew, err, None))
}

/// Forward-difference Jacobian ∂f/∂y and ∂f/∂t at (t, y) (backward where the forward point is
/// inadmissible).
fn fd_jacobian<const N: usize, F>(
    f: &mut F,
    t: f64,
    y: &[f64; N],
    f0: &[f64; N],
    ctl: &Control<N>,
    h: f64,
    st: &mut OdeStats,
) -> Option<([[f64; N]; N], [f64; N])>
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
{
    let sq = f64::EPSILON.sqrt();
    let mut j = [[0.0; N]; N];
    st.jacobians += 1;
    for col in 0..N {
        let mut d = sq * y[col].abs().max(ctl.floor[col]);
        let mut yp = *y;
        yp[col] += d;
        st.rhs += 1;
        let fp = match f(t, &yp) {
            Ok(v) => v,
            Err(_) => {
                d = -d;
                yp[col] = y[col] + d;
                st.rhs += 1;
                f(t, &yp).ok()?
            }
        };
        for row in 0..N {
            j[row][col] = (fp[row] - f0[row]) / d;
        }
    }
    let dt = sq * t.abs().max(h);
    st.rhs += 1;
    let ft = f(t + dt, y).ok()?;
    let mut dfdt = [0.0; N];
    for i in 0..N {
        dfdt[i] = (ft[i] - f0[i]) / dt;
    }
    Some((j, dfdt))
}

/// LU with partial pivoting in place; returns the pivots or None if singular.
fn lu<const N: usize>(a: &mut [[f64; N]; N]) -> Option<[usize; N]> {
    let mut piv = [0usize; N];
    for k in 0..N {
        let mut p = k;
        for i in k + 1..N {
            if a[i][k].abs() > a[p][k].abs() {
                p = i;
            }
        }
        if !(a[p][k].abs() > 0.0) || !a[p][k].is_finite() {
            return None;
        }
        piv[k] = p;
        a.swap(k, p);
        for i in k + 1..N {
            let m = a[i][k] / a[k][k];
            a[i][k] = m;
            for jx in k + 1..N {
                a[i][jx] -= m * a[k][jx];
            }
        }
    }
    Some(piv)
}

fn lu_solve<const N: usize>(a: &[[f64; N]; N], piv: &[usize; N], b: &mut [f64; N]) {
    for k in 0..N {
        b.swap(k, piv[k]);
        for i in k + 1..N {
            b[i] -= a[i][k] * b[k];
        }
    }
    for k in (0..N).rev() {
        let mut s = b[k];
        for jx in k + 1..N {
            s -= a[k][jx] * b[jx];
        }
        b[k] = s / a[k][k];
    }
}

fn rosenbrock_step<const N: usize, F>(f: &mut F, t: f64, y: &[f64; N], f0: &[f64; N], j: &[[f64; N]; N], dfdt: &[f64; N], h: f64, st: &mut OdeStats) -> Trial<N>
where
    F: FnMut(f64, &[f64; N]) -> Result<[f64; N], ModelError>,
{
    let mut a = [[0.0; N]; N];
    for r in 0..N {
        for c in 0..N {
            a[r][c] = -j[r][c];
        }
        a[r][r] += 1.0 / (RGAM * h);
    }
    let piv = lu(&mut a).ok_or_else(|| ModelError::new("singular Rosenbrock matrix"))?;
    let mut g1 = [0.0; N];
    for i in 0..N {
        g1[i] = f0[i] + h * RC1X * dfdt[i];
    }
    lu_solve(&a, &piv, &mut g1);
    st.rhs += 2;
    let f1 = f(t + RA2X * h, &lin(y, &[(RA21, &g1)]))?;
    let mut g2 = [0.0; N];
    for i in 0..N {
        g2[i] = f1[i] + h * RC2X * dfdt[i] + RC21 * g1[i] / h;
    }
    lu_solve(&a, &piv, &mut g2);
    let f2 = f(t + RA3X * h, &lin(y, &[(RA31, &g1), (RA32, &g2)]))?;
    let mut g3 = [0.0; N];
    for i in 0..N {
        g3[i] = f2[i] + h * RC3X * dfdt[i] + (RC31 * g1[i] + RC32 * g2[i]) / h;
    }
    lu_solve(&a, &piv, &mut g3);
    let mut g4 = [0.0; N];
    for i in 0..N {
        g4[i] = f2[i] + h * RC4X * dfdt[i] + (RC41 * g1[i] + RC42 * g2[i] + RC43 * g3[i]) / h;
    }
    lu_solve(&a, &piv, &mut g4);
    let ynew = lin(y, &[(RB1, &g1), (RB2, &g2), (RB3, &g3), (RB4, &g4)]);
    let mut err = [0.0; N];
    for i in 0..N {
        err[i] = RE1 * g1[i] + RE2 * g2[i] + RE3 * g3[i] + RE4 * g4[i];
    }
    Ok((ynew, err, None))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ctl(method: Method, rtol: f64) -> Control<2> {
        Control { method, rtol, floor: [1e-3; 2], h_max: 1e9, min_step_rel: 1e-12, max_substeps: 1_000_000, stop_on_reject: false }
    }

    /// y'' = −y as a system, with a time-dependent forcing: y1' = y2 + cos t·0, exact sin/cos.
    fn harmonic(method: Method, rtol: f64) -> (f64, OdeStats) {
        let mut st = OdeStats::default();
        let mut h = 0.0;
        let mut f = |_t: f64, y: &[f64; 2]| Ok([y[1], -y[0]]);
        let y = integrate(&mut f, 0.0, 10.0, [0.0, 1.0], &mut h, &ctl(method, rtol), &mut st, |_, _| {}).unwrap();
        let e = (y[0] - 10f64.sin()).abs().max((y[1] - 10f64.cos()).abs());
        (e, st)
    }

    #[test]
    fn every_method_converges_with_tolerance() {
        for m in Method::ALL {
            let (e6, s6) = harmonic(m, 1e-6);
            let (e9, s9) = harmonic(m, 1e-9);
            assert!(e6 < 1e-4 && e9 < 1e-7, "{m:?}: {e6} {e9}");
            assert!(e9 < e6 / 20.0, "{m:?}: error must fall with the tolerance: {e6} {e9}");
            assert!(s9.rhs > s6.rhs);
        }
    }

    /// Non-autonomous linear problem y' = −y + t (exact y = t − 1 + 2e^{−t}): the ∂f/∂t term of the
    /// Rosenbrock method and the stage times of the explicit ones.
    #[test]
    fn non_autonomous_problem_is_integrated_to_tolerance() {
        for m in Method::ALL {
            let mut st = OdeStats::default();
            let mut h = 0.0;
            let mut f = |t: f64, y: &[f64; 1]| Ok([-y[0] + t]);
            let c = Control { method: m, rtol: 1e-8, floor: [1e-6], h_max: 1e9, min_step_rel: 1e-12, max_substeps: 100000, stop_on_reject: false };
            let y = integrate(&mut f, 0.0, 5.0, [1.0], &mut h, &c, &mut st, |_, _| {}).unwrap();
            let exact = 5.0 - 1.0 + 2.0 * (-5f64).exp();
            assert!((y[0] - exact).abs() < 1e-6, "{m:?}: {} vs {exact}", y[0]);
        }
    }

    /// A stiff linear problem: the Rosenbrock method needs far fewer steps than the explicit pair.
    #[test]
    fn rosenbrock_is_stable_on_stiff_problem() {
        let mut f = |_t: f64, y: &[f64; 2]| Ok([-1e5 * (y[0] - y[1]), -y[1]]);
        let run = |m: Method, f: &mut dyn FnMut(f64, &[f64; 2]) -> Result<[f64; 2], ModelError>| {
            let mut st = OdeStats::default();
            let mut h = 0.0;
            let mut g = |t: f64, y: &[f64; 2]| f(t, y);
            let y = integrate(&mut g, 0.0, 5.0, [2.0, 1.0], &mut h, &ctl(m, 1e-6), &mut st, |_, _| {}).unwrap();
            assert!((y[1] - (-5f64).exp()).abs() < 1e-5, "{m:?} {y:?}");
            st
        };
        let sr = run(Method::Rosenbrock4, &mut f);
        let sd = run(Method::Dopri5, &mut f);
        assert!(sr.steps * 10 < sd.steps, "{sr:?} {sd:?}");
    }

    /// `integrate_while` ends after the accepted step its callback refuses, at that step's state:
    /// the same steps as the whole integration up to there, and y = e^(−t) there.
    #[test]
    fn integrate_while_stops_after_the_refused_step() {
        let mut f = |_t: f64, y: &[f64; 2]| Ok([-y[0], -2.0 * y[1]]);
        let (mut h, mut st, mut seen) = (0.0, OdeStats::default(), Vec::new());
        let (y, reached) = integrate_while(&mut f, 0.0, 5.0, [1.0, 1.0], &mut h, &ctl(Method::Dopri5, 1e-8), &mut st, |t, y| {
            seen.push((t, *y));
            seen.len() < 3
        })
        .unwrap();
        assert!(!reached && st.steps == 3 && seen.len() == 3);
        let (t3, y3) = seen[2];
        assert_eq!(y, y3);
        assert!(t3 > 0.0 && t3 < 5.0 && (y3[0] - (-t3).exp()).abs() < 1e-7 && (y3[1] - (-2.0 * t3).exp()).abs() < 1e-7, "{t3} {y3:?}");
        let (mut h2, mut st2, mut whole) = (0.0, OdeStats::default(), Vec::new());
        integrate(&mut f, 0.0, 5.0, [1.0, 1.0], &mut h2, &ctl(Method::Dopri5, 1e-8), &mut st2, |t, y| whole.push((t, *y))).unwrap();
        assert_eq!(&whole[..3], &seen[..]);
    }

    /// The shortcut of [`accepted_factor`] below [`CLAMPED_AT_5`] gives what the power gives.
    #[test]
    fn accepted_factor_shortcut_is_the_clamped_power() {
        for m in Method::ALL {
            for k in 0..200 {
                let e = CLAMPED_AT_5 * (k as f64 / 200.0).powi(3);
                let full = if e == 0.0 { 5.0 } else { (0.9 * e.powf(-m.exponent())).clamp(0.2, 5.0) };
                assert_eq!(accepted_factor(m, e).to_bits(), full.to_bits(), "{m:?} e = {e}");
            }
            assert!(accepted_factor(m, 1.0) < 1.0);
        }
    }

    #[test]
    fn failing_rhs_reports_model_error() {
        let mut st = OdeStats::default();
        let mut h = 0.0;
        // blows up at t = 1: y' = y², y(0) = 1, y = 1/(1 − t)
        let mut f = |_t: f64, y: &[f64; 1]| {
            if y[0] > 1e12 { Err(ModelError::new("too large")) } else { Ok([y[0] * y[0]]) }
        };
        let c = Control { method: Method::Dopri5, rtol: 1e-6, floor: [1e-6], h_max: 1e9, min_step_rel: 1e-12, max_substeps: 100000, stop_on_reject: false };
        let r = integrate(&mut f, 0.0, 2.0, [1.0], &mut h, &c, &mut st, |_, _| {});
        assert!(r.is_err());
    }

    /// Strategy-1 trial: a step of the whole interval is taken once; the decay y' = −y over Δt
    /// has the Dormand–Prince local error ≈ C·Δt⁵, so Δt = 0.1 passes at rtol 1e-6 and Δt = 2
    /// is rejected at once (one trial, no retries), with the proposal below Δt.
    #[test]
    fn stop_on_reject_tries_one_step() {
        let mut f = |_t: f64, y: &[f64; 1]| Ok([-y[0]]);
        let c = Control { method: Method::Dopri5, rtol: 1e-6, floor: [1e-6], h_max: 1e9, min_step_rel: 1e-12, max_substeps: 100000, stop_on_reject: true };
        let mut st = OdeStats::default();
        let mut h = 0.1 * (1.0 + 1e-9);
        let y = integrate(&mut f, 0.0, 0.1, [1.0], &mut h, &c, &mut st, |_, _| {}).unwrap();
        assert_eq!((st.steps, st.rejected), (1, 0));
        assert!((y[0] - (-0.1f64).exp()).abs() < 1e-7);
        let mut st = OdeStats::default();
        let mut h = 2.0 * (1.0 + 1e-9);
        let e = integrate(&mut f, 0.0, 2.0, [1.0], &mut h, &c, &mut st, |_, _| {}).unwrap_err();
        assert_eq!(e.message, STEP_REJECTED);
        assert_eq!((st.steps, st.rejected), (0, 1));
        assert!(h > 0.0 && h < 2.0, "{h}");
    }
}

//! Lockstep integration of up to [`LANES`] contacts at once (docs/diffusion7.md §7, "The sweep in
//! lanes"): the coupled loop's 7-DOF sweep spends its time in the right-hand side (M8), a few
//! hundred flops with four square roots and about twenty divisions per evaluation. Evaluated for
//! four contacts side by side in structure-of-arrays form, every operation is one vector
//! instruction (AVX2 where the CPU has it, chosen at run time; two SSE2 halves otherwise).
//!
//! Each lane runs its own Dormand–Prince 5(4) step control, with its own step size, acceptance and
//! counters; the lanes only share the instruction stream. Every lane operation is the same IEEE
//! operation in the same order as the scalar code ([`super::kinetics::evaluate`],
//! [`crate::models::ode::integrate`]; Rust does not contract `a*b + c` into a fused multiply–add),
//! so a contact integrated in a lane ends bit for bit where [`super::advance::advance`] would
//! have ended it (tested). A new contact's first step takes its starting substep from the scalar
//! estimate and then runs in a lane too. A contact the lanes do not cover — a temperature kink or
//! phase change inside the interval, another method, a strategy-1 trial — goes to the scalar path, and so does a lane that meets an error condition: the scalar
//! path repeats its integration from the unchanged state and reports the error with its full
//! context.

use super::advance::{PairMaterials, SolverOptions, TemperaturePath, advance, smooth_inside};
use super::contact::Contact7;
use super::kinetics::rates_with;
use super::material::{Coeffs, ContactParams};
use crate::error::ModelError;
use crate::models::ode::{Control, Method, OdeStats, accepted_factor, err_norm, initial_step, proposal_after_accept, rejected_factor};
use std::f64::consts::PI;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// Contacts integrated side by side [1].
pub const LANES: usize = 4;

/// Four f64 lanes; each operator is one lane-wise IEEE operation.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(transparent)]
pub struct F4(pub [f64; LANES]);

impl F4 {
    #[inline(always)]
    pub fn splat(v: f64) -> F4 {
        F4([v; LANES])
    }
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> F4 {
        F4(std::array::from_fn(|l| f(self.0[l])))
    }
    #[inline(always)]
    fn zip(self, o: F4, f: impl Fn(f64, f64) -> f64) -> F4 {
        F4(std::array::from_fn(|l| f(self.0[l], o.0[l])))
    }
    #[inline(always)]
    fn sqrt(self) -> F4 {
        self.map(f64::sqrt)
    }
    /// Lanes where `v > 0` (false for NaN).
    #[inline(always)]
    fn positive(self) -> [bool; LANES] {
        std::array::from_fn(|l| self.0[l] > 0.0)
    }
    #[inline(always)]
    fn finite(self) -> [bool; LANES] {
        std::array::from_fn(|l| self.0[l].is_finite())
    }
}

macro_rules! lane_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for F4 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, o: F4) -> F4 {
                self.zip(o, |a, b| a $op b)
            }
        }
        impl $tr<F4> for f64 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, o: F4) -> F4 {
                F4::splat(self).zip(o, |a, b| a $op b)
            }
        }
        impl $tr<f64> for F4 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, o: f64) -> F4 {
                self.zip(F4::splat(o), |a, b| a $op b)
            }
        }
    };
}
lane_op!(Add, add, +);
lane_op!(Sub, sub, -);
lane_op!(Mul, mul, *);
lane_op!(Div, div, /);

impl Neg for F4 {
    type Output = F4;
    #[inline(always)]
    fn neg(self) -> F4 {
        self.map(|a| -a)
    }
}

#[inline(always)]
fn and(a: [bool; LANES], b: [bool; LANES]) -> [bool; LANES] {
    std::array::from_fn(|l| a[l] && b[l])
}

/// The transport coefficients (M9) of four contacts, lane-wise ([`Coeffs`]).
#[derive(Debug, Clone, Copy)]
pub struct CoeffsL {
    omega: F4,
    gamma_s: [F4; 2],
    gamma_gb: F4,
    k_gb: F4,
    k_lat_gb: [F4; 2],
    k_s_neck: [F4; 2],
    k_b_neck: [F4; 2],
    k_s_cap: [F4; 2],
    k_b_cap: [F4; 2],
    normal_force: F4,
}

impl Default for CoeffsL {
    fn default() -> Self {
        let z = F4::splat(0.0);
        // Ω = 1 keeps an idle lane's arithmetic finite; its results are never read
        CoeffsL {
            omega: F4::splat(1.0),
            gamma_s: [z; 2],
            gamma_gb: z,
            k_gb: z,
            k_lat_gb: [z; 2],
            k_s_neck: [z; 2],
            k_b_neck: [z; 2],
            k_s_cap: [z; 2],
            k_b_cap: [z; 2],
            normal_force: z,
        }
    }
}

impl CoeffsL {
    /// Puts `k` into lane `l`.
    #[inline]
    pub fn set(&mut self, l: usize, k: &Coeffs) {
        self.omega.0[l] = k.omega;
        self.gamma_gb.0[l] = k.gamma_gb;
        self.k_gb.0[l] = k.k_gb;
        self.normal_force.0[l] = k.normal_force;
        for s in 0..2 {
            self.gamma_s[s].0[l] = k.gamma_s[s];
            self.k_lat_gb[s].0[l] = k.k_lat_gb[s];
            self.k_s_neck[s].0[l] = k.k_s_neck[s];
            self.k_b_neck[s].0[l] = k.k_b_neck[s];
            self.k_s_cap[s].0[l] = k.k_s_cap[s];
            self.k_b_cap[s].0[l] = k.k_b_cap[s];
        }
    }
}

/// A state of four contacts, component-major: `y[i].0[l]` is y_{i+1} of lane `l` [m].
pub type StateL = [F4; 7];

/// One side's geometry (G1)–(G3), (G6), derivatives (G7)–(G9) and the admissibility (A1)–(A4)
/// of each lane, in the scalar code's operation order ([`super::geometry::Side`]).
struct SideL {
    h: F4,
    s: F4,
    dv: [F4; 4],
    da: [F4; 4],
    ratio_c: F4,
    ok: [bool; LANES],
}

#[inline(always)]
fn side_l(a: F4, r: F4, c: F4, d: F4) -> SideL {
    // (A1)
    let ok1 = and(and(a.positive(), r.positive()), c.positive());
    let ok1 = and(ok1, and(and(d.finite(), a.finite()), and(r.finite(), c.finite())));
    let p = d - c;
    let h2 = r * r - p * p;
    let ok2 = h2.positive();
    let h = h2.sqrt();
    let s = ((h - a) * (h - a) + c * c).sqrt();
    let tau = p * c - h * (h - a);
    let ok3 = tau.positive();
    // (G7)
    let dv_a = PI / 3.0 * c * (2.0 * a + h);
    let dv_r = 2.0 * PI * r * (r + p) + PI / 3.0 * c * (a + 2.0 * h) * r / h;
    let dv_c = PI / 3.0 * (a + 2.0 * h) * tau / h;
    let dv_d = PI / 3.0 * (a * a + a * h + h * h) - dv_c;
    let ok4 = dv_d.positive();
    // (G8)
    let w = (s * s + h * h - a * a) / s;
    let da_a = PI * (s * s - h * h + a * a) / s;
    let da_r = 2.0 * PI * (2.0 * r + p) + PI * w * r / h;
    let da_c = -2.0 * PI * r + PI * w * p / h + PI * (a + h) * c / s;
    let da_d = 2.0 * PI * r - PI * w * p / h;
    // (G9); h⁴ = (h·h)·(h·h) and h³ = h·(h·h) are how `powi` expands
    let x = p * (2.0 * h * (h - a) + c * c) + h * c * (h + a);
    let hh = h * h;
    let h4 = hh * hh;
    let h3 = h * hh;
    let c3 = c * (c * c);
    let m = 4.0 * h4 - 4.0 * h3 * a + 3.0 * h * h * c * c - 4.0 * h * p * a * c + h * a * c * c + p * c3;
    let ratio_c = 3.0 * m / (s * (a + 2.0 * h) * (x + 2.0 * h * r * s));
    SideL { h, s, dv: [dv_a, dv_r, dv_c, dv_d], da: [da_a, da_r, da_c, da_d], ratio_c, ok: and(and(ok1, ok2), and(ok3, ok4)) }
}

/// dy/dt [m/s] (M8) of four contacts at states `y` [m] with their coefficients `k`, and which
/// lanes are admissible with a finite rate (the scalar [`super::kinetics::rates_with`] returning `Ok`).
#[inline(always)]
pub fn rates_l(y: &StateL, k: &CoeffsL) -> (StateL, [bool; LANES]) {
    let a = y[0];
    let sa = side_l(y[0], y[1], y[2], y[3]);
    let sb = side_l(y[0], y[4], y[5], y[6]);
    let om = k.omega;
    let dv = [sa.dv[0] + sb.dv[0], sa.dv[1], sa.dv[2], sa.dv[3], sb.dv[1], sb.dv[2], sb.dv[3]];
    // (M3)
    let mu1 = om * (k.gamma_s[0] * sa.da[0] + k.gamma_s[1] * sb.da[0] + k.gamma_gb * 2.0 * PI * a) / dv[0];
    let side_mu = |g: F4, d: &SideL| [om * g * d.da[1] / d.dv[1], om * g * d.ratio_c, om * g * d.da[3] / d.dv[3]];
    let mut ma = side_mu(k.gamma_s[0], &sa);
    let mut mb = side_mu(k.gamma_s[1], &sb);
    // (M11), only in lanes with a force (as the scalar guard)
    if k.normal_force.0.iter().any(|&f| f != 0.0) {
        let fa = ma[2] + om * k.normal_force / dv[3];
        let fb = mb[2] + om * k.normal_force / dv[6];
        for l in 0..LANES {
            if k.normal_force.0[l] != 0.0 {
                ma[2].0[l] = fa.0[l];
                mb[2].0[l] = fb.0[l];
            }
        }
    }
    // (M5)
    let fl = |s: usize, sd: &SideL, m: &[F4; 3]| {
        let (mu2, mu3, mu4) = (m[0], m[1], m[2]);
        let geo_neck = (a + sd.h) / sd.s;
        let geo_cap = sd.h / sd.s;
        [
            k.k_gb * (mu4 - mu1),
            k.k_lat_gb[s] * a * (mu4 - mu1),
            k.k_s_neck[s] * geo_neck * (mu3 - mu1),
            k.k_b_neck[s] * (a + sd.h) * (mu3 - mu1),
            k.k_s_cap[s] * geo_cap * (mu2 - mu3),
            k.k_b_cap[s] * sd.h * (mu2 - mu3),
        ]
    };
    let ja = fl(0, &sa, &ma);
    let jb = fl(1, &sb, &mb);
    // (M7), (M8)
    let q1 = ja[0] + jb[0] + ja[1] + jb[1] + ja[2] + jb[2] + ja[3] + jb[3];
    let q = [q1, -(ja[4] + ja[5]), (ja[4] + ja[5]) - (ja[2] + ja[3]), -(ja[0] + ja[1]), -(jb[4] + jb[5]), (jb[4] + jb[5]) - (jb[2] + jb[3]), -(jb[0] + jb[1])];
    let mut dydt = [F4::splat(0.0); 7];
    let mut ok = and(sa.ok, sb.ok);
    for i in 0..7 {
        dydt[i] = q[i] / dv[i];
        ok = and(ok, dydt[i].finite());
    }
    (dydt, ok)
}

// Dormand–Prince 5(4), the tableau of the scalar integrator
use crate::models::ode::{
    A21, A31, A32, A41, A42, A43, A51, A52, A53, A54, A61, A62, A63, A64, A65, A71, A73, A74, A75, A76, C2, C3, C4, C5, E1, E3, E4, E5, E6, E7,
};

/// `y + Σ c_j k_j`, terms in order, a term skipped in a lane where its `c` is 0 (as the scalar
/// `lin`).
#[inline(always)]
fn lin_l(y: &StateL, h: F4, terms: &[(f64, &StateL)]) -> StateL {
    let mut out = *y;
    for (coef, k) in terms {
        let c = h * *coef;
        for i in 0..7 {
            let sum = out[i] + c * k[i];
            for l in 0..LANES {
                if c.0[l] != 0.0 {
                    out[i].0[l] = sum.0[l];
                }
            }
        }
    }
    out
}

/// Where the coefficients of a lane come from (four of these live on the stack of one sweep
/// call, so the size of the large variant costs nothing).
#[derive(Clone, Copy)]
#[allow(clippy::large_enum_variant)]
enum LaneCoeffs<'a> {
    /// Constant over the interval (T constant).
    Fixed,
    /// Evaluated at the stage's temperature, T(τ + t_c) (T varies).
    Varying { params: ContactParams, temp: TemperaturePath<'a>, tc: f64, force: f64 },
}

impl LaneCoeffs<'_> {
    #[inline]
    fn at(&self, tau: f64) -> Option<Coeffs> {
        match self {
            LaneCoeffs::Fixed => None,
            LaneCoeffs::Varying { params, temp, tc, force } => {
                let mut k = params.at(temp.at(tau + tc)).ok()?;
                k.normal_force = *force;
                Some(k)
            }
        }
    }
}

/// One lane's integration: interval in the contact's own time, step control, counters.
#[derive(Clone, Copy)]
struct Lane<'a> {
    coeffs: LaneCoeffs<'a>,
    t: f64,
    t1: f64,
    hh: f64,
    /// The scalar integrator's control of this contact (tolerance (T1), step bounds).
    ctl: Control<7>,
    substeps: u64,
    stats: OdeStats,
    active: bool,
    /// Hand the contact to the scalar path (an error condition or an inadmissible start).
    scalar: bool,
}

/// Whether [`advance_lanes`] integrates `c` in a lane over `[t0, t1]`, and with which
/// coefficients: `None` sends it to the scalar path.
fn lane_setup<'a, 'm>(
    c: &Contact7,
    mats: &PairMaterials<'m>,
    temp: &TemperaturePath<'a>,
    t0: f64,
    t1: f64,
    opts: &SolverOptions,
    cache: &mut Option<(PairMaterials<'m>, f64, f64, Coeffs)>,
) -> Option<(Lane<'a>, Option<Coeffs>)> {
    if opts.method != Method::Dopri5 || opts.stop_on_reject || !(t1 > t0) {
        return None;
    }
    if !(opts.rtol > 0.0 && opts.rtol < 1.0) {
        return None;
    }
    if !smooth_inside(temp, mats, t0, t1) {
        return None;
    }
    let tc = c.t_created;
    let (tau0, tau1) = (t0 - tc, t1 - tc);
    if !(tau1 > tau0) || !tau0.is_finite() || !tau1.is_finite() {
        return None;
    }
    let (ta, tb) = (temp.at(t0), temp.at(t1));
    let tmid = temp.at(0.5 * (t0 + t1));
    let (coeffs, fixed) = if ta == tb {
        // the coefficients of the lane before when it has the same materials and temperatures
        // (the same function of the same inputs: an isothermal chunk computes them once)
        let same = cache.as_ref().is_some_and(|(m, tm, t, _)| {
            std::ptr::eq(m.a, mats.a) && std::ptr::eq(m.b, mats.b) && m.factors == mats.factors && tm.to_bits() == tmid.to_bits() && t.to_bits() == ta.to_bits()
        });
        let mut k = match cache {
            Some((_, _, _, k)) if same => *k,
            _ => {
                let k = mats.params_at(tmid).at(ta).ok()?;
                *cache = Some((*mats, tmid, ta, k));
                k
            }
        };
        k.normal_force = c.normal_force;
        (LaneCoeffs::Fixed, Some(k))
    } else {
        (LaneCoeffs::Varying { params: mats.params_at(tmid), temp: *temp, tc, force: c.normal_force }, None)
    };
    let ctl = opts.control(c.r_min());
    let mut stats = OdeStats::default();
    let mut h = c.h_last;
    if !(h > 0.0) || !h.is_finite() {
        // a new contact: the scalar starting step (`ode::initial_step`), from the same k1 the
        // lanes compute again (counted there)
        let mut f = |tau: f64, y: &[f64; 7]| match (fixed, coeffs.at(tau)) {
            (Some(k), _) | (None, Some(k)) => rates_with(y, &k),
            (None, None) => Err(ModelError::new("no transport coefficients at this temperature")),
        };
        let f0 = f(tau0, &c.y).ok()?;
        h = initial_step(&mut f, tau0, &c.y, &f0, &ctl, 4.0, tau1 - tau0, &mut stats);
    }
    let lane = Lane { coeffs, t: tau0, t1: tau1, hh: h.min(ctl.h_max), ctl, substeps: 0, stats, active: true, scalar: false };
    Some((lane, fixed))
}

#[inline(always)]
fn lane_of(y: &StateL, l: usize) -> [f64; 7] {
    std::array::from_fn(|i| y[i].0[l])
}

/// Advances up to [`LANES`] contacts from `t0` to `t1` [s] as [`advance`] does each (same
/// result, same counters, bit for bit), the eligible ones side by side. `mats(l)` and `temp(l)`
/// give contact `l`'s materials and temperature path. Returns one result per contact and how many
/// of them went through the lanes to the end.
pub fn advance_lanes<'a, 'm>(
    contacts: &mut [Contact7],
    mats: &[PairMaterials<'m>],
    temps: &[TemperaturePath<'a>],
    t0: f64,
    t1: f64,
    opts: &SolverOptions,
) -> (Vec<Result<OdeStats, ModelError>>, usize) {
    let n = contacts.len();
    assert!(n <= LANES && mats.len() == n && temps.len() == n, "advance_lanes: at most {LANES} contacts with their materials and paths");
    let mut lanes: [Option<Lane<'a>>; LANES] = [None; LANES];
    let mut fixed = CoeffsL::default();
    let mut y = [F4::splat(0.0); 7];
    let mut cache = None;
    for l in 0..n {
        if let Some((lane, k)) = lane_setup(&contacts[l], &mats[l], &temps[l], t0, t1, opts, &mut cache) {
            if let Some(k) = k {
                fixed.set(l, &k);
            }
            for i in 0..7 {
                y[i].0[l] = contacts[l].y[i];
            }
            lanes[l] = Some(lane);
        }
    }
    // an idle lane holds a copy of an active lane's state with the default coefficients (no
    // transport: finite, zero rates); its results are never read
    if let Some(src) = (0..n).find(|&l| lanes[l].is_some()) {
        for l in (0..LANES).filter(|&l| lanes[l].is_none()) {
            for i in 0..7 {
                y[i].0[l] = y[i].0[src];
            }
        }
        let y_end = run(&mut lanes, y, &fixed);
        for l in 0..n {
            if let Some(lane) = &lanes[l]
                && !lane.scalar
            {
                contacts[l].y = lane_of(&y_end, l);
                contacts[l].h_last = lane.hh;
            }
        }
    }
    let in_lanes = lanes.iter().filter(|l| l.as_ref().is_some_and(|l| !l.scalar)).count();
    let results = (0..n)
        .map(|l| match &lanes[l] {
            Some(lane) if !lane.scalar => Ok(lane.stats),
            _ => {
                let mut st = OdeStats::default();
                advance(&mut contacts[l], &mats[l], &temps[l], t0, t1, opts, &mut st, |_, _, _| {}).map(|_| st)
            }
        })
        .collect();
    (results, in_lanes)
}

/// An order of the contacts that puts contacts of alike work into the same chunk of [`LANES`]: new
/// contacts (no substep proposed yet) first, then by the number of substeps they took in the last
/// interval, in doubling classes (1, 2, 3–4, 5–8, …), stable within a class. `None` when the
/// contacts are already so ordered (no gather needed).
pub fn work_order(contacts: &[Contact7], substeps: &[u32]) -> Option<Vec<u32>> {
    let class = |k: usize| -> usize {
        if !(contacts[k].h_last > 0.0) {
            0
        } else {
            let n = substeps.get(k).copied().unwrap_or(1).max(1);
            // 1 → 1, 2 → 2, 3–4 → 3, 5–8 → 4, …
            1 + (u32::BITS - (n - 1).leading_zeros()) as usize
        }
    };
    let n = contacts.len();
    let mut count = [0usize; 34];
    let mut sorted = true;
    let mut last = 0;
    for k in 0..n {
        let c = class(k);
        count[c] += 1;
        sorted &= c >= last;
        last = c;
    }
    if sorted {
        return None;
    }
    let mut start = [0usize; 34];
    for c in 1..34 {
        start[c] = start[c - 1] + count[c - 1];
    }
    let mut order = vec![0u32; n];
    for k in 0..n {
        let c = class(k);
        order[start[c]] = k as u32;
        start[c] += 1;
    }
    Some(order)
}

/// The lockstep loop, compiled twice: with AVX2 where the CPU has it, and for the baseline.
fn run(lanes: &mut [Option<Lane>; LANES], y: StateL, fixed: &CoeffsL) -> StateL {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked above); `run_avx2` only differs from `run_body` in
        // the instructions the compiler may use.
        return unsafe { run_avx2(lanes, y, fixed) };
    }
    run_body(lanes, y, fixed)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn run_avx2(lanes: &mut [Option<Lane>; LANES], y: StateL, fixed: &CoeffsL) -> StateL {
    run_body(lanes, y, fixed)
}

/// Coefficients of every lane at the stage times `tau` (fixed lanes keep theirs); a lane whose
/// temperature gives no coefficients is marked in the returned mask.
#[inline(always)]
fn stage_coeffs(lanes: &[Option<Lane>; LANES], fixed: &CoeffsL, tau: &[f64; LANES]) -> (CoeffsL, [bool; LANES]) {
    let mut k = *fixed;
    let mut ok = [true; LANES];
    for l in 0..LANES {
        if let Some(lane) = &lanes[l]
            && lane.active
            && let LaneCoeffs::Varying { .. } = lane.coeffs
        {
            match lane.coeffs.at(tau[l]) {
                Some(c) => k.set(l, &c),
                None => ok[l] = false,
            }
        }
    }
    (k, ok)
}

/// The stage times of every lane, `t + c·h` [s].
#[inline(always)]
fn tau_of(lanes: &[Option<Lane>; LANES], h: &F4, c: f64) -> [f64; LANES] {
    std::array::from_fn(|l| lanes[l].map_or(0.0, |ln| ln.t + c * h.0[l]))
}

/// One stage: the coefficients at the stage times, the rates at `yy`, and the lanes that failed
/// cleared in `ok` (a plain function, not a closure, so that it is compiled with the caller's
/// instruction set).
#[inline(always)]
fn stage(lanes: &[Option<Lane>; LANES], fixed: &CoeffsL, varying: bool, h: &F4, yy: &StateL, c: f64, ok: &mut [bool; LANES]) -> StateL {
    let (kk, okr) = if varying {
        let (k, okc) = stage_coeffs(lanes, fixed, &tau_of(lanes, h, c));
        *ok = and(*ok, okc);
        rates_l(yy, &k)
    } else {
        rates_l(yy, fixed)
    };
    *ok = and(*ok, okr);
    kk
}

#[inline(always)]
fn run_body(lanes: &mut [Option<Lane>; LANES], mut y: StateL, fixed: &CoeffsL) -> StateL {
    // any lane whose coefficients follow the temperature within the interval
    let varying = lanes.iter().any(|l| l.as_ref().is_some_and(|l| matches!(l.coeffs, LaneCoeffs::Varying { .. })));
    // first stage at the start (the scalar `integrate`'s k1)
    let zero = F4::splat(0.0);
    let (k, okc) = stage_coeffs(lanes, fixed, &tau_of(lanes, &zero, 0.0));
    let (mut k1, ok) = rates_l(&y, &k);
    for l in 0..LANES {
        if let Some(lane) = lanes[l].as_mut() {
            lane.stats.rhs += 1;
            if !(ok[l] && okc[l]) {
                lane.active = false;
                lane.scalar = true;
            }
        }
    }
    loop {
        let mut h = zero;
        let mut truncated = [false; LANES];
        for l in 0..LANES {
            let Some(lane) = lanes[l].as_mut() else { continue };
            if !lane.active {
                continue;
            }
            if !(lane.t < lane.t1) {
                lane.active = false;
                continue;
            }
            lane.substeps += 1;
            if lane.substeps > lane.ctl.max_substeps {
                lane.active = false;
                lane.scalar = true;
                continue;
            }
            let remaining = lane.t1 - lane.t;
            truncated[l] = lane.hh >= remaining;
            let step = if truncated[l] { remaining } else { lane.hh };
            if lane.t + step == lane.t {
                lane.active = false;
                lane.scalar = true;
                continue;
            }
            h.0[l] = step;
            lane.stats.rhs += 6;
        }
        if !lanes.iter().any(|l| l.as_ref().is_some_and(|l| l.active)) {
            break;
        }
        // the stages (docs/diffusion7.md §7), all lanes at once
        let mut ok = [true; LANES];
        let k2 = stage(lanes, fixed, varying, &h, &lin_l(&y, h, &[(A21, &k1)]), C2, &mut ok);
        let k3 = stage(lanes, fixed, varying, &h, &lin_l(&y, h, &[(A31, &k1), (A32, &k2)]), C3, &mut ok);
        let k4 = stage(lanes, fixed, varying, &h, &lin_l(&y, h, &[(A41, &k1), (A42, &k2), (A43, &k3)]), C4, &mut ok);
        let k5 = stage(lanes, fixed, varying, &h, &lin_l(&y, h, &[(A51, &k1), (A52, &k2), (A53, &k3), (A54, &k4)]), C5, &mut ok);
        let k6 = stage(lanes, fixed, varying, &h, &lin_l(&y, h, &[(A61, &k1), (A62, &k2), (A63, &k3), (A64, &k4), (A65, &k5)]), 1.0, &mut ok);
        let ynew = lin_l(&y, h, &[(A71, &k1), (A73, &k3), (A74, &k4), (A75, &k5), (A76, &k6)]);
        let k7 = stage(lanes, fixed, varying, &h, &ynew, 1.0, &mut ok);
        let mut err = [zero; 7];
        for i in 0..7 {
            err[i] = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
        }
        // each lane's step control (the scalar `integrate`)
        for l in 0..LANES {
            let Some(lane) = lanes[l].as_mut() else { continue };
            if !lane.active {
                continue;
            }
            let step = h.0[l];
            let (accepted, fac) = if ok[l] {
                lane.stats.rhs += 1;
                let yl = lane_of(&y, l);
                let yn = lane_of(&ynew, l);
                let e = err_norm(&lane_of(&err, l), &yl, &yn, &lane.ctl);
                if e <= 1.0 && yn.iter().all(|v| v.is_finite()) {
                    lane.t = if truncated[l] { lane.t1 } else { lane.t + step };
                    for i in 0..7 {
                        y[i].0[l] = ynew[i].0[l];
                        k1[i].0[l] = k7[i].0[l];
                    }
                    lane.stats.steps += 1;
                    (true, accepted_factor(Method::Dopri5, e))
                } else {
                    (false, rejected_factor(Method::Dopri5, e))
                }
            } else {
                (false, 0.25)
            };
            if accepted {
                lane.hh = proposal_after_accept(step, fac, truncated[l], lane.hh, lane.ctl.h_max);
            } else {
                lane.stats.rejected += 1;
                lane.hh = step * fac;
                if lane.hh < lane.ctl.min_step_rel * lane.t || !(lane.hh > 0.0) {
                    lane.active = false;
                    lane.scalar = true;
                }
            }
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::diffusion7::material::{Material, PathFactors};

    fn copper() -> Material {
        Material::copper()
    }

    /// A spread of admissible and inadmissible states around fresh and grown necks.
    fn states() -> Vec<[f64; 7]> {
        let mut out = Vec::new();
        let r = 25e-6;
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..400 {
            let ratio = 0.02 + 0.7 * rnd();
            let rb = r * (0.5 + rnd());
            let d = (r + rb) * (1.0 - 0.05 * rnd());
            if let Ok(mut y) = super::super::contact::initial_state(r, rb, d, 0.01, 0.1) {
                y[0] *= 1.0 + 10.0 * ratio;
                for v in y.iter_mut().skip(1) {
                    *v *= 1.0 + 0.02 * (rnd() - 0.5);
                }
                out.push(y);
            }
        }
        out
    }

    #[test]
    fn lane_rates_equal_the_scalar_rates_bit_for_bit() {
        let m = copper();
        let pm = PairMaterials { a: &m, b: &m, factors: PathFactors::default() };
        let (mut same, mut refused) = (0, 0);
        for (n, chunk) in states().chunks(LANES).enumerate() {
            if chunk.len() < LANES {
                continue;
            }
            let mut y = [F4::splat(0.0); 7];
            let mut k = CoeffsL::default();
            let mut ks = Vec::new();
            for (l, s) in chunk.iter().enumerate() {
                for i in 0..7 {
                    y[i].0[l] = s[i];
                }
                let mut c = pm.params_at(1000.0 + 50.0 * l as f64).at(1000.0 + 50.0 * l as f64).unwrap();
                c.normal_force = if (n + l) % 3 == 0 { 1e-3 * l as f64 } else { 0.0 };
                k.set(l, &c);
                ks.push(c);
            }
            let (r, ok) = rates_l(&y, &k);
            for (l, s) in chunk.iter().enumerate() {
                match rates_with(s, &ks[l]) {
                    Ok(v) => {
                        assert!(ok[l], "lane {l} refused a state the scalar rate accepts: {s:?}");
                        for i in 0..7 {
                            assert_eq!(r[i].0[l].to_bits(), v[i].to_bits(), "component {i} of {s:?}");
                        }
                        same += 1;
                    }
                    Err(_) => {
                        assert!(!ok[l], "lane {l} accepted a state the scalar rate refuses: {s:?}");
                        refused += 1;
                    }
                }
            }
        }
        assert!(same > 300, "{same} states compared");
        let _ = refused;
    }

    #[test]
    fn work_order_groups_new_contacts_then_doubling_classes_stably() {
        let r = 25e-6;
        let mut cs: Vec<Contact7> = (0..8).map(|_| Contact7::new(r, r, 2.0 * r, 0.0, 0.01, 0.1).unwrap()).collect();
        for (k, c) in cs.iter_mut().enumerate() {
            c.h_last = if k == 3 || k == 6 { 0.0 } else { 1e-3 };
        }
        // substeps of the last interval: classes 1 → 1, 2 → 2, 3–4 → 3, 5–8 → 4, 9–16 → 5
        let sub = [1, 9, 4, 7, 1, 3, 2, 16];
        let order = work_order(&cs, &sub).expect("not yet ordered");
        assert_eq!(order, vec![3u32, 6, 0, 4, 2, 5, 1, 7]);
        // already in class order: no gather
        let sorted: Vec<u32> = order.iter().map(|&k| sub[k as usize]).collect();
        let cs2: Vec<Contact7> = order.iter().map(|&k| cs[k as usize]).collect();
        assert!(work_order(&cs2, &sorted).is_none());
    }

    #[test]
    fn lanes_end_where_the_scalar_path_ends_bit_for_bit() {
        let m = copper();
        let ti = Material::titanium();
        let pm = PairMaterials { a: &m, b: &m, factors: PathFactors::default() };
        let pt = PairMaterials { a: &ti, b: &ti, factors: PathFactors::default() };
        let opts = SolverOptions { rtol: 1e-5, ..Default::default() };
        let r = 25e-6;
        // seven contacts of different ages and sizes over three paths: a chunk of four, one of three
        let mut contacts: Vec<Contact7> = (0..7)
            .map(|j| {
                let rb = r * (0.6 + 0.1 * j as f64);
                let mut c = Contact7::new(r, rb, (r + rb) * 0.999, -(1.0 + 3.0 * j as f64), 0.01, 0.1).unwrap();
                c.normal_force = if j == 2 { 2e-4 } else { 0.0 };
                c
            })
            .collect();
        // first calls (no proposed substep yet) take the scalar path; later ones the lanes
        // a ramp with a kink at 3 s (inside the fourth step), then a hold
        let profile = crate::profile::Profile::from_table(&[[0.0, 1000.0], [3.0, 1293.0], [1e3, 1293.0]]).unwrap();
        let paths = |j: usize, t0: f64, t1: f64| match j % 3 {
            0 => TemperaturePath::Constant(1200.0 + 20.0 * j as f64),
            1 => TemperaturePath::Linear { t0, temp0: 1100.0, t1, temp1: 1180.0 + 10.0 * j as f64 },
            _ => TemperaturePath::Profile(&profile),
        };
        let mut scalar = contacts.clone();
        let mut t = 0.0;
        let mut used = 0;
        for step in 0..6 {
            let dt = 0.5 + step as f64;
            let (t0, t1) = (t, t + dt);
            // titanium contacts 4 and 6: contact 4's path crosses the α/β transition
            let mats: Vec<PairMaterials> = (0..7).map(|j| if j == 4 || j == 6 { pt } else { pm }).collect();
            let temps: Vec<TemperaturePath> = (0..7).map(|j| paths(j, t0, t1)).collect();
            let mut lane_stats = Vec::new();
            for (cs, (ms, ts)) in contacts.chunks_mut(LANES).zip(mats.chunks(LANES).zip(temps.chunks(LANES))) {
                let (r, n) = advance_lanes(cs, ms, ts, t0, t1, &opts);
                lane_stats.extend(r.into_iter().map(|r| r.unwrap()));
                used += n;
            }
            for (j, c) in scalar.iter_mut().enumerate() {
                let mut st = OdeStats::default();
                advance(c, &mats[j], &temps[j], t0, t1, &opts, &mut st, |_, _, _| {}).unwrap();
                assert_eq!(st, lane_stats[j], "counters of contact {j} in step {step}");
                assert_eq!(c.h_last.to_bits(), contacts[j].h_last.to_bits(), "proposed substep of contact {j} in step {step}");
                for i in 0..7 {
                    assert_eq!(c.y[i].to_bits(), contacts[j].y[i].to_bits(), "y{} of contact {j} in step {step}", i + 1);
                }
            }
            t = t1;
        }
        // six steps of seven contacts (the first ones too), less contact 4 crossing the transition
        // in every step and contacts 2 and 5 over the kink at 3 s
        assert_eq!(used, 6 * 7 - 6 - 2, "contact steps in lanes");
        for (c, s) in contacts.iter().zip(&scalar) {
            assert!(c.neck_ratio() > 0.05 && c.y == s.y, "the necks grew, alike");
        }
    }
}

//! Contacts that cannot change within the tolerance over an interval (docs/diffusion7.md §7,
//! (T2)): the coupled sweep keeps their state instead of integrating them.
//!
//! The rates (M8) are linear in the transport coefficients: every flux of (M5) is a coefficient
//! k_m of (M9) times a factor of the geometry and the potentials (M3), (M11), none of which depends
//! on the temperature within a phase. With every k_m rising with T up to the interval's hottest
//! temperature T̂ ([`ContactParams::coefficients_rise_up_to`]) and no phase change or kink inside,
//!
//! ```text
//! |y_i(t1) − y_i(t0)| ≤ Δt·(|ẏ_i(y0; k(T̂))| + δ·B_i),                                 (T2a)
//!     B_i = Σ_{fluxes J of Q_i} |J(y0; k(T̂))| / |∂V/∂y_i|,  δ = max_m (1 − k_m(T_cold)/k_m(T̂))
//! ```
//!
//! to first order in the change itself (the rate at T differs from that at T̂ by the coefficients'
//! fall times their fluxes; δ = 0 at constant temperature), and the contact is skipped when this bound passes the
//! integrator's own acceptance test (T1) for the step `y_new = y_old`:
//!
//! ```text
//! s = max_i Δt·B_i / (rtol·max(|y_i|, f·R_min)) ≤ 1.                                   (T2b)
//! ```

use super::advance::{PairMaterials, SolverOptions, TemperaturePath, smooth_inside};
use super::contact::Contact7;
use super::kinetics::evaluate;
use super::material::Coeffs;

/// The bound B_i of (T2a) on |dy_i/dt| [m/s] from the fluxes of one evaluation (M5), (M7):
/// each net rate Q_i is a signed sum of fluxes, bounded by the sum of their magnitudes.
pub fn rate_bound(flux: &[[f64; 6]; 2], dv: &[f64; 7]) -> [f64; 7] {
    let [ja, jb] = flux.map(|j| j.map(f64::abs));
    let q1 = ja[0] + jb[0] + ja[1] + jb[1] + ja[2] + jb[2] + ja[3] + jb[3];
    let q = [q1, ja[4] + ja[5], ja[4] + ja[5] + ja[2] + ja[3], ja[0] + ja[1], jb[4] + jb[5], jb[4] + jb[5] + jb[2] + jb[3], jb[0] + jb[1]];
    std::array::from_fn(|i| q[i] / dv[i].abs())
}

/// The measure s of (T2b) for `c` over the global interval `[t0, t1]` [s] on the temperature
/// path `temp` [1]; `None` when (T2a) does not hold there: an empty interval, a kink of the path
/// or a phase transition inside it, a coefficient that does not rise with T up to the hottest
/// end, an inadmissible state (the integrator then reports it) or a non-finite bound.
pub fn change_measure(c: &Contact7, mats: &PairMaterials, temp: &TemperaturePath, t0: f64, t1: f64, opts: &SolverOptions) -> Option<f64> {
    if !(t1 > t0) || !(opts.rtol > 0.0) {
        return None;
    }
    if !smooth_inside(temp, mats, t0, t1) {
        return None;
    }
    // no kink inside: T is linear over the interval, its hottest point an end
    let hot = temp.at(t0).max(temp.at(t1));
    let params = mats.params_at(temp.at(0.5 * (t0 + t1)));
    if !params.coefficients_rise_up_to(hot) {
        return None;
    }
    let mut k = params.at(hot).ok()?;
    k.normal_force = c.normal_force;
    let e = evaluate(&c.y, &k).ok()?;
    // the largest relative fall of a coefficient from the hot to the cold end (0 at constant T)
    let cold = temp.at(t0).min(temp.at(t1));
    let delta = if cold < hot { coefficient_fall(&k, &params.at(cold).ok()?) } else { 0.0 };
    let b = rate_bound(&e.flux, &e.dv);
    let floor = opts.norm_floor * c.r_min();
    let dt = t1 - t0;
    let mut s: f64 = 0.0;
    for i in 0..7 {
        s = s.max(dt * (e.dydt[i].abs() + delta * b[i]) / (opts.rtol * c.y[i].abs().max(floor)));
    }
    s.is_finite().then_some(s)
}

/// δ of (T2a): the largest `1 − k_m(T_cold)/k_m(T̂)` over the transport coefficients (M9) that
/// are not zero [1], in [0, 1] for rising coefficients.
pub fn coefficient_fall(hot: &Coeffs, cold: &Coeffs) -> f64 {
    let pairs = [
        (hot.k_gb, cold.k_gb),
        (hot.k_lat_gb[0], cold.k_lat_gb[0]),
        (hot.k_lat_gb[1], cold.k_lat_gb[1]),
        (hot.k_s_neck[0], cold.k_s_neck[0]),
        (hot.k_s_neck[1], cold.k_s_neck[1]),
        (hot.k_b_neck[0], cold.k_b_neck[0]),
        (hot.k_b_neck[1], cold.k_b_neck[1]),
        (hot.k_s_cap[0], cold.k_s_cap[0]),
        (hot.k_s_cap[1], cold.k_s_cap[1]),
        (hot.k_b_cap[0], cold.k_b_cap[0]),
        (hot.k_b_cap[1], cold.k_b_cap[1]),
    ];
    pairs.iter().filter(|(h, _)| *h != 0.0).map(|(h, c)| (1.0 - c / h).clamp(0.0, 1.0)).fold(0.0, f64::max)
}

/// The sweep tests a contact by (T2) only when its last change rate ([`Contact7::change_rate`])
/// times Δt is at most this [1]: a contact that moved by more than four tolerances over a step
/// of this length cannot fall below one in the next step unless its rates fall fourfold in one
/// step. Only the cost depends on it: a contact not tested is integrated.
pub const TEST_BELOW: f64 = 4.0;

/// [`Contact7::change_rate`] of an interval of length `dt` [s] that took `c` from `y0` to its
/// state now [1/s].
pub fn change_rate(c: &Contact7, y0: &[f64; 7], dt: f64, opts: &SolverOptions) -> f64 {
    let floor = opts.norm_floor * c.r_min();
    let mut s: f64 = 0.0;
    for i in 0..7 {
        s = s.max((c.y[i] - y0[i]).abs() / (opts.rtol * y0[i].abs().max(floor)));
    }
    if dt > 0.0 && s.is_finite() { s / dt } else { 0.0 }
}

/// Whether the sweep keeps `c` unchanged over `[t0, t1]` (T2b), with the measure s [1].
pub fn skippable(c: &Contact7, mats: &PairMaterials, temp: &TemperaturePath, t0: f64, t1: f64, opts: &SolverOptions) -> (bool, Option<f64>) {
    let s = change_measure(c, mats, temp, t0, t1, opts);
    (s.is_some_and(|s| s <= 1.0), s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::diffusion7::advance::advance;
    use crate::models::diffusion7::kinetics::rates_with;
    use crate::models::diffusion7::material::{Material, PathFactors};
    use crate::models::ode::OdeStats;

    /// A copper neck grown at 1293 K for `age` [s] from (I1)–(I4), radii 25 and 22 µm.
    fn grown_copper(m: &Material, age: f64) -> Contact7 {
        let pm = PairMaterials { a: m, b: m, factors: PathFactors::default() };
        let (ra, rb) = (25e-6, 22e-6);
        let mut c = Contact7::new(ra, rb, (ra + rb) * 0.999, 0.0, 0.01, 0.1).unwrap();
        let mut st = OdeStats::default();
        advance(&mut c, &pm, &TemperaturePath::Constant(1293.0), 0.0, age, &SolverOptions::default(), &mut st, |_, _, _| {}).unwrap();
        c
    }

    /// The largest |Δy_i| of an integration at rtol 1e-10 over `[t0, t1]`, relative to Δt·B_i
    /// (T2a) [1], and the measure s of (T2b) at `opts`.
    fn integrated_against_bound(c: &Contact7, pm: &PairMaterials, path: &TemperaturePath, t0: f64, t1: f64, opts: &SolverOptions) -> (f64, f64, [f64; 7]) {
        let s = change_measure(c, pm, path, t0, t1, opts).expect("(T2a) applies");
        let hot = path.at(t0).max(path.at(t1));
        let mut k = pm.params_at(hot).at(hot).unwrap();
        k.normal_force = c.normal_force;
        let e = evaluate(&c.y, &k).unwrap();
        let cold = path.at(t0).min(path.at(t1));
        let delta = coefficient_fall(&k, &pm.params_at(cold).at(cold).unwrap());
        let b0 = rate_bound(&e.flux, &e.dv);
        let b: [f64; 7] = std::array::from_fn(|i| e.dydt[i].abs() + delta * b0[i]);
        let mut moved = *c;
        let tight = SolverOptions { rtol: 1e-10, ..*opts };
        advance(&mut moved, pm, path, t0, t1, &tight, &mut OdeStats::default(), |_, _, _| {}).unwrap();
        let dy: [f64; 7] = std::array::from_fn(|i| moved.y[i] - c.y[i]);
        let ratio = (0..7).map(|i| dy[i].abs() / ((t1 - t0) * b[i])).fold(0.0, f64::max);
        (ratio, s, dy)
    }

    /// The bound holds against the integrated change, for a hot and a cold interval, at constant
    /// temperature and on a ramp (heating: the bound is taken at the hot end), and for a contact
    /// under a normal force (M11).
    #[test]
    fn the_integrated_change_stays_below_the_bound() {
        let m = Material::copper();
        let pm = PairMaterials { a: &m, b: &m, factors: PathFactors::default() };
        let opts = SolverOptions { rtol: 1e-5, ..Default::default() };
        let mut c = grown_copper(&m, 1000.0);
        for force in [0.0, 2e-4] {
            c.normal_force = force;
            for path in [
                TemperaturePath::Constant(1293.0),
                TemperaturePath::Constant(900.0),
                TemperaturePath::Linear { t0: 1000.0, temp0: 1000.0, t1: 1010.0, temp1: 1010.0 },
                TemperaturePath::Linear { t0: 1000.0, temp0: 1010.0, t1: 1010.0, temp1: 1000.0 },
                TemperaturePath::Linear { t0: 1000.0, temp0: 850.0, t1: 1010.0, temp1: 860.0 },
                TemperaturePath::Linear { t0: 1000.0, temp0: 860.0, t1: 1010.0, temp1: 850.0 },
            ] {
                let (ratio, s, _) = integrated_against_bound(&c, &pm, &path, 1000.0, 1010.0, &opts);
                // (T2a) holds to first order: the rate itself drifts over the interval, by 1.7e-6
                // of itself at 900 K (s = 0.056), by 0.8 % at 1293 K under the force (s = 354,
                // a contact integrated anyway), measured
                let slack = if s <= 10.0 { 1e-4 } else { 0.02 };
                assert!(ratio <= 1.0 + slack, "force {force} N, {path:?}: s = {s}, |Δy|/(Δt·B) = {ratio}");
                assert!(ratio > 1e-3, "the bound is not vacuous: {ratio}");
            }
        }
    }

    /// A contact skipped by (T2b) changes by less than the tolerance when integrated anyway (each
    /// component within rtol·max(|y|, f·R_min) of the kept state), checked against the
    /// integrated value; the hot contact of the copper compact's hold (1293 K, Δt = 10 s, rtol
    /// 1e-5) is never skipped, and its measure exceeds 1 by the margin its integrated change
    /// shows.
    #[test]
    fn skipped_contacts_change_less_than_the_tolerance_and_hot_ones_are_integrated() {
        let m = Material::copper();
        let pm = PairMaterials { a: &m, b: &m, factors: PathFactors::default() };
        let opts = SolverOptions { rtol: 1e-5, ..Default::default() };
        let c = grown_copper(&m, 1000.0);
        let floor = opts.norm_floor * c.r_min();
        let tol = |i: usize| opts.rtol * c.y[i].abs().max(floor);
        // hot: the hold of cases/copper-compact.toml
        let hot = TemperaturePath::Constant(1293.0);
        let (skip, s) = skippable(&c, &pm, &hot, 1000.0, 1010.0, &opts);
        assert!(!skip && s.unwrap() > 1.0, "{s:?}");
        let (_, _, dy) = integrated_against_bound(&c, &pm, &hot, 1000.0, 1010.0, &opts);
        assert!((0..7).any(|i| dy[i].abs() > tol(i)), "the hot contact moves by more than the tolerance: {dy:?}");
        // cooling: the same neck at falling temperatures; the first skipped one and a colder one
        let mut first_skipped = None;
        for temp in (500..=1293).rev().step_by(10) {
            let path = TemperaturePath::Constant(temp as f64);
            let (skip, s) = skippable(&c, &pm, &path, 1000.0, 1010.0, &opts);
            if skip {
                first_skipped.get_or_insert(temp);
                let (_, s2, dy) = integrated_against_bound(&c, &pm, &path, 1000.0, 1010.0, &opts);
                assert_eq!(Some(s2), s);
                for i in 0..7 {
                    assert!(dy[i].abs() <= tol(i), "T = {temp} K, s = {s2}: |Δy{}| = {} above the tolerance {}", i + 1, dy[i].abs(), tol(i));
                }
            } else {
                assert!(first_skipped.is_none(), "the measure falls with the temperature: {temp} K not skipped after a hotter one was");
            }
        }
        // the neck of y1/R ≈ 0.3 after 1000 s stops moving within 1e-5 over 10 s some 300 K below
        // the hold (the activation energies of the bundled copper data, docs/diffusion7.md §9)
        let t_skip = first_skipped.expect("cold contacts are skipped");
        assert!((800..1100).contains(&t_skip), "first skipped at {t_skip} K");
    }

    /// (T2a) does not apply, so nothing is skipped, over a phase transition (titanium α/β at
    /// 1156 K), over a kink of the heating profile, and for a mechanism with Q = 0 whose
    /// coefficient falls with T; the measure grows linearly with Δt.
    #[test]
    fn no_measure_where_the_bound_does_not_hold() {
        let ti = Material::titanium();
        let pt = PairMaterials { a: &ti, b: &ti, factors: PathFactors::default() };
        let opts = SolverOptions { rtol: 1e-6, ..Default::default() };
        let c = Contact7::new(30e-6, 30e-6, 60e-6 * 0.999, 0.0, 0.01, 0.1).unwrap();
        let across = TemperaturePath::Linear { t0: 0.0, temp0: 1150.0, t1: 10.0, temp1: 1160.0 };
        assert_eq!(change_measure(&c, &pt, &across, 0.0, 10.0, &opts), None);
        let below = TemperaturePath::Linear { t0: 0.0, temp0: 1140.0, t1: 10.0, temp1: 1150.0 };
        assert!(change_measure(&c, &pt, &below, 0.0, 10.0, &opts).is_some());
        let profile = crate::profile::Profile::from_table(&[[0.0, 700.0], [5.0, 710.0], [1e3, 710.0]]).unwrap();
        assert_eq!(change_measure(&c, &pt, &TemperaturePath::Profile(&profile), 0.0, 10.0, &opts), None);
        assert!(change_measure(&c, &pt, &TemperaturePath::Profile(&profile), 5.0, 15.0, &opts).is_some());
        let mut flat = ti.clone();
        flat.phases[0].q_lattice = 0.0;
        let pf = PairMaterials { a: &flat, b: &flat, factors: PathFactors::default() };
        assert_eq!(change_measure(&c, &pf, &TemperaturePath::Constant(700.0), 0.0, 10.0, &opts), None);
        assert_eq!(change_measure(&c, &pt, &TemperaturePath::Constant(700.0), 0.0, 0.0, &opts), None);
        let s1 = change_measure(&c, &pt, &TemperaturePath::Constant(700.0), 0.0, 10.0, &opts).unwrap();
        let s2 = change_measure(&c, &pt, &TemperaturePath::Constant(700.0), 0.0, 20.0, &opts).unwrap();
        assert!((s2 / s1 - 2.0).abs() < 1e-12, "{s1} {s2}");
    }

    /// `smooth_inside` says what `split_times` says: kinks and transition crossings inside.
    #[test]
    fn smooth_inside_agrees_with_split_times() {
        use crate::models::diffusion7::advance::split_times;
        let ti = Material::titanium();
        let pt = PairMaterials { a: &ti, b: &ti, factors: PathFactors::default() };
        let profile = crate::profile::Profile::from_table(&[[0.0, 1100.0], [5.0, 1200.0], [1e3, 1200.0]]).unwrap();
        let mut checked = [0, 0];
        for k in 0..60 {
            let (t0, t1) = (0.25 * k as f64, 0.25 * k as f64 + 0.7);
            for path in [
                TemperaturePath::Profile(&profile),
                TemperaturePath::Linear { t0, temp0: 1100.0 + 2.0 * k as f64, t1, temp1: 1150.0 + k as f64 },
                TemperaturePath::Constant(1156.0),
            ] {
                let smooth = smooth_inside(&path, &pt, t0, t1);
                assert_eq!(smooth, split_times(&path, t0, t1, &pt.transitions()).is_empty(), "{path:?} over [{t0}, {t1}]");
                checked[smooth as usize] += 1;
            }
        }
        assert!(checked[0] > 10 && checked[1] > 10, "{checked:?}");
    }

    /// The bound is the magnitude sum of the signed sums of (M7): at least |dy_i/dt| of (M8).
    #[test]
    fn rate_bound_dominates_the_rates() {
        let m = Material::copper();
        let pm = PairMaterials { a: &m, b: &m, factors: PathFactors::default() };
        let c = grown_copper(&m, 10.0);
        let k = pm.params_at(1293.0).at(1293.0).unwrap();
        let e = evaluate(&c.y, &k).unwrap();
        let r = rates_with(&c.y, &k).unwrap();
        let b = rate_bound(&e.flux, &e.dv);
        for i in 0..7 {
            assert!(b[i] >= r[i].abs() * (1.0 - 1e-14) && b[i] > 0.0, "component {i}: {} < {}", b[i], r[i].abs());
        }
    }
}

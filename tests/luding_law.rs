//! Luding's sintering contact law (docs/luding.md): each branch of the normal force
//! at chosen overlaps, k1(T) at the paper's temperatures, the relaxation law against its ODE, the
//! history rules on heating and cooling, cohesion and friction scaling, the tangential spring, and
//! rejection of bad parameters.

use nalgebra::Vector3;
mod common;
use common::{doc_snippets, key_of, rel};
use sinterdem::error::ConfigError;
use sinterdem::models::luding::*;

const R0: f64 = 1e-3;
const C0: f64 = 273.15;

fn params() -> LudingParams {
    LudingParams::new(&LudingSpec::default(), R0).unwrap()
}

fn cold(p: &LudingParams) -> LudingState {
    // far below T_melt: k1(T) = k1 to 2e-9
    LudingState::new(p, C0 + 20.0)
}

#[test]
fn k1_of_temperature_matches_eq10_at_the_papers_temperatures() {
    let p = params();
    // docs/decisions-laws.md L10: 0.598688, 0.401312, 0.119203, 3.3535e-4 (paper rounds to 0.6, 0.4, 0.12, 3e-4)
    for &(t_c, want) in &[(118.0, 0.598688), (122.0, 0.401312), (130.0, 0.119203), (160.0, 3.3535e-4)] {
        let x = p.k1_of_temperature(C0 + t_c) / p.k1;
        assert!(rel(x, want) < 2e-5, "{t_c} C: {x} vs {want}");
        let tanh = 0.5 * (1.0 + ((p.t_melt - (C0 + t_c)) / p.t_var).tanh());
        assert!(rel(x, tanh) < 1e-12, "not the tanh of eq. 10");
    }
    assert_eq!(p.k1_of_temperature(p.t_melt), 0.5 * p.k1);
    assert!(rel(p.k1_of_temperature(C0 - 100.0), p.k1) < 1e-15);
    let hot = p.k1_of_temperature(1e4);
    assert!((0.0..1e-200).contains(&hot));
}

#[test]
fn loading_unloading_and_cohesive_branches() {
    let p = params();
    let mut s = cold(&p);
    let k1 = s.k1_t;
    // loading: f = k1·δ, δ_max follows, δ_0 = (1 − k1/k2(δ_max))·δ_max
    let dm = 5e-5;
    for i in 1..=50 {
        let d = dm * i as f64 / 50.0;
        let f = normal_force(&p, &mut s, d, 0.0);
        assert!(rel(f.elastic, k1 * d) < 1e-12, "loading at {d}: {}", f.elastic);
    }
    assert_eq!(s.delta_max, dm);
    let k2 = p.k2_of(dm);
    assert!(rel(k2, p.k1 + (p.k2 - p.k1) * dm / p.delta_max_fluid) < 1e-14);
    assert!(k2 > k1 && k2 < p.k2);
    let d0 = (1.0 - k1 / k2) * dm;
    assert!(rel(s.delta_0, d0) < 1e-14);
    // unloading to δ_0 on slope k2(δ_max)
    for &d in &[0.9 * dm, 0.5 * (dm + d0), d0 * 1.0000001] {
        let f = normal_force(&p, &mut s, d, 0.0).elastic;
        assert!(rel(f, k2 * (d - d0)) < 1e-9, "unloading at {d}: {f}");
    }
    let f0 = normal_force(&p, &mut s, d0, 0.0).elastic;
    assert!(f0.abs() < 1e-9 * k1 * dm, "force at delta_0: {f0}");
    // reloading follows the same line back to the loading line (no new plasticity)
    let f = normal_force(&p, &mut s, 0.99 * dm, 0.0).elastic;
    assert!(rel(f, k2 * (0.99 * dm - d0)) < 1e-12);
    assert_eq!(s.delta_max, dm);
    // attractive between δ_min and δ_0; minimum f_min = −kc·δ_min at δ_min (eq. 15)
    let kc = p.kc_of(k1, dm);
    let dmin = (k2 - k1) / (k2 + kc) * dm;
    assert!(rel(p.delta_min(k1, dm), dmin) < 1e-14);
    let fmin_eq15 = -(k2 - k1) / (1.0 + k2 / kc) * dm;
    assert!(rel(p.f_min(k1, dm), fmin_eq15) < 1e-12);
    // the worked numbers of docs/luding.md (Table 1, r_0 = 1 mm, δ_max = 50 µm)
    assert!(rel(k2, 1.125e5) < 1e-8 && rel(s.delta_0, 5.5556e-6) < 1e-4 && rel(kc, 0.5625e5) < 1e-8);
    assert!(rel(dmin, 3.7037e-6) < 1e-4 && rel(fmin_eq15, -0.20833) < 1e-4, "{dmin} {fmin_eq15}");
    let f = normal_force(&p, &mut s, dmin, 0.0).elastic;
    assert!(rel(f, -kc * dmin) < 1e-9 && rel(f, fmin_eq15) < 1e-9, "{f} vs {fmin_eq15}");
    let f_mid = normal_force(&p, &mut s, 0.5 * (dmin + d0), 0.0).elastic;
    assert!(f_mid < 0.0 && f_mid > fmin_eq15);
    // below δ_min: the −kc·δ line, and δ_max shifts so that δ is the new δ_min
    let d = 0.5 * dmin;
    let f = normal_force(&p, &mut s, d, 0.0).elastic;
    assert!(rel(f, -kc * d) < 1e-12, "{f}");
    assert!(s.delta_max < dm);
    // the shifted δ_max has δ as its δ_min, with k2 and kc of the new δ_max (MercuryDPM's
    // (k2 + kc)/(k2 − k1)·δ, taken self-consistently)
    let (k2n, kcn) = (p.k2_of(s.delta_max), p.kc_of(k1, s.delta_max));
    assert!(rel(s.delta_max, (k2n + kcn) / (k2n - k1) * d) < 1e-10);
    assert!(rel(p.delta_min(k1, s.delta_max), d) < 1e-10);
    // the un/reloading line now passes through the cohesive line −kc(T,t,δ_max)·δ at δ (kc of the
    // new δ_max: eq. 13 weakens the cohesion as δ_max shifts down), and reloading leaves it along k2
    let dd = 1e-3 * d;
    let f1 = normal_force(&p, &mut s, d, 0.0).elastic;
    assert!(rel(f1, -kcn * d) < 1e-9, "{f1} vs {}", -kcn * d);
    assert!(kcn < kc && f1 > f);
    let f2 = normal_force(&p, &mut s, d + dd, 0.0).elastic;
    let slope = (f2 - f1) / dd;
    assert!(rel(slope, k2n) < 1e-6, "reload slope {slope} vs {k2n}");
    // unloading along the cohesive line in small steps is continuous (Lipschitz in δ)
    let mut prev = (d, normal_force(&p, &mut s, d, 0.0).elastic);
    for i in 1..=1000 {
        let x = d * (1.0 - 0.9 * i as f64 / 1000.0);
        let f = normal_force(&p, &mut s, x, 0.0).elastic;
        assert!(f <= 0.0 && (f - prev.1).abs() <= 2.0 * p.kc * (prev.0 - x), "jump at {x}: {f} after {}", prev.1);
        prev = (x, f);
    }
    // the cone holds everywhere on a random walk of overlaps
    let mut x = 0.3f64;
    for _ in 0..2000 {
        x = (x * 3.7 * (1.0 - x)).clamp(0.01, 0.99);
        let d = 1.5 * dm * x;
        let f = normal_force(&p, &mut s, d, 0.0).elastic;
        let kc = p.kc_of(s.k1_t, s.delta_max);
        assert!(f <= s.k1_t * d * (1.0 + 1e-12) && f >= -kc * d * (1.0 + 1e-12), "cone violated at {d}: {f}");
    }
}

#[test]
fn hysteresis_dissipates_the_loop_area() {
    // Cycle 0 → δ_max → δ_0 on a cold contact: the work lost is k1 δ_max²/2 − k2(δ_max − δ_0)²/2
    // = (k1 δ_max²/2)(1 − k1/k2(δ_max)), the triangle between the two lines.
    let p = params();
    let mut s = cold(&p);
    let dm = 8e-5;
    let n = 20000;
    let mut work = 0.0;
    let mut prev = (0.0, 0.0);
    for i in 1..=n {
        let d = dm * i as f64 / n as f64;
        let f = normal_force(&p, &mut s, d, 0.0).elastic;
        work += 0.5 * (f + prev.1) * (d - prev.0);
        prev = (d, f);
    }
    let d0 = s.delta_0;
    for i in 1..=n {
        let d = dm - (dm - d0) * i as f64 / n as f64;
        let f = normal_force(&p, &mut s, d, 0.0).elastic;
        work += 0.5 * (f + prev.1) * (d - prev.0);
        prev = (d, f);
    }
    let k1 = s.k1_t;
    let want = 0.5 * k1 * dm * dm * (1.0 - k1 / p.k2_of(dm));
    assert!(rel(work, want) < 1e-6, "{work} vs {want}");
}

#[test]
fn damping_is_added_after_the_clamp_and_opposes_the_rate() {
    let p = params();
    let mut s = cold(&p);
    let f = normal_force(&p, &mut s, 1e-5, 0.02);
    assert!(rel(f.damping, p.gamma_n * 0.02) < 1e-15);
    assert!(rel(f.total, s.k1_t * 1e-5 + p.gamma_n * 0.02) < 1e-14);
    // separating contact below δ_min: clamp first, then damping (attractive beyond −kc·δ)
    let mut s = cold(&p);
    normal_force(&p, &mut s, 5e-5, 0.0);
    let d = 1e-7;
    let kc = p.kc_of(s.k1_t, s.delta_max);
    let f = normal_force(&p, &mut s, d, -0.01);
    assert!(rel(f.elastic, -kc * d) < 1e-9);
    assert!(rel(f.total, -kc * d - p.gamma_n * 0.01) < 1e-9);
    // open contact: no force
    assert_eq!(normal_force(&p, &mut s, -1e-6, 0.3).total, 0.0);
    // eq. 6
    let m = 1e-5;
    let eta = p.gamma_n / (2.0 * m);
    assert!(rel(p.contact_duration(m).unwrap(), std::f64::consts::PI / (p.k2 / m - eta * eta).sqrt()) < 1e-15);
    assert!(p.contact_duration(1e-12).is_err(), "over-damped contact must be an error");
}

#[test]
fn k2_grows_linearly_to_the_fluid_limit_where_delta0_freezes() {
    let p = params();
    assert!(rel(p.delta_fluid, 0.2 * R0) < 1e-15);
    assert!(rel(p.delta_max_fluid, p.k2 * p.delta_fluid / (p.k2 - p.k1)) < 1e-15);
    assert_eq!(p.k2_of(0.0), p.k1);
    assert!(rel(p.k2_of(0.5 * p.delta_max_fluid), 0.5 * (p.k1 + p.k2)) < 1e-15);
    assert_eq!(p.k2_of(p.delta_max_fluid), p.k2);
    assert_eq!(p.k2_of(3.0 * p.delta_max_fluid), p.k2);
    // a cold virgin load to δ_max^fluid reaches δ_0 = δ_fluid exactly; beyond, δ_0 stays frozen
    let mut s = cold(&p);
    let k1 = s.k1_t;
    normal_force(&p, &mut s, p.delta_max_fluid, 0.0);
    assert!(rel(s.delta_0, p.delta_fluid) < 1e-8, "{}", s.delta_0);
    let d = 1.5 * p.delta_max_fluid;
    let f = normal_force(&p, &mut s, d, 0.0).elastic;
    assert_eq!(s.delta_0, p.delta_fluid);
    assert!(s.is_fluid(&p));
    // fluid branch: slope k2 from δ_fluid, above the k1 line (paper Fig. 3)
    assert!(rel(f, p.k2 * (d - p.delta_fluid)) < 1e-12 && f > k1 * d);
    let f2 = normal_force(&p, &mut s, 0.8 * d, 0.0).elastic;
    assert!(rel(f2, p.k2 * (0.8 * d - p.delta_fluid)) < 1e-12);
}

#[test]
fn heating_keeps_delta_max_and_cooling_keeps_delta_0() {
    let p = params();
    let mut s = cold(&p);
    let dm = 5e-5;
    normal_force(&p, &mut s, dm, 0.0);
    // heat to 140 °C with the freeze: k1(T,t) relaxes down over dt, δ_max stays, δ_0 grows
    let t_hot = C0 + 140.0;
    let dt = 0.05;
    update_stiffness(&p, &mut s, t_hot, 0.1, dt);
    let k1_hot = p.k1_of_temperature(t_hot);
    let want = relax(p.k1_of_temperature(C0 + 20.0), k1_hot, 0.1, dt);
    assert!(rel(s.k1_t, want) < 1e-14);
    assert_eq!(s.delta_max, dm);
    assert!(rel(s.delta_0, (1.0 - s.k1_t / p.k2_of(dm)) * dm) < 1e-14);
    // the contact at its old δ_0 is now compressed less: the force at fixed δ drops
    let f_hot = normal_force(&p, &mut s, 0.95 * dm, 0.0).elastic;
    let mut c = cold(&p);
    normal_force(&p, &mut c, dm, 0.0);
    let f_cold = normal_force(&p, &mut c, 0.95 * dm, 0.0).elastic;
    assert!(f_hot < f_cold);
    // cool with the freeze: k1(T,t) = k1(T) at once, δ_0 stays, δ_max grows (consistent rule)
    let d0 = s.delta_0;
    update_stiffness(&p, &mut s, C0 + 20.0, 0.1, dt);
    assert_eq!(s.k1_t, p.k1_of_temperature(C0 + 20.0));
    assert_eq!(s.delta_0, d0);
    assert!(s.delta_max > dm);
    assert!(rel((1.0 - s.k1_t / p.k2_of(s.delta_max)) * s.delta_max, d0) < 1e-10);
}

#[test]
fn cooling_rules_on_the_specs_table1_example() {
    // docs/luding.md, cooling rule: δ_0 = 1e-3 r_0 cooled to k1(T,t) = k1: paper 2.0e-3 r_0, consistent 2.0506e-2 r_0
    let base = LudingSpec { t_melt: 1000.0, ..LudingSpec::default() }; // 300 K is then k1(T) = k1 to e^-140
    for (rule, want) in [(CoolingRule::Paper, 2.0e-3), (CoolingRule::Consistent, 2.0506e-2)] {
        let p = LudingParams::new(&LudingSpec { cooling: rule, ..base.clone() }, R0).unwrap();
        let mut s = LudingState { delta_max: 1e-3 * R0, delta_0: 1e-3 * R0, xi: Vector3::zeros(), k1_t: 0.3 * p.k1, sliding: false };
        update_stiffness(&p, &mut s, 300.0, 1e3, 1e-6);
        assert_eq!(s.k1_t, p.k1);
        assert!(rel(s.delta_max / R0, want) < 5e-5, "{rule:?}: {}", s.delta_max / R0);
        assert_eq!(s.delta_0, 1e-3 * R0);
    }
    // consistent = the state of a cold contact virgin-loaded to the same δ_0
    let p = LudingParams::new(&base, R0).unwrap();
    let mut s = LudingState::new(&p, 300.0);
    normal_force(&p, &mut s, 2.0506e-2 * R0, 0.0);
    assert!(rel(s.delta_0, 1e-3 * R0) < 5e-5, "{}", s.delta_0 / R0);
}

/// RK4 integration of eq. 12 at constant k1(T) from k_start over t with n steps.
fn rk4_eq12(k_start: f64, k_t: f64, t0: f64, t: f64, n: usize) -> f64 {
    let f = |k: f64| {
        let d = k_t - k;
        d * d.abs() / (k_t * t0)
    };
    let h = t / n as f64;
    let mut k = k_start;
    for _ in 0..n {
        let a = f(k);
        let b = f(k + 0.5 * h * a);
        let c = f(k + 0.5 * h * b);
        let d = f(k + h * c);
        k += h / 6.0 * (a + 2.0 * b + 2.0 * c + d);
    }
    k
}

#[test]
fn relaxation_closed_form_solves_eq12_on_both_branches() {
    // paper Fig. 6: k1(T_0) = 1 → k1(T) = 0.6 with t_0 = 10 s; down branch = paper eq. 11
    let (k_t, t0) = (0.6, 10.0);
    for &t in &[0.1, 1.0, 10.0, 100.0, 1e3, 1e4] {
        let k = relax(1.0, k_t, t0, t);
        let eq11 = k_t * (1.0 - 1.0 / (1.0 / (1.0 - 1.0 / k_t) - t / t0));
        assert!(rel(k, eq11) < 1e-13, "t = {t}: {k} vs eq. 11 {eq11}");
        assert!(rel(k, rk4_eq12(1.0, k_t, t0, t, 20000)) < 1e-9, "t = {t}");
        assert!(k > k_t && k <= 1.0);
    }
    // algebraic (not exponential) approach: k − k1(T) ≈ k1(T)·t_0/t for t ≫ t_0
    let k = relax(1.0, k_t, t0, 1e6);
    assert!(rel(k - k_t, k_t * t0 / 1e6) < 1e-3);
    // up branch (no freeze): x_0 = 0.5, t_0 = 10 s: 0.524 at t = 1 s where eq. 11 gives 0.474
    let k = relax(0.5, 1.0, 10.0, 1.0);
    assert!((k - 0.52381).abs() < 1e-5, "{k}");
    let eq11: f64 = 1.0 - 1.0 / (1.0 / (1.0 - 0.5) - 1.0 / 10.0);
    assert!((eq11 - 0.47368).abs() < 1e-5);
    assert!(rel(k, rk4_eq12(0.5, 1.0, 10.0, 1.0, 20000)) < 1e-10);
}

#[test]
fn stepwise_relaxation_is_exact_at_constant_temperature() {
    // Updating with the closed form from the previous step's k1(T,t) composes exactly (semigroup),
    // whatever the steps: the integrated rate equals the closed form at the end time.
    let spec = LudingSpec { freeze_on_cooling: false, ..LudingSpec::default() };
    let p = LudingParams::new(&spec, R0).unwrap();
    let t_hot = C0 + 125.0;
    let t0 = 0.1;
    for (start, target_t) in [(C0 + 80.0, t_hot), (t_hot, C0 + 80.0)] {
        let mut s = LudingState::new(&p, start);
        let k_start = s.k1_t;
        let mut t = 0.0;
        let mut i = 0;
        while t < 2.0 {
            let dt = 1e-3 * (1.0 + (i % 7) as f64);
            update_stiffness(&p, &mut s, target_t, t0, dt);
            t += dt;
            i += 1;
        }
        let want = relax(k_start, p.k1_of_temperature(target_t), t0, t);
        assert!(rel(s.k1_t, want) < 1e-12, "{} vs {want}", s.k1_t);
    }
    // with the freeze (default), cooling sets k1(T,t) = k1(T) at once
    let p = params();
    let mut s = LudingState::new(&p, t_hot);
    update_stiffness(&p, &mut s, C0 + 80.0, 1e3, 1e-6);
    assert_eq!(s.k1_t, p.k1_of_temperature(C0 + 80.0));
}

#[test]
fn thermal_expansion_changes_the_radius_at_constant_mass() {
    let p = params();
    let r_m = 1e-3;
    assert_eq!(p.radius(r_m, p.t_melt), r_m);
    // 80 °C: 40 K below T_melt, α_r = 1e-4/K: 0.4 % smaller
    assert!(rel(p.radius(r_m, C0 + 80.0), r_m * (1.0 - 40e-4)) < 1e-15);
    let r80 = p.radius(r_m, C0 + 80.0);
    assert!(rel(p.radius_from(r80, C0 + 80.0, C0 + 140.0), p.radius(r_m, C0 + 140.0)) < 1e-14);
    // constant mass: ρ(T)/ρ(T_melt) = (r(T_melt)/r(T))³
    let rho_ratio = (r_m / r80).powi(3);
    assert!(rho_ratio > 1.0 && rel(rho_ratio, 1.0 / (1.0 - 40e-4f64).powi(3)) < 1e-14);
}

#[test]
fn cohesion_and_friction_scale_with_k1_t_and_k2() {
    let p = params();
    let dm = 0.25 * p.delta_max_fluid;
    let k1_hot = p.k1_of_temperature(C0 + 130.0);
    // eq. 13
    let kc = p.kc_of(k1_hot, dm);
    assert!(rel(kc, (k1_hot / p.k1) * (p.k2_of(dm) / p.k2) * p.kc) < 1e-15);
    assert!(rel(p.kc_of(p.k1, 2.0 * p.delta_max_fluid), p.kc) < 1e-15);
    // eq. 24
    assert!(rel(p.friction_of(k1_hot), p.friction * 0.119203) < 1e-5);
    // eq. 15 equals −kc·δ_min and vanishes with the overlap
    assert!(rel(p.f_min(k1_hot, dm), -kc * p.delta_min(k1_hot, dm)) < 1e-14);
    assert_eq!(p.f_min(k1_hot, 0.0), 0.0);
    // kc = 0: no attraction, the cone's lower line is f = 0 and δ_0 follows unloading below it
    let p0 = LudingParams::new(&LudingSpec { kc: 0.0, ..LudingSpec::default() }, R0).unwrap();
    let mut s = cold(&p0);
    normal_force(&p0, &mut s, 5e-5, 0.0);
    let f = normal_force(&p0, &mut s, 1e-6, 0.0).elastic;
    assert_eq!(f, 0.0);
    assert!(rel(s.delta_0, 1e-6) < 1e-12);
    assert_eq!(p0.f_min(p0.k1, 5e-5), 0.0);
}

#[test]
fn tangential_spring_sticks_slides_and_stays_in_the_tangent_plane() {
    let p = params();
    let mut s = cold(&p);
    let dm = 5e-5;
    let f_n = normal_force(&p, &mut s, dm, 0.0).total;
    let n = Vector3::new(0.0, 0.0, 1.0);
    let f_min = p.f_min(s.k1_t, s.delta_max);
    let f_c = p.friction_of(s.k1_t) * (f_n - f_min);
    let kt = p.tangential_ratio * p.k2_of(s.delta_max);
    let dt = 1e-6;
    // stick: constant small surface velocity; f = −k_t ξ − γ_t v_t with ξ = Σ v_t Δt
    let v = Vector3::new(1e-3, 0.0, 0.0);
    let mut steps = 0;
    loop {
        let xi_before = s.xi;
        let t = tangential_force(&p, &mut s, &n, &v, f_n, dt);
        if t.sliding {
            // slide at the limit, along the trial direction, spring reset to the limit (eq. 21)
            assert!(rel(t.force.norm(), f_c) < 1e-12);
            let trial = -kt * xi_before - p.gamma_t * v;
            assert!((t.force / t.force.norm() - trial / trial.norm()).norm() < 1e-12);
            let next_trial = -kt * s.xi - p.gamma_t * v;
            assert!(rel(next_trial.norm(), f_c) < 1e-12);
            assert!((next_trial - t.force).norm() < 1e-12 * f_c);
            break;
        }
        let want = -kt * xi_before - p.gamma_t * v;
        assert!((t.force - want).norm() <= 1e-15 * want.norm().max(1e-30));
        assert!(t.force.norm() <= f_c);
        assert!((s.xi - (xi_before + v * dt)).norm() < 1e-18);
        steps += 1;
        assert!(steps < 10_000_000, "never slid");
    }
    // it slid when k_t·ξ + γ_t·v reached f_C
    let xi_stick = (f_c - p.gamma_t * v.norm()) / kt;
    assert!((steps as f64 * v.norm() * dt - xi_stick).abs() <= 2.0 * v.norm() * dt);
    // keep sliding: force stays at the limit
    // (the reset spring sits exactly on the limit: the next step sticks there, the one after slides)
    for _ in 0..10 {
        let t = tangential_force(&p, &mut s, &n, &v, f_n, dt);
        assert!(rel(t.force.norm(), f_c) < 1e-9);
    }
    // rotate the contact frame: ξ is projected into the new tangent plane (eq. 16)
    let th: f64 = 0.1;
    let n2 = Vector3::new(th.sin(), 0.0, th.cos());
    let t = tangential_force(&p, &mut s, &n2, &Vector3::zeros(), f_n, dt);
    assert!(n2.dot(&s.xi).abs() < 1e-15 * s.xi.norm());
    assert!(n2.dot(&t.force).abs() < 1e-12 * t.force.norm());
    // normal components of the surface velocity are ignored (eq. 17)
    let mut a = s;
    let mut b = s;
    let ta = tangential_force(&p, &mut a, &n2, &Vector3::new(0.0, 2e-4, 0.0), f_n, dt);
    let tb = tangential_force(&p, &mut b, &n2, &(Vector3::new(0.0, 2e-4, 0.0) + 5e-3 * n2), f_n, dt);
    assert!((ta.force - tb.force).norm() < 1e-15 && (a.xi - b.xi).norm() < 1e-20);
}

#[test]
fn cohesion_shifts_the_coulomb_limit_and_temperature_lowers_it() {
    let p = params();
    let mut s = cold(&p);
    normal_force(&p, &mut s, 5e-5, 0.0);
    let f_min = p.f_min(s.k1_t, s.delta_max);
    assert!(f_min < 0.0);
    // static friction at zero normal force (paper §3.6): f_C = μ·(0 − f_min) > 0
    let n = Vector3::z();
    let t = tangential_force(&p, &mut s, &n, &Vector3::zeros(), 0.0, 1e-6);
    assert!(rel(t.limit, -p.friction_of(s.k1_t) * f_min) < 1e-14);
    // at f_n = f_min the limit vanishes: any tangential load slides with zero force
    s.xi = Vector3::new(1e-6, 0.0, 0.0);
    let t = tangential_force(&p, &mut s, &n, &Vector3::zeros(), f_min, 1e-6);
    assert!(t.sliding && t.force.norm() < 1e-20);
    // hot contact: μ(T,t) = μ·k1(T,t)/k1
    let mut h = LudingState::new(&p, C0 + 130.0);
    let f_n = normal_force(&p, &mut h, 5e-5, 0.0).total;
    let t = tangential_force(&p, &mut h, &n, &Vector3::zeros(), f_n, 1e-6);
    let want = p.friction * h.k1_t / p.k1 * (f_n - p.f_min(h.k1_t, h.delta_max));
    assert!(rel(t.limit, want) < 1e-14);
}

#[test]
fn paper_option_drops_cohesion_while_sliding() {
    let mk = |keep: bool| LudingParams::new(&LudingSpec { cohesion_while_sliding: keep, ..LudingSpec::default() }, R0).unwrap();
    for keep in [true, false] {
        let p = mk(keep);
        let mut s = cold(&p);
        let n = Vector3::z();
        let kin = |d: f64, v: Vector3<f64>| ContactKinematics { normal: n, overlap: d, overlap_rate: 0.0, surface_velocity: v };
        contact_force(&p, &mut s, &kin(5e-5, Vector3::zeros()), C0 + 20.0, 1e3, 1e-6);
        // pull to the attractive part and shear hard: sliding
        let d = 0.5 * (s.delta_0 + p.delta_min(s.k1_t, s.delta_max));
        s.xi = Vector3::new(1e-3, 0.0, 0.0);
        let out = contact_force(&p, &mut s, &kin(d, Vector3::zeros()), C0 + 20.0, 1e3, 1e-6);
        assert!(out.sliding && out.normal_parts.total < 0.0);
        if keep {
            assert_eq!(out.normal, out.normal_parts.total);
        } else {
            assert_eq!(out.normal, 0.0);
        }
    }
}

#[test]
fn surface_velocity_is_eq18() {
    let n = Vector3::new(0.0, 0.0, 1.0);
    let (ri, rj) = (1e-3, 2e-3);
    let w_i = Vector3::new(0.0, 3.0, 0.0);
    let w_j = Vector3::new(0.0, -1.0, 0.0);
    let v = surface_velocity(&n, &Vector3::new(0.1, 0.0, 0.2), &Vector3::zeros(), &w_i, &w_j, ri, rj);
    // contact point of i at x_i − r_i n moves with v_i + ω_i × (−r_i n); of j with v_j + ω_j × (r_j n)
    let pi = Vector3::new(0.1, 0.0, 0.2) + w_i.cross(&(-ri * n));
    let pj = w_j.cross(&(rj * n));
    assert!((v - (pi - pj)).norm() < 1e-15);
}

#[test]
fn bad_parameters_are_rejected_with_the_key_named() {
    let d = LudingSpec::default;
    let cases: Vec<(LudingSpec, &str, bool)> = vec![
        (LudingSpec { k2: 0.5e5, ..d() }, "luding.k2", true),
        (LudingSpec { k2: 1e5, ..d() }, "luding.k2", true),
        (LudingSpec { k1: -1.0, ..d() }, "luding.k1", false),
        (LudingSpec { kc: -1.0, ..d() }, "luding.kc", false),
        (LudingSpec { t_var: 0.0, ..d() }, "luding.t_var", false),
        (LudingSpec { t_var: -5.0, ..d() }, "luding.t_var", false),
        (LudingSpec { gamma_n: -0.1, ..d() }, "luding.gamma_n", false),
        (LudingSpec { friction: -0.5, ..d() }, "luding.friction", false),
        (LudingSpec { t0: 0.0, ..d() }, "luding.t0", false),
        (LudingSpec { fluid_overlap: 1.0, ..d() }, "luding.fluid_overlap", false),
        (LudingSpec { expansion: 5e-3, ..d() }, "luding.expansion", true),
        (LudingSpec { tangential_ratio: 0.0, ..d() }, "luding.tangential_ratio", false),
        (LudingSpec { k1: f64::NAN, ..d() }, "luding.k1", false),
    ];
    for (spec, key, inconsistent) in cases {
        let e = LudingParams::new(&spec, R0).unwrap_err();
        assert_eq!(key_of(&e), key, "{e}");
        assert_eq!(matches!(e, ConfigError::Inconsistent { .. }), inconsistent, "{e}");
        assert!(e.to_string().contains(key));
    }
    let e = LudingParams::new(&d(), 0.0).unwrap_err();
    assert!(e.to_string().contains("luding.fluid_overlap"));
}

#[test]
fn toml_section_parses_with_defaults_and_rejects_unknown_keys() {
    let v: toml::Value = toml::from_str(
        r#"
k1 = 1.0e5
k2 = 2.0e5
kc = 1.0e5
t_melt = 393.15
t_var = 10.0
t0 = 0.1
cooling = "paper"
freeze_on_cooling = true
contact_temperature = "harmonic"
"#,
    )
    .unwrap();
    let p = LudingParams::from_value(v, 1e-3).unwrap();
    assert_eq!(p.cooling, CoolingRule::Paper);
    assert_eq!(p.t0, 0.1);
    assert_eq!(p.friction, 0.5);
    assert!(rel(p.delta_fluid, 2e-4) < 1e-15);
    let v: toml::Value = toml::from_str("k1 = 1.0e5\nk_2 = 3.0").unwrap();
    let e = LudingParams::from_value(v, 1e-3).unwrap_err().to_string();
    assert!(e.contains("k_2") && e.contains("[luding]"), "{e}");
    let v: toml::Value = toml::from_str("cooling = \"sometimes\"").unwrap();
    assert!(LudingParams::from_value(v, 1e-3).is_err());
}

/// Velocity-Verlet of the relative motion of a pair, `m·δ̈ = f_ext − f_n(δ, δ̇)`, contact
/// temperature `temp` (K), until `t_end` or until the pair separates after contact.
/// Returns (time, δ, δ̇) samples and the final state.
fn pair_run(
    p: &LudingParams,
    s: &mut LudingState,
    m: f64,
    f_ext: f64,
    delta0: f64,
    v0: f64,
    temp: f64,
    t0: f64,
    dt: f64,
    t_end: f64,
) -> (Vec<(f64, f64, f64)>, f64) {
    let (mut d, mut v) = (delta0, v0);
    let mut peak = d;
    update_stiffness(p, s, temp, t0, 0.0);
    let mut acc = (f_ext - normal_force(p, s, d, v).total) / m;
    let mut out = vec![(0.0, d, v)];
    let n = (t_end / dt).round() as usize;
    let mut touched = d > 0.0;
    for i in 1..=n {
        let vh = v + 0.5 * dt * acc;
        d += vh * dt;
        update_stiffness(p, s, temp, t0, dt);
        acc = (f_ext - normal_force(p, s, d, vh).total) / m;
        v = vh + 0.5 * dt * acc;
        touched |= d > 0.0;
        peak = peak.max(d);
        if i % 1000 == 0 || (touched && d <= 0.0) {
            out.push((i as f64 * dt, d, v));
        }
        if touched && d <= 0.0 {
            break;
        }
    }
    (out, peak)
}

#[test]
fn cold_collision_restitution_is_sqrt_k1_over_k2() {
    // Walton–Braun: without cohesion and damping, a head-on collision returns
    // v_out/v_in = √(k1/k2(δ_max)), δ_max = v_in·√(m_ij/k1).
    let spec = LudingSpec { kc: 0.0, gamma_n: 0.0, fluid_overlap: 0.01, ..LudingSpec::default() };
    let p = LudingParams::new(&spec, R0).unwrap();
    let m = 1e-5;
    for v_in in [0.3, 1.0, 1.8] {
        let mut s = LudingState::new(&p, C0 + 20.0);
        let dt = p.contact_duration(m).unwrap() / 2000.0;
        let (out, peak) = pair_run(&p, &mut s, m, 0.0, 0.0, v_in, C0 + 20.0, 1e3, dt, 1.0);
        let (_, d, v_out) = *out.last().unwrap();
        assert!(d <= 0.0 && v_out < 0.0, "did not separate");
        let dm = v_in * (m / s.k1_t).sqrt();
        assert!(rel(peak, dm) < 1e-3, "{peak} vs {dm}");
        let e = (-v_out) / v_in;
        let want = (s.k1_t / p.k2_of(peak)).sqrt();
        assert!(want < 0.95, "k2(δ_max) should differ from k1: {want}");
        assert!((e - want).abs() < 1e-3, "v_in {v_in}: e = {e} vs {want}");
    }
}

#[test]
fn confined_pair_creeps_along_the_loading_line_as_k1_relaxes() {
    // A pair pressed by F at 140 °C (t_0 = 0.1 s): k1(T,t) relaxes down, δ_max is pushed along, and
    // the quasi-static overlap is δ(t) = F/k1(T,t) with k1(T,t) from the closed form of eq. 11.
    let p = params();
    let m = 1e-5;
    let f = 0.1;
    let t_cold = C0 + 20.0;
    let t_hot = C0 + 140.0;
    let mut s = LudingState::new(&p, t_cold);
    let k1s = s.k1_t;
    let d0 = f / k1s;
    normal_force(&p, &mut s, d0, 0.0);
    let dt = p.contact_duration(m).unwrap() / 50.0;
    let (out, _) = pair_run(&p, &mut s, m, f, d0, 0.0, t_hot, 0.1, dt, 0.5);
    let k1_hot = p.k1_of_temperature(t_hot);
    for &(t, d, _) in out.iter().filter(|x| x.0 >= 0.01) {
        let k = relax(k1s, k1_hot, 0.1, t);
        assert!(rel(d, f / k) < 2e-3, "t = {t}: δ = {d} vs F/k1(T,t) = {}", f / k);
    }
    let (_, d_end, _) = *out.last().unwrap();
    assert!(d_end > 40.0 * d0, "the hot contact must creep far: {d_end} vs {d0}");
    assert!(rel(s.delta_max, d_end) < 1e-3 && !s.is_fluid(&p));
}

#[test]
fn docs_snippet_is_a_valid_section_equal_to_the_defaults() {
    let v = doc_snippets("docs/luding.md", "luding");
    assert_eq!(v.len(), 1);
    let p = LudingParams::from_value(v[0].clone(), R0).unwrap();
    assert_eq!(p, params());
}

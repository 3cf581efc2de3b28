//! The 7-DOF model against the reference state of docs/diffusion7.md §11 and the structural
//! invariants of §2, §3, §8.

use sinterdem::models::diffusion7::geometry::{Side, sides};
use sinterdem::models::diffusion7::material::{ContactParams, Material, PathFactors};
use sinterdem::models::diffusion7::{evaluate, initial_state, invariants, rates};

mod common;
use common::rel;

const R: f64 = 25e-6;

fn ref_state() -> [f64; 7] {
    [0.3 * R, R, 0.05 * R, 0.97 * R, R, 0.05 * R, 0.97 * R]
}

fn copper() -> ContactParams {
    ContactParams::single(&Material::copper(), 0, PathFactors::default())
}

#[track_caller]
fn close(name: &str, got: f64, want: f64, tol: f64) {
    assert!(rel(got, want) < tol, "{name}: got {got:.10e}, want {want:.10e} (rel {:.2e})", rel(got, want));
}

/// §11 unit-test state: geometry (G1)–(G6), derivatives (G7), (G8) to 1e-9.
#[test]
fn reference_state_geometry_and_derivatives() {
    let (a, b) = sides(&ref_state()).unwrap();
    assert_eq!(a, b);
    close("h", a.h, 9.7979589711e-6, 1e-9);
    close("s", a.s, 2.6159349061e-6, 1e-9);
    close("tau", a.tau, 6.2346922835e-12, 1e-9);
    close("V_side", a.volume(), 6.5439551286e-14, 1e-9);
    close("A_side", a.area(), 7.6819804876e-9, 1e-9);
    let d = a.derivs().unwrap();
    let dv = [3.2460452387e-11, 7.6303220169e-9, 1.8055598689e-11, 2.1833321829e-10];
    let da = [-3.9519342231e-5, 6.0144651271e-4, 2.3979476937e-7, 2.5727566220e-5];
    for i in 0..4 {
        close(&format!("dV/dy{i}"), d.dv[i], dv[i], 1e-9);
        close(&format!("dA/dy{i}"), d.da[i], da[i], 1e-9);
    }
    // (G9) equals the direct ratio away from tangency
    close("G9", d.ratio_c, d.da[2] / d.dv[2], 1e-10);
}

/// §11: potentials, fluxes, dY/dt and dG/dt to 1e-9 relative.
#[test]
fn reference_state_potentials_fluxes_rates() {
    let k = copper().at(1293.0).unwrap();
    let e = evaluate(&ref_state(), &k).unwrap();
    let mu = [-2.0860684064e-23, 1.6556028074e-24, 2.7895221989e-25, 2.4750324532e-24];
    for i in 0..4 {
        close(&format!("mu{}", i + 1), e.mu[i], mu[i], 1e-9);
    }
    let fl = [1.9370747590e-21, 2.2114850276e-20, 1.7899618611e-20, 3.4654148858e-20, 1.3205071001e-21, 2.5565376900e-21];
    for i in 0..6 {
        close(&format!("J{}", i + 1), e.flux[0][i], fl[i], 1e-9);
        assert_eq!(e.flux[0][i], e.flux[1][i]);
    }
    let dy = [2.3599699595e-9, -5.0811024509e-13, -2.6959351233e-9, -1.1016154676e-10];
    for i in 0..4 {
        close(&format!("dy{}", i + 1), e.dydt[i], dy[i], 1e-9);
    }
    for i in 1..4 {
        assert_eq!(e.dydt[i], e.dydt[i + 3], "B = A");
    }
    close("dG/dt", e.dg_dt, -2.8433453727e-13, 1e-9);
    // rates() is the same function of (y, params, T)
    assert_eq!(rates(&ref_state(), &copper(), 1293.0).unwrap(), e.dydt);
}

/// (M9) diffusivities of docs/diffusion7.md §9.
#[test]
fn diffusivities_match_the_table() {
    let cu = &Material::copper().phases[0];
    let ti = Material::titanium();
    let d = |d0: f64, q: f64, t: f64| sinterdem::units::arrhenius(d0, q, t);
    close("Cu Ds", d(cu.d0_surface, cu.q_surface, 1293.0), 7.909e-9, 1e-3);
    close("Cu Dgb", d(cu.d0_gb, cu.q_gb, 1293.0), 1.709e-9, 1e-3);
    close("Cu Db", d(cu.d0_lattice, cu.q_lattice, 1293.0), 2.693e-13, 1e-3);
    let rows = [
        (793.0, 5.137e-9, 9.463e-12, 3.396e-21),
        (1155.9, 1.107e-5, 2.512e-11, 3.297e-17),
        (1156.0, 2.085e-11, 5.267e-9, 2.369e-14),
        (1373.0, 6.089e-10, 1.994e-7, 2.922e-13),
    ];
    for (t, ds, dgb, db) in rows {
        let ph = &ti.phases[ti.phase_at(t)];
        close("Ti Ds", d(ph.d0_surface, ph.q_surface, t), ds, 1e-3);
        close("Ti Dgb", d(ph.d0_gb, ph.q_gb, t), dgb, 1e-3);
        close("Ti Db", d(ph.d0_lattice, ph.q_lattice, t), db, 1e-3);
    }
    assert_eq!(ti.phase_at(1155.999), 0);
    assert_eq!(ti.phase_at(1156.0), 1);
}

/// §2: central differences of (G4), (G5) agree with (G7), (G8).
#[test]
fn closed_form_derivatives_match_finite_differences() {
    for y in [ref_state(), initial_state(R, 0.6 * R, 1.6 * R * 0.995, 0.01, 0.1).unwrap()] {
        for side in 0..2 {
            let base = if side == 0 { [y[0], y[1], y[2], y[3]] } else { [y[0], y[4], y[5], y[6]] };
            let s = Side::new(base[0], base[1], base[2], base[3]).unwrap();
            let d = s.derivs().unwrap();
            for k in 0..4 {
                let step = 1e-7 * R;
                let mut p = base;
                let mut m = base;
                p[k] += step;
                m[k] -= step;
                let (sp, sm) = (Side::new(p[0], p[1], p[2], p[3]).unwrap(), Side::new(m[0], m[1], m[2], m[3]).unwrap());
                let fv = (sp.volume() - sm.volume()) / (2.0 * step);
                let fa = (sp.area() - sm.area()) / (2.0 * step);
                assert!(rel(fv, d.dv[k]) < 1e-5, "side {side} dV/d{k}: {fv} vs {}", d.dv[k]);
                assert!(rel(fa, d.da[k]) < 1e-5 || (fa - d.da[k]).abs() < 1e-6 * R, "side {side} dA/d{k}: {fa} vs {}", d.da[k]);
            }
        }
    }
}

/// §2: small-neck limit μ_2·R/(2Ωγ_s) → 1.
#[test]
fn small_neck_cap_potential_tends_to_the_sphere() {
    let p = copper();
    let k = p.at(1293.0).unwrap();
    for (eps, want) in [(0.01, 0.999586), (0.001, 0.999996)] {
        let y = initial_state(R, R, 2.0 * R, eps, 0.1).unwrap();
        let e = evaluate(&y, &k).unwrap();
        let ratio = e.mu[1] * R / (2.0 * k.omega * k.gamma_s[0]);
        assert!((ratio - want).abs() < 2e-6, "eps {eps}: {ratio}");
    }
}

/// (I1)–(I4): touching spheres give V ≈ two spheres (+2.3e-9 relative at ε = 0.01), θ = 0.18;
/// overlaps give the documented tangency ratios.
#[test]
fn initial_state_of_touching_and_overlapping_spheres() {
    let y = initial_state(R, R, 2.0 * R, 0.01, 0.1).unwrap();
    assert!(rel(y[3], R) < 1e-14);
    let (v, _) = invariants(&y, &copper()).unwrap();
    let spheres = 2.0 * 4.0 / 3.0 * std::f64::consts::PI * R.powi(3);
    let excess = (v - spheres) / spheres;
    assert!(excess > 0.0 && (excess - 2.3e-9).abs() < 0.2e-9, "{excess}");
    for (ratio, theta) in [(1.0, 0.18), (0.999, 0.41), (0.99, 0.65), (0.9, 0.88)] {
        let y = initial_state(R, R, 2.0 * R * ratio, 0.01, 0.1).unwrap();
        let th = sinterdem::models::diffusion7::contact::tangency(&y).unwrap();
        assert!((th[0] - theta).abs() < 0.006, "centre distance {ratio}·2R: θ = {}", th[0]);
        assert_eq!(th[0], th[1]);
    }
    // bad input: an error, never a panic
    assert!(initial_state(R, R, 2.1 * R, 0.01, 0.1).is_err());
    assert!(initial_state(R, R, 2.0 * R, 0.5, 0.1).is_err());
    assert!(initial_state(-R, R, 2.0 * R, 0.01, 0.1).is_err());
    assert!(initial_state(R, R, f64::NAN, 0.01, 0.1).is_err());
}

/// §3, §8: Σ Q_i = 0 to round-off and d𝒢/dt ≤ 0 at many admissible states,
/// equal and unequal, copper and both titanium phases.
#[test]
fn mass_balance_and_dissipation_at_many_states() {
    let ti = Material::titanium();
    let cu = Material::copper();
    let sets = [
        (ContactParams::single(&cu, 0, PathFactors::default()), 1293.0),
        (ContactParams::single(&ti, 0, PathFactors::default()), 1000.0),
        (ContactParams::single(&ti, 1, PathFactors::default()), 1373.0),
        (ContactParams::new(&cu, 0, &ti, 1, PathFactors::default()), 1300.0),
    ];
    let mut n = 0;
    for (p, t) in &sets {
        let k = p.at(*t).unwrap();
        for (rb, ov) in [(1.0, 0.0), (0.5, 0.0), (0.1, 0.0), (1.0, 0.01), (0.3, 0.02)] {
            for eps in [0.001, 0.01, 0.05, 0.1] {
                let Ok(y) = initial_state(R, rb * R, (1.0 + rb) * R * (1.0 - ov), eps, 0.3) else { continue };
                let e = evaluate(&y, &k).unwrap();
                let qsum: f64 = e.q.iter().sum();
                let qmax = e.q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                assert!(qsum.abs() <= 1e-13 * qmax, "ΣQ = {qsum} vs {qmax}");
                assert!(e.dg_dt <= 0.0, "dG/dt = {}", e.dg_dt);
                // (M10): Σ μ_i Q_i / Ω equals minus the sum of path dissipations
                n += 1;
            }
        }
    }
    assert!(n > 50);
}

/// Inadmissible states are reported as ModelErrors naming the condition, never NaN.
#[test]
fn inadmissible_states_give_model_errors() {
    let p = copper();
    let mut y = ref_state();
    y[2] = -1e-9;
    let e = rates(&y, &p, 1293.0).unwrap_err().to_string();
    assert!(e.contains("(A1)"), "{e}");
    let mut y = ref_state();
    y[3] = 3.0 * R;
    assert!(rates(&y, &p, 1293.0).unwrap_err().to_string().contains("(A2)"));
    let mut y = ref_state();
    y[2] = 1e-3 * R; // junction far out: the cone turns into the sphere
    y[0] = 0.05 * R;
    // side A: p = d − c = 0.969 R, h = √(R² − p²) = 0.247 R, so τ = p·c − h·(h − a)
    // = (0.00097 − 0.0487) R² < 0: the cone runs inside the cap, (A3) is violated
    let e = rates(&y, &p, 1293.0).unwrap_err().to_string();
    assert!(e.contains("side A") && e.contains("(A3)"), "{e}");
    assert!(rates(&ref_state(), &p, f64::NAN).is_err());
    assert!(rates(&ref_state(), &p, -5.0).is_err());
}

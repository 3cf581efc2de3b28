//! Viscous grain-boundary sliding of the bonded links (docs/mechanics.md (B24)–(B28)): the
//! tangential viscosity of (B24) by hand; a pair under a constant tangential force slides at
//! F/η_t per unit time after its elastic jump; a periodic simple-cubic cell under a constant shear
//! stress creeps with the shear viscosity η_t/(2d) of its closed form; a free SC cell is not
//! changed by sliding (symmetry); no sliding is the elastic link bit for bit.

use nalgebra::{Matrix3, Vector3};
use sinterdem::mechanics::periodic::{CellControl, CellInput};
use sinterdem::mechanics::sliding::{Relaxation, maxwell_factor, tangential_viscosity};
use sinterdem::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, NodalLoad, StepInput, dof, link_stiffness};

const E: f64 = 110e9;
const NU: f64 = 0.34;
const R: f64 = 25e-6;

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// (B24) written out: f·(R*/a)²/M_c, R* = 2 R_A R_B/(R_A + R_B); no mobility, no sliding.
#[test]
fn tangential_viscosity_is_the_contact_law() {
    let (a, mobility) = (5e-6, 4.5e-6);
    let eta = tangential_viscosity(1.0, a, R, R, mobility);
    let by_hand = (R / a).powi(2) / mobility;
    assert!(rel(eta, by_hand) < 1e-14, "{eta} vs {by_hand}");
    // R* = 2 R_A R_B/(R_A + R_B) = 4R/3 for R and 2R; the factor scales it
    let mixed = tangential_viscosity(0.01, a, R, 2.0 * R, mobility);
    assert!(rel(mixed, 0.01 * by_hand * (4.0 / 3.0f64).powi(2)) < 1e-14);
    assert_eq!(tangential_viscosity(1.0, a, R, R, 0.0), f64::INFINITY);
    assert_eq!(maxwell_factor(1.0, f64::INFINITY, 1.0), 1.0);
    assert_eq!(maxwell_factor(2.0, 3.0, 0.0), 1.0);
    assert!(rel(maxwell_factor(2.0, 3.0, 0.5), 0.75) < 1e-15);
}

/// Particle 0 held, particle 1 free, the bond along z; a tangential force F along x applied at
/// step 1 (loads are increments) and held. Step 1 is the Maxwell element's elastic jump plus one
/// step of flow; from step 2 on the bending of the link is stationary, so the centre slides by
/// exactly F·Δt/η_t per step (B25)–(B27), and the stored tangential force stays F.
#[test]
fn pair_under_a_constant_tangential_force_slides_at_f_over_eta() {
    let pos = [Vector3::zeros(), Vector3::new(0.0, 0.0, 2.0 * R)];
    let mut cons = Constraints::none(2);
    cons.fix(0, dof::ALL).unwrap();
    let params = MechParams { young_modulus: E, poisson_ratio: NU, solver: LinearSolver::Cholesky, rtol: 1e-13, ..Default::default() };
    let mut sys = BondedSystem::new(2, params, cons).unwrap();
    sys.set_topology(&[[0, 1]]).unwrap();
    let (f, eta, dt) = (1e-3, 2.0e5, 0.7);
    let k_t = link_stiffness(E, NU, R)[0];
    let mut stored = Vec::new();
    // the geometry of the start in every step (small displacements: no turn of the bond)
    let x = pos;
    for step in 0..6 {
        let ext = [NodalLoad::default(), NodalLoad { force: Vector3::new(if step == 0 { f } else { 0.0 }, 0.0, 0.0), moment: Vector3::zeros() }];
        sys.set_relaxation(Some(Relaxation { dt, viscosity: vec![eta], stored: stored.clone(), ..Default::default() }));
        let out = sys.step(&StepInput { positions: &x, radii: &[R, R], y4_y7: &[[R, R]], load: &[0.0], external: Some(&ext) }).unwrap();
        // the link force P_t with ε = u_A − u_B: B is held by −P_t = −F, so P_t = −F along x
        assert!(rel(out.tangential[0].x, -f) < 1e-9 && out.tangential[0].yz().norm() < 1e-12 * f, "step {step}: {:?}", out.tangential[0]);
        if step == 0 {
            // elastic jump plus flow at the bond point: F/(φ k_t) = F/k_t + F Δt/η
            assert!(out.du[1].x > f / k_t + f * dt / eta * 0.999, "{}", out.du[1].x);
        } else {
            assert!(rel(out.du[1].x, f * dt / eta) < 1e-9, "step {step}: {} vs {}", out.du[1].x, f * dt / eta);
            assert!(out.dtheta[1].norm() < 1e-12 * f * dt / eta / R);
        }
        assert!(out.du[1].z.abs() < 1e-9 * out.du[1].x.abs());
        stored = out.tangential;
    }
    // η_t = ∞ (no grain-boundary transport) is the elastic link bit for bit, and so is no sliding
    let step = |relax: Option<Relaxation>| {
        let mut cons = Constraints::none(2);
        cons.fix(0, dof::ALL).unwrap();
        let mut s = BondedSystem::new(2, params, cons).unwrap();
        s.set_topology(&[[0, 1]]).unwrap();
        s.set_relaxation(relax);
        let ext = [NodalLoad::default(), NodalLoad { force: Vector3::new(f, 0.3 * f, -0.2 * f), moment: Vector3::new(0.0, 1e-3 * f * R, 0.0) }];
        s.step(&StepInput { positions: &pos, radii: &[R, R], y4_y7: &[[R, R]], load: &[1e-4], external: Some(&ext) }).unwrap()
    };
    let (el, inf) =
        (step(None), step(Some(Relaxation { dt, viscosity: vec![f64::INFINITY], stored: vec![Vector3::new(2.0 * f, 0.0, 0.0)], ..Default::default() })));
    assert!(el.tangential.is_empty());
    assert_eq!((el.du, el.dtheta, el.xi), (inf.du, inf.dtheta, inf.xi));
}

/// (B30): particle 0 held, particle 1 free, the bond along z, rolling viscosities [η_b, η_tw]
/// and a tangential η_t = ∞ (no sliding). A moment (M_x, 0, M_z) applied at step 1 and held:
/// after the elastic jump the particle rolls about x at M_x/η_b and twists about z at M_z/η_tw
/// per unit time (its centre translates so that the bond point does not slide), the stored
/// moment stays −M; without rolling viscosities the same step is the elastic link bit for bit.
#[test]
fn pair_under_a_constant_moment_rolls_and_twists_at_m_over_eta() {
    let pos = [Vector3::zeros(), Vector3::new(0.0, 0.0, 2.0 * R)];
    let params = MechParams { young_modulus: E, poisson_ratio: NU, solver: LinearSolver::Cholesky, rtol: 1e-13, ..Default::default() };
    let system = || {
        let mut cons = Constraints::none(2);
        cons.fix(0, dof::ALL).unwrap();
        let mut sys = BondedSystem::new(2, params, cons).unwrap();
        sys.set_topology(&[[0, 1]]).unwrap();
        sys
    };
    let mut sys = system();
    let (m, eta_b, eta_tw, dt) = (Vector3::new(2e-9, 0.0, -3e-9), 4.0e-7, 9.0e-7, 0.3);
    let mut stored_moment = Vec::new();
    for step in 0..6 {
        let ext = [NodalLoad::default(), NodalLoad { force: Vector3::zeros(), moment: if step == 0 { m } else { Vector3::zeros() } }];
        let relax =
            Relaxation { dt, viscosity: vec![f64::INFINITY], rolling: vec![[eta_b, eta_tw]], stored_moment: stored_moment.clone(), ..Default::default() };
        sys.set_relaxation(Some(relax));
        let out = sys.step(&StepInput { positions: &pos, radii: &[R, R], y4_y7: &[[R, R]], load: &[0.0], external: Some(&ext) }).unwrap();
        assert!((out.moment[0] + m).norm() < 1e-9 * m.norm(), "step {step}: {:?}", out.moment[0]);
        if step > 0 {
            let (wx, wz) = (out.dtheta[1].x, out.dtheta[1].z);
            assert!(rel(wx, m.x * dt / eta_b) < 1e-9, "step {step}: {wx} vs {}", m.x * dt / eta_b);
            assert!(rel(wz, m.z * dt / eta_tw) < 1e-9, "step {step}: {wz} vs {}", m.z * dt / eta_tw);
            // the centre follows the rolling so that the bond point does not slide: u_y = R θ_x
            assert!(rel(out.du[1].y, -R * wx) < 1e-9 || rel(out.du[1].y, R * wx) < 1e-9, "{} vs {}", out.du[1].y, R * wx);
        }
        stored_moment = out.moment;
    }
    let step = |relax: Option<Relaxation>| {
        let mut s = system();
        s.set_relaxation(relax);
        let ext = [NodalLoad::default(), NodalLoad { force: Vector3::new(1e-3, 0.0, 0.0), moment: m }];
        s.step(&StepInput { positions: &pos, radii: &[R, R], y4_y7: &[[R, R]], load: &[1e-4], external: Some(&ext) }).unwrap()
    };
    let (el, inf) = (step(None), step(Some(Relaxation { dt, viscosity: vec![f64::INFINITY], rolling: vec![[f64::INFINITY; 2]], ..Default::default() })));
    assert!(el.moment.is_empty());
    assert_eq!((el.du, el.dtheta, el.xi), (inf.du, inf.dtheta, inf.xi));
}

/// The periodic SC lattice (3³ touching spheres, d = 2R), all six components, a shear stress
/// Σ_xy applied at step 1 and held: the x-bonds carry the tangential force Σd² along y and the
/// y-bonds along x (their normal forces vanish by symmetry), so from step 2 on the engineering
/// shear grows by 2Σd·Δt/η_t per step: the shear viscosity is η_t/(2d). The normal strains stay 0.
#[test]
fn sc_cell_under_shear_has_the_closed_form_shear_viscosity() {
    let d = 2.0 * R;
    let n1 = 3;
    let mut pos = Vec::new();
    for i in 0..n1 {
        for j in 0..n1 {
            for k in 0..n1 {
                pos.push(Vector3::new(i as f64, j as f64, k as f64) * d);
            }
        }
    }
    let idx = |i: usize, j: usize, k: usize| (((i % n1) * n1 + j % n1) * n1 + k % n1) as u32;
    let mut pairs = Vec::new();
    for i in 0..n1 {
        for j in 0..n1 {
            for k in 0..n1 {
                for (di, dj, dk) in [(1, 0, 0), (0, 1, 0), (0, 0, 1)] {
                    pairs.push([idx(i, j, k), idx(i + di, j + dj, k + dk)]);
                }
            }
        }
    }
    let n = pos.len();
    let cell = Matrix3::identity() * (n1 as f64 * d);
    let (sigma, eta, dt) = (1.0e4, 3.0e5, 2.0);
    for solver in [LinearSolver::Cholesky, LinearSolver::Amg] {
        let params = MechParams { young_modulus: E, poisson_ratio: NU, solver, rtol: 1e-13, ..Default::default() };
        let mut sys = BondedSystem::new(n, params, Constraints::none(n)).unwrap();
        sys.set_topology(&pairs).unwrap();
        let mut stored = Vec::new();
        let mut x = pos.clone();
        let mut l = cell;
        for step in 0..5 {
            let mut controls = [CellControl::Stress(0.0); 6];
            if step == 0 {
                controls[5] = CellControl::Stress(sigma);
            }
            sys.set_relaxation(Some(Relaxation { dt, viscosity: vec![eta; pairs.len()], stored: stored.clone(), ..Default::default() }));
            let y = vec![[R, R]; pairs.len()];
            let zero = vec![0.0; pairs.len()];
            let (out, cs) = sys
                .step_periodic(
                    &StepInput { positions: &x, radii: &vec![R; n], y4_y7: &y, load: &zero, external: None },
                    &CellInput { cell: &l, controls: &controls },
                )
                .unwrap();
            if step > 0 {
                let gamma = 2.0 * sigma * d * dt / eta;
                assert!(rel(cs.strain[5], gamma) < 1e-6, "{solver:?} step {step}: shear {} vs {gamma}", cs.strain[5]);
                // the shear viscosity Σ/γ̇ = η_t/(2d)
                assert!(rel(sigma / (cs.strain[5] / dt), eta / (2.0 * d)) < 1e-6);
            }
            // the normal strains: only the second-order turn of the sheared bonds (γ ≈ 7e-6 per step)
            assert!(cs.strain[..5].iter().all(|e| e.abs() < 1e-4 * cs.strain[5].abs()), "{:?}", cs.strain);
            // x- and y-bonds carry Σd², the z-bonds (every third) nothing
            for (c, t) in out.tangential.iter().enumerate() {
                if c % 3 == 2 {
                    assert!(t.norm() < 1e-9 * sigma * d * d, "bond {c}: {t:?}");
                } else {
                    assert!(rel(t.norm(), sigma * d * d) < 1e-6, "bond {c}: {t:?}");
                }
            }
            let de = sinterdem::mechanics::periodic::strain_tensor(&cs.strain);
            for (xi, du) in x.iter_mut().zip(&out.du) {
                *xi += du;
            }
            l = (Matrix3::identity() + de) * l;
            stored = out.tangential;
        }
    }
}

/// The viscous network of a load distribution (docs/mechanics.md (B29)) on a periodic FCC lattice
/// (2³ cells, 32 spheres, nearest-neighbour bonds, d = 2R): every site is a centre of symmetry,
/// so the network deforms affinely and its response is the closed form of the bond sums over the
/// six directions (1,±1,0), (1,0,±1), (0,1,±1)/√2 with V = d³/√2 per particle:
/// under σ_zz = −S, σ_xx = σ_yy = 0 the strain-rate ratio is ν = (η_n − η_t)/(3η_n + η_t) and
/// σ_zz = (d²/V)[η_n(ε̇_xx + ε̇_zz) + η_t(ε̇_zz − ε̇_xx)]; under a hydrostatic stress the bulk
/// viscosity is (2√2/3)·η_n/d, whatever η_t; the bonds in the xy plane carry the normal force
/// −η_n d ε̇_xx and no tangential force. Rolling and twisting do not enter (no particle turns).
#[test]
fn fcc_viscous_network_has_the_closed_form_poisson_ratio_and_bulk_viscosity() {
    let d = 2.0 * R;
    let a0 = d * 2f64.sqrt();
    let n1 = 2;
    let mut pos = Vec::new();
    for i in 0..n1 {
        for j in 0..n1 {
            for k in 0..n1 {
                let o = Vector3::new(i as f64, j as f64, k as f64) * a0;
                for b in [[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]] {
                    pos.push(o + Vector3::new(b[0], b[1], b[2]) * a0);
                }
            }
        }
    }
    let n = pos.len();
    let box_l = n1 as f64 * a0;
    let mut pairs = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let mut v = pos[j] - pos[i];
            v.iter_mut().for_each(|x| *x -= box_l * (*x / box_l).round());
            if rel(v.norm(), d) < 1e-9 {
                pairs.push([i as u32, j as u32]);
            }
        }
    }
    assert_eq!(pairs.len(), 6 * n);
    let cell = Matrix3::identity() * box_l;
    let (eta_n, eta_t) = (2.0e5, 6.0e4);
    let (bend, twist) = (eta_n * (0.3 * R).powi(2) / 12.0, eta_t * (0.3 * R).powi(2) / 2.0);
    let links = vec![[eta_t, eta_t, eta_n, bend, bend, twist]; pairs.len()];
    let s = 1.0e5;
    let vp = d.powi(3) / 2f64.sqrt();
    for solver in [LinearSolver::Cholesky, LinearSolver::Amg] {
        let params = MechParams { young_modulus: E, poisson_ratio: NU, solver, rtol: 1e-13, ..Default::default() };
        let solve = |stress: [f64; 3]| {
            let mut sys = BondedSystem::new(n, params, Constraints::none(n)).unwrap();
            sys.set_topology(&pairs).unwrap();
            sys.set_relaxation(Some(Relaxation { dt: 1.0, viscosity: vec![eta_t; pairs.len()], network: links.clone(), ..Default::default() }));
            let mut controls = [CellControl::Stress(0.0); 6];
            for a in 0..3 {
                controls[a] = CellControl::Stress(stress[a]);
            }
            let y = vec![[R, R]; pairs.len()];
            let zero = vec![0.0; pairs.len()];
            sys.step_periodic(
                &StepInput { positions: &pos, radii: &vec![R; n], y4_y7: &y, load: &zero, external: None },
                &CellInput { cell: &cell, controls: &controls },
            )
            .unwrap()
        };
        let (out, cs) = solve([0.0, 0.0, -s]);
        let (ex, ey, ez) = (cs.strain[0], cs.strain[1], cs.strain[2]);
        let nu = (eta_n - eta_t) / (3.0 * eta_n + eta_t);
        assert!(rel(-ex / ez, nu) < 1e-6 && rel(ey, ex) < 1e-6, "{solver:?}: nu {} vs {nu}", -ex / ez);
        let szz = d * d / vp * (eta_n * (ex + ez) + eta_t * (ez - ex));
        assert!(rel(szz, -s) < 1e-6, "{solver:?}: sigma_zz {szz} vs {}", -s);
        assert!(cs.strain[3..].iter().all(|e| e.abs() < 1e-9 * ez.abs()), "{:?}", cs.strain);
        for (c, &[a, b]) in pairs.iter().enumerate() {
            let mut v = pos[b as usize] - pos[a as usize];
            v.iter_mut().for_each(|x| *x -= box_l * (*x / box_l).round());
            if v.z.abs() < 1e-9 * d {
                // an xy-plane bond: approach −d ε̇_xx under η_n, no tangential force
                assert!(rel(cs.axial_force[c], -eta_n * d * ex) < 1e-6, "bond {c}: {} vs {}", cs.axial_force[c], -eta_n * d * ex);
                assert!(out.dtheta[a as usize].norm() < 1e-9 * ez.abs(), "no particle turns");
            }
        }
        let (_, cs) = solve([-s; 3]);
        let ev: f64 = cs.strain[..3].iter().sum();
        let bulk = -s / ev;
        assert!(rel(bulk, 2.0 * 2f64.sqrt() / 3.0 * eta_n / d) < 1e-6, "{solver:?}: K {bulk} vs {}", 2.0 * 2f64.sqrt() / 3.0 * eta_n / d);
    }
}

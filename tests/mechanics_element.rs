//! The bonded link (docs/mechanics.md (B1)–(B7)): symmetry, exactly six zero
//! eigenvalues spanned by the rigid modes, self-equilibrated nodal forces, the paper's eq. 37 signs
//! failing the same checks; constraints, rattlers, pins and bad input.

use nalgebra::{DMatrix, Matrix3, SMatrix, SymmetricEigen, Vector3};
use sinterdem::Error;
use sinterdem::mechanics::bond::{BondGeometry, element_blocks, element_matrix, frame, h_matrix, link_forces, link_stiffness};
use sinterdem::mechanics::{BondedSystem, Constraints, MechParams, NodalLoad, StepInput, dof};
use std::f64::consts::PI;

type V12 = SMatrix<f64, 12, 1>;

fn rng(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

fn unit(seed: &mut u64) -> Vector3<f64> {
    Vector3::new(rng(seed) - 0.5, rng(seed) - 0.5, rng(seed) - 0.5).normalize()
}

/// A link in a random orientation between unequal particles (R_A = 25 µm, R_B = 15 µm), with a
/// sintered overlap and y4 + y7 ≠ d (so the scaling to d is exercised).
fn random_link(seed: &mut u64) -> (Vector3<f64>, Vector3<f64>, BondGeometry, [f64; 6], f64) {
    let (ra, rb) = (25e-6, 15e-6);
    let x_a = Vector3::new(rng(seed), rng(seed), rng(seed)) * 1e-3;
    let d = 0.97 * (ra + rb);
    let x_b = x_a + unit(seed) * d;
    let (y4, y7) = (0.6 * d * 1.001, 0.4 * d * 1.002);
    let g = BondGeometry::new(&x_a, &x_b, y4, y7).unwrap();
    let k = link_stiffness(110e9, 0.34, 0.5 * (ra + rb));
    (x_a, x_b, g, k, 0.5 * (ra + rb))
}

/// Rigid modes in scaled unknowns [u_A, r̄θ_A, u_B, r̄θ_B]: three translations, three rotations
/// about the origin (u = ω × x, θ = ω).
fn rigid_modes(x_a: &Vector3<f64>, x_b: &Vector3<f64>, rbar: f64) -> Vec<V12> {
    let mut v = Vec::new();
    for j in 0..3 {
        let mut t = V12::zeros();
        t[j] = 1.0;
        t[6 + j] = 1.0;
        v.push(t);
    }
    for j in 0..3 {
        let mut w = Vector3::zeros();
        w[j] = 1.0;
        let mut r = V12::zeros();
        r.fixed_rows_mut::<3>(0).copy_from(&w.cross(x_a));
        r.fixed_rows_mut::<3>(3).copy_from(&(w * rbar));
        r.fixed_rows_mut::<3>(6).copy_from(&w.cross(x_b));
        r.fixed_rows_mut::<3>(9).copy_from(&(w * rbar));
        v.push(r);
    }
    v
}

#[test]
fn link_stiffness_matches_the_spec_constants() {
    let (e, nu, rm) = (110e9, 0.34, 20e-6);
    let k = link_stiffness(e, nu, rm);
    let g = e / (2.0 * (1.0 + nu));
    let lb = 2.0 * rm;
    // axial constant shared with the load (F5): EA/L_b = (π/2)·E·R_m
    assert!((k[2] / (0.5 * PI * e * rm) - 1.0).abs() < 1e-15);
    assert!((k[0] / (g * PI * rm * rm / lb) - 1.0).abs() < 1e-15);
    assert!((k[3] / (e * PI * rm.powi(4) / 4.0 / lb) - 1.0).abs() < 1e-15);
    assert!((k[5] / (g * PI * rm.powi(4) / 2.0 / lb) - 1.0).abs() < 1e-15);
    assert_eq!(k[0], k[1]);
    assert_eq!(k[3], k[4]);
}

#[test]
fn frame_is_orthonormal_and_right_handed() {
    let mut s = 3u64;
    for _ in 0..50 {
        let e3 = unit(&mut s);
        let r = frame(&e3);
        assert!((r * r.transpose() - Matrix3::identity()).abs().max() < 1e-15);
        assert!((r.determinant() - 1.0).abs() < 1e-14);
        assert!((r.row(2).transpose() - e3).norm() < 1e-15);
    }
    for e3 in [Vector3::x(), -Vector3::y(), Vector3::z()] {
        assert!((frame(&e3).determinant() - 1.0).abs() < 1e-15);
    }
}

#[test]
fn element_is_symmetric_with_exactly_six_rigid_zero_modes() {
    let mut s = 11u64;
    for _ in 0..20 {
        let (x_a, x_b, g, k, rbar) = random_link(&mut s);
        // the bond points coincide after the scaling to d
        assert!(((x_a + g.l_a) - (x_b + g.l_b)).norm() < 1e-15 * x_a.norm().max(1e-3));
        let ke = element_matrix(&g, &k, rbar);
        let kmax = ke.abs().max();
        assert!((ke - ke.transpose()).abs().max() <= 1e-15 * kmax, "not symmetric");
        let eig = SymmetricEigen::new(DMatrix::from_column_slice(12, 12, ke.as_slice()));
        let lmax = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
        let zero: Vec<usize> = (0..12).filter(|&i| eig.eigenvalues[i].abs() < 1e-12 * lmax).collect();
        assert_eq!(zero.len(), 6, "eigenvalues {:?}", eig.eigenvalues);
        assert!(eig.eigenvalues.iter().filter(|l| **l > 1e-6 * lmax).count() == 6);
        // every rigid mode is annihilated…
        let modes = rigid_modes(&x_a, &x_b, rbar);
        for m in &modes {
            assert!((ke * m).norm() <= 1e-12 * lmax * m.norm(), "rigid mode carries energy");
        }
        // …and the null space is spanned by them: each zero eigenvector lies in their span
        let basis = DMatrix::from_columns(&modes.iter().map(|m| nalgebra::DVector::from_column_slice(m.as_slice())).collect::<Vec<_>>());
        let q = basis.qr().q();
        for &i in &zero {
            let v = eig.eigenvectors.column(i).into_owned();
            let rest = &v - &q * (q.transpose() * &v);
            assert!(rest.norm() < 1e-8, "zero mode outside the rigid span: {}", rest.norm());
        }
    }
}

#[test]
fn element_blocks_are_the_blocks_of_the_element_matrix() {
    let mut s = 17u64;
    for _ in 0..50 {
        let (_, _, g, k, rbar) = random_link(&mut s);
        let ke = element_matrix(&g, &k, rbar);
        let kmax = ke.abs().max();
        let (kaa, kab, kbb) = element_blocks(&g, &k, rbar);
        for (blk, (r, c)) in [(kaa, (0, 0)), (kab, (0, 6)), (kbb, (6, 6))] {
            let d = (blk - ke.fixed_view::<6, 6>(r, c)).abs().max();
            assert!(d <= 1e-14 * kmax, "block ({r}, {c}) differs by {d:e} of {kmax:e}");
        }
    }
}

#[test]
fn nodal_forces_are_self_equilibrated() {
    let mut s = 5u64;
    for _ in 0..20 {
        let (x_a, x_b, g, k, rbar) = random_link(&mut s);
        let ke = element_matrix(&g, &k, rbar);
        let y = V12::from_fn(|_, _| (rng(&mut s) - 0.5) * 1e-8);
        let p = ke * y;
        // unscale: moments are divided by r̄ in the scaled system
        let (fa, ma) = (p.fixed_rows::<3>(0).into_owned(), p.fixed_rows::<3>(3) * rbar);
        let (fb, mb) = (p.fixed_rows::<3>(6).into_owned(), p.fixed_rows::<3>(9) * rbar);
        let fscale = fa.norm() + fb.norm();
        let mscale = x_a.norm() * fa.norm() + x_b.norm() * fb.norm() + ma.norm() + mb.norm();
        assert!((fa + fb).norm() <= 1e-14 * fscale, "ΣF = {:?}", fa + fb);
        let m_tot = x_a.cross(&fa) + x_b.cross(&fb) + ma + mb;
        assert!(m_tot.norm() <= 1e-13 * mscale, "ΣM = {:e} of {:e}", m_tot.norm(), mscale);
        // the written-out form F_A = F_link, M_A = M_link + l_A0 × F_link (global axes)
        let pl = link_forces(&g, &k, rbar, &y);
        let r = frame(&g.e3);
        let f_link = r.transpose() * Vector3::new(pl[0], pl[1], pl[2]);
        let m_link = r.transpose() * Vector3::new(pl[3], pl[4], pl[5]);
        assert!((fa - f_link).norm() <= 1e-13 * fscale);
        assert!((ma - (m_link + g.l_a.cross(&f_link))).norm() <= 1e-12 * (ma.norm() + 1e-30));
        assert!((mb - (-m_link - g.l_b.cross(&f_link))).norm() <= 1e-12 * (mb.norm() + 1e-30));
    }
}

/// The paper's eq. 37 (M_A = M_link − l_A0 × F_link, M_B = −M_link + l_B0 × F_link) is the transfer
/// matrix H with the skew blocks negated: it still kills the rigid modes (the kinematics are right)
/// but the matrix is not symmetric and a shear force leaves the moment 2(l_B0 − l_A0) × F_link.
#[test]
fn paper_eq37_signs_fail_symmetry_and_moment_balance() {
    let mut s = 17u64;
    let (x_a, x_b, g, k, _) = random_link(&mut s);
    let r = frame(&g.e3);
    let mut rr = SMatrix::<f64, 6, 6>::zeros();
    rr.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    rr.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    let d = SMatrix::<f64, 6, 6>::from_diagonal(&nalgebra::Vector6::from_row_slice(&k));
    let b_right = rr * h_matrix(&g.l_a, &g.l_b);
    let b_paper = rr * h_matrix(&(-g.l_a), &(-g.l_b));
    let k_right = b_right.transpose() * d * b_right;
    let k_paper = b_paper.transpose() * d * b_right;
    let kmax = k_right.abs().max();
    assert!((k_right - k_right.transpose()).abs().max() <= 1e-15 * kmax);
    let asym = (k_paper - k_paper.transpose()).abs().max();
    assert!(asym > 1e-6 * kmax, "eq. 37 matrix unexpectedly symmetric");
    for m in rigid_modes(&x_a, &x_b, 1.0) {
        assert!((k_paper * m).norm() <= 1e-9 * kmax * m.norm());
    }
    // pure shear displacement of B along e1: moment imbalance of the eq. 37 transfer
    let mut y = V12::zeros();
    y.fixed_rows_mut::<3>(6).copy_from(&(r.row(0).transpose() * 1e-9));
    for (kk, expect_balanced) in [(k_right, true), (k_paper, false)] {
        let p = kk * y;
        let (fa, ma, fb, mb) = (p.fixed_rows::<3>(0), p.fixed_rows::<3>(3), p.fixed_rows::<3>(6), p.fixed_rows::<3>(9));
        let m_tot = x_a.cross(&fa.into_owned()) + x_b.cross(&fb.into_owned()) + ma + mb;
        let scale = x_a.norm() * fa.norm();
        if expect_balanced {
            assert!(m_tot.norm() <= 1e-12 * scale);
        } else {
            let f_link = (b_right * y).fixed_rows::<3>(0).into_owned();
            let f_link_g = r.transpose() * Vector3::new(f_link[0] * k[0], f_link[1] * k[1], f_link[2] * k[2]);
            let expect = 2.0 * (g.l_b - g.l_a).cross(&f_link_g);
            assert!(expect.norm() > 1e-3 * scale);
            assert!((m_tot - expect).norm() <= 1e-9 * expect.norm(), "{m_tot:?} vs {expect:?}");
        }
    }
}

#[test]
fn scaled_and_unscaled_elements_are_related_by_s() {
    let mut s = 23u64;
    let (_, _, g, k, rbar) = random_link(&mut s);
    let k1 = element_matrix(&g, &k, 1.0);
    let ks = element_matrix(&g, &k, rbar);
    let sdiag = SMatrix::<f64, 12, 12>::from_diagonal(&V12::from_fn(|i, _| if (i / 3) % 2 == 1 { 1.0 / rbar } else { 1.0 }));
    let expect = sdiag * k1 * sdiag;
    assert!((ks - expect).abs().max() <= 1e-12 * ks.abs().max());
    // well scaled: all entries of the scaled matrix within a few decades (N/m)
    let kmax = ks.abs().max();
    let diag_min = (0..12).map(|i| ks[(i, i)]).fold(f64::INFINITY, f64::min);
    assert!(diag_min > 1e-2 * kmax, "scaled diagonal spans {:e}", kmax / diag_min);
}

fn pair_system(pin_floating: bool, fix_a: bool) -> (BondedSystem, Vec<Vector3<f64>>, Vec<f64>) {
    let pos = vec![Vector3::zeros(), Vector3::new(50e-6, 0.0, 0.0)];
    let rad = vec![25e-6, 25e-6];
    let mut c = Constraints::none(2);
    c.pin_floating = pin_floating;
    if fix_a {
        c.fix(0, dof::ALL).unwrap();
    }
    let mut sys = BondedSystem::new(2, MechParams::default(), c).unwrap();
    sys.set_topology(&[[0, 1]]).unwrap();
    (sys, pos, rad)
}

#[test]
fn unconstrained_pair_is_a_clear_solve_error_and_pinning_fixes_it() {
    let (mut sys, pos, rad) = pair_system(false, false);
    let inp = StepInput { positions: &pos, radii: &rad, y4_y7: &[[25e-6, 25e-6]], load: &[1.0], external: None };
    match sys.step(&inp) {
        Err(Error::Solve(e)) => {
            assert_eq!(e.stage, "mechanics constraints");
            assert!(e.message.contains("singular") && e.message.contains("6 free rigid-body mode"), "{e}");
        }
        other => panic!("expected a SolveError, got {:?}", other.map(|s| s.info)),
    }
    // with pinning (the default) the nearest-centroid particle is pinned: the other moves by ξ
    let (mut sys, _, _) = pair_system(true, false);
    let out = sys.step(&inp).unwrap();
    assert_eq!(sys.report().unwrap().pinned.len(), 1);
    let xi_expect = 1.0 / (0.5 * PI * MechParams::default().young_modulus * 25e-6);
    assert!((out.xi[0] / xi_expect - 1.0).abs() < 1e-12);
    // a partially held component is pinned too (one DOF fixed leaves five modes)
    let (mut sys, pos, rad) = pair_system(false, false);
    let mut c = Constraints::none(2);
    c.pin_floating = false;
    c.fix(0, dof::UX).unwrap();
    sys.set_constraints(c).unwrap();
    let err = sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &[[25e-6, 25e-6]], load: &[1.0], external: None }).unwrap_err();
    assert!(err.to_string().contains("5 free rigid-body mode"), "{err}");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let (mut sys, pos, rad) = pair_system(true, true);
    let ok = |y: [[f64; 2]; 1], l: f64, p: &[Vector3<f64>], r: &[f64], sys: &mut BondedSystem| {
        sys.step(&StepInput { positions: p, radii: r, y4_y7: &y, load: &[l], external: None })
    };
    assert!(ok([[25e-6, 25e-6]], f64::NAN, &pos, &rad, &mut sys).is_err());
    assert!(ok([[25e-6, f64::INFINITY]], 1.0, &pos, &rad, &mut sys).is_err());
    assert!(ok([[-25e-6, 20e-6]], 1.0, &pos, &rad, &mut sys).is_err());
    assert!(ok([[25e-6, 25e-6]], 1.0, &[pos[0], pos[0]], &rad, &mut sys).is_err(), "coincident centres");
    assert!(ok([[25e-6, 25e-6]], 1.0, &pos, &[25e-6, 0.0], &mut sys).is_err());
    assert!(ok([[25e-6, 25e-6]], 1.0, &pos[..1], &rad, &mut sys).is_err());
    assert!(ok([[25e-6, 25e-6]], 1.0, &[pos[0], Vector3::new(f64::NAN, 0.0, 0.0)], &rad, &mut sys).is_err());
    let ext = [NodalLoad { force: Vector3::new(f64::NAN, 0.0, 0.0), moment: Vector3::zeros() }; 2];
    assert!(sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &[[25e-6, 25e-6]], load: &[1.0], external: Some(&ext) }).is_err());
    assert!(sys.set_topology(&[[0, 0]]).is_err());
    assert!(sys.set_topology(&[[0, 2]]).is_err());
    assert!(sys.set_topology(&[[0, 1], [1, 0]]).is_err());
    assert!(BondedSystem::new(2, MechParams { young_modulus: -1.0, ..Default::default() }, Constraints::none(2)).is_err());
    assert!(BondedSystem::new(2, MechParams { poisson_ratio: 0.7, ..Default::default() }, Constraints::none(2)).is_err());
    assert!(BondedSystem::new(2, MechParams { rtol: f64::NAN, ..Default::default() }, Constraints::none(2)).is_err());
    assert!(BondedSystem::new(3, MechParams::default(), Constraints::none(2)).is_err());
    assert!(Constraints::principal_planes(&pos, &[1.0], 0.01).is_err());
    assert!(Constraints::none(2).fix(5, dof::ALL).is_err());
    // still usable after the errors
    sys.set_topology(&[[0, 1]]).unwrap();
    assert!(ok([[25e-6, 25e-6]], 1.0, &pos, &rad, &mut sys).is_ok());
}

#[test]
fn rattlers_are_left_out_and_floating_clusters_pinned() {
    // a held pair on the planes (particles 0, 1 along x, 2 along y, 3 along z around the corner),
    // a floating pair (4, 5) far away, and a rattler (6)
    let r = 10e-6;
    let pos = vec![
        Vector3::new(r, r, r),
        Vector3::new(3.0 * r, r, r),
        Vector3::new(r, 3.0 * r, r),
        Vector3::new(r, r, 3.0 * r),
        Vector3::new(20.0 * r, 20.0 * r, 20.0 * r),
        Vector3::new(22.0 * r, 20.0 * r, 20.0 * r),
        Vector3::new(40.0 * r, 40.0 * r, 40.0 * r),
    ];
    let rad = vec![r; 7];
    let mut cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
    // the corner particle touches all three planes, the others two each (bounding box at the origin)
    assert_eq!(cons.fixed[0], dof::U);
    assert_eq!(cons.fixed[1], dof::UY | dof::UZ);
    cons.pin_floating = true;
    let mut sys = BondedSystem::new(7, MechParams::default(), cons).unwrap();
    let pairs = [[0, 1], [0, 2], [0, 3], [4, 5]];
    sys.set_topology(&pairs).unwrap();
    let y = [[r, r]; 4];
    let load = [1.0, 2.0, 3.0, 4.0];
    let out = sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None }).unwrap();
    let rep = sys.report().unwrap();
    assert_eq!(rep.components, 2);
    assert_eq!(rep.rattlers, vec![6]);
    assert_eq!(rep.pinned.len(), 1);
    assert!(rep.pinned[0] == 4 || rep.pinned[0] == 5);
    assert_eq!(out.du[6], Vector3::zeros());
    // every bond of this statically determinate tree shortens by its free-bar approach ΔF/(EA/L_b)
    let ka = 0.5 * PI * MechParams::default().young_modulus * r;
    for (c, &l) in load.iter().enumerate() {
        assert!((out.xi[c] / (l / ka) - 1.0).abs() < 1e-10, "contact {c}: {} vs {}", out.xi[c], l / ka);
    }
    assert!(out.info.residuals.last().unwrap() <= &1e-10);
    assert_eq!(out.info.newton_iterations, 1);
}

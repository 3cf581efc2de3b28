//! The periodic cell against closed forms: lattices under equal sintering loads shrink by the
//! pair's approach (B13)–(B18), a simple-cubic cell under a uniaxial stress strains by σ·d/k_ax,
//! and on a disordered cell the gauge carries no reaction, the virial (B20) equals the stress
//! controls, and the result does not depend on the solver.

use super::*;
use crate::mechanics::{Constraints, LinearSolver, MechParams, fixtures::rng, link_stiffness};

const R: f64 = 25e-6;
const E: f64 = 1.0e11;
const NU: f64 = 0.3;

/// A periodic lattice of `m`³ cubic cells of edge `a` with the fractional `basis`, optionally
/// jittered by `jitter`·R: positions, the cell, and the pairs closer than `reach` (minimum image).
fn lattice(basis: &[[f64; 3]], m: usize, a: f64, jitter: f64, reach: f64) -> (Vec<Vector3<f64>>, Matrix3<f64>, Vec<[u32; 2]>) {
    let mut s = 7u64;
    let mut pos = Vec::new();
    for i in 0..m {
        for j in 0..m {
            for k in 0..m {
                for b in basis {
                    let j3 = Vector3::new(rng(&mut s) - 0.5, rng(&mut s) - 0.5, rng(&mut s) - 0.5) * (2.0 * jitter * R);
                    pos.push(Vector3::new(i as f64 + b[0], j as f64 + b[1], k as f64 + b[2]) * a + j3);
                }
            }
        }
    }
    let cell = Matrix3::from_diagonal_element(m as f64 * a);
    let inv = cell.try_inverse().unwrap();
    let mut pairs = Vec::new();
    for i in 0..pos.len() {
        for j in i + 1..pos.len() {
            if minimum_image(&(pos[j] - pos[i]), &cell, &inv).norm() < reach {
                pairs.push([i as u32, j as u32]);
            }
        }
    }
    (pos, cell, pairs)
}

fn system(n: usize, pairs: &[[u32; 2]], solver: LinearSolver) -> BondedSystem {
    let params = MechParams { young_modulus: E, poisson_ratio: NU, solver, rtol: 1e-12, ..Default::default() };
    let mut sys = BondedSystem::new(n, params, Constraints::none(n)).unwrap();
    sys.set_topology(pairs).unwrap();
    sys
}

fn half_distances(pos: &[Vector3<f64>], pairs: &[[u32; 2]], cell: &Matrix3<f64>) -> Vec<[f64; 2]> {
    branch_vectors(pos, pairs, cell).unwrap().iter().map(|l| [0.5 * l.norm(), 0.5 * l.norm()]).collect()
}

const SC: [[f64; 3]; 1] = [[0.0, 0.0, 0.0]];
const FCC: [[f64; 3]; 4] = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]];

/// Under the same load ΔF on every bond and zero stress, a lattice of equal spheres strains by
/// exactly the pair's approach ΔF/k_ax over the centre distance d in every normal component
/// (and, with all six components, shears by nothing), with no fluctuation and no gauge reaction.
#[test]
fn lattices_shrink_by_the_pair_approach() {
    let k_ax = link_stiffness(E, NU, R)[2];
    let df = 1e-3;
    for (basis, m, a, d, comps) in
        [(&SC[..], 3, 2.0 * R, 2.0 * R, 3), (&FCC[..], 2, 2.0 * R * 2f64.sqrt(), 2.0 * R, 3), (&FCC[..], 2, 2.0 * R * 2f64.sqrt(), 2.0 * R, 6)]
    {
        let (pos, cell, pairs) = lattice(basis, m, a, 0.0, 1.01 * d);
        assert_eq!(pairs.len(), pos.len() * if basis.len() == 1 { 3 } else { 6 });
        let mut sys = system(pos.len(), &pairs, LinearSolver::Cholesky);
        let y = half_distances(&pos, &pairs, &cell);
        let load = vec![df; pairs.len()];
        let radii = vec![R; pos.len()];
        let controls = vec![CellControl::Stress(0.0); comps];
        let inp = StepInput { positions: &pos, radii: &radii, y4_y7: &y, load: &load, external: None };
        let (out, cs) = sys.step_periodic(&inp, &CellInput { cell: &cell, controls: &controls }).unwrap();
        let want = -df / (k_ax * d);
        for k in 0..3 {
            assert!((cs.strain[k] / want - 1.0).abs() < 1e-12, "{basis:?} component {k}: {} vs {want}", cs.strain[k]);
        }
        for k in 3..6 {
            assert!(cs.strain[k].abs() < 1e-12 * want.abs(), "shear {k}: {}", cs.strain[k]);
        }
        // every bond approaches by exactly the pair's ΔF/k_ax; the fluctuation is nil
        for &x in &out.xi {
            assert!((x / (df / k_ax) - 1.0).abs() < 1e-12, "{x}");
        }
        for (i, du) in out.du.iter().enumerate() {
            assert!((du - strain_tensor(&cs.strain) * pos[i]).norm() < 1e-12 * (df / k_ax));
        }
        assert!(cs.gauge_reaction < 1e-12 * df, "{}", cs.gauge_reaction);
        assert!(cs.stress.iter().all(|s| s.abs() < 1e-12 * df / (R * R)), "{:?}", cs.stress);
    }
}

/// A simple-cubic cell under a uniaxial stress σ_xx: each x bond carries σ·d² and stretches by
/// σ·d²/k_ax, so Δe_xx = σ·d/k_ax; the bonds are orthogonal, so nothing happens across. The
/// same cell held (strain 0) under the sintering loads reports the reaction stress
/// −ΔF/d² tensile... of the loads themselves: Σ_aa = ΔF/d² per axis (B20).
#[test]
fn simple_cubic_cell_under_stress_and_under_constraint() {
    let k_ax = link_stiffness(E, NU, R)[2];
    let d = 2.0 * R;
    let (pos, cell, pairs) = lattice(&SC, 3, d, 0.0, 1.01 * d);
    let mut sys = system(pos.len(), &pairs, LinearSolver::Cholesky);
    let y = half_distances(&pos, &pairs, &cell);
    let radii = vec![R; pos.len()];
    let zero = vec![0.0; pairs.len()];
    let sigma = 1e6;
    let controls = [CellControl::Stress(sigma), CellControl::Stress(0.0), CellControl::Stress(0.0)];
    let inp = StepInput { positions: &pos, radii: &radii, y4_y7: &y, load: &zero, external: None };
    let (_, cs) = sys.step_periodic(&inp, &CellInput { cell: &cell, controls: &controls }).unwrap();
    assert!((cs.strain[0] / (sigma * d / k_ax) - 1.0).abs() < 1e-12, "{:?}", cs.strain);
    assert!(cs.strain[1].abs() < 1e-12 * cs.strain[0] && cs.strain[2].abs() < 1e-12 * cs.strain[0]);
    assert!((cs.stress[0] / sigma - 1.0).abs() < 1e-12, "{:?}", cs.stress);
    // held cell: the sintering loads ΔF per bond give the tensile reaction ΔF/d² on every axis
    let df = 1e-3;
    let load = vec![df; pairs.len()];
    let held = [CellControl::Strain(0.0); 3];
    let inp = StepInput { load: &load, ..inp };
    let (out, cs) = sys.step_periodic(&inp, &CellInput { cell: &cell, controls: &held }).unwrap();
    for k in 0..3 {
        assert!((cs.stress[k] / (df / (d * d)) - 1.0).abs() < 1e-12, "{:?}", cs.stress);
    }
    assert!(out.xi.iter().all(|x| x.abs() < 1e-12 * df / k_ax));
}

/// A disordered periodic cell (FCC jittered by 5 % of R, unequal loads): the gauge particle's
/// reaction is zero to solver tolerance, the virial of the bond forces equals the stress
/// controls, the strain-controlled components are met exactly, and AMG-CG (and hypre's
/// BoomerAMG-PCG with the `hypre` feature) gives the Cholesky result to its tolerance.
#[test]
fn disordered_cell_gauge_virial_and_solvers() {
    let a = 2.0 * R * 2f64.sqrt();
    let (pos, cell, pairs) = lattice(&FCC, 3, a, 0.05, 2.02 * R);
    let n = pos.len();
    let y = half_distances(&pos, &pairs, &cell);
    let radii = vec![R; n];
    let mut s = 3u64;
    let load: Vec<f64> = pairs.iter().map(|_| 1e-3 * (0.5 + rng(&mut s))).collect();
    let controls = [
        CellControl::Stress(-2e5),
        CellControl::Stress(0.0),
        CellControl::Strain(1e-5),
        CellControl::Stress(0.0),
        CellControl::Strain(0.0),
        CellControl::Stress(1e5),
    ];
    let inp = StepInput { positions: &pos, radii: &radii, y4_y7: &y, load: &load, external: None };
    let mut results = Vec::new();
    #[allow(unused_mut)]
    let mut solvers = vec![LinearSolver::Cholesky, LinearSolver::Amg];
    #[cfg(feature = "hypre")]
    solvers.push(LinearSolver::Hypre);
    for &solver in &solvers {
        let mut sys = system(n, &pairs, solver);
        let (out, cs) = sys.step_periodic(&inp, &CellInput { cell: &cell, controls: &controls }).unwrap();
        let rep = sys.report().unwrap();
        assert_eq!(rep.pinned.len(), 1);
        assert_eq!(rep.fixed[rep.pinned[0] as usize], dof::U, "a network spanning the cell: translation gauge only");
        assert!(cs.gauge_reaction <= 1e-9 * cs.load_scale, "gauge reaction {} N against loads {} N", cs.gauge_reaction, cs.load_scale);
        for (k, c) in controls.iter().enumerate() {
            match c {
                CellControl::Stress(v) => assert!((cs.stress[k] - v).abs() < 1e-8 * 2e5, "{k}: {} vs {v}", cs.stress[k]),
                CellControl::Strain(v) => assert_eq!(cs.strain[k], *v),
            }
        }
        // the mean fluctuation is removed: the mean of du − ΔE x is zero
        let de = strain_tensor(&cs.strain);
        let mean = out.du.iter().zip(&pos).fold(Vector3::zeros(), |m, (d, x)| m + d - de * x) / n as f64;
        assert!(mean.norm() < 1e-12 * out.du.iter().map(|d| d.norm()).fold(0.0, f64::max));
        results.push((out, cs));
    }
    let c = &results[0];
    let scale = c.0.du.iter().map(|d| d.norm()).fold(0.0, f64::max);
    for (a, solver) in results.iter().zip(&solvers).skip(1) {
        let worst = c.0.du.iter().zip(&a.0.du).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
        assert!(worst < 1e-8 * scale, "{solver:?} vs Cholesky: {worst:e} of {scale:e}");
    }
}

/// A floating cluster and a network that does not wrap: pinned with all six DOF, and stress
/// control on a cell that nothing spans is a clear error.
#[test]
fn clusters_that_do_not_span_the_cell() {
    let d = 2.0 * R;
    let pos = vec![Vector3::new(0.0, 0.0, 0.0), Vector3::new(d, 0.0, 0.0), Vector3::new(2.0 * d, 0.0, 0.0)];
    let cell = Matrix3::from_diagonal_element(10.0 * d);
    let pairs = [[0, 1], [1, 2]];
    let rep = analyse(3, &pairs, &branch_vectors(&pos, &pairs, &cell).unwrap(), &cell).unwrap();
    assert_eq!(rep.fixed[0], dof::ALL);
    let mut sys = system(3, &pairs, LinearSolver::Cholesky);
    let y = half_distances(&pos, &pairs, &cell);
    let inp = StepInput { positions: &pos, radii: &[R; 3], y4_y7: &y, load: &[1e-3, 1e-3], external: None };
    let err = sys.step_periodic(&inp, &CellInput { cell: &cell, controls: &[CellControl::Stress(0.0); 3] }).unwrap_err().to_string();
    assert!(err.contains("does not span the cell"), "{err}");
    // a chain closing on itself along x wraps once: translations and the rotation about x held
    let cell = Matrix3::from_diagonal(&Vector3::new(3.0 * d, 10.0 * d, 10.0 * d));
    let pairs = [[0, 1], [1, 2], [0, 2]];
    let rep = analyse(3, &pairs, &branch_vectors(&pos, &pairs, &cell).unwrap(), &cell).unwrap();
    assert_eq!(rep.fixed[0], dof::U | dof::RX);
    let bad = [CellControl::Stress(f64::NAN), CellControl::Stress(0.0), CellControl::Stress(0.0)];
    let inp = StepInput { load: &[0.0; 3], y4_y7: &[[R, R]; 3], ..inp };
    let mut sys = system(3, &pairs, LinearSolver::Cholesky);
    assert!(sys.step_periodic(&inp, &CellInput { cell: &cell, controls: &bad }).is_err());
}

/// Consecutive AMG steps on a periodic cell (the loads changing by 1 % per step, as sintering
/// loads do): the hierarchy of the first step is reused, not rebuilt (each right-hand side of
/// (B17) is its own solve; before, the four solves' summed iterations marked it stale at every
/// step), and the warm-started strain columns (B12) need fewer CG iterations than the cold
/// first step, while the result equals a cold solve of the same step to the solver tolerance.
#[test]
fn amg_steps_reuse_the_hierarchy_and_warm_start_the_columns() {
    let a = 2.0 * R * 2f64.sqrt();
    let (pos, cell, pairs) = lattice(&FCC, 4, a, 0.05, 2.02 * R);
    let n = pos.len();
    let y = half_distances(&pos, &pairs, &cell);
    let radii = vec![R; n];
    let controls = [CellControl::Stress(0.0); 3];
    // the coupled loop's settings: reuse and warm start on
    let params =
        MechParams { young_modulus: E, poisson_ratio: NU, solver: LinearSolver::Amg, rtol: 1e-9, reuse_factor: true, warm_start: true, ..Default::default() };
    let mut sys = BondedSystem::new(n, params, Constraints::none(n)).unwrap();
    sys.set_topology(&pairs).unwrap();
    let mut s = 5u64;
    let base: Vec<f64> = pairs.iter().map(|_| 1e-3 * (0.5 + rng(&mut s))).collect();
    let mut infos = Vec::new();
    let mut last = None;
    for step in 0..4 {
        let load: Vec<f64> = base.iter().map(|f| f * (1.0 + 0.01 * step as f64)).collect();
        let inp = StepInput { positions: &pos, radii: &radii, y4_y7: &y, load: &load, external: None };
        let (out, cs) = sys.step_periodic(&inp, &CellInput { cell: &cell, controls: &controls }).unwrap();
        infos.push(out.info.clone());
        last = Some((load, out, cs));
    }
    assert_eq!(infos[0].amg_builds, 1);
    for (k, i) in infos.iter().enumerate().skip(1) {
        assert_eq!(i.amg_builds, 0, "step {k} rebuilt the hierarchy: {i:?}");
        assert!(i.pcg_iterations < infos[0].pcg_iterations, "step {k}: {} CG iterations, cold first step {}", i.pcg_iterations, infos[0].pcg_iterations);
    }
    // the warm-started last step against a cold system on the same step
    let (load, warm, wcs) = last.unwrap();
    let mut cold = BondedSystem::new(n, params, Constraints::none(n)).unwrap();
    cold.set_topology(&pairs).unwrap();
    let inp = StepInput { positions: &pos, radii: &radii, y4_y7: &y, load: &load, external: None };
    let (out, ccs) = cold.step_periodic(&inp, &CellInput { cell: &cell, controls: &controls }).unwrap();
    let scale = out.du.iter().map(|d| d.norm()).fold(0.0, f64::max);
    let worst = out.du.iter().zip(&warm.du).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
    assert!(worst < 1e-6 * scale, "warm vs cold: {worst:e} of {scale:e}");
    for k in 0..3 {
        assert!((wcs.strain[k] - ccs.strain[k]).abs() < 1e-6 * ccs.strain[k].abs(), "{k}: {} vs {}", wcs.strain[k], ccs.strain[k]);
    }
}

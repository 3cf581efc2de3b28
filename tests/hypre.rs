//! hypre's BoomerAMG-preconditioned PCG (`mechanics.solver = "hypre"`, cargo feature `hypre`,
//! docs/coupled.md "hypre's BoomerAMG against our AMG") against the sparse Cholesky and our AMG: the same displacements to the
//! solver tolerance on a walled bonded packing, and the same copper compact end to end.
//! Compiled only with the feature: `cargo test --release --features h5,hypre --test hypre`
//! (scripts/test-all.sh runs it where libhypre-dev is installed or installable).
#![cfg(feature = "hypre")]

use sinterdem::mechanics::fixtures::{fcc_packing, rng};
use sinterdem::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, SolverUsed, StepInput};

mod common;

/// A walled FCC packing (radii ±5 %, about half the neighbours bonded: 248 rattlers, plane
/// constraints): hypre's solution equals the Cholesky one to the
/// bound cond(K)·rtol of the residual test (B10) with rtol 1e-10, as our AMG's does (1e-8 of the
/// largest displacement, src/mechanics/amg.rs tests); fixed DOF are exactly zero.
#[test]
fn hypre_equals_cholesky_on_a_walled_packing() {
    let (pos, rad, pairs, y) = fcc_packing(3000, 5);
    let mut s = 5u64;
    let load: Vec<f64> = pairs.iter().map(|_| 1e-3 * (0.5 + rng(&mut s))).collect();
    let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
    let inp = StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None };
    let solve = |solver| {
        let p = MechParams { young_modulus: 110e9, poisson_ratio: 0.34, solver, ..Default::default() };
        let mut sys = BondedSystem::new(pos.len(), p, cons.clone()).unwrap();
        sys.set_topology(&pairs).unwrap();
        let out = sys.step(&inp).unwrap();
        (out, sys.report().unwrap().fixed.clone())
    };
    let (chol, _) = solve(LinearSolver::Cholesky);
    let (h, fixed) = solve(LinearSolver::Hypre);
    assert_eq!(h.info.solver, SolverUsed::Hypre);
    assert!(chol.info.rattlers > 0, "rattlers {}", chol.info.rattlers);
    let res = *h.info.residuals.last().unwrap();
    assert!(res <= 1e-10, "hypre residual {res:.2e}");
    let scale = chol.du.iter().map(|v| v.norm()).fold(0.0, f64::max);
    let diff = chol.du.iter().zip(&h.du).map(|(p, q)| (p - q).norm()).fold(0.0, f64::max);
    assert!(diff <= 1e-8 * scale, "max |Δu| difference {diff:.2e} of {scale:.2e}");
    let xi = chol.xi.iter().zip(&h.xi).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
    assert!(xi <= 1e-8 * scale, "ξ difference {xi:.2e}");
    for (i, &m) in fixed.iter().enumerate() {
        for k in 0..3 {
            if m & (1 << k) != 0 {
                assert_eq!(h.du[i][k], 0.0, "particle {i} DOF {k}");
            }
            if m & (8 << k) != 0 {
                assert_eq!(h.dtheta[i][k], 0.0, "particle {i} DOF {}", 3 + k);
            }
        }
    }
    // BoomerAMG with nodal coarsening and the rigid rotations: a multigrid iteration count, not
    // block-Jacobi's hundreds (≈ 330 on a 2000-particle packing, src/mechanics/amg.rs tests)
    assert!(h.info.pcg_iterations <= 100, "hypre PCG iterations {}", h.info.pcg_iterations);
    eprintln!("hypre: {} equations, {} PCG iterations, residual {res:.2e}, |Δu| difference {:.2e}", h.info.equations, h.info.pcg_iterations, diff / scale);
}

/// The copper compact on a corner of the bundled green packing (new contacts during the run):
/// with `mechanics.solver = "hypre"` and with "amg" the same steps and shrinkage to the solver
/// tolerance (both iterate to rtol 1e-10, so the results agree far inside the 2e-3 of the issue).
#[test]
fn copper_compact_with_hypre_equals_amg() {
    let dir = common::tmp_dir("hypre-compact");
    let rows = common::green_copper_block(2.6e-4, 2.6e-4);
    assert!(rows.len() > 30, "{}", rows.len());
    let packing = common::write_block(&dir, "corner.csv", "x,y,z,r", rows.into_iter().map(|(l, _)| l));
    let run = |solver: &str| {
        let v = common::copper_compact(&packing, 300.0, &[&format!("mechanics.solver=\"{solver}\"")]);
        common::run_compact(v, &dir.join(solver))
    };
    let a = run("amg");
    let h = run("hypre");
    assert_eq!(a["steps"], h["steps"]);
    for k in ["shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density"] {
        let (x, y) = (a[k].as_f64().unwrap(), h[k].as_f64().unwrap());
        assert!(common::rel(x, y) < 1e-6, "{k}: amg {x} hypre {y}");
    }
}

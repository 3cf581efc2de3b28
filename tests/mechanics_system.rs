//! Assembled bonded packings against closed forms: the isolated pair with the 7-DOF contact
//! (docs/diffusion7.md §8), a cantilever chain (Timoshenko beam with the chain's midpoint
//! quadrature, exact for the discrete chain), lattices under uniaxial load and under uniform
//! sintering loads, SPD assembly of a random packing, PCG against Cholesky, factor reuse, and
//! thread-count determinism.

use nalgebra::Vector3;
use sinterdem::mechanics::fixtures::fcc_packing;
use sinterdem::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, NodalLoad, SolverUsed, StepInput, dof, link_stiffness};
use sinterdem::models::diffusion7::{
    self, Material, PairMaterials, PathFactors, SolverOptions, TemperaturePath, advance, correct_y4_y7, load_increment, sintering_force,
};
use sinterdem::models::ode::OdeStats;
use std::f64::consts::PI;

const E: f64 = 110e9;
const NU: f64 = 0.34;

fn params(solver: LinearSolver) -> MechParams {
    MechParams { young_modulus: E, poisson_ratio: NU, solver, ..Default::default() }
}

fn rng(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

/// docs/diffusion7.md §8: an isolated copper pair (25/15 µm, 1293 K) with A fixed, loaded by
/// (F5) each step, approaches by exactly Δy4 + Δy7; the correction (C1)–(C4) then leaves y4, y7 at
/// the free 7-DOF values, so the coupled run follows the free run; the accumulated load is (F4).
#[test]
fn isolated_pair_reproduces_the_free_seven_dof_approach() {
    let cu = Material::copper();
    let mats = PairMaterials { a: &cu, b: &cu, factors: PathFactors::default() };
    let temp = TemperaturePath::Constant(1293.0);
    let opts = SolverOptions::default();
    let (ra, rb) = (25e-6, 15e-6);
    let mut contact = diffusion7::Contact7::new(ra, rb, ra + rb, 0.0, 0.01, 0.1).unwrap();
    let mut free = contact;
    let rm = contact.r_mean();
    // an arbitrary orientation and position
    let e3 = Vector3::new(0.3, -0.8, 0.52).normalize();
    let mut pos = vec![Vector3::new(1e-4, 2e-4, 3e-4), Vector3::zeros()];
    pos[1] = pos[0] + e3 * (contact.y[3] + contact.y[6]);
    let rad = vec![ra, rb];
    let mut cons = Constraints::none(2);
    cons.fix(0, dof::ALL).unwrap();
    let mut sys = BondedSystem::new(2, params(LinearSolver::Cholesky), cons).unwrap();
    sys.set_topology(&[[0, 1]]).unwrap();
    let mut stats = OdeStats::default();
    let mut load_total = 0.0;
    let times = [0.0, 1e-3, 0.1, 1.0, 10.0, 100.0, 1000.0];
    for w in times.windows(2) {
        let prev = contact.y;
        advance(&mut contact, &mats, &temp, w[0], w[1], &opts, &mut stats, |_, _, _| {}).unwrap();
        advance(&mut free, &mats, &temp, w[0], w[1], &opts, &mut stats, |_, _, _| {}).unwrap();
        let star = contact.y;
        let (dy4, dy7) = (prev[3] - star[3], prev[6] - star[6]);
        assert!(dy4 + dy7 > 0.0);
        let df = load_increment(dy4, dy7, rm, E);
        load_total += df;
        let out = sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &[[prev[3], prev[6]]], load: &[df], external: None }).unwrap();
        assert!((out.xi[0] / (dy4 + dy7) - 1.0).abs() < 1e-12, "ξ = {} vs Δy4 + Δy7 = {}", out.xi[0], dy4 + dy7);
        assert_eq!(out.du[0], Vector3::zeros());
        // only the axial DOF responds
        assert!((out.du[1] - (-out.xi[0]) * e3).norm() < 1e-12 * out.xi[0]);
        assert!(out.dtheta[1].norm() * rb < 1e-12 * out.xi[0]);
        let params_t = mats.params_at(1293.0);
        let rates = diffusion7::rates(&star, &params_t, 1293.0).unwrap();
        let c = correct_y4_y7((prev[3], prev[6]), (star[3], star[6]), (rates[3], rates[6]), out.xi[0], ra + rb);
        assert!((c.y4 - star[3]).abs() < 1e-15 * ra * 10.0 && (c.y7 - star[6]).abs() < 1e-15 * ra * 10.0, "correction moved y4, y7");
        assert!(c.dl_bar.abs() < 1e-14 * ra * 10.0);
        contact.y[3] = c.y4;
        contact.y[6] = c.y7;
        contact.y_prev = contact.y;
        let mut rot = vec![Vector3::zeros(); 2];
        out.apply(&mut pos, &mut rot);
        // the centre distance follows y4 + y7
        assert!(((pos[1] - pos[0]).norm() - (contact.y[3] + contact.y[6])).abs() < 1e-14 * (ra + rb) * 10.0);
    }
    // the coupled contact follows the free one; accumulated load = (F4)
    for k in 0..7 {
        assert!((contact.y[k] - free.y[k]).abs() < 1e-12 * ra, "y{} {} vs {}", k + 1, contact.y[k], free.y[k]);
    }
    let f4 = sintering_force(contact.l0, contact.y[3], contact.y[6], rm, E);
    assert!((load_total / f4 - 1.0).abs() < 1e-12, "ΣΔF = {load_total} vs (F4) = {f4}");
}

/// A chain of n + 1 equal touching particles (bond length 2R), particle 0 clamped, loaded at the
/// tip. Closed forms with per-link stiffnesses k = link_stiffness(E, ν, R), L = 2R·n:
/// - axial force P: δ = n·P/k_a = PL/(EA);
/// - torsion T: φ = n·T/k_t = TL/(GJ);
/// - end moment M: rotation ML/(EI), deflection ML²/(2EI) (Euler–Bernoulli, exact for the chain);
/// - transverse force P: rotation PL²/(2EI) and deflection PL³/(3EI)·(1 − 1/(4n²)) + PL/(GA):
///   Timoshenko with shear coefficient 1, the bending part being the midpoint rule of the moment
///   integral over the n links (exact for the discrete chain, → PL³/3EI as n grows).
#[test]
fn cantilever_chain_matches_beam_closed_forms() {
    let r = 20e-6;
    let n = 12usize; // links
    let a = Vector3::new(1.0, 2.0, -0.5).normalize();
    let b = a.cross(&Vector3::new(0.3, 0.1, 1.0)).normalize();
    let c = a.cross(&b);
    let x0 = Vector3::new(1e-3, -2e-3, 5e-4);
    let pos: Vec<Vector3<f64>> = (0..=n).map(|i| x0 + a * (2.0 * r * i as f64)).collect();
    let rad = vec![r; n + 1];
    let pairs: Vec<[u32; 2]> = (0..n as u32).map(|i| [i, i + 1]).collect();
    let y = vec![[r, r]; n];
    let mut cons = Constraints::none(n + 1);
    cons.fix(0, dof::ALL).unwrap();
    let mut sys = BondedSystem::new(n + 1, params(LinearSolver::Cholesky), cons).unwrap();
    sys.set_topology(&pairs).unwrap();
    let k = link_stiffness(E, NU, r);
    let g = E / (2.0 * (1.0 + NU));
    let (area, inertia, polar) = (PI * r * r, PI * r.powi(4) / 4.0, PI * r.powi(4) / 2.0);
    let len = 2.0 * r * n as f64;
    let nf = n as f64;
    let zero = vec![0.0; n];
    let mut solve = |force: Vector3<f64>, moment: Vector3<f64>| {
        let mut ext = vec![NodalLoad::default(); n + 1];
        ext[n] = NodalLoad { force, moment };
        let out = sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &zero, external: Some(&ext) }).unwrap();
        assert!(out.info.residuals.last().unwrap() <= &1e-10);
        (out.du[n], out.dtheta[n])
    };
    let close = |got: f64, want: f64, what: &str| assert!((got / want - 1.0).abs() < 1e-9, "{what}: {got:e} vs {want:e}");
    // axial
    let p = 1e-3;
    let (u, th) = solve(a * p, Vector3::zeros());
    close(u.dot(&a), nf * p / k[2], "axial, link count");
    close(u.dot(&a), p * len / (E * area), "axial, PL/EA");
    assert!(u.cross(&a).norm() < 1e-9 * u.norm() && th.norm() * r < 1e-9 * u.norm());
    // torsion
    let t = 1e-9;
    let (u, th) = solve(Vector3::zeros(), a * t);
    close(th.dot(&a), t * len / (g * polar), "torsion TL/GJ");
    assert!(u.norm() < 1e-9 * th.norm() * r);
    // end moment about c (bends a towards b)
    let m = 1e-9;
    let (u, th) = solve(Vector3::zeros(), c * m);
    close(th.dot(&c), m * len / (E * inertia), "end moment, rotation ML/EI");
    close(u.dot(&b), m * len * len / (2.0 * E * inertia), "end moment, deflection ML²/2EI");
    // transverse tip force along b
    let (u, th) = solve(b * p, Vector3::zeros());
    let w_expect = p * len.powi(3) / (3.0 * E * inertia) * (1.0 - 1.0 / (4.0 * nf * nf)) + p * len / (g * area);
    close(u.dot(&b), w_expect, "tip force, Timoshenko deflection");
    close(th.dot(&c), p * len * len / (2.0 * E * inertia), "tip force, rotation PL²/2EI");
    // towards the continuum: the discrete correction is below 0.2 % here
    let eb = p * len.powi(3) / (3.0 * E * inertia) + p * len / (g * area);
    assert!((u.dot(&b) / eb - 1.0).abs() < 2e-3);
}

fn sc_lattice(m: usize, r: f64) -> (Vec<Vector3<f64>>, Vec<[u32; 2]>) {
    let idx = |i: usize, j: usize, k: usize| (i * m * m + j * m + k) as u32;
    let mut pos = Vec::new();
    let mut pairs = Vec::new();
    for i in 0..m {
        for j in 0..m {
            for k in 0..m {
                pos.push(Vector3::new(r + 2.0 * r * i as f64, r + 2.0 * r * j as f64, r + 2.0 * r * k as f64));
                if i + 1 < m {
                    pairs.push([idx(i, j, k), idx(i + 1, j, k)]);
                }
                if j + 1 < m {
                    pairs.push([idx(i, j, k), idx(i, j + 1, k)]);
                }
                if k + 1 < m {
                    pairs.push([idx(i, j, k), idx(i, j, k + 1)]);
                }
            }
        }
    }
    (pos, pairs)
}

/// Simple-cubic lattice of m³ touching particles on the three planes, tension P on every particle
/// of the face x = max: each x-row is m − 1 links in series, m² rows in parallel, so
/// u_x(i) = i·P/k_a exactly, nothing moves sideways or rotates, and the lattice modulus is
/// σ/ε = k_a/(2R) = (π/4)·E.
#[test]
fn simple_cubic_lattice_under_uniaxial_load_is_a_spring_network() {
    let (m, r) = (6usize, 10e-6);
    let (pos, pairs) = sc_lattice(m, r);
    let n = pos.len();
    let rad = vec![r; n];
    let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
    for solver in [LinearSolver::Cholesky, LinearSolver::Pcg] {
        let mut sys = BondedSystem::new(n, params(solver), cons.clone()).unwrap();
        sys.set_topology(&pairs).unwrap();
        let p = 1e-2;
        let xmax = pos.iter().map(|x| x.x).fold(0.0, f64::max);
        let ext: Vec<NodalLoad> =
            pos.iter().map(|x| NodalLoad { force: if x.x == xmax { Vector3::new(p, 0.0, 0.0) } else { Vector3::zeros() }, moment: Vector3::zeros() }).collect();
        let y = vec![[r, r]; pairs.len()];
        let out = sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &vec![0.0; pairs.len()], external: Some(&ext) }).unwrap();
        assert_eq!(sys.report().unwrap().pinned.len(), 0, "the planes hold the lattice");
        let ka = link_stiffness(E, NU, r)[2];
        let scale = (m - 1) as f64 * p / ka;
        for (x, (du, dt)) in pos.iter().zip(out.du.iter().zip(&out.dtheta)) {
            let i = ((x.x - r) / (2.0 * r)).round();
            assert!((du.x - i * p / ka).abs() < 1e-9 * scale, "{solver:?}: u_x = {} vs {}", du.x, i * p / ka);
            assert!(du.y.abs() < 1e-9 * scale && du.z.abs() < 1e-9 * scale && dt.norm() * r < 1e-9 * scale);
        }
        let sigma = (m * m) as f64 * p / (2.0 * r * m as f64).powi(2);
        let eps = scale / (2.0 * r * (m - 1) as f64);
        assert!((sigma / eps / (PI / 4.0 * E) - 1.0).abs() < 1e-9);
        let used = out.info.solver;
        assert_eq!(used, if solver == LinearSolver::Pcg { SolverUsed::Pcg } else { SolverUsed::Cholesky });
    }
}

fn fcc_lattice(m: usize, r: f64) -> (Vec<Vector3<f64>>, Vec<[u32; 2]>) {
    let a = 2.0 * r * std::f64::consts::SQRT_2;
    let basis = [[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.0, 0.5], [0.0, 0.5, 0.5]];
    let mut pos = Vec::new();
    for i in 0..m {
        for j in 0..m {
            for k in 0..m {
                for b in &basis {
                    pos.push(Vector3::new(i as f64 + b[0], j as f64 + b[1], k as f64 + b[2]) * a + Vector3::repeat(r));
                }
            }
        }
    }
    let pairs = sinterdem::contacts::detect::touching_pairs(&pos, &vec![r; pos.len()], 1e-3 * r).into_iter().map(|(i, j)| [i, j]).collect();
    (pos, pairs)
}

/// Equal sintering loads (F5) on every bond of a lattice of equal touching particles: the uniform
/// contraction u = −(δ/2R)(x − x_corner) is compatible with the roller planes and leaves every link
/// exactly at its free-bar approach, so ξ = Δy4 + Δy7 = δ for every contact, no rotation: the
/// packing reproduces the free pair (simple cubic: coordination 6; FCC: 12, non-orthogonal bonds).
#[test]
fn lattices_under_equal_sintering_loads_shrink_like_the_free_pair() {
    let r = 10e-6;
    for (name, (pos, pairs)) in [("sc", sc_lattice(5, r)), ("fcc", fcc_lattice(3, r))] {
        let n = pos.len();
        let rad = vec![r; n];
        let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
        let delta = 1e-4 * r;
        let load = vec![load_increment(0.5 * delta, 0.5 * delta, r, E); pairs.len()];
        let y = vec![[r, r]; pairs.len()];
        for solver in [LinearSolver::Cholesky, LinearSolver::Pcg] {
            let mut sys = BondedSystem::new(n, params(solver), cons.clone()).unwrap();
            sys.set_topology(&pairs).unwrap();
            let out = sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None }).unwrap();
            for (c, xi) in out.xi.iter().enumerate() {
                assert!((xi / delta - 1.0).abs() < 1e-8, "{name} {solver:?} contact {c}: ξ/δ = {}", xi / delta);
            }
            let eps = delta / (2.0 * r);
            for (x, (du, dt)) in pos.iter().zip(out.du.iter().zip(&out.dtheta)) {
                let expect = -(x - Vector3::repeat(r)) * eps;
                assert!((du - expect).norm() < 1e-8 * delta * m_of(n) && dt.norm() * r < 1e-8 * delta, "{name}: {du:?} vs {expect:?}");
            }
        }
    }
}

fn m_of(n: usize) -> f64 {
    (n as f64).cbrt()
}

/// A random bonded packing (FCC sites, radii ±5 %, about half the neighbours bonded): rattlers and
/// floating clusters are handled, the constrained stiffness is SPD (Cholesky succeeds in one Newton
/// iteration to 1e-10), PCG agrees with it, factor reuse converges to the same answer, and the
/// result is bit-identical on 1 and 2 threads.
#[test]
fn random_packing_is_spd_and_solvers_agree() {
    let (pos, rad, pairs, y) = fcc_packing(2000, 5);
    let n = pos.len();
    let mut s = 3u64;
    let load: Vec<f64> = pairs
        .iter()
        .map(|&[i, j]| {
            let rm = 0.5 * (rad[i as usize] + rad[j as usize]);
            load_increment(1e-4 * rm * rng(&mut s), 1e-4 * rm * rng(&mut s), rm, E)
        })
        .collect();
    let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
    let inp = StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &load, external: None };
    let run = |solver: LinearSolver, threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| {
            let mut sys = BondedSystem::new(n, params(solver), cons.clone()).unwrap();
            sys.set_topology(&pairs).unwrap();
            let out = sys.step(&inp).unwrap();
            (out, sys.report().unwrap().clone())
        })
    };
    let (chol, rep) = run(LinearSolver::Cholesky, 2);
    assert!(rep.components >= 1 && !rep.rattlers.is_empty(), "packing should have rattlers: {:?}", (rep.components, rep.rattlers.len()));
    // the main component is held by the planes; only small clusters are pinned
    assert!(rep.pinned.len() < rep.components, "{} pinned of {} components", rep.pinned.len(), rep.components);
    assert_eq!(chol.info.newton_iterations, 1);
    assert!(chol.info.residuals[0] <= 1e-10, "{:?}", chol.info.residuals);
    for &i in &rep.rattlers {
        assert_eq!(chol.du[i as usize], Vector3::zeros());
    }
    let (pcg, _) = run(LinearSolver::Pcg, 2);
    assert!(pcg.info.pcg_iterations > 0 && pcg.info.residuals.last().unwrap() <= &1e-10);
    let scale = chol.du.iter().map(|d| d.norm()).fold(0.0, f64::max);
    let diff = chol.du.iter().zip(&pcg.du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff < 1e-7 * scale, "PCG vs Cholesky: {diff:e} of {scale:e}");
    // sintering loads are self-equilibrated: the mean approach is positive (the packing shrinks)
    let mean_xi = chol.xi.iter().sum::<f64>() / chol.xi.len() as f64;
    assert!(mean_xi > 0.0);
    // thread-count determinism
    let (chol1, _) = run(LinearSolver::Cholesky, 1);
    assert!(chol1.du == chol.du && chol1.xi == chol.xi, "1 vs 2 threads differ (Cholesky)");
    let (pcg1, _) = run(LinearSolver::Pcg, 1);
    assert!(pcg1.du == pcg.du, "1 vs 2 threads differ (PCG)");
    // factor reuse across a small geometry change: modified Newton reaches the same tolerance
    let mut sys = BondedSystem::new(n, MechParams { reuse_factor: true, ..params(LinearSolver::Cholesky) }, cons.clone()).unwrap();
    sys.set_topology(&pairs).unwrap();
    sys.step(&inp).unwrap();
    let pos2: Vec<Vector3<f64>> = pos.iter().zip(&chol.du).map(|(x, d)| x + d).collect();
    let inp2 = StepInput { positions: &pos2, ..inp };
    let reused = sys.step(&inp2).unwrap();
    assert_eq!(reused.info.factorizations, 0);
    assert!(reused.info.residuals.last().unwrap() <= &1e-10);
    let mut fresh_sys = BondedSystem::new(n, params(LinearSolver::Cholesky), cons).unwrap();
    fresh_sys.set_topology(&pairs).unwrap();
    let fresh = fresh_sys.step(&inp2).unwrap();
    let diff = fresh.du.iter().zip(&reused.du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff < 1e-8 * scale, "reuse vs fresh: {diff:e}");
}

/// An iteration budget that cannot reach the tolerance is a SolveError with the residual history,
/// not a silent inaccurate answer.
#[test]
fn unconverged_pcg_is_a_solve_error_with_history() {
    let r = 10e-6;
    let (pos, pairs) = sc_lattice(4, r);
    let rad = vec![r; pos.len()];
    let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
    let mut sys = BondedSystem::new(pos.len(), MechParams { pcg_max_iter: 2, max_newton: 2, ..params(LinearSolver::Pcg) }, cons).unwrap();
    sys.set_topology(&pairs).unwrap();
    let mut s = 9u64;
    let load: Vec<f64> = pairs.iter().map(|_| rng(&mut s)).collect();
    let err = sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &vec![[r, r]; pairs.len()], load: &load, external: None }).unwrap_err();
    match err {
        sinterdem::Error::Solve(e) => {
            assert!(e.stage.contains("PCG") && !e.residuals.is_empty(), "{e}");
            assert!(e.residuals.iter().all(|v| v.is_finite()));
        }
        other => panic!("expected SolveError, got {other}"),
    }
}

/// docs/mechanics.md (B12): the warm start of the CG-based solvers is the Galerkin projection
/// onto the last solutions (Cholesky steps ignore it).
/// A load that is a multiple of the last one is solved by the projection alone (residual at
/// round-off, no Newton iteration, the same answer as a cold solve); a new load pattern starts
/// below ‖b‖ and ends at the same tolerance and answer as a cold solve, with fewer CG iterations
/// than from zero; a dropped factor (checkpoints) forgets the history; 1 and 2 threads agree.
#[test]
fn warm_start_projects_onto_the_last_solutions() {
    let (pos, rad, pairs, y) = fcc_packing(2000, 5);
    let n = pos.len();
    let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
    let loads = |seed: u64| -> Vec<f64> {
        let mut s = seed;
        pairs
            .iter()
            .map(|&[i, j]| {
                let rm = 0.5 * (rad[i as usize] + rad[j as usize]);
                load_increment(1e-4 * rm * rng(&mut s), 1e-4 * rm * rng(&mut s), rm, E)
            })
            .collect()
    };
    let (l1, l3) = (loads(3), loads(11));
    let l2: Vec<f64> = l1.iter().map(|v| 2.5 * v).collect();
    // a load between the two patterns: mostly in the span of the history, not entirely
    let l4: Vec<f64> = l1.iter().zip(&l3).enumerate().map(|(k, (a, b))| 0.7 * a + 0.4 * b + if k % 7 == 0 { 0.2 * a } else { 0.0 }).collect();
    let rtol = 1e-8;
    for solver in [LinearSolver::Cholesky, LinearSolver::Amg, LinearSolver::Pcg] {
        let run = |warm: bool, threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let p = MechParams { warm_start: warm, rtol, reuse_factor: true, ..params(solver) };
                let mut sys = BondedSystem::new(n, p, cons.clone()).unwrap();
                sys.set_topology(&pairs).unwrap();
                let mut outs = Vec::new();
                for l in [&l1, &l2, &l3, &l4] {
                    outs.push(sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: l, external: None }).unwrap());
                }
                sys.drop_factor();
                outs.push(sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: &y, load: &l4, external: None }).unwrap());
                outs
            })
        };
        let cold = run(false, 2);
        let warm = run(true, 2);
        if solver == LinearSolver::Cholesky {
            // a direct solve does not use the warm start: bit for bit the cold steps
            assert!(warm.iter().all(|w| w.info.warm_start == 0.0));
            assert!(warm.iter().zip(&cold).all(|(w, c)| w.du == c.du));
            continue;
        }
        let scale = cold[3].du.iter().map(|d| d.norm()).fold(0.0, f64::max);
        for (k, (c, w)) in cold.iter().zip(&warm).enumerate() {
            let diff = c.du.iter().zip(&w.du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
            assert!(diff < 1e-6 * scale, "{solver:?} step {k}: warm vs cold {diff:e} of {scale:e}");
            assert!(w.info.residuals.last().copied().unwrap_or(w.info.warm_start) <= rtol, "{solver:?} step {k}: {:?}", w.info);
        }
        // step 1: no history; step 2: 2.5 × step 1, solved by the projection alone (its residual
        // is step 1's, within rtol)
        assert_eq!(warm[0].info.warm_start, 0.0);
        assert!(warm[1].info.warm_start <= rtol, "{solver:?}: {:e}", warm[1].info.warm_start);
        assert_eq!(warm[1].info.newton_iterations, 0);
        // step 3: an unrelated pattern (its projection may be discarded: residual not below ‖b‖);
        // step 4: a mixture of the last two patterns plus a part outside their span
        assert!(warm[2].info.warm_start > 0.0, "{solver:?}: {:e}", warm[2].info.warm_start);
        assert!(warm[3].info.warm_start < 0.2, "{solver:?}: {:e}", warm[3].info.warm_start);
        assert!(warm[3].info.pcg_iterations < cold[3].info.pcg_iterations, "{} vs {}", warm[3].info.pcg_iterations, cold[3].info.pcg_iterations);
        // after drop_factor the history is gone: the step equals the cold one bit for bit
        assert_eq!(warm[4].info.warm_start, 0.0);
        assert!(warm[4].du == cold[4].du, "{solver:?}: a dropped history must give the cold result");
        let one = run(true, 1);
        assert!(one.iter().zip(&warm).all(|(a, b)| a.du == b.du), "{solver:?}: 1 vs 2 threads differ");
    }
}

/// docs/mechanics.md (B12) with a deeper history (`warm_start_depth`): a load mixed from the
/// last three patterns is solved by the projection alone with three solutions kept, not with two
/// (the oldest pattern is outside their span); the answer is the cold solve's to the tolerance.
/// `amg_keep_on_new_bonds`: after new bonds the kept hierarchy preconditions the new stiffness
/// (no build in that step) and CG reaches the same tolerance and answer as a fresh hierarchy.
#[test]
fn deeper_warm_start_and_amg_kept_across_new_bonds() {
    let (pos, rad, pairs, y) = fcc_packing(2000, 5);
    let n = pos.len();
    let cons = Constraints::principal_planes(&pos, &rad, 0.01).unwrap();
    let loads = |seed: u64, pairs: &[[u32; 2]]| -> Vec<f64> {
        let mut s = seed;
        pairs
            .iter()
            .map(|&[i, j]| {
                let rm = 0.5 * (rad[i as usize] + rad[j as usize]);
                load_increment(1e-4 * rm * rng(&mut s), 1e-4 * rm * rng(&mut s), rm, E)
            })
            .collect()
    };
    let (l1, l2, l3) = (loads(3, &pairs), loads(11, &pairs), loads(17, &pairs));
    let mix: Vec<f64> = (0..l1.len()).map(|k| 0.5 * l1[k] + 0.3 * l2[k] + 0.2 * l3[k]).collect();
    let rtol = 1e-8;
    // bonds that join late: every 40th between particles with at least four bonds (so that no
    // particle is left without one: the free DOF stay the same)
    let mut degree = vec![0usize; n];
    for &[a, b] in &pairs {
        degree[a as usize] += 1;
        degree[b as usize] += 1;
    }
    let late = |k: usize| k % 40 == 7 && pairs[k].iter().all(|&p| degree[p as usize] >= 4);
    let y_early: Vec<[f64; 2]> = y.iter().enumerate().filter(|(k, _)| !late(*k)).map(|(_, v)| *v).collect();
    let step = |sys: &mut BondedSystem, l: &[f64], pairs: &[[u32; 2]]| {
        let y = if pairs.len() == y.len() { &y[..] } else { &y_early[..] };
        sys.step(&StepInput { positions: &pos, radii: &rad, y4_y7: y, load: l, external: None }).unwrap()
    };
    let mut last = Vec::new();
    for (depth, threads) in [(2, 2), (3, 2), (3, 1)] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let p = MechParams { warm_start: true, warm_start_depth: depth, rtol, ..params(LinearSolver::Amg) };
        pool.install(|| {
            let mut sys = BondedSystem::new(n, p, cons.clone()).unwrap();
            sys.set_topology(&pairs).unwrap();
            for l in [&l1, &l2, &l3] {
                step(&mut sys, l, &pairs);
            }
            last.push(step(&mut sys, &mix, &pairs));
        });
    }
    assert!(last[1].du == last[2].du, "depth 3: 1 vs 2 threads differ");
    assert!(last[0].info.warm_start > 1e3 * rtol && last[0].info.pcg_iterations > 0, "depth 2: {:?}", last[0].info);
    assert!(last[1].info.warm_start <= rtol && last[1].info.newton_iterations == 0, "depth 3: {:?}", last[1].info);
    let mut cold = BondedSystem::new(n, MechParams { rtol, ..params(LinearSolver::Amg) }, cons.clone()).unwrap();
    cold.set_topology(&pairs).unwrap();
    let c = step(&mut cold, &mix, &pairs);
    let scale = c.du.iter().map(|d| d.norm()).fold(0.0, f64::max);
    for w in &last {
        let diff = c.du.iter().zip(&w.du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(diff < 1e-6 * scale, "warm vs cold {diff:e} of {scale:e}");
    }
    assert!(MechParams { warm_start_depth: 9, ..params(LinearSolver::Amg) }.validate().is_err());
    assert!(MechParams { warm_start_depth: 0, ..params(LinearSolver::Amg) }.validate().is_err());

    // new bonds: the late ones join after a first step
    let early: Vec<[u32; 2]> = pairs.iter().enumerate().filter(|(k, _)| !late(*k)).map(|(_, p)| *p).collect();
    assert!(early.len() < pairs.len());
    let mut answers = Vec::new();
    for keep in [false, true] {
        let p = MechParams { rtol, amg_keep_on_new_bonds: keep, ..params(LinearSolver::Amg) };
        let mut sys = BondedSystem::new(n, p, cons.clone()).unwrap();
        sys.set_topology(&early).unwrap();
        let first = step(&mut sys, &loads(5, &early), &early);
        assert_eq!(first.info.amg_builds, 1);
        sys.set_topology(&pairs).unwrap();
        let second = step(&mut sys, &l1, &pairs);
        assert_eq!(second.info.amg_builds, if keep { 0 } else { 1 }, "keep = {keep}: {:?}", second.info);
        assert!(second.info.residuals.last().unwrap() <= &rtol);
        answers.push(second);
    }
    let scale = answers[0].du.iter().map(|d| d.norm()).fold(0.0, f64::max);
    let diff = answers[0].du.iter().zip(&answers[1].du).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
    assert!(diff < 1e-6 * scale, "kept vs fresh hierarchy {diff:e} of {scale:e}");
}

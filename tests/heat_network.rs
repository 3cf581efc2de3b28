//! The implicit heat network against exact solutions: exponential decay of a pair, the discrete
//! eigen-expansion of a chain between two fixed ends, convergence orders of the three schemes with
//! Δt far above the explicit limit C/(2K), and the energy balance to round-off.

use sinterdem::heat::{Furnace, HeatNetwork, HeatSources, Scheme};
use sinterdem::profile::Profile;

fn run(net: &mut HeatNetwork, temps: &mut [f64], k: &[f64], dt: f64, steps: usize) -> (f64, f64) {
    let (mut heat_in, mut stored) = (0.0, 0.0);
    let mut t = 0.0;
    for _ in 0..steps {
        let info = net.step(t, dt, temps, k).unwrap();
        heat_in += info.heat_in;
        stored += info.stored_change;
        t += dt;
    }
    (heat_in, stored)
}

fn observed_orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

/// Two particles C1 = 1, C2 = 3 J/K, K = 2 W/K: T1 − T2 decays as exp(−K(1/C1 + 1/C2) t).
#[test]
fn pair_decays_exponentially_at_the_scheme_order() {
    let (c1, c2, k): (f64, f64, f64) = (1.0, 3.0, 2.0);
    let lambda = k * (1.0 / c1 + 1.0 / c2);
    let t_end = 1.0;
    // explicit stability limit C/(2K) = 0.25 s; the steps below are smaller: this test's point
    // is the order. The chain test below runs at 2–16 × its explicit limit.
    for scheme in [Scheme::BackwardEuler, Scheme::CrankNicolson, Scheme::Bdf2] {
        let mut errors = Vec::new();
        for m in [0, 1, 2, 3] {
            let dt = 0.05 / f64::powi(2.0, m);
            let mut net = HeatNetwork::new(vec![c1, c2], HeatSources::default(), scheme, 1e-12);
            net.set_topology(&[[0, 1]]).unwrap();
            let mut temps = [400.0, 300.0];
            let steps = (t_end / dt).round() as usize;
            let (heat_in, stored) = run(&mut net, &mut temps, &[k], dt, steps);
            // isolated pair: no heat enters, total heat conserved to round-off
            assert!(heat_in.abs() < 1e-12 && stored.abs() < 1e-9, "{scheme:?}: {heat_in} {stored}");
            let mean = (c1 * 400.0 + c2 * 300.0) / (c1 + c2);
            assert!((c1 * temps[0] + c2 * temps[1] - (c1 + c2) * mean).abs() < 1e-9);
            let exact = 100.0 * (-lambda * t_end).exp();
            errors.push(((temps[0] - temps[1]) - exact).abs());
        }
        let orders = observed_orders(&errors);
        let p = scheme.order() as f64;
        for o in &orders {
            assert!((o - p).abs() < 0.15, "{scheme:?}: orders {orders:?}, errors {errors:?}");
        }
    }
}

/// A chain of N = 20 free particles (C = K = 1) between two ends held at 300 K and 500 K.
/// Exact: T(t) = T_ss + Σ_k c_k e^{−λ_k t} sin(kπl/(N+1)), λ_k = 2(K/C)(1 − cos(kπ/(N+1))).
/// Time steps 2–16 × the explicit limit C/(2K) = 0.5 s.
///
/// Two initial states: "step" (uniform 300 K, so the hot end is a jump that excites every mode,
/// the stiff ones included) and "smooth" (T_ss plus the two slowest modes). Backward Euler and
/// BDF2 reach their order on both. Crank–Nicolson is A- but not L-stable: on the step its stiff
/// modes are damped by only |1 − λΔt/2|/(1 + λΔt/2) per step, which dominates the error at these
/// Δt (order reduction, documented in docs/heat-model.md); on smooth data it is second order.
#[test]
fn chain_matches_discrete_eigen_expansion_at_the_scheme_order() {
    let n = 20usize;
    let np1 = (n + 1) as f64;
    let (tl, tr) = (300.0, 500.0);
    let cap = vec![1.0; n + 2];
    let sources = HeatSources {
        fixed: (0..n + 2)
            .map(|i| {
                if i == 0 {
                    Some(0)
                } else if i == n + 1 {
                    Some(1)
                } else {
                    None
                }
            })
            .collect(),
        profiles: vec![Profile::constant(tl).unwrap(), Profile::constant(tr).unwrap()],
        ..Default::default()
    };
    let pipes: Vec<[u32; 2]> = (0..=n as u32).map(|i| [i, i + 1]).collect();
    let k = vec![1.0; pipes.len()];
    let t_end = 64.0;
    let pi = std::f64::consts::PI;
    let phi = |m: usize, j: usize| (m as f64 * pi * j as f64 / np1).sin();
    let lam = |m: usize| 2.0 * (1.0 - (m as f64 * pi / np1).cos());
    let t_ss = |l: usize| tl + (tr - tl) * l as f64 / np1;
    for smooth in [false, true] {
        // modal coefficients of T0 − T_ss
        let coef: Vec<f64> = (1..=n)
            .map(|m| {
                if smooth {
                    match m {
                        1 => 50.0,
                        2 => 20.0,
                        _ => 0.0,
                    }
                } else {
                    (1..=n).map(|j| -(tr - tl) * j as f64 / np1 * phi(m, j)).sum::<f64>() * 2.0 / np1
                }
            })
            .collect();
        let exact = |l: usize, t: f64| t_ss(l) + (1..=n).map(|m| coef[m - 1] * (-lam(m) * t).exp() * phi(m, l)).sum::<f64>();
        for scheme in [Scheme::BackwardEuler, Scheme::CrankNicolson, Scheme::Bdf2] {
            if scheme == Scheme::CrankNicolson && !smooth {
                continue;
            }
            let mut errors = Vec::new();
            for dt in [8.0f64, 4.0, 2.0, 1.0] {
                let mut net = HeatNetwork::new(cap.clone(), sources.clone(), scheme, 1e-12);
                net.set_topology(&pipes).unwrap();
                let mut temps: Vec<f64> = (0..n + 2).map(|l| exact(l, 0.0)).collect();
                net.apply_fixed(0.0, &mut temps);
                let steps = (t_end / dt).round() as usize;
                let (heat_in, stored) = run(&mut net, &mut temps, &k, dt, steps);
                assert!((heat_in - stored).abs() <= 1e-12 * heat_in.abs().max(1.0), "{scheme:?}: balance {heat_in} vs {stored}");
                let err = (1..=n).map(|l| (temps[l] - exact(l, t_end)).abs()).fold(0.0, f64::max);
                errors.push(err);
            }
            let orders = observed_orders(&errors);
            let p = scheme.order() as f64;
            for o in &orders[1..] {
                assert!((o - p).abs() < 0.2, "{scheme:?} smooth={smooth}: orders {orders:?}, errors {errors:?}");
            }
        }
    }
}

/// A random network with Dirichlet nodes following a ramp, convection, radiation and volumetric
/// heating: stored heat equals heat in to round-off (radiation: to the Newton tolerance).
#[test]
fn energy_balance_with_every_source() {
    let n = 60usize;
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((seed >> 11) as f64) / ((1u64 << 53) as f64)
    };
    let cap: Vec<f64> = (0..n).map(|_| 0.5 + rnd()).collect();
    let mut pipes = Vec::new();
    for i in 0..n as u32 {
        for j in i + 1..n as u32 {
            if rnd() < 0.08 {
                pipes.push([i, j]);
            }
        }
    }
    let k: Vec<f64> = pipes.iter().map(|_| 0.5 + rnd()).collect();
    for radiation in [false, true] {
        for scheme in [Scheme::BackwardEuler, Scheme::CrankNicolson, Scheme::Bdf2] {
            let sources = HeatSources {
                fixed: (0..n).map(|i| if i < 4 { Some(0) } else { None }).collect(),
                profiles: vec![Profile::from_schedule("start 300 K, heat 600 K/min to 900 K, hold 1 min").unwrap()],
                exposed_area: (0..n).map(|i| if i % 5 == 0 { 1e-2 } else { 0.0 }).collect(),
                power: (0..n).map(|i| if i % 7 == 0 { 3.0 } else { 0.0 }).collect(),
                furnace: Some(Furnace {
                    gas: Profile::constant(350.0).unwrap(),
                    wall: Profile::from_table(&[[0.0, 300.0], [60.0, 1000.0]]).unwrap(),
                    convection: 20.0,
                    emissivity: if radiation { 0.8 } else { 0.0 },
                }),
            };
            let mut net = HeatNetwork::new(cap.clone(), sources, scheme, 1e-12);
            net.set_topology(&pipes).unwrap();
            let mut temps = vec![300.0; n];
            net.apply_fixed(0.0, &mut temps);
            let mut t = 0.0;
            let (mut hin, mut st, mut scale) = (0.0, 0.0, 0.0f64);
            for s in 0..60 {
                let dt = 0.5 + 0.3 * ((s % 3) as f64); // variable steps
                let info = net.step(t, dt, &mut temps, &k).unwrap();
                hin += info.heat_in;
                st += info.stored_change;
                scale += info.heat_in.abs();
                t += dt;
                if radiation {
                    assert!(info.iterations >= 2 && info.iterations <= 8, "{}", info.iterations);
                }
            }
            let rel = (hin - st).abs() / scale;
            let bound = if radiation { 1e-9 } else { 1e-13 };
            assert!(rel < bound, "{scheme:?} radiation {radiation}: {rel:e}");
            assert!(temps.iter().all(|v| v.is_finite() && *v > 250.0 && *v < 1200.0));
        }
    }
}

/// The factor is reused while nothing changes (fixed network, constant Δt, no radiation).
#[test]
fn factor_reuse_on_a_fixed_network() {
    let mut net = HeatNetwork::new(vec![1.0; 3], HeatSources::default(), Scheme::BackwardEuler, 1e-12);
    net.set_topology(&[[0, 1], [1, 2]]).unwrap();
    let mut temps = [300.0, 400.0, 500.0];
    let k = [1.0, 2.0];
    assert!(!net.step(0.0, 1.0, &mut temps, &k).unwrap().reused_factor);
    assert!(net.step(1.0, 1.0, &mut temps, &k).unwrap().reused_factor);
    assert!(!net.step(2.0, 0.5, &mut temps, &k).unwrap().reused_factor);
    assert!(net.step(2.0, 1.0, &mut temps, &[1.0, f64::NAN]).is_err());
    assert!(net.step(2.0, -1.0, &mut temps, &k).is_err());
}

//! `sinterdem bench heat`: assembly, symbolic analysis, factorisation and solve times of one
//! implicit heat step on random packings of N particles (the test matrices used when faer was chosen: random
//! points at unit density connected within a radius giving a mean degree ≈ 6, pipe conductances
//! from volume-conserving necks, Δt = 1000 × the explicit limit).

use crate::error::Error;
use crate::heat::{Conductance, HeatNetwork, HeatSources, Scheme};
use crate::particles::Particles;
use nalgebra::Vector3;
use std::time::Instant;

fn rng(seed: &mut u64) -> f64 {
    *seed ^= *seed << 13;
    *seed ^= *seed >> 7;
    *seed ^= *seed << 17;
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

/// A random overlapping packing of `n` copper spheres of radius 50 µm ± 10 % with mean
/// coordination ≈ 6 (centres uniform in a cube, radii scaled so that neighbours overlap).
pub fn random_packing(n: usize, seed: u64) -> Particles {
    let mut s = seed.max(1);
    let r0: f64 = 50e-6;
    // number density chosen so that spheres of radius r0·1.12 have ~6 neighbours within 2r
    let reach = 2.0 * r0 * 1.1;
    let density = 6.0 / (4.0 / 3.0 * std::f64::consts::PI * reach.powi(3));
    let side = (n as f64 / density).cbrt();
    let mut p = Particles::default();
    for _ in 0..n {
        let x = Vector3::new(rng(&mut s), rng(&mut s), rng(&mut s)) * side;
        let r = r0 * 1.1 * (1.0 + 0.1 * (2.0 * rng(&mut s) - 1.0));
        p.push(x, r, 0, 8960.0, 385.0, 300.0);
    }
    p
}

/// Prints the benchmark table.
pub fn bench_heat(sizes: &[usize], repeat: usize) -> Result<(), Error> {
    let mat = crate::material::preset("copper").unwrap();
    println!("# one implicit heat step (backward Euler, Δt = 1000 × explicit limit), {} rayon threads", rayon::current_num_threads());
    println!(
        "{:>9} {:>9} {:>11} {:>11} {:>11} {:>11} {:>11} {:>11} {:>10}",
        "particles", "contacts", "detect_s", "necks_s", "symbolic_s", "assemble_s", "factor_s", "solve_s", "residual"
    );
    for &n in sizes {
        let p = random_packing(n, 42 + n as u64);
        let mut rows = Vec::new();
        for _ in 0..repeat {
            let t0 = Instant::now();
            let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&p.position, &p.radius, 0.0).into_iter().map(|(i, j)| [i, j]).collect();
            let t_detect = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            // random points are not a sintered packing: overlaps are clipped to half the neck
            // model's limit so that every pair has a valid volume-conserving neck
            let law = Conductance::default();
            let conductance: Vec<f64> = pairs
                .iter()
                .map(|&[i, j]| {
                    let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
                    let d = (p.position[j as usize] - p.position[i as usize]).norm();
                    let h = (ri + rj - d).min(0.5 * crate::neck::max_overlap(ri, rj));
                    let a = crate::neck::solve(ri, rj, h).map(|n| n.a)?;
                    Ok(law.pipe(mat.conductivity, mat.conductivity, ri, rj, a).pair)
                })
                .collect::<Result<_, crate::error::ModelError>>()?;
            let pipes = crate::scene::Pipes { pairs, conductance, ..Default::default() };
            let q = &p;
            let t_necks = t1.elapsed().as_secs_f64();
            let kmax = pipes.conductance.iter().copied().fold(0.0, f64::max);
            let cmin = q.capacity.iter().copied().fold(f64::INFINITY, f64::min);
            let dt = 1000.0 * cmin / (2.0 * 6.0 * kmax);
            let mut net = HeatNetwork::new(q.capacity.clone(), HeatSources::default(), Scheme::BackwardEuler, 1e-9);
            let t_sym = net.set_topology(&pipes.pairs)?;
            let mut temps: Vec<f64> = (0..n).map(|i| 300.0 + 100.0 * (q.position[i].x * 1e3).sin()).collect();
            let info = net.step(0.0, dt, &mut temps, &pipes.conductance)?;
            rows.push((
                pipes.pairs.len(),
                t_detect,
                t_necks,
                t_sym,
                info.assemble_seconds,
                info.solve.factor_seconds,
                info.solve.solve_seconds,
                info.solve.residual,
            ));
        }
        rows.sort_by(|a, b| a.5.total_cmp(&b.5));
        let r = rows[rows.len() / 2];
        println!("{:>9} {:>9} {:>11.4} {:>11.4} {:>11.4} {:>11.4} {:>11.4} {:>11.4} {:>10.1e}", n, r.0, r.1, r.2, r.3, r.4, r.5, r.6, r.7);
    }
    Ok(())
}

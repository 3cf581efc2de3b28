//! Stage 3, diffusion: every contact's 7-DOF ODE over the step at its own temperature path, four
//! contacts at a time side by side in a rayon sweep (docs/diffusion7.md §7).

use super::Window;
use crate::coupled::Simulation;
use crate::error::{Error, ModelError};
use crate::models::diffusion7::lanes::{LANES, advance_lanes, work_order};
use crate::models::diffusion7::{Contact7, PairMaterials, TemperaturePath, skip};
use crate::models::ode::OdeStats;
use rayon::prelude::*;

/// What the sweep of a trial step gives the step control.
pub(in crate::coupled) struct Sweep {
    /// Integration counters per contact, in contact order.
    pub stats: Vec<OdeStats>,
    /// Strategy 1 (docs/coupled.md (S1)–(S2)): one step of the whole Δt per contact, rejected as
    /// a whole when any contact rejects it.
    pub strategy1: bool,
    /// Contacts that needed more steps than allowed (strategy 2) or rejected the trial (strategy 1).
    pub subdivided: usize,
}

/// The contact temperature of a pair from its particles' [K]: harmonic or arithmetic mean.
pub(in crate::coupled) fn contact_temperature(harmonic: bool, a: f64, b: f64) -> f64 {
    if harmonic { 2.0 * a * b / (a + b) } else { 0.5 * (a + b) }
}

/// Stage 3: integrates every contact from `w.t0` to `w.t1`, its temperature going linearly from
/// that of `temps_old` to that of the particles now (the furnace profile when isothermal). On a
/// failure the state goes back to the last completed step (heat included) and the error is returned.
pub(in crate::coupled) fn diffusion(sim: &mut Simulation, w: &Window, temps_old: &[f64]) -> Result<Sweep, Error> {
    let (t0, t1, dt) = (w.t0, w.t1, w.dt);
    let strategy1 = sim.settings.strategy == 1 && dt > sim.settings.dt_min;
    let mut solver = sim.settings.solver;
    if strategy1 {
        // strategy 1 (docs/coupled.md (S1)–(S2)): every contact tries one step of the whole Δt; the first
        // rejection anywhere rejects the global step (no adaptive retries)
        solver.stop_on_reject = true;
        for c in sim.contacts.state.iter_mut() {
            c.h_last = dt * (1.0 + 1e-9);
        }
    }
    let p = &sim.prep.scene.particles;
    let temps_new = &p.temperature;
    let iso = sim.prep.isothermal.as_ref();
    let mats = &sim.d7_materials;
    let factors = sim.settings.factors;
    let harmonic = sim.settings.harmonic;
    let ct = |a: f64, b: f64| contact_temperature(harmonic, a, b);
    let pair_materials = |[i, j]: [u32; 2]| PairMaterials { a: &mats[p.material[i as usize] as usize], b: &mats[p.material[j as usize] as usize], factors };
    let path_of = |[i, j]: [u32; 2]| {
        let (i, j) = (i as usize, j as usize);
        match iso {
            Some(prof) => TemperaturePath::Profile(prof),
            None => TemperaturePath::Linear { t0, temp0: ct(temps_old[i], temps_old[j]), t1, temp1: ct(temps_new[i], temps_new[j]) },
        }
    };
    // contacts that cannot change within the tolerance over the step keep their state
    // (docs/diffusion7.md (T2)); decided per contact from its own state and temperature path,
    // so the same on any number of threads; not in a strategy-1 trial, whose growth test reads
    // every contact's proposed substep
    // per contact: 0 not measured, 1 measured and integrated, 2 skipped; tested only when its
    // last change rate makes it a candidate (`skip::TEST_BELOW`, a matter of cost only)
    let skip_on = solver.skip_unchanged && !strategy1;
    let skipped: Vec<u8> = if skip_on {
        sim.contacts
            .state
            .par_iter_mut()
            .zip(sim.contacts.pairs.par_iter())
            .map(|(c, &pair)| {
                if c.change_rate * dt > skip::TEST_BELOW {
                    return 0;
                }
                match skip::skippable(c, &pair_materials(pair), &path_of(pair), t0, t1, &solver) {
                    (true, Some(s)) => {
                        c.change_rate = s / dt;
                        2
                    }
                    (_, Some(_)) => 1,
                    (_, None) => 0,
                }
            })
            .collect()
    } else {
        Vec::new()
    };
    let n_skipped = skipped.iter().filter(|&&k| k == 2).count();
    // contacts four at a time side by side (docs/diffusion7.md §7 "The sweep in lanes"),
    // each ending bit for bit where the scalar integration would; lanes run in lockstep, so
    // contacts of alike work share a chunk: the order by last step's substeps, new contacts
    // together (the result does not depend on it); skipped contacts left out
    let mut order = work_order(&sim.contacts.state, &sim.contacts.substeps);
    if n_skipped > 0 {
        let all = order.take().unwrap_or_else(|| (0..sim.contacts.len() as u32).collect());
        order = Some(all.into_iter().filter(|&k| skipped[k as usize] != 2).collect());
    }
    let (mut work, work_pairs) = match &order {
        Some(o) => (o.iter().map(|&k| sim.contacts.state[k as usize]).collect(), o.iter().map(|&k| sim.contacts.pairs[k as usize]).collect()),
        None => (Vec::new(), Vec::new()),
    };
    let (states, pairs_in_order): (&mut [Contact7], &[[u32; 2]]) =
        if order.is_some() { (&mut work, &work_pairs) } else { (&mut sim.contacts.state, &sim.contacts.pairs) };
    let chunks: Vec<(Vec<Result<OdeStats, ModelError>>, usize)> = states
        .par_chunks_mut(LANES)
        .zip(pairs_in_order.par_chunks(LANES))
        .enumerate()
        .map(|(ch, (cs, ps))| {
            let pms: Vec<PairMaterials> = ps.iter().map(|&pair| pair_materials(pair)).collect();
            let paths: Vec<TemperaturePath> = ps.iter().map(|&pair| path_of(pair)).collect();
            let (res, n) = advance_lanes(cs, &pms, &paths, t0, t1, &solver);
            let res = res
                .into_iter()
                .zip(ps)
                .enumerate()
                .map(|(l, (r, &[i, j]))| {
                    let k = order.as_ref().map_or(ch * LANES + l, |o| o[ch * LANES + l] as usize);
                    r.map_err(|e| e.with_context(format!("contact {k} between particles {i} and {j}")))
                })
                .collect();
            (res, n)
        })
        .collect();
    let mut results: Vec<Result<OdeStats, ModelError>> = Vec::with_capacity(sim.contacts.len());
    for (r, n) in chunks {
        results.extend(r);
        sim.contacts_in_lanes += n as u64;
    }
    if let Some(o) = &order {
        // back to contact order (`o` holds every contact not skipped: their slots are written,
        // a skipped contact keeps its state and counts its one evaluation of (T2))
        let skip_stats = OdeStats { rhs: 1, skipped: 1, ..Default::default() };
        let mut back: Vec<Result<OdeStats, ModelError>> = (0..sim.contacts.len()).map(|_| Ok(skip_stats)).collect();
        for ((&k, r), c) in o.iter().zip(results).zip(&work) {
            sim.contacts.state[k as usize] = *c;
            back[k as usize] = r;
        }
        results = back;
    }
    if !skipped.is_empty() {
        // the evaluation of (T2) of a contact integrated after all
        for (r, &k) in results.iter_mut().zip(&skipped) {
            if let (Ok(s), 1) = (r, k) {
                s.rhs += 1;
            }
        }
    }
    sim.skipped_last = n_skipped;
    if skip_on {
        // the change rate of every integrated contact, for the next sweep's test
        sim.contacts.state.par_iter_mut().zip(skipped.par_iter()).for_each(|(c, &k)| {
            if k != 2 {
                c.change_rate = skip::change_rate(c, &c.y_prev, dt, &solver);
            }
        });
    }
    let mut stats = Vec::with_capacity(results.len());
    let mut trial_rejected = 0usize;
    for r in results {
        match r {
            Ok(s) => stats.push(s),
            Err(e) if strategy1 && e.message == crate::models::ode::STEP_REJECTED => {
                trial_rejected += 1;
                stats.push(OdeStats { rejected: 1, ..Default::default() });
            }
            Err(e) => {
                // the state stays that of the last completed step
                sim.undo_sweep(temps_old);
                return Err(e.into());
            }
        }
    }
    if let Err(e) = crate::finite::ensure_finite_groups("diffusion", sim.step + 1, t1, "contact", "7-DOF state", sim.contacts.state.iter().map(|c| &c.y)) {
        sim.undo_sweep(temps_old);
        return Err(e.into());
    }
    let subdivided = if strategy1 { trial_rejected } else { stats.iter().filter(|s| s.steps > sim.settings.substeps_allowed).count() };
    Ok(Sweep { stats, strategy1, subdivided })
}

//! Stage 3, diffusion: every contact's 7-DOF ODE over the step at its own temperature path, four
//! contacts at a time side by side in a rayon sweep (docs/diffusion7.md §7).

use super::Window;
use crate::coupled::Simulation;
use crate::error::{Error, ModelError};
use crate::models::diffusion7::lanes::{LANES, advance_lanes, work_order};
use crate::models::diffusion7::{Contact7, PairMaterials, TemperaturePath};
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
    // contacts four at a time side by side (docs/diffusion7.md §7 "The sweep in lanes"),
    // each ending bit for bit where the scalar integration would; lanes run in lockstep, so
    // contacts of alike work share a chunk: the order by last step's substeps, new contacts
    // together (the result does not depend on it)
    let order = work_order(&sim.contacts.state, &sim.contacts.substeps);
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
            let pms: Vec<PairMaterials> = ps
                .iter()
                .map(|&[i, j]| PairMaterials { a: &mats[p.material[i as usize] as usize], b: &mats[p.material[j as usize] as usize], factors })
                .collect();
            let paths: Vec<TemperaturePath> = ps
                .iter()
                .map(|&[i, j]| {
                    let (i, j) = (i as usize, j as usize);
                    match iso {
                        Some(prof) => TemperaturePath::Profile(prof),
                        None => TemperaturePath::Linear { t0, temp0: ct(temps_old[i], temps_old[j]), t1, temp1: ct(temps_new[i], temps_new[j]) },
                    }
                })
                .collect();
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
        // back to contact order (`o` is a permutation: every slot is written)
        let mut back: Vec<Result<OdeStats, ModelError>> = (0..o.len()).map(|_| Ok(OdeStats::default())).collect();
        for ((&k, r), c) in o.iter().zip(results).zip(&work) {
            sim.contacts.state[k as usize] = *c;
            back[k as usize] = r;
        }
        results = back;
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

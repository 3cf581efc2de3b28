//! Stage 6, step control: a trial step rejected (strategy 1) or kept, the time advanced and the
//! next Δt chosen (strategies 1 and 2, docs/coupled.md (S1)–(S3)).

use super::Window;
use super::diffusion::Sweep;
use crate::coupled::Simulation;
use crate::heat::HeatStepInfo;
use nalgebra::Vector3;

/// Strategy 1: a trial step in which any contact needed more than one step is rejected: the
/// state goes back to `temps_old` [K] and the last corrected contacts, Δt shrinks by α. Returns
/// whether the step was rejected (then it is tried again).
pub(in crate::coupled) fn reject(sim: &mut Simulation, w: &Window, sweep: &Sweep, temps_old: &[f64]) -> bool {
    if !(sweep.strategy1 && sweep.subdivided > 0) {
        return false;
    }
    sim.undo_sweep(temps_old);
    for s in &sweep.stats {
        sim.ode.add(s);
    }
    sim.rejected += 1;
    sim.dt = (w.dt / sim.settings.alpha).max(sim.settings.dt_min);
    true
}

/// Keeps the sweep of the step: its integration counters and substeps, and the heat balance of
/// the step's heat solve.
pub(in crate::coupled) fn keep(sim: &mut Simulation, sweep: &Sweep, heat_info: Option<HeatStepInfo>) {
    for (s, n) in sweep.stats.iter().zip(sim.contacts.substeps.iter_mut()) {
        sim.ode.add(s);
        *n = s.steps as u32;
    }
    if let Some(info) = heat_info {
        sim.heat_in += info.heat_in;
        sim.heat_stored += info.stored_change;
        sim.heat_scale += info.heat_in.abs();
    }
}

/// Stage 6: the time advanced to `w.t1` (onto the end time when within rounding), the particle
/// velocities over the step from `x_start` [m], and the next Δt from the step's `subdivided`
/// contacts.
pub(in crate::coupled) fn step_control(sim: &mut Simulation, w: &Window, x_start: &[Vector3<f64>], subdivided: usize) {
    let (t1, end, dt) = (w.t1, w.end, w.dt);
    sim.t = if t1 >= end * (1.0 - 1e-12) { end } else { t1 };
    for ((v, x), x0) in sim.velocity.iter_mut().zip(&sim.prep.scene.particles.position).zip(x_start) {
        *v = (x - x0) / dt;
    }
    // a step shortened to land on an output or the end time does not lower the controller's Δt
    let base = if w.shortened { sim.dt } else { dt };
    sim.step += 1;
    if let Some(prof) = &sim.prep.isothermal {
        // isothermal: the particles carry the furnace temperature (output only; the
        // contacts read the profile itself)
        let temp = prof.temperature(sim.t);
        sim.prep.scene.particles.temperature.iter_mut().for_each(|v| *v = temp);
    }
    let m = sim.contacts.len();
    let frac = if m > 0 { subdivided as f64 / m as f64 } else { 0.0 };
    let s = &sim.settings;
    sim.dt = match s.strategy {
        1 => {
            // grow when every contact's next proposed substep exceeds 1.43 Δt, i.e. e_j < 0.1 ((S2); Ivannikov et al. 2022 eq. 46)
            let min_h = sim.contacts.state.iter().map(|c| c.h_last).fold(f64::INFINITY, f64::min);
            if min_h >= 0.9 * 10f64.powf(0.2) * dt { (base * s.alpha).min(s.dt_max) } else { base }
        }
        _ => {
            if frac < s.grow_below {
                (base * s.alpha).min(s.dt_max)
            } else if frac > s.shrink_above {
                (dt / s.alpha).max(s.dt_min)
            } else {
                base
            }
        }
    };
}

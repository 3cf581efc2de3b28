//! One step of the heat run: where it must land (end, next snapshot, profile kink), its Δt under
//! the fixed or error-controlled step (docs/heat-model.md eqs. E1–E3), the network solve, the
//! local error estimate, and the retries of a rejected or failed step.

use super::HeatLoop;
use crate::error::Error;
use crate::heat::adaptive::StepControl;
use crate::heat::{HeatNetwork, PipeConductance, Scheme};
use crate::profile::Profile;
use crate::scene::{Prepared, step_control};

/// What the loop holds fixed: end time, the case's Δt, snapshot times, the kinks of the prescribed
/// profiles, the step control (None: the fixed Δt of the case), the checkpoint interval.
pub(super) struct Plan {
    pub end: f64,
    pub dt0: f64,
    /// Times closer than this are the same [s].
    pub tiny: f64,
    pub snap_times: Vec<f64>,
    /// The extrapolation of the error estimate is not valid across a kink of a prescribed
    /// profile: it restarts there, and adaptive steps land on them.
    pub kinks: Vec<f64>,
    pub control: Option<StepControl>,
    pub scheme: Scheme,
    pub ck_every: usize,
}

impl Plan {
    pub fn new(prep: &Prepared, log: &mut dyn FnMut(&str)) -> Result<Plan, Error> {
        let case = &prep.case;
        let (end, dt0) = (case.time.end, case.time.dt);
        let snap_times: Vec<f64> = match case.output.snapshots as usize {
            0 => vec![],
            1 => vec![end],
            k => (0..k).map(|i| end * i as f64 / (k - 1) as f64).collect(),
        };
        let kinks = kinks_of(prep, end);
        // step control (eq. E3): None = the fixed Δt of the case
        let control = step_control(case)?;
        if let Some(c) = &control {
            log(&format!("Δt chosen by error: time.heat_tolerance = {} K per step, first step {dt0} s, Δt in [{:e}, {:e}] s", c.tolerance, c.dt_min, c.dt_max));
        }
        Ok(Plan { end, dt0, tiny: 1e-12 * end, snap_times, kinks, control, scheme: case.time.scheme, ck_every: case.output.checkpoint_every as usize })
    }

    /// Re-reads the kinks of the prescribed profiles (after the caller changed the furnace's).
    pub fn update_kinks(&mut self, prep: &Prepared) {
        self.kinks = kinks_of(prep, self.end);
    }

    /// Whether the step that ended at `t` after `steps` steps writes a checkpoint.
    pub fn checkpoint_due(&self, steps: usize, t: f64) -> bool {
        self.ck_every > 0 && steps.is_multiple_of(self.ck_every) && t < self.end * (1.0 - 1e-12)
    }

    /// Where the step from `t` must land: the end, or (adaptive) the next snapshot or profile kink.
    fn stop(&self, t: f64, next_snap: usize) -> f64 {
        match &self.control {
            None => self.end,
            Some(_) => {
                let snap = self.snap_times.get(next_snap).copied().filter(|&s| s > t + self.tiny).unwrap_or(self.end);
                let kink = self.kinks.iter().copied().find(|&k| k > t + self.tiny).unwrap_or(self.end);
                self.end.min(snap).min(kink)
            }
        }
    }
}

/// The breakpoints in (0, end) of the fixed-temperature profiles and the furnace's, sorted.
fn kinks_of(prep: &Prepared, end: f64) -> Vec<f64> {
    let mut kinks: Vec<f64> = prep.sources.profiles.iter().flat_map(|p| p.breakpoints().to_vec()).collect();
    if let Some(f) = &prep.sources.furnace {
        kinks.extend_from_slice(f.gas.breakpoints());
        kinks.extend_from_slice(f.wall.breakpoints());
    }
    kinks.retain(|k| *k > 0.0 && *k < end);
    kinks.sort_by(f64::total_cmp);
    kinks
}

/// An accepted step: its Δt [s], radiation iterations, heat into the free particles [J].
pub(super) struct Step {
    pub dt: f64,
    pub iterations: u32,
    pub heat_in: f64,
}

/// One try at a step: accepted, or rejected with the next step length to try [s].
enum Attempt {
    Accepted(Step),
    Retry(f64),
}

/// Advances the temperatures by one accepted step from `st.t`, retrying shorter steps while the
/// error control rejects them or a solve fails; the loop state's accounts include the step (not
/// its time and count).
pub(super) fn advance(
    plan: &Plan,
    st: &mut HeatLoop,
    prep: &mut Prepared,
    net: &mut HeatNetwork,
    parts: &[PipeConductance],
    log: &mut dyn FnMut(&str),
) -> Result<Step, Error> {
    let stop = plan.stop(st.t, st.next_snap);
    let mut h = match &plan.control {
        None => plan.dt0,
        Some(c) => st.dt_next.unwrap_or(plan.dt0).clamp(c.dt_min, c.dt_max),
    };
    let temps = &mut prep.scene.particles.temperature;
    loop {
        match attempt(plan, st, temps, prep.isothermal.as_ref(), net, parts, h, stop, log)? {
            Attempt::Accepted(step) => return Ok(step),
            Attempt::Retry(next) => h = next,
        }
    }
}

/// One try of a step of length `h` towards `stop`.
fn attempt(
    plan: &Plan,
    st: &mut HeatLoop,
    temps: &mut Vec<f64>,
    isothermal: Option<&Profile>,
    net: &mut HeatNetwork,
    parts: &[PipeConductance],
    h: f64,
    stop: f64,
    log: &mut dyn FnMut(&str),
) -> Result<Attempt, Error> {
    let (t, tiny, control) = (st.t, plan.tiny, &plan.control);
    let left = stop - t;
    let dt = if h >= left * (1.0 - 1e-12) {
        left
    } else if control.is_some() && h > 0.5 * left {
        0.5 * left // two equal steps rather than a sliver
    } else {
        h
    };
    if let Some(prof) = isothermal {
        let tt = prof.temperature(t + dt);
        temps.iter_mut().for_each(|v| *v = tt);
        return Ok(Attempt::Accepted(Step { dt, iterations: 0, heat_in: 0.0 }));
    }
    let spans_kink = plan.kinks.iter().any(|&k| k > t + tiny && k < t + dt - tiny);
    if spans_kink || st.hist_t.last().is_some_and(|&tl| (tl - t).abs() > tiny) {
        st.hist.clear();
        st.hist_t.clear();
        st.hist.push(temps.clone());
        st.hist_t.push(t);
    }
    let saved = control.as_ref().map(|_| (temps.clone(), net.history().cloned()));
    // the fixed-Δt report uses full-order estimates only; step control also the
    // conservative lower-order ones while the history builds up
    let ydot = (control.is_some() && st.hist.len() == 1 && !spans_kink).then(|| net.rate_of_change(t, temps, parts));
    let bdf2_step = plan.scheme == Scheme::Bdf2 && net.history().is_some();
    let step_order = if plan.scheme == Scheme::BackwardEuler || (plan.scheme == Scheme::Bdf2 && !bdf2_step) { 1 } else { 2 };
    let info = match (net.step_pipes(t, dt, temps, parts), control, &saved) {
        (Ok(i), _, _) => i,
        (Err(e), Some(c), Some((before, bdf))) if dt > c.dt_min * (1.0 + 1e-9) => {
            // a failed solve (radiation or property iteration) on a long step: shorter
            log(&format!("t = {t:e} s: step of {dt:e} s failed ({e}); retried with a shorter one"));
            temps.clone_from(before);
            net.set_history(bdf.clone());
            st.rejected += 1;
            return Ok(Attempt::Retry((dt * crate::heat::adaptive::SHRINK_MIN).max(c.dt_min)));
        }
        (Err(e), _, _) => return Err(e.into()),
    };
    crate::finite::ensure_finite("heat", st.steps as u64 + 1, t + dt, "particle", "temperature", temps.iter().copied())?;
    let est = if spans_kink {
        None
    } else {
        let vals: Vec<&[f64]> = st.hist.iter().map(|v| v.as_slice()).collect();
        crate::heat::adaptive::estimate(plan.scheme, bdf2_step, &st.hist_t, &vals, t + dt, temps, ydot.as_deref(), |i| !net.is_fixed(i))
            .filter(|e| control.is_some() || e.order == step_order)
    };
    if let (Some(c), Some(e), Some((before, bdf))) = (control, est, &saved) {
        if e.error > c.tolerance && dt > c.dt_min * (1.0 + 1e-9) {
            temps.clone_from(before);
            net.set_history(bdf.clone());
            st.rejected += 1;
            return Ok(Attempt::Retry((dt * c.factor(e.error, e.order).min(1.0)).max(c.dt_min)));
        }
        if e.error > c.tolerance {
            st.forced_at_dt_min += 1;
        }
        let proposal = (dt * c.factor(e.error, e.order)).clamp(c.dt_min, c.dt_max);
        // a step shortened to land on a stop does not shrink the next one
        st.dt_next = Some(if dt < h { proposal.max(st.dt_next.unwrap_or(plan.dt0)) } else { proposal });
    }
    if let Some(e) = est {
        st.max_err_est = st.max_err_est.max(e.error);
    }
    account(st, &info);
    let ends_at_kink = plan.kinks.iter().any(|&k| (k - (t + dt)).abs() <= tiny);
    if spans_kink || ends_at_kink {
        st.hist.clear();
        st.hist_t.clear();
    }
    st.hist.push(temps.clone());
    st.hist_t.push(t + dt);
    if st.hist.len() > 3 {
        st.hist.remove(0);
        st.hist_t.remove(0);
    }
    Ok(Attempt::Accepted(Step { dt, iterations: info.iterations, heat_in: info.heat_in }))
}

/// Adds an accepted step's energy, timing and solver figures to the loop state.
fn account(st: &mut HeatLoop, info: &crate::heat::HeatStepInfo) {
    st.heat_in += info.heat_in;
    st.stored += info.stored_change;
    st.stored_plain += info.stored_change_plain;
    st.scale += info.heat_in.abs();
    st.t_assemble += info.assemble_seconds;
    st.t_factor += info.solve.factor_seconds;
    st.t_solve += info.solve.solve_seconds;
    st.factorizations += (!info.reused_factor) as usize * info.iterations.max(1) as usize;
    st.max_resid = st.max_resid.max(info.solve.residual);
    st.max_iters = st.max_iters.max(info.iterations);
}

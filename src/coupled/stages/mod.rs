//! The stages of one coupled step ([`crate::coupled::Simulation::advance_step`], docs/coupled.md
//! "One step"), one function each, in the order they run: [`topology`], the applied load
//! ([`load`]), [`heat`], [`diffusion`], [`mechanics`], [`correction`], [`control`].

mod control;
mod correction;
mod diffusion;
mod heat;
mod load;
mod mechanics;
mod topology;

pub(super) use control::{keep, reject, step_control};
pub(super) use correction::correction;
pub(super) use diffusion::{contact_temperature, diffusion};
pub(super) use heat::heat;
pub(super) use mechanics::{mechanics, sliding_viscosities, tension_floors};
pub(super) use topology::topology;

/// The time window of a trial step [s]: from `t0` to `t1 = t0 + dt`, ending no later than `end`
/// (the run's end or the next output time).
#[derive(Debug, Clone, Copy)]
pub(super) struct Window {
    pub t0: f64,
    pub t1: f64,
    pub dt: f64,
    pub end: f64,
    /// The step was shortened to land on `end` (it does not lower the controller's Δt).
    pub shortened: bool,
}

impl Window {
    /// The next trial step from `t0` with the controller's `dt`, cut at `end` [s].
    pub(super) fn new(t0: f64, dt: f64, end: f64) -> Window {
        let step = dt.min(end - t0);
        Window { t0, t1: t0 + step, dt: step, end, shortened: step < dt }
    }
}

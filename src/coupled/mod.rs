//! The staggered loop of a compact run (`kind = "compact"`, docs/coupled.md "One step"):
//! 1. topology (new contacts by cell list);
//! 2. heat (implicit network, conductances from the current necks);
//! 3. diffusion (every contact's 7-DOF ODE over the step at its own temperature, rayon sweep);
//! 4. mechanics (bonded quasi-static equilibrium under the load increments);
//! 5. correction of y4, y7 ((C1)–(C4), docs/coupled.md);
//! 6. step control (strategies 1 and 2);
//! 7. output. Stages a scene does not need are skipped and the log says so.
//!
//! Determinism: every contact writes only its own slot in the parallel sweep and all reductions
//! run sequentially in contact order, so results are bit-identical for any thread count.

//!
//! Files: [`settings`](Settings) (the case read), `contacts` (the contact store), `simulation`
//! (the state and its construction), `step` ([`Simulation::advance_step`], one call per stage of
//! `stages/`), `bonded` (the mechanics adapter), `validity` (the checks after a step), [`dose`] (the diffusion dose and the calibrated-range verdict),
//! `observables` (what the outputs report), [`expansion`], [`load`].

mod bonded;
pub mod cell;
mod contacts;
pub mod dose;
pub mod expansion;
pub mod load;
mod observables;
mod settings;
mod simulation;
mod stages;
mod step;
mod validity;

pub use bonded::{MechProfile, MechanicsStage};
pub use contacts::{Contacts, new_contact_neck};
pub use settings::{MechanicsSettings, NeckSource, NewContactState, Settings};
pub use simulation::{Simulation, Timing, prepare};

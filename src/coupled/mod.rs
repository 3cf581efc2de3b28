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

pub mod expansion;
pub mod load;
mod step;

pub use step::*;

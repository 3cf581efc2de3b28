//! The staggered loop of a compact run (`kind = "compact"`; architecture map "The loop"):
//! 1. topology (new contacts by cell list), 2. heat (implicit network, conductances from the
//! current necks), 3. diffusion (every contact's 7-DOF ODE over the step at its own temperature,
//! rayon sweep), 4. mechanics (bonded quasi-static equilibrium under the load increments),
//! 5. correction of y4, y7 (seven-dof-model.md §9), 6. step control (§10, strategies 1 and 2),
//! 7. output. Stages a scene does not need are skipped and the log says so.
//!
//! Determinism: every contact writes only its own slot in the parallel sweep and all reductions
//! run sequentially in contact order, so results are bit-identical for any thread count.

mod bench;
mod checkpoint;
mod driver;
mod output;
mod step;
mod validate;

pub use bench::bench_coupled;
pub use checkpoint::{read_checkpoint, resume, Checkpoint, OutputState};
pub use driver::{run, run_from};
pub use output::{compact_conductivity, write_correction_histogram, write_plots};
pub use step::*;
pub use validate::MAX_CHECKPOINT_STEP;
pub(crate) use checkpoint::write_checkpoint;
pub(crate) use output::{write_snapshot, Due};

//! `sinterdem bench …`: the benchmarks and the precision ladder. They sit above the run kinds
//! (they run cases through [`crate::kinds::run`]) and beside no physics: each times or measures a
//! room below it (docs/coupled.md "Scaling", docs/heat-model.md, docs/mechanics.md,
//! docs/diffusion7.md §7, docs/studies.md).
//!
//! - [`heat`]: the implicit heat step on 10³–10⁵ particles, fixed against error-controlled Δt;
//! - [`mechanics`]: the bonded solve (Cholesky against AMG-CG);
//! - [`coupled`]: the coupled loop per stage; [`precision`]: run time against error of it;
//! - [`diffusion7`]: work-precision of the 7-DOF integrators and the sweep in lanes;
//! - [`generate`]: packing generation;
//! - [`study`]: the study engine's overhead per run.

pub mod coupled;
pub mod diffusion7;
pub mod generate;
pub mod heat;
pub mod mechanics;
pub mod precision;
pub mod study;

pub use coupled::bench_coupled;

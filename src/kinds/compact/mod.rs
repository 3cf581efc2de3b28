//! The compact run (`kind = "compact"`): the driver around the staggered step of [`crate::coupled`],
//! its outputs, checkpoints and the validation of a resumed run.

mod checkpoint;
mod columns;
mod driver;
mod output;
mod stepping;
mod validate;

pub(crate) use checkpoint::write_checkpoint;
pub use checkpoint::{CHECKPOINT_FORMAT, Checkpoint, OutputState, read_checkpoint, resume};
pub use driver::{CompactRun, run, run_from};
pub(crate) use output::plot_header;
pub(crate) use output::{Due, write_snapshot};
pub use output::{compact_conductivity, mean_overlap_ratio, periodic_conductivity, write_correction_histogram, write_plots};
pub use validate::MAX_CHECKPOINT_STEP;

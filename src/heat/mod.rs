//! The heat network (docs/heat-model.md): conductance of a pipe, the implicit network step, and the
//! effective conductivity of a compact.

pub mod adaptive;
pub mod bench;
pub mod conductance;
pub mod conductivity;
pub mod fe_fit;
pub mod gap;
pub mod network;
pub mod properties;
pub mod run;

pub use conductance::{Conductance, ConductanceLaw, PipeConductance};
pub use network::{Furnace, HeatNetwork, HeatSources, HeatStepInfo, Scheme};

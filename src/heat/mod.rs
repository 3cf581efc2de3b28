//! The heat network (docs/heat-model.md): conductance of a pipe, the implicit network step, and the
//! effective conductivity of a compact.

pub mod adaptive;
pub mod balance;
pub mod conductance;
pub mod conductivity;
pub mod fe_fit;
pub mod gap;
pub mod network;
pub mod pipes;
pub mod properties;

pub use conductance::{Conductance, ConductanceLaw, MultiNeck, PipeConductance};
pub use network::{Furnace, HeatNetwork, HeatSources, HeatStepInfo, Scheme};
pub use pipes::{Pipes, pipes, pipes_from_pairs};

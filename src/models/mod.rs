//! Contact models and their small integrators (docs/design.md).
//!
//! - [`diffusion7`]: the 7-DOF diffusion contact (docs/diffusion7.md);
//! - [`luding`]: Luding's long-time sintering law (docs/luding.md);
//! - [`frenkel`]: the SinterNormal family (docs/frenkel.md);
//! - [`ode`]: fixed-size adaptive integrators (Dormand–Prince 5(4), RK4 step doubling, Rosenbrock 4(3)).

pub mod diffusion7;
pub mod frenkel;
pub mod luding;
pub mod ode;

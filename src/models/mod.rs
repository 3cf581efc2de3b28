//! Contact models and their small integrators (architecture map `models/`).
//!
//! - [`diffusion7`]: the 7-DOF diffusion contact (seven-dof-model.md);
//! - [`luding`]: Luding's long-time sintering law (explicit-sintering-laws.md §1);
//! - [`frenkel`]: the SinterNormal family (explicit-sintering-laws.md §2);
//! - [`ode`]: fixed-size adaptive integrators (Dormand–Prince 5(4), RK4 step doubling, Rosenbrock 4(3)).

pub mod diffusion7;
pub mod frenkel;
pub mod luding;
pub mod ode;

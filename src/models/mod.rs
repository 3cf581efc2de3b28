//! Contact models and their small integrators (architecture map `models/`).
//!
//! - [`diffusion7`]: the 7-DOF diffusion contact (seven-dof-model.md);
//! - [`ode`]: fixed-size adaptive integrators (Dormand–Prince 5(4), RK4 step doubling, Rosenbrock 4(3)).

pub mod diffusion7;
pub mod ode;

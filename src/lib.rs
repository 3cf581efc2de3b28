//! # sinterdem
//!
//! A coupled thermo-mechanical simulator of powder sintering. One time step of a packing run
//! (see docs/design.md and docs/coupled.md):
//! 1. topology: new contacts by cell-list search,
//! 2. heat: implicit pipe network, `(C/Δt + L) T^{n+1} = C/Δt T^n + b` ([`heat`]),
//! 3. diffusion: the 7-DOF contact ODE at each contact's temperature,
//! 4. mechanics: bonded quasi-static equilibrium,
//! 5. correction of the contact state, 6. step control, 7. output.
//!
//! Modules are named for the physics or numerical job they do.

// `!(x > 0.0)` is the crate's way of rejecting NaN together with the out-of-range values (a
// `partial_cmp` chain would hide that intent); the lint is off on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bench;
pub mod calibrate;
pub mod cli;
pub mod config;
pub mod contacts;
pub mod coupled;
pub mod error;
pub mod explicit;
pub mod finite;
pub mod heat;
pub mod interrupt;
pub mod io;
pub mod kinds;
pub mod linsolve;
pub mod logging;
pub mod material;
pub mod mechanics;
pub mod models;
pub mod neck;
pub mod packing;
pub mod particles;
pub mod plot;
pub mod profile;
pub mod scene;
pub mod study;
pub mod units;

pub use error::{ConfigError, Error, ModelError, Result, SolveError};

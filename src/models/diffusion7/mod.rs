//! The 7-DOF diffusion contact (docs/diffusion7.md; Thomsen et al. 2018/2019 as used by
//! Ivannikov et al. 2022, [IV22]): neck radius y1, cap radii y2, y5, cone lengths y3, y6 and
//! centre–GB distances y4, y7 of a pair of particles evolve by surface, grain-boundary and lattice
//! diffusion driven by interfacial energy.
//!
//! - [`geometry`]: (G1)–(G10), admissibility (A1)–(A4);
//! - [`kinetics`]: potentials (M3), fluxes (M5), balances (M7), ODE (M8), [`rates`], [`invariants`];
//! - [`library`]: the bundled materials library (docs/materials.md);
//! - [`material`]: material data (§9), phases, resolution per contact (§3), coefficients (M9);
//! - [`contact`]: per-contact state, initial state (I1)–(I4), force (F4), (F5), correction (C1)–(C4);
//! - [`advance`]: adaptive per-contact integration over an interval, split at kinks and phase changes;
//! - [`skip`]: the bound (T2) on a contact's change over an interval (contacts the sweep need not integrate);

pub mod advance;
pub mod contact;
pub mod geometry;
pub mod kinetics;
pub mod lanes;
pub mod library;
pub mod material;
pub mod ranges;
pub mod skip;

pub use advance::{PairMaterials, SolverOptions, TemperaturePath, advance};
pub use contact::{Contact7, Correction, correct_y4_y7, initial_state, initial_state_with_neck, load_increment, sintering_force};
pub use kinetics::{Evaluation, evaluate, invariants, load_response, rates, rates_with};
pub use material::{ContactParams, Material, PathFactors, Phase};
pub use ranges::RANGES;

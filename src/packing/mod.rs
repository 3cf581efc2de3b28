//! Packings: size distributions and the seeded random numbers of generation ([`dist`]), import
//! of packings made elsewhere ([`import`]) and the packing report ([`report`]). Generating a green
//! body (`kind = "generate"`) is a run kind: [`crate::kinds::generate`].

pub mod dist;
pub mod import;
pub mod report;

pub use dist::{Rng, SizeDistribution};
pub use import::{ImportFormat, ImportedPacking, import, import_str};

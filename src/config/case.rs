//! The typed case file of a packing run (`kind = "heat"`, the default). See docs/case-file.md for
//! every key with default, unit and range.

use crate::heat::{ConductanceLaw, Scheme};
use crate::material::MaterialSpec;
use crate::profile::ProfileSpec;
use serde::{Deserialize, Serialize};

/// The whole case.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    /// What to run: "heat" (default). Other kinds are dispatched before this struct is read.
    #[serde(default)]
    pub kind: Option<String>,
    /// Free text shown in the log.
    #[serde(default)]
    pub title: Option<String>,
    pub time: TimeSpec,
    #[serde(default)]
    pub output: OutputSpec,
    pub materials: Vec<MaterialSpec>,
    pub particles: ParticlesSpec,
    #[serde(default)]
    pub thermal: ThermalSpec,
    /// Settings of `sinterdem conductivity`.
    #[serde(default)]
    pub conductivity: ConductivitySpec,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Simulated end time [s].
    pub end: f64,
    /// Time step [s].
    pub dt: f64,
    /// Heat scheme: backward_euler, crank_nicolson, bdf2 (default).
    #[serde(default)]
    pub scheme: Scheme,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Number of snapshots (VTU + HDF5) evenly spaced in time, the initial state included (default 5).
    #[serde(default = "default_snapshots")]
    pub snapshots: f64,
    /// A series row every this many steps (default 1).
    #[serde(default = "one")]
    pub series_every: f64,
    /// Write VTU/PVD snapshots (default true).
    #[serde(default = "yes")]
    pub vtu: bool,
    /// Write HDF5 (default true; needs the `h5` build feature).
    #[serde(default = "yes")]
    pub hdf5: bool,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec { snapshots: default_snapshots(), series_every: 1.0, vtu: true, hdf5: true }
    }
}

fn default_snapshots() -> f64 {
    5.0
}
fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}

/// Where the particles come from.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ParticlesSpec {
    /// "lattice", "pair" or "file".
    pub source: String,
    /// Lattice type: "sc", "bcc", "fcc".
    pub lattice: Option<String>,
    /// Lattice cells per axis.
    pub cells: Option<[u32; 3]>,
    /// Particle radius [m] (lattice, pair).
    pub radius: Option<f64>,
    /// Second radius of a pair [m] (default: `radius`).
    pub radius_2: Option<f64>,
    /// Overlap h relative to the smaller radius [1] (lattice nearest neighbours, pair).
    #[serde(default)]
    pub overlap: f64,
    /// Packing file (CSV x,y,z,r[,material][,temperature]) relative to the case file.
    pub file: Option<String>,
    /// Material name for every particle (default: the first material).
    pub material: Option<String>,
    /// Initial temperature [K] (default 293.15).
    pub initial_temperature: Option<f64>,
}

/// A set of particles.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// A face of the packing's bounding box: "x-", "x+", "y-", "y+", "z-", "z+": particles whose
    /// sphere comes within `depth` of it.
    pub face: Option<String>,
    /// Depth for `face` [m] (default: the mean radius).
    pub depth: Option<f64>,
    /// Axis-aligned box `[[xmin, ymin, zmin], [xmax, ymax, zmax]]` containing the centres [m].
    #[serde(rename = "box")]
    pub bbox: Option<[[f64; 3]; 2]>,
    /// A layer of centres `from ≤ x_axis ≤ to` [m].
    pub layer: Option<LayerSpec>,
    /// Explicit particle indices (0-based, file order).
    pub particles: Option<Vec<u32>>,
    /// Every particle.
    pub all: Option<bool>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    pub axis: String,
    pub from: f64,
    pub to: f64,
}

/// Particles held at a prescribed temperature.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FixedSpec {
    pub region: RegionSpec,
    pub profile: ProfileSpec,
}

/// Volumetric heat generation in a region.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct VolumetricSpec {
    pub region: RegionSpec,
    /// q‴ [W/m³].
    pub power_density: f64,
}

/// The furnace atmosphere.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct FurnaceSpec {
    /// Furnace temperature history (gas and walls).
    pub profile: ProfileSpec,
    /// Separate wall temperature history for radiation (default: `profile`).
    pub wall_profile: Option<ProfileSpec>,
    /// h_c [W/(m²·K)] (default 0).
    #[serde(default)]
    pub convection_coefficient: f64,
    /// ε [1] (default 0).
    #[serde(default)]
    pub emissivity: f64,
    /// Fraction of an exposed particle's sphere area that sees the furnace [1] (default 0.5).
    #[serde(default = "half")]
    pub exposure: f64,
    /// Which particles are exposed (default: the six faces of the bounding box, one mean radius deep).
    pub exposed: Option<RegionSpec>,
}

fn half() -> f64 {
    0.5
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ThermalSpec {
    /// "network" (default) or "isothermal" (every particle at the furnace profile; no heat solve).
    #[serde(default = "network")]
    pub mode: String,
    /// "linear" (default, c_K κ π a) or "fe_fit".
    #[serde(default)]
    pub conductance: ConductanceLaw,
    /// c_K of the linear law (default 1.064).
    #[serde(default = "ck")]
    pub conductance_factor: f64,
    /// Interface conductance in series [W/K] (default none).
    pub contact_conductance: Option<f64>,
    /// Radiation Newton tolerance (default 1e-9).
    #[serde(default = "rad_tol")]
    pub radiation_tolerance: f64,
    /// Contact temperature: "arithmetic" (default) or "harmonic".
    #[serde(default = "arith")]
    pub contact_temperature: String,
    #[serde(default)]
    pub fixed: Vec<FixedSpec>,
    #[serde(default)]
    pub volumetric: Vec<VolumetricSpec>,
    pub furnace: Option<FurnaceSpec>,
}

impl Default for ThermalSpec {
    fn default() -> Self {
        ThermalSpec {
            mode: network(),
            conductance: ConductanceLaw::Linear,
            conductance_factor: ck(),
            contact_conductance: None,
            radiation_tolerance: rad_tol(),
            contact_temperature: arith(),
            fixed: Vec::new(),
            volumetric: Vec::new(),
            furnace: None,
        }
    }
}

fn network() -> String {
    "network".into()
}
fn ck() -> f64 {
    1.064
}
fn rad_tol() -> f64 {
    1e-9
}
fn arith() -> String {
    "arithmetic".into()
}

/// `sinterdem conductivity` settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ConductivitySpec {
    /// "faces" (default: two opposite layers held at fixed temperatures, per axis) or "periodic"
    /// (imposed mean gradient; needs a lattice).
    #[serde(default = "faces")]
    pub boundary: String,
    /// Axes to compute ("x", "y", "z"; default all).
    #[serde(default = "xyz")]
    pub axes: Vec<String>,
    /// T_hot − T_cold [K] (default 1).
    #[serde(default = "one")]
    pub temperature_difference: f64,
    /// Dirichlet layer thickness as a fraction of the extent along the axis; default: one mean
    /// radius (particles whose sphere touches the face).
    pub layer_fraction: Option<f64>,
}

impl Default for ConductivitySpec {
    fn default() -> Self {
        ConductivitySpec { boundary: faces(), axes: xyz(), temperature_difference: 1.0, layer_fraction: None }
    }
}

fn faces() -> String {
    "faces".into()
}
fn xyz() -> Vec<String> {
    vec!["x".into(), "y".into(), "z".into()]
}

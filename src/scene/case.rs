//! The typed case file of a packing run (`kind = "heat"`, the default). See docs/case-file.md for
//! every key with default, unit and range.

use crate::error::ConfigError;
pub use crate::heat::gap::GapSpec;
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
    /// Settings of `sinterdem conductivity` (and of the conductivity analyses of a compact run).
    #[serde(default)]
    pub conductivity: ConductivitySpec,
    /// Contacts of a compact run (`kind = "compact"`).
    pub contacts: Option<ContactsSpec>,
    /// 7-DOF path factors (`kind = "compact"`; same keys as a pair case).
    pub model: Option<crate::models::diffusion7::material::PathFactors>,
    /// 7-DOF integrator (`kind = "compact"`; same keys as a pair case).
    pub solver: Option<crate::models::diffusion7::advance::SolverOptions>,
    /// Bonded mechanics (`kind = "compact"`).
    pub mechanics: Option<MechanicsSpec>,
    /// Applied load: hot pressing or isostatic pressure (`kind = "compact"`; docs/pressure.md).
    pub load: Option<LoadSpec>,
    /// Constitutive data of a periodic compact (`sinterdem rve`, docs/rve.md): read by
    /// `crate::kinds::rve` only; `sinterdem run` runs the free compact and ignores it.
    pub rve: Option<toml::Value>,
}

/// An applied mechanical load on the compact (docs/pressure.md): a compressive stress following
/// a profile in time, on one face (`uniaxial`, the opposite principal plane held) or on every
/// outer face (`isostatic`).
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct LoadSpec {
    /// "none", "uniaxial" (hot pressing) or "isostatic".
    pub mode: String,
    /// Load axis of `uniaxial`: "x", "y" or "z" (default "z"); the load acts on the far face.
    pub axis: Option<String>,
    /// Constant compressive stress [Pa] (exactly one of `stress`, `stress_table`).
    pub stress: Option<f64>,
    /// Piecewise-linear stress history `[[time s, stress Pa], …]`, times strictly increasing;
    /// the first value before the first row, the last after the last row.
    pub stress_table: Option<Vec<[f64; 2]>>,
    /// Largest mean normal stress |F_n|/(π a²) a contact passes to its diffusion model [Pa]
    /// (docs/pressure.md (P5): the flow stress above which a neck yields plastically; default:
    /// no limit).
    pub contact_stress_limit: Option<f64>,
}

/// New contacts and their initial 7-DOF state.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ContactsSpec {
    /// Search for newly touching pairs during the run (default true).
    #[serde(default = "yes")]
    pub detect_new: bool,
    /// Search every this many steps (default 5: in the copper compact, `sinterdem bench
    /// precision` finds the end shrinkage as close to the every-step reference as with 1, with
    /// 2.4× fewer refactorisations; docs/coupled.md "Run time against error").
    #[serde(default = "five")]
    pub detect_every: f64,
    /// Pairs whose surface gap is below this fraction of the mean radius count as touching
    /// (green packings are stress-free, so most neighbours are at a tiny gap) [1] (default 1e-3).
    #[serde(default = "gap")]
    pub gap_tolerance: f64,
    /// Initial neck excess ε of (I2) [1] (default 0.01).
    #[serde(default = "eps")]
    pub epsilon: f64,
    /// Initial cone parameter η of (I2) [1] (default 0.1).
    #[serde(default = "eta")]
    pub eta: f64,
    /// Neck radius feeding the conductance: "volume_conserving" (default, from the centre
    /// distance) or "seven_dof" (y1).
    #[serde(default = "vc")]
    pub neck: String,
    /// Initial 7-DOF state of a contact created during the run (docs/coupled.md "New contacts"):
    /// "seed" (default, (I1)–(I4)) or "volume_conserving" (the neck of the overlap at detection).
    #[serde(default = "seed")]
    pub new_contact_state: String,
    /// Surface gap, relative to the mean radius, below which a pair counts as touching in the
    /// searches after the start (default: `gap_tolerance`; 0: only overlapping pairs) [1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub new_contact_gap: Option<f64>,
}

impl Default for ContactsSpec {
    fn default() -> Self {
        ContactsSpec {
            detect_new: true,
            detect_every: 5.0,
            gap_tolerance: gap(),
            epsilon: eps(),
            eta: eta(),
            neck: vc(),
            new_contact_state: seed(),
            new_contact_gap: None,
        }
    }
}

fn gap() -> f64 {
    1e-3
}
fn eps() -> f64 {
    0.01
}
fn eta() -> f64 {
    0.1
}
fn vc() -> String {
    "volume_conserving".into()
}
fn seed() -> String {
    "seed".into()
}

/// Bonded quasi-static mechanics settings.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MechanicsSpec {
    /// Constrain particles touching the principal planes x = 0, y = 0, z = 0 (default true).
    #[serde(default = "yes")]
    pub constrain_planes: bool,
    /// A particle touches a plane when its centre is within `plane_margin·r` of it (default 1.01).
    #[serde(default = "margin")]
    pub plane_margin: f64,
    /// Linear solver: "auto" (default), "cholesky", "cg" (block-Jacobi), "amg" (aggregation-multigrid
    /// CG) or "hypre" (hypre's BoomerAMG-PCG; only in builds with the `hypre` cargo feature,
    /// otherwise a configuration error that says how to build it; docs/coupled.md).
    #[serde(default = "auto")]
    pub solver: String,
    /// Reuse the last Cholesky factor as the Newton operator while the contacts are unchanged,
    /// refactorising only when Newton stalls (default true; the step's residual test still holds).
    #[serde(default = "yes")]
    pub reuse_factor: bool,
    /// Newton tolerance of the bonded solve: accept when the scaled residual ‖S(ΔF − KΔy)‖₂ ≤
    /// rtol·‖SΔF‖₂ (docs/mechanics.md (B10)) [1].
    #[serde(default = "mech_rtol")]
    pub rtol: f64,
    /// Start each bonded solve from the Galerkin projection onto the last two solutions
    /// (docs/mechanics.md (B12)) instead of from zero (default true).
    #[serde(default = "yes")]
    pub warm_start: bool,
    /// Earlier solutions spanning the warm start (B12) [1], an integer in [1, 8] (default
    /// [`WARM_START_DEPTH_CASE`]; docs/coupled.md "Scaling", 2026-12-04).
    #[serde(default = "warm_depth")]
    pub warm_start_depth: f64,
    /// Keep the AMG hierarchy across new contacts while the free DOF stay the same (default
    /// false; docs/coupled.md "Scaling", 2026-12-04).
    #[serde(default)]
    pub amg_keep_on_new_bonds: bool,
    /// Low-rank (Woodbury) update of the kept Cholesky factor for new bonds while its rank stays
    /// at most this [1], an integer in [0, 2000] (default [`UPDATE_RANK_DEFAULT`]); 0: a new
    /// analysis and factorisation at every new contact (docs/coupled.md "Low-rank update of the
    /// factor").
    #[serde(default = "update_rank_default")]
    pub update_rank: f64,
    /// "walls" (default: the principal planes of docs/mechanics.md "Constraints") or "periodic"
    /// (a periodic cell on `particles.periodic_box`, docs/mechanics.md "Periodic cell").
    #[serde(default = "walls")]
    pub boundary: String,
    /// The controls of the periodic cell's strain components (`boundary = "periodic"`).
    pub cell: Option<CellSpec>,
    /// Grain-boundary sliding at the necks: "none" (default: the elastic link of
    /// docs/mechanics.md (B5)) or "viscous" (the Maxwell links of (B24)–(B30)).
    #[serde(default = "no_sliding")]
    pub sliding: String,
    /// The dimensionless factor f of the tangential viscosity (B24) (`sliding = "viscous"`;
    /// default [`SLIDING_FACTOR_DEFAULT`]).
    pub sliding_factor: Option<f64>,
}

/// Default sliding factor f of (B24) [1], the tangential parameter η of the Bouvard–McMeeking
/// law (0.003–1 in DEM sintering, Yan 2014): the value of the half-decade grid 0.01, 0.03, 0.1,
/// 0.3 whose copper RVE starts at the measured onset ν_p ≈ 0.21 of Zuo et al. (2003) and rises
/// with density (docs/decisions-mechanics.md "Sliding", docs/rve.md).
pub const SLIDING_FACTOR_DEFAULT: f64 = 0.03;
fn no_sliding() -> String {
    "none".into()
}

/// Default warm-start depth of compact runs [1]: the E14B compact (docs/coupled.md "Scaling",
/// 2026-12-04) needs 8099 CG iterations with 2, 6135 with 4, 5705 with 6.
pub const WARM_START_DEPTH_CASE: usize = 4;
fn warm_depth() -> f64 {
    WARM_START_DEPTH_CASE as f64
}

fn walls() -> String {
    "walls".into()
}

/// One component's control in the case file: exactly one of `stress`, `stress_table`, `strain_rate`.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ComponentSpec {
    /// Constant mean stress [Pa], tension positive.
    pub stress: Option<f64>,
    /// Piecewise-linear stress history `[[time s, stress Pa], …]`, times strictly increasing.
    pub stress_table: Option<Vec<[f64; 2]>>,
    /// Prescribed strain rate [1/s] (engineering shear rate for a shear).
    pub strain_rate: Option<f64>,
}

/// `[mechanics.cell]`.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CellSpec {
    /// "normal" (default: the three normal strains solved, the cell stays orthorhombic) or "all"
    /// (the shears too).
    pub components: Option<String>,
    pub xx: Option<ComponentSpec>,
    pub yy: Option<ComponentSpec>,
    pub zz: Option<ComponentSpec>,
    pub yz: Option<ComponentSpec>,
    pub xz: Option<ComponentSpec>,
    pub xy: Option<ComponentSpec>,
    /// (P5) limit of the contact normal force under a cell stress [Pa] (default: none).
    pub contact_stress_limit: Option<f64>,
}

/// Default `mechanics.update_rank` [1] (r_max of docs/mechanics.md (B31)): the measured optimum of the copper compact, flat between
/// 90 and 120 (docs/coupled.md "Low-rank update of the factor", docs/decisions.md).
pub const UPDATE_RANK_DEFAULT: f64 = 90.0;

fn update_rank_default() -> f64 {
    UPDATE_RANK_DEFAULT
}

/// Default Newton tolerance of compact runs: 1e-5 (docs/mechanics.md (B10)). Against 1e-6 it moves
/// shrinkage and density by < 4e-7 relative on E14B and < 1.1e-7 on the copper compact, three
/// orders below the coupled loop's own error (6e-4, `sinterdem bench precision`), with 29 % fewer
/// CG iterations on E14B and 18 % fewer Newton solves on the copper compact (docs/coupled.md "The
/// Newton tolerance of compact runs").
fn mech_rtol() -> f64 {
    1e-5
}

impl Default for MechanicsSpec {
    fn default() -> Self {
        MechanicsSpec {
            constrain_planes: true,
            plane_margin: margin(),
            solver: auto(),
            reuse_factor: true,
            rtol: mech_rtol(),
            warm_start: true,
            warm_start_depth: warm_depth(),
            amg_keep_on_new_bonds: false,
            update_rank: update_rank_default(),
            boundary: walls(),
            cell: None,
            sliding: no_sliding(),
            sliding_factor: None,
        }
    }
}

fn margin() -> f64 {
    1.01
}
fn auto() -> String {
    "auto".into()
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
    /// Compact runs: step-control strategy 1 (global) or 2 (per-contact subdivision, default).
    pub strategy: Option<f64>,
    /// Compact runs: largest global step [s] (default 10 s strategy 2, 100 s strategy 1).
    pub dt_max: Option<f64>,
    /// Compact runs: smallest global step [s] (default 1e-12 s).
    pub dt_min: Option<f64>,
    /// Compact runs: growth/shrink factor α (default 1.5).
    pub alpha: Option<f64>,
    /// Strategy 2: grow when fewer than this fraction of contacts subdivided (default 0.05).
    pub grow_below: Option<f64>,
    /// Strategy 2: shrink when more than this fraction subdivided (default 0.15).
    pub shrink_above: Option<f64>,
    /// Strategy 2: a contact counts as subdivided when it needed more than this many substeps
    /// (default 1, the paper's rule).
    pub substeps_allowed: Option<f64>,
    /// Compact runs: end the run once the relative density (eq. 49) reaches this value, e.g. 0.8,
    /// the end of the 7-DOF model's validity (Ivannikov et al. 2022 §4) [1].
    pub stop_relative_density: Option<f64>,
    /// Local error tolerance of the heat step, max over particles [K] (heat-model.md eq. E3).
    /// Heat runs: Δt is chosen by error (time.dt the first step, within time.dt_min, time.dt_max);
    /// compact runs: the heat stage subdivides its step. Absent: the fixed Δt.
    pub heat_tolerance: Option<f64>,
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
    /// Compact runs: write a checkpoint every this many steps (0: only at the end).
    #[serde(default)]
    pub checkpoint_every: f64,
    /// Compact runs: times [s] at which the effective conductivity of the compact is computed.
    #[serde(default)]
    pub conductivity_at: Vec<f64>,
    /// Compact runs: times [s] at which the histogram of the y4/y7 corrections ΔL̄ is written
    /// (Ivannikov et al. 2022 Fig. 20: 30 min of E14B); the end of the run always gets one.
    #[serde(default)]
    pub correction_histogram_at: Vec<f64>,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            snapshots: default_snapshots(),
            series_every: 1.0,
            vtu: true,
            hdf5: true,
            checkpoint_every: 0.0,
            conductivity_at: Vec::new(),
            correction_histogram_at: Vec::new(),
        }
    }
}

fn default_snapshots() -> f64 {
    5.0
}
fn five() -> f64 {
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
    /// Packing file relative to the case file: CSV `x,y,z,r[,material][,temperature]` (material
    /// = 0-based index into `[[materials]]`), a LIGGGHTS/LAMMPS dump, or a Yade text export.
    pub file: Option<String>,
    /// Format of `file`: "csv", "liggghts" or "yade" (default: from the extension).
    pub format: Option<String>,
    /// The periodic box `[Lx, Ly, Lz]` of a `file` packing, from the origin [m]: particles may
    /// stick out of it (they are wrapped into it by the periodic contact search). Read by
    /// `conductivity.boundary = "periodic"`.
    pub periodic_box: Option<[f64; 3]>,
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
    /// "fe_fit" (default: the FE-fitted factor f(a/r), docs/heat-model.md (H8)) or "linear"
    /// (c_K κ π a, the seed paper's eq. 43).
    #[serde(default)]
    pub conductance: ConductanceLaw,
    /// c_K of the linear law (default 1.064).
    #[serde(default = "ck")]
    pub conductance_factor: f64,
    /// Interface conductance in series [W/K] (default none).
    pub contact_conductance: Option<f64>,
    /// Interface resistance per unit neck area R_b [m²·K/W] in series with each pipe as
    /// R_b/(π a²) (docs/heat-model.md (H7); default 0).
    #[serde(default)]
    pub boundary_resistance: f64,
    /// Multi-neck correction of the half pipes: "fabric" (default; docs/heat-model.md
    /// (H8a)–(H8c), validated within 2 % of 3-D FE) or "none" (every half pipe the pair's).
    #[serde(default)]
    pub multi_neck: crate::heat::MultiNeck,
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
    /// Optional heat transfer across the gaps between near, non-touching particles (gas
    /// conduction and radiation; docs/heat-model.md (H18)–(H23)). Absent: off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap: Option<GapSpec>,
}

impl Default for ThermalSpec {
    fn default() -> Self {
        ThermalSpec {
            mode: network(),
            conductance: ConductanceLaw::default(),
            conductance_factor: ck(),
            contact_conductance: None,
            boundary_resistance: 0.0,
            multi_neck: crate::heat::MultiNeck::default(),
            radiation_tolerance: rad_tol(),
            contact_temperature: arith(),
            fixed: Vec::new(),
            volumetric: Vec::new(),
            furnace: None,
            gap: None,
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
    /// (imposed mean gradient; needs a lattice or a file packing with `particles.periodic_box`).
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
    /// "thermal" (default: κ_eff from each material's κ) or "electrical" (σ_eff from each
    /// material's electrical resistivity ρ_e(T) at the particles' temperature, the same network:
    /// docs/heat-model.md "Electrical conductivity").
    #[serde(default = "thermal")]
    pub quantity: String,
}

impl Default for ConductivitySpec {
    fn default() -> Self {
        ConductivitySpec { boundary: faces(), axes: xyz(), temperature_difference: 1.0, layer_fraction: None, quantity: thermal() }
    }
}

fn thermal() -> String {
    "thermal".into()
}

fn faces() -> String {
    "faces".into()
}
fn xyz() -> Vec<String> {
    vec!["x".into(), "y".into(), "z".into()]
}

/// The time plan of a heat or compact case: every time key in range (also those the kind does not
/// read), `dt_min <= dt_max`, and a plausible number of steps.
pub fn check_time(t: &TimeSpec, compact: bool) -> Result<(), ConfigError> {
    use crate::config::plausible::check_steps;
    use crate::error::fmt_value;
    let end = crate::config::check("time.end", t.end)?;
    let dt = crate::config::check("time.dt", t.dt)?;
    let dt_max = crate::config::check_opt("time.dt_max", t.dt_max)?;
    let dt_min = crate::config::check_opt("time.dt_min", t.dt_min)?;
    if let (Some(lo), Some(hi)) = (dt_min, dt_max)
        && lo > hi
    {
        return Err(ConfigError::inconsistent("time.dt_min", format!("{} s is larger than time.dt_max = {} s", fmt_value(lo), fmt_value(hi))));
    }
    if compact {
        if let Some(hi) = dt_max {
            check_steps("time.dt_max", end, hi)?;
        }
        if let Some(lo) = dt_min
            && end + lo == end
        {
            return Err(ConfigError::inconsistent(
                "time.dt_min",
                format!("{} s is below the resolution of time near time.end = {} s: a step of that size would not advance time", fmt_value(lo), fmt_value(end)),
            ));
        }
    } else {
        check_steps("time.dt", end, dt)?;
    }
    Ok(())
}

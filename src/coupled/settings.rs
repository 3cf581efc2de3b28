//! The settings of a compact run read from its case: step control, contacts, output times
//! ([`Settings`]) and the mechanics ([`MechanicsSettings`]), validated against the range tables.

use crate::config;
use crate::error::ConfigError;
use crate::mechanics::LinearSolver;
use crate::models::diffusion7::{PathFactors, SolverOptions};
use crate::scene::case::Case;

/// Which neck radius feeds the conductance (docs/heat-model.md "Which neck radius feeds (H6)").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NeckSource {
    /// From the overlap of the current centre distance.
    VolumeConserving,
    /// The 7-DOF neck radius y1.
    SevenDof,
}

/// Initial 7-DOF state of a contact created during the run (docs/coupled.md "New contacts").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NewContactState {
    /// (I1)–(I4): neck `r_c + ε·min(R_A, R_B)`, as every contact of the green body.
    Seed,
    /// Neck = the volume-conserving neck of the overlap at detection (crate::neck, the heat
    /// model's (H9)–(H15)), at least `ε·min(R_A, R_B)`.
    VolumeConserving,
}

impl NewContactState {
    /// The case-file names, in the order of the documentation.
    pub const NAMES: [&'static str; 2] = ["seed", "volume_conserving"];

    pub fn parse(s: &str) -> Result<NewContactState, ConfigError> {
        match s {
            "seed" => Ok(NewContactState::Seed),
            "volume_conserving" => Ok(NewContactState::VolumeConserving),
            o => Err(ConfigError::invalid(format!(
                "contacts.new_contact_state = \"{o}\": expected one of {} (docs/coupled.md \"New contacts\")",
                NewContactState::NAMES.map(|n| format!("\"{n}\"")).join(", ")
            ))),
        }
    }
}

/// Step-control and contact settings of a compact run, validated.
#[derive(Debug, Clone)]
pub struct Settings {
    pub end: f64,
    pub dt0: f64,
    pub strategy: u8,
    pub dt_max: f64,
    pub dt_min: f64,
    pub alpha: f64,
    pub grow_below: f64,
    pub shrink_above: f64,
    pub substeps_allowed: u64,
    /// Stop once the relative density reaches this value [1].
    pub stop_relative_density: Option<f64>,
    pub detect_new: bool,
    pub detect_every: u64,
    /// Gap [m] below which a pair counts as touching.
    pub gap: f64,
    /// Gap [m] below which a pair counts as touching in the searches after the start.
    pub new_gap: f64,
    /// Initial state of the contacts created after the start.
    pub new_state: NewContactState,
    pub epsilon: f64,
    pub eta: f64,
    pub neck: NeckSource,
    pub harmonic: bool,
    pub solver: SolverOptions,
    pub factors: PathFactors,
    pub mechanics: MechanicsSettings,
    pub snapshots: usize,
    pub series_every: u64,
    pub checkpoint_every: u64,
    /// Times of the conductivity analyses [s].
    pub conductivity_at: Vec<f64>,
    /// Times of the y4/y7 correction histograms [s] ((C4); Ivannikov et al. 2022 eq. 44).
    pub histogram_at: Vec<f64>,
    /// Write the PNG plots at the end (the run API turns them off in studies).
    pub plots: bool,
    /// Wall-time budget of the run [s] (set by the caller, e.g. a benchmark; None: unlimited).
    pub wall_limit: Option<f64>,
    /// Applied load (`[load]`, docs/pressure.md); None: no load.
    pub load: Option<super::load::LoadSettings>,
}

impl Settings {
    pub fn from_case(case: &Case) -> Result<Settings, ConfigError> {
        let t = &case.time;
        let strategy = config::check("time.strategy", t.strategy.unwrap_or(2.0))?;
        if strategy.fract() != 0.0 {
            return Err(ConfigError::invalid("time.strategy must be 1 or 2"));
        }
        let strategy = strategy as u8;
        let c = case.contacts.clone().unwrap_or_default();
        let neck = match c.neck.as_str() {
            "volume_conserving" => NeckSource::VolumeConserving,
            "seven_dof" => NeckSource::SevenDof,
            o => return Err(ConfigError::invalid(format!("contacts.neck = \"{o}\": expected volume_conserving or seven_dof"))),
        };
        let solver = case.solver.unwrap_or_default();
        solver.validate()?;
        let factors = case.model.unwrap_or_default();
        factors.validate()?;
        let m = case.mechanics.clone().unwrap_or_default();
        let mechanics = MechanicsSettings::from_spec(&m)?;
        let every = config::check("contacts.detect_every", c.detect_every)?;
        let ck = config::check("output.checkpoint_every", case.output.checkpoint_every)?;
        for (k, &tc) in case.output.conductivity_at.iter().enumerate() {
            config::check(&format!("output.conductivity_at.{k}"), tc)?;
        }
        for (k, &tc) in case.output.correction_histogram_at.iter().enumerate() {
            config::check(&format!("output.correction_histogram_at.{k}"), tc)?;
        }
        // the run writes each analysis when it reaches the next time listed: a time listed after a
        // later one was written at that later time (issue 38: [2.0, 1.0] gave two tensors at 2 s)
        for (name, list) in [("output.conductivity_at", &case.output.conductivity_at), ("output.correction_histogram_at", &case.output.correction_histogram_at)]
        {
            if let Some(k) = (1..list.len()).find(|&k| !(list[k] > list[k - 1])) {
                return Err(ConfigError::inconsistent(
                    format!("{name}.{k}"),
                    format!(
                        "{} s is not after the entry before it ({} s): list the times in increasing order, each once",
                        crate::error::fmt_value(list[k]),
                        crate::error::fmt_value(list[k - 1])
                    ),
                ));
            }
        }
        let dt_max = config::check("time.dt_max", t.dt_max.unwrap_or(if strategy == 1 { 100.0 } else { 10.0 }))?;
        // a step must advance time also near the end: at least 4 ulp of time.end (3.6e5 s: 3e-10 s)
        let dt_min = config::check("time.dt_min", t.dt_min.unwrap_or(1e-12))?.max(4.0 * f64::EPSILON * t.end);
        if dt_min > dt_max {
            return Err(ConfigError::inconsistent(
                "time.dt_min",
                format!("{} s is larger than time.dt_max = {} s", crate::error::fmt_value(dt_min), crate::error::fmt_value(dt_max)),
            ));
        }
        Ok(Settings {
            end: config::check("time.end", t.end)?,
            dt0: config::check("time.dt", t.dt)?.min(dt_max),
            strategy,
            dt_max,
            dt_min,
            alpha: config::check("time.alpha", t.alpha.unwrap_or(1.5))?,
            grow_below: config::check("time.grow_below", t.grow_below.unwrap_or(0.05))?,
            shrink_above: config::check("time.shrink_above", t.shrink_above.unwrap_or(0.15))?,
            substeps_allowed: config::check("time.substeps_allowed", t.substeps_allowed.unwrap_or(1.0))? as u64,
            stop_relative_density: t.stop_relative_density.map(|v| config::check("time.stop_relative_density", v)).transpose()?,
            detect_new: c.detect_new,
            detect_every: every as u64,
            gap: config::check("contacts.gap_tolerance", c.gap_tolerance)?,
            new_gap: match c.new_contact_gap {
                Some(g) => config::check("contacts.new_contact_gap", g)?,
                None => c.gap_tolerance,
            },
            new_state: NewContactState::parse(&c.new_contact_state)?,
            epsilon: config::check("contacts.epsilon", c.epsilon)?,
            eta: config::check("contacts.eta", c.eta)?,
            neck,
            harmonic: case.thermal.contact_temperature == "harmonic",
            solver,
            factors,
            mechanics,
            snapshots: config::check("output.snapshots", case.output.snapshots)? as usize,
            series_every: config::check("output.series_every", case.output.series_every)? as u64,
            checkpoint_every: ck as u64,
            conductivity_at: case.output.conductivity_at.clone(),
            histogram_at: case.output.correction_histogram_at.clone(),
            plots: true,
            wall_limit: None,
            load: super::load::LoadSettings::from_spec(case.load.as_ref())?,
        })
    }
}

/// Mechanics settings of a compact run, validated.
#[derive(Debug, Clone)]
pub struct MechanicsSettings {
    pub constrain_planes: bool,
    /// Relative surface gap of the plane test: centre within (1 + gap)·r (docs/mechanics.md "Constraints": 1 %).
    pub plane_gap: f64,
    pub solver: LinearSolver,
    pub reuse_factor: bool,
    /// Newton tolerance [1].
    pub rtol: f64,
    /// Warm start of the bonded solve (docs/mechanics.md (B12)).
    pub warm_start: bool,
    /// Earlier solutions spanning the warm start [1].
    pub warm_start_depth: usize,
    /// Keep the AMG hierarchy across new contacts [flag].
    pub amg_keep_on_new_bonds: bool,
    /// Largest rank of the low-rank update of the kept Cholesky factor for new bonds [1]; 0: off.
    pub update_rank: usize,
    /// The periodic cell's controls (`boundary = "periodic"`); None: walls.
    pub cell: Option<super::cell::CellSettings>,
    /// Viscous grain-boundary sliding (docs/mechanics.md (B24)–(B30)): the factor f of (B24)
    /// [1]; None: `sliding = "none"`, the elastic link.
    pub sliding: Option<f64>,
}

impl MechanicsSettings {
    pub fn from_spec(m: &crate::scene::case::MechanicsSpec) -> Result<Self, ConfigError> {
        let margin = config::check("mechanics.plane_margin", m.plane_margin)?;
        let solver = match m.solver.as_str() {
            "auto" => LinearSolver::Auto,
            "cholesky" => LinearSolver::Cholesky,
            "cg" => LinearSolver::Pcg,
            "amg" => LinearSolver::Amg,
            "hypre" if crate::mechanics::hypre::AVAILABLE => LinearSolver::Hypre,
            "hypre" => return Err(crate::mechanics::hypre::feature_missing("mechanics.solver")),
            o if crate::mechanics::hypre::AVAILABLE => {
                return Err(ConfigError::invalid(format!("mechanics.solver = \"{o}\": expected auto, cholesky, cg, amg or hypre")));
            }
            o => {
                return Err(ConfigError::invalid(format!(
                    "mechanics.solver = \"{o}\": expected auto, cholesky, cg or amg (hypre: build with the `hypre` feature)"
                )));
            }
        };
        let rtol = config::check("mechanics.rtol", m.rtol)?;
        let depth = config::check("mechanics.warm_start_depth", m.warm_start_depth)?;
        if depth.fract() != 0.0 {
            return Err(ConfigError::invalid(format!("mechanics.warm_start_depth = {depth}: expected an integer in [1, 8] (earlier solutions)")));
        }
        let update_rank = config::check("mechanics.update_rank", m.update_rank)?;
        if update_rank.fract() != 0.0 {
            return Err(ConfigError::invalid(format!(
                "mechanics.update_rank = {update_rank}: expected an integer in [0, 2000] (largest rank of the low-rank factor update; 0: off)"
            )));
        }
        let sliding = match m.sliding.as_str() {
            "none" => {
                if let Some(f) = m.sliding_factor {
                    return Err(ConfigError::invalid(format!(
                        "mechanics.sliding_factor = {f} is given but mechanics.sliding = \"none\": set sliding = \"viscous\" (docs/mechanics.md (B24)) or drop the factor"
                    )));
                }
                None
            }
            "viscous" => Some(config::check("mechanics.sliding_factor", m.sliding_factor.unwrap_or(crate::scene::case::SLIDING_FACTOR_DEFAULT))?),
            o => {
                return Err(ConfigError::invalid(format!(
                    "mechanics.sliding = \"{o}\": expected \"none\" (elastic links) or \"viscous\" (grain-boundary sliding, docs/mechanics.md (B24))"
                )));
            }
        };
        Ok(MechanicsSettings {
            sliding,
            constrain_planes: m.constrain_planes,
            plane_gap: margin - 1.0,
            solver,
            reuse_factor: m.reuse_factor,
            rtol,
            warm_start: m.warm_start,
            warm_start_depth: depth as usize,
            amg_keep_on_new_bonds: m.amg_keep_on_new_bonds,
            update_rank: update_rank as usize,
            cell: super::cell::CellSettings::from_spec(&m.boundary, m.cell.as_ref())?,
        })
    }
}

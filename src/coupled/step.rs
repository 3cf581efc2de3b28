//! The coupled step and its step control: settings, the per-contact stores, the mechanics stage
//! and [`Simulation::advance_step`] (topology → heat → diffusion → mechanics → correction → step
//! control; docs/coupled.md).

use crate::config;
use crate::error::{ConfigError, Error, ModelError};
use crate::heat::{Conductance, HeatNetwork};
use crate::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, NodalLoad, StepInput};
use crate::models::diffusion7::{self as d7, Contact7, PairMaterials, PathFactors, SolverOptions, TemperaturePath};
use crate::models::ode::OdeStats;
use crate::scene::Prepared;
use crate::scene::case::Case;
use nalgebra::Vector3;
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

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
}

impl MechanicsSettings {
    pub fn from_spec(m: &crate::scene::case::MechanicsSpec) -> Result<Self, ConfigError> {
        let margin = config::check("mechanics.plane_margin", m.plane_margin)?;
        let solver = match m.solver.as_str() {
            "auto" => LinearSolver::Auto,
            "cholesky" => LinearSolver::Cholesky,
            "cg" => LinearSolver::Pcg,
            "amg" => LinearSolver::Amg,
            o => return Err(ConfigError::invalid(format!("mechanics.solver = \"{o}\": expected auto, cholesky, cg or amg"))),
        };
        let rtol = config::check("mechanics.rtol", m.rtol)?;
        Ok(MechanicsSettings {
            constrain_planes: m.constrain_planes,
            plane_gap: margin - 1.0,
            solver,
            reuse_factor: m.reuse_factor,
            rtol,
            warm_start: m.warm_start,
        })
    }
}

/// Stage 4: the bonded system, built at the first solve and re-topologised when contacts appear.
pub struct MechanicsStage {
    settings: MechanicsSettings,
    sys: Option<BondedSystem>,
    bonds: usize,
    /// Accumulated rotations [rad].
    pub rotation: Vec<Vector3<f64>>,
    /// Newton iterations and factorisations so far.
    pub newton_iterations: u64,
    pub factorizations: u64,
    pub max_residual: f64,
    /// Where the mechanics time goes (this process only; not checkpointed).
    pub profile: MechProfile,
}

/// Counters and wall times of the mechanics stage, summed over steps (summary `mechanics_profile`).
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct MechProfile {
    /// Topology analyses (bond set changed) [1].
    pub topology_changes: u64,
    /// CG iterations (stale-factor or AMG preconditioned) [1].
    pub cg_iterations: u64,
    /// Wall times [s]: topology analysis, symbolic factorisation, assembly, numeric factorisation,
    /// solves (triangular or CG).
    pub analysis_s: f64,
    pub symbolic_s: f64,
    pub assemble_s: f64,
    pub factor_s: f64,
    pub solve_s: f64,
    /// Whole mechanics steps [s].
    pub total_s: f64,
}

impl MechanicsStage {
    pub fn new(n: usize, settings: &MechanicsSettings) -> Self {
        MechanicsStage {
            settings: settings.clone(),
            sys: None,
            bonds: 0,
            rotation: vec![Vector3::zeros(); n],
            newton_iterations: 0,
            factorizations: 0,
            max_residual: 0.0,
            profile: MechProfile::default(),
        }
    }

    /// Builds the bonded system with the plane constraints of the initial packing.
    pub fn build(&mut self, p: &crate::particles::Particles, young: f64, poisson: f64) -> Result<(), Error> {
        let cons = if self.settings.constrain_planes {
            Constraints::principal_planes(&p.position, &p.radius, self.settings.plane_gap)?
        } else {
            Constraints::none(p.len())
        };
        let params = MechParams {
            young_modulus: young,
            poisson_ratio: poisson,
            solver: self.settings.solver,
            reuse_factor: self.settings.reuse_factor,
            rtol: self.settings.rtol,
            warm_start: self.settings.warm_start,
            ..Default::default()
        };
        self.sys = Some(BondedSystem::new(p.len(), params, cons)?);
        Ok(())
    }

    /// Forgets the cached factor, so that the next step factorises afresh (done at checkpoints, so
    /// that a resumed run repeats the uninterrupted one bit for bit).
    pub fn drop_factor(&mut self) -> Result<(), Error> {
        if let Some(sys) = self.sys.as_mut() {
            sys.drop_factor();
        }
        Ok(())
    }

    /// Solves the step: displacement increments per particle and the axial approach ξ per contact.
    /// `radii`: the thermally expanded radii (docs/coupled.md (X6)) that set R_m of the links and of
    /// the load (F5); None: the particles' own.
    fn solve(
        &mut self,
        p: &crate::particles::Particles,
        contacts: &Contacts,
        approach: &[f64],
        external: Option<&[NodalLoad]>,
        radii: Option<&[f64]>,
    ) -> Result<(Vec<Vector3<f64>>, Vec<f64>), Error> {
        let sys = self.sys.as_mut().ok_or_else(|| ModelError::new("mechanics: the bonded system was not built"))?;
        if self.bonds != contacts.len() {
            sys.set_topology(&contacts.pairs)?;
            self.bonds = contacts.len();
        }
        let y4_y7: Vec<[f64; 2]> = contacts.state.iter().map(|c| [c.y_prev[3], c.y_prev[6]]).collect();
        // the load (F5) with the link's own E, so that E cancels from the approach per bond
        let load: Vec<f64> = contacts
            .state
            .iter()
            .zip(approach)
            .zip(&contacts.pairs)
            .map(|((c, &a), &[i, j])| {
                let r_m = radii.map_or(c.r_mean(), |r| 0.5 * (r[i as usize] + r[j as usize]));
                d7::load_increment(a, 0.0, r_m, sys.link_elastic(i, j)[0])
            })
            .collect();
        let inp = StepInput { positions: &p.position, radii: radii.unwrap_or(&p.radius), y4_y7: &y4_y7, load: &load, external };
        let out = step_or_refactor(sys, &inp)?;
        for (r, d) in self.rotation.iter_mut().zip(&out.dtheta) {
            *r += d;
        }
        self.count(&out.info);
        Ok((out.du, out.xi))
    }

    /// The load distribution of docs/pressure.md (P3): the bonded equilibrium under the nodal
    /// forces `loads` alone (no sintering loads), at the current geometry; returns per contact the
    /// axial force (compressive positive) [N] and the force on A exerted by B (global axes) [N].
    /// Positions and rotations are not changed.
    fn distribute(&mut self, p: &crate::particles::Particles, contacts: &Contacts, loads: &[NodalLoad]) -> Result<(Vec<f64>, Vec<Vector3<f64>>), Error> {
        let sys = self.sys.as_mut().ok_or_else(|| ModelError::new("mechanics: the bonded system was not built"))?;
        if self.bonds != contacts.len() {
            sys.set_topology(&contacts.pairs)?;
            self.bonds = contacts.len();
        }
        let y4_y7: Vec<[f64; 2]> = contacts.state.iter().map(|c| [c.y_prev[3], c.y_prev[6]]).collect();
        let zero = vec![0.0; contacts.len()];
        let out = step_or_refactor(sys, &StepInput { positions: &p.position, radii: &p.radius, y4_y7: &y4_y7, load: &zero, external: Some(loads) })?;
        let r_scale = p.radius.iter().sum::<f64>() / p.len().max(1) as f64;
        let mut normal = Vec::with_capacity(contacts.len());
        let mut force = Vec::with_capacity(contacts.len());
        for (k, &[a, b]) in contacts.pairs.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            let [y4, y7] = y4_y7[k];
            let g = crate::mechanics::BondGeometry::new(&p.position[a], &p.position[b], y4, y7)?;
            let [e, nu] = sys.link_elastic(a as u32, b as u32);
            let kl = crate::mechanics::link_stiffness(e, nu, 0.5 * (p.radius[a] + p.radius[b]));
            let mut y = nalgebra::SMatrix::<f64, 12, 1>::zeros();
            for d in 0..3 {
                y[d] = out.du[a][d];
                y[3 + d] = out.dtheta[a][d] * r_scale;
                y[6 + d] = out.du[b][d];
                y[9 + d] = out.dtheta[b][d] * r_scale;
            }
            let fl = crate::mechanics::bond::link_forces(&g, &kl, r_scale, &y);
            // local [F1, F2, F3] with F3 > 0 compression; the link pushes A by −Rᵀ·F_local
            let rot = crate::mechanics::frame(&g.e3);
            normal.push(fl[2]);
            force.push(-(rot.transpose() * Vector3::new(fl[0], fl[1], fl[2])));
        }
        self.count(&out.info);
        Ok((normal, force))
    }

    /// Adds a solve's counters and times to the stage's totals.
    fn count(&mut self, out_info: &crate::mechanics::MechInfo) {
        self.newton_iterations += out_info.newton_iterations as u64;
        self.factorizations += out_info.factorizations as u64;
        let (pr, i) = (&mut self.profile, out_info);
        pr.topology_changes += i.topology_rebuilt as u64;
        pr.cg_iterations += i.pcg_iterations as u64;
        pr.analysis_s += i.analysis_seconds;
        pr.symbolic_s += i.symbolic_seconds;
        pr.assemble_s += i.assemble_seconds;
        pr.factor_s += i.factor_seconds;
        pr.solve_s += i.solve_seconds;
        pr.total_s += i.total_seconds;
        // a step solved by its warm start alone (docs/mechanics.md (B12)) has no Newton residual
        self.max_residual = self.max_residual.max(out_info.residuals.last().copied().unwrap_or(out_info.warm_start));
    }
}

/// One bonded step; a stale factor that fails to converge (a SolveError, which ends a run) is
/// dropped and the step repeated once with a fresh analysis and factorisation (seen under an
/// applied load, docs/pressure.md). Runs that converge are not affected.
fn step_or_refactor(sys: &mut BondedSystem, inp: &StepInput) -> Result<crate::mechanics::MechStep, Error> {
    match sys.step(inp) {
        Err(Error::Solve(_)) => {
            sys.drop_factor();
            sys.step(inp)
        }
        r => r,
    }
}

/// The diffusion contacts of a packing, struct of arrays (docs/design.md).
#[derive(Debug, Clone, Default)]
pub struct Contacts {
    /// Particle pairs (i < j).
    pub pairs: Vec<[u32; 2]>,
    /// 7-DOF state of each contact.
    pub state: Vec<Contact7>,
    /// ΔL̄ of the last correction ((C4); Ivannikov et al. 2022 eq. 44) [m].
    pub dl_bar: Vec<f64>,
    /// Substeps of the last sweep.
    pub substeps: Vec<u32>,
}

impl Contacts {
    pub fn len(&self) -> usize {
        self.pairs.len()
    }
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
}

/// Wall-time shares of the stages [s].
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct Timing {
    pub detection: f64,
    pub heat: f64,
    pub diffusion: f64,
    pub mechanics: f64,
    pub correction: f64,
    pub output: f64,
}

/// A compact simulation in progress (everything a checkpoint must hold is here).
pub struct Simulation {
    pub prep: Prepared,
    pub settings: Settings,
    /// Bundled 7-DOF data per material index.
    pub d7_materials: Vec<d7::Material>,
    pub contacts: Contacts,
    /// Current time [s].
    pub t: f64,
    /// Next global step [s].
    pub dt: f64,
    /// The next step ends no later than this time [s] (a requested output time; the driver sets
    /// it before each step, ∞ for none): steps are shortened to land on it exactly.
    pub stop_at: f64,
    /// Mean velocity of each particle over the last step, Δx/Δt [m/s] (output; zero before the
    /// first step and right after a resume).
    pub velocity: Vec<Vector3<f64>>,
    /// Accepted steps so far.
    pub step: u64,
    /// Rejected global steps (strategy 1).
    pub rejected: u64,
    pub heat: Option<HeatNetwork>,
    pub mechanics: MechanicsStage,
    /// Initial positions [m].
    pub x0: Vec<Vector3<f64>>,
    /// Lower faces of the initial bounding box (the principal planes) [m].
    pub planes: Vector3<f64>,
    /// Particles of the far layer per axis (for the shrinkage measure) and their initial mean extent [m].
    pub far_layer: [Vec<u32>; 3],
    /// The near layer of each axis (used instead of the principal planes when they are not
    /// constrained: the body then moves as a whole).
    pub near_layer: [Vec<u32>; 3],
    pub extent0: Vector3<f64>,
    pub ode: OdeStats,
    /// Contact steps integrated in lanes (docs/diffusion7.md §7) since this process started (not
    /// checkpointed: a diagnostic of the sweep, not part of the result).
    pub contacts_in_lanes: u64,
    pub timing: Timing,
    pub heat_in: f64,
    pub heat_stored: f64,
    pub heat_scale: f64,
    pub warnings: Vec<String>,
    /// Corrections (C4) that had to be limited to keep a contact admissible.
    pub limited_corrections: u64,
    /// Log of what was skipped, said once.
    pub skipped: Vec<&'static str>,
    /// The case as run (overrides applied) and its directory, for checkpoints.
    pub source: (String, std::path::PathBuf),
    /// The applied load and its distribution over the contacts (docs/pressure.md); None: no load.
    pub load: Option<super::load::LoadState>,
    /// Thermal expansion of the particles (docs/coupled.md (X1)–(X12)); None: no material expands.
    pub expansion: Option<super::expansion::ThermalExpansion>,
}

fn dist(p: &crate::particles::Particles, i: u32, j: u32) -> f64 {
    (p.position[j as usize] - p.position[i as usize]).norm()
}

/// Initial neck radius [m] of a contact created with `contacts.new_contact_state =
/// "volume_conserving"` between spheres of radii `r_i`, `r_j` [m] at centre distance `d` [m]: the
/// volume-conserving neck of the overlap `h = r_i + r_j − d` (crate::neck, the neck the heat model
/// gives the same pair), at least `ε·min(r_i, r_j)`, the seed neck of a touching pair (the 7-DOF
/// model needs a finite neck, (I2); below an overlap of about ε²·r/2 the seed is larger).
pub fn new_contact_neck(r_i: f64, r_j: f64, d: f64, eps: f64) -> Result<f64, ModelError> {
    let a = crate::neck::solve(r_i, r_j, r_i + r_j - d)?.a;
    Ok(a.max(eps * r_i.min(r_j)))
}

impl Simulation {
    /// Builds a compact simulation from a prepared case.
    pub fn new(prep: Prepared, log: &mut dyn FnMut(&str)) -> Result<Simulation, Error> {
        let settings = Settings::from_case(&prep.case)?;
        let mut d7m = Vec::new();
        for m in &prep.scene.materials {
            let mut dm = match &m.diffusion_data {
                Some(d) => d.clone(),
                None => {
                    let name = m.diffusion.as_deref().ok_or_else(|| ConfigError::invalid(format!("materials.{}: a compact run needs 7-DOF diffusion data: diffusion = \"copper\" or \"titanium\", or [[materials.phases]] (docs/case-file.md)", m.name)))?;
                    d7::Material::builtin(name)?
                }
            };
            dm.young_modulus = m.young_modulus;
            dm.poisson_ratio = m.poisson_ratio;
            d7m.push(dm);
        }
        let p = &prep.scene.particles;
        let n = p.len();
        let (lo, hi) = p.bounding_box();
        let r_mean = p.mean_radius();
        // the far layer of each axis, without particles that touch nothing (rattlers stay put)
        let mut touching = vec![false; n];
        for (i, j) in crate::contacts::detect::touching_pairs(&p.position, &p.radius, settings.gap * r_mean) {
            touching[i as usize] = true;
            touching[j as usize] = true;
        }
        // the far faces of the touching particles (a particle touching nothing beyond the body,
        // e.g. an isolated one, must not empty the far layer)
        let hi: Vector3<f64> = if touching.iter().any(|&t| t) {
            Vector3::from_fn(|a, _| (0..n).filter(|&i| touching[i]).map(|i| p.position[i][a] + p.radius[i]).fold(f64::NEG_INFINITY, f64::max))
        } else {
            hi
        };
        let far_layer: [Vec<u32>; 3] = std::array::from_fn(|a| {
            (0..n as u32).filter(|&i| touching[i as usize] && p.position[i as usize][a] + p.radius[i as usize] >= hi[a] - r_mean).collect()
        });
        let near_layer: [Vec<u32>; 3] = std::array::from_fn(|a| {
            (0..n as u32).filter(|&i| touching[i as usize] && p.position[i as usize][a] - p.radius[i as usize] <= lo[a] + r_mean).collect()
        });
        let mut sim = Simulation {
            mechanics: MechanicsStage::new(n, &settings.mechanics),
            settings,
            d7_materials: d7m,
            contacts: Contacts::default(),
            t: 0.0,
            dt: 0.0,
            stop_at: f64::INFINITY,
            velocity: vec![Vector3::zeros(); n],
            step: 0,
            rejected: 0,
            heat: None,
            x0: p.position.clone(),
            planes: lo,
            far_layer,
            near_layer,
            extent0: Vector3::zeros(),
            ode: OdeStats::default(),
            contacts_in_lanes: 0,
            timing: Timing::default(),
            heat_in: 0.0,
            heat_stored: 0.0,
            heat_scale: 0.0,
            warnings: Vec::new(),
            limited_corrections: 0,
            skipped: Vec::new(),
            source: (String::new(), std::path::PathBuf::new()),
            load: None,
            expansion: None,
            prep,
        };
        sim.extent0 = sim.extents();
        sim.dt = sim.settings.dt0;
        if let Some(prof) = &sim.prep.isothermal {
            let t0 = prof.temperature(0.0);
            sim.prep.scene.particles.temperature.iter_mut().for_each(|v| *v = t0);
            log("thermal.mode = isothermal: the heat network solve is skipped; every contact follows the furnace profile");
            sim.skipped.push("heat solve (isothermal)");
        } else {
            let p = &mut sim.prep.scene.particles;
            let net = crate::scene::network_for(&sim.prep.case, &sim.prep.sources, p, &sim.prep.scene.materials, &sim.prep.conductance);
            net.apply_fixed(0.0, &mut p.temperature);
            sim.heat = Some(net);
        }
        // (X1): the reference temperature of each particle is its temperature at t = 0
        sim.expansion = super::expansion::ThermalExpansion::new(&sim.prep.scene.materials, &sim.prep.scene.particles);
        if let Some(x) = sim.expansion.as_mut() {
            let p = &sim.prep.scene.particles;
            if sim.settings.mechanics.constrain_planes {
                x.plane_mask = crate::mechanics::Constraints::principal_planes(&p.position, &p.radius, sim.settings.mechanics.plane_gap)?.fixed;
            }
            log(
                "thermal expansion on: particle radii grow by ε = ∫α dT from each particle's temperature at t = 0; shrinkage is reported in total and net of the thermal strain (docs/coupled.md \"Thermal expansion\")",
            );
        }
        if n == 2 {
            log("two particles: the bonded mechanics is skipped; the pair approaches by exactly the 7-DOF prediction");
            sim.skipped.push("mechanics (pair)");
        } else {
            let (young, poisson) = (sim.d7_materials[0].young_modulus, sim.d7_materials[0].poisson_ratio);
            sim.mechanics.build(&sim.prep.scene.particles, young, poisson)?;
            // each bond takes the elastic constants of its own particles' materials
            let el: Vec<[f64; 2]> = sim.d7_materials.iter().map(|m| [m.young_modulus, m.poisson_ratio]).collect();
            if el.iter().any(|m| *m != el[0]) {
                let per: Vec<[f64; 2]> = sim.prep.scene.particles.material.iter().map(|&k| el[k as usize]).collect();
                if let Some(sys) = sim.mechanics.sys.as_mut() {
                    sys.set_particle_elastic(Some(per))?;
                }
                log("materials differ in E or ν: each bond takes its own particles' constants (two half-links in series)");
            }
        }
        if let Some(ls) = sim.settings.load.clone() {
            if n == 2 {
                return Err(ConfigError::inconsistent(
                    "load",
                    "an applied load needs the bonded mechanics, which a two-particle compact skips; for a loaded pair use kind = \"pair\" with load.force (N)",
                )
                .into());
            }
            log(&format!(
                "applied load: {:?}, peak stress {:.4e} Pa, on the particles of the far layer(s); contact normal forces from the load distribution (docs/pressure.md)",
                ls.mode,
                ls.stress.max()
            ));
            sim.load = Some(super::load::LoadState::new(ls, n));
        }
        if !sim.settings.detect_new {
            log("contacts.detect_new = false: the neighbour search runs once, at the start");
            sim.skipped.push("neighbour search after the start");
        }
        sim.add_new_contacts(log)?;
        Ok(sim)
    }

    /// Extent from the principal planes to the mean far face along each axis [m], with the
    /// thermally expanded radii (docs/coupled.md (X12)).
    pub fn extents(&self) -> Vector3<f64> {
        let p = &self.prep.scene.particles;
        let free = !self.settings.mechanics.constrain_planes;
        let eps = self.thermal_strains();
        let r = |i: u32| match &eps {
            Some(e) => p.radius[i as usize] * (1.0 + e[i as usize]),
            None => p.radius[i as usize],
        };
        Vector3::from_fn(|a, _| {
            let l = &self.far_layer[a];
            let s: f64 = l.iter().map(|&i| p.position[i as usize][a] + r(i)).sum();
            // with constrained planes the near face is the plane itself (the particles held on it
            // keep their surface on it, (X7)); without, it is the mean near face of the particles
            // that started on it ((S6) with both faces measured)
            let near = if free && !self.near_layer[a].is_empty() {
                let l = &self.near_layer[a];
                l.iter().map(|&i| p.position[i as usize][a] - r(i)).sum::<f64>() / l.len() as f64
            } else {
                self.planes[a]
            };
            s / l.len().max(1) as f64 - near
        })
    }

    /// Stage 1: contacts for newly touching pairs, with their initial 7-DOF state at time `t`.
    /// At the start (`step == 0`) pairs within `contacts.gap_tolerance` get the seed state
    /// (I1)–(I4); afterwards pairs within `contacts.new_contact_gap` get the state of
    /// `contacts.new_contact_state` (docs/coupled.md "New contacts"). Returns the number added.
    pub fn add_new_contacts(&mut self, log: &mut dyn FnMut(&str)) -> Result<usize, Error> {
        let p = &self.prep.scene.particles;
        let during_run = self.step > 0;
        let gap = if during_run { self.settings.new_gap } else { self.settings.gap };
        let state = if during_run { self.settings.new_state } else { NewContactState::Seed };
        // with thermal expansion the search sees the expanded radii and each contact starts from
        // the reference distance (X9) of its pair
        let eps = self.thermal_strains();
        let radii: std::borrow::Cow<[f64]> = match &eps {
            Some(e) => p.radius.iter().zip(e).map(|(r, e)| r * (1.0 + e)).collect::<Vec<f64>>().into(),
            None => (&p.radius[..]).into(),
        };
        let r_mean = if eps.is_some() { radii.iter().sum::<f64>() / radii.len().max(1) as f64 } else { p.mean_radius() };
        let found = crate::contacts::detect::touching_pairs(&p.position, &radii, gap * r_mean);
        let existing: std::collections::HashSet<(u32, u32)> = self.contacts.pairs.iter().map(|&[i, j]| (i, j)).collect();
        let mut added = 0;
        // overlap at detection relative to the smaller radius (log only)
        let mut overlaps = Vec::new();
        for (i, j) in found {
            if existing.contains(&(i, j)) {
                continue;
            }
            let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
            let d_now = match &eps {
                Some(e) => super::expansion::ThermalExpansion::reference_distance(p, e, i as usize, j as usize, dist(p, i, j)),
                None => dist(p, i, j),
            };
            overlaps.push((ri + rj - d_now) / ri.min(rj));
            // a pair within the gap tolerance starts as touching (I1 needs d ≤ R_A + R_B)
            let d = d_now.min(ri + rj);
            let ctx = |e: ModelError| e.with_context(format!("new contact between particles {i} and {j} at t = {} s", self.t));
            let c = match state {
                NewContactState::Seed => Contact7::new(ri, rj, d, self.t, self.settings.epsilon, self.settings.eta).map_err(ctx)?,
                NewContactState::VolumeConserving => {
                    let a0 = new_contact_neck(ri, rj, d_now, self.settings.epsilon).map_err(ctx)?;
                    Contact7::with_neck(ri, rj, d, self.t, a0, self.settings.eta).map_err(ctx)?
                }
            };
            self.contacts.pairs.push([i, j]);
            self.contacts.state.push(c);
            self.contacts.dl_bar.push(0.0);
            self.contacts.substeps.push(0);
            added += 1;
        }
        if added > 0 && during_run {
            overlaps.sort_by(f64::total_cmp);
            let apart = overlaps.iter().filter(|&&h| h <= 0.0).count();
            log(&format!(
                "t = {:.6e} s: {added} new contacts ({} in all); overlap at detection h/R_min median {:.3e}, max {:.3e}, {apart} within the gap tolerance without overlap",
                self.t,
                self.contacts.len(),
                overlaps[overlaps.len() / 2],
                overlaps[overlaps.len() - 1]
            ));
        }
        Ok(added)
    }

    /// Pipe conductances from the current necks [W/K].
    pub(crate) fn conductances(&self) -> Result<Vec<f64>, ModelError> {
        Ok(self.pipe_parts()?.iter().map(|p| p.pair).collect())
    }

    /// Halves and series conductance of every pipe at the materials' constant κ [W/K].
    pub(crate) fn pipe_parts(&self) -> Result<Vec<crate::heat::PipeConductance>, ModelError> {
        let p = &self.prep.scene.particles;
        let law: &Conductance = &self.prep.conductance;
        let mats = &self.prep.scene.materials;
        let eps = self.thermal_strains();
        self.contacts
            .pairs
            .iter()
            .zip(&self.contacts.state)
            .enumerate()
            .map(|(k, (&[i, j], c))| {
                let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
                let a = match self.settings.neck {
                    NeckSource::SevenDof => c.y[0],
                    NeckSource::VolumeConserving => {
                        // in the reference geometry of the contact (X9)
                        let d = match &eps {
                            Some(e) => super::expansion::ThermalExpansion::reference_distance(p, e, i as usize, j as usize, dist(p, i, j)),
                            None => dist(p, i, j),
                        };
                        let h = ri + rj - d;
                        crate::neck::solve(ri, rj, h).map_err(|e| e.with_context(format!("contact {k} ({i}–{j}) at t = {} s", self.t)))?.a
                    }
                };
                let (ki, kj) = (mats[p.material[i as usize] as usize].conductivity, mats[p.material[j as usize] as usize].conductivity);
                Ok(law.pipe(ki, kj, ri, rj, a))
            })
            .collect()
    }

    /// One accepted global step (strategy 1 may reject and retry inside).
    pub fn advance_step(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let end = self.stop_at.min(self.settings.end);
        loop {
            let dt = self.dt.min(end - self.t);
            // a step shortened to land on an output or the end time does not lower the controller's Δt
            let shortened = dt < self.dt;
            let t0 = self.t;
            let t1 = t0 + dt;
            let x_start = self.prep.scene.particles.position.clone();
            // 1. topology
            let tic = Instant::now();
            if self.settings.detect_new && self.step > 0 && self.step.is_multiple_of(self.settings.detect_every) {
                self.add_new_contacts(log)?;
            }
            self.timing.detection += tic.elapsed().as_secs_f64();
            // 1b. applied load: the contacts' normal forces at t0 (docs/pressure.md (P3))
            let tic = Instant::now();
            self.update_load_forces(t0)?;
            self.timing.mechanics += tic.elapsed().as_secs_f64();
            // 2. heat
            let tic = Instant::now();
            let temps_old = self.prep.scene.particles.temperature.clone();
            let mut heat_info = None;
            if self.heat.is_some() {
                let k = self.pipe_parts()?;
                let control = crate::scene::step_control(&self.prep.case)?.map(|c| crate::heat::adaptive::StepControl { dt_min: 1e-6 * dt, dt_max: dt, ..c });
                if let Some(net) = self.heat.as_mut() {
                    // contact pipes, then the gap pipes of the current positions (heat-model.md (H18)–(H23))
                    let p = &self.prep.scene.particles;
                    let (k, _) = crate::heat::gap::attach(net, self.prep.gap.as_mut(), &p.position, &p.radius, &self.contacts.pairs, k)?;
                    heat_info = Some(crate::heat::adaptive::advance(net, t0, dt, &mut self.prep.scene.particles.temperature, &k, control)?.0);
                }
                if let Err(e) =
                    crate::finite::ensure_finite("heat", self.step + 1, t1, "particle", "temperature", self.prep.scene.particles.temperature.iter().copied())
                {
                    self.undo_sweep(temps_old);
                    return Err(e.into());
                }
            }
            self.timing.heat += tic.elapsed().as_secs_f64();
            // 3. diffusion sweep
            let tic = Instant::now();
            let p = &self.prep.scene.particles;
            let temps_new = &p.temperature;
            let iso = self.prep.isothermal.as_ref();
            let mats = &self.d7_materials;
            let factors = self.settings.factors;
            let strategy1 = self.settings.strategy == 1 && dt > self.settings.dt_min;
            let mut solver = self.settings.solver;
            if strategy1 {
                // strategy 1 (docs/coupled.md (S1)–(S2)): every contact tries one step of the whole Δt; the first
                // rejection anywhere rejects the global step (no adaptive retries)
                solver.stop_on_reject = true;
                for c in self.contacts.state.iter_mut() {
                    c.h_last = dt * (1.0 + 1e-9);
                }
            }
            let harmonic = self.settings.harmonic;
            let ct = |a: f64, b: f64| if harmonic { 2.0 * a * b / (a + b) } else { 0.5 * (a + b) };
            // contacts four at a time side by side (docs/diffusion7.md §7 "The sweep in lanes"),
            // each ending bit for bit where the scalar integration would
            use d7::lanes::{LANES, advance_lanes, work_order};
            // lanes run in lockstep, so contacts of alike work share a chunk: the order by last
            // step's substeps, new contacts together (the result does not depend on it)
            let order = work_order(&self.contacts.state, &self.contacts.substeps);
            let (mut work, work_pairs) = match &order {
                Some(o) => (o.iter().map(|&k| self.contacts.state[k as usize]).collect(), o.iter().map(|&k| self.contacts.pairs[k as usize]).collect()),
                None => (Vec::new(), Vec::new()),
            };
            let (states, pairs_in_order): (&mut [Contact7], &[[u32; 2]]) =
                if order.is_some() { (&mut work, &work_pairs) } else { (&mut self.contacts.state, &self.contacts.pairs) };
            let chunks: Vec<(Vec<Result<OdeStats, ModelError>>, usize)> = states
                .par_chunks_mut(LANES)
                .zip(pairs_in_order.par_chunks(LANES))
                .enumerate()
                .map(|(ch, (cs, ps))| {
                    let pms: Vec<PairMaterials> = ps
                        .iter()
                        .map(|&[i, j]| PairMaterials { a: &mats[p.material[i as usize] as usize], b: &mats[p.material[j as usize] as usize], factors })
                        .collect();
                    let paths: Vec<TemperaturePath> = ps
                        .iter()
                        .map(|&[i, j]| {
                            let (i, j) = (i as usize, j as usize);
                            match iso {
                                Some(prof) => TemperaturePath::Profile(prof),
                                None => TemperaturePath::Linear { t0, temp0: ct(temps_old[i], temps_old[j]), t1, temp1: ct(temps_new[i], temps_new[j]) },
                            }
                        })
                        .collect();
                    let (res, n) = advance_lanes(cs, &pms, &paths, t0, t1, &solver);
                    let res = res
                        .into_iter()
                        .zip(ps)
                        .enumerate()
                        .map(|(l, (r, &[i, j]))| {
                            let k = order.as_ref().map_or(ch * LANES + l, |o| o[ch * LANES + l] as usize);
                            r.map_err(|e| e.with_context(format!("contact {k} between particles {i} and {j}")))
                        })
                        .collect();
                    (res, n)
                })
                .collect();
            let mut results: Vec<Result<OdeStats, ModelError>> = Vec::with_capacity(self.contacts.len());
            for (r, n) in chunks {
                results.extend(r);
                self.contacts_in_lanes += n as u64;
            }
            if let Some(o) = &order {
                // back to contact order (`o` is a permutation: every slot is written)
                let mut back: Vec<Result<OdeStats, ModelError>> = (0..o.len()).map(|_| Ok(OdeStats::default())).collect();
                for ((&k, r), c) in o.iter().zip(results).zip(&work) {
                    self.contacts.state[k as usize] = *c;
                    back[k as usize] = r;
                }
                results = back;
            }
            let mut stats = Vec::with_capacity(results.len());
            let mut trial_rejected = 0usize;
            for r in results {
                match r {
                    Ok(s) => stats.push(s),
                    Err(e) if strategy1 && e.message == crate::models::ode::STEP_REJECTED => {
                        trial_rejected += 1;
                        stats.push(OdeStats { rejected: 1, ..Default::default() });
                    }
                    Err(e) => {
                        // the state stays that of the last completed step
                        self.undo_sweep(temps_old);
                        return Err(e.into());
                    }
                }
            }
            if let Err(e) =
                crate::finite::ensure_finite_groups("diffusion", self.step + 1, t1, "contact", "7-DOF state", self.contacts.state.iter().map(|c| &c.y))
            {
                self.undo_sweep(temps_old);
                return Err(e.into());
            }
            self.timing.diffusion += tic.elapsed().as_secs_f64();
            let subdivided = if strategy1 { trial_rejected } else { stats.iter().filter(|s| s.steps > self.settings.substeps_allowed).count() };
            if strategy1 && subdivided > 0 {
                // strategy 1: any contact that needed more than one step rejects the global step
                self.undo_sweep(temps_old);
                for s in &stats {
                    self.ode.add(s);
                }
                self.rejected += 1;
                self.dt = (dt / self.settings.alpha).max(self.settings.dt_min);
                continue;
            }
            for (s, n) in stats.iter().zip(self.contacts.substeps.iter_mut()) {
                self.ode.add(s);
                *n = s.steps as u32;
            }
            if let Some(info) = heat_info {
                self.heat_in += info.heat_in;
                self.heat_stored += info.stored_change;
                self.heat_scale += info.heat_in.abs();
            }
            // 4. mechanics: load increments (F5) along e3 of the step
            let tic = Instant::now();
            let p = &self.prep.scene.particles;
            let m = self.contacts.len();
            let mut e3 = Vec::with_capacity(m);
            let mut approach = Vec::with_capacity(m);
            for (c, &[i, j]) in self.contacts.state.iter().zip(&self.contacts.pairs) {
                let d = p.position[j as usize] - p.position[i as usize];
                e3.push(d / d.norm());
                approach.push((c.y_prev[3] - c.y[3]) + (c.y_prev[6] - c.y[6]));
            }
            // thermal expansion (docs/coupled.md (X3)–(X6)): each bond's eigen-approach in the
            // current geometry is the scaled sintering approach less the thermal elongation
            let thermal = self.expansion.as_ref().map(|x| {
                let temps_end = match &self.prep.isothermal {
                    Some(prof) => vec![prof.temperature(if t1 >= end * (1.0 - 1e-12) { end } else { t1 }); p.len()],
                    None => p.temperature.clone(),
                };
                x.step_terms(p, &self.contacts.pairs, &x.strains(p, &temps_old), &x.strains(p, &temps_end), &self.planes)
            });
            if let Some(th) = &thermal {
                for ((a, f), dth) in approach.iter_mut().zip(&th.factor).zip(&th.elongation) {
                    *a = f * *a - dth;
                }
            }
            let n_particles = p.len();
            let xi: Vec<f64> = if n_particles == 2 {
                if let Some(th) = &thermal {
                    // the predictor (X7) moves both; B covers the rest of the approach below
                    for (x, q) in self.prep.scene.particles.position.iter_mut().zip(&th.predictor) {
                        *x += q;
                    }
                }
                approach.clone()
            } else {
                // the applied load enters as its increment over the step (docs/pressure.md (P2))
                let external = self.load_increment(t1);
                let radii = thermal.as_ref().map(|th| th.radii.as_slice());
                // with thermal expansion the solve takes what the predictor (X7) leaves
                let solve_approach: std::borrow::Cow<[f64]> = match &thermal {
                    Some(th) => approach.iter().zip(&th.predictor_approach).map(|(a, q)| a - q).collect::<Vec<f64>>().into(),
                    None => (&approach[..]).into(),
                };
                let (mut du, mut xi) = self.mechanics.solve(&self.prep.scene.particles, &self.contacts, &solve_approach, external.as_deref(), radii)?;
                if let Some(th) = &thermal {
                    du.iter_mut().zip(&th.predictor).for_each(|(d, q)| *d += q);
                    xi.iter_mut().zip(&th.predictor_approach).for_each(|(x, q)| *x += q);
                }
                for (x, d) in self.prep.scene.particles.position.iter_mut().zip(&du) {
                    *x += d;
                }
                xi
            };
            crate::finite::ensure_finite("mechanics", self.step + 1, t1, "contact", "axial approach", xi.iter().copied())?;
            // (X8): the correction gets the mechanical approach net of the thermal elongation, in
            // the reference geometry of the 7-DOF contacts (the pair moves by the full ξ above)
            let xi_ref: std::borrow::Cow<[f64]> = match &thermal {
                Some(th) => xi.iter().zip(&th.elongation).zip(&th.factor).map(|((x, d), f)| (x + d) / f).collect::<Vec<f64>>().into(),
                None => (&xi[..]).into(),
            };
            self.timing.mechanics += tic.elapsed().as_secs_f64();
            // 5. correction (C1)–(C4)
            let tic = Instant::now();
            let p2 = n_particles == 2;
            for k in 0..m {
                let [i, j] = self.contacts.pairs[k];
                let c = &mut self.contacts.state[k];
                let star = (c.y[3], c.y[6]);
                let prev = (c.y_prev[3], c.y_prev[6]);
                let r_sum = c.r0[0] + c.r0[1];
                let rates_star = if prev.0 - star.0 + prev.1 - star.1 > 1e-12 * r_sum {
                    (0.0, 0.0)
                } else {
                    let temp_c = match &self.prep.isothermal {
                        Some(prof) => prof.temperature(t1),
                        None => {
                            let tt = &self.prep.scene.particles.temperature;
                            if harmonic {
                                2.0 * tt[i as usize] * tt[j as usize] / (tt[i as usize] + tt[j as usize])
                            } else {
                                0.5 * (tt[i as usize] + tt[j as usize])
                            }
                        }
                    };
                    let pm = PairMaterials {
                        a: &self.d7_materials[self.prep.scene.particles.material[i as usize] as usize],
                        b: &self.d7_materials[self.prep.scene.particles.material[j as usize] as usize],
                        factors,
                    };
                    let mut kc = pm.params_at(temp_c).at(temp_c)?;
                    kc.normal_force = c.normal_force;
                    let r = d7::rates_with(&c.y, &kc)?;
                    (r[3], r[6])
                };
                let corr = d7::correct_y4_y7(prev, star, rates_star, xi_ref[k], r_sum);
                // (C4) can push a young contact's cone past tangency (A3) when its neighbours
                // compress it more than its own approach: then the deviation from y* is halved
                // until the state is admissible (counted; docs/decisions.md)
                let mut w = 1.0;
                loop {
                    c.y[3] = star.0 + w * (corr.y4 - star.0);
                    c.y[6] = star.1 + w * (corr.y7 - star.1);
                    let ok = d7::geometry::sides(&c.y).is_ok_and(|(a, b)| a.derivs().is_ok() && b.derivs().is_ok());
                    if ok {
                        break;
                    }
                    if w < 1e-6 {
                        c.y[3] = star.0;
                        c.y[6] = star.1;
                        break;
                    }
                    w *= 0.5;
                }
                if w < 1.0 {
                    self.limited_corrections += 1;
                }
                c.y_prev = c.y;
                c.e3 = [e3[k].x, e3[k].y, e3[k].z];
                self.contacts.dl_bar[k] = (c.y[3] + c.y[6]) - (star.0 + star.1);
                if p2 {
                    // an isolated pair: A stays, B approaches by exactly the 7-DOF prediction
                    let ps = &mut self.prep.scene.particles;
                    match &thermal {
                        Some(th) => ps.position[j as usize] -= (xi[k] - th.predictor_approach[k]) * e3[k],
                        None => ps.position[j as usize] -= xi[k] * e3[k],
                    }
                }
            }
            crate::finite::ensure_finite_groups("correction", self.step + 1, t1, "contact", "7-DOF state", self.contacts.state.iter().map(|c| &c.y))?;
            self.timing.correction += tic.elapsed().as_secs_f64();
            // 6. step control
            self.t = if t1 >= end * (1.0 - 1e-12) { end } else { t1 };
            for ((v, x), x0) in self.velocity.iter_mut().zip(&self.prep.scene.particles.position).zip(&x_start) {
                *v = (x - x0) / dt;
            }
            let base = if shortened { self.dt } else { dt };
            self.step += 1;
            if let Some(prof) = &self.prep.isothermal {
                // isothermal: the particles carry the furnace temperature (output only; the
                // contacts read the profile itself)
                let temp = prof.temperature(self.t);
                self.prep.scene.particles.temperature.iter_mut().for_each(|v| *v = temp);
            }
            let frac = if m > 0 { subdivided as f64 / m as f64 } else { 0.0 };
            let s = &self.settings;
            self.dt = match s.strategy {
                1 => {
                    // grow when every contact's next proposed substep exceeds 1.43 Δt, i.e. e_j < 0.1 ((S2); Ivannikov et al. 2022 eq. 46)
                    let min_h = self.contacts.state.iter().map(|c| c.h_last).fold(f64::INFINITY, f64::min);
                    if min_h >= 0.9 * 10f64.powf(0.2) * dt { (base * s.alpha).min(s.dt_max) } else { base }
                }
                _ => {
                    if frac < s.grow_below {
                        (base * s.alpha).min(s.dt_max)
                    } else if frac > s.shrink_above {
                        (dt / s.alpha).max(s.dt_min)
                    } else {
                        base
                    }
                }
            };
            self.check_state(log)?;
            return Ok(());
        }
    }

    /// After a completed step: every state finite, relative density at most 1, no particle at or
    /// above its material's melting temperature (ModelErrors naming step and particle/contact),
    /// and a warning, once per material and side, when a contact temperature leaves the range its
    /// diffusion data are calibrated for.
    fn check_state(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let p = &self.prep.scene.particles;
        let at = format!("step {}, t = {:e} s", self.step, self.t);
        if let Some(i) = (0..p.len()).find(|&i| !(p.position[i].iter().all(|v| v.is_finite()) && p.temperature[i].is_finite())) {
            return Err(ModelError::new(format!(
                "non-finite state of particle {i} (position {:?}, temperature {} K) after {at}",
                p.position[i].as_slice(),
                p.temperature[i]
            ))
            .into());
        }
        if let Some(k) = self.contacts.state.iter().position(|c| !c.y.iter().all(|v| v.is_finite())) {
            let [i, j] = self.contacts.pairs[k];
            return Err(
                ModelError::new(format!("non-finite 7-DOF state of contact {k} (particles {i}, {j}) after {at}: {:?}", self.contacts.state[k].y)).into()
            );
        }
        let rho = self.relative_density();
        if !(rho.is_finite() && rho <= 1.0) {
            return Err(ModelError::new(format!(
                "relative density {rho:.6} after {at}: above 1 (or not finite), the packing has left the model's range (eq. 49)"
            ))
            .into());
        }
        for (i, (&t, &m)) in p.temperature.iter().zip(&p.material).enumerate() {
            let mat = &self.d7_materials[m as usize];
            if let Some(tm) = mat.melting_temperature
                && t >= tm
            {
                return Err(ModelError::new(format!("particle {i} of material \"{}\" reached {t:.1} K after {at}, at or above its melting/solidus temperature {tm} K: solid-state sintering no longer applies", mat.name)).into());
            }
        }
        // calibrated range of each material's diffusion data, seen at the contacts
        let harmonic = self.settings.harmonic;
        let iso = self.prep.isothermal.as_ref().map(|prof| prof.temperature(self.t));
        let mut lo_hi = vec![(f64::INFINITY, f64::NEG_INFINITY); self.d7_materials.len()];
        for &[i, j] in &self.contacts.pairs {
            let (ti, tj) = (p.temperature[i as usize], p.temperature[j as usize]);
            let tc = iso.unwrap_or(if harmonic { 2.0 * ti * tj / (ti + tj) } else { 0.5 * (ti + tj) });
            for m in [p.material[i as usize], p.material[j as usize]] {
                let e = &mut lo_hi[m as usize];
                *e = (e.0.min(tc), e.1.max(tc));
            }
        }
        for (m, &(lo, hi)) in lo_hi.iter().enumerate() {
            let mat = &self.d7_materials[m];
            for (below, t, lim) in [(true, lo, mat.calibrated_min_temperature), (false, hi, mat.calibrated_max_temperature)] {
                let out = if below { t < lim } else { t > lim };
                let tag = format!("material \"{}\": contact temperature {} the calibrated range", mat.name, if below { "below" } else { "above" });
                if out && !self.warnings.iter().any(|w| w.starts_with(&tag)) {
                    let w = format!(
                        "{tag} {:.1}–{:.1} K ({t:.1} K first at {at}): its diffusion data are extrapolated",
                        mat.calibrated_min_temperature, mat.calibrated_max_temperature
                    );
                    log(&format!("warning: {w}"));
                    self.warnings.push(w);
                }
            }
        }
        Ok(())
    }

    /// Particles without a conductive path to any heat source (no chain of contacts, or of gap
    /// pipes with the gap model (heat-model.md (H18)–(H23)), to a particle of prescribed
    /// temperature, exposed to the furnace or heated volumetrically); empty in isothermal runs.
    /// Their temperature stays where it started.
    pub fn isolated_particles(&self) -> Vec<u32> {
        let p = &self.prep.scene.particles;
        let mut pairs = self.contacts.pairs.clone();
        if let Some(g) = &self.prep.gap {
            pairs.extend(g.pairs_now(&p.position, &p.radius, &self.contacts.pairs));
        }
        self.isolated_through(&pairs)
    }

    /// With the gap model: the particles that reach a heat source only through gap pipes
    /// (isolated without them); empty without the model.
    pub fn particles_connected_only_through_gaps(&self) -> Vec<u32> {
        if self.prep.gap.is_none() {
            return vec![];
        }
        let with = self.isolated_particles();
        self.isolated_through(&self.contacts.pairs).into_iter().filter(|i| with.binary_search(i).is_err()).collect()
    }

    /// The particles without a path through `pairs` to a heat source, sorted.
    fn isolated_through(&self, pairs: &[[u32; 2]]) -> Vec<u32> {
        let Some(net) = self.heat.as_ref() else { return vec![] };
        let src = &self.prep.sources;
        let n = self.prep.scene.particles.len();
        // the components of the network (every pipe conducts)
        let root = crate::heat::conductivity::components(n, pairs, &vec![1.0; pairs.len()]);
        let furnace = src.furnace.is_some();
        let mut heated = vec![false; n];
        for i in 0..n {
            let source = net.is_fixed(i)
                || src.fixed.get(i).is_some_and(Option::is_some)
                || (furnace && src.exposed_area.get(i).is_some_and(|&a| a > 0.0))
                || src.power.get(i).is_some_and(|&q| q != 0.0);
            if source {
                heated[root[i] as usize] = true;
            }
        }
        (0..n as u32).filter(|&i| !heated[root[i as usize] as usize]).collect()
    }

    /// Mean, min and max particle temperature [K] over the particles not in `iso` (the
    /// [`Simulation::isolated_particles`]; all particles when every one is isolated).
    pub fn temperature_stats(&self, iso: &[u32]) -> (f64, f64, f64) {
        let t = &self.prep.scene.particles.temperature;
        let mut skip = vec![false; t.len()];
        if iso.len() < t.len() {
            for &i in iso {
                skip[i as usize] = true;
            }
        }
        let vals = t.iter().zip(&skip).filter(|(_, s)| !**s).map(|(v, _)| *v);
        let (mut sum, mut n, mut lo, mut hi) = (0.0, 0usize, f64::INFINITY, f64::NEG_INFINITY);
        for v in vals {
            sum += v;
            n += 1;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        (sum / n.max(1) as f64, lo, hi)
    }

    /// Undoes the heat step and the diffusion sweep of a step that is not kept: every contact
    /// back to its last corrected state, the particles to `temps_old` [K], the heat network's
    /// BDF2 history forgotten (its next step is backward Euler).
    fn undo_sweep(&mut self, temps_old: Vec<f64>) {
        for c in &mut self.contacts.state {
            c.y = c.y_prev;
        }
        self.prep.scene.particles.temperature = temps_old;
        if let Some(net) = self.heat.as_mut() {
            net.reset_history();
        }
    }

    /// The nodal forces of the applied load at time `t` [s] with the current extents (P1) [N].
    fn load_forces_at(&self, t: f64) -> Option<Vec<Vector3<f64>>> {
        let ls = self.load.as_ref()?;
        let sigma = ls.settings.stress.at(t);
        let free = !self.settings.mechanics.constrain_planes;
        Some(super::load::nodal_forces(ls.settings.mode, sigma, &self.extents(), &self.prep.scene.particles.radius, &self.far_layer, &self.near_layer, free))
    }

    /// (P2): the increment of the applied nodal forces over the step ending at `t1`, recorded as
    /// applied; None when there is no load or the increment is zero.
    fn load_increment(&mut self, t1: f64) -> Option<Vec<NodalLoad>> {
        let target = self.load_forces_at(t1)?;
        let ls = self.load.as_mut()?;
        let inc: Vec<Vector3<f64>> = target.iter().zip(&ls.applied).map(|(t, a)| t - a).collect();
        ls.applied = target;
        super::load::as_nodal_loads(&inc)
    }

    /// (P3): sets every contact's normal force from the load distribution at `t0` [s]: solved
    /// afresh when contacts appeared, at the first loaded step and every
    /// [`super::load::REDISTRIBUTE_EVERY`] steps, otherwise the last solve scaled by the total
    /// applied force. Without a load (or at zero stress) every normal force is exactly 0.
    fn update_load_forces(&mut self, t0: f64) -> Result<(), Error> {
        let Some(f) = self.load_forces_at(t0) else { return Ok(()) };
        let total = super::load::total_force(&f);
        let m = self.contacts.len();
        let step = self.step;
        let Some(ls) = self.load.as_ref() else { return Ok(()) };
        if total == 0.0 {
            self.contacts.state.iter_mut().for_each(|c| c.normal_force = 0.0);
            return Ok(());
        }
        let resolve = ls.ref_total == 0.0 || ls.ref_contacts != m || step >= ls.ref_step + super::load::REDISTRIBUTE_EVERY;
        if resolve {
            let Some(loads) = super::load::as_nodal_loads(&f) else { return Ok(()) };
            let (normal, force) = self.mechanics.distribute(&self.prep.scene.particles, &self.contacts, &loads)?;
            crate::finite::ensure_finite("load distribution", step + 1, t0, "contact", "normal force", normal.iter().copied())?;
            let Some(ls) = self.load.as_mut() else { return Ok(()) };
            ls.contact_normal = normal;
            ls.contact_force = force;
            ls.ref_total = total;
            ls.ref_contacts = m;
            ls.ref_step = step;
            ls.solves += 1;
        }
        let Some(ls) = self.load.as_ref() else { return Ok(()) };
        let scale = total / ls.ref_total;
        let lim = ls.settings.contact_stress_limit;
        for (c, &nf) in self.contacts.state.iter_mut().zip(&ls.contact_normal) {
            // (P5): compression only, at most the flow stress over the neck area π a² of the
            // step's start
            let cap = lim * std::f64::consts::PI * c.y[0] * c.y[0];
            c.normal_force = (nf * scale).clamp(0.0, cap);
        }
        Ok(())
    }

    /// The applied stress σ(t) at the current time [Pa] (0 without a load).
    pub fn applied_stress(&self) -> f64 {
        self.load.as_ref().map_or(0.0, |l| l.settings.stress.at(self.t))
    }

    /// (P4): the macroscopic stress `[xx, yy, zz, yz, xz, xy]` [Pa] (tension positive) of the
    /// contact forces of the applied load at the current time, over the box volume of (S6).
    pub fn macroscopic_stress(&self) -> [f64; 6] {
        let Some(ls) = self.load.as_ref() else { return [0.0; 6] };
        if ls.ref_total == 0.0 {
            return [0.0; 6];
        }
        let Some(f) = self.load_forces_at(self.t) else { return [0.0; 6] };
        let scale = super::load::total_force(&f) / ls.ref_total;
        let e = self.extents();
        let n = ls.contact_force.len().min(self.contacts.len());
        super::load::macroscopic_stress(&self.contacts.pairs[..n], &ls.contact_force[..n], scale, &self.prep.scene.particles.position, e.x * e.y * e.z)
    }

    /// Mean normal force of the contacts in the last step [N] (compressive positive).
    pub fn mean_normal_force(&self) -> f64 {
        self.contacts.state.iter().map(|c| c.normal_force).sum::<f64>() / self.contacts.len().max(1) as f64
    }

    /// Mean neck ratio y1/R_min over contacts [1].
    pub fn mean_neck_ratio(&self) -> f64 {
        let m = self.contacts.len().max(1) as f64;
        self.contacts.state.iter().map(|c| c.neck_ratio()).sum::<f64>() / m
    }

    /// Relative density: particle volume over the bounding volume from the principal planes to the
    /// far faces (Ivannikov et al. 2022 eq. 49) [1], both with the thermally expanded radii (X12).
    pub fn relative_density(&self) -> f64 {
        let p = &self.prep.scene.particles;
        let v: f64 = match self.thermal_strains() {
            Some(e) => p.radius.iter().zip(&e).map(|(&r, e)| crate::units::sphere_volume(r * (1.0 + e))).sum(),
            None => p.radius.iter().map(|&r| crate::units::sphere_volume(r)).sum(),
        };
        let e = self.extents();
        v / (e.x * e.y * e.z)
    }

    /// Mean contact shrinkage ΔL/L0 and mean neck ratio in `layers` slabs along z (contact
    /// midpoints, initial positions), bottom first: the densification profile of a compact heated
    /// from one face.
    pub fn layer_profile(&self, layers: usize) -> Vec<(f64, f64, f64, usize)> {
        let p = &self.prep.scene.particles;
        let (lo, hi) = (self.planes.z, self.planes.z + self.extent0.z);
        let mut acc = vec![(0.0, 0.0, 0usize); layers];
        for (c, &[i, j]) in self.contacts.state.iter().zip(&self.contacts.pairs) {
            let z = 0.5 * (self.x0[i as usize].z + self.x0[j as usize].z);
            let k = (((z - lo) / (hi - lo) * layers as f64) as usize).min(layers - 1);
            acc[k].0 += c.shrinkage();
            acc[k].1 += c.neck_ratio();
            acc[k].2 += 1;
        }
        let _ = p;
        acc.iter()
            .enumerate()
            .map(|(k, &(s, nr, n))| (lo + (k as f64 + 0.5) * (hi - lo) / layers as f64, s / n.max(1) as f64, nr / n.max(1) as f64, n))
            .collect()
    }

    /// Shrinkage per axis, 1 − L/L0 [1]: the total, thermal strain included (a dilatometer's).
    pub fn shrinkage(&self) -> Vector3<f64> {
        let e = self.extents();
        Vector3::from_fn(|a, _| 1.0 - e[a] / self.extent0[a])
    }

    /// (X1) The thermal strain ε_i of every particle at its current temperature [1]; None
    /// without thermal expansion.
    pub fn thermal_strains(&self) -> Option<Vec<f64>> {
        let x = self.expansion.as_ref()?;
        let p = &self.prep.scene.particles;
        Some(x.strains(p, &p.temperature))
    }

    /// (X10) The mean thermal strain of the compact (volume-weighted over the particles with a
    /// contact), and the smallest and largest particle strain among them [1]; zeros without
    /// thermal expansion.
    pub fn thermal_strain(&self) -> (f64, f64, f64) {
        match self.thermal_strains() {
            Some(e) => super::expansion::ThermalExpansion::mean_strain(&self.prep.scene.particles, &e, &self.contacts.pairs),
            None => (0.0, 0.0, 0.0),
        }
    }

    /// (X11) Sintering shrinkage per axis: the total shrinkage net of the mean thermal strain,
    /// `1 − (1 − s)/(1 + ε̄)` [1]; the total itself without thermal expansion.
    pub fn sintering_shrinkage(&self) -> Vector3<f64> {
        let s = self.shrinkage();
        if self.expansion.is_none() {
            return s;
        }
        let eps = self.thermal_strain().0;
        s.map(|v| super::expansion::sintering_shrinkage(v, eps))
    }
}

/// Parse → validate → build a compact case.
pub fn prepare(value: toml::Value, base: &Path, log: &mut dyn FnMut(&str)) -> Result<Simulation, Error> {
    let text = toml::to_string(&value).map_err(|e| ConfigError::invalid(format!("case cannot be re-serialised: {e}")))?;
    let prep = crate::scene::prepare_scene(value, base)?;
    if prep.case.kind.as_deref() != Some("compact") {
        return Err(ConfigError::invalid("a compact run needs kind = \"compact\"").into());
    }
    let mut sim = Simulation::new(prep, log)?;
    let base = base.canonicalize().unwrap_or_else(|_| base.to_path_buf());
    sim.source = (text, base);
    Ok(sim)
}

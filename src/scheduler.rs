//! The staggered loop of a compact run (`kind = "compact"`; architecture map "The loop"):
//! 1. topology (new contacts by cell list), 2. heat (implicit network, conductances from the
//! current necks), 3. diffusion (every contact's 7-DOF ODE over the step at its own temperature,
//! rayon sweep), 4. mechanics (bonded quasi-static equilibrium under the load increments),
//! 5. correction of y4, y7 (seven-dof-model.md §9), 6. step control (§10, strategies 1 and 2),
//! 7. output. Stages a scene does not need are skipped and the log says so.
//!
//! Determinism: every contact writes only its own slot in the parallel sweep and all reductions
//! run sequentially in contact order, so results are bit-identical for any thread count.

use crate::config::{self, case::Case};
use crate::error::{ConfigError, Error, IoError, ModelError};
use crate::heat::run::Prepared;
use crate::heat::{Conductance, HeatNetwork};
use crate::io::{self, Series, Snapshot, SnapshotWriter};
use crate::mechanics::{BondedSystem, Constraints, LinearSolver, MechParams, StepInput};
use crate::models::diffusion7::{self as d7, Contact7, PairMaterials, PathFactors, SolverOptions, TemperaturePath};
use crate::models::ode::OdeStats;
use nalgebra::Vector3;
use rayon::prelude::*;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// Which neck radius feeds the conductance (heat-network.md "Which neck radius ...").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NeckSource {
    /// From the overlap of the current centre distance.
    VolumeConserving,
    /// The 7-DOF neck radius y1.
    SevenDof,
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
    /// Times of the y4/y7 correction histograms [s] (eq. 44).
    pub histogram_at: Vec<f64>,
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
        let dt_min = config::check("time.dt_min", t.dt_min.unwrap_or(1e-12))?;
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
        })
    }
}

/// Mechanics settings of a compact run, validated.
#[derive(Debug, Clone)]
pub struct MechanicsSettings {
    pub constrain_planes: bool,
    /// Relative surface gap of the plane test: centre within (1 + gap)·r (spec §8: 1 %).
    pub plane_gap: f64,
    pub solver: LinearSolver,
    pub reuse_factor: bool,
}

impl MechanicsSettings {
    pub fn from_spec(m: &crate::config::case::MechanicsSpec) -> Result<Self, ConfigError> {
        let margin = config::check("mechanics.plane_margin", m.plane_margin)?;
        let solver = match m.solver.as_str() {
            "auto" => LinearSolver::Auto,
            "cholesky" => LinearSolver::Cholesky,
            "cg" => LinearSolver::Pcg,
            "amg" => LinearSolver::Amg,
            o => return Err(ConfigError::invalid(format!("mechanics.solver = \"{o}\": expected auto, cholesky, cg or amg"))),
        };
        Ok(MechanicsSettings { constrain_planes: m.constrain_planes, plane_gap: margin - 1.0, solver, reuse_factor: m.reuse_factor })
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
}

impl MechanicsStage {
    pub fn new(n: usize, settings: &MechanicsSettings) -> Self {
        MechanicsStage { settings: settings.clone(), sys: None, bonds: 0, rotation: vec![Vector3::zeros(); n], newton_iterations: 0, factorizations: 0, max_residual: 0.0 }
    }

    /// Builds the bonded system with the plane constraints of the initial packing.
    pub fn build(&mut self, p: &crate::particles::Particles, young: f64, poisson: f64) -> Result<(), Error> {
        let cons = if self.settings.constrain_planes {
            Constraints::principal_planes(&p.position, &p.radius, self.settings.plane_gap)?
        } else {
            Constraints::none(p.len())
        };
        let params = MechParams { young_modulus: young, poisson_ratio: poisson, solver: self.settings.solver, reuse_factor: self.settings.reuse_factor, ..Default::default() };
        self.sys = Some(BondedSystem::new(p.len(), params, cons)?);
        Ok(())
    }

    /// Forgets the cached factor, so that the next step factorises afresh (done at checkpoints, so
    /// that a resumed run repeats the uninterrupted one bit for bit).
    pub fn drop_factor(&mut self) -> Result<(), Error> {
        if let Some(sys) = self.sys.as_mut() {
            let pairs = sys.pairs().to_vec();
            sys.set_topology(&pairs)?;
        }
        Ok(())
    }

    /// Solves the step: displacement increments per particle and the axial approach ξ per contact.
    #[allow(clippy::too_many_arguments)]
    fn solve(&mut self, p: &crate::particles::Particles, contacts: &Contacts, approach: &[f64], young: f64) -> Result<(Vec<Vector3<f64>>, Vec<f64>), Error> {
        let sys = self.sys.as_mut().ok_or_else(|| ModelError::new("mechanics: the bonded system was not built"))?;
        if self.bonds != contacts.len() {
            sys.set_topology(&contacts.pairs)?;
            self.bonds = contacts.len();
        }
        let y4_y7: Vec<[f64; 2]> = contacts.state.iter().map(|c| [c.y_prev[3], c.y_prev[6]]).collect();
        let load: Vec<f64> = contacts.state.iter().zip(approach).map(|(c, &a)| d7::load_increment(a, 0.0, c.r_mean(), young)).collect();
        let out = sys.step(&StepInput { positions: &p.position, radii: &p.radius, y4_y7: &y4_y7, load: &load, external: None })?;
        for (r, d) in self.rotation.iter_mut().zip(&out.dtheta) {
            *r += d;
        }
        self.newton_iterations += out.info.newton_iterations as u64;
        self.factorizations += out.info.factorizations as u64;
        self.max_residual = self.max_residual.max(out.info.residuals.last().copied().unwrap_or(0.0));
        Ok((out.du, out.xi))
    }
}

/// The diffusion contacts of a packing, struct of arrays (architecture map).
#[derive(Debug, Clone, Default)]
pub struct Contacts {
    /// Particle pairs (i < j).
    pub pairs: Vec<[u32; 2]>,
    /// 7-DOF state of each contact.
    pub state: Vec<Contact7>,
    /// ΔL̄ of the last correction (paper eq. 44) [m].
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
    pub extent0: Vector3<f64>,
    pub ode: OdeStats,
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
}

fn dist(p: &crate::particles::Particles, i: u32, j: u32) -> f64 {
    (p.position[j as usize] - p.position[i as usize]).norm()
}

impl Simulation {
    /// Builds a compact simulation from a prepared case.
    pub fn new(prep: Prepared, log: &mut dyn FnMut(&str)) -> Result<Simulation, Error> {
        let settings = Settings::from_case(&prep.case)?;
        let mut d7m = Vec::new();
        for m in &prep.scene.materials {
            let name = m.diffusion.as_deref().ok_or_else(|| ConfigError::invalid(format!("materials.{}.diffusion: a compact run needs 7-DOF diffusion data (\"copper\" or \"titanium\")", m.name)))?;
            let mut dm = d7::Material::builtin(name)?;
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
        let far_layer: [Vec<u32>; 3] = std::array::from_fn(|a| (0..n as u32).filter(|&i| touching[i as usize] && p.position[i as usize][a] + p.radius[i as usize] >= hi[a] - r_mean).collect());
        let mut sim = Simulation {
            mechanics: MechanicsStage::new(n, &settings.mechanics),
            settings,
            d7_materials: d7m,
            contacts: Contacts::default(),
            t: 0.0,
            dt: 0.0,
            step: 0,
            rejected: 0,
            heat: None,
            x0: p.position.clone(),
            planes: lo,
            far_layer,
            extent0: Vector3::zeros(),
            ode: OdeStats::default(),
            timing: Timing::default(),
            heat_in: 0.0,
            heat_stored: 0.0,
            heat_scale: 0.0,
            warnings: Vec::new(),
            limited_corrections: 0,
            skipped: Vec::new(),
            source: (String::new(), std::path::PathBuf::new()),
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
            let net = HeatNetwork::new(p.capacity.clone(), sim.prep.sources.clone(), sim.prep.case.time.scheme, sim.prep.case.thermal.radiation_tolerance);
            net.apply_fixed(0.0, &mut p.temperature);
            sim.heat = Some(net);
        }
        if n == 2 {
            log("two particles: the bonded mechanics is skipped; the pair approaches by exactly the 7-DOF prediction");
            sim.skipped.push("mechanics (pair)");
        } else {
            let (young, poisson) = (sim.d7_materials[0].young_modulus, sim.d7_materials[0].poisson_ratio);
            sim.mechanics.build(&sim.prep.scene.particles, young, poisson)?;
        }
        if !sim.settings.detect_new {
            log("contacts.detect_new = false: the neighbour search runs once, at the start");
            sim.skipped.push("neighbour search after the start");
        }
        sim.add_new_contacts(log)?;
        Ok(sim)
    }

    /// Extent from the principal planes to the mean far face along each axis [m].
    pub fn extents(&self) -> Vector3<f64> {
        let p = &self.prep.scene.particles;
        Vector3::from_fn(|a, _| {
            let l = &self.far_layer[a];
            let s: f64 = l.iter().map(|&i| p.position[i as usize][a] + p.radius[i as usize]).sum();
            s / l.len().max(1) as f64 - self.planes[a]
        })
    }

    /// Stage 1: contacts for newly touching pairs, with their initial 7-DOF state at time `t`.
    fn add_new_contacts(&mut self, log: &mut dyn FnMut(&str)) -> Result<usize, Error> {
        let p = &self.prep.scene.particles;
        let found = crate::contacts::detect::touching_pairs(&p.position, &p.radius, self.settings.gap * p.mean_radius());
        let existing: std::collections::HashSet<(u32, u32)> = self.contacts.pairs.iter().map(|&[i, j]| (i, j)).collect();
        let mut added = 0;
        for (i, j) in found {
            if existing.contains(&(i, j)) {
                continue;
            }
            let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
            // a pair within the gap tolerance starts as touching (I1 needs d ≤ R_A + R_B)
            let d = dist(p, i, j).min(ri + rj);
            let c = Contact7::new(ri, rj, d, self.t, self.settings.epsilon, self.settings.eta)
                .map_err(|e| e.with_context(format!("new contact between particles {i} and {j} at t = {} s", self.t)))?;
            self.contacts.pairs.push([i, j]);
            self.contacts.state.push(c);
            self.contacts.dl_bar.push(0.0);
            self.contacts.substeps.push(0);
            added += 1;
        }
        if added > 0 && self.step > 0 {
            log(&format!("t = {:.6e} s: {added} new contacts ({} in all)", self.t, self.contacts.len()));
        }
        Ok(added)
    }

    /// Pipe conductances from the current necks [W/K].
    fn conductances(&self) -> Result<Vec<f64>, ModelError> {
        let p = &self.prep.scene.particles;
        let law: &Conductance = &self.prep.conductance;
        let mats = &self.prep.scene.materials;
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
                        let h = ri + rj - dist(p, i, j);
                        crate::neck::solve(ri, rj, h).map_err(|e| e.with_context(format!("contact {k} ({i}–{j}) at t = {} s", self.t)))?.a
                    }
                };
                let (ki, kj) = (mats[p.material[i as usize] as usize].conductivity, mats[p.material[j as usize] as usize].conductivity);
                Ok(law.pipe(ki, kj, ri, rj, a).pair)
            })
            .collect()
    }

    /// One accepted global step (strategy 1 may reject and retry inside).
    pub fn advance_step(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let end = self.settings.end;
        loop {
            let dt = self.dt.min(end - self.t);
            let t0 = self.t;
            let t1 = t0 + dt;
            // 1. topology
            let tic = Instant::now();
            if self.settings.detect_new && self.step > 0 && self.step.is_multiple_of(self.settings.detect_every) {
                self.add_new_contacts(log)?;
            }
            self.timing.detection += tic.elapsed().as_secs_f64();
            // 2. heat
            let tic = Instant::now();
            let temps_old = self.prep.scene.particles.temperature.clone();
            let mut heat_info = None;
            if self.heat.is_some() {
                let k = self.conductances()?;
                if let Some(net) = self.heat.as_mut() {
                    net.set_topology(&self.contacts.pairs)?;
                    heat_info = Some(net.step(t0, dt, &mut self.prep.scene.particles.temperature, &k)?);
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
                // strategy 1 (spec §10): every contact tries one step of the whole Δt; the first
                // rejection anywhere rejects the global step (no adaptive retries)
                solver.stop_on_reject = true;
                for c in self.contacts.state.iter_mut() {
                    c.h_last = dt * (1.0 + 1e-9);
                }
            }
            let harmonic = self.settings.harmonic;
            let ct = |a: f64, b: f64| if harmonic { 2.0 * a * b / (a + b) } else { 0.5 * (a + b) };
            let results: Vec<Result<OdeStats, ModelError>> = self
                .contacts
                .state
                .par_iter_mut()
                .zip(self.contacts.pairs.par_iter())
                .enumerate()
                .map(|(k, (c, &[i, j]))| {
                    let (i, j) = (i as usize, j as usize);
                    let pm = PairMaterials { a: &mats[p.material[i] as usize], b: &mats[p.material[j] as usize], factors };
                    let path = match iso {
                        Some(prof) => TemperaturePath::Profile(prof),
                        None => TemperaturePath::Linear { t0, temp0: ct(temps_old[i], temps_old[j]), t1, temp1: ct(temps_new[i], temps_new[j]) },
                    };
                    let mut st = OdeStats::default();
                    d7::advance(c, &pm, &path, t0, t1, &solver, &mut st, |_, _, _| {})
                        .map_err(|e| e.with_context(format!("contact {k} between particles {i} and {j}")))?;
                    Ok(st)
                })
                .collect();
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
            let n_particles = p.len();
            let xi: Vec<f64> = if n_particles == 2 {
                approach.clone()
            } else {
                // one E and ν for the bonded system: those of the first material (docs/decisions.md)
                let young = self.d7_materials[0].young_modulus;
                let (du, xi) = self.mechanics.solve(&self.prep.scene.particles, &self.contacts, &approach, young)?;
                for (x, d) in self.prep.scene.particles.position.iter_mut().zip(&du) {
                    *x += d;
                }
                xi
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
                            if harmonic { 2.0 * tt[i as usize] * tt[j as usize] / (tt[i as usize] + tt[j as usize]) } else { 0.5 * (tt[i as usize] + tt[j as usize]) }
                        }
                    };
                    let pm = PairMaterials { a: &self.d7_materials[self.prep.scene.particles.material[i as usize] as usize], b: &self.d7_materials[self.prep.scene.particles.material[j as usize] as usize], factors };
                    let r = d7::rates(&c.y, &pm.params_at(temp_c), temp_c)?;
                    (r[3], r[6])
                };
                let corr = d7::correct_y4_y7(prev, star, rates_star, xi[k], r_sum);
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
                    ps.position[j as usize] -= xi[k] * e3[k];
                }
            }
            self.timing.correction += tic.elapsed().as_secs_f64();
            // 6. step control
            self.t = if t1 >= end * (1.0 - 1e-12) { end } else { t1 };
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
                    // grow when every contact's next proposed substep exceeds 1.43 Δt, i.e. e_j < 0.1 (eq. 46)
                    let min_h = self.contacts.state.iter().map(|c| c.h_last).fold(f64::INFINITY, f64::min);
                    if min_h >= 0.9 * 10f64.powf(0.2) * dt { (dt * s.alpha).min(s.dt_max) } else { dt.max(self.dt) }
                }
                _ => {
                    if frac < s.grow_below {
                        (dt * s.alpha).min(s.dt_max)
                    } else if frac > s.shrink_above {
                        (dt / s.alpha).max(s.dt_min)
                    } else {
                        dt.max(self.dt.min(dt))
                    }
                }
            };
            if !self.prep.scene.particles.position.iter().all(|x| x.iter().all(|v| v.is_finite())) {
                return Err(ModelError::new(format!("non-finite particle position after the step to t = {} s", self.t)).into());
            }
            return Ok(());
        }
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

    /// Mean neck ratio y1/R_min over contacts [1].
    pub fn mean_neck_ratio(&self) -> f64 {
        let m = self.contacts.len().max(1) as f64;
        self.contacts.state.iter().map(|c| c.neck_ratio()).sum::<f64>() / m
    }

    /// Relative density: particle volume over the bounding volume from the principal planes to the
    /// far faces (Ivannikov et al. 2022 eq. 49) [1].
    pub fn relative_density(&self) -> f64 {
        let p = &self.prep.scene.particles;
        let v: f64 = p.radius.iter().map(|&r| crate::units::sphere_volume(r)).sum();
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

    /// Shrinkage per axis, 1 − L/L0 [1].
    pub fn shrinkage(&self) -> Vector3<f64> {
        let e = self.extents();
        Vector3::from_fn(|a, _| 1.0 - e[a] / self.extent0[a])
    }
}

/// Parse → validate → build a compact case.
pub fn prepare(value: toml::Value, base: &Path, log: &mut dyn FnMut(&str)) -> Result<Simulation, Error> {
    let text = toml::to_string(&value).map_err(|e| ConfigError::invalid(format!("case cannot be re-serialised: {e}")))?;
    let prep = crate::heat::run::prepare_scene(value, base)?;
    if prep.case.kind.as_deref() != Some("compact") {
        return Err(ConfigError::invalid("a compact run needs kind = \"compact\"").into());
    }
    let mut sim = Simulation::new(prep, log)?;
    let base = base.canonicalize().unwrap_or_else(|_| base.to_path_buf());
    sim.source = (text, base);
    Ok(sim)
}

/// Output bookkeeping that a checkpoint carries.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct OutputState {
    pub next_snap: usize,
    pub next_cond: usize,
    pub cond_results: Vec<serde_json::Value>,
    /// Next entry of `output.correction_histogram_at` to write [1].
    #[serde(default)]
    pub next_hist: usize,
    /// The histograms written so far (time [s], mean and std of ΔL̄/L0 [1], files).
    #[serde(default)]
    pub hist_results: Vec<serde_json::Value>,
    /// Lines of series.csv (header included) at the checkpoint.
    pub series_lines: usize,
    pub snapshots: usize,
    pub vtu_entries: Vec<(f64, String, String)>,
    /// Wall time spent before the checkpoint [s].
    pub wall_before: f64,
}

/// Everything needed to continue a run bit for bit (`DIR/checkpoint.json`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Checkpoint {
    pub format: String,
    pub case_toml: String,
    pub base_dir: std::path::PathBuf,
    pub t: f64,
    pub dt: f64,
    pub step: u64,
    pub rejected: u64,
    pub ode: OdeStats,
    pub timing: Timing,
    pub heat_in: f64,
    pub heat_stored: f64,
    pub heat_scale: f64,
    pub warnings: Vec<String>,
    pub limited_corrections: u64,
    pub position: Vec<[f64; 3]>,
    pub temperature: Vec<f64>,
    pub rotation: Vec<[f64; 3]>,
    /// Mechanics counters: Newton iterations, numeric factorisations, largest final scaled residual.
    #[serde(default)]
    pub mechanics_counters: (u64, u64, f64),
    pub pairs: Vec<[u32; 2]>,
    pub contacts: Vec<Contact7>,
    pub dl_bar: Vec<f64>,
    pub substeps: Vec<u32>,
    pub heat_history: Option<(Vec<f64>, f64)>,
    pub output: OutputState,
}

const CHECKPOINT_FORMAT: &str = "sinterdem-checkpoint-1";

impl Simulation {
    fn checkpoint(&self, output: OutputState) -> Checkpoint {
        let p = &self.prep.scene.particles;
        Checkpoint {
            format: CHECKPOINT_FORMAT.into(),
            case_toml: self.source.0.clone(),
            base_dir: self.source.1.clone(),
            t: self.t,
            dt: self.dt,
            step: self.step,
            rejected: self.rejected,
            ode: self.ode,
            timing: self.timing,
            heat_in: self.heat_in,
            heat_stored: self.heat_stored,
            heat_scale: self.heat_scale,
            warnings: self.warnings.clone(),
            limited_corrections: self.limited_corrections,
            position: p.position.iter().map(|x| [x.x, x.y, x.z]).collect(),
            temperature: p.temperature.clone(),
            rotation: self.mechanics.rotation.iter().map(|x| [x.x, x.y, x.z]).collect(),
            mechanics_counters: (self.mechanics.newton_iterations, self.mechanics.factorizations, self.mechanics.max_residual),
            pairs: self.contacts.pairs.clone(),
            contacts: self.contacts.state.clone(),
            dl_bar: self.contacts.dl_bar.clone(),
            substeps: self.contacts.substeps.clone(),
            heat_history: self.heat.as_ref().and_then(|h| h.history().cloned()),
            output,
        }
    }

    /// Rebuilds a simulation from a checkpoint: the case is prepared again from its text (so the
    /// initial packing, planes and constraints are the same), then the state is restored.
    pub fn from_checkpoint(ck: &Checkpoint, log: &mut dyn FnMut(&str)) -> Result<(Simulation, OutputState), Error> {
        if ck.format != CHECKPOINT_FORMAT {
            return Err(ConfigError::invalid(format!("checkpoint format \"{}\" is not {CHECKPOINT_FORMAT}", ck.format)).into());
        }
        let value: toml::Value = toml::Value::Table(ck.case_toml.parse::<toml::Table>().map_err(|e| ConfigError::invalid(format!("checkpoint case: {e}")))?);
        let mut sim = prepare(value, &ck.base_dir, &mut |_| {})?;
        let n = sim.prep.scene.particles.len();
        if ck.position.len() != n || ck.temperature.len() != n || ck.pairs.len() != ck.contacts.len() {
            return Err(ConfigError::invalid("checkpoint does not match its case (particle or contact counts differ)").into());
        }
        let p = &mut sim.prep.scene.particles;
        p.position = ck.position.iter().map(|x| Vector3::new(x[0], x[1], x[2])).collect();
        p.temperature = ck.temperature.clone();
        sim.mechanics.rotation = ck.rotation.iter().map(|x| Vector3::new(x[0], x[1], x[2])).collect();
        (sim.mechanics.newton_iterations, sim.mechanics.factorizations, sim.mechanics.max_residual) = ck.mechanics_counters;
        sim.contacts = Contacts { pairs: ck.pairs.clone(), state: ck.contacts.clone(), dl_bar: ck.dl_bar.clone(), substeps: ck.substeps.clone() };
        if let Some(h) = sim.heat.as_mut() {
            h.set_history(ck.heat_history.clone());
        }
        sim.t = ck.t;
        sim.dt = ck.dt;
        sim.step = ck.step;
        sim.rejected = ck.rejected;
        sim.ode = ck.ode;
        sim.timing = ck.timing;
        sim.heat_in = ck.heat_in;
        sim.heat_stored = ck.heat_stored;
        sim.heat_scale = ck.heat_scale;
        sim.warnings = ck.warnings.clone();
        sim.limited_corrections = ck.limited_corrections;
        log(&format!("resumed from the checkpoint at t = {} s (step {}, {} contacts)", sim.t, sim.step, sim.contacts.len()));
        Ok((sim, ck.output.clone()))
    }
}

/// Writes `dir/checkpoint.json` atomically (temporary file, then rename).
fn write_checkpoint(dir: &Path, ck: &Checkpoint) -> Result<(), IoError> {
    let path = dir.join("checkpoint.json");
    let tmp = dir.join("checkpoint.json.tmp");
    let text = serde_json::to_string(ck).map_err(|e| IoError::new(&path, e))?;
    std::fs::write(&tmp, text).map_err(|e| IoError::new(&tmp, e))?;
    std::fs::rename(&tmp, &path).map_err(|e| IoError::new(&path, e))
}

/// Reads `dir/checkpoint.json`.
pub fn read_checkpoint(dir: &Path) -> Result<Checkpoint, Error> {
    let path = dir.join("checkpoint.json");
    let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
    Ok(serde_json::from_str(&text).map_err(|e| IoError::new(&path, e))?)
}

/// `sinterdem resume DIR`: continues the run whose checkpoint is in `dir`.
pub fn resume(dir: &Path, progress: bool, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    let ck = read_checkpoint(dir)?;
    let (sim, out_state) = Simulation::from_checkpoint(&ck, log)?;
    run_from(sim, dir, progress, log, Some(out_state), None)
}

const SERIES_HEADER: &[&str] = &[
    "time_s", "dt_s", "shrinkage_x", "shrinkage_y", "shrinkage_z", "relative_density", "coordination_mean", "neck_ratio_mean",
    "contacts", "mean_temperature_K", "min_temperature_K", "max_temperature_K", "subdivided_fraction", "rhs_evaluations",
];

/// Runs a compact simulation to its end time, writing series, snapshots, checkpoints and the summary.
pub fn run(sim: Simulation, out: &Path, progress: bool, log: &mut dyn FnMut(&str)) -> Result<serde_json::Value, Error> {
    run_from(sim, out, progress, log, None, None)
}

/// Runs from a fresh start (`state = None`) or a checkpoint's output state; `stop_after_step`
/// ends the run early after that step (as if killed right after its checkpoint, for tests), with
/// `Ok(Value::Null)`.
pub fn run_from(mut sim: Simulation, out: &Path, progress: bool, log: &mut dyn FnMut(&str), state: Option<OutputState>, stop_after_step: Option<u64>) -> Result<serde_json::Value, Error> {
    let wall = Instant::now();
    io::ensure_dir(out)?;
    let n = sim.prep.scene.particles.len();
    let resumed = state.is_some();
    let st = state.unwrap_or_default();
    log(&format!(
        "compact run: {n} particles, {} initial contacts, strategy {}, Δt0 = {:e} s, Δt_max = {} s, end = {} s",
        sim.contacts.len(),
        sim.settings.strategy,
        sim.dt,
        sim.settings.dt_max,
        sim.settings.end
    ));
    let (vtu_on, h5_on) = (sim.prep.case.output.vtu, sim.prep.case.output.hdf5);
    let (mut series, mut snaps, mut series_lines) = if resumed {
        (
            Series::resume(&out.join("series.csv"), st.series_lines, SERIES_HEADER.len())?,
            SnapshotWriter::resume(out, vtu_on, h5_on, st.snapshots, st.vtu_entries.clone(), log)?,
            st.series_lines,
        )
    } else {
        (Series::create(&out.join("series.csv"), SERIES_HEADER)?, SnapshotWriter::new(out, vtu_on, h5_on, log)?, 1)
    };
    let end = sim.settings.end;
    let snap_times: Vec<f64> = match sim.settings.snapshots {
        0 => vec![],
        1 => vec![end],
        k => (0..k).map(|i| end * i as f64 / (k - 1) as f64).collect(),
    };
    let mut due = Due {
        snap_times,
        next_snap: st.next_snap,
        next_cond: st.next_cond,
        cond_results: st.cond_results.clone(),
        next_hist: st.next_hist,
        hist_results: st.hist_results.clone(),
    };
    let bar = io::progress::Progress::new(end, progress);
    let mut stop_reason: Option<String> = None;
    let mut failure: Option<Error> = None;
    let write_row = |sim: &Simulation, series: &mut Series, dt: f64| -> Result<(), IoError> {
        let sh = sim.shrinkage();
        let t = &sim.prep.scene.particles.temperature;
        let mean = t.iter().sum::<f64>() / t.len() as f64;
        let frac = sim.contacts.substeps.iter().filter(|&&s| s > 1).count() as f64 / sim.contacts.len().max(1) as f64;
        series.row(&[
            sim.t,
            dt,
            sh.x,
            sh.y,
            sh.z,
            sim.relative_density(),
            2.0 * sim.contacts.len() as f64 / n as f64,
            sim.mean_neck_ratio(),
            sim.contacts.len() as f64,
            mean,
            t.iter().copied().fold(f64::INFINITY, f64::min),
            t.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            frac,
            sim.ode.rhs as f64,
        ])
    };
    if !resumed {
        write_row(&sim, &mut series, 0.0)?;
        series_lines += 1;
    }
    loop {
        let tic = Instant::now();
        due.write(&sim, out, &mut snaps, log)?;
        sim.timing.output += tic.elapsed().as_secs_f64();
        if sim.t >= end {
            break;
        }
        let dt_used = sim.dt.min(end - sim.t);
        if let Err(e) = sim.advance_step(log) {
            match e {
                // the model's validity ends (a contact's geometry or integrator breaks down): the
                // run stops with the last completed step summarised, then reports the error
                Error::Model(ref m) => {
                    log(&format!("stopped at t = {} s (step {}): {m}", sim.t, sim.step));
                    stop_reason = Some(format!("model error after t = {} s: {m}", sim.t));
                    failure = Some(e);
                    break;
                }
                _ => return Err(e),
            }
        }
        let tic = Instant::now();
        let rho_stop = sim.settings.stop_relative_density.filter(|&r| sim.relative_density() >= r);
        if let Some(r) = rho_stop {
            log(&format!("t = {} s: relative density {:.4} reached time.stop_relative_density = {r}: the run ends here", sim.t, sim.relative_density()));
            stop_reason = Some(format!("relative density {r} reached"));
        }
        if sim.step.is_multiple_of(sim.settings.series_every) || sim.t >= end || rho_stop.is_some() {
            write_row(&sim, &mut series, dt_used)?;
            series_lines += 1;
        }
        if sim.settings.checkpoint_every > 0 && sim.step.is_multiple_of(sim.settings.checkpoint_every) && sim.t < end {
            // snapshots and analyses due at this time are written before the checkpoint
            due.write(&sim, out, &mut snaps, log)?;
            sim.mechanics.drop_factor()?;
            let os = OutputState {
                next_snap: due.next_snap,
                next_cond: due.next_cond,
                cond_results: due.cond_results.clone(),
                next_hist: due.next_hist,
                hist_results: due.hist_results.clone(),
                series_lines,
                snapshots: snaps.count(),
                vtu_entries: snaps.vtu_entries(),
                wall_before: st.wall_before + wall.elapsed().as_secs_f64(),
            };
            write_checkpoint(out, &sim.checkpoint(os))?;
            if stop_after_step.is_some_and(|s| sim.step >= s) {
                bar.finish();
                return Ok(serde_json::Value::Null);
            }
        }
        sim.timing.output += tic.elapsed().as_secs_f64();
        if rho_stop.is_some() {
            break;
        }
        bar.set(sim.t, &format!("step {}, Δt = {:.3e} s, contacts {}", sim.step, sim.dt, sim.contacts.len()));
    }
    bar.finish();
    if stop_reason.is_some() && sim.settings.snapshots > 0 {
        // a run that ends before its end time keeps its last state as a snapshot
        write_snapshot(&sim, &mut snaps)?;
    }
    let sh = sim.shrinkage();
    let balance = if sim.heat.is_some() { (sim.heat_stored - sim.heat_in).abs() / sim.heat_scale.max(sim.heat_stored.abs()).max(1e-300) } else { 0.0 };
    let t = &sim.prep.scene.particles.temperature;
    let dl: Vec<f64> = sim.contacts.dl_bar.clone();
    let dl_mean = dl.iter().sum::<f64>() / dl.len().max(1) as f64;
    let dl_std = (dl.iter().map(|v| (v - dl_mean) * (v - dl_mean)).sum::<f64>() / dl.len().max(1) as f64).sqrt();
    let v_particles: f64 = sim.prep.scene.particles.radius.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    let rho0 = v_particles / (sim.extent0.x * sim.extent0.y * sim.extent0.z);
    let summary = json!({
        "kind": "compact",
        "final_time_s": sim.t,
        "steps": sim.step,
        "rejected_steps": sim.rejected,
        "wall_seconds": st.wall_before + wall.elapsed().as_secs_f64(),
        "particles": n,
        "contacts": sim.contacts.len(),
        "shrinkage_x": sh.x,
        "shrinkage_y": sh.y,
        "shrinkage_z": sh.z,
        "relative_density": sim.relative_density(),
        "relative_density_initial": rho0,
        "coordination_mean": 2.0 * sim.contacts.len() as f64 / n as f64,
        "neck_ratio": sim.mean_neck_ratio(),
        "mean_temperature_K": t.iter().sum::<f64>() / t.len() as f64,
        "min_temperature_K": t.iter().copied().fold(f64::INFINITY, f64::min),
        "max_temperature_K": t.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        "energy_balance_rel": balance,
        "rhs_evaluations": sim.ode.rhs,
        "limited_corrections": sim.limited_corrections,
        "ode_steps": sim.ode.steps,
        "ode_rejected": sim.ode.rejected,
        "timing_seconds": sim.timing,
        "dl_bar_mean_m": dl_mean,
        "dl_bar_std_m": dl_std,
        "conductivity": due.cond_results,
        "correction_histograms": due.hist_results,
        "mechanics": {
            "newton_iterations": sim.mechanics.newton_iterations,
            "factorizations": sim.mechanics.factorizations,
            "max_final_residual": sim.mechanics.max_residual,
            "rtol": MechParams::default().rtol,
        },
        "skipped": sim.skipped,
        "warnings": sim.warnings,
        "threads": rayon::current_num_threads(),
        "completed": stop_reason.is_none(),
        "stop_reason": stop_reason,
    });
    let mut summary = summary;
    let prof = sim.layer_profile(5);
    summary["layer_z_m"] = json!(prof.iter().map(|l| l.0).collect::<Vec<_>>());
    summary["layer_contact_shrinkage"] = json!(prof.iter().map(|l| l.1).collect::<Vec<_>>());
    summary["layer_neck_ratio"] = json!(prof.iter().map(|l| l.2).collect::<Vec<_>>());
    io::write_json(&out.join("summary.json"), &summary)?;
    if let Err(e) = write_plots(out, &sim) {
        log(&format!("warning: plots not written: {e}"));
    }
    log(&format!(
        "done: {} steps to t = {} s in {:.3} s; shrinkage x/y/z = {:.4e}/{:.4e}/{:.4e}; relative density {:.4}; mean neck ratio {:.4}",
        sim.step,
        sim.t,
        wall.elapsed().as_secs_f64(),
        sh.x,
        sh.y,
        sh.z,
        sim.relative_density(),
        sim.mean_neck_ratio()
    ));
    match failure {
        Some(e) => Err(e),
        None => Ok(summary),
    }
}

/// Output analyses due at given times, and where each list stands (a checkpoint carries it).
struct Due {
    snap_times: Vec<f64>,
    next_snap: usize,
    next_cond: usize,
    cond_results: Vec<serde_json::Value>,
    next_hist: usize,
    hist_results: Vec<serde_json::Value>,
}

impl Due {
    /// Writes the snapshots, conductivity analyses and correction histograms due at the current time.
    fn write(&mut self, sim: &Simulation, out: &Path, snaps: &mut SnapshotWriter, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let now = sim.t * (1.0 + 1e-12);
        while self.next_snap < self.snap_times.len() && self.snap_times[self.next_snap] <= now + 1e-300 {
            write_snapshot(sim, snaps)?;
            self.next_snap += 1;
        }
        let at = &sim.settings.conductivity_at;
        while self.next_cond < at.len() && at[self.next_cond] <= now {
            let k = compact_conductivity(sim)?;
            log(&format!("t = {:.6e} s: effective conductivity diag = [{:.4e}, {:.4e}, {:.4e}] W/(m K)", sim.t, k[0], k[1], k[2]));
            self.cond_results.push(json!({"time_s": sim.t, "kappa_eff_W_per_mK": k}));
            self.next_cond += 1;
        }
        let at = &sim.settings.histogram_at;
        while self.next_hist < at.len() && at[self.next_hist] <= now {
            // the corrections of the step that ended at (or first after) the asked time
            if sim.step > 0 {
                let tag = format!("t{:.0}s", at[self.next_hist]);
                let h = write_correction_histogram(out, sim, &tag)?;
                log(&format!("t = {:.6e} s: correction histogram {tag}: mean ΔL̄/L0 = {:.3e}, std {:.3e} ({} contacts)", sim.t, h.0, h.1, sim.contacts.len()));
                self.hist_results.push(json!({"asked_time_s": at[self.next_hist], "time_s": sim.t, "dl_bar_rel_mean": h.0, "dl_bar_rel_std": h.1, "files": [format!("dl_bar_{tag}.csv"), format!("dl_bar_histogram_{tag}.png")]}));
            }
            self.next_hist += 1;
        }
        Ok(())
    }
}

fn write_snapshot(sim: &Simulation, snaps: &mut SnapshotWriter) -> Result<(), IoError> {
    let p = &sim.prep.scene.particles;
    let neck: Vec<f64> = sim.contacts.state.iter().map(|c| c.y[0]).collect();
    let shrink: Vec<f64> = sim.contacts.state.iter().map(|c| c.shrinkage()).collect();
    let disp: Vec<nalgebra::Vector3<f64>> = p.position.iter().zip(&sim.x0).map(|(x, x0)| x - x0).collect();
    let materials_json = serde_json::to_string_pretty(&sim.d7_materials).unwrap_or_default();
    snaps.write(&Snapshot {
        time: sim.t,
        step: sim.step,
        position: &p.position,
        radius: &p.radius,
        temperature: &p.temperature,
        contacts: &sim.contacts.pairs,
        contact_data: vec![("neck_radius_m", &neck), ("contact_shrinkage", &shrink), ("dl_bar_m", &sim.contacts.dl_bar)],
        particle_data: vec![],
        particle_vectors: vec![("displacement_m", &disp)],
        parameters: Some(io::Parameters { case_toml: sim.source.0.clone(), materials_json }),
    })
}

/// Effective conductivity (faces method, diagonal) of the compact in its current state [W/(m·K)].
pub fn compact_conductivity(sim: &Simulation) -> Result<[f64; 3], Error> {
    let p = &sim.prep.scene.particles;
    let k = sim.conductances()?;
    let pipes = crate::scene::Pipes { pairs: sim.contacts.pairs.clone(), conductance: k, ..Default::default() };
    let mut out = [0.0; 3];
    for (a, o) in out.iter_mut().enumerate() {
        *o = crate::heat::conductivity::faces(p, &pipes, a, 0.5 * p.mean_radius(), 1.0)?.kappa;
    }
    Ok(out)
}

/// The y4/y7 corrections of the last step, ΔL̄/L0 per contact (Ivannikov et al. 2022 eq. 44,
/// Fig. 20): `dl_bar_TAG.csv` (pair, L0, ΔL̄, ΔL̄/L0) and `dl_bar_histogram_TAG.png` (30 bins);
/// returns the mean and standard deviation of ΔL̄/L0.
pub fn write_correction_histogram(out: &Path, sim: &Simulation, tag: &str) -> Result<(f64, f64), IoError> {
    use crate::plot::{Plot, Series as Line};
    let dl: Vec<f64> = sim.contacts.dl_bar.iter().zip(&sim.contacts.state).map(|(d, c)| d / c.l0).collect();
    let csv_path = out.join(format!("dl_bar_{tag}.csv"));
    let mut text = String::from("particle_a,particle_b,l0_m,dl_bar_m,dl_bar_rel\n");
    for (k, (&[a, b], c)) in sim.contacts.pairs.iter().zip(&sim.contacts.state).enumerate() {
        text.push_str(&format!("{a},{b},{:e},{:e},{:e}\n", c.l0, sim.contacts.dl_bar[k], dl[k]));
    }
    std::fs::write(&csv_path, text).map_err(|e| IoError::new(&csv_path, e))?;
    let n = dl.len().max(1) as f64;
    let mean = dl.iter().sum::<f64>() / n;
    let std = (dl.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt();
    if !dl.is_empty() {
        let (lo, hi) = dl.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let bins = 30usize;
        let w = ((hi - lo) / bins as f64).max(f64::MIN_POSITIVE);
        let mut count = vec![0usize; bins];
        for v in &dl {
            count[(((v - lo) / w) as usize).min(bins - 1)] += 1;
        }
        let mut pts = Vec::new();
        for (k, &c) in count.iter().enumerate() {
            let (a, b) = (lo + k as f64 * w, lo + (k + 1) as f64 * w);
            pts.push((a, 0.0));
            pts.push((a, c as f64));
            pts.push((b, c as f64));
            pts.push((b, 0.0));
        }
        let mut p = Plot::new(format!("y4/y7 corrections at t = {:.0} s (paper Fig. 20)", sim.t)).labels("dL_bar / L0 [1]", "contacts");
        p.add(Line::new("histogram", pts));
        let name = if tag == "end" { "dl_bar_histogram.png".to_string() } else { format!("dl_bar_histogram_{tag}.png") };
        p.save_png(&out.join(name))?;
    }
    Ok((mean, std))
}

/// PNG plots of a compact run from its series.csv, the ΔL̄ histogram (Ivannikov et al. 2022
/// Fig. 20) and the layer profile along z.
pub fn write_plots(out: &Path, sim: &Simulation) -> Result<(), IoError> {
    use crate::plot::{Plot, Series as Line};
    // the series and summary also go into the HDF5 file (docs/outputs.md)
    let h5 = if sim.prep.case.output.hdf5 { io::hdf5::finish(out) } else { Ok(()) };
    let path = out.join("series.csv");
    let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect()).collect();
    let col = |name: &str| -> Vec<(f64, f64)> {
        let k = header.iter().position(|h| *h == name).unwrap_or(0);
        rows.iter().filter(|r| r[0] > 0.0).map(|r| (r[0], r[k])).collect()
    };
    let mut p = Plot::new("shrinkage along each axis").labels("time t [s]", "shrinkage 1 - L/L0 [1]");
    for (name, key) in [("x", "shrinkage_x"), ("y", "shrinkage_y"), ("z", "shrinkage_z")] {
        p.add(Line::new(name, col(key)));
    }
    p.save_png(&out.join("shrinkage.png"))?;
    let mut p = Plot::new("relative density (eq. 49)").labels("time t [s]", "relative density [1]");
    p.add(Line::new("relative density", col("relative_density")));
    p.save_png(&out.join("relative_density.png"))?;
    let mut p = Plot::new("mean coordination number").labels("time t [s]", "coordination [1]");
    p.add(Line::new("2 contacts / particles", col("coordination_mean")));
    p.save_png(&out.join("coordination.png"))?;
    let mut p = Plot::new("mean neck ratio").labels("time t [s]", "y1/R_min [1]").log_x(true);
    p.add(Line::new("neck ratio", col("neck_ratio_mean")));
    p.save_png(&out.join("neck_ratio.png"))?;
    let mut p = Plot::new("particle temperatures").labels("time t [s]", "T [K]");
    for (name, key) in [("mean", "mean_temperature_K"), ("min", "min_temperature_K"), ("max", "max_temperature_K")] {
        p.add(Line::new(name, col(key)));
    }
    p.save_png(&out.join("temperature.png"))?;
    write_correction_histogram(out, sim, "end")?;
    let prof = sim.layer_profile(5);
    let mut p = Plot::new("densification through the height").labels("height z [m]", "mean contact shrinkage dL/L0 [1]");
    p.add(Line::new("contacts by layer", prof.iter().map(|l| (l.0, l.1)).collect()).with_markers());
    p.save_png(&out.join("layer_profile.png"))?;
    h5
}

/// `sinterdem bench coupled`: the bundled copper compact run whole (wall time and the share of
/// each stage), then the cost per step of isothermal FCC compacts of about `sizes` particles.
pub fn bench_coupled(copper_case: Option<&Path>, sizes: &[usize], steps: u64) -> Result<String, Error> {
    use std::fmt::Write as _;
    let mut out = String::new();
    let _ = writeln!(out, "# sinterdem bench coupled ({} rayon threads)", rayon::current_num_threads());
    if let Some(case) = copper_case {
        let value = crate::config::load_case(case, &["output.snapshots=0".into(), "output.vtu=false".into(), "output.hdf5=false".into(), "output.checkpoint_every=0".into(), "output.conductivity_at=[]".into()])?;
        let base = case.parent().unwrap_or(Path::new("."));
        let dir = std::env::temp_dir().join(format!("sinterdem-bench-{}", std::process::id()));
        let sim = prepare(value, base, &mut |_| {})?;
        let s = run(sim, &dir, false, &mut |_| {})?;
        let _ = std::fs::remove_dir_all(&dir);
        let tm: Timing = serde_json::from_value(s["timing_seconds"].clone()).unwrap_or_default();
        let total = s["wall_seconds"].as_f64().unwrap_or(0.0);
        let _ = writeln!(out, "{}: {} steps, {} contacts at the end, wall {:.2} s", case.display(), s["steps"], s["contacts"], total);
        for (name, v) in [("detection", tm.detection), ("heat", tm.heat), ("diffusion", tm.diffusion), ("mechanics", tm.mechanics), ("correction", tm.correction), ("output", tm.output)] {
            let _ = writeln!(out, "  {name:<11} {v:>9.3} s  {:>5.1} %", 100.0 * v / total.max(1e-300));
        }
    }
    let _ = writeln!(out, "{:>9} {:>9} {:>12} {:>12} {:>12} {:>12} {:>12}", "particles", "contacts", "s/step", "detection", "diffusion", "mechanics", "correction");
    for &n in sizes {
        let cells = ((n as f64 / 4.0).cbrt().round() as u32).max(2);
        let text = format!(
            "kind = \"compact\"\n[time]\nend = {end}\ndt = 1.0\ndt_max = 1.0\n[output]\nsnapshots = 0\nvtu = false\nhdf5 = false\n[[materials]]\nname = \"copper\"\npreset = \"copper\"\n[particles]\nsource = \"lattice\"\nlattice = \"fcc\"\ncells = [{cells}, {cells}, {cells}]\nradius = 25e-6\noverlap = 0.0\n[thermal]\nmode = \"isothermal\"\nfurnace = {{ profile = {{ constant = 1293.0 }} }}\n[contacts]\ndetect_new = true\n",
            end = steps as f64
        );
        let value = toml::Value::Table(text.parse::<toml::Table>().map_err(|e| ConfigError::invalid(e.to_string()))?);
        let mut sim = prepare(value, Path::new("."), &mut |_| {})?;
        // the first step of a new contact is the stiff start; time the later steps
        sim.advance_step(&mut |_| {})?;
        let t0 = sim.timing;
        let w = Instant::now();
        let mut k = 0;
        while sim.t < sim.settings.end && k < steps {
            sim.advance_step(&mut |_| {})?;
            k += 1;
        }
        let per = w.elapsed().as_secs_f64() / k.max(1) as f64;
        let tm = sim.timing;
        let d = |a: f64, b: f64| (a - b) / k.max(1) as f64;
        let _ = writeln!(
            out,
            "{:>9} {:>9} {:>12.4} {:>12.4} {:>12.4} {:>12.4} {:>12.4}",
            sim.prep.scene.particles.len(),
            sim.contacts.len(),
            per,
            d(tm.detection, t0.detection),
            d(tm.diffusion, t0.diffusion),
            d(tm.mechanics, t0.mechanics),
            d(tm.correction, t0.correction)
        );
    }
    Ok(out)
}

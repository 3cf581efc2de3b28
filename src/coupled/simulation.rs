//! The compact simulation in progress ([`Simulation`]): its state, its construction from a
//! prepared case ([`prepare`], [`Simulation::new`]) and the extents every measure starts from.

use super::{Contacts, MechanicsStage, Settings};
use crate::error::{ConfigError, Error};
use crate::heat::HeatNetwork;
use crate::models::diffusion7 as d7;
use crate::models::ode::OdeStats;
use crate::scene::Prepared;
use nalgebra::Vector3;
use std::path::Path;

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
    /// Contacts the last sweep kept unchanged by docs/diffusion7.md (T2) (status line).
    pub skipped_last: usize,
    pub timing: Timing,
    pub heat_in: f64,
    pub heat_stored: f64,
    pub heat_scale: f64,
    pub warnings: Vec<String>,
    /// Notes logged once (the first time a contact leaves its material's calibrated range).
    pub notes: Vec<String>,
    /// The lowest contact temperature after a step, per material [K] (f64::MAX before the first step;
    /// the calibrated-range verdict, docs/diffusion7.md (V3)).
    pub lowest_contact_temperature: Vec<f64>,
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
    /// The periodic cell (`mechanics.boundary = "periodic"`, docs/mechanics.md "Periodic cell");
    /// None: walls.
    pub cell: Option<super::cell::CellState>,
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
            if dm.young_modulus != m.young_modulus {
                // the case's own E replaces the library's E(T) (docs/materials.md (L1))
                dm.young_modulus_table = None;
            }
            dm.young_modulus = m.young_modulus;
            dm.poisson_ratio = m.poisson_ratio;
            d7m.push(dm);
        }
        let p = &prep.scene.particles;
        let n = p.len();
        let (lo, _) = p.bounding_box();
        let r_mean = p.mean_radius();
        // the far layer of each axis, without particles that touch nothing (rattlers stay put)
        let mut touching = vec![false; n];
        for (i, j) in crate::contacts::detect::touching_pairs(&p.position, &p.radius, settings.gap * r_mean) {
            touching[i as usize] = true;
            touching[j as usize] = true;
        }
        // no pair touches at the start (two spheres apart, contacts to come): every particle
        // counts, else the far layers are empty and the extents meaningless
        if !touching.iter().any(|&t| t) {
            touching.fill(true);
        }
        // the far faces of the touching particles (a particle touching nothing beyond the body,
        // e.g. an isolated one, must not empty the far layer)
        let hi: Vector3<f64> =
            Vector3::from_fn(|a, _| (0..n).filter(|&i| touching[i]).map(|i| p.position[i][a] + p.radius[i]).fold(f64::NEG_INFINITY, f64::max));
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
            skipped_last: 0,
            timing: Timing::default(),
            heat_in: 0.0,
            heat_stored: 0.0,
            heat_scale: 0.0,
            warnings: Vec::new(),
            notes: Vec::new(),
            lowest_contact_temperature: Vec::new(),
            limited_corrections: 0,
            skipped: Vec::new(),
            source: (String::new(), std::path::PathBuf::new()),
            load: None,
            expansion: None,
            cell: None,
            prep,
        };
        sim.cell = super::cell::start(&sim.settings, &sim.prep, log)?;
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
        if let Some(c) = &self.cell {
            return c.lengths();
        }
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

    /// Undoes the heat step and the diffusion sweep of a step that is not kept: every contact
    /// back to its last corrected state, the particles to `temps_old` [K], the heat network's
    /// BDF2 history forgotten (its next step is backward Euler).
    pub(super) fn undo_sweep(&mut self, temps_old: &[f64]) {
        for c in &mut self.contacts.state {
            c.y = c.y_prev;
        }
        self.prep.scene.particles.temperature = temps_old.to_vec();
        if let Some(net) = self.heat.as_mut() {
            net.reset_history();
        }
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

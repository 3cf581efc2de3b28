//! The explicit DEM driver: velocity Verlet for translations and rotations of spheres with
//! elastic-viscous normal contacts, a Coulomb-limited tangential spring, planar walls and gravity
//! (docs/design.md, "Explicit driver": the explicit-DEM laws run in a separate velocity-Verlet driver).
//! Packing generation ([`crate::packing`]) runs on it; the explicit sintering laws plug into it
//! through [`law::ContactModel`].
//!
//! One step (velocity Verlet, Δt fixed):
//! 1. `v ← v + Δt/2 · F/m`, `ω ← ω + Δt/2 · M/I` (forces of the previous step, gravity included);
//! 2. `x ← x + Δt v`, rotation vector `θ ← θ + Δt ω`; walls move under their control;
//! 3. neighbour list rebuilt if any particle moved more than half the Verlet skin since the last build
//!    (cell list of [`crate::contacts::detect`]); contact history carried over by pair;
//! 4. forces at the new positions (velocities of the half step in the viscous terms);
//! 5. `v ← v + Δt/2 · F/m`, `ω ← ω + Δt/2 · M/I`.
//!
//! Tangential law (Luding et al. 2005 eqs. 16–22, docs/luding.md): the spring ξ is
//! projected into the current tangent plane `ξ ← ξ − n(n·ξ)`; trial force `f_t° = −k_t ξ − γ_t v_t`
//! with `k_t = α k_n`, `γ_t = β γ_n`; sticking if `|f_t°| ≤ μ f_n` (then `ξ ← ξ + v_t Δt`), else
//! sliding with `f_t = μ f_n t̂` and `ξ ← −(f_t + γ_t v_t)/k_t`.
//!
//! Parallel sweeps write only their own contact slot; a second pass gathers onto particles through
//! a CSR incidence table in a fixed order, so results are bit-identical for any thread count.
//!
//! Periodic box ([`Explicit::set_periodic_box`], docs/packing.md (G1)–(G4)): no walls; every pair's
//! branch is the minimum image, the neighbour list the periodic cell list, and the caller strains the
//! box affinely ([`Explicit::strain_box`]) with the velocities as fluctuations about the affine flow.
//!
//! Energy ([`Energy`]): kinetic (translation + rotation), elastic (normal and tangential springs),
//! gravitational potential, dissipated (viscous normal and tangential, Coulomb sliding, Cundall local
//! damping) and the work done by the walls on the particles. Their balance
//! `E_kin + E_el + E_pot + E_diss − W_wall` is constant up to the integrator's error.

pub mod law;
mod neighbours;
mod periodic;
pub mod sinter;
mod state;
mod sweep;
mod walls;

pub use periodic::minimum_image;
pub use state::DriverState;
pub use walls::{Wall, WallControl};

use crate::error::{ConfigError, Error, SolveError};
use crate::particles::Particles;
use law::{ContactModel, NormalOut};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

type V3 = Vector3<f64>;

/// Driver settings (SI).
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Time step Δt [s]; see [`time_step`] for its choice from the contact stiffness.
    pub dt: f64,
    /// Gravitational acceleration [m/s²].
    pub gravity: V3,
    /// Particle–particle Coulomb friction coefficient μ [1].
    pub friction: f64,
    /// Particle–wall Coulomb friction coefficient μ_w [1].
    pub wall_friction: f64,
    /// Tangential stiffness ratio α = k_t/k_n [1] (Luding eq. 23: 0.2).
    pub tangential_stiffness_ratio: f64,
    /// Tangential damping ratio β = γ_t/γ_n [1].
    pub tangential_damping_ratio: f64,
    /// Cundall's local non-viscous damping λ ∈ [0, 1): each force component is reduced by
    /// `λ|F| sign(v)` (Yade's NewtonIntegrator damping). For quasi-static packing only; 0 for dynamics.
    pub local_damping: f64,
    /// Background viscous damping rate c [1/s]: force `−c m v` and torque `−c I ω` on every
    /// particle. Unlike the local damping it also stops particles that carry no force (a loose,
    /// stress-free packing). For quasi-static relaxation only; 0 (default) for dynamics.
    pub viscous_damping: f64,
    /// Verlet skin [m]: pairs closer than this gap are kept in the neighbour list.
    pub skin: f64,
    /// Integrate rotations (false: spheres do not spin, torques ignored).
    pub rotation: bool,
}

impl Settings {
    /// Plain defaults: no gravity, no friction, no local damping, skin 0.1·`mean_radius`.
    pub fn new(dt: f64, mean_radius: f64) -> Self {
        Settings {
            dt,
            gravity: V3::zeros(),
            friction: 0.0,
            wall_friction: 0.0,
            tangential_stiffness_ratio: 0.2,
            tangential_damping_ratio: 0.0,
            local_damping: 0.0,
            viscous_damping: 0.0,
            skin: 0.1 * mean_radius,
            rotation: true,
        }
    }

    fn validate(&self) -> Result<(), ConfigError> {
        let bad = |k: &str, v: f64, what: &str| Err(ConfigError::inconsistent(k, format!("{v} must be {what}")));
        if !(self.dt > 0.0 && self.dt.is_finite()) {
            return bad("explicit.dt", self.dt, "positive and finite (s)");
        }
        if !(self.friction >= 0.0 && self.friction.is_finite()) {
            return bad("explicit.friction", self.friction, ">= 0");
        }
        if !(self.wall_friction >= 0.0 && self.wall_friction.is_finite()) {
            return bad("explicit.wall_friction", self.wall_friction, ">= 0");
        }
        if !(self.tangential_stiffness_ratio > 0.0 && self.tangential_stiffness_ratio.is_finite()) {
            return bad("explicit.tangential_stiffness_ratio", self.tangential_stiffness_ratio, "> 0");
        }
        if !(self.tangential_damping_ratio >= 0.0 && self.tangential_damping_ratio.is_finite()) {
            return bad("explicit.tangential_damping_ratio", self.tangential_damping_ratio, ">= 0");
        }
        if !(0.0..1.0).contains(&self.local_damping) {
            return bad("explicit.local_damping", self.local_damping, "in [0, 1)");
        }
        if !(self.viscous_damping >= 0.0 && self.viscous_damping.is_finite()) {
            return bad("explicit.viscous_damping", self.viscous_damping, ">= 0 (1/s)");
        }
        if !(self.skin >= 0.0 && self.skin.is_finite()) {
            return bad("explicit.skin", self.skin, ">= 0 (m)");
        }
        if !self.gravity.iter().all(|g| g.is_finite()) {
            return Err(ConfigError::inconsistent("explicit.gravity", "must be finite (m/s^2)"));
        }
        Ok(())
    }
}

/// Energy account [J]; see the module docs for the balance.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Energy {
    /// Translational plus rotational kinetic energy.
    pub kinetic: f64,
    /// Elastic energy of the normal and tangential springs (particle and wall contacts).
    pub elastic: f64,
    /// Gravitational potential `−Σ m g·x`.
    pub potential: f64,
    /// Energy dissipated since the start (viscous, friction, local damping).
    pub dissipated: f64,
    /// Work done by the walls on the particles since the start.
    pub wall_work: f64,
}

impl Energy {
    /// The conserved sum `E_kin + E_el + E_pot + E_diss − W_wall`.
    pub fn balance(&self) -> f64 {
        self.kinetic + self.elastic + self.potential + self.dissipated - self.wall_work
    }
}

/// Time step from the contact stiffness: `Δt = fraction · t_c,min`, with t_c the collision time of
/// the lightest pair (reduced mass of the two lightest particles, or the lightest particle against
/// a wall when `walls`). Returns `(dt, t_c)` [s].
pub fn time_step<M: ContactModel>(law: &M, p: &Particles, fraction: f64, impact_speed: f64, walls: bool) -> Result<(f64, f64), Error> {
    if p.is_empty() {
        return Err(ConfigError::invalid("explicit: no particles").into());
    }
    if !(fraction > 0.0 && fraction <= 1.0) {
        return Err(ConfigError::inconsistent("explicit.dt_fraction", format!("{fraction} must be in (0, 1]")).into());
    }
    let mut best = f64::INFINITY;
    let (mut m1, mut m2) = (f64::INFINITY, f64::INFINITY);
    let mut r_min = f64::INFINITY;
    for (&m, &r) in p.mass.iter().zip(&p.radius) {
        if m < m1 {
            m2 = m1;
            m1 = m;
        } else if m < m2 {
            m2 = m;
        }
        r_min = r_min.min(r);
    }
    if m2.is_finite() {
        best = best.min(law.collision_time(m1 * m2 / (m1 + m2), 0.5 * r_min, impact_speed));
    }
    if walls || !m2.is_finite() {
        best = best.min(law.collision_time(m1, r_min, impact_speed));
    }
    if !(best.is_finite() && best > 0.0) {
        return Err(SolveError::new("explicit time step", format!("collision time {best} s is not positive and finite")).into());
    }
    Ok((fraction * best, best))
}

/// Particles per chunk of the per-particle sweeps, contacts per chunk of the contact sweep. Sums
/// (energies, wall forces, the rebuild test) are formed per fixed chunk and the chunk sums added in
/// chunk order, so they depend neither on the thread count nor on whether a sweep runs in parallel.
const PARTICLE_CHUNK: usize = 1024;
const CONTACT_CHUNK: usize = 4096;

/// Per-contact history carried across neighbour-list rebuilds.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
struct Slot<S> {
    /// Tangential spring ξ [m].
    #[serde(with = "crate::io::serde_v3")]
    xi: V3,
    state: S,
}

/// Per-contact result of the force sweep.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
struct Out {
    /// Force on particle i [N] (on j: −f).
    #[serde(with = "crate::io::serde_v3")]
    f: V3,
    /// n × f_t [N]; torque on i is `−r_i n×f_t`, on j `−r_j n×f_t`.
    #[serde(with = "crate::io::serde_v3")]
    nxft: V3,
    /// Normal force on i along +n [N] (positive repulsive).
    normal_force: f64,
}

/// Counters of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Counters {
    pub steps: u64,
    pub rebuilds: u64,
}

/// The driver, generic over the contact law.
#[derive(Clone)]
pub struct Explicit<M: ContactModel> {
    pub settings: Settings,
    pub law: M,
    pub walls: Vec<Wall>,
    /// Simulated time [s].
    pub time: f64,
    pub energy: Energy,
    pub counters: Counters,
    pairs: Vec<(u32, u32)>,
    slots: Vec<Slot<M::State>>,
    /// Per pair: in contact at the last force evaluation; `out` is valid only where true (the
    /// sweeps skip the other pairs without touching their slots).
    touching: Vec<bool>,
    out: Vec<Out>,
    /// CSR incidence particle → (contact, is_i).
    inc_start: Vec<u32>,
    inc: Vec<(u32, bool)>,
    /// Positions at the last neighbour build.
    built_at: Vec<V3>,
    /// Particle–wall candidates, CSR particle → walls in ascending order (`wall_start`, `wall_of`):
    /// gap below 1.5 skins at the last build (particles move < skin since then and walls < skin/2
    /// before a rebuild, so no contact is missed). `wall_spring` holds each candidate's tangential
    /// spring; a spring leaving the list is dropped (it is out of contact).
    wall_start: Vec<u32>,
    wall_of: Vec<u32>,
    wall_spring: Vec<V3>,
    /// Wall offsets at the last wall-list build.
    wall_list_at: Vec<f64>,
    force: Vec<V3>,
    torque: Vec<V3>,
    wall_power: Vec<f64>,
    last_dissipation: f64,
    ready: bool,
    /// Run the sweeps on rayon when the neighbour-pair count exceeds this (the results do not
    /// depend on it).
    pub parallel_threshold: usize,
    /// Periodic box `[0, L_x) × [0, L_y) × [0, L_z)` [m] (None: open space bounded by the walls);
    /// set by [`Self::set_periodic_box`], strained by [`Self::strain_box`] (docs/packing.md (G1)–(G3)).
    periodic: Option<V3>,
    /// The periodic box at the last neighbour build [m].
    built_box: V3,
}

impl<M: ContactModel> Explicit<M> {
    pub fn new(settings: Settings, law: M, walls: Vec<Wall>) -> Result<Self, Error> {
        settings.validate()?;
        for (k, w) in walls.iter().enumerate() {
            if !(w.normal.iter().all(|x| x.is_finite()) && (w.normal.norm() - 1.0).abs() < 1e-9 && w.offset.is_finite()) {
                return Err(ConfigError::inconsistent(format!("walls.{k}"), "normal must be a finite unit vector and offset finite").into());
            }
            if let WallControl::Stress { mass, damping, pressure } = w.control
                && !(mass > 0.0 && damping >= 0.0 && pressure.is_finite() && w.area > 0.0)
            {
                return Err(ConfigError::inconsistent(format!("walls.{k}"), "stress control needs mass > 0, damping >= 0, finite pressure, area > 0").into());
            }
        }
        Ok(Explicit {
            settings,
            law,
            walls,
            time: 0.0,
            energy: Energy::default(),
            counters: Counters::default(),
            pairs: Vec::new(),
            slots: Vec::new(),
            touching: Vec::new(),
            out: Vec::new(),
            inc_start: Vec::new(),
            inc: Vec::new(),
            built_at: Vec::new(),
            wall_start: Vec::new(),
            wall_of: Vec::new(),
            wall_spring: Vec::new(),
            wall_list_at: Vec::new(),
            force: Vec::new(),
            torque: Vec::new(),
            wall_power: Vec::new(),
            last_dissipation: 0.0,
            ready: false,
            parallel_threshold: 20_000,
            periodic: None,
            built_box: V3::zeros(),
        })
    }

    /// Candidate pairs of the current neighbour list (sorted).
    pub fn neighbour_pairs(&self) -> &[(u32, u32)] {
        &self.pairs
    }

    /// Pairs currently in contact (overlap > 0) at the last force evaluation.
    pub fn contacts(&self) -> Vec<(u32, u32)> {
        self.pairs.iter().zip(&self.touching).filter(|(_, t)| **t).map(|(p, _)| *p).collect()
    }

    /// Particle–particle contacts at the last force evaluation with their normal force [N]
    /// (positive repulsive) and the law's state, in pair order.
    pub fn contact_states(&self) -> Vec<((u32, u32), f64, M::State)> {
        self.pairs
            .iter()
            .zip(&self.out)
            .zip(&self.slots)
            .zip(&self.touching)
            .filter(|(_, t)| **t)
            .map(|(((p, o), s), _)| (*p, o.normal_force, s.state))
            .collect()
    }

    /// Forces on the particles at the last evaluation [N] (gravity included).
    pub fn forces(&self) -> &[V3] {
        &self.force
    }

    /// Marks the neighbour list stale (after the caller moved particles or changed their number).
    pub fn invalidate(&mut self) {
        self.ready = false;
    }

    fn parallel(&self) -> bool {
        self.pairs.len() > self.parallel_threshold
    }

    /// Prepares forces and energies at the current state (called by the first [`Self::step`]).
    pub fn initialise(&mut self, p: &mut Particles) -> Result<(), Error> {
        check_particles(p)?;
        self.rebuild(p);
        self.ready = true;
        let (el, d) = self.contact_sweep(p);
        let s = self.particle_sweep(p, false);
        self.last_dissipation = d + s.dissipation;
        self.energy.kinetic = s.kinetic;
        self.energy.potential = s.potential;
        self.energy.elastic = el + s.elastic;
        Ok(())
    }

    /// Advances one velocity-Verlet step.
    pub fn step(&mut self, p: &mut Particles) -> Result<(), Error> {
        if !self.ready || self.force.len() != p.len() {
            self.initialise(p)?;
        }
        let dt = self.settings.dt;
        let h = 0.5 * dt;
        let diss_old: f64 = self.last_dissipation;
        let wall_power_old: f64 = self.wall_power.iter().sum();
        // half kick + drift
        let stale = self.kick_drift(p);
        walls::drift(&mut self.walls, dt, h);
        if stale {
            self.rebuild(p);
            self.ready = true;
        } else if self.walls_moved() {
            self.rebuild_wall_list(p);
        }
        let (el_c, diss_c) = self.contact_sweep(p);
        let s = self.particle_sweep(p, true);
        let (el, diss_new, ke) = (el_c + s.elastic, diss_c + s.dissipation, s.kinetic);
        walls::second_kick(&mut self.walls, h);
        let wall_power_new: f64 = self.wall_power.iter().sum();
        self.energy.kinetic = ke;
        self.energy.potential = s.potential;
        self.energy.elastic = el;
        self.energy.dissipated += h * (diss_old + diss_new);
        self.energy.wall_work += h * (wall_power_old + wall_power_new);
        self.last_dissipation = diss_new;
        self.time += dt;
        self.counters.steps += 1;
        if !ke.is_finite() || !el.is_finite() {
            return Err(SolveError::new(
                "explicit step",
                format!("non-finite energy at t = {:.6e} s (kinetic {ke}, elastic {el}); reduce the time step", self.time),
            )
            .into());
        }
        Ok(())
    }

    /// Runs `steps` steps.
    pub fn run(&mut self, p: &mut Particles, steps: u64) -> Result<(), Error> {
        for _ in 0..steps {
            self.step(p)?;
        }
        Ok(())
    }
}

/// Coulomb-limited tangential spring (module docs). Returns (force on i, stored energy,
/// dissipated power).
#[inline]
pub(crate) fn tangential(xi: &mut V3, n: &V3, vt: &V3, no: &NormalOut, mu: f64, alpha: f64, beta: f64, dt: f64) -> (V3, f64, f64) {
    if mu == 0.0 {
        *xi = V3::zeros();
        return (V3::zeros(), 0.0, 0.0);
    }
    let kt = alpha * no.stiffness;
    let gt = beta * no.damping;
    *xi -= n * n.dot(xi);
    let trial = -kt * *xi - gt * vt;
    let fc = mu * no.force.max(0.0);
    let tn = trial.norm();
    if tn <= fc {
        let diss = gt * vt.norm_squared();
        *xi += vt * dt;
        let e = 0.5 * kt * xi.norm_squared();
        (trial, e, diss)
    } else {
        let ft = if tn > 0.0 { trial * (fc / tn) } else { V3::zeros() };
        *xi = if kt > 0.0 { -(ft + gt * vt) / kt } else { V3::zeros() };
        let diss = -ft.dot(vt);
        (ft, 0.5 * kt * xi.norm_squared(), diss.max(0.0))
    }
}

fn check_particles(p: &Particles) -> Result<(), Error> {
    for a in 0..p.len() {
        if !(p.radius[a] > 0.0 && p.mass[a] > 0.0 && p.inertia[a] > 0.0) || !p.position[a].iter().all(|x| x.is_finite()) {
            return Err(ConfigError::invalid(format!(
                "explicit: particle {a} needs a finite position and positive radius, mass and inertia (r = {} m, m = {} kg)",
                p.radius[a], p.mass[a]
            ))
            .into());
        }
    }
    Ok(())
}

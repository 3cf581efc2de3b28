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
//! Energy ([`Energy`]): kinetic (translation + rotation), elastic (normal and tangential springs),
//! gravitational potential, dissipated (viscous normal and tangential, Coulomb sliding, Cundall local
//! damping) and the work done by the walls on the particles. Their balance
//! `E_kin + E_el + E_pot + E_diss − W_wall` is constant up to the integrator's error.

pub mod law;
pub mod sinter;

use crate::contacts::detect::touching_pairs;
use crate::error::{ConfigError, Error, SolveError};
use crate::particles::Particles;
use law::{ContactCtx, ContactModel, NormalOut, PairGeom, TangentialParams};
use nalgebra::Vector3;
use rayon::prelude::*;
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

/// How a wall moves along its normal.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum WallControl {
    /// Does not move.
    Fixed,
    /// Moves with a prescribed normal velocity [m/s] (`Wall::velocity`, which a caller may change
    /// between steps, e.g. from a servo).
    Velocity,
    /// Moves towards `target` [m] (plane offset) at `speed` [m/s], then holds.
    Position { target: f64, speed: f64 },
    /// A body of mass `mass` [kg] pushed into the domain by `pressure` [Pa] over `Wall::area`,
    /// with viscous damping `damping` [kg/s]: `m_w s̈ = p A − F_w − γ_w ṡ` (Luding 2005 eq. 1),
    /// F_w the particles' normal force on it.
    Stress { pressure: f64, mass: f64, damping: f64 },
}

/// An infinite plane `n·x = offset`, particles on the side `n·x > offset`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Wall {
    /// Unit normal pointing into the domain [1].
    #[serde(with = "crate::io::serde_v3")]
    pub normal: V3,
    /// Plane offset along the normal [m].
    pub offset: f64,
    /// Normal velocity ṡ [m/s] (> 0 moves into the domain).
    pub velocity: f64,
    pub control: WallControl,
    /// Area over which a stress-controlled wall's pressure acts [m²].
    pub area: f64,
    /// Normal force the particles exert on the wall at the last force evaluation [N] (> 0 compressive).
    pub force: f64,
}

impl Wall {
    /// A fixed wall through `point` with inward normal `normal` (normalised here).
    pub fn new(normal: V3, point: V3) -> Self {
        let n = normal.normalize();
        Wall { normal: n, offset: n.dot(&point), velocity: 0.0, control: WallControl::Fixed, area: 1.0, force: 0.0 }
    }
    /// Mean normal stress on the wall, `force/area` [Pa].
    pub fn pressure(&self) -> f64 {
        self.force / self.area
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

/// Sums of one chunk of the per-particle sweep.
#[derive(Debug, Clone, Default)]
struct ParticleSums {
    elastic: f64,
    dissipation: f64,
    kinetic: f64,
    potential: f64,
    /// Normal force of the chunk's particles on each wall [N].
    wall_force: Vec<f64>,
}

/// The mutable per-particle slices of one chunk of the particle sweep.
struct ParticleChunk<'a> {
    first: usize,
    force: &'a mut [V3],
    torque: &'a mut [V3],
    velocity: &'a mut [V3],
    angular_velocity: &'a mut [V3],
    /// Tangential springs of the chunk's particle–wall candidates.
    wall_spring: &'a mut [V3],
}

/// The driver's complete state between two steps (checkpoints of `explicit_sinter` runs): with
/// it, [`Explicit::restore_state`] continues bit for bit as if never stopped. Everything is kept,
/// caches included (neighbour list, incidence, last forces), because the summation order of the
/// sweeps follows them.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DriverState<S> {
    pub time: f64,
    pub energy: Energy,
    pub counters: Counters,
    pub walls: Vec<Wall>,
    pairs: Vec<(u32, u32)>,
    slots: Vec<Slot<S>>,
    touching: Vec<bool>,
    out: Vec<Out>,
    inc_start: Vec<u32>,
    inc: Vec<(u32, bool)>,
    #[serde(with = "crate::io::serde_v3::vec")]
    built_at: Vec<V3>,
    wall_start: Vec<u32>,
    wall_of: Vec<u32>,
    #[serde(with = "crate::io::serde_v3::vec")]
    wall_spring: Vec<V3>,
    wall_list_at: Vec<f64>,
    #[serde(with = "crate::io::serde_v3::vec")]
    force: Vec<V3>,
    #[serde(with = "crate::io::serde_v3::vec")]
    torque: Vec<V3>,
    wall_power: Vec<f64>,
    last_dissipation: f64,
    ready: bool,
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

    /// The complete state for a checkpoint ([`DriverState`]).
    pub fn save_state(&self) -> DriverState<M::State> {
        DriverState {
            time: self.time,
            energy: self.energy,
            counters: self.counters,
            walls: self.walls.clone(),
            pairs: self.pairs.clone(),
            slots: self.slots.clone(),
            touching: self.touching.clone(),
            out: self.out.clone(),
            inc_start: self.inc_start.clone(),
            inc: self.inc.clone(),
            built_at: self.built_at.clone(),
            wall_start: self.wall_start.clone(),
            wall_of: self.wall_of.clone(),
            wall_spring: self.wall_spring.clone(),
            wall_list_at: self.wall_list_at.clone(),
            force: self.force.clone(),
            torque: self.torque.clone(),
            wall_power: self.wall_power.clone(),
            last_dissipation: self.last_dissipation,
            ready: self.ready,
        }
    }

    /// Restores a [`DriverState`] saved from a driver of the same law and settings over `n`
    /// particles, after checking that it is consistent (lengths, indices, finite values); the
    /// error names what is wrong.
    pub fn restore_state(&mut self, s: DriverState<M::State>, n: usize) -> Result<(), String> {
        let np = s.pairs.len();
        let nw = s.walls.len();
        let len = |what: &str, got: usize, want: &[usize]| -> Result<(), String> {
            if want.contains(&got) {
                Ok(())
            } else {
                Err(format!("{what}: {got} entries, expected {}", want.iter().map(|w| w.to_string()).collect::<Vec<_>>().join(" or ")))
            }
        };
        len("walls", nw, &[self.walls.len()])?;
        len("slots", s.slots.len(), &[np])?;
        len("touching", s.touching.len(), &[np])?;
        len("out", s.out.len(), &[np])?;
        len("inc_start", s.inc_start.len(), &[0, n + 1])?;
        len("inc", s.inc.len(), &[0, 2 * np])?;
        len("built_at", s.built_at.len(), &[0, n])?;
        len("wall_start", s.wall_start.len(), &[0, n + 1])?;
        len("wall_spring", s.wall_spring.len(), &[s.wall_of.len()])?;
        len("wall_list_at", s.wall_list_at.len(), &[0, nw])?;
        len("force", s.force.len(), &[0, n])?;
        len("torque", s.torque.len(), &[0, n])?;
        len("wall_power", s.wall_power.len(), &[0, nw])?;
        if let Some(&(i, j)) = s.pairs.iter().find(|&&(i, j)| !(i < j && (j as usize) < n)) {
            return Err(format!("pairs: ({i}, {j}) is not a pair of distinct particles below {n}"));
        }
        if !s.pairs.windows(2).all(|w| w[0] < w[1]) {
            return Err("pairs: not sorted".into());
        }
        if let Some(&(c, _)) = s.inc.iter().find(|&&(c, _)| c as usize >= np) {
            return Err(format!("inc: contact {c} of {np}"));
        }
        let total = |v: &[u32]| v.last().copied().unwrap_or(0) as usize;
        if !s.inc_start.windows(2).all(|w| w[0] <= w[1]) || (!s.inc_start.is_empty() && total(&s.inc_start) != s.inc.len()) {
            return Err("inc_start: not an incidence table of inc".into());
        }
        if !s.wall_start.windows(2).all(|w| w[0] <= w[1]) || (!s.wall_start.is_empty() && total(&s.wall_start) != s.wall_of.len()) {
            return Err("wall_start: not an incidence table of wall_of".into());
        }
        if let Some(w) = s.wall_of.iter().find(|&&w| w as usize >= nw) {
            return Err(format!("wall_of: wall {w} of {nw}"));
        }
        let finite3 = |v: &V3| v.iter().all(|x| x.is_finite());
        let bad_v = [("built_at", &s.built_at), ("wall_spring", &s.wall_spring), ("force", &s.force), ("torque", &s.torque)]
            .into_iter()
            .find(|(_, v)| !v.iter().all(finite3));
        if let Some((what, _)) = bad_v {
            return Err(format!("{what}: non-finite value"));
        }
        if !(s.time.is_finite() && s.time >= 0.0) {
            return Err(format!("time = {} s: expected a finite time >= 0", s.time));
        }
        if !s.walls.iter().all(|w| finite3(&w.normal) && w.offset.is_finite() && w.velocity.is_finite() && w.area > 0.0 && w.force.is_finite()) {
            return Err("walls: non-finite offset, velocity or force, or area <= 0".into());
        }
        if !(s.wall_list_at.iter().chain(&s.wall_power).all(|x| x.is_finite()) && s.last_dissipation.is_finite()) {
            return Err("wall_list_at, wall_power or last_dissipation: non-finite value".into());
        }
        if !s.slots.iter().all(|sl| finite3(&sl.xi)) || !s.out.iter().all(|o| finite3(&o.f) && finite3(&o.nxft) && o.normal_force.is_finite()) {
            return Err("contact slots: non-finite spring or force".into());
        }
        if s.ready && (s.force.len() != n || s.built_at.len() != n || s.inc_start.len() != n + 1) {
            return Err("ready is set without the neighbour list of every particle".into());
        }
        self.time = s.time;
        self.energy = s.energy;
        self.counters = s.counters;
        self.walls = s.walls;
        self.pairs = s.pairs;
        self.slots = s.slots;
        self.touching = s.touching;
        self.out = s.out;
        self.inc_start = s.inc_start;
        self.inc = s.inc;
        self.built_at = s.built_at;
        self.wall_start = s.wall_start;
        self.wall_of = s.wall_of;
        self.wall_spring = s.wall_spring;
        self.wall_list_at = s.wall_list_at;
        self.force = s.force;
        self.torque = s.torque;
        self.wall_power = s.wall_power;
        self.last_dissipation = s.last_dissipation;
        self.ready = s.ready;
        Ok(())
    }

    /// Marks the neighbour list stale (after the caller moved particles or changed their number).
    pub fn invalidate(&mut self) {
        self.ready = false;
    }

    fn parallel(&self) -> bool {
        self.pairs.len() > self.parallel_threshold
    }

    fn rebuild(&mut self, p: &Particles) {
        let new_pairs = touching_pairs(&p.position, &p.radius, self.settings.skin);
        // carry history over by pair (both lists sorted)
        let mut new_slots = vec![Slot::<M::State>::default(); new_pairs.len()];
        let mut new_out = vec![Out::default(); new_pairs.len()];
        let mut new_touching = vec![false; new_pairs.len()];
        let mut k = 0;
        for (a, np) in new_pairs.iter().enumerate() {
            while k < self.pairs.len() && self.pairs[k] < *np {
                k += 1;
            }
            if k < self.pairs.len() && self.pairs[k] == *np {
                new_slots[a] = self.slots[k];
                new_out[a] = self.out[k];
                new_touching[a] = self.touching[k];
            }
        }
        self.pairs = new_pairs;
        self.slots = new_slots;
        self.out = new_out;
        self.touching = new_touching;
        let n = p.len();
        let mut start = vec![0u32; n + 1];
        for &(i, j) in &self.pairs {
            start[i as usize + 1] += 1;
            start[j as usize + 1] += 1;
        }
        for a in 0..n {
            start[a + 1] += start[a];
        }
        let mut fill = start.clone();
        let mut inc = vec![(0u32, false); 2 * self.pairs.len()];
        for (c, &(i, j)) in self.pairs.iter().enumerate() {
            inc[fill[i as usize] as usize] = (c as u32, true);
            fill[i as usize] += 1;
            inc[fill[j as usize] as usize] = (c as u32, false);
            fill[j as usize] += 1;
        }
        self.inc_start = start;
        self.inc = inc;
        self.built_at.clone_from(&p.position);
        self.rebuild_wall_list(p);
        self.counters.rebuilds += 1;
    }

    /// Particle–wall candidates: gap < 1.5 skins. Springs of pairs leaving the list are reset
    /// (they are out of contact: a pair in contact stays within the margin).
    fn rebuild_wall_list(&mut self, p: &Particles) {
        let n = p.len();
        let margin = 1.5 * self.settings.skin;
        let walls = &self.walls;
        let (position, radius) = (&p.position, &p.radius);
        // walls of each particle in ascending order, by fixed chunks of particles
        let body = |c: usize| -> (Vec<u32>, Vec<u32>) {
            let (a0, a1) = (c * PARTICLE_CHUNK, ((c + 1) * PARTICLE_CHUNK).min(n));
            let mut count = Vec::with_capacity(a1 - a0);
            let mut of = Vec::new();
            for a in a0..a1 {
                let before = of.len();
                for (w, wall) in walls.iter().enumerate() {
                    if wall.normal.dot(&position[a]) - wall.offset - radius[a] < margin {
                        of.push(w as u32);
                    }
                }
                count.push((of.len() - before) as u32);
            }
            (count, of)
        };
        let chunks = n.div_ceil(PARTICLE_CHUNK);
        let parts: Vec<(Vec<u32>, Vec<u32>)> = if self.parallel() { (0..chunks).into_par_iter().map(body).collect() } else { (0..chunks).map(body).collect() };
        let mut start = Vec::with_capacity(n + 1);
        start.push(0u32);
        let mut of = Vec::with_capacity(parts.iter().map(|x| x.1.len()).sum());
        for (count, o) in parts {
            for c in count {
                let last = *start.last().unwrap();
                start.push(last + c);
            }
            of.extend(o);
        }
        // carry the springs of kept candidates over
        let mut spring = vec![V3::zeros(); of.len()];
        if self.wall_start.len() == n + 1 {
            for a in 0..n {
                let (o0, o1) = (self.wall_start[a] as usize, self.wall_start[a + 1] as usize);
                if o0 == o1 {
                    continue;
                }
                for q in start[a] as usize..start[a + 1] as usize {
                    if let Some(k) = self.wall_of[o0..o1].iter().position(|&w| w == of[q]) {
                        spring[q] = self.wall_spring[o0 + k];
                    }
                }
            }
        }
        self.wall_start = start;
        self.wall_of = of;
        self.wall_spring = spring;
        self.wall_list_at = self.walls.iter().map(|w| w.offset).collect();
    }

    fn walls_moved(&self) -> bool {
        let half = 0.5 * self.settings.skin;
        self.wall_list_at.len() != self.walls.len() || self.walls.iter().zip(&self.wall_list_at).any(|(w, &o)| (w.offset - o).abs() >= half)
    }

    /// First half kick and drift (steps 1–2 of the module docs); returns whether the neighbour list
    /// must be rebuilt (a particle moved half a skin since the last build, or the list is stale).
    fn kick_drift(&mut self, p: &mut Particles) -> bool {
        let dt = self.settings.dt;
        let h = 0.5 * dt;
        let rot = self.settings.rotation;
        let half = 0.5 * self.settings.skin;
        let h2 = half * half;
        let check = self.ready && self.built_at.len() == p.len();
        let par = self.parallel();
        let (force, torque, built) = (&self.force, &self.torque, &self.built_at);
        let Particles { position, velocity, angular_velocity, rotation, mass, inertia, .. } = p;
        let (mass, inertia) = (&*mass, &*inertia);
        type Chunk<'a> = (usize, (((&'a mut [V3], &'a mut [V3]), &'a mut [V3]), &'a mut [V3]));
        let body = |(c, (((x, v), w), th)): Chunk| -> bool {
            let a0 = c * PARTICLE_CHUNK;
            let mut moved = false;
            for k in 0..x.len() {
                let a = a0 + k;
                v[k] += force[a] * (h / mass[a]);
                x[k] += v[k] * dt;
                if rot {
                    w[k] += torque[a] * (h / inertia[a]);
                    th[k] += w[k] * dt;
                }
                if check && (x[k] - built[a]).norm_squared() >= h2 {
                    moved = true;
                }
            }
            moved
        };
        const C: usize = PARTICLE_CHUNK;
        #[allow(clippy::unnecessary_fold)]
        let moved = if par {
            position
                .par_chunks_mut(C)
                .zip(velocity.par_chunks_mut(C))
                .zip(angular_velocity.par_chunks_mut(C))
                .zip(rotation.par_chunks_mut(C))
                .enumerate()
                .map(body)
                .reduce(|| false, |a, b| a || b)
        } else {
            position
                .chunks_mut(C)
                .zip(velocity.chunks_mut(C))
                .zip(angular_velocity.chunks_mut(C))
                .zip(rotation.chunks_mut(C))
                .enumerate()
                .map(body)
                // not `any`: it would stop early and skip the remaining chunks' drift
                .fold(false, |a, b| a || b)
        };
        !check || moved
    }

    /// Contact forces at the current positions (one slot per neighbour pair); returns (elastic
    /// energy, dissipated power) of the particle–particle contacts.
    fn contact_sweep(&mut self, p: &Particles) -> (f64, f64) {
        let st = &self.settings;
        let law = &self.law;
        let dt = st.dt;
        let rot = st.rotation;
        let pairs = &self.pairs;
        let par = self.pairs.len() > self.parallel_threshold;
        let tan = TangentialParams { friction: st.friction, stiffness_ratio: st.tangential_stiffness_ratio, damping_ratio: st.tangential_damping_ratio, dt };
        let kernel = |c: usize, slot: &mut Slot<M::State>, out: &mut Out, touching: &mut bool| -> (f64, f64) {
            let (i, j) = (pairs[c].0 as usize, pairs[c].1 as usize);
            let d = p.position[i] - p.position[j];
            let dist2 = d.norm_squared();
            let reach = p.radius[i] + p.radius[j];
            if dist2 >= reach * reach || dist2 == 0.0 {
                // the slot of a pair out of contact is clear already (rebuilds carry the flag over
                // with the spring): write only on separation, to spare the memory traffic
                if *touching {
                    *touching = false;
                    slot.xi = V3::zeros();
                }
                return (0.0, 0.0);
            }
            let dist = dist2.sqrt();
            let overlap = reach - dist;
            if overlap <= 0.0 {
                *touching = false;
                slot.xi = V3::zeros();
                return (0.0, 0.0);
            }
            let nrm = d / dist;
            let (wi, wj) = if rot { (p.angular_velocity[i], p.angular_velocity[j]) } else { (V3::zeros(), V3::zeros()) };
            let vij = p.velocity[i] - p.velocity[j] + p.radius[i] * nrm.cross(&wi) + p.radius[j] * nrm.cross(&wj);
            let vn = vij.dot(&nrm);
            let g = PairGeom {
                overlap,
                overlap_rate: -vn,
                mass: p.mass[i] * p.mass[j] / (p.mass[i] + p.mass[j]),
                radius: p.radius[i] * p.radius[j] / (p.radius[i] + p.radius[j]),
            };
            let vt = vij - nrm * vn;
            let ctx = ContactCtx {
                geom: g,
                normal: nrm,
                surface_velocity: vij,
                tangential_velocity: vt,
                radius_i: p.radius[i],
                radius_j: p.radius[j],
                temperature_i: p.temperature.get(i).copied().unwrap_or(0.0),
                temperature_j: p.temperature.get(j).copied().unwrap_or(0.0),
            };
            let co = law.contact(&ctx, &mut slot.state, &mut slot.xi, &tan);
            *out = Out { f: nrm * co.normal_force + co.tangential, nxft: nrm.cross(&co.tangential), normal_force: co.normal_force };
            *touching = true;
            (co.elastic_energy, co.dissipation)
        };
        type Chunk<'a, S> = (usize, ((&'a mut [Slot<S>], &'a mut [Out]), &'a mut [bool]));
        let body = |(c, ((slots, outs), touching)): Chunk<M::State>| -> (f64, f64) {
            let c0 = c * CONTACT_CHUNK;
            let (mut el, mut di) = (0.0, 0.0);
            for (k, ((s, o), t)) in slots.iter_mut().zip(outs.iter_mut()).zip(touching.iter_mut()).enumerate() {
                let (e, d) = kernel(c0 + k, s, o, t);
                el += e;
                di += d;
            }
            (el, di)
        };
        let sums: Vec<(f64, f64)> = if par {
            self.slots
                .par_chunks_mut(CONTACT_CHUNK)
                .zip(self.out.par_chunks_mut(CONTACT_CHUNK))
                .zip(self.touching.par_chunks_mut(CONTACT_CHUNK))
                .enumerate()
                .map(body)
                .collect()
        } else {
            self.slots
                .chunks_mut(CONTACT_CHUNK)
                .zip(self.out.chunks_mut(CONTACT_CHUNK))
                .zip(self.touching.chunks_mut(CONTACT_CHUNK))
                .enumerate()
                .map(body)
                .collect()
        };
        sums.iter().fold((0.0, 0.0), |(a, b), (e, d)| (a + e, b + d))
    }

    /// Per particle, in a fixed order: gravity, the contact forces through the incidence table,
    /// the wall contacts (walls in ascending order), Cundall's local damping; then, if `kick`, the
    /// second half kick (step 5); sums the kinetic and potential energy after it. Sets the walls'
    /// forces and powers.
    fn particle_sweep(&mut self, p: &mut Particles, kick: bool) -> ParticleSums {
        let n = p.len();
        let nw = self.walls.len();
        let par = self.parallel();
        let st = &self.settings;
        let (dt, rot, g, lam, visc) = (st.dt, st.rotation, st.gravity, st.local_damping, st.viscous_damping);
        let h = 0.5 * dt;
        let (muw, alpha, beta) = (st.wall_friction, st.tangential_stiffness_ratio, st.tangential_damping_ratio);
        let law = &self.law;
        let walls = &self.walls;
        let (out, touching, inc, inc_start) = (&self.out, &self.touching, &self.inc, &self.inc_start);
        let (wall_start, wall_of) = (&self.wall_start, &self.wall_of);
        self.force.resize(n, V3::zeros());
        self.torque.resize(n, V3::zeros());
        let Particles { position, velocity, angular_velocity, radius, mass, inertia, .. } = p;
        let (position, radius, mass, inertia) = (&*position, &*radius, &*mass, &*inertia);
        // the chunks' mutable slices (wall springs: the candidates of the chunk's particles)
        let mut chunks = Vec::with_capacity(n.div_ceil(PARTICLE_CHUNK));
        let mut rest: &mut [V3] = &mut self.wall_spring[..];
        for (c, (((f, t), v), w)) in self
            .force
            .chunks_mut(PARTICLE_CHUNK)
            .zip(self.torque.chunks_mut(PARTICLE_CHUNK))
            .zip(velocity.chunks_mut(PARTICLE_CHUNK))
            .zip(angular_velocity.chunks_mut(PARTICLE_CHUNK))
            .enumerate()
        {
            let a0 = c * PARTICLE_CHUNK;
            let len = (wall_start[a0 + f.len()] - wall_start[a0]) as usize;
            let (head, tail) = std::mem::take(&mut rest).split_at_mut(len);
            rest = tail;
            chunks.push(ParticleChunk { first: a0, force: f, torque: t, velocity: v, angular_velocity: w, wall_spring: head });
        }
        let body = |ch: ParticleChunk| -> ParticleSums {
            let mut s = ParticleSums { wall_force: vec![0.0; nw], ..Default::default() };
            let q0 = wall_start[ch.first] as usize;
            for k in 0..ch.force.len() {
                let a = ch.first + k;
                let mut fa = mass[a] * g;
                let mut ta = V3::zeros();
                for &(c, is_i) in &inc[inc_start[a] as usize..inc_start[a + 1] as usize] {
                    if !touching[c as usize] {
                        continue;
                    }
                    let o = &out[c as usize];
                    if is_i {
                        fa += o.f;
                    } else {
                        fa -= o.f;
                    }
                    ta -= radius[a] * o.nxft;
                }
                let va = ch.velocity[k];
                let wa = if rot { ch.angular_velocity[k] } else { V3::zeros() };
                for q in wall_start[a] as usize..wall_start[a + 1] as usize {
                    let w = wall_of[q] as usize;
                    let wall = &walls[w];
                    let xi = &mut ch.wall_spring[q - q0];
                    let gap = wall.normal.dot(&position[a]) - wall.offset - radius[a];
                    if gap >= 0.0 {
                        *xi = V3::zeros();
                        continue;
                    }
                    let nrm = wall.normal;
                    let vij = va - nrm * wall.velocity + radius[a] * nrm.cross(&wa);
                    let vn = vij.dot(&nrm);
                    let gm = PairGeom { overlap: -gap, overlap_rate: -vn, mass: mass[a], radius: radius[a] };
                    let mut state = M::State::default();
                    let no = law.normal(&gm, &mut state);
                    let vt = vij - nrm * vn;
                    let (ft, el_t, diss_t) = tangential(xi, &nrm, &vt, &no, muw, alpha, beta, dt);
                    fa += nrm * no.force + ft;
                    ta -= radius[a] * nrm.cross(&ft);
                    s.elastic += no.elastic_energy + el_t;
                    s.dissipation += no.damping_force * gm.overlap_rate + diss_t;
                    s.wall_force[w] += no.force;
                }
                // Cundall local damping
                if lam > 0.0 {
                    for d in 0..3 {
                        let v = va[d];
                        let dmp = lam * fa[d].abs() * v.signum() * if v == 0.0 { 0.0 } else { 1.0 };
                        fa[d] -= dmp;
                        s.dissipation += dmp * v;
                    }
                    if rot {
                        for d in 0..3 {
                            let w = wa[d];
                            let dmp = lam * ta[d].abs() * w.signum() * if w == 0.0 { 0.0 } else { 1.0 };
                            ta[d] -= dmp;
                            s.dissipation += dmp * w;
                        }
                    }
                }
                if visc > 0.0 {
                    fa -= visc * mass[a] * va;
                    s.dissipation += visc * mass[a] * va.norm_squared();
                    if rot {
                        ta -= visc * inertia[a] * wa;
                        s.dissipation += visc * inertia[a] * wa.norm_squared();
                    }
                }
                ch.force[k] = fa;
                ch.torque[k] = ta;
                if kick {
                    ch.velocity[k] += fa * (h / mass[a]);
                    if rot {
                        ch.angular_velocity[k] += ta * (h / inertia[a]);
                    }
                }
                s.kinetic += 0.5 * mass[a] * ch.velocity[k].norm_squared();
                if rot {
                    s.kinetic += 0.5 * inertia[a] * ch.angular_velocity[k].norm_squared();
                }
                s.potential -= mass[a] * g.dot(&position[a]);
            }
            s
        };
        let parts: Vec<ParticleSums> = if par { chunks.into_par_iter().map(body).collect() } else { chunks.into_iter().map(body).collect() };
        let mut total = ParticleSums { wall_force: vec![0.0; nw], ..Default::default() };
        for s in &parts {
            total.elastic += s.elastic;
            total.dissipation += s.dissipation;
            total.kinetic += s.kinetic;
            total.potential += s.potential;
            for (a, b) in total.wall_force.iter_mut().zip(&s.wall_force) {
                *a += b;
            }
        }
        self.wall_power.resize(nw, 0.0);
        for ((wall, pw), &f) in self.walls.iter_mut().zip(self.wall_power.iter_mut()).zip(&total.wall_force) {
            wall.force = f;
            *pw = f * wall.velocity;
        }
        total
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
        for w in self.walls.iter_mut() {
            match w.control {
                WallControl::Fixed => w.velocity = 0.0,
                WallControl::Velocity => w.offset += w.velocity * dt,
                WallControl::Position { target, speed } => {
                    let rest = target - w.offset;
                    let step = speed.abs() * dt;
                    if rest.abs() <= step {
                        w.velocity = rest / dt;
                        w.offset = target;
                    } else {
                        w.velocity = speed.abs() * rest.signum();
                        w.offset += w.velocity * dt;
                    }
                }
                WallControl::Stress { pressure, mass, damping } => {
                    let acc = (pressure * w.area - w.force - damping * w.velocity) / mass;
                    w.velocity += h * acc;
                    w.offset += w.velocity * dt;
                }
            }
        }
        if stale {
            self.rebuild(p);
            self.ready = true;
        } else if self.walls_moved() {
            self.rebuild_wall_list(p);
        }
        let (el_c, diss_c) = self.contact_sweep(p);
        let s = self.particle_sweep(p, true);
        let (el, diss_new, ke) = (el_c + s.elastic, diss_c + s.dissipation, s.kinetic);
        for w in self.walls.iter_mut() {
            if let WallControl::Stress { pressure, mass, damping } = w.control {
                // semi-implicit in the damping term for the second half kick
                let v = (w.velocity + h * (pressure * w.area - w.force) / mass) / (1.0 + h * damping / mass);
                w.velocity = v;
            }
        }
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

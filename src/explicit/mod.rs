//! The explicit DEM driver: velocity Verlet for translations and rotations of spheres with
//! elastic-viscous normal contacts, a Coulomb-limited tangential spring, planar walls and gravity
//! (architecture map, "The explicit-DEM laws ... run in a separate velocity-Verlet driver").
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
//! Tangential law (Luding 2005 eqs. 16–22, `explicit-sintering-laws.md` §1): the spring ξ is
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
pub mod protocol;
pub mod sinter;

use crate::contacts::detect::touching_pairs;
use crate::error::{ConfigError, Error, SolveError};
use crate::particles::Particles;
use law::{ContactCtx, ContactModel, NormalOut, PairGeom, TangentialParams};
use nalgebra::Vector3;
use rayon::prelude::*;

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
#[derive(Debug, Clone, Copy, PartialEq)]
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
#[derive(Debug, Clone, PartialEq)]
pub struct Wall {
    /// Unit normal pointing into the domain [1].
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
#[derive(Debug, Clone, Copy, Default, PartialEq)]
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

/// Per-contact history carried across neighbour-list rebuilds.
#[derive(Debug, Clone, Copy, Default)]
struct Slot<S> {
    /// Tangential spring ξ [m].
    xi: V3,
    state: S,
}

/// Per-contact result of the force sweep.
#[derive(Debug, Clone, Copy, Default)]
struct Out {
    /// Force on particle i [N] (on j: −f).
    f: V3,
    /// n × f_t [N]; torque on i is `−r_i n×f_t`, on j `−r_j n×f_t`.
    nxft: V3,
    elastic: f64,
    /// Power dissipated in this contact [W].
    dissipation: f64,
    /// Normal force on i along +n [N] (positive repulsive).
    normal_force: f64,
    in_contact: bool,
}

/// Counters of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
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
    out: Vec<Out>,
    /// CSR incidence particle → (contact, is_i).
    inc_start: Vec<u32>,
    inc: Vec<(u32, bool)>,
    /// Positions and wall offsets at the last neighbour build.
    built_at: Vec<V3>,
    wall_built_at: Vec<f64>,
    /// Tangential springs of particle–wall contacts, `[particle * walls + wall]`.
    wall_xi: Vec<V3>,
    /// Particle–wall candidates `(wall, particle)`, sorted: gap below 1.5 skins at the last build
    /// (particles move < skin since then and walls < skin/2 before a rebuild, so no contact is missed).
    wall_list: Vec<(u32, u32)>,
    /// Wall offsets at the last wall-list build.
    wall_list_at: Vec<f64>,
    force: Vec<V3>,
    torque: Vec<V3>,
    wall_power: Vec<f64>,
    last_dissipation: f64,
    ready: bool,
    /// Use rayon when the contact count exceeds this.
    pub parallel_threshold: usize,
}

impl<M: ContactModel> Explicit<M> {
    pub fn new(settings: Settings, law: M, walls: Vec<Wall>) -> Result<Self, Error> {
        settings.validate()?;
        for (k, w) in walls.iter().enumerate() {
            if !(w.normal.iter().all(|x| x.is_finite()) && (w.normal.norm() - 1.0).abs() < 1e-9 && w.offset.is_finite()) {
                return Err(ConfigError::inconsistent(format!("walls.{k}"), "normal must be a finite unit vector and offset finite").into());
            }
            if let WallControl::Stress { mass, damping, pressure } = w.control {
                if !(mass > 0.0 && damping >= 0.0 && pressure.is_finite() && w.area > 0.0) {
                    return Err(ConfigError::inconsistent(format!("walls.{k}"), "stress control needs mass > 0, damping >= 0, finite pressure, area > 0").into());
                }
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
            out: Vec::new(),
            inc_start: Vec::new(),
            inc: Vec::new(),
            built_at: Vec::new(),
            wall_built_at: Vec::new(),
            wall_xi: Vec::new(),
            wall_list: Vec::new(),
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
        self.pairs.iter().zip(&self.out).filter(|(_, o)| o.in_contact).map(|(p, _)| *p).collect()
    }

    /// Particle–particle contacts at the last force evaluation with their normal force [N]
    /// (positive repulsive) and the law's state, in pair order.
    pub fn contact_states(&self) -> Vec<((u32, u32), f64, M::State)> {
        self.pairs
            .iter()
            .zip(&self.out)
            .zip(&self.slots)
            .filter(|((_, o), _)| o.in_contact)
            .map(|((p, o), s)| (*p, o.normal_force, s.state))
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

    fn rebuild(&mut self, p: &Particles) {
        let new_pairs = touching_pairs(&p.position, &p.radius, self.settings.skin);
        // carry history over by pair (both lists sorted)
        let mut new_slots = vec![Slot::<M::State>::default(); new_pairs.len()];
        let mut k = 0;
        for (a, np) in new_pairs.iter().enumerate() {
            while k < self.pairs.len() && self.pairs[k] < *np {
                k += 1;
            }
            if k < self.pairs.len() && self.pairs[k] == *np {
                new_slots[a] = self.slots[k];
            }
        }
        self.pairs = new_pairs;
        self.slots = new_slots;
        self.out = vec![Out::default(); self.pairs.len()];
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
        self.built_at = p.position.clone();
        self.wall_built_at = self.walls.iter().map(|w| w.offset).collect();
        self.rebuild_wall_list(p);
        self.counters.rebuilds += 1;
    }

    /// Particle–wall candidates: gap < 1.5 skins. Springs of pairs leaving the list are reset
    /// (they are out of contact: a pair in contact stays within the margin).
    fn rebuild_wall_list(&mut self, p: &Particles) {
        let nw = self.walls.len();
        if self.wall_xi.len() != p.len() * nw {
            self.wall_xi = vec![V3::zeros(); p.len() * nw];
            self.wall_list.clear();
        }
        let margin = 1.5 * self.settings.skin;
        let mut list = Vec::with_capacity(self.wall_list.len());
        for (w, wall) in self.walls.iter().enumerate() {
            for a in 0..p.len() {
                if wall.normal.dot(&p.position[a]) - wall.offset - p.radius[a] < margin {
                    list.push((w as u32, a as u32));
                }
            }
        }
        // reset the springs of dropped candidates (both lists sorted)
        let mut k = 0;
        for &(w, a) in &self.wall_list {
            while k < list.len() && list[k] < (w, a) {
                k += 1;
            }
            if k >= list.len() || list[k] != (w, a) {
                self.wall_xi[a as usize * nw + w as usize] = V3::zeros();
            }
        }
        self.wall_list = list;
        self.wall_list_at = self.walls.iter().map(|w| w.offset).collect();
    }

    fn walls_moved(&self) -> bool {
        let half = 0.5 * self.settings.skin;
        self.wall_list_at.len() != self.walls.len() || self.walls.iter().zip(&self.wall_list_at).any(|(w, &o)| (w.offset - o).abs() >= half)
    }

    fn needs_rebuild(&self, p: &Particles) -> bool {
        if !self.ready || self.built_at.len() != p.len() {
            return true;
        }
        let half = 0.5 * self.settings.skin;
        let h2 = half * half;
        if self.built_at.iter().zip(&p.position).any(|(a, b)| (a - b).norm_squared() >= h2) {
            return true;
        }
        false
    }

    /// Contact forces at the current positions; gathers onto particles and walls; returns
    /// (elastic energy, dissipated power).
    fn compute_forces(&mut self, p: &Particles) -> (f64, f64) {
        let n = p.len();
        let st = &self.settings;
        let law = &self.law;
        let dt = st.dt;
        let (mu, alpha, beta) = (st.friction, st.tangential_stiffness_ratio, st.tangential_damping_ratio);
        let rot = st.rotation;
        let pairs = &self.pairs;
        let tan = TangentialParams { friction: mu, stiffness_ratio: alpha, damping_ratio: beta, dt };
        let kernel = |(c, (slot, out)): (usize, (&mut Slot<M::State>, &mut Out))| {
            let (i, j) = (pairs[c].0 as usize, pairs[c].1 as usize);
            let d = p.position[i] - p.position[j];
            let dist = d.norm();
            let overlap = p.radius[i] + p.radius[j] - dist;
            if overlap <= 0.0 || dist == 0.0 {
                *out = Out::default();
                slot.xi = V3::zeros();
                return;
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
            *out = Out {
                f: nrm * co.normal_force + co.tangential,
                nxft: nrm.cross(&co.tangential),
                elastic: co.elastic_energy,
                dissipation: co.dissipation,
                normal_force: co.normal_force,
                in_contact: true,
            };
        };
        if self.pairs.len() > self.parallel_threshold {
            self.slots.par_iter_mut().zip(self.out.par_iter_mut()).enumerate().for_each(kernel);
        } else {
            self.slots.iter_mut().zip(self.out.iter_mut()).enumerate().for_each(kernel);
        }
        // gather onto particles in a fixed order
        let out = &self.out;
        let inc = &self.inc;
        let inc_start = &self.inc_start;
        let g = st.gravity;
        let gather = |(a, (f, t)): (usize, (&mut V3, &mut V3))| {
            let mut fa = p.mass[a] * g;
            let mut ta = V3::zeros();
            for &(c, is_i) in &inc[inc_start[a] as usize..inc_start[a + 1] as usize] {
                let o = &out[c as usize];
                if is_i {
                    fa += o.f;
                } else {
                    fa -= o.f;
                }
                ta -= p.radius[a] * o.nxft;
            }
            *f = fa;
            *t = ta;
        };
        self.force.resize(n, V3::zeros());
        self.torque.resize(n, V3::zeros());
        if self.pairs.len() > self.parallel_threshold {
            self.force.par_iter_mut().zip(self.torque.par_iter_mut()).enumerate().for_each(gather);
        } else {
            self.force.iter_mut().zip(self.torque.iter_mut()).enumerate().for_each(gather);
        }
        let mut elastic: f64 = self.out.iter().map(|o| o.elastic).sum();
        let mut dissipation: f64 = self.out.iter().map(|o| o.dissipation).sum();
        // walls (sequential over particles, fixed order)
        let nw = self.walls.len();
        self.wall_power.resize(nw, 0.0);
        let muw = st.wall_friction;
        let mut fw = vec![0.0; nw];
        self.wall_power.iter_mut().for_each(|x| *x = 0.0);
        for &(w, a) in &self.wall_list {
            let (w, a) = (w as usize, a as usize);
            let wall = &self.walls[w];
            let gap = wall.normal.dot(&p.position[a]) - wall.offset - p.radius[a];
            let xi = &mut self.wall_xi[a * nw + w];
            if gap >= 0.0 {
                *xi = V3::zeros();
                continue;
            }
            let nrm = wall.normal;
            let wa = if rot { p.angular_velocity[a] } else { V3::zeros() };
            let vij = p.velocity[a] - nrm * wall.velocity + p.radius[a] * nrm.cross(&wa);
            let vn = vij.dot(&nrm);
            let g = PairGeom { overlap: -gap, overlap_rate: -vn, mass: p.mass[a], radius: p.radius[a] };
            let mut s = M::State::default();
            let no = self.law.normal(&g, &mut s);
            let vt = vij - nrm * vn;
            let (ft, el_t, diss_t) = tangential(xi, &nrm, &vt, &no, muw, alpha, beta, dt);
            self.force[a] += nrm * no.force + ft;
            self.torque[a] -= p.radius[a] * nrm.cross(&ft);
            elastic += no.elastic_energy + el_t;
            dissipation += no.damping_force * g.overlap_rate + diss_t;
            fw[w] += no.force;
            self.wall_power[w] += no.force * wall.velocity;
        }
        for (wall, f) in self.walls.iter_mut().zip(fw) {
            wall.force = f;
        }
        // Cundall local damping
        let lam = st.local_damping;
        if lam > 0.0 {
            for a in 0..n {
                for k in 0..3 {
                    let v = p.velocity[a][k];
                    let fk = self.force[a][k];
                    let dmp = lam * fk.abs() * v.signum() * if v == 0.0 { 0.0 } else { 1.0 };
                    self.force[a][k] -= dmp;
                    dissipation += dmp * v;
                }
                if rot {
                    for k in 0..3 {
                        let w = p.angular_velocity[a][k];
                        let tk = self.torque[a][k];
                        let dmp = lam * tk.abs() * w.signum() * if w == 0.0 { 0.0 } else { 1.0 };
                        self.torque[a][k] -= dmp;
                        dissipation += dmp * w;
                    }
                }
            }
        }
        (elastic, dissipation)
    }

    fn kinetic_and_potential(&self, p: &Particles) -> (f64, f64) {
        let mut ke = 0.0;
        let mut pe = 0.0;
        for a in 0..p.len() {
            ke += 0.5 * p.mass[a] * p.velocity[a].norm_squared();
            if self.settings.rotation {
                ke += 0.5 * p.inertia[a] * p.angular_velocity[a].norm_squared();
            }
            pe -= p.mass[a] * self.settings.gravity.dot(&p.position[a]);
        }
        (ke, pe)
    }

    /// Prepares forces and energies at the current state (called by the first [`Self::step`]).
    pub fn initialise(&mut self, p: &mut Particles) -> Result<(), Error> {
        check_particles(p)?;
        self.rebuild(p);
        self.ready = true;
        let (el, d) = self.compute_forces(p);
        self.last_dissipation = d;
        let (ke, pe) = self.kinetic_and_potential(p);
        self.energy.kinetic = ke;
        self.energy.potential = pe;
        self.energy.elastic = el;
        Ok(())
    }

    /// Advances one velocity-Verlet step.
    pub fn step(&mut self, p: &mut Particles) -> Result<(), Error> {
        if !self.ready || self.force.len() != p.len() {
            self.initialise(p)?;
        }
        let dt = self.settings.dt;
        let h = 0.5 * dt;
        let rot = self.settings.rotation;
        let diss_old: f64 = self.last_dissipation;
        let wall_power_old: f64 = self.wall_power.iter().sum();
        // half kick + drift
        for a in 0..p.len() {
            p.velocity[a] += self.force[a] * (h / p.mass[a]);
            p.position[a] += p.velocity[a] * dt;
            if rot {
                p.angular_velocity[a] += self.torque[a] * (h / p.inertia[a]);
                p.rotation[a] += p.angular_velocity[a] * dt;
            }
        }
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
        if self.needs_rebuild(p) {
            self.rebuild(p);
            self.ready = true;
        } else if self.walls_moved() {
            self.rebuild_wall_list(p);
        }
        let (el, diss_new) = self.compute_forces(p);
        for a in 0..p.len() {
            p.velocity[a] += self.force[a] * (h / p.mass[a]);
            if rot {
                p.angular_velocity[a] += self.torque[a] * (h / p.inertia[a]);
            }
        }
        for w in self.walls.iter_mut() {
            if let WallControl::Stress { pressure, mass, damping } = w.control {
                // semi-implicit in the damping term for the second half kick
                let v = (w.velocity + h * (pressure * w.area - w.force) / mass) / (1.0 + h * damping / mass);
                w.velocity = v;
            }
        }
        let wall_power_new: f64 = self.wall_power.iter().sum();
        let (ke, pe) = self.kinetic_and_potential(p);
        self.energy.kinetic = ke;
        self.energy.potential = pe;
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
#[allow(clippy::too_many_arguments)]
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

//! One sample of the protocol: the loose random start in its box of six walls, and its advance
//! in time under the protocol's temperature (profile or heat network) with the history rows.

use super::case::{CouplingMode, ExplicitSinterCase};
use super::machine::StepClock;
use super::output::Row;
use crate::error::{ConfigError, Error, ModelError};
use crate::explicit::sinter::SinterLaw;
use crate::explicit::{Explicit, Settings, Wall, WallControl, time_step};
use crate::heat::conductance::Conductance;
use crate::heat::network::{HeatNetwork, HeatSources, Scheme};
use crate::packing::Rng;
use crate::particles::Particles;
use crate::profile::Profile;
use nalgebra::Vector3;

type V3 = Vector3<f64>;

/// The state of one sample in its history.
#[derive(Clone)]
pub struct Sample<M: SinterLaw> {
    pub particles: Particles,
    pub driver: Explicit<M>,
    /// Radii at `temperature_cold` [m] (eq. 9 reference).
    pub r_ref: Vec<f64>,
    /// Particles whose temperature follows the profile in network mode.
    pub fixed: Vec<bool>,
    /// Heat network solves so far; steps since the last solve.
    pub heat_solves: u64,
    pub(super) since_heat: u64,
    /// Radius change since the last neighbour rebuild request [m].
    pub(super) radius_drift: f64,
    /// Stress accumulators for the row average.
    pub(super) acc: [f64; 3],
    pub(super) acc_n: u64,
    pub rows: Vec<Row>,
    pub warnings: Vec<String>,
    pub pressure: f64,
}

pub(super) fn random_loose_sample(case: &ExplicitSinterCase) -> Result<(Particles, f64), Error> {
    let s = &case.sample;
    let n = s.particles as usize;
    let mut rng = Rng::new(s.seed as u64);
    let radii: Vec<f64> = (0..n).map(|_| s.mean_radius * (1.0 + s.radius_spread * (2.0 * rng.uniform() - 1.0))).collect();
    let vol: f64 = radii.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    let side = (vol / s.initial_fraction).cbrt();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| radii[b].total_cmp(&radii[a]));
    let mut pos = vec![V3::zeros(); n];
    let mut placed: Vec<usize> = Vec::with_capacity(n);
    for &a in &order {
        let r = radii[a];
        let mut ok = false;
        for _ in 0..100_000 {
            let x = V3::new(r + (side - 2.0 * r) * rng.uniform(), r + (side - 2.0 * r) * rng.uniform(), r + (side - 2.0 * r) * rng.uniform());
            if placed.iter().all(|&b| (pos[b] - x).norm() > radii[b] + r) {
                pos[a] = x;
                ok = true;
                break;
            }
        }
        if !ok {
            return Err(ConfigError::inconsistent(
                "sample.initial_fraction",
                format!("{}: could not place {n} spheres without overlap; lower it", s.initial_fraction),
            )
            .into());
        }
        placed.push(a);
    }
    let mut p = Particles::default();
    let t0 = case.protocol.temperature_cold;
    let cp = case.coupling.specific_heat.unwrap_or(1.0);
    for a in 0..n {
        p.push(pos[a], radii[a], 0, s.density, cp, t0);
        if s.initial_speed > 0.0 {
            let g = V3::new(rng.normal(), rng.normal(), rng.normal());
            p.velocity[a] = g * (s.initial_speed / 3f64.sqrt());
        }
    }
    Ok((p, side))
}

/// Box edge lengths from the six walls (fixed x⁻,y⁻,z⁻ at 0; walls 3..6 the moving faces).
pub(super) fn box_size(walls: &[Wall]) -> [f64; 3] {
    [-walls[3].offset, -walls[4].offset, -walls[5].offset]
}

fn update_areas(walls: &mut [Wall]) {
    let l = box_size(walls);
    let a = [l[1] * l[2], l[0] * l[2], l[0] * l[1]];
    for k in 0..3 {
        walls[k].area = a[k];
        walls[k + 3].area = a[k];
    }
}

impl<M: SinterLaw> Sample<M> {
    /// A loose random sample in its box, walls under the pressure `pressure` [Pa].
    pub fn new(case: &ExplicitSinterCase, law: M, pressure: f64) -> Result<Self, Error> {
        let (particles, side) = random_loose_sample(case)?;
        let mut walls = Vec::new();
        for k in 0..3 {
            let mut e = V3::zeros();
            e[k] = 1.0;
            walls.push(Wall::new(e, V3::zeros()));
        }
        for k in 0..3 {
            let mut e = V3::zeros();
            e[k] = -1.0;
            let mut pnt = V3::zeros();
            pnt[k] = side;
            let mut w = Wall::new(e, pnt);
            w.control = WallControl::Stress { pressure, mass: case.walls.mass, damping: case.walls.damping };
            walls.push(w);
        }
        update_areas(&mut walls);
        let mut law = law;
        law.set_friction(case.protocol.prepare_friction);
        let (dt, _tc) = time_step(&law, &particles, case.stepping.dt_fraction, 0.0, true)?;
        let mut st = Settings::new(dt, case.sample.mean_radius);
        st.wall_friction = case.walls.friction;
        st.skin = case.stepping.skin * case.sample.mean_radius;
        let mut driver = Explicit::new(st, law, walls)?;
        driver.parallel_threshold = case.stepping.parallel_threshold as usize;
        let r_ref = particles.radius.clone();
        let n = particles.len();
        Ok(Sample {
            particles,
            driver,
            r_ref,
            fixed: vec![true; n],
            heat_solves: 0,
            since_heat: 0,
            radius_drift: 0.0,
            acc: [0.0; 3],
            acc_n: 0,
            rows: Vec::new(),
            warnings: Vec::new(),
            pressure,
        })
    }

    /// Solid fraction ΣV_i/(L_x L_y L_z) with the current radii.
    pub fn density(&self) -> f64 {
        let l = box_size(&self.driver.walls);
        let v: f64 = self.particles.radius.iter().map(|&r| crate::units::sphere_volume(r)).sum();
        v / (l[0] * l[1] * l[2])
    }

    pub(super) fn row(&mut self, temperature: f64, strain: f64) -> Row {
        let states = self.driver.contact_states();
        let n = self.particles.len() as f64;
        let forces: Vec<f64> = states.iter().map(|s| s.1).collect();
        let (mut fmin, mut fmax, mut fsum) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
        for &f in &forces {
            fmin = fmin.min(f);
            fmax = fmax.max(f);
            fsum += f;
        }
        let stress = if self.acc_n > 0 {
            [self.acc[0] / self.acc_n as f64, self.acc[1] / self.acc_n as f64, self.acc[2] / self.acc_n as f64]
        } else {
            [self.driver.walls[3].pressure(), self.driver.walls[4].pressure(), self.driver.walls[5].pressure()]
        };
        self.acc = [0.0; 3];
        self.acc_n = 0;
        Row {
            time: self.driver.time,
            temperature,
            density: self.density(),
            coordination: 2.0 * forces.len() as f64 / n,
            stress,
            box_size: box_size(&self.driver.walls),
            force_min: if forces.is_empty() { 0.0 } else { fmin },
            force_mean: if forces.is_empty() { 0.0 } else { fsum / forces.len() as f64 },
            force_max: if forces.is_empty() { 0.0 } else { fmax },
            state_mean: M::state_mean(&states),
            kinetic: self.driver.energy.kinetic,
            strain,
        }
    }

    /// Sets the temperatures for time `t` (profile, or network solve every `heat_every` steps) and
    /// the radii (eq. 9).
    fn thermal(&mut self, case: &ExplicitSinterCase, profile: &Profile, net: &mut Option<HeatNetwork>, t: f64) -> Result<(), Error> {
        let tp = profile.temperature(t);
        let t_cold = case.protocol.temperature_cold;
        match case.coupling.mode {
            CouplingMode::Profile => {
                if self.particles.temperature.first().copied() != Some(tp) {
                    self.particles.temperature.iter_mut().for_each(|x| *x = tp);
                }
            }
            CouplingMode::Network => {
                if t < case.protocol.t_prepare {
                    self.particles.temperature.iter_mut().for_each(|x| *x = tp);
                } else {
                    if net.is_none() {
                        *net = Some(self.build_network(case, profile)?);
                        self.since_heat = case.coupling.heat_every as u64;
                    }
                    self.since_heat += 1;
                    if self.since_heat >= case.coupling.heat_every as u64 {
                        let dth = self.since_heat as f64 * self.driver.settings.dt;
                        self.since_heat = 0;
                        self.heat_solve(case, net.as_mut().unwrap(), t - dth, dth)?;
                    }
                }
            }
        }
        let mut drift: f64 = 0.0;
        for a in 0..self.particles.len() {
            let r = self.driver.law.radius(self.r_ref[a], t_cold, self.particles.temperature[a]);
            drift = drift.max((r - self.particles.radius[a]).abs());
            self.particles.radius[a] = r;
        }
        self.radius_drift += drift;
        if self.radius_drift > 0.05 * self.driver.settings.skin {
            self.driver.invalidate();
            self.radius_drift = 0.0;
        }
        Ok(())
    }

    fn build_network(&mut self, case: &ExplicitSinterCase, profile: &Profile) -> Result<HeatNetwork, Error> {
        let n = self.particles.len();
        let walls = &self.driver.walls;
        let mut fixed = vec![None; n];
        for a in 0..n {
            let x = self.particles.position[a];
            let r = self.particles.radius[a];
            if walls.iter().any(|w| w.normal.dot(&x) - w.offset - r < 0.5 * r) {
                fixed[a] = Some(0);
            }
        }
        self.fixed = fixed.iter().map(|f| f.is_some()).collect();
        let cp = case.coupling.specific_heat.unwrap_or(1.0);
        let cap: Vec<f64> = self.particles.mass.iter().map(|m| m * cp).collect();
        let sources = HeatSources { fixed, profiles: vec![profile.clone()], ..Default::default() };
        Ok(HeatNetwork::new(cap, sources, Scheme::BackwardEuler, 1e-10))
    }

    fn heat_solve(&mut self, case: &ExplicitSinterCase, net: &mut HeatNetwork, t: f64, dt: f64) -> Result<(), Error> {
        let kappa = case.coupling.conductivity.unwrap_or(0.0);
        let contacts = self.driver.contacts();
        let pipes: Vec<[u32; 2]> = contacts.iter().map(|&(i, j)| [i, j]).collect();
        let law = Conductance::default();
        let mut k = Vec::with_capacity(pipes.len());
        let n = self.particles.len();
        let mut sum_k = vec![0.0; n];
        for &[i, j] in &pipes {
            let (i, j) = (i as usize, j as usize);
            let (ri, rj) = (self.particles.radius[i], self.particles.radius[j]);
            let h = ri + rj - (self.particles.position[i] - self.particles.position[j]).norm();
            let a = if h > 0.0 {
                crate::neck::solve(ri, rj, h).map_err(|e| ModelError::new(format!("heat step at t = {t:.4e} s, contact ({i}, {j}): {e}")))?.a
            } else {
                0.0
            };
            let kk = law.pipe(kappa, kappa, ri, rj, a).pair;
            sum_k[i] += kk;
            sum_k[j] += kk;
            k.push(kk);
        }
        let mut fastest = f64::INFINITY;
        for a in 0..n {
            if !self.fixed[a] && sum_k[a] > 0.0 {
                fastest = fastest.min(self.particles.capacity[a] / sum_k[a]);
            }
        }
        if dt > 0.1 * fastest && !self.warnings.iter().any(|w| w.starts_with("heat_every")) {
            let msg = format!(
                "heat_every: Δt_heat = {dt:.3e} s exceeds 0.1·min C_i/ΣK_ij = {:.3e} s (the fastest thermal time); lower coupling.heat_every",
                0.1 * fastest
            );
            tracing::warn!("{msg}");
            self.warnings.push(msg);
        }
        net.set_topology(&pipes)?;
        net.step(t, dt, &mut self.particles.temperature, &k)?;
        self.heat_solves += 1;
        Ok(())
    }

    /// Advances to time `until` [s] under `profile`, writing a history row every `interval`.
    /// `clock` counts the steps of the whole protocol; when it reaches a multiple of its
    /// checkpoint interval, or its step budget before a step, the advance pauses and returns
    /// `Ok(false)` (call it again to go on: the continuation is the same as if it had not
    /// paused); `Ok(true)` once `until` is reached.
    pub(super) fn advance(
        &mut self,
        case: &ExplicitSinterCase,
        profile: &Profile,
        net: &mut Option<HeatNetwork>,
        until: f64,
        interval: f64,
        sintering: bool,
        strain_of: Option<(f64, f64)>,
        clock: &mut StepClock,
    ) -> Result<bool, Error> {
        let t0s = case.protocol.t0_sinter;
        self.driver.law.set_sintering(sintering, t0s);
        let dt = self.driver.settings.dt;
        let mut next_row = self.rows.last().map(|r| r.time + interval).unwrap_or(0.0);
        while self.driver.time + 0.5 * dt < until {
            if clock.spent() {
                return Ok(false);
            }
            let t = self.driver.time + dt;
            self.thermal(case, profile, net, t)?;
            update_areas(&mut self.driver.walls);
            self.driver.step(&mut self.particles)?;
            for k in 0..3 {
                self.acc[k] += self.driver.walls[k + 3].pressure();
            }
            self.acc_n += 1;
            if self.driver.time + 0.5 * dt >= next_row {
                let strain = strain_of.map(|(z0, _)| 1.0 - box_size(&self.driver.walls)[2] / z0).unwrap_or(0.0);
                let r = self.row(profile.temperature(self.driver.time), strain);
                self.rows.push(r);
                next_row = self.driver.time + interval;
            }
            if clock.tick() {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// A fresh heat network for a branch (same fixed particles, the branch's profile).
    pub(super) fn build_network_keep(&mut self, case: &ExplicitSinterCase, profile: &Profile) -> Result<HeatNetwork, Error> {
        let n = self.particles.len();
        let fixed: Vec<Option<u32>> = (0..n).map(|a| if self.fixed[a] { Some(0) } else { None }).collect();
        let cp = case.coupling.specific_heat.unwrap_or(1.0);
        let cap: Vec<f64> = self.particles.mass.iter().map(|m| m * cp).collect();
        let sources = HeatSources { fixed, profiles: vec![profile.clone()], ..Default::default() };
        Ok(HeatNetwork::new(cap, sources, Scheme::BackwardEuler, 1e-10))
    }
}

//! The driver's checkpoint state ([`DriverState`]): saved and restored bit for bit.

use super::law::ContactModel;
use super::{Counters, Energy, Explicit, Out, Slot, V3, Wall};
use serde::{Deserialize, Serialize};

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

impl<M: ContactModel> Explicit<M> {
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
}

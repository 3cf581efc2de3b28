//! The sweeps of one step: the first half kick and drift over the particles, the force sweep over
//! the contacts (one slot per neighbour pair), and the particle sweep that gathers the forces in a
//! fixed order, adds the walls and damping and gives the second half kick (module docs of
//! [`crate::explicit`]).

use super::law::{ContactCtx, ContactModel, PairGeom, TangentialParams};
use super::{CONTACT_CHUNK, Explicit, Out, PARTICLE_CHUNK, Slot, V3, tangential};
use crate::particles::Particles;
use rayon::prelude::*;

/// Sums of one chunk of the per-particle sweep.
#[derive(Debug, Clone, Default)]
pub(super) struct ParticleSums {
    pub(super) elastic: f64,
    pub(super) dissipation: f64,
    pub(super) kinetic: f64,
    pub(super) potential: f64,
    /// Normal force of the chunk's particles on each wall [N].
    pub(super) wall_force: Vec<f64>,
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

impl<M: ContactModel> Explicit<M> {
    /// First half kick and drift (steps 1–2 of the module docs); returns whether the neighbour list
    /// must be rebuilt (a particle moved half a skin since the last build, or the list is stale).
    pub(super) fn kick_drift(&mut self, p: &mut Particles) -> bool {
        let dt = self.settings.dt;
        let h = 0.5 * dt;
        let rot = self.settings.rotation;
        // half the skin; less while a periodic box is strained (docs/packing.md (G3))
        let (half, box_forced) = self.rebuild_threshold();
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
        !check || moved || box_forced
    }

    /// Contact forces at the current positions (one slot per neighbour pair); returns (elastic
    /// energy, dissipated power) of the particle–particle contacts.
    pub(super) fn contact_sweep(&mut self, p: &Particles) -> (f64, f64) {
        let st = &self.settings;
        let law = &self.law;
        let dt = st.dt;
        let rot = st.rotation;
        let pairs = &self.pairs;
        let pbox = self.periodic;
        let par = self.pairs.len() > self.parallel_threshold;
        let tan = TangentialParams { friction: st.friction, stiffness_ratio: st.tangential_stiffness_ratio, damping_ratio: st.tangential_damping_ratio, dt };
        let kernel = |c: usize, slot: &mut Slot<M::State>, out: &mut Out, touching: &mut bool| -> (f64, f64) {
            let (i, j) = (pairs[c].0 as usize, pairs[c].1 as usize);
            let mut d = p.position[i] - p.position[j];
            if let Some(l) = &pbox {
                d = super::minimum_image(d, l);
            }
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
    pub(super) fn particle_sweep(&mut self, p: &mut Particles, kick: bool) -> ParticleSums {
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
}

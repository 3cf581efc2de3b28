//! The generate protocol (module docs of [`super`]): cloud, settle, triaxial compaction, unload
//! and relax, each a function over the explicit simulation in scaled units.

use super::{GenerateCase, GenerateSummary, Packing, Protocol, V3, summarise};
use crate::error::{ConfigError, Error, SolveError};
use crate::explicit::law::{Damping, LinearSpringDashpot};
use crate::explicit::{Explicit, Settings, Wall, WallControl, time_step};
use crate::packing::Rng;
use crate::particles::Particles;
use std::time::Instant;

type Sim = Explicit<LinearSpringDashpot>;

pub(super) struct Progress {
    pub(super) on: bool,
    pub(super) t0: Instant,
}
impl Progress {
    pub(super) fn say(&self, msg: impl AsRef<str>) {
        if self.on {
            tracing::info!("[generate {:7.2} s] {}", self.t0.elapsed().as_secs_f64(), msg.as_ref());
        }
    }
}

fn box_walls(l: [f64; 3]) -> Vec<Wall> {
    let mut w = Vec::new();
    for a in 0..3 {
        let mut e = V3::zeros();
        e[a] = 1.0;
        w.push(Wall::new(e, V3::zeros()));
        let mut p = V3::zeros();
        p[a] = l[a];
        w.push(Wall::new(-e, p));
    }
    w
}

/// Box edges from the walls (lower walls 2a, upper 2a+1).
fn box_of(walls: &[Wall]) -> [f64; 3] {
    [0, 1, 2].map(|a| -walls[2 * a + 1].offset - walls[2 * a].offset)
}

fn set_areas(walls: &mut [Wall]) {
    let l = box_of(walls);
    for a in 0..3 {
        let area = l[(a + 1) % 3] * l[(a + 2) % 3];
        walls[2 * a].area = area;
        walls[2 * a + 1].area = area;
    }
}

fn max_overlap(p: &Particles, walls: &[Wall], pairs: &[(u32, u32)]) -> f64 {
    let mut m: f64 = 0.0;
    for &(i, j) in pairs {
        let (i, j) = (i as usize, j as usize);
        m = m.max(p.radius[i] + p.radius[j] - (p.position[i] - p.position[j]).norm());
    }
    for w in walls {
        for a in 0..p.len() {
            m = m.max(-(w.normal.dot(&p.position[a]) - w.offset - p.radius[a]));
        }
    }
    m
}

/// Fastest wall speed of the compaction [r̄ per scaled time unit √(m̄/k_n)]; the periodic die's
/// height moves at the same speed (G9).
pub(super) const WALL_SPEED: f64 = 0.03;
/// Strain rate [1 per scaled time unit] at which the walls back off to unload the packing
/// (the copper box, 15 r̄ high, backs off at 2·10⁻⁴ r̄ per time unit).
pub(super) const BACKOFF_STRAIN_RATE: f64 = 1.3e-5;
/// Background viscous damping rate [1 per scaled time unit] of the final relaxation: the kinetic
/// energy falls by e^{-0.1} per time unit (≈ 6 steps), a damping ratio of ≈ 0.01 of the contacts.
const DRAIN_DAMPING: f64 = 0.05;

/// Morton (Z-order) key of a lattice cell: the bits of the three indices interleaved.
pub(super) fn morton(ix: usize, iy: usize, iz: usize) -> u64 {
    fn spread(v: usize) -> u64 {
        let mut x = (v as u64) & 0x1f_ffff;
        x = (x | x << 32) & 0x1f00000000ffff;
        x = (x | x << 16) & 0x1f0000ff0000ff;
        x = (x | x << 8) & 0x100f00f00f00f00f;
        x = (x | x << 4) & 0x10c30c30c30c30c3;
        (x | x << 2) & 0x1249249249249249
    }
    spread(ix) | spread(iy) << 1 | spread(iz) << 2
}

/// Generates the packing of a validated case in scaled units (module docs) and returns it in SI.
pub fn generate(case: &GenerateCase, progress: bool) -> Result<(Packing, GenerateSummary), Error> {
    let pr = Progress { on: progress, t0: Instant::now() };
    let t0 = Instant::now();
    let n = case.particles;
    let mut rng = Rng::new(case.seed);
    let s = scaled_sizes(case, &mut rng)?;
    // 1. cloud on a jittered lattice
    let (mut p, order, cloud) = cloud(case, &s, &mut rng);
    let (mut sim, dt, g) = simulation(&case.protocol, &s, &cloud, &p, &pr)?;
    // 2. settle
    let (steps_settle, zmax) = settle(&mut sim, &mut p, &s, &cloud, dt, g, case.protocol.max_steps, &pr)?;
    // 3. triaxial compaction (a stop request, crate::interrupt: the packing as it is)
    let stop = crate::interrupt::requested;
    let c = if stop() {
        Compacted { target: box_of(&sim.walls), mu: case.protocol.friction, steps: 0 }
    } else {
        compact(&mut sim, &mut p, &s, zmax, dt, &mut rng, &case.protocol, &pr)?
    };
    // 4. unload and relax
    let (met, steps_relax) = if stop() { (false, 0) } else { relax(&mut sim, &mut p, n, &c, &case.protocol, &pr)? };
    let steps_total = sim.counters.steps;
    pr.say(format!(
        "relaxed after {steps_relax} steps (kinetic energy {:.3e}, thresholds met: {met}; {} neighbour-list builds in all)",
        sim.energy.kinetic / n as f64,
        sim.counters.rebuilds
    ));
    // report (scaled → SI)
    let r_unit = s.r_unit;
    let lbox = box_of(&sim.walls);
    let lo = V3::new(sim.walls[0].offset, sim.walls[2].offset, sim.walls[4].offset);
    let mut pos_si = vec![V3::zeros(); n];
    let mut rad_si = vec![0.0; n];
    for (m, &k) in order.iter().enumerate() {
        pos_si[k] = (p.position[m] - lo) * r_unit;
        rad_si[k] = p.radius[m] * r_unit;
    }
    let box_si = lbox.map(|l| l * r_unit);
    let summary = summarise(
        case,
        &pos_si,
        &rad_si,
        box_si,
        r_unit,
        sim.energy.kinetic / n as f64,
        c.mu,
        [steps_settle, c.steps, steps_relax],
        steps_total,
        t0.elapsed().as_secs_f64(),
        met,
        None,
    );
    Ok((Packing { positions: pos_si, radii: rad_si, box_size: box_si }, super::interrupted(summary)))
}

/// The sizes in scaled units (module docs) and the target box.
struct Scaled {
    /// Length unit: the mean radius of the drawn diameters [m].
    r_unit: f64,
    /// Radii in draw order, largest radius, Σ V_i (scaled).
    radii: Vec<f64>,
    r_max: f64,
    vp: f64,
    /// Target box edges (scaled).
    target: [f64; 3],
}

/// The drawn sizes in scaled units: length unit r̄ [m], radii in draw order, largest radius, Σ V_i.
pub(super) fn draw_radii(case: &GenerateCase, rng: &mut Rng) -> (f64, Vec<f64>, f64, f64) {
    let n = case.particles;
    let diam: Vec<f64> = (0..n).map(|_| case.size.sample(rng)).collect();
    let r_unit = diam.iter().sum::<f64>() / (2.0 * n as f64); // length unit: mean radius [m]
    let radii: Vec<f64> = diam.iter().map(|d| 0.5 * d / r_unit).collect();
    let r_max = radii.iter().copied().fold(0.0, f64::max);
    let vp: f64 = radii.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    (r_unit, radii, r_max, vp)
}

/// The target box [scaled units]: the requested shape scaled to the target volume, the
/// compaction's (walls: `Σ V_i / (φ (1 + 2 compaction_overlap))`) or exactly `Σ V_i / φ`
/// (periodic, docs/packing.md (G6)); every edge must be finite and at least two largest
/// diameters. `check` asks it too ([`super::check_generate_case`]), so that `check` refuses what
/// `generate` refuses (issue 26, class 8).
pub(super) fn target_box(case: &GenerateCase, vp: f64, r_max: f64) -> Result<[f64; 3], Error> {
    let shape = case.box_size;
    let volume = shape[0] * shape[1] * shape[2];
    if case.periodic {
        let target = shape.map(|s| s * (vp / (case.target_solid_fraction * volume)).cbrt());
        if let Some(a) = (0..3).find(|&a| !(target[a].is_finite() && target[a] >= 4.0 * r_max)) {
            return Err(ConfigError::inconsistent(
                "packing.box",
                format!(
                    "the periodic target box is {:.3e} mean radii along {} (shape {:?} scaled to {} particles at solid fraction {}), not a finite length of at least two largest diameters ({:.3} mean radii); add particles or make the shape less elongated",
                    target[a],
                    ["x", "y", "z"][a],
                    case.box_size,
                    case.particles,
                    case.target_solid_fraction,
                    4.0 * r_max
                ),
            )
            .into());
        }
        return Ok(target);
    }
    // compaction aims slightly above the target: unloading from the compaction pressure expands
    // the box by about the elastic strain; 2·compaction_overlap is the measured relative loss
    let v_target = vp / (case.target_solid_fraction * (1.0 + 2.0 * case.protocol.compaction_overlap));
    let scale = (v_target / volume).cbrt();
    let target = shape.map(|s| s * scale);
    if target.iter().any(|&l| !(l.is_finite() && l >= 4.0 * r_max)) {
        return Err(ConfigError::inconsistent(
            "packing.box",
            format!(
                "the target box [{:.3e}, {:.3e}, {:.3e}] mean radii (shape {:?} scaled to {} particles) is not finite or narrower than two largest diameters ({:.3}); add particles or change the shape",
                target[0],
                target[1],
                target[2],
                case.box_size,
                case.particles,
                4.0 * r_max
            ),
        )
        .into());
    }
    Ok(target)
}

/// Draws the diameters and scales the requested box shape to the target volume.
fn scaled_sizes(case: &GenerateCase, rng: &mut Rng) -> Result<Scaled, Error> {
    let (r_unit, radii, r_max, vp) = draw_radii(case, rng);
    let target = target_box(case, vp, r_max)?;
    Ok(Scaled { r_unit, radii, r_max, vp, target })
}

/// The cloud's footprint and height (scaled).
struct Cloud {
    foot: [f64; 2],
    h_cloud: f64,
}

/// Stage 1: the particles on a jittered lattice in Morton order, with `order[m]` the draw index
/// of the particle stored at m.
fn cloud(case: &GenerateCase, s: &Scaled, rng: &mut Rng) -> (Particles, Vec<usize>, Cloud) {
    let n = case.particles;
    let (target, r_max, radii) = (s.target, s.r_max, &s.radii);
    let foot = [target[0] * 1.02, target[1] * 1.02];
    let a = 2.0 * r_max * 1.02;
    let nx = (foot[0] / a).floor() as usize;
    let ny = (foot[1] / a).floor() as usize;
    let nz_min = n.div_ceil(nx * ny);
    let h_cloud = (s.vp / (case.protocol.cloud_solid_fraction * foot[0] * foot[1])).max(nz_min as f64 * a);
    let nz = ((h_cloud / a).floor() as usize).max(nz_min);
    let (ax, ay, az) = (foot[0] / nx as f64, foot[1] / ny as f64, h_cloud / nz as f64);
    let mut cells: Vec<usize> = (0..nx * ny * nz).collect();
    rng.shuffle(&mut cells);
    let mut cloud = Vec::with_capacity(n);
    for k in 0..n {
        let c = cells[k];
        let (ix, iy, iz) = (c % nx, (c / nx) % ny, c / (nx * ny));
        let r = radii[k];
        let jit = |rng: &mut Rng, s: f64| (2.0 * rng.uniform() - 1.0) * (0.5 * s - r).max(0.0) * 0.9;
        let x = V3::new((ix as f64 + 0.5) * ax + jit(rng, ax), (iy as f64 + 0.5) * ay + jit(rng, ay), (iz as f64 + 0.5) * az + jit(rng, az));
        let v = V3::new(rng.normal(), rng.normal(), rng.normal()) * 0.01;
        cloud.push((x, v, morton(ix, iy, iz)));
    }
    // memory order: along a Morton (Z-order) curve of the lattice cells, so that neighbours are
    // near in memory (large packings were dominated by cache misses); `order[m]` is the draw
    // index of the particle stored at m, and the output restores the draw order
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&k| cloud[k].2);
    let mut p = Particles::default();
    let density = 3.0 / (4.0 * std::f64::consts::PI);
    for (m, &k) in order.iter().enumerate() {
        p.push(cloud[k].0, radii[k], 0, density, 1.0, 300.0);
        p.velocity[m] = cloud[k].1;
    }
    (p, order, Cloud { foot, h_cloud })
}

/// The explicit simulation of the protocol in its box (gravity on), its time step and gravity.
fn simulation(proto: &Protocol, s: &Scaled, cloud: &Cloud, p: &Particles, pr: &Progress) -> Result<(Sim, f64, f64), Error> {
    let (foot, h_cloud) = (cloud.foot, cloud.h_cloud);
    let law = LinearSpringDashpot { stiffness: 1.0, damping: Damping::restitution_ratio(proto.restitution) };
    let (dt, tc) = time_step(&law, p, proto.dt_fraction, 0.0, true)?;
    pr.say(format!(
        "{} particles, mean radius {:.4e} m, target box {:.3?} r, cloud height {h_cloud:.2} r, dt = {dt:.4} (t_c = {tc:.4}, scaled units)",
        p.len(),
        s.r_unit,
        s.target
    ));
    let mut settings = Settings::new(dt, 1.0);
    settings.friction = proto.friction;
    settings.wall_friction = proto.wall_friction;
    settings.local_damping = proto.local_damping;
    settings.tangential_damping_ratio = 0.0;
    settings.skin = 0.3;
    let v_imp = 0.2;
    let g = v_imp * v_imp / (2.0 * h_cloud);
    settings.gravity = V3::new(0.0, 0.0, -g);
    let mut walls = box_walls([foot[0], foot[1], h_cloud + 2.0 * s.r_max]);
    set_areas(&mut walls);
    let mut sim = Explicit::new(settings, law, walls)?;
    sim.parallel_threshold = 30_000;
    Ok((sim, dt, g))
}

/// The error of a stage that ran out of `packing.protocol.max_steps`.
pub(super) fn out_of_steps(budget: u64, stage: &str, steps: u64) -> Error {
    SolveError::new("packing generation", format!("{stage}: step budget packing.protocol.max_steps = {budget} exhausted after {steps} steps")).into()
}

/// Stage 2: settles under gravity; returns the steps and the top of the packing (scaled).
fn settle(sim: &mut Sim, p: &mut Particles, s: &Scaled, cloud: &Cloud, dt: f64, g: f64, budget: u64, pr: &Progress) -> Result<(u64, f64), Error> {
    let n = p.len();
    let fall_steps = ((2.0 * cloud.h_cloud / g).sqrt() / dt) as u64;
    let ke_settle = 0.01 * g * n as f64;
    let mut steps_settle = 0u64;
    loop {
        sim.run(p, 100)?;
        steps_settle += 100;
        if crate::interrupt::requested() {
            break;
        }
        if steps_settle > fall_steps && sim.energy.kinetic < ke_settle {
            break;
        }
        if sim.counters.steps > budget {
            return Err(out_of_steps(budget, "settling", sim.counters.steps));
        }
    }
    let zmax = p.position.iter().zip(&p.radius).map(|(x, r)| x[2] + r).fold(0.0, f64::max);
    pr.say(format!(
        "settled after {steps_settle} steps ({} neighbour-list builds so far), top at {zmax:.2} r (target height {:.2} r)",
        sim.counters.rebuilds, s.target[2]
    ));
    Ok((steps_settle, zmax))
}

/// The end of the compaction: the box reached (scaled), the friction coefficient, the steps.
struct Compacted {
    target: [f64; 3],
    mu: f64,
    steps: u64,
}

/// Stage 3: gravity off, the top wall lowered onto the packing (top at `zmax`), the upper walls
/// driven to the target box under the pressure servo, friction lowered and the packing tapped
/// while it jams.
fn compact(sim: &mut Sim, p: &mut Particles, s: &Scaled, zmax: f64, dt: f64, rng: &mut Rng, proto: &Protocol, pr: &Progress) -> Result<Compacted, Error> {
    let (n, vp, budget) = (p.len(), s.vp, proto.max_steps);
    sim.settings.gravity = V3::zeros();
    sim.walls[5].offset = -zmax;
    sim.invalidate();
    let l0 = box_of(&sim.walls);
    let p_c = proto.compaction_overlap / 4.0;
    let v_max = WALL_SPEED;
    let mut target = s.target;
    let path_len = (0..3).map(|a| (target[a] - l0[a]).abs()).fold(0.0, f64::max).max(1e-12);
    let mut lambda = 0.0f64;
    let mut jam = Jam::new(proto.friction);
    let mut steps_compact = 0u64;
    for a in 0..3 {
        sim.walls[2 * a + 1].control = WallControl::Velocity;
    }
    while lambda < 1.0 {
        if crate::interrupt::requested() {
            // stopped: the walls stay where they are
            target = box_of(&sim.walls);
            break;
        }
        let pm = (0..3).map(|a| sim.walls[2 * a + 1].pressure()).sum::<f64>() / 3.0;
        let servo = (1.0 - pm / p_c).clamp(0.0, 1.0);
        let dl = (servo * v_max * dt / path_len).min(1.0 - lambda);
        lambda += dl;
        for a in 0..3 {
            let speed = dl * (target[a] - l0[a]) / dt; // dL/dt
            sim.walls[2 * a + 1].velocity = -speed; // upper wall's normal points down: inward = −dL
        }
        if lambda >= 1.0 {
            // land exactly on the target
            for a in 0..3 {
                let want = -target[a];
                let w = &mut sim.walls[2 * a + 1];
                w.velocity = -((w.offset - want) / dt);
            }
        }
        if jam.update(sim, p, servo, vp / box_of(&sim.walls).iter().product::<f64>(), rng, pr) {
            target = box_of(&sim.walls);
            lambda = 1.0;
            continue;
        }
        sim.step(p)?;
        set_areas(&mut sim.walls);
        steps_compact += 1;
        if steps_compact.is_multiple_of(2000) {
            pr.say(format!(
                "compaction: solid fraction {:.4}, pressure/p_c {:.3}, kinetic energy/particle {:.2e}, contacts/particle {:.2}",
                vp / box_of(&sim.walls).iter().product::<f64>(),
                pm / p_c,
                sim.energy.kinetic / n as f64,
                2.0 * sim.contacts().len() as f64 / n as f64
            ));
        }
        if sim.counters.steps > budget {
            return Err(out_of_steps(budget, "compaction", sim.counters.steps));
        }
    }
    for a in 0..3 {
        sim.walls[2 * a + 1].control = WallControl::Fixed;
        sim.walls[2 * a + 1].velocity = 0.0;
        sim.walls[2 * a + 1].offset = -target[a];
    }
    set_areas(&mut sim.walls);
    let mu = jam.mu;
    pr.say(format!(
        "compacted to the target box ({} taps) after {steps_compact} steps ({} neighbour-list builds so far), friction {mu:.4}, wall pressure {:.3e} (p_c = {p_c:.3e})",
        jam.taps,
        sim.counters.rebuilds,
        (0..3).map(|a| sim.walls[2 * a + 1].pressure()).sum::<f64>() / 3.0
    ));
    Ok(Compacted { target, mu, steps: steps_compact })
}

/// What the compaction does while the walls (or the periodic die's height, (G9)) stall: friction
/// lowered step by step, then (without friction) taps; strength of a tap, jammed steps before a
/// tap, taps per stall check.
pub(super) struct Jam {
    pub(super) mu: f64,
    jammed_steps: u64,
    pub(super) taps: u32,
    phi_at_check: f64,
}

impl Jam {
    pub(super) fn new(friction: f64) -> Self {
        Jam { mu: friction, jammed_steps: 0, taps: 0, phi_at_check: 0.0 }
    }

    const TAP: f64 = 0.05;
    const QUIET_STEPS: u64 = 150;
    const STALL_TAPS: u32 = 40;

    /// One compaction step's jam handling at servo factor `servo` and solid fraction `phi` of the
    /// current box; true: the packing stalled, accept the current box.
    pub(super) fn update(&mut self, sim: &mut Sim, p: &mut Particles, servo: f64, phi: f64, rng: &mut Rng, pr: &Progress) -> bool {
        if servo < 0.05 {
            self.jammed_steps += 1;
            if self.jammed_steps >= 300 && self.mu > 0.0 {
                self.mu = if self.mu < 0.005 { 0.0 } else { self.mu * 0.6 };
                sim.settings.friction = self.mu;
                if self.mu == 0.0 {
                    // without friction spin has no effect on the geometry and is never damped
                    p.angular_velocity.iter_mut().for_each(|w| *w = V3::zeros());
                }
                self.jammed_steps = 0;
                pr.say(format!("jammed at solid fraction {phi:.4}: friction lowered to {:.4}", self.mu));
            }
        } else {
            self.jammed_steps = 0;
        }
        if self.mu == 0.0 && self.jammed_steps >= Self::QUIET_STEPS {
            // frictionless and jammed below the target box (the flat walls leave looser layers):
            // tap, i.e. random velocities of `TAP`·√(k_n/m̄) r̄, so that the packing explores denser
            // configurations under the same pressure; accept the box once `STALL_TAPS` taps
            // gained < 1e-3 in solid fraction
            self.jammed_steps = 0;
            self.taps += 1;
            if self.taps.is_multiple_of(Self::STALL_TAPS) {
                if phi - self.phi_at_check < 1e-3 {
                    pr.say(format!("jammed at solid fraction {phi:.4} after {} taps: accepting it", self.taps));
                    return true;
                }
                self.phi_at_check = phi;
            }
            for v in p.velocity.iter_mut() {
                *v += V3::new(rng.normal(), rng.normal(), rng.normal()) * Self::TAP;
            }
        }
        false
    }
}

/// Stops the spin of every contact-free sphere (a rattler: zero force). Nothing damps it, it
/// does not shape the packing, and its energy would hold the kinetic energy above the threshold
/// for ever.
pub(super) fn stop_rattler_spin(sim: &Sim, p: &mut Particles) {
    for (w, f) in p.angular_velocity.iter_mut().zip(sim.forces()) {
        if *f == V3::zeros() {
            *w = V3::zeros();
        }
    }
}

/// Once the box is final and the overlaps are within the threshold, only kinetic energy is left,
/// in a nearly stress-free packing whose particles drift with almost no force. The local damping,
/// proportional to the force, hardly slows them (the kinetic energy of a 10⁴-particle packing
/// took ~2·10⁴ steps to fall by 100), so a background viscous damping drains it (once).
pub(super) fn drain_kinetic_energy(sim: &mut Sim, ov: f64, ov_tol: f64, ke: f64, n: usize, pr: &Progress) {
    if ov < ov_tol && sim.settings.viscous_damping == 0.0 {
        sim.settings.viscous_damping = DRAIN_DAMPING;
        pr.say(format!("overlaps below {ov_tol:.1e} r: draining the kinetic energy ({:.2e} per particle) with viscous damping", ke / n as f64));
    }
}

/// The unloading rule of the walled relaxation, shared by the periodic die (G9): at rest (kinetic
/// energy below 100× its threshold) with overlaps above the threshold at 4 checks, the packing
/// carries load and its box backs off, until the pressure has fallen to
/// `p_end` = 0.02 p_c · max_overlap_rel / compaction_overlap or the largest overlap to half the
/// threshold.
pub(super) struct Unloading {
    quiet: u64,
    pub(super) backing_off: bool,
    ke_tol: f64,
    pub(super) ov_tol: f64,
    p_end: f64,
}

impl Unloading {
    pub(super) fn new(proto: &Protocol, n: usize) -> Self {
        let p_c = proto.compaction_overlap / 4.0;
        let p_end = 0.02 * p_c * proto.max_overlap_rel / proto.compaction_overlap.max(proto.max_overlap_rel);
        Unloading { quiet: 0, backing_off: false, ke_tol: proto.kinetic_energy_rel * n as f64, ov_tol: proto.max_overlap_rel, p_end: p_end.max(1e-14) }
    }

    /// The thresholds are met and the box is not moving: relaxed.
    pub(super) fn relaxed(&self, ke: f64, ov: f64) -> bool {
        ke < self.ke_tol && ov < self.ov_tol && !self.backing_off
    }

    /// One check at kinetic energy `ke`, largest overlap `ov` and pressure `pm`; returns
    /// (backing off started, backing off stopped) at this check (both when it ends at once).
    pub(super) fn update(&mut self, ke: f64, ov: f64, pm: f64) -> (bool, bool) {
        if ov >= self.ov_tol && ke < 100.0 * self.ke_tol {
            self.quiet += 1;
        }
        let started = !self.backing_off && self.quiet >= 4;
        if started {
            self.backing_off = true;
        }
        let stopped = self.backing_off && (pm <= self.p_end || ov < 0.5 * self.ov_tol);
        if stopped {
            self.backing_off = false;
            self.quiet = 0;
        }
        (started, stopped)
    }
}

/// Stage 4: walls at the target box, backed off while the packing carries load ([`Unloading`]),
/// then the kinetic energy drained; returns whether the thresholds were met within the budget,
/// and the steps.
fn relax(sim: &mut Sim, p: &mut Particles, n: usize, c: &Compacted, proto: &Protocol, pr: &Progress) -> Result<(bool, u64), Error> {
    let (mu, target, budget) = (c.mu, c.target, proto.max_steps);
    let p_c = proto.compaction_overlap / 4.0;
    if mu == 0.0 {
        p.angular_velocity.iter_mut().for_each(|w| *w = V3::zeros());
    }
    let mut un = Unloading::new(proto, n);
    let mut steps_relax = 0u64;
    let met = loop {
        sim.run(p, 50)?;
        steps_relax += 50;
        if crate::interrupt::requested() {
            break false;
        }
        if mu > 0.0 {
            // gravity is off: a rattler has zero force
            stop_rattler_spin(sim, p);
        }
        let ke = sim.energy.kinetic;
        let ov = max_overlap(p, &sim.walls, sim.neighbour_pairs());
        if un.relaxed(ke, ov) {
            break true;
        }
        let pm = (0..3).map(|a| sim.walls[2 * a + 1].pressure()).sum::<f64>() / 3.0;
        let was_backing_off = un.backing_off;
        let (started, stopped) = un.update(ke, ov, pm);
        if started {
            pr.say(format!("relaxed with largest overlap {ov:.2e} r: backing the walls off (pressure {pm:.3e})"));
        }
        if stopped {
            for a in 0..3 {
                sim.walls[2 * a + 1].control = WallControl::Fixed;
            }
        } else if un.backing_off {
            for a in 0..3 {
                // a strain rate: the walls' travel to unload grows with the box
                let w = &mut sim.walls[2 * a + 1];
                w.control = WallControl::Velocity;
                w.velocity = -BACKOFF_STRAIN_RATE * target[a];
            }
        }
        if was_backing_off || started {
            set_areas(&mut sim.walls);
        }
        if !un.backing_off {
            drain_kinetic_energy(sim, ov, un.ov_tol, ke, n, pr);
        }
        if steps_relax.is_multiple_of(2000) {
            pr.say(format!(
                "relax: kinetic energy/particle {:.2e}, largest overlap {ov:.2e} r, pressure/p_c {:.3e}, backing off {}",
                ke / n as f64,
                pm / p_c,
                un.backing_off
            ));
        }
        if sim.counters.steps > budget {
            break false;
        }
    };
    Ok((met, steps_relax))
}

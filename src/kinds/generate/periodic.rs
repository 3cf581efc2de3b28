//! The periodic generate protocol (`packing.boundary = "periodic"`, docs/packing.md "Periodic
//! packings"): random sequential insertion at a low solid fraction in a periodic box, compaction by
//! affine box strain (G2) at a strain rate slowed by a pressure servo (G5), friction lowered while
//! the packing jams short of the target, then relaxation in the target box. No walls, no gravity;
//! the same scaled units as the walled protocol (module docs of [`super`]).

use super::output::periodic_report;
use super::protocol::{
    BACKOFF_STRAIN_RATE, Jam, Progress, Unloading, WALL_SPEED, drain_kinetic_energy, draw_radii, morton, out_of_steps, stop_rattler_spin, target_box,
};
use super::{Compaction, GenerateCase, GenerateSummary, Packing, PeriodicReport, Protocol, V3};
use crate::error::{ConfigError, Error, SolveError};
use crate::explicit::law::{Damping, LinearSpringDashpot};
use crate::explicit::{Explicit, Settings, minimum_image, time_step};
use crate::packing::Rng;
use crate::particles::Particles;
use std::time::Instant;

type Sim = Explicit<LinearSpringDashpot>;

/// Insertion attempts per particle before the random insertion gives up.
const ATTEMPTS: usize = 20_000;

/// Generates a periodic packing of a validated case (`case.periodic`) and returns it in SI.
pub fn generate_periodic(case: &GenerateCase, progress: bool) -> Result<(Packing, GenerateSummary), Error> {
    let pr = Progress { on: progress, t0: Instant::now() };
    let t0 = Instant::now();
    let n = case.particles;
    let proto = &case.protocol;
    let mut rng = Rng::new(case.seed);
    let (r_unit, radii, r_max, vp) = draw_radii(case, &mut rng);
    // the target box: the requested shape scaled to Σ V_i / φ (G6), exactly
    let target = V3::from(target_box(case, vp, r_max)?);
    let die = proto.compaction == Compaction::Die;
    // the die aims at φ (1 + 2 c_o), as the walled box does: unloading expands it again (G9)
    let aim = if die { target / (1.0 + 2.0 * proto.compaction_overlap).cbrt() } else { target };
    let l0 = if die {
        // the walled cloud's footprint, 2 % above the target's; the height at the cloud fraction
        let (fx, fy) = (aim.x * 1.02, aim.y * 1.02);
        V3::new(fx, fy, (vp / (proto.cloud_solid_fraction * fx * fy)).max(aim.z))
    } else {
        // the cloud is never denser than the target (then the compaction is empty)
        target * (case.target_solid_fraction / proto.cloud_solid_fraction).cbrt().max(1.0)
    };
    let (mut p, order) = insert(&radii, l0, &mut rng)?;
    let law = LinearSpringDashpot { stiffness: 1.0, damping: Damping::restitution_ratio(proto.restitution) };
    let (dt, tc) = time_step(&law, &p, proto.dt_fraction, 0.0, false)?;
    pr.say(format!("{n} particles (periodic), mean radius {r_unit:.4e} m, target box {target:.3?} r, cloud box {l0:.3?} r, dt = {dt:.4} (t_c = {tc:.4})"));
    let mut settings = Settings::new(dt, 1.0);
    settings.friction = proto.friction;
    settings.local_damping = proto.local_damping;
    settings.tangential_damping_ratio = 0.0;
    settings.skin = 0.3;
    let mut sim = Explicit::new(settings, law, Vec::new())?;
    sim.set_periodic_box(l0, &p)?;
    sim.parallel_threshold = 30_000;
    let mut extra = PeriodicReport::default();
    let (mu, steps_compact) = if die {
        compact_die(&mut sim, &mut p, aim, vp, proto, &mut rng, &mut extra, &pr)?
    } else {
        compact(&mut sim, &mut p, target, vp, proto, &mut extra, &pr)?
    };
    // a stop request (crate::interrupt): the packing as it is, in the box as it is
    let stopped = crate::interrupt::requested();
    let (met, steps_relax, mu) = if stopped {
        (false, 0, mu)
    } else if die {
        relax_die(&mut sim, &mut p, mu, aim, proto, &pr)?
    } else {
        relax(&mut sim, &mut p, mu, proto, &pr)?
    };
    // the die's box is where the unloading left it
    let target = if die || crate::interrupt::requested() { sim.periodic_box().unwrap_or(target) } else { target };
    pr.say(format!(
        "relaxed after {steps_relax} steps (kinetic energy {:.3e}, largest overlap {:.2e} r, thresholds met: {met}; {} neighbour-list builds in all)",
        sim.energy.kinetic / n as f64,
        sim.max_pair_overlap(&p),
        sim.counters.rebuilds
    ));
    let contacts = sim.contact_states();
    let f_contact = contacts.iter().map(|c| c.1.abs()).sum::<f64>() / contacts.len().max(1) as f64;
    let f_particle = sim.forces().iter().map(|f| f.norm()).sum::<f64>() / n as f64;
    extra.unbalanced_force_ratio = if f_contact > 0.0 { f_particle / f_contact } else { 0.0 };
    // report: positions wrapped into the box, scaled to SI, in draw order
    let mut pos_si = vec![V3::zeros(); n];
    let mut rad_si = vec![0.0; n];
    for (m, &k) in order.iter().enumerate() {
        pos_si[k] = p.position[m].zip_map(&target, |x, l| x.rem_euclid(l)) * r_unit;
        rad_si[k] = p.radius[m] * r_unit;
    }
    let box_si = [0, 1, 2].map(|a| target[a] * r_unit);
    let mut summary = super::summarise(
        case,
        &pos_si,
        &rad_si,
        box_si,
        r_unit,
        sim.energy.kinetic / n as f64,
        mu,
        [0, steps_compact, steps_relax],
        sim.counters.steps,
        t0.elapsed().as_secs_f64(),
        met,
        Some(V3::from(box_si)),
    );
    let gap = proto.contact_gap_rel * r_unit;
    summary.periodic = Some(periodic_report(&pos_si, &rad_si, V3::from(box_si), gap, summary.lamina_width, extra));
    Ok((Packing { positions: pos_si, radii: rad_si, box_size: box_si }, super::interrupted(summary)))
}

/// Random sequential insertion (G5, stage 1) of the spheres, in draw order, into the periodic box
/// `l` (scaled units): uniform random centres, a centre rejected if its sphere overlaps one already
/// placed (minimum image, a cell grid of edge ≥ one largest diameter). Returns the particles at
/// rest stored along a Morton curve of the grid cells, and `order[m]`, the draw index of the
/// particle stored at m.
fn insert(radii: &[f64], l: V3, rng: &mut Rng) -> Result<(Particles, Vec<usize>), Error> {
    let n = radii.len();
    let r_max = radii.iter().copied().fold(0.0, f64::max);
    let dims: [usize; 3] = std::array::from_fn(|a| ((l[a] / (2.0 * r_max)).floor() as usize).clamp(1, 1 << 20));
    let cell_of = |x: &V3| -> [usize; 3] { std::array::from_fn(|a| ((x[a] / l[a] * dims[a] as f64) as usize).min(dims[a] - 1)) };
    let lin = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    let mut grid: Vec<Vec<u32>> = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
    let mut pos: Vec<V3> = Vec::with_capacity(n);
    let around = |c: usize, m: usize| -> Vec<usize> {
        let mut v: Vec<usize> = [c + m - 1, c, c + 1].iter().map(|k| k % m).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    for (k, &r) in radii.iter().enumerate() {
        let mut placed = false;
        for _ in 0..ATTEMPTS {
            let x = V3::new(rng.uniform() * l.x, rng.uniform() * l.y, rng.uniform() * l.z);
            let c = cell_of(&x);
            let free = around(c[2], dims[2]).into_iter().all(|z| {
                around(c[1], dims[1]).into_iter().all(|y| {
                    around(c[0], dims[0])
                        .into_iter()
                        .all(|xx| grid[lin([xx, y, z])].iter().all(|&j| minimum_image(x - pos[j as usize], &l).norm() >= r + radii[j as usize]))
                })
            });
            if free {
                grid[lin(c)].push(k as u32);
                pos.push(x);
                placed = true;
                break;
            }
        }
        if !placed {
            return Err(ConfigError::inconsistent(
                "packing.protocol.cloud_solid_fraction",
                format!(
                    "random insertion into the periodic box found no free place for particle {k} of {n} in {ATTEMPTS} attempts; lower it (random sequential addition saturates near 0.38)"
                ),
            )
            .into());
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&k| {
        let c = cell_of(&pos[k]);
        (morton(c[0], c[1], c[2]), k)
    });
    let mut p = Particles::default();
    let density = 3.0 / (4.0 * std::f64::consts::PI);
    for &k in &order {
        p.push(pos[k], radii[k], 0, density, 1.0, 300.0);
    }
    Ok((p, order))
}

/// Stage 2 (G5): the box strained from its cloud size to `target` at the strain rate
/// `strain_rate · max(0, 1 − p/p_c)` (p the virial pressure (G4), p_c the compaction pressure);
/// while the servo holds the box (jammed) the friction is lowered (×0.6 every 300 steps, 0 below
/// 0.005). Lands exactly on the target. Returns the friction and the steps.
fn compact(sim: &mut Sim, p: &mut Particles, target: V3, vp: f64, proto: &Protocol, extra: &mut PeriodicReport, pr: &Progress) -> Result<(f64, u64), Error> {
    let p_c = proto.compaction_overlap / 4.0;
    let dt = sim.settings.dt;
    let l0 = sim.periodic_box().unwrap_or(target);
    let mut lambda = l0.x / target.x;
    let mut mu = proto.friction;
    let (mut jammed, mut jammed_frictionless, mut steps) = (0u64, 0u64, 0u64);
    extra.first_jam_solid_fraction = 0.0;
    let phi = |lambda: f64| vp / (target * lambda).product();
    while lambda > 1.0 {
        if crate::interrupt::requested() {
            break;
        }
        let pm = sim.virial_pressure(p);
        let servo = (1.0 - pm / p_c).clamp(0.0, 1.0);
        lambda = (lambda * (1.0 - proto.strain_rate * dt * servo)).max(1.0);
        if servo < 0.05 {
            jammed += 1;
            if extra.first_jam_solid_fraction == 0.0 {
                extra.first_jam_solid_fraction = phi(lambda);
            }
            if mu == 0.0 {
                jammed_frictionless += 1;
            }
            if jammed >= 300 && mu > 0.0 {
                mu = if mu < 0.005 { 0.0 } else { mu * 0.6 };
                sim.settings.friction = mu;
                if mu == 0.0 {
                    p.angular_velocity.iter_mut().for_each(|w| *w = V3::zeros());
                }
                jammed = 0;
                pr.say(format!("jammed at solid fraction {:.4}: friction lowered to {mu:.4}", phi(lambda)));
            }
            if jammed_frictionless >= 20_000 {
                return Err(SolveError::new(
                    "periodic packing compaction",
                    format!(
                        "frictionless and jammed at solid fraction {:.4} for 20000 steps, short of packing.target_solid_fraction = {:.4}: the target is above the random close packing of this size distribution; lower it",
                        phi(lambda),
                        vp / target.product()
                    ),
                )
                .into());
            }
        } else {
            jammed = 0;
        }
        let l = if lambda == 1.0 { target } else { target * lambda };
        let at = Progressed { phi: phi(lambda), pressure_rel: pm / p_c, stage: "compaction" };
        compaction_step(sim, p, l, &mut steps, &at, proto, extra, pr)?;
    }
    extra.compaction_pressure_end_rel = 4.0 * sim.virial_pressure(p);
    if extra.first_jam_solid_fraction == 0.0 {
        extra.first_jam_solid_fraction = phi(1.0);
    }
    pr.say(format!(
        "compacted to the target box after {steps} steps ({} neighbour-list builds so far), friction {mu:.4}, pressure {:.3e} (p_c = {p_c:.3e}), largest kinetic energy/particle {:.2e}",
        sim.counters.rebuilds,
        sim.virial_pressure(p),
        extra.compaction_kinetic_energy_max_rel
    ));
    Ok((mu, steps))
}

/// Where a box compaction stands before its step: solid fraction, pressure / p_c, the stage's name.
struct Progressed {
    phi: f64,
    pressure_rel: f64,
    stage: &'static str,
}

/// One step of a box compaction, (G5) or (G9): the box strained to `l` by (G2), one explicit
/// step, the largest kinetic energy per particle recorded, progress every 2000 steps, and the
/// step budget checked.
#[allow(clippy::too_many_arguments)]
fn compaction_step(
    sim: &mut Sim,
    p: &mut Particles,
    l: V3,
    steps: &mut u64,
    at: &Progressed,
    proto: &Protocol,
    extra: &mut PeriodicReport,
    pr: &Progress,
) -> Result<(), Error> {
    let n = p.len() as f64;
    sim.strain_box(p, l)?;
    sim.step(p)?;
    *steps += 1;
    extra.compaction_kinetic_energy_max_rel = extra.compaction_kinetic_energy_max_rel.max(sim.energy.kinetic / n);
    if steps.is_multiple_of(2000) {
        pr.say(format!(
            "{}: solid fraction {:.4}, pressure/p_c {:.3}, kinetic energy/particle {:.2e}, contacts/particle {:.2}",
            at.stage,
            at.phi,
            at.pressure_rel,
            sim.energy.kinetic / n,
            2.0 * sim.contacts().len() as f64 / n
        ));
    }
    if sim.counters.steps > proto.max_steps {
        return Err(out_of_steps(proto.max_steps, &format!("periodic {}", at.stage), sim.counters.steps));
    }
    Ok(())
}

/// Stage 2 of the die (G9): the footprint driven from its cloud size and the height from the
/// cloud's, along the straight path to `aim`, at `WALL_SPEED` on the longest leg, slowed by the
/// pressure servo of the walled box (virial pressure (G4) against p_c); friction lowered and the
/// packing tapped while it jams ([`Jam`], the walled box's rules); a stall accepts the current
/// box. Returns the friction and the steps; the taps go to `extra`.
#[allow(clippy::too_many_arguments)]
fn compact_die(
    sim: &mut Sim,
    p: &mut Particles,
    aim: V3,
    vp: f64,
    proto: &Protocol,
    rng: &mut Rng,
    extra: &mut PeriodicReport,
    pr: &Progress,
) -> Result<(f64, u64), Error> {
    let p_c = proto.compaction_overlap / 4.0;
    let dt = sim.settings.dt;
    let l0 = sim.periodic_box().unwrap_or(aim);
    let path_len = (0..3).map(|a| (aim[a] - l0[a]).abs()).fold(0.0, f64::max).max(1e-12);
    let (mut lambda, mut steps) = (0.0f64, 0u64);
    let mut jam = Jam::new(proto.friction);
    extra.first_jam_solid_fraction = 0.0;
    while lambda < 1.0 {
        if crate::interrupt::requested() {
            break;
        }
        let pm = sim.virial_pressure(p);
        let servo = (1.0 - pm / p_c).clamp(0.0, 1.0);
        let phi = vp / sim.periodic_box().unwrap_or(aim).product();
        if servo < 0.05 && extra.first_jam_solid_fraction == 0.0 {
            extra.first_jam_solid_fraction = phi;
        }
        if jam.update(sim, p, servo, phi, rng, pr) {
            break;
        }
        lambda += (servo * WALL_SPEED * dt / path_len).min(1.0 - lambda);
        let l = if lambda >= 1.0 { aim } else { l0 + (aim - l0) * lambda };
        let at = Progressed { phi, pressure_rel: pm / p_c, stage: "die compaction" };
        compaction_step(sim, p, l, &mut steps, &at, proto, extra, pr)?;
    }
    let l = sim.periodic_box().unwrap_or(aim);
    extra.compaction_pressure_end_rel = 4.0 * sim.virial_pressure(p);
    if extra.first_jam_solid_fraction == 0.0 {
        extra.first_jam_solid_fraction = vp / l.product();
    }
    extra.taps = Some(jam.taps);
    pr.say(format!(
        "die compacted to solid fraction {:.4} ({} taps) after {steps} steps, friction {:.4}, pressure {:.3e} (p_c = {p_c:.3e})",
        vp / l.product(),
        jam.taps,
        jam.mu,
        sim.virial_pressure(p)
    ));
    Ok((jam.mu, steps))
}

/// Stage 3 of the die (G9), the walled relaxation with the box for the walls: while the packing
/// carries load ([`Unloading`]) every edge backs off at `BACKOFF_STRAIN_RATE`·(aimed edge) per
/// time unit; then the kinetic energy is drained. Returns whether the thresholds were met, the
/// steps and the friction.
fn relax_die(sim: &mut Sim, p: &mut Particles, mu: f64, aim: V3, proto: &Protocol, pr: &Progress) -> Result<(bool, u64, f64), Error> {
    let n = p.len();
    let p_c = proto.compaction_overlap / 4.0;
    if mu == 0.0 {
        p.angular_velocity.iter_mut().for_each(|w| *w = V3::zeros());
    }
    let dt = sim.settings.dt;
    let mut un = Unloading::new(proto, n);
    let mut steps = 0u64;
    let met = loop {
        if un.backing_off {
            for _ in 0..50 {
                let l = sim.periodic_box().unwrap_or(aim) + aim * (BACKOFF_STRAIN_RATE * dt);
                sim.strain_box(p, l)?;
                sim.step(p)?;
            }
        } else {
            sim.run(p, 50)?;
        }
        steps += 50;
        if crate::interrupt::requested() {
            break false;
        }
        if mu > 0.0 {
            stop_rattler_spin(sim, p);
        }
        let ke = sim.energy.kinetic;
        let ov = sim.max_pair_overlap(p);
        if un.relaxed(ke, ov) {
            break true;
        }
        let pm = sim.virial_pressure(p);
        if un.update(ke, ov, pm).0 {
            pr.say(format!("relaxed with largest overlap {ov:.2e} r: backing the box off (pressure {pm:.3e})"));
        }
        if !un.backing_off {
            drain_kinetic_energy(sim, ov, un.ov_tol, ke, n, pr);
        }
        if steps.is_multiple_of(2000) {
            pr.say(format!(
                "relax: kinetic energy/particle {:.2e}, largest overlap {ov:.2e} r, pressure/p_c {:.3e}, backing off {}",
                ke / n as f64,
                pm / p_c,
                un.backing_off
            ));
        }
        if sim.counters.steps > proto.max_steps {
            break false;
        }
    };
    Ok((met, steps, mu))
}

/// Stage 3 (G5): the box fixed at the target; relaxed until the kinetic energy per particle and the
/// largest overlap are below their thresholds. While the packing rests with overlaps above the
/// threshold (it carries load at this solid fraction and friction), the friction is lowered as in
/// the compaction; once the overlaps are below it a viscous damping drains the kinetic energy.
/// Returns whether the thresholds were met within the budget, the steps and the final friction.
fn relax(sim: &mut Sim, p: &mut Particles, mut mu: f64, proto: &Protocol, pr: &Progress) -> Result<(bool, u64, f64), Error> {
    let n = p.len();
    let ke_tol = proto.kinetic_energy_rel * n as f64;
    let ov_tol = proto.max_overlap_rel;
    let (mut steps, mut quiet) = (0u64, 0u32);
    // frictionless, at rest and still overlapping: the overlap every 100 such checks
    let (mut stuck, mut ov_at_check) = (0u32, f64::INFINITY);
    let met = loop {
        sim.run(p, 50)?;
        if crate::interrupt::requested() {
            break false;
        }
        steps += 50;
        if mu > 0.0 {
            stop_rattler_spin(sim, p);
        }
        let ke = sim.energy.kinetic;
        let ov = sim.max_pair_overlap(p);
        if ke < ke_tol && ov < ov_tol {
            break true;
        }
        quiet = if ov >= ov_tol && ke < 100.0 * ke_tol { quiet + 1 } else { 0 };
        if quiet >= 4 && mu > 0.0 {
            mu = if mu < 0.005 { 0.0 } else { mu * 0.6 };
            sim.settings.friction = mu;
            if mu == 0.0 {
                p.angular_velocity.iter_mut().for_each(|w| *w = V3::zeros());
            }
            quiet = 0;
            pr.say(format!("at rest with largest overlap {ov:.2e} r: friction lowered to {mu:.4}"));
        }
        if mu == 0.0 && ov >= ov_tol && ke < 100.0 * ke_tol {
            stuck += 1;
            if stuck.is_multiple_of(100) {
                if ov > 0.99 * ov_at_check {
                    // the target is above the jamming point of the frictionless packing: it cannot
                    // become stress-free in this box (the caller reports the thresholds not met)
                    pr.say(format!("frictionless, at rest and jammed with largest overlap {ov:.2e} r: giving up"));
                    break false;
                }
                ov_at_check = ov;
            }
        }
        drain_kinetic_energy(sim, ov, ov_tol, ke, n, pr);
        if steps.is_multiple_of(2000) {
            pr.say(format!(
                "relax: kinetic energy/particle {:.2e}, largest overlap {ov:.2e} r, pressure/p_c {:.3e}",
                ke / n as f64,
                4.0 * sim.virial_pressure(p) / proto.compaction_overlap
            ));
        }
        if sim.counters.steps > proto.max_steps {
            break false;
        }
    };
    Ok((met, steps, mu))
}

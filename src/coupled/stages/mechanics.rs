//! Stage 4, mechanics: the load increments (F5) of the step's sintering approach along each
//! contact's e3, with thermal expansion and an applied load, solved by the bonded system; the
//! particles move by the solution.

use super::Window;
use crate::coupled::Simulation;
use crate::coupled::expansion::StepTerms;
use crate::error::Error;
use crate::mechanics::sliding::{self, NeckViscosities};
use nalgebra::Vector3;

/// The viscosities of every neck at time `t` [s] (docs/mechanics.md (B24), (B29), (B30)): the
/// tangential viscosity `f·(R*/a)²/M_c` [N·s/m] with the neck radius of its current state and the
/// normal mobility M_c (M13) of its 7-DOF model at its own temperature (the furnace profile when
/// isothermal, else the contact temperature of its particles), the rolling and twisting
/// viscosities, and the link viscosities of the load distribution's viscous network — empty when
/// a contact has no transport (M_c = 0: it does not slide, η_t = +∞, and distributions use the
/// Maxwell links). None without sliding.
pub(in crate::coupled) fn sliding_viscosities(sim: &Simulation, t: f64) -> Result<Option<NeckViscosities>, Error> {
    let Some(f) = sim.settings.mechanics.sliding else { return Ok(None) };
    let m = sim.contacts.len();
    let mut v = NeckViscosities { tangential: Vec::with_capacity(m), rolling: Vec::with_capacity(m), network: Vec::with_capacity(m) };
    for (k, (c, &[i, j])) in sim.contacts.state.iter().zip(&sim.contacts.pairs).enumerate() {
        let (temp, cp) = sim.pair_params(i, j, t);
        let ctx = |e: crate::error::ModelError| e.with_context(format!("sliding viscosity: contact {k} ({i}–{j}) at t = {t} s"));
        let coeffs = cp.at(temp).map_err(ctx)?;
        let (_, mobility) = crate::models::diffusion7::load_response(&c.y, &coeffs).map_err(ctx)?;
        let eta_t = sliding::tangential_viscosity(f, c.y[0], c.r0[0], c.r0[1], mobility);
        v.tangential.push(eta_t);
        v.rolling.push(sliding::rolling_viscosities(eta_t, mobility, c.y[0]));
        if let Some(l) = sliding::network_links(eta_t, mobility, c.y[0]) {
            v.network.push(l);
        }
    }
    if v.network.len() != m {
        v.network.clear();
    }
    Ok(Some(v))
}

/// The tension floor of every contact's normal force at time `t` [s] with sliding (docs/pressure.md
/// (P5)): `−F_s = −v0/M_c` [N] (compression positive), the tensile force that stops the contact's
/// free approach (M14), or 0 where it does not approach (v0 ≤ 0) or has no transport. A tensile
/// force up to it only slows the approach, which the 7-DOF model describes; beyond it the neck
/// would separate. None without sliding: the normal forces are clamped to compression.
pub(in crate::coupled) fn tension_floors(sim: &Simulation, t: f64) -> Result<Option<Vec<f64>>, Error> {
    if sim.settings.mechanics.sliding.is_none() {
        return Ok(None);
    }
    let mut floors = Vec::with_capacity(sim.contacts.len());
    for (k, (c, &[i, j])) in sim.contacts.state.iter().zip(&sim.contacts.pairs).enumerate() {
        let (temp, cp) = sim.pair_params(i, j, t);
        let ctx = |e: crate::error::ModelError| e.with_context(format!("tension floor: contact {k} ({i}–{j}) at t = {t} s"));
        let coeffs = cp.at(temp).map_err(ctx)?;
        let (v0, mobility) = crate::models::diffusion7::load_response(&c.y, &coeffs).map_err(ctx)?;
        let floor = if v0 > 0.0 && mobility > 0.0 && (v0 / mobility).is_finite() { -v0 / mobility } else { 0.0 };
        floors.push(floor);
    }
    Ok(Some(floors))
}

/// What the mechanics stage gives the correction.
pub(in crate::coupled) struct Motion {
    /// Unit axis e3 of each contact at the step's start (A → B).
    pub e3: Vec<Vector3<f64>>,
    /// Axial approach ξ of each contact over the step (C1) [m].
    pub xi: Vec<f64>,
    /// ξ for the correction: net of the thermal elongation, in the reference geometry of the
    /// 7-DOF contacts (X8); ξ itself without thermal expansion [m].
    pub xi_ref: Vec<f64>,
    /// The thermal terms of the step ((X3)–(X7)); None without thermal expansion.
    pub thermal: Option<StepTerms>,
}

/// Stage 4: load increments (F5) along e3 of the step, the bonded solve (an isolated pair
/// instead approaches by exactly the 7-DOF prediction, in the correction) and the particles
/// moved. `temps_old`: the particle temperatures at the step's start [K].
pub(in crate::coupled) fn mechanics(sim: &mut Simulation, w: &Window, temps_old: &[f64]) -> Result<Motion, Error> {
    let (t1, end) = (w.t1, w.end);
    let p = &sim.prep.scene.particles;
    let m = sim.contacts.len();
    let mut e3 = Vec::with_capacity(m);
    let mut approach = Vec::with_capacity(m);
    for (c, &[i, j]) in sim.contacts.state.iter().zip(&sim.contacts.pairs) {
        let d = sim.branch(i, j);
        e3.push(d / d.norm());
        approach.push((c.y_prev[3] - c.y[3]) + (c.y_prev[6] - c.y[6]));
    }
    // thermal expansion (docs/coupled.md (X3)–(X6)): each bond's eigen-approach in the
    // current geometry is the scaled sintering approach less the thermal elongation
    let thermal = sim.expansion.as_ref().map(|x| {
        let temps_end = match &sim.prep.isothermal {
            Some(prof) => vec![prof.temperature(if t1 >= end * (1.0 - 1e-12) { end } else { t1 }); p.len()],
            None => p.temperature.clone(),
        };
        x.step_terms(p, &sim.contacts.pairs, &x.strains(p, temps_old), &x.strains(p, &temps_end), &sim.planes)
    });
    if let Some(th) = &thermal {
        for ((a, f), dth) in approach.iter_mut().zip(&th.factor).zip(&th.elongation) {
            *a = f * *a - dth;
        }
    }
    let visc = sliding_viscosities(sim, t1)?;
    sim.mechanics.set_sliding(visc.map(|v| (v, w.dt)));
    let p = &sim.prep.scene.particles;
    let xi: Vec<f64> = if p.len() == 2 {
        if let Some(th) = &thermal {
            // the predictor (X7) moves both; B covers the rest of the approach in the correction
            for (x, q) in sim.prep.scene.particles.position.iter_mut().zip(&th.predictor) {
                *x += q;
            }
        }
        approach
    } else if sim.cell.is_some() {
        periodic_solve(sim, w, &approach)?
    } else {
        bonded_solve(sim, t1, &approach, thermal.as_ref())?
    };
    crate::finite::ensure_finite("mechanics", sim.step + 1, t1, "contact", "axial approach", xi.iter().copied())?;
    // (X8): the correction gets the mechanical approach net of the thermal elongation, in
    // the reference geometry of the 7-DOF contacts (the pair moves by the full ξ above)
    let xi_ref = match &thermal {
        Some(th) => xi.iter().zip(&th.elongation).zip(&th.factor).map(|((x, d), f)| (x + d) / f).collect(),
        None => xi.clone(),
    };
    Ok(Motion { e3, xi, xi_ref, thermal })
}

/// The bonded solve of a packing (more than two particles) for the eigen-approach `approach` [m]
/// and the applied load's increment over the step ending at `t1` [s]; moves the particles and
/// returns ξ per contact [m].
fn bonded_solve(sim: &mut Simulation, t1: f64, approach: &[f64], thermal: Option<&StepTerms>) -> Result<Vec<f64>, Error> {
    // the applied load enters as its increment over the step (docs/pressure.md (P2))
    let external = sim.load_increment(t1);
    elastic_at_temperature(sim)?;
    let radii = thermal.map(|th| th.radii.as_slice());
    // with thermal expansion the solve takes what the predictor (X7) leaves
    let solve_approach: std::borrow::Cow<[f64]> = match thermal {
        Some(th) => approach.iter().zip(&th.predictor_approach).map(|(a, q)| a - q).collect::<Vec<f64>>().into(),
        None => approach.into(),
    };
    let (mut du, mut xi) = sim.mechanics.solve(&sim.prep.scene.particles, &sim.contacts, &solve_approach, external.as_deref(), radii)?;
    if let Some(th) = thermal {
        du.iter_mut().zip(&th.predictor).for_each(|(d, q)| *d += q);
        xi.iter_mut().zip(&th.predictor_approach).for_each(|(x, q)| *x += q);
    }
    for (x, d) in sim.prep.scene.particles.position.iter_mut().zip(&du) {
        *x += d;
    }
    Ok(xi)
}

/// A material with an E(T) table (docs/materials.md (L1)): each particle's `[E(T_i), ν]` at its
/// current temperature, so that each link takes the constants of its two particles at theirs.
/// Nothing changes for materials without a table.
fn elastic_at_temperature(sim: &mut Simulation) -> Result<(), Error> {
    if sim.d7_materials.iter().all(|m| m.young_modulus_table.is_none()) {
        return Ok(());
    }
    let p = &sim.prep.scene.particles;
    let iso = sim.prep.isothermal.as_ref().map(|prof| prof.temperature(sim.t));
    let per: Vec<[f64; 2]> = p
        .material
        .iter()
        .zip(&p.temperature)
        .map(|(&k, &t)| {
            let m = &sim.d7_materials[k as usize];
            [m.young_modulus_at(iso.unwrap_or(t)), m.poisson_ratio]
        })
        .collect();
    if let Some(sys) = sim.mechanics.sys.as_mut() {
        sys.set_particle_elastic(Some(per))?;
    }
    Ok(())
}

/// The bonded solve on the periodic cell (docs/mechanics.md (B13)–(B21)): the cell controls of
/// the window `w`, the particles moved by `Δu + ΔE·x`, the cell deformed to `(I + ΔE)·L`, the
/// mean stress (B20) accumulated; returns ξ per contact [m].
fn periodic_solve(sim: &mut Simulation, w: &Window, approach: &[f64]) -> Result<Vec<f64>, Error> {
    let (Some(cell), Some(cs)) = (sim.cell.as_ref(), sim.settings.mechanics.cell.as_ref()) else {
        return Err(crate::error::ModelError::new("periodic mechanics: the cell was not set up").into());
    };
    let controls = cs.step_controls(w.t1, w.dt, &cell.applied);
    let target = cs.stress_at(w.t1);
    let m = cell.matrix();
    let (du, xi, step) = sim.mechanics.solve_periodic(&sim.prep.scene.particles, &sim.contacts, approach, &m, &controls)?;
    for (x, d) in sim.prep.scene.particles.position.iter_mut().zip(&du) {
        *x += d;
    }
    let Some(cell) = sim.cell.as_mut() else { return Ok(xi) };
    cell.deform(&crate::mechanics::periodic::strain_tensor(&step.strain));
    for k in 0..6 {
        cell.stress[k] += step.stress[k];
    }
    for (k, c) in controls.iter().enumerate() {
        if matches!(c, crate::mechanics::periodic::CellControl::Stress(_)) {
            cell.applied[k] = target[k];
        }
    }
    if step.load_scale > 0.0 {
        cell.gauge_reaction = cell.gauge_reaction.max(step.gauge_reaction / step.load_scale);
    }
    Ok(xi)
}

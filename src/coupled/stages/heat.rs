//! Stage 2, heat: the implicit heat network over the step, with pipe conductances from the
//! current necks (docs/heat-model.md).

use super::Window;
use crate::coupled::{NeckSource, Simulation};
use crate::error::{Error, ModelError};
use crate::heat::{Conductance, HeatStepInfo};

/// Stage 2: advances the particle temperatures over `w` (nothing when the run is isothermal).
/// A non-finite temperature restores `temps_old` [K] and fails. Returns the heat balance of the
/// step, added to the run's totals only when the step is kept.
pub(in crate::coupled) fn heat(sim: &mut Simulation, w: &Window, temps_old: &[f64]) -> Result<Option<HeatStepInfo>, Error> {
    if sim.heat.is_none() {
        return Ok(None);
    }
    let mut heat_info = None;
    let k = sim.pipe_parts()?;
    let control = crate::scene::step_control(&sim.prep.case)?.map(|c| crate::heat::adaptive::StepControl { dt_min: 1e-6 * w.dt, dt_max: w.dt, ..c });
    if let Some(net) = sim.heat.as_mut() {
        // contact pipes, then the gap pipes of the current positions (heat-model.md (H18)–(H23))
        let p = &sim.prep.scene.particles;
        let (k, _) = crate::heat::gap::attach(net, sim.prep.gap.as_mut(), &p.position, &p.radius, &sim.contacts.pairs, k)?;
        heat_info = Some(crate::heat::adaptive::advance(net, w.t0, w.dt, &mut sim.prep.scene.particles.temperature, &k, control)?.0);
    }
    if let Err(e) = crate::finite::ensure_finite("heat", sim.step + 1, w.t1, "particle", "temperature", sim.prep.scene.particles.temperature.iter().copied()) {
        sim.undo_sweep(temps_old);
        return Err(e.into());
    }
    Ok(heat_info)
}

impl Simulation {
    /// Pipe conductances from the current necks [W/K].
    pub(crate) fn conductances(&self) -> Result<Vec<f64>, ModelError> {
        Ok(self.pipe_parts()?.iter().map(|p| p.pair).collect())
    }

    /// Halves and series conductance of every pipe at the materials' constant κ [W/K], with the
    /// crowding of each neck from the current necks and branch vectors (heat-model.md (H8a)).
    pub(crate) fn pipe_parts(&self) -> Result<Vec<crate::heat::PipeConductance>, ModelError> {
        let p = &self.prep.scene.particles;
        let law: &Conductance = &self.prep.conductance;
        let mats = &self.prep.scene.materials;
        let eps = self.thermal_strains();
        let necks: Vec<f64> = self
            .contacts
            .pairs
            .iter()
            .zip(&self.contacts.state)
            .enumerate()
            .map(|(k, (&[i, j], c))| {
                let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
                Ok(match self.settings.neck {
                    NeckSource::SevenDof => c.y[0],
                    NeckSource::VolumeConserving => {
                        // in the reference geometry of the contact (X9)
                        let d = match &eps {
                            Some(e) => crate::coupled::expansion::ThermalExpansion::reference_distance(p, e, i as usize, j as usize, self.distance(i, j)),
                            None => self.distance(i, j),
                        };
                        let h = ri + rj - d;
                        crate::neck::solve(ri, rj, h).map_err(|e| e.with_context(format!("contact {k} ({i}–{j}) at t = {} s", self.t)))?.a
                    }
                })
            })
            .collect::<Result<_, ModelError>>()?;
        let branch: Vec<nalgebra::Vector3<f64>> = self.contacts.pairs.iter().map(|&[i, j]| self.branch(i, j)).collect();
        let phi = if law.multi_neck == crate::heat::MultiNeck::None {
            vec![[1.0, 1.0]; necks.len()]
        } else {
            crate::heat::pipes::crowding(&self.contacts.pairs, &branch, &necks, p.len(), law)
        };
        let mut parts: Vec<crate::heat::PipeConductance> = self
            .contacts
            .pairs
            .iter()
            .zip(necks.iter().zip(&phi))
            .map(|(&[i, j], (&a, &ph))| {
                let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
                let (ki, kj) = (mats[p.material[i as usize] as usize].conductivity, mats[p.material[j as usize] as usize].conductivity);
                law.pipe_crowded(ki, kj, ri, rj, a, ph)
            })
            .collect();
        // the bound (H8d): with the cell's solid fraction in a periodic cell
        let solid = self.cell.as_ref().map(|c| crate::heat::pipes::solid_fraction(&p.radius, c.volume()));
        let kappa: Vec<f64> = p.material.iter().map(|&m| mats[m as usize].conductivity).collect();
        crate::heat::pipes::bound_halves(&mut parts, &self.contacts.pairs, &branch, &necks, &p.radius, &kappa, law, solid);
        Ok(parts)
    }
}

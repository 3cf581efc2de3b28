//! The applied load of a step (docs/pressure.md): the nodal forces at a time, their increment over
//! the step (P2) and the contacts' normal forces from the load distribution (P3).

use crate::coupled::Simulation;
use crate::error::Error;
use crate::mechanics::NodalLoad;
use nalgebra::Vector3;

impl Simulation {
    /// The nodal forces of the applied load at time `t` [s] with the current extents (P1) [N].
    pub(in crate::coupled) fn load_forces_at(&self, t: f64) -> Option<Vec<Vector3<f64>>> {
        let ls = self.load.as_ref()?;
        let sigma = ls.settings.stress.at(t);
        let free = !self.settings.mechanics.constrain_planes;
        Some(crate::coupled::load::nodal_forces(
            ls.settings.mode,
            sigma,
            &self.extents(),
            &self.prep.scene.particles.radius,
            &self.far_layer,
            &self.near_layer,
            free,
        ))
    }

    /// (P2): the increment of the applied nodal forces over the step ending at `t1`, recorded as
    /// applied; None when there is no load or the increment is zero.
    pub(in crate::coupled) fn load_increment(&mut self, t1: f64) -> Option<Vec<NodalLoad>> {
        let target = self.load_forces_at(t1)?;
        let ls = self.load.as_mut()?;
        let inc: Vec<Vector3<f64>> = target.iter().zip(&ls.applied).map(|(t, a)| t - a).collect();
        ls.applied = target;
        crate::coupled::load::as_nodal_loads(&inc)
    }

    /// (P3): sets every contact's normal force from the load distribution at `t0` [s]: solved
    /// afresh when contacts appeared, at the first loaded step and every
    /// [`crate::coupled::load::REDISTRIBUTE_EVERY`] steps, otherwise the last solve scaled by the total
    /// applied force. Without a load (or at zero stress) every normal force is exactly 0.
    pub(in crate::coupled) fn update_load_forces(&mut self, t0: f64) -> Result<(), Error> {
        if self.cell.is_some() {
            return self.update_cell_forces(t0);
        }
        let Some(f) = self.load_forces_at(t0) else { return Ok(()) };
        let total = crate::coupled::load::total_force(&f);
        let m = self.contacts.len();
        let step = self.step;
        let Some(ls) = self.load.as_ref() else { return Ok(()) };
        if total == 0.0 {
            self.contacts.state.iter_mut().for_each(|c| c.normal_force = 0.0);
            return Ok(());
        }
        let resolve = ls.ref_total == 0.0 || ls.ref_contacts != m || step >= ls.ref_step + crate::coupled::load::REDISTRIBUTE_EVERY;
        if resolve {
            let Some(loads) = crate::coupled::load::as_nodal_loads(&f) else { return Ok(()) };
            let visc = super::sliding_viscosities(self, t0)?;
            self.mechanics.set_sliding(visc.map(|v| (v, self.dt)));
            let (normal, force) = self.mechanics.distribute(&self.prep.scene.particles, &self.contacts, &loads)?;
            crate::finite::ensure_finite("load distribution", step + 1, t0, "contact", "normal force", normal.iter().copied())?;
            let Some(ls) = self.load.as_mut() else { return Ok(()) };
            ls.contact_normal = normal;
            ls.contact_force = force;
            ls.ref_total = total;
            ls.ref_contacts = m;
            ls.ref_step = step;
            ls.solves += 1;
        }
        let Some(ls) = self.load.as_ref() else { return Ok(()) };
        let scale = total / ls.ref_total;
        let lim = ls.settings.contact_stress_limit;
        let floors = super::tension_floors(self, t0)?;
        for (k, (c, &nf)) in self.contacts.state.iter_mut().zip(&ls.contact_normal).enumerate() {
            // (P5): compression only (with sliding: tension down to the force that stops the
            // approach), at most the flow stress over the neck area π a² of the step's start
            let cap = lim * std::f64::consts::PI * c.y[0] * c.y[0];
            let floor = floors.as_ref().map_or(0.0, |f| f[k]);
            c.normal_force = (nf * scale).clamp(floor, cap);
        }
        Ok(())
    }
}

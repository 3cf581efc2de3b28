//! Stage 1, topology: contacts for the pairs that have come to touch (docs/coupled.md "New
//! contacts").

use crate::coupled::{NewContactState, Simulation, new_contact_neck};
use crate::error::{Error, ModelError};
use crate::models::diffusion7::Contact7;

/// Stage 1: the neighbour search of the step, every `contacts.detect_every` steps after the start
/// (none with `contacts.detect_new = false`).
pub(in crate::coupled) fn topology(sim: &mut Simulation, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
    if sim.settings.detect_new && sim.step > 0 && sim.step.is_multiple_of(sim.settings.detect_every) {
        sim.add_new_contacts(log)?;
    }
    Ok(())
}

impl Simulation {
    /// Contacts for newly touching pairs, with their initial 7-DOF state at time `t`.
    /// At the start (`step == 0`) pairs within `contacts.gap_tolerance` get the seed state
    /// (I1)–(I4); afterwards pairs within `contacts.new_contact_gap` get the state of
    /// `contacts.new_contact_state` (docs/coupled.md "New contacts"). Returns the number added.
    pub fn add_new_contacts(&mut self, log: &mut dyn FnMut(&str)) -> Result<usize, Error> {
        let p = &self.prep.scene.particles;
        let during_run = self.step > 0;
        let gap = if during_run { self.settings.new_gap } else { self.settings.gap };
        let state = if during_run { self.settings.new_state } else { NewContactState::Seed };
        // with thermal expansion the search sees the expanded radii and each contact starts from
        // the reference distance (X9) of its pair
        let eps = self.thermal_strains();
        let radii: std::borrow::Cow<[f64]> = match &eps {
            Some(e) => p.radius.iter().zip(e).map(|(r, e)| r * (1.0 + e)).collect::<Vec<f64>>().into(),
            None => (&p.radius[..]).into(),
        };
        let r_mean = if eps.is_some() { radii.iter().sum::<f64>() / radii.len().max(1) as f64 } else { p.mean_radius() };
        let found = match &self.cell {
            Some(c) => c.touching(&p.position, &radii, gap * r_mean)?,
            None => crate::contacts::detect::touching_pairs(&p.position, &radii, gap * r_mean),
        };
        let existing: std::collections::HashSet<(u32, u32)> = self.contacts.pairs.iter().map(|&[i, j]| (i, j)).collect();
        let mut added = 0;
        // overlap at detection relative to the smaller radius (log only)
        let mut overlaps = Vec::new();
        for (i, j) in found {
            if existing.contains(&(i, j)) {
                continue;
            }
            let (ri, rj) = (p.radius[i as usize], p.radius[j as usize]);
            let d_now = match &eps {
                Some(e) => crate::coupled::expansion::ThermalExpansion::reference_distance(p, e, i as usize, j as usize, self.distance(i, j)),
                None => self.distance(i, j),
            };
            overlaps.push((ri + rj - d_now) / ri.min(rj));
            // a pair within the gap tolerance starts as touching (I1 needs d ≤ R_A + R_B)
            let d = d_now.min(ri + rj);
            let ctx = |e: ModelError| e.with_context(format!("new contact between particles {i} and {j} at t = {} s", self.t));
            let c = match state {
                NewContactState::Seed => Contact7::new(ri, rj, d, self.t, self.settings.epsilon, self.settings.eta).map_err(ctx)?,
                NewContactState::VolumeConserving => {
                    let a0 = new_contact_neck(ri, rj, d_now, self.settings.epsilon).map_err(ctx)?;
                    Contact7::with_neck(ri, rj, d, self.t, a0, self.settings.eta).map_err(ctx)?
                }
            };
            self.contacts.pairs.push([i, j]);
            self.contacts.state.push(c);
            self.contacts.dl_bar.push(0.0);
            self.contacts.substeps.push(0);
            self.contacts.dose.push(Default::default());
            added += 1;
        }
        if added > 0 && during_run {
            overlaps.sort_by(f64::total_cmp);
            let apart = overlaps.iter().filter(|&&h| h <= 0.0).count();
            // detail (console at -v, always in log.txt): the status lines count new contacts
            log(&format!(
                "{}t = {}: {added} new contacts ({} in all); overlap at detection h/R_min median {:.3e}, max {:.3e}, {apart} within the gap tolerance without overlap",
                crate::logging::DETAIL,
                crate::units::fmt_seconds(self.t),
                self.contacts.len(),
                overlaps[overlaps.len() / 2],
                overlaps[overlaps.len() - 1]
            ));
        }
        Ok(added)
    }
}

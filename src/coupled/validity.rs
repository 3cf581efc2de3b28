//! The checks after a completed step: the state finite, the packing within the model's range,
//! no particle molten, a warning when a contact rises above its material's calibrated range and a
//! log.txt note when it first falls below it (the verdict on that comes at the end, [`super::dose`]).

use super::Simulation;
use crate::error::{Error, ModelError};

impl Simulation {
    /// After a completed step: every state finite, relative density at most 1, no particle at or
    /// above its material's melting temperature (ModelErrors naming step and particle/contact),
    /// a warning, once per material, when a contact temperature rises above the range its
    /// diffusion data are calibrated for, and a log.txt note the first time one falls below it
    /// (the lowest temperature is kept for the verdict of docs/diffusion7.md (V3)).
    pub(super) fn check_state(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let p = &self.prep.scene.particles;
        let at = format!("step {}, t = {:e} s", self.step, self.t);
        if let Some(i) = (0..p.len()).find(|&i| !(p.position[i].iter().all(|v| v.is_finite()) && p.temperature[i].is_finite())) {
            return Err(ModelError::new(format!(
                "non-finite state of particle {i} (position {:?}, temperature {} K) after {at}",
                p.position[i].as_slice(),
                p.temperature[i]
            ))
            .into());
        }
        if let Some(k) = self.contacts.state.iter().position(|c| !c.y.iter().all(|v| v.is_finite())) {
            let [i, j] = self.contacts.pairs[k];
            return Err(
                ModelError::new(format!("non-finite 7-DOF state of contact {k} (particles {i}, {j}) after {at}: {:?}", self.contacts.state[k].y)).into()
            );
        }
        let rho = self.relative_density();
        if !(rho.is_finite() && rho <= 1.0) {
            return Err(ModelError::new(format!(
                "relative density {rho:.6} after {at}: above 1 (or not finite), the packing has left the model's range (eq. 49)"
            ))
            .into());
        }
        for (i, (&t, &m)) in p.temperature.iter().zip(&p.material).enumerate() {
            let mat = &self.d7_materials[m as usize];
            if let Some(tm) = mat.melting_temperature
                && t >= tm
            {
                return Err(ModelError::new(format!("particle {i} of material \"{}\" reached {t:.1} K after {at}, at or above its melting/solidus temperature {tm} K: solid-state sintering no longer applies", mat.name)).into());
            }
        }
        // calibrated range of each material's diffusion data, seen at the contacts
        let harmonic = self.settings.harmonic;
        let iso = self.prep.isothermal.as_ref().map(|prof| prof.temperature(self.t));
        let mut lo_hi = vec![(f64::INFINITY, f64::NEG_INFINITY); self.d7_materials.len()];
        for &[i, j] in &self.contacts.pairs {
            let (ti, tj) = (p.temperature[i as usize], p.temperature[j as usize]);
            let tc = iso.unwrap_or_else(|| super::stages::contact_temperature(harmonic, ti, tj));
            for m in [p.material[i as usize], p.material[j as usize]] {
                let e = &mut lo_hi[m as usize];
                *e = (e.0.min(tc), e.1.max(tc));
            }
        }
        self.lowest_contact_temperature.resize(lo_hi.len(), f64::MAX);
        for (m, &(lo, hi)) in lo_hi.iter().enumerate() {
            self.lowest_contact_temperature[m] = self.lowest_contact_temperature[m].min(lo);
            let mat = &self.d7_materials[m];
            for (below, t, lim) in [(true, lo, mat.calibrated_min_temperature), (false, hi, mat.calibrated_max_temperature)] {
                let out = if below { t < lim } else { t > lim };
                let tag = format!("material \"{}\": contact temperature {} the calibrated range", mat.name, if below { "below" } else { "above" });
                if !out || self.notes.contains(&tag) {
                    continue;
                }
                let w = format!(
                    "{tag} {:.1}–{:.1} K ({t:.1} K first at {at}): its diffusion data are extrapolated",
                    mat.calibrated_min_temperature, mat.calibrated_max_temperature
                );
                let seen = self.warnings.iter().any(|x| x.starts_with(&tag));
                self.notes.push(tag);
                if below {
                    // below the range: the first time goes to log.txt (detail); whether it matters
                    // is the end-of-run verdict on the diffusion dose (docs/diffusion7.md (V1)–(V3))
                    log(&format!("{}{w}; the end of the run weighs its share of the sintering (docs/diffusion7.md (V3))", crate::logging::DETAIL));
                } else {
                    // once in summary.json, also across a resume (the notes are not checkpointed)
                    if !seen {
                        self.warnings.push(w.clone());
                    }
                    log(&format!("warning: {w}"));
                }
            }
        }
        Ok(())
    }
}

//! The checks after a completed step: the state finite, the packing within the model's range,
//! no particle molten, and a warning when a contact leaves its material's calibrated range.

use super::Simulation;
use crate::error::{Error, ModelError};

impl Simulation {
    /// After a completed step: every state finite, relative density at most 1, no particle at or
    /// above its material's melting temperature (ModelErrors naming step and particle/contact),
    /// and a warning, once per material and side, when a contact temperature leaves the range its
    /// diffusion data are calibrated for.
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
            let tc = iso.unwrap_or(if harmonic { 2.0 * ti * tj / (ti + tj) } else { 0.5 * (ti + tj) });
            for m in [p.material[i as usize], p.material[j as usize]] {
                let e = &mut lo_hi[m as usize];
                *e = (e.0.min(tc), e.1.max(tc));
            }
        }
        for (m, &(lo, hi)) in lo_hi.iter().enumerate() {
            let mat = &self.d7_materials[m];
            for (below, t, lim) in [(true, lo, mat.calibrated_min_temperature), (false, hi, mat.calibrated_max_temperature)] {
                let out = if below { t < lim } else { t > lim };
                let tag = format!("material \"{}\": contact temperature {} the calibrated range", mat.name, if below { "below" } else { "above" });
                if !out {
                    continue;
                }
                let w = format!(
                    "{tag} {:.1}–{:.1} K ({t:.1} K first at {at}): its diffusion data are extrapolated",
                    mat.calibrated_min_temperature, mat.calibrated_max_temperature
                );
                // summary.json lists the first time a contact leaves the range, as ever
                let first = !self.warnings.iter().any(|x| x.starts_with(&tag));
                if first {
                    self.warnings.push(w.clone());
                }
                // below the range, where every mechanism's D is under 1 % of its value at the
                // range's lower end, the extrapolated diffusion adds less than 1 % of what a
                // calibrated contact does in the same time: detail (log.txt, -v), not a warning
                // (a heat-up from room temperature, issue 25; docs/diffusion7.md §10); the
                // warning comes once the extrapolation matters
                if below && negligible_diffusion(mat, t) {
                    if first {
                        log(&format!(
                            "{}{w} (diffusion is negligible there: every D below {NEGLIGIBLE_DIFFUSION} of its value at {:.1} K; a warning follows if it stops being so)",
                            crate::logging::DETAIL,
                            mat.calibrated_min_temperature
                        ));
                    }
                } else if !self.notes.contains(&tag) {
                    let now = if first {
                        w
                    } else {
                        format!(
                            "{tag} {:.1}–{:.1} K ({t:.1} K at {at}): its diffusion data are extrapolated",
                            mat.calibrated_min_temperature, mat.calibrated_max_temperature
                        )
                    };
                    log(&format!("warning: {now}"));
                    self.notes.push(tag);
                }
            }
        }
        Ok(())
    }
}

/// Below the calibrated range, diffusion whose every coefficient is under this fraction of its
/// value at the range's lower end is negligible (the calibrated-range warning becomes a note).
pub const NEGLIGIBLE_DIFFUSION: f64 = 1e-2;

/// Whether every diffusion mechanism of `mat` at `t` [K] (phase at `t`) runs below
/// [`NEGLIGIBLE_DIFFUSION`] of the same mechanism at the lower end of the calibrated range (M9).
pub fn negligible_diffusion(mat: &crate::models::diffusion7::Material, t: f64) -> bool {
    let t_ref = mat.calibrated_min_temperature;
    let (ph, pr) = (&mat.phases[mat.phase_at(t)], &mat.phases[mat.phase_at(t_ref)]);
    let d = |d0: f64, q: f64, t: f64| crate::models::diffusion7::material::Arrhenius { d0, q }.at(t);
    [
        (ph.d0_surface, ph.q_surface, pr.d0_surface, pr.q_surface),
        (ph.d0_gb, ph.q_gb, pr.d0_gb, pr.q_gb),
        (ph.d0_lattice, ph.q_lattice, pr.d0_lattice, pr.q_lattice),
    ]
    .iter()
    .all(|&(d0, q, d0r, qr)| d(d0, q, t) < NEGLIGIBLE_DIFFUSION * d(d0r, qr, t_ref))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::diffusion7::Material;

    #[test]
    fn diffusion_at_room_temperature_is_negligible_and_just_below_the_range_is_not() {
        let cu = Material::copper();
        // copper's lattice diffusion (Q = 207 kJ/mol): D(293 K)/D(1193 K) ~ 1e-29
        assert!(negligible_diffusion(&cu, 293.15));
        // 1150 K: D_lattice(1150)/D_lattice(1193) = exp(-Q/R (1/1150 - 1/1193)) = 0.51
        assert!(!negligible_diffusion(&cu, 1150.0));
        // the line for the lattice (smallest Q): exp(-207e3/R (1/T - 1/1193)) = 0.01 at T = 1012 K
        let t1 = 1.0 / (1.0 / 1193.0 + (100.0f64).ln() * crate::units::GAS_CONSTANT / 207.0e3);
        assert!(negligible_diffusion(&cu, t1 - 1.0) && !negligible_diffusion(&cu, t1 + 1.0), "{t1}");
        // titanium: alpha below 1156 K, its GB Q = 20.5 kJ/mol keeps GB diffusion alive far down
        let ti = Material::titanium();
        assert!(!negligible_diffusion(&ti, 700.0));
    }
}

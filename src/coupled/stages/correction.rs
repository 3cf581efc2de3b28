//! Stage 5, correction: y4 and y7 of every contact corrected to the mechanical approach
//! ((C1)–(C4), docs/coupled.md; Ivannikov et al. 2022 eq. 44).

use super::Window;
use super::diffusion::contact_temperature;
use super::mechanics::Motion;
use crate::coupled::Simulation;
use crate::error::Error;
use crate::models::diffusion7::{self as d7, PairMaterials};

/// Stage 5: corrects y4, y7 of every contact to the approach ξ of `motion` at the step's end
/// `w.t1`, records ΔL̄ and e3, and moves B of an isolated pair by the 7-DOF approach.
pub(in crate::coupled) fn correction(sim: &mut Simulation, w: &Window, motion: &Motion) -> Result<(), Error> {
    let t1 = w.t1;
    let Motion { e3, xi, xi_ref, thermal } = motion;
    let p2 = sim.prep.scene.particles.len() == 2;
    let (harmonic, factors) = (sim.settings.harmonic, sim.settings.factors);
    for k in 0..sim.contacts.len() {
        let [i, j] = sim.contacts.pairs[k];
        let c = &mut sim.contacts.state[k];
        let star = (c.y[3], c.y[6]);
        let prev = (c.y_prev[3], c.y_prev[6]);
        let r_sum = c.r0[0] + c.r0[1];
        let rates_star = if prev.0 - star.0 + prev.1 - star.1 > 1e-12 * r_sum {
            (0.0, 0.0)
        } else {
            let temp_c = match &sim.prep.isothermal {
                Some(prof) => prof.temperature(t1),
                None => {
                    let tt = &sim.prep.scene.particles.temperature;
                    contact_temperature(harmonic, tt[i as usize], tt[j as usize])
                }
            };
            let pm = PairMaterials {
                a: &sim.d7_materials[sim.prep.scene.particles.material[i as usize] as usize],
                b: &sim.d7_materials[sim.prep.scene.particles.material[j as usize] as usize],
                factors,
            };
            let mut kc = pm.params_at(temp_c).at(temp_c)?;
            kc.normal_force = c.normal_force;
            let r = d7::rates_with(&c.y, &kc)?;
            (r[3], r[6])
        };
        let corr = d7::correct_y4_y7(prev, star, rates_star, xi_ref[k], r_sum);
        // (C4) can push a young contact's cone past tangency (A3) when its neighbours
        // compress it more than its own approach: then the deviation from y* is halved
        // until the state is admissible (counted; docs/decisions.md)
        let mut w = 1.0;
        loop {
            c.y[3] = star.0 + w * (corr.y4 - star.0);
            c.y[6] = star.1 + w * (corr.y7 - star.1);
            let ok = d7::geometry::sides(&c.y).is_ok_and(|(a, b)| a.derivs().is_ok() && b.derivs().is_ok());
            if ok {
                break;
            }
            if w < 1e-6 {
                c.y[3] = star.0;
                c.y[6] = star.1;
                break;
            }
            w *= 0.5;
        }
        if w < 1.0 {
            sim.limited_corrections += 1;
        }
        c.y_prev = c.y;
        c.e3 = [e3[k].x, e3[k].y, e3[k].z];
        sim.contacts.dl_bar[k] = (c.y[3] + c.y[6]) - (star.0 + star.1);
        if p2 {
            // an isolated pair: A stays, B approaches by exactly the 7-DOF prediction
            let ps = &mut sim.prep.scene.particles;
            match thermal {
                Some(th) => ps.position[j as usize] -= (xi[k] - th.predictor_approach[k]) * e3[k],
                None => ps.position[j as usize] -= xi[k] * e3[k],
            }
        }
    }
    crate::finite::ensure_finite_groups("correction", sim.step + 1, t1, "contact", "7-DOF state", sim.contacts.state.iter().map(|c| &c.y))?;
    Ok(())
}

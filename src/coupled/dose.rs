//! The diffusion dose of each contact (the "work of sintering" Θ of master-sintering-curve
//! theory, docs/diffusion7.md §10 (V1)–(V3)): per mechanism the Arrhenius time integral of the
//! contact's run and of the part of it spent below the calibrated range, and the end-of-run
//! verdict on how much of a contact's sintering used extrapolated diffusion data.

use super::Simulation;
use super::stages::Window;
use crate::models::diffusion7::Material;
use rayon::prelude::*;

/// A contact's dose is "material" when more than this share of it (V3) came from below the
/// calibrated range: then the end-of-run verdict is a warning, otherwise a log.txt line.
pub const EXTRAPOLATED_SHARE_LIMIT: f64 = 1e-2;

/// (V1) The dose of one contact per mechanism (surface, grain boundary, lattice), in seconds at
/// the lower end of the calibrated range: Θ̃_x = ∫ D_x(T_c(t))/D_x(T_min) dt over the contact's
/// life (`total`) and over the time its temperature was below T_min (`below`). Single precision:
/// the verdict needs 1 % of the share, and 24 bytes per contact.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Dose {
    /// Θ̃_x over the contact's life, surface / GB / lattice [s at T_min] (V1).
    pub total: [f32; 3],
    /// Θ̃_x over the time below the calibrated range [s at T_min] (V1).
    pub below: [f32; 3],
}

impl Dose {
    /// (V3) The share of the dose made below the calibrated range: the largest over the
    /// mechanisms of Θ_x,below/Θ_x [1] (0 before any dose).
    pub fn share(&self) -> f64 {
        (0..3).filter(|&x| self.total[x] > 0.0).map(|x| self.below[x] as f64 / self.total[x] as f64).fold(0.0, f64::max)
    }

    /// Adds a step of `dt` [s] at contact temperature `t` [K] (the step's midpoint) under `law`.
    pub fn add(&mut self, law: &DoseLaw, t: f64, dt: f64) {
        self.add_ratios(law.ratios(t), t < law.t_min, dt);
    }

    /// Adds a step of `dt` [s] with the ratios (V2) `r` of its temperature, `below` the range or not.
    fn add_ratios(&mut self, r: [f64; 3], below: bool, dt: f64) {
        for x in 0..3 {
            // saturating: a JSON checkpoint cannot hold ∞
            let d = (r[x] * dt) as f32;
            self.total[x] = (self.total[x] + d).min(f32::MAX);
            if below {
                self.below[x] = (self.below[x] + d).min(f32::MAX);
            }
        }
    }
}

/// (V2) The Arrhenius ratios D_x(T)/D_x(T_min) of one material, phase by phase:
/// `exp(a_x − b_x/T)` with a_x = ln(D0_x/D0_x,ref) + Q_x,ref/(R T_min), b_x = Q_x/R.
#[derive(Debug, Clone)]
pub struct DoseLaw {
    /// Lower end of the calibrated range T_min [K].
    pub t_min: f64,
    /// Per phase: its lower temperature [K] and (a_x, b_x) per mechanism.
    phases: Vec<(f64, [(f64, f64); 3])>,
}

impl DoseLaw {
    /// The law (V2) of `mat`: its lower range end T_min [K] and, per phase, a_x [1] and b_x = Q_x/R [K].
    pub fn new(mat: &Material) -> DoseLaw {
        let t_min = mat.calibrated_min_temperature;
        let r = crate::units::GAS_CONSTANT;
        let p0 = &mat.phases[mat.phase_at(t_min)];
        let refs = [(p0.d0_surface, p0.q_surface), (p0.d0_gb, p0.q_gb), (p0.d0_lattice, p0.q_lattice)];
        let phases = mat
            .phases
            .iter()
            .map(|ph| {
                let m = [(ph.d0_surface, ph.q_surface), (ph.d0_gb, ph.q_gb), (ph.d0_lattice, ph.q_lattice)];
                let ab = std::array::from_fn(|x| {
                    let ((d0, q), (d0r, qr)) = (m[x], refs[x]);
                    // a mechanism without data (D0 = 0) carries no dose
                    if d0 > 0.0 && d0r > 0.0 { ((d0 / d0r).ln() + qr / (r * t_min), q / r) } else { (f64::NEG_INFINITY, 0.0) }
                });
                (ph.from_temperature, ab)
            })
            .collect();
        DoseLaw { t_min, phases }
    }

    /// (V2) D_x(t)/D_x(T_min) for surface, GB and lattice at `t` [K].
    pub fn ratios(&self, t: f64) -> [f64; 3] {
        let k = self.phases.iter().rposition(|p| p.0 <= t).unwrap_or(0);
        let ab = &self.phases[k].1;
        std::array::from_fn(|x| (ab[x].0 - ab[x].1 / t).exp())
    }
}

/// The end-of-run verdict of one material whose contacts were below its calibrated range.
#[derive(Debug, Clone, PartialEq)]
pub struct BelowRange {
    /// Material index.
    pub material: usize,
    /// The largest share (V3) over the material's contacts [1].
    pub share: f64,
    /// The contact of that share.
    pub contact: usize,
    /// The lowest contact temperature of the material seen after a step [K].
    pub lowest_temperature: f64,
}

impl Simulation {
    /// The material whose data a contact's dose follows: of the two particles', the one with the
    /// higher lower end of its calibrated range (the first particle's on a tie).
    fn dose_material(&self, i: u32, j: u32) -> usize {
        let p = &self.prep.scene.particles;
        let (a, b) = (p.material[i as usize] as usize, p.material[j as usize] as usize);
        if self.d7_materials[b].calibrated_min_temperature > self.d7_materials[a].calibrated_min_temperature { b } else { a }
    }

    /// (V1) Adds the completed step `w` to every contact's dose, at the contact temperature of
    /// the step's midpoint (the sweep's linear path from `temps_old` [K], or the profile when
    /// isothermal): three exponentials per contact and step (one per material when isothermal).
    pub(super) fn accumulate_dose(&mut self, w: &Window, temps_old: &[f64]) {
        let laws: Vec<DoseLaw> = self.d7_materials.iter().map(DoseLaw::new).collect();
        let dt = w.t1 - w.t0;
        let p = &self.prep.scene.particles;
        let harmonic = self.settings.harmonic;
        let mut dose = std::mem::take(&mut self.contacts.dose);
        dose.resize(self.contacts.pairs.len(), Dose::default());
        let this = &*self;
        match &this.prep.isothermal {
            // one temperature for every contact: the ratios once per material
            Some(prof) => {
                let t = prof.temperature(0.5 * (w.t0 + w.t1));
                let ratios: Vec<[f64; 3]> = laws.iter().map(|l| l.ratios(t)).collect();
                dose.par_iter_mut().zip(this.contacts.pairs.par_iter()).for_each(|(d, &[i, j])| {
                    let m = this.dose_material(i, j);
                    d.add_ratios(ratios[m], t < laws[m].t_min, dt);
                });
            }
            None => {
                let ct = |a: f64, b: f64| super::stages::contact_temperature(harmonic, a, b);
                dose.par_iter_mut().zip(this.contacts.pairs.par_iter()).for_each(|(d, &[i, j])| {
                    let (a, b) = (i as usize, j as usize);
                    let t = 0.5 * (ct(temps_old[a], temps_old[b]) + ct(p.temperature[a], p.temperature[b]));
                    d.add(&laws[this.dose_material(i, j)], t, dt);
                });
            }
        }
        self.contacts.dose = dose;
    }

    /// The verdict (V3) per material whose contacts went below its calibrated range: the largest
    /// share over its contacts, the contact and the lowest temperature; materials never below
    /// the range are left out.
    pub fn below_range_verdict(&self) -> Vec<BelowRange> {
        let mut out: Vec<BelowRange> = Vec::new();
        for (m, mat) in self.d7_materials.iter().enumerate() {
            let lowest = self.lowest_contact_temperature.get(m).copied().unwrap_or(f64::MAX);
            if lowest >= mat.calibrated_min_temperature {
                continue;
            }
            let mut v = BelowRange { material: m, share: 0.0, contact: 0, lowest_temperature: lowest };
            for (k, (d, &[i, j])) in self.contacts.dose.iter().zip(&self.contacts.pairs).enumerate() {
                let s = d.share();
                if self.dose_material(i, j) == m && s > v.share {
                    (v.share, v.contact) = (s, k);
                }
            }
            out.push(v);
        }
        out
    }

    /// The verdict's lines: warnings (share above [`EXTRAPOLATED_SHARE_LIMIT`]) and notes for
    /// log.txt, without prefixes.
    pub fn below_range_messages(&self) -> (Vec<String>, Vec<String>) {
        let (mut warn, mut note) = (Vec::new(), Vec::new());
        for v in self.below_range_verdict() {
            let mat = &self.d7_materials[v.material];
            let [i, j] = self.contacts.pairs.get(v.contact).copied().unwrap_or([0, 0]);
            let what = format!(
                "material \"{}\": {:.3} % of the diffusion dose of contact {} (particles {i}, {j}) came from below the calibrated range {:.1}–{:.1} K (contacts down to {:.1} K; docs/diffusion7.md (V1)–(V3))",
                mat.name,
                100.0 * v.share,
                v.contact,
                mat.calibrated_min_temperature,
                mat.calibrated_max_temperature,
                v.lowest_temperature
            );
            if v.share > EXTRAPOLATED_SHARE_LIMIT {
                warn.push(format!(
                    "{what}: its diffusion data are extrapolated there, more than {} % of the sintering rests on them",
                    100.0 * EXTRAPOLATED_SHARE_LIMIT
                ));
            } else {
                note.push(format!("{what}, the largest share: below {} %, the extrapolation does not matter", 100.0 * EXTRAPOLATED_SHARE_LIMIT));
            }
        }
        (warn, note)
    }

    /// summary.json's `extrapolated_below_range`: per material name, the largest share, its contact
    /// and the lowest contact temperature [K] (materials never below their range left out).
    pub fn below_range_summary(&self) -> serde_json::Value {
        let mut o = serde_json::Map::new();
        for v in self.below_range_verdict() {
            o.insert(
                self.d7_materials[v.material].name.clone(),
                serde_json::json!({"share": v.share, "contact": v.contact, "lowest_temperature_K": v.lowest_temperature}),
            );
        }
        serde_json::Value::Object(o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (V1)–(V3) at piecewise constant temperature: Θ̃_x = Σ r_x(T_k) Δt_k, r_x = exp(−Q_x/R (1/T − 1/T_min)).
    #[test]
    fn the_share_of_a_two_temperature_history_is_the_arrhenius_weighted_time_below() {
        let cu = Material::copper();
        let law = DoseLaw::new(&cu);
        let (t_lo, t_hi, t_min) = (1100.0, 1293.0, cu.calibrated_min_temperature);
        let mut d = Dose::default();
        // 300 s at 1100 K, then 900 s at 1293 K, in steps of 1 s
        for k in 0..1200 {
            d.add(&law, if k < 300 { t_lo } else { t_hi }, 1.0);
        }
        let ph = &cu.phases[0];
        let r = |q: f64, t: f64| (-q / crate::units::GAS_CONSTANT * (1.0 / t - 1.0 / t_min)).exp();
        let share: f64 =
            [ph.q_surface, ph.q_gb, ph.q_lattice].iter().map(|&q| 300.0 * r(q, t_lo) / (300.0 * r(q, t_lo) + 900.0 * r(q, t_hi))).fold(0.0, f64::max);
        assert!((d.share() - share).abs() < 1e-4 * share, "{} vs {share}", d.share());
        // the mechanism with the smallest Q (lattice, 207 kJ/mol) carries the largest share: a
        // quarter of the time below the range is only about 1.1 % of its dose
        assert!(share > 0.01 && share < 0.013, "{share}");
        // at a single temperature the dose is the time itself times r, and wholly below: share 1
        let mut cold = Dose::default();
        cold.add(&law, 1000.0, 50.0);
        assert_eq!(cold.share(), 1.0);
        let ratio = (cold.total[2] as f64) / 50.0;
        assert!((ratio - r(ph.q_lattice, 1000.0)).abs() < 1e-6 * ratio);
    }

    /// An Arrhenius ramp T = T0 + βt below T_min: ∫ r dt = ∫ r(T) dT/β; for Q/(R T) ≫ 1,
    /// ∫_{T0}^{T1} exp(−Q/(R T)) dT ≈ (R T1²/Q) exp(−Q/(R T1)) (1 − 2u + 6u²), u = R T1/Q (asymptotic series).
    #[test]
    fn a_ramp_dose_matches_the_arrhenius_ramp_integral() {
        let cu = Material::copper();
        let law = DoseLaw::new(&cu);
        let (t0, t1, beta) = (600.0, 1150.0, 1.0);
        let mut d = Dose::default();
        let n = 5_500;
        let h = (t1 - t0) / beta / n as f64;
        for k in 0..n {
            d.add(&law, t0 + beta * h * (k as f64 + 0.5), h);
        }
        let q = cu.phases[0].q_lattice;
        let rg = crate::units::GAS_CONSTANT;
        let tm = cu.calibrated_min_temperature;
        let u = rg * t1 / q;
        let approx = rg * t1 * t1 / q * (-q / rg * (1.0 / t1 - 1.0 / tm)).exp() * (1.0 - 2.0 * u + 6.0 * u * u) / beta;
        let got = d.total[2] as f64;
        assert!((got - approx).abs() < 0.01 * approx, "{got} vs {approx}");
    }
}

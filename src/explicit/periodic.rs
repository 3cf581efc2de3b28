//! The periodic box of the driver (docs/packing.md, "Periodic packings", (G1)–(G4)): contacts by
//! minimum image, no walls, and the box strained affinely by the caller.
//!
//! Velocities are the particles' fluctuations about the homogeneous (affine) flow of the box, as
//! in Yade's periodic cell with homothetic resize and LAMMPS `fix deform` without `remap v`: the
//! box strain moves positions (G2) but does not enter the relative velocity of a contact, so the
//! viscous and tangential terms see the fluctuations only. The work of the box strain is not in
//! the energy account (its balance holds only while the box is fixed).

use super::law::ContactModel;
use super::{Explicit, V3};
pub use crate::contacts::detect::minimum_image;
use crate::error::{ConfigError, Error};
use crate::particles::Particles;

/// Refuses a box edge that is not finite and at least two largest diameters `4 r_max` [m]: then a
/// pair touches through one image only and the minimum image (G1) is exact.
fn check_box(l: &V3, p: &Particles, key: &str) -> Result<(), ConfigError> {
    let d_max = 2.0 * p.radius.iter().copied().fold(0.0, f64::max);
    for a in 0..3 {
        if !(l[a].is_finite() && l[a] >= 2.0 * d_max && l[a] > 0.0) {
            return Err(ConfigError::OutOfRange {
                key: key.into(),
                value: l[a],
                range: format!("[2 largest particle diameters = {}, inf)", crate::error::fmt_value(2.0 * d_max)),
                unit: "m".into(),
            });
        }
    }
    Ok(())
}

impl<M: ContactModel> Explicit<M> {
    /// Makes the driver periodic with the box `[0, l)` [m] (particles may lie outside it: every
    /// difference of positions is taken by minimum image (G1)). Refuses walls and a box edge below
    /// two largest diameters of `p`.
    pub fn set_periodic_box(&mut self, l: V3, p: &Particles) -> Result<(), Error> {
        if !self.walls.is_empty() {
            return Err(ConfigError::inconsistent("walls", format!("{} walls given: a periodic box has none", self.walls.len())).into());
        }
        check_box(&l, p, "periodic_box")?;
        self.periodic = Some(l);
        self.ready = false;
        Ok(())
    }

    /// The periodic box [m], if any.
    pub fn periodic_box(&self) -> Option<V3> {
        self.periodic
    }

    /// Strains the periodic box to `l` [m]: every position is mapped affinely, `x_a ← x_a · l_a/L_a`
    /// (G2); velocities are left alone (module docs). The neighbour list stays valid while the
    /// box change since the last build plus the particles' displacements stays within the skin
    /// (G3); the next step rebuilds it otherwise.
    pub fn strain_box(&mut self, p: &mut Particles, l: V3) -> Result<(), Error> {
        let Some(old) = self.periodic else {
            return Err(ConfigError::invalid("explicit: strain_box needs a periodic box (set_periodic_box)").into());
        };
        check_box(&l, p, "periodic_box")?;
        let f = l.component_div(&old);
        for x in p.position.iter_mut() {
            *x = x.component_mul(&f);
        }
        self.periodic = Some(l);
        Ok(())
    }

    /// The mean normal stress of the periodic box from the contacts of the last force evaluation,
    /// the virial `p = Σ_c f_n,c |b_c| / (3 V)` (G4) [Pa], b_c the minimum-image branch vector and
    /// V the box volume; 0 without a periodic box. The tangential forces do not enter the trace
    /// (they are orthogonal to the branch).
    pub fn virial_pressure(&self, p: &Particles) -> f64 {
        let Some(l) = self.periodic else { return 0.0 };
        let mut s = 0.0;
        for ((&(i, j), o), &t) in self.pairs.iter().zip(&self.out).zip(&self.touching) {
            if t {
                s += o.normal_force * minimum_image(p.position[i as usize] - p.position[j as usize], &l).norm();
            }
        }
        s / (3.0 * l.x * l.y * l.z)
    }

    /// Largest particle–particle overlap r_i + r_j − |b| [m] over the neighbour list at the current
    /// positions (minimum image in a periodic box); 0 if no pair overlaps.
    pub fn max_pair_overlap(&self, p: &Particles) -> f64 {
        let mut m: f64 = 0.0;
        for &(i, j) in &self.pairs {
            let (i, j) = (i as usize, j as usize);
            let mut d = p.position[i] - p.position[j];
            if let Some(l) = self.periodic {
                d = minimum_image(d, &l);
            }
            m = m.max(p.radius[i] + p.radius[j] - d.norm());
        }
        m
    }

    /// The rebuild threshold of the particles' displacement [m] and whether the box strain alone
    /// forces a rebuild (G3): with a box change `|ΔL|` since the last build a pair's branch changes
    /// by at most `|Δx_i| + |Δx_j| + |ΔL|`, so each particle may move `(skin − |ΔL|)/2`; once
    /// `|ΔL|` reaches half the skin the list is rebuilt.
    pub(super) fn rebuild_threshold(&self) -> (f64, bool) {
        let skin = self.settings.skin;
        match self.periodic {
            None => (0.5 * skin, false),
            Some(l) => {
                let dl = (l - self.built_box).norm();
                (0.5 * (skin - dl).max(0.0), dl >= 0.5 * skin)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::explicit::law::{Damping, LinearSpringDashpot};
    use crate::explicit::{Settings, time_step};

    fn pair_across_the_face(gap: f64) -> (Particles, V3) {
        let mut p = Particles::default();
        let l = V3::new(10.0, 8.0, 9.0);
        // centres 2 + gap apart through the x face: x = 0.5 and x = 10 − 1.5 − gap
        p.push(V3::new(0.5, 4.0, 4.5), 1.0, 0, 1.0, 1.0, 300.0);
        p.push(V3::new(l.x - 1.5 - gap, 4.0, 4.5), 1.0, 0, 1.0, 1.0, 300.0);
        (p, l)
    }

    fn driver(p: &Particles) -> Explicit<LinearSpringDashpot> {
        let law = LinearSpringDashpot { stiffness: 1.0, damping: Damping::restitution_ratio(1.0) };
        let (dt, _) = time_step(&law, p, 0.05, 0.0, false).unwrap();
        Explicit::new(Settings::new(dt, 1.0), law, Vec::new()).unwrap()
    }

    #[test]
    fn minimum_image_picks_the_nearest_image() {
        let l = V3::new(10.0, 8.0, 9.0);
        let b = minimum_image(V3::new(9.0, -7.5, 4.4), &l);
        assert!((b - V3::new(-1.0, 0.5, 4.4)).norm() < 1e-14, "{b}");
        assert!((minimum_image(V3::new(-21.0, 0.0, 0.0), &l).x + 1.0).abs() < 1e-14);
    }

    #[test]
    fn a_pair_across_a_face_repels_and_conserves_momentum_and_energy() {
        // overlap 0.1 through the x face: the elastic pair oscillates like a free pair
        let (mut p, l) = pair_across_the_face(-0.1);
        let mut sim = driver(&p);
        sim.set_periodic_box(l, &p).unwrap();
        sim.initialise(&mut p).unwrap();
        assert_eq!(sim.neighbour_pairs(), &[(0, 1)]);
        // repulsion: particle 0 is pushed in +x (its partner's image sits at x = −1.4)
        assert!(sim.forces()[0].x > 0.0 && (sim.forces()[0].x - 0.1).abs() < 1e-12, "{}", sim.forces()[0]);
        assert!((sim.max_pair_overlap(&p) - 0.1).abs() < 1e-12);
        // virial: f_n |b| / (3V) = 0.1 · 1.9 / (3 · 720)
        assert!((sim.virial_pressure(&p) - 0.1 * 1.9 / (3.0 * 720.0)).abs() < 1e-15);
        let e0 = sim.energy.balance();
        // half a contact, then ≈ 3 radii of flight (not round the box again)
        sim.run(&mut p, 200).unwrap();
        let mom = p.velocity[0] * p.mass[0] + p.velocity[1] * p.mass[1];
        assert!(mom.norm() < 1e-14, "{mom}");
        // velocity Verlet at Δt = t_c/20: the energy of the elastic pair to ≈ (ω Δt)²/8
        assert!((sim.energy.balance() - e0).abs() < 1e-2 * 0.5 * 0.01, "{} vs {e0}", sim.energy.balance());
        assert!(sim.max_pair_overlap(&p) == 0.0 && sim.contacts().is_empty());
        // restitution 1: they separate with the speed the spring gave them
        assert!(p.velocity[0].x > 0.0 && p.velocity[1].x < 0.0);
    }

    #[test]
    fn box_strain_is_affine_and_small_boxes_are_refused() {
        let (mut p, l) = pair_across_the_face(0.2);
        let mut sim = driver(&p);
        sim.set_periodic_box(l, &p).unwrap();
        sim.initialise(&mut p).unwrap();
        assert!(sim.neighbour_pairs().is_empty() && sim.max_pair_overlap(&p) == 0.0);
        // compress x by 2 %: every x scales by 0.98
        let x1 = p.position[1].x;
        sim.strain_box(&mut p, V3::new(9.8, 8.0, 9.0)).unwrap();
        assert!((p.position[1].x - x1 * 0.98).abs() < 1e-14);
        assert_eq!(sim.periodic_box(), Some(V3::new(9.8, 8.0, 9.0)));
        // the box moved 0.2, more than half the skin (0.1): no displacement allowed, rebuild forced
        let (half, forced) = sim.rebuild_threshold();
        assert!(half == 0.0 && forced, "{half} {forced}");
        let e = sim.strain_box(&mut p, V3::new(3.9, 8.0, 9.0)).unwrap_err().to_string();
        assert!(e.contains("periodic_box") && e.contains('4'), "{e}");
        let walled = Explicit::new(Settings::new(0.1, 1.0), sim.law, vec![crate::explicit::Wall::new(V3::z(), V3::zeros())]);
        let e = walled.unwrap().set_periodic_box(l, &p).unwrap_err().to_string();
        assert!(e.contains("walls"), "{e}");
    }
}

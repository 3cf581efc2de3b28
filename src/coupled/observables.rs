//! What a compact run reports of its state (series.csv, summary.json, plots): shrinkage,
//! relative density, neck ratio, temperatures, isolated particles, stresses, thermal strains and
//! the layer profile.

use super::Simulation;
use nalgebra::Vector3;

impl Simulation {
    /// Particles without a conductive path to any heat source (no chain of contacts, or of gap
    /// pipes with the gap model (heat-model.md (H18)–(H23)), to a particle of prescribed
    /// temperature, exposed to the furnace or heated volumetrically); empty in isothermal runs.
    /// Their temperature stays where it started.
    pub fn isolated_particles(&self) -> Vec<u32> {
        let p = &self.prep.scene.particles;
        let mut pairs = self.contacts.pairs.clone();
        if let Some(g) = &self.prep.gap {
            pairs.extend(g.pairs_now(&p.position, &p.radius, &self.contacts.pairs));
        }
        self.isolated_through(&pairs)
    }

    /// With the gap model: the particles that reach a heat source only through gap pipes
    /// (isolated without them); empty without the model.
    pub fn particles_connected_only_through_gaps(&self) -> Vec<u32> {
        if self.prep.gap.is_none() {
            return vec![];
        }
        let with = self.isolated_particles();
        self.isolated_through(&self.contacts.pairs).into_iter().filter(|i| with.binary_search(i).is_err()).collect()
    }

    /// The particles without a path through `pairs` to a heat source, sorted.
    fn isolated_through(&self, pairs: &[[u32; 2]]) -> Vec<u32> {
        let Some(net) = self.heat.as_ref() else { return vec![] };
        let src = &self.prep.sources;
        let n = self.prep.scene.particles.len();
        // the components of the network (every pipe conducts)
        let root = crate::heat::conductivity::components(n, pairs, &vec![1.0; pairs.len()]);
        let furnace = src.furnace.is_some();
        let mut heated = vec![false; n];
        for i in 0..n {
            let source = net.is_fixed(i)
                || src.fixed.get(i).is_some_and(Option::is_some)
                || (furnace && src.exposed_area.get(i).is_some_and(|&a| a > 0.0))
                || src.power.get(i).is_some_and(|&q| q != 0.0);
            if source {
                heated[root[i] as usize] = true;
            }
        }
        (0..n as u32).filter(|&i| !heated[root[i as usize] as usize]).collect()
    }

    /// Mean, min and max particle temperature [K] over the particles not in `iso` (the
    /// [`Simulation::isolated_particles`]; all particles when every one is isolated).
    pub fn temperature_stats(&self, iso: &[u32]) -> (f64, f64, f64) {
        let t = &self.prep.scene.particles.temperature;
        let mut skip = vec![false; t.len()];
        if iso.len() < t.len() {
            for &i in iso {
                skip[i as usize] = true;
            }
        }
        let vals = t.iter().zip(&skip).filter(|(_, s)| !**s).map(|(v, _)| *v);
        let (mut sum, mut n, mut lo, mut hi) = (0.0, 0usize, f64::INFINITY, f64::NEG_INFINITY);
        for v in vals {
            sum += v;
            n += 1;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        (sum / n.max(1) as f64, lo, hi)
    }

    /// The applied stress σ(t) at the current time [Pa] (0 without a load; a periodic cell: the
    /// mean of its prescribed normal stresses, compressive positive).
    pub fn applied_stress(&self) -> f64 {
        // a periodic cell: the mean prescribed normal stress, compressive positive
        if let Some(cs) = self.settings.mechanics.cell.as_ref() {
            let s = cs.stress_at(self.t);
            return -(s[0] + s[1] + s[2]) / 3.0;
        }
        self.load.as_ref().map_or(0.0, |l| l.settings.stress.at(self.t))
    }

    /// (P4): the macroscopic stress `[xx, yy, zz, yz, xz, xy]` [Pa] (tension positive) of the
    /// contact forces of the applied load at the current time, over the box volume of (S6); a
    /// periodic cell: its mean (virial) stress (B20) accumulated over the steps.
    pub fn macroscopic_stress(&self) -> [f64; 6] {
        if let Some(c) = &self.cell {
            return c.stress;
        }
        let Some(ls) = self.load.as_ref() else { return [0.0; 6] };
        if ls.ref_total == 0.0 {
            return [0.0; 6];
        }
        let Some(f) = self.load_forces_at(self.t) else { return [0.0; 6] };
        let scale = super::load::total_force(&f) / ls.ref_total;
        let e = self.extents();
        let n = ls.contact_force.len().min(self.contacts.len());
        super::load::macroscopic_stress(&self.contacts.pairs[..n], &ls.contact_force[..n], scale, &self.prep.scene.particles.position, e.x * e.y * e.z)
    }

    /// Mean normal force of the contacts in the last step [N] (compressive positive).
    pub fn mean_normal_force(&self) -> f64 {
        self.contacts.state.iter().map(|c| c.normal_force).sum::<f64>() / self.contacts.len().max(1) as f64
    }

    /// Mean coordination number, 2 · contacts / particles [1].
    pub fn coordination(&self) -> f64 {
        2.0 * self.contacts.len() as f64 / self.prep.scene.particles.len() as f64
    }

    /// Share of the contacts whose last sweep needed more than one substep [1].
    pub fn subdivided_fraction(&self) -> f64 {
        self.contacts.substeps.iter().filter(|&&s| s > 1).count() as f64 / self.contacts.len().max(1) as f64
    }

    /// Mean neck ratio y1/R_min over contacts [1].
    pub fn mean_neck_ratio(&self) -> f64 {
        let m = self.contacts.len().max(1) as f64;
        self.contacts.state.iter().map(|c| c.neck_ratio()).sum::<f64>() / m
    }

    /// Relative density: particle volume over the bounding volume from the principal planes to the
    /// far faces (Ivannikov et al. 2022 eq. 49) [1], both with the thermally expanded radii (X12).
    pub fn relative_density(&self) -> f64 {
        let p = &self.prep.scene.particles;
        let v: f64 = match self.thermal_strains() {
            Some(e) => p.radius.iter().zip(&e).map(|(&r, e)| crate::units::sphere_volume(r * (1.0 + e))).sum(),
            None => p.radius.iter().map(|&r| crate::units::sphere_volume(r)).sum(),
        };
        // a periodic cell: the solid volume over the cell's volume det(L), exact because the model
        // conserves each particle's volume (docs/mechanics.md (B22))
        if let Some(c) = &self.cell {
            return v / c.volume();
        }
        let e = self.extents();
        v / (e.x * e.y * e.z)
    }

    /// Mean contact shrinkage ΔL/L0 and mean neck ratio in `layers` slabs along z (contact
    /// midpoints, initial positions), bottom first: the densification profile of a compact heated
    /// from one face.
    pub fn layer_profile(&self, layers: usize) -> Vec<(f64, f64, f64, usize)> {
        let p = &self.prep.scene.particles;
        let (lo, hi) = (self.planes.z, self.planes.z + self.extent0.z);
        let mut acc = vec![(0.0, 0.0, 0usize); layers];
        for (c, &[i, j]) in self.contacts.state.iter().zip(&self.contacts.pairs) {
            let z = 0.5 * (self.x0[i as usize].z + self.x0[j as usize].z);
            let k = (((z - lo) / (hi - lo) * layers as f64) as usize).min(layers - 1);
            acc[k].0 += c.shrinkage();
            acc[k].1 += c.neck_ratio();
            acc[k].2 += 1;
        }
        let _ = p;
        acc.iter()
            .enumerate()
            .map(|(k, &(s, nr, n))| (lo + (k as f64 + 0.5) * (hi - lo) / layers as f64, s / n.max(1) as f64, nr / n.max(1) as f64, n))
            .collect()
    }

    /// Shrinkage per axis, 1 − L/L0 [1]: the total, thermal strain included (a dilatometer's).
    pub fn shrinkage(&self) -> Vector3<f64> {
        let e = self.extents();
        Vector3::from_fn(|a, _| 1.0 - e[a] / self.extent0[a])
    }

    /// (X1) The thermal strain ε_i of every particle at its current temperature [1]; None
    /// without thermal expansion.
    pub fn thermal_strains(&self) -> Option<Vec<f64>> {
        let x = self.expansion.as_ref()?;
        let p = &self.prep.scene.particles;
        Some(x.strains(p, &p.temperature))
    }

    /// (X10) The mean thermal strain of the compact (volume-weighted over the particles with a
    /// contact), and the smallest and largest particle strain among them [1]; zeros without
    /// thermal expansion.
    pub fn thermal_strain(&self) -> (f64, f64, f64) {
        match self.thermal_strains() {
            Some(e) => super::expansion::ThermalExpansion::mean_strain(&self.prep.scene.particles, &e, &self.contacts.pairs),
            None => (0.0, 0.0, 0.0),
        }
    }

    /// (X11) Sintering shrinkage per axis: the total shrinkage net of the mean thermal strain,
    /// `1 − (1 − s)/(1 + ε̄)` [1]; the total itself without thermal expansion.
    pub fn sintering_shrinkage(&self) -> Vector3<f64> {
        let s = self.shrinkage();
        if self.expansion.is_none() {
            return s;
        }
        let eps = self.thermal_strain().0;
        s.map(|v| super::expansion::sintering_shrinkage(v, eps))
    }
}

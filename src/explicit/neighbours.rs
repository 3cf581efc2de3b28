//! The neighbour lists of the driver: particle pairs within the Verlet skin (with the contact
//! history carried over by pair and the CSR incidence particle → contact) and the particle–wall
//! candidates.

use super::law::ContactModel;
use super::{Explicit, Out, PARTICLE_CHUNK, Slot, V3};
use crate::contacts::detect::{touching_pairs, touching_pairs_periodic};
use crate::particles::Particles;
use rayon::prelude::*;

impl<M: ContactModel> Explicit<M> {
    pub(super) fn rebuild(&mut self, p: &Particles) {
        let new_pairs = match self.periodic {
            None => touching_pairs(&p.position, &p.radius, self.settings.skin),
            Some(l) => {
                // minimum image (docs/packing.md (G1)); the sweeps recompute the branch at every
                // step, so only the pair is kept, in the walled list's (i, j) order
                let mut v: Vec<(u32, u32)> = touching_pairs_periodic(&p.position, &p.radius, l, self.settings.skin).into_iter().map(|q| (q.i, q.j)).collect();
                v.sort_unstable();
                self.built_box = l;
                v
            }
        };
        // carry history over by pair (both lists sorted)
        let mut new_slots = vec![Slot::<M::State>::default(); new_pairs.len()];
        let mut new_out = vec![Out::default(); new_pairs.len()];
        let mut new_touching = vec![false; new_pairs.len()];
        let mut k = 0;
        for (a, np) in new_pairs.iter().enumerate() {
            while k < self.pairs.len() && self.pairs[k] < *np {
                k += 1;
            }
            if k < self.pairs.len() && self.pairs[k] == *np {
                new_slots[a] = self.slots[k];
                new_out[a] = self.out[k];
                new_touching[a] = self.touching[k];
            }
        }
        self.pairs = new_pairs;
        self.slots = new_slots;
        self.out = new_out;
        self.touching = new_touching;
        let n = p.len();
        let mut start = vec![0u32; n + 1];
        for &(i, j) in &self.pairs {
            start[i as usize + 1] += 1;
            start[j as usize + 1] += 1;
        }
        for a in 0..n {
            start[a + 1] += start[a];
        }
        let mut fill = start.clone();
        let mut inc = vec![(0u32, false); 2 * self.pairs.len()];
        for (c, &(i, j)) in self.pairs.iter().enumerate() {
            inc[fill[i as usize] as usize] = (c as u32, true);
            fill[i as usize] += 1;
            inc[fill[j as usize] as usize] = (c as u32, false);
            fill[j as usize] += 1;
        }
        self.inc_start = start;
        self.inc = inc;
        self.built_at.clone_from(&p.position);
        self.rebuild_wall_list(p);
        self.counters.rebuilds += 1;
    }

    /// Particle–wall candidates: gap < 1.5 skins. Springs of pairs leaving the list are reset
    /// (they are out of contact: a pair in contact stays within the margin).
    pub(super) fn rebuild_wall_list(&mut self, p: &Particles) {
        let n = p.len();
        let margin = 1.5 * self.settings.skin;
        let walls = &self.walls;
        let (position, radius) = (&p.position, &p.radius);
        // walls of each particle in ascending order, by fixed chunks of particles
        let body = |c: usize| -> (Vec<u32>, Vec<u32>) {
            let (a0, a1) = (c * PARTICLE_CHUNK, ((c + 1) * PARTICLE_CHUNK).min(n));
            let mut count = Vec::with_capacity(a1 - a0);
            let mut of = Vec::new();
            for a in a0..a1 {
                let before = of.len();
                for (w, wall) in walls.iter().enumerate() {
                    if wall.normal.dot(&position[a]) - wall.offset - radius[a] < margin {
                        of.push(w as u32);
                    }
                }
                count.push((of.len() - before) as u32);
            }
            (count, of)
        };
        let chunks = n.div_ceil(PARTICLE_CHUNK);
        let parts: Vec<(Vec<u32>, Vec<u32>)> = if self.parallel() { (0..chunks).into_par_iter().map(body).collect() } else { (0..chunks).map(body).collect() };
        let mut start = Vec::with_capacity(n + 1);
        start.push(0u32);
        let mut of = Vec::with_capacity(parts.iter().map(|x| x.1.len()).sum());
        for (count, o) in parts {
            for c in count {
                let last = *start.last().unwrap();
                start.push(last + c);
            }
            of.extend(o);
        }
        // carry the springs of kept candidates over
        let mut spring = vec![V3::zeros(); of.len()];
        if self.wall_start.len() == n + 1 {
            for a in 0..n {
                let (o0, o1) = (self.wall_start[a] as usize, self.wall_start[a + 1] as usize);
                if o0 == o1 {
                    continue;
                }
                for q in start[a] as usize..start[a + 1] as usize {
                    if let Some(k) = self.wall_of[o0..o1].iter().position(|&w| w == of[q]) {
                        spring[q] = self.wall_spring[o0 + k];
                    }
                }
            }
        }
        self.wall_start = start;
        self.wall_of = of;
        self.wall_spring = spring;
        self.wall_list_at = self.walls.iter().map(|w| w.offset).collect();
    }

    pub(super) fn walls_moved(&self) -> bool {
        let half = 0.5 * self.settings.skin;
        self.wall_list_at.len() != self.walls.len() || self.walls.iter().zip(&self.wall_list_at).any(|(w, &o)| (w.offset - o).abs() >= half)
    }
}

//! The contact store of a compact run ([`Contacts`], struct of arrays) and the initial neck of a
//! contact created during the run.

use crate::error::ModelError;
use crate::models::diffusion7::Contact7;

/// The diffusion contacts of a packing, struct of arrays (docs/design.md).
#[derive(Debug, Clone, Default)]
pub struct Contacts {
    /// Particle pairs (i < j).
    pub pairs: Vec<[u32; 2]>,
    /// 7-DOF state of each contact.
    pub state: Vec<Contact7>,
    /// ΔL̄ of the last correction ((C4); Ivannikov et al. 2022 eq. 44) [m].
    pub dl_bar: Vec<f64>,
    /// Substeps of the last sweep.
    pub substeps: Vec<u32>,
    /// Diffusion dose of each contact, total and below the calibrated range (docs/diffusion7.md
    /// (V1)); zero for a new contact.
    pub dose: Vec<super::dose::Dose>,
}

impl Contacts {
    pub fn len(&self) -> usize {
        self.pairs.len()
    }
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }
}

impl super::Simulation {
    /// The branch vector `x_j − x_i` of particles `i`, `j` [m]: the minimum image in a periodic
    /// cell (docs/mechanics.md (B14)), the plain difference otherwise.
    pub fn branch(&self, i: u32, j: u32) -> nalgebra::Vector3<f64> {
        let p = &self.prep.scene.particles;
        let (xi, xj) = (p.position[i as usize], p.position[j as usize]);
        match &self.cell {
            Some(c) => c.branch(&xi, &xj),
            None => xj - xi,
        }
    }

    /// Centre distance of particles `i`, `j` [m] (minimum image in a periodic cell).
    pub fn distance(&self, i: u32, j: u32) -> f64 {
        self.branch(i, j).norm()
    }
}

/// Initial neck radius [m] of a contact created with `contacts.new_contact_state =
/// "volume_conserving"` between spheres of radii `r_i`, `r_j` [m] at centre distance `d` [m]: the
/// volume-conserving neck of the overlap `h = r_i + r_j − d` (crate::neck, the neck the heat model
/// gives the same pair), at least `ε·min(r_i, r_j)`, the seed neck of a touching pair (the 7-DOF
/// model needs a finite neck, (I2); below an overlap of about ε²·r/2 the seed is larger).
pub fn new_contact_neck(r_i: f64, r_j: f64, d: f64, eps: f64) -> Result<f64, ModelError> {
    let a = crate::neck::solve(r_i, r_j, r_i + r_j - d)?.a;
    Ok(a.max(eps * r_i.min(r_j)))
}

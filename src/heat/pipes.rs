//! The pipes of a static heat network: one per touching pair, its overlap, the volume-conserving
//! neck (crate::neck) and the pipe conductance of the chosen law (docs/heat-model.md (H6), (P4)).

use crate::error::ModelError;
use crate::heat::Conductance;
use crate::material::Material;
use crate::particles::Particles;
use nalgebra::Vector3;

/// The contact pipes of a static network: pairs, overlaps, necks and conductances.
#[derive(Debug, Clone, Default)]
pub struct Pipes {
    pub pairs: Vec<[u32; 2]>,
    /// Overlap h = r_i + r_j − d [m].
    pub overlap: Vec<f64>,
    /// Neck radius a [m].
    pub neck: Vec<f64>,
    /// Pipe conductance K_ij [W/K].
    pub conductance: Vec<f64>,
    /// The halves and series conductance of each pipe at the materials' constant κ [W/K] (the
    /// heat network rescales the halves with κ(T), heat-model.md eq. P4).
    pub parts: Vec<crate::heat::PipeConductance>,
    /// Pipes whose a/r_min exceeds 0.7 (the linear law is extrapolated there).
    pub extrapolated: usize,
}

/// Pipes from explicit pairs with their branch vectors `d_ij = x_j − x_i` (periodic images allowed).
pub fn pipes_from_pairs(pairs: Vec<[u32; 2]>, branch: &[Vector3<f64>], p: &Particles, materials: &[Material], law: &Conductance) -> Result<Pipes, ModelError> {
    let mut out = Pipes { pairs, ..Default::default() };
    for (k, &[i, j]) in out.pairs.iter().enumerate() {
        let (i, j) = (i as usize, j as usize);
        let (ri, rj) = (p.radius[i], p.radius[j]);
        let h = ri + rj - branch[k].norm();
        let neck = crate::neck::solve(ri, rj, h).map_err(|e| e.with_context(format!("contact {k} between particles {i} and {j}")))?;
        let (ki, kj) = (materials[p.material[i] as usize].conductivity, materials[p.material[j] as usize].conductivity);
        let pipe = law.pipe(ki, kj, ri, rj, neck.a);
        if neck.a > 0.7 * ri.min(rj) {
            out.extrapolated += 1;
        }
        out.overlap.push(h);
        out.neck.push(neck.a);
        out.conductance.push(pipe.pair);
        out.parts.push(pipe);
    }
    Ok(out)
}

/// Pipes between all touching particles (no periodicity).
pub fn pipes(p: &Particles, materials: &[Material], law: &Conductance) -> Result<Pipes, ModelError> {
    let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&p.position, &p.radius, 0.0).into_iter().map(|(i, j)| [i, j]).collect();
    let branch: Vec<Vector3<f64>> = pairs.iter().map(|&[i, j]| p.position[j as usize] - p.position[i as usize]).collect();
    pipes_from_pairs(pairs, &branch, p, materials, law)
}

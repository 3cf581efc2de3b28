//! The pipes of a static heat network: one per touching pair, its overlap, the volume-conserving
//! neck (crate::neck) and the pipe conductance of the chosen law (docs/heat-model.md (H6), (P4)).

use crate::error::ModelError;
use crate::heat::conductance;
use crate::heat::{Conductance, MultiNeck};
use crate::material::Material;
use crate::particles::Particles;
use nalgebra::{Matrix3, Vector3};

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
    /// Particles whose halves the bound (H8d) scaled down.
    pub bounded: usize,
}

/// The neck fabric of every particle, `M_i = Σ_l a_l n_l n_lᵀ` [m], and its summed neck radii
/// `A_i = Σ_l a_l` [m], over its necks (docs/heat-model.md (H8a)): `pairs`, their branch vectors
/// `d_ij = x_j − x_i` (any periodic image: only the axis enters, not its sign) and neck radii
/// `neck` [m]; `n` particles.
pub fn neck_fabric(pairs: &[[u32; 2]], branch: &[Vector3<f64>], neck: &[f64], n: usize) -> Vec<(Matrix3<f64>, f64)> {
    let mut m = vec![(Matrix3::zeros(), 0.0); n];
    for ((&[i, j], b), &a) in pairs.iter().zip(branch).zip(neck) {
        let d2 = b.norm_squared();
        if !(a > 0.0 && d2 > 0.0) {
            continue;
        }
        let t = (b * b.transpose()) * (a / d2);
        for k in [i as usize, j as usize] {
            m[k].0 += t;
            m[k].1 += a;
        }
    }
    m
}

/// The crowding `[φ_i, φ_j]` of every pipe's neck on its two particles (docs/heat-model.md
/// (H8a)); all 1 for `multi_neck = "none"`.
pub fn crowding(pairs: &[[u32; 2]], branch: &[Vector3<f64>], neck: &[f64], n: usize, law: &Conductance) -> Vec<[f64; 2]> {
    if law.multi_neck == MultiNeck::None {
        return vec![[1.0, 1.0]; pairs.len()];
    }
    let m = neck_fabric(pairs, branch, neck, n);
    let phi = |k: u32, b: &Vector3<f64>, a: f64| conductance::crowding(&m[k as usize].0, m[k as usize].1, b, a);
    pairs.iter().zip(branch).zip(neck).map(|((&[i, j], b), &a)| [phi(i, b, a), phi(j, b, a)]).collect()
}

/// Pipes from explicit pairs with their branch vectors `d_ij = x_j − x_i` (periodic images allowed),
/// bounded by (H8d) without a known solid fraction (per particle: each component of κ_eff at most κ_s).
pub fn pipes_from_pairs(pairs: Vec<[u32; 2]>, branch: &[Vector3<f64>], p: &Particles, materials: &[Material], law: &Conductance) -> Result<Pipes, ModelError> {
    pipes_from_pairs_in(pairs, branch, p, materials, law, None)
}

/// [`pipes_from_pairs`] in a cell of solid fraction `solid_fraction` = Σ (4/3)π r³ / V [1] (a
/// periodic box): the bound (H8d) is then one scale for the cell, which keeps the mean of the
/// diagonal of κ_eff at or below the Hashin–Shtrikman upper bound of that solid fraction and every
/// component at or below φκ_s.
pub fn pipes_from_pairs_in(
    pairs: Vec<[u32; 2]>,
    branch: &[Vector3<f64>],
    p: &Particles,
    materials: &[Material],
    law: &Conductance,
    solid_fraction: Option<f64>,
) -> Result<Pipes, ModelError> {
    let mut out = Pipes { pairs, ..Default::default() };
    for (k, &[i, j]) in out.pairs.iter().enumerate() {
        let (i, j) = (i as usize, j as usize);
        let (ri, rj) = (p.radius[i], p.radius[j]);
        let h = ri + rj - branch[k].norm();
        let neck = crate::neck::solve(ri, rj, h).map_err(|e| e.with_context(format!("contact {k} between particles {i} and {j}")))?;
        if neck.a > 0.7 * ri.min(rj) {
            out.extrapolated += 1;
        }
        out.overlap.push(h);
        out.neck.push(neck.a);
    }
    let phi = crowding(&out.pairs, branch, &out.neck, p.len(), law);
    for (k, &[i, j]) in out.pairs.iter().enumerate() {
        let (i, j) = (i as usize, j as usize);
        let (ki, kj) = (materials[p.material[i] as usize].conductivity, materials[p.material[j] as usize].conductivity);
        out.parts.push(law.pipe_crowded(ki, kj, p.radius[i], p.radius[j], out.neck[k], phi[k]));
    }
    let kappa: Vec<f64> = p.material.iter().map(|&m| materials[m as usize].conductivity).collect();
    out.bounded = bound_halves(&mut out.parts, &out.pairs, branch, &out.neck, &p.radius, &kappa, law, solid_fraction);
    out.conductance = out.parts.iter().map(|pc| pc.pair).collect();
    Ok(out)
}

/// The solid fraction of spheres of radii `radius` [m] in a cell of volume `volume` [m³]:
/// Σ (4/3)π r³ / V (the volume-conserving neck keeps each particle's volume) [1].
pub fn solid_fraction(radius: &[f64], volume: f64) -> f64 {
    radius.iter().map(|r| 4.0 / 3.0 * std::f64::consts::PI * r * r * r).sum::<f64>() / volume
}

/// The bound on the pipes (docs/heat-model.md (H8d)); returns the number of particles whose
/// halves it scaled (every particle with a pipe when the cell's scale acts, none otherwise).
///
/// - **A cell of known solid fraction** (`solid_fraction` = φ = Σ v_i / V, v_i = (4/3)π r_i³: a
///   periodic box). The uniform-gradient (Voigt) flux of the network bounds κ_eff from above
///   (minimum energy: θ = 0 is one admissible fluctuation): `e·κ_eff·e ≤ e·T·e / V`,
///   `T = Σ_pipes K_ij b_ij b_ijᵀ`. With κ̄ = Σ κ_i v_i / Σ v_i (the solid's conductivity; its
///   volume mean for several materials) and φ_c = min(φ, 1), one scale for every half of the cell,
///   `s = min(1, φ_c κ̄ V / λ_max(T), 3·(2φ_c/(3 − φ_c)) κ̄ V / tr T)`, keeps every diagonal
///   component of κ_eff at or below φ_c κ̄ ≤ κ̄ (Wiener) and the mean of the diagonal at or below
///   2φ_c/(3 − φ_c)·κ̄ (Hashin–Shtrikman). Scaling both halves by s scales each pipe by at most s
///   (an interface resistance in series only lowers it further). It acts only where the cell's
///   Voigt bound exceeds the bound, which no stored FE cell of the validated range does
///   (docs/validation-conductance.md); `s = 1` leaves every pipe bit for bit.
/// - **Otherwise** (walled bodies, heat runs: no solid fraction) each particle's halves form
///   `C_i = Σ_k K_ik l_ik² n_k n_kᵀ` [W·m] (l_ik = |b| r_i/(r_i + r_j) its share of the branch
///   vector b, n_k = b/|b|); by Cauchy–Schwarz `K_ij |b|² ≤ K_i l_i² + K_j l_j²`, so
///   `e·κ_eff·e ≤ (1/V) Σ_i e·C_i·e`, and scaling particle i's halves by
///   `s_i = min(1, κ_i v_i / λ_max(C_i))` keeps every diagonal component of κ_eff at or below the
///   solid's κ (Wiener with φ ≤ 1) in a one-material body.
#[allow(clippy::too_many_arguments)]
pub fn bound_halves(
    parts: &mut [crate::heat::PipeConductance],
    pairs: &[[u32; 2]],
    branch: &[Vector3<f64>],
    neck: &[f64],
    radius: &[f64],
    kappa: &[f64],
    law: &Conductance,
    solid_fraction: Option<f64>,
) -> usize {
    let n = radius.len();
    let volume: Vec<f64> = radius.iter().map(|r| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3)).collect();
    let scale: Vec<f64> = match solid_fraction {
        Some(phi) if phi > 0.0 && phi.is_finite() => {
            let s = cell_scale(parts, branch, &volume, kappa, phi);
            let mut touched = vec![false; n];
            for (pc, &[i, j]) in parts.iter().zip(pairs) {
                if pc.pair > 0.0 {
                    touched[i as usize] = true;
                    touched[j as usize] = true;
                }
            }
            touched.iter().map(|&t| if t { s } else { 1.0 }).collect()
        }
        _ => particle_scales(parts, pairs, branch, radius, &volume, kappa),
    };
    for (k, pc) in parts.iter_mut().enumerate() {
        let [i, j] = pairs[k];
        let (si, sj) = (scale[i as usize], scale[j as usize]);
        if si < 1.0 || sj < 1.0 {
            *pc = law.series(pc.half_i * si, pc.half_j * sj, neck[k]);
        }
    }
    scale.iter().filter(|&&s| s < 1.0).count()
}

/// The one scale (H8d) of a cell of solid fraction `phi`: `min(1, φ_c κ̄ V / λ_max(T),
/// 3 HS(φ_c) κ̄ V / tr T)` with `T = Σ_pipes K_ij b bᵀ`, V = Σ v_i / φ and κ̄ the volume mean of
/// the particles' `kappa` over their volumes `volume` [m³] (see [`bound_halves`]).
fn cell_scale(parts: &[crate::heat::PipeConductance], branch: &[Vector3<f64>], volume: &[f64], kappa: &[f64], phi: f64) -> f64 {
    let mut t = Matrix3::<f64>::zeros();
    for (pc, b) in parts.iter().zip(branch) {
        if pc.pair > 0.0 {
            t += (b * b.transpose()) * pc.pair;
        }
    }
    let tr = t.trace();
    let solid: f64 = volume.iter().sum();
    if !(tr > 0.0 && solid > 0.0) {
        return 1.0;
    }
    let kbar = volume.iter().zip(kappa).map(|(v, k)| v * k).sum::<f64>() / solid;
    let cell = solid / phi;
    let phi_c = phi.min(1.0);
    let hs = 2.0 * phi_c / (3.0 - phi_c);
    let lmax = t.symmetric_eigenvalues().max();
    (phi_c * kbar * cell / lmax).min(3.0 * hs * kbar * cell / tr).min(1.0)
}

/// The per-particle scales (H8d) without a solid fraction: `s_i = min(1, κ_i v_i / λ_max(C_i))`
/// (see [`bound_halves`]).
fn particle_scales(
    parts: &[crate::heat::PipeConductance],
    pairs: &[[u32; 2]],
    branch: &[Vector3<f64>],
    radius: &[f64],
    volume: &[f64],
    kappa: &[f64],
) -> Vec<f64> {
    let mut c = vec![Matrix3::<f64>::zeros(); radius.len()];
    for ((pc, &[i, j]), b) in parts.iter().zip(pairs).zip(branch) {
        let (i, j) = (i as usize, j as usize);
        let d2 = b.norm_squared();
        if !(d2 > 0.0 && pc.pair > 0.0) {
            continue;
        }
        let nn = (b * b.transpose()) / d2;
        let d = d2.sqrt();
        let li = d * radius[i] / (radius[i] + radius[j]);
        let lj = d - li;
        c[i] += nn * (pc.half_i * li * li);
        c[j] += nn * (pc.half_j * lj * lj);
    }
    c.iter()
        .zip(volume.iter().zip(kappa))
        .map(|(ci, (v, k))| {
            if !(ci.trace() > 0.0) {
                return 1.0;
            }
            (k * v / ci.symmetric_eigenvalues().max()).min(1.0)
        })
        .collect()
}

/// Pipes between all touching particles (no periodicity).
pub fn pipes(p: &Particles, materials: &[Material], law: &Conductance) -> Result<Pipes, ModelError> {
    let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&p.position, &p.radius, 0.0).into_iter().map(|(i, j)| [i, j]).collect();
    let branch: Vec<Vector3<f64>> = pairs.iter().map(|&[i, j]| p.position[j as usize] - p.position[i as usize]).collect();
    pipes_from_pairs(pairs, &branch, p, materials, law)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The periodic nearest-neighbour bonds of particle 0 of a Bravais lattice as pairs with
    /// itself (its images), all with neck radius `a`.
    fn star(dirs: &[Vector3<f64>], a: f64) -> (Vec<[u32; 2]>, Vec<Vector3<f64>>, Vec<f64>) {
        (vec![[0, 0]; dirs.len()], dirs.to_vec(), vec![a; dirs.len()])
    }

    fn fabric_crowding(dirs: &[Vector3<f64>]) -> Vec<[f64; 2]> {
        // each bond of a lattice particle with its image counts on both of its ends, so every
        // direction once (the ± pairs come from the pair's two ends)
        let (pairs, branch, neck) = star(dirs, 0.3e-3);
        crowding(&pairs, &branch, &neck, 1, &Conductance { law: crate::heat::ConductanceLaw::FeFit, multi_neck: MultiNeck::Fabric, ..Default::default() })
    }

    #[test]
    fn crowding_of_lattices_is_the_closed_form() {
        // (H8c): SC 1, BCC 4/3, FCC 2 for every neck; the pair (one bond) 1
        let v = Vector3::new;
        let sc = [v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, 0.0, 1.0)];
        let bcc = [v(1.0, 1.0, 1.0), v(1.0, 1.0, -1.0), v(1.0, -1.0, 1.0), v(-1.0, 1.0, 1.0)];
        let fcc = [v(1.0, 1.0, 0.0), v(1.0, -1.0, 0.0), v(1.0, 0.0, 1.0), v(1.0, 0.0, -1.0), v(0.0, 1.0, 1.0), v(0.0, 1.0, -1.0)];
        for (dirs, want) in [(&sc[..], 1.0), (&bcc[..], 4.0 / 3.0), (&fcc[..], 2.0), (&sc[..1], 1.0)] {
            for phi in fabric_crowding(dirs) {
                assert!((phi[0] / want - 1.0).abs() < 1e-14 && (phi[1] / want - 1.0).abs() < 1e-14, "{phi:?} vs {want}");
            }
        }
    }

    #[test]
    fn lone_neck_and_chain_keep_the_pair_law_and_none_switches_off() {
        // a chain 0–1–2 along x: particle 1 has two opposite equal necks (φ = 1 exactly), the ends
        // one neck each (nᵀMn = a, plus the pair's mirror 2a − A = a: 1 exactly)
        let pairs = vec![[0, 1], [1, 2]];
        let b = vec![Vector3::new(1.9e-3, 0.0, 0.0); 2];
        let neck = vec![0.3e-3; 2];
        let law = Conductance { law: crate::heat::ConductanceLaw::FeFit, multi_neck: MultiNeck::Fabric, ..Default::default() };
        assert_eq!(crowding(&pairs, &b, &neck, 3, &law), vec![[1.0, 1.0]; 2]);
        // a T junction: particle 1 gets a third neck along y; its x necks stay at 1 (n·n_y = 0),
        // its y neck (a = 0.5 mm, A = 1.1 mm) (0.5 + 0)/(2·0.5) = 1/2: heat turning the corner
        // has a shorter path than through the pair's hemisphere
        let pairs = vec![[0, 1], [1, 2], [1, 3]];
        let b = vec![Vector3::new(1.9e-3, 0.0, 0.0), Vector3::new(1.9e-3, 0.0, 0.0), Vector3::new(0.0, 1.9e-3, 0.0)];
        let neck = vec![0.3e-3, 0.3e-3, 0.5e-3];
        let phi = crowding(&pairs, &b, &neck, 4, &law);
        assert!((phi[0][1] - 1.0).abs() < 1e-15 && (phi[1][0] - 1.0).abs() < 1e-15, "{phi:?}");
        assert!((phi[2][0] - 0.5).abs() < 1e-15 && phi[2][1] == 1.0, "{phi:?}");
        // three coplanar necks at 60° on particle 0, radii 1, 1, 3 (A = 5): neck 1
        // (1 + 0.25 + 3·0.25)/2 = 1; neck 2 (0.25 + 1 + 3·0.25)/2 = 1; neck 3 (0.25 + 0.25 + 3 + (6 − 5))/6
        let c = 0.5f64;
        let pairs = vec![[0, 1], [0, 2], [0, 3]];
        let b = vec![Vector3::new(1.0, 0.0, 0.0), Vector3::new(c, (1.0 - c * c).sqrt(), 0.0), Vector3::new(-c, (1.0 - c * c).sqrt(), 0.0)];
        let neck = vec![1.0, 1.0, 3.0];
        let phi = crowding(&pairs, &b, &neck, 4, &law);
        for (k, want) in [1.0, 1.0, 0.75].into_iter().enumerate() {
            assert!((phi[k][0] - want).abs() < 1e-14, "{phi:?}");
            assert_eq!(phi[k][1], 1.0);
        }
        let none = Conductance { multi_neck: MultiNeck::None, ..law };
        let fcc_like: Vec<Vector3<f64>> = (0..12).map(|k| Vector3::new((k as f64).cos(), (k as f64).sin(), 0.3 * k as f64)).collect();
        let (pairs, branch, neck) = star(&fcc_like, 0.3);
        assert!(crowding(&pairs, &branch, &neck, 1, &law).iter().all(|p| p[0] > 1.0));
        assert_eq!(crowding(&pairs, &branch, &neck, 1, &none), vec![[1.0, 1.0]; 12]);
    }

    #[test]
    fn fabric_is_the_sum_of_axis_dyads_weighted_by_neck() {
        let pairs = vec![[0, 1], [0, 2]];
        let b = vec![Vector3::new(0.0, 0.0, -2.0), Vector3::new(3.0, 4.0, 0.0)];
        let m = neck_fabric(&pairs, &b, &[0.5, 2.0], 3);
        let want0 = Matrix3::new(2.0 * 0.36, 2.0 * 0.48, 0.0, 2.0 * 0.48, 2.0 * 0.64, 0.0, 0.0, 0.0, 0.5);
        assert!((m[0].0 - want0).norm() < 1e-15, "{}", m[0].0);
        assert!((m[1].0 - Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5)).norm() < 1e-15);
        assert!((m[0].0.trace() - 2.5).abs() < 1e-15 && m[0].1 == 2.5 && m[1].1 == 0.5 && m[2].1 == 2.0);
    }
}

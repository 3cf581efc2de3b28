//! Effective conductivity of a compact (docs/heat-model.md (H17), "Effective conductivity").
//!
//! - **faces**: two opposite layers of particles held at `T_hot` and `T_cold` (Dirichlet), steady
//!   state `L T = b` on the rest; components without a Dirichlet node are removed;
//!   `κ_eff = (Q/A)/((T_hot − T_cold)/L_D)` with Q the heat leaving the hot layer (checked against
//!   the heat entering the cold one), A the bounding-box cross-section, L_D the distance between
//!   the layers' mean centre coordinates.
//! - **periodic**: a periodic box with an imposed mean gradient G: `T_i = G·x_i + θ_i`, θ periodic,
//!   `(L θ)_i = Σ_j K_ij G·b_ij` (b_ij the minimum-image branch vector), one node pinned per
//!   component; the mean heat flux `q̄ = (1/V) Σ_pipes K_ij (T_i − T_j) b_ij = −κ_eff G` gives the
//!   full tensor. For Bravais lattices it reproduces K/D (SC), √3 K/D (BCC), 2√2 K/D (FCC).

use crate::error::{Error, SolveError};
use crate::heat::Conductance;
use crate::heat::pipes::{self, Pipes};
use crate::linsolve::{SpdPattern, set_parallelism_for};
use crate::material::Material;
use crate::particles::Particles;
use nalgebra::{Matrix3, Vector3};

/// Result of one axis of the faces method.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct AxisResult {
    pub axis: usize,
    /// Heat leaving the hot layer [W].
    pub q_hot: f64,
    /// Heat entering the cold layer [W].
    pub q_cold: f64,
    /// Cross-section [m²].
    pub area: f64,
    /// Distance between the Dirichlet layers [m].
    pub length: f64,
    /// κ_eff along the axis [W/(m·K)].
    pub kappa: f64,
    /// Particles removed as floating (no conducting path to a Dirichlet layer).
    pub floating: usize,
    pub hot_particles: usize,
    pub cold_particles: usize,
    /// Fraction of the cross-section the hot layer's disks π r² cover (H17a) [1].
    pub hot_coverage: f64,
    /// Fraction of the cross-section the cold layer's disks cover [1].
    pub cold_coverage: f64,
    /// How far the hot face moved inward from the most extreme particle (H17a) [m].
    pub hot_face_shift_m: f64,
    /// How far the cold face moved inward from the most extreme particle [m].
    pub cold_face_shift_m: f64,
}

/// Connected components of the pipe network over pipes of positive conductance: the root (smallest
/// member index) of each node.
pub(crate) fn components(n: usize, pipes: &[[u32; 2]], k: &[f64]) -> Vec<u32> {
    // union-find over pipes with positive conductance
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(p: &mut [u32], mut x: u32) -> u32 {
        while p[x as usize] != x {
            p[x as usize] = p[p[x as usize] as usize];
            x = p[x as usize];
        }
        x
    }
    for (e, &[i, j]) in pipes.iter().enumerate() {
        if k[e] > 0.0 {
            let (a, b) = (find(&mut parent, i), find(&mut parent, j));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    (0..n as u32).map(|i| find(&mut parent, i)).collect()
}

/// Solves `A x = b` for a weighted graph Laplacian restricted to `unknown` nodes (others fixed at
/// their `values`), returning the full vector.
fn steady(n: usize, pipes: &[[u32; 2]], k: &[f64], is_unknown: &[bool], values: &mut [f64], extra_rhs: &[f64]) -> Result<(), SolveError> {
    let mut v = [values.to_vec()];
    steady_many(n, pipes, k, is_unknown, &mut v, &[extra_rhs])?;
    values.copy_from_slice(&v[0]);
    Ok(())
}

/// [`steady`] for several right-hand sides with one factorisation.
fn steady_many(n: usize, pipes: &[[u32; 2]], k: &[f64], is_unknown: &[bool], values: &mut [Vec<f64>], extra_rhs: &[&[f64]]) -> Result<(), SolveError> {
    let mut local = vec![u32::MAX; n];
    let mut m = 0u32;
    for i in 0..n {
        if is_unknown[i] {
            local[i] = m;
            m += 1;
        }
    }
    let m = m as usize;
    if m == 0 {
        return Ok(());
    }
    let mut entries: Vec<(u32, u32)> = (0..m as u32).map(|l| (l, l)).collect();
    let mut vals = vec![0.0; m];
    let mut rhs = vec![vec![0.0; m]; extra_rhs.len()];
    for (r, extra) in rhs.iter_mut().zip(extra_rhs) {
        for i in 0..n {
            if is_unknown[i] {
                r[local[i] as usize] += extra[i];
            }
        }
    }
    for (e, &[i, j]) in pipes.iter().enumerate() {
        let (li, lj) = (local[i as usize], local[j as usize]);
        let kk = k[e];
        if kk == 0.0 || i == j {
            continue;
        }
        if li != u32::MAX {
            vals[li as usize] += kk;
            if lj == u32::MAX {
                for (r, v) in rhs.iter_mut().zip(values.iter()) {
                    r[li as usize] += kk * v[j as usize];
                }
            }
        }
        if lj != u32::MAX {
            vals[lj as usize] += kk;
            if li == u32::MAX {
                for (r, v) in rhs.iter_mut().zip(values.iter()) {
                    r[lj as usize] += kk * v[i as usize];
                }
            }
        }
        if li != u32::MAX && lj != u32::MAX {
            entries.push((li.max(lj), li.min(lj)));
            vals.push(-kk);
        }
    }
    set_parallelism_for(m);
    let pat = SpdPattern::new(m, &entries)?;
    let f = pat.factorize(&vals)?;
    for (r, v) in rhs.iter_mut().zip(values.iter_mut()) {
        f.solve_in_place(&pat, r)?;
        for i in 0..n {
            if local[i] != u32::MAX {
                v[i] = r[local[i] as usize];
            }
        }
    }
    Ok(())
}

/// Smallest fraction of a face's cross-section the disks (π r²) of its Dirichlet layer must
/// cover (H17a): a walled random packing's face layer covers 0.6–0.75, a cut face 0.13–0.21, an SC
/// block's π/4; one particle standing proud of a face of 8 000 covers about 0.01.
pub const FACE_COVERAGE_MIN: f64 = 0.1;

/// Face-layer coverage below which a face is a cut (rough) face rather than a wall-compacted one
/// (H17b). Wall-compacted faces cover 0.70–0.76 of the cross-section; the cut faces of a body
/// opened from a periodic packing or the titanium column cover 0.13–0.21. On cut faces the faces
/// method reads 17–48 % low for 27 000–500 particles (docs/heat-model.md "Error of the faces
/// method"), so its result is reported with a warning. A fraction of the cross-section [1].
pub const FACE_COVERAGE_CUT: f64 = 0.25;

/// The warning (H17b) for faces-method results whose least-covered face layer is below
/// [`FACE_COVERAGE_CUT`]; None when every face looks wall-compacted.
pub fn cut_face_warning(axes: &[AxisResult]) -> Option<String> {
    let (c, axis) = axes.iter().flat_map(|r| [(r.hot_coverage, r.axis), (r.cold_coverage, r.axis)]).min_by(|a, b| a.0.total_cmp(&b.0))?;
    (c < FACE_COVERAGE_CUT).then(|| {
        format!(
            "conductivity (faces method): a face layer along {} covers only {c:.2} of the cross-section (a wall-compacted face covers about 0.7): these are cut faces, on which the faces method reads 17-48 % low for 27 000-500 particles (docs/heat-model.md \"Error of the faces method\"); for material data use the periodic tensor (conductivity.boundary = \"periodic\" on a periodic packing)",
            ["x", "y", "z"][axis.min(2)]
        )
    })
}

/// Farthest a face moves inward from its most extreme particle to reach [`FACE_COVERAGE_MIN`],
/// in mean radii (two diameters); beyond it the face stays at the extreme particle.
pub const FACE_SHIFT_MAX_RADII: f64 = 4.0;

/// Position of the lower face of a set of particles along one axis (H17a): `lower[i]` the
/// particle's lower extent x_i − r_i, `disk[i]` its disk area π r_i² [m²]. The face is the
/// extent e_k of the first particle (in ascending order) whose layer {i : e_i ≤ e_k + depth}
/// covers `c_min·area` with its disks, so that a particle standing proud of the surface does not
/// become the layer by itself; at most `max_shift` [m] inward of the extreme particle, else the
/// extreme particle (the old rule). Returns (face [m], covered fraction of its layer).
pub(crate) fn face_position(lower: &[f64], disk: &[f64], depth: f64, area: f64, c_min: f64, max_shift: f64) -> (f64, f64) {
    let mut order: Vec<usize> = (0..lower.len()).collect();
    order.sort_by(|&a, &b| lower[a].total_cmp(&lower[b]).then(a.cmp(&b)));
    let e0 = lower[order[0]];
    let (mut j, mut covered) = (0usize, 0.0);
    let mut first = None;
    for &k in &order {
        let e = lower[k];
        if e - e0 > max_shift {
            break;
        }
        while j < order.len() && lower[order[j]] <= e + depth {
            covered += disk[order[j]];
            j += 1;
        }
        let frac = covered / area;
        if first.is_none() {
            first = Some(frac);
        }
        if frac >= c_min {
            return (e, frac);
        }
    }
    (e0, first.unwrap_or(0.0))
}

/// The faces method along `axis` (0, 1, 2). `depth` [m]: particles whose sphere comes within it
/// of a face form that face's Dirichlet layer. The faces are those of the conducting particles'
/// extent, each moved inward past particles standing proud of the surface until its layer covers
/// [`FACE_COVERAGE_MIN`] of the cross-section (H17a); the cross-section A is that of the moved
/// faces of the two other axes.
pub fn faces(p: &Particles, pipes: &Pipes, axis: usize, depth: f64, delta_t: f64) -> Result<AxisResult, Error> {
    let n = p.len();
    // particles without a conducting pipe (rattlers) neither bound the packing nor form layers
    let mut conducts = vec![false; n];
    for (e, &[i, j]) in pipes.pairs.iter().enumerate() {
        if pipes.conductance[e] > 0.0 {
            conducts[i as usize] = true;
            conducts[j as usize] = true;
        }
    }
    let idx: Vec<usize> = (0..n).filter(|&i| conducts[i]).collect();
    if idx.is_empty() {
        return Err(SolveError::new("effective conductivity", format!("axis {axis}: no particle has a conducting pipe")).into());
    }
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for &i in &idx {
        lo = lo.inf(&p.position[i].add_scalar(-p.radius[i]));
        hi = hi.sup(&p.position[i].add_scalar(p.radius[i]));
    }
    // (H17a) every face moved inward past particles standing proud of it
    let disk: Vec<f64> = idx.iter().map(|&i| std::f64::consts::PI * p.radius[i] * p.radius[i]).collect();
    let max_shift = FACE_SHIFT_MAX_RADII * p.mean_radius();
    let (mut flo, mut fhi) = (lo, hi);
    let mut cover = [[0.0; 2]; 3];
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let area = (hi[b] - lo[b]) * (hi[c] - lo[c]);
        let d = if a == axis { depth } else { 0.5 * p.mean_radius() };
        let lower: Vec<f64> = idx.iter().map(|&i| p.position[i][a] - p.radius[i]).collect();
        let upper: Vec<f64> = idx.iter().map(|&i| -(p.position[i][a] + p.radius[i])).collect();
        let (f0, c0) = face_position(&lower, &disk, d, area, FACE_COVERAGE_MIN, max_shift);
        let (f1, c1) = face_position(&upper, &disk, d, area, FACE_COVERAGE_MIN, max_shift);
        flo[a] = f0;
        fhi[a] = -f1;
        cover[a] = [c0, c1];
    }
    let hot: Vec<bool> = (0..n).map(|i| conducts[i] && p.position[i][axis] - p.radius[i] <= flo[axis] + depth).collect();
    let cold: Vec<bool> = (0..n).map(|i| conducts[i] && p.position[i][axis] + p.radius[i] >= fhi[axis] - depth && !hot[i]).collect();
    let (nh, nc) = (hot.iter().filter(|&&h| h).count(), cold.iter().filter(|&&c| c).count());
    if nh == 0 || nc == 0 {
        return Err(SolveError::new("effective conductivity", format!("axis {axis}: a Dirichlet layer is empty (hot {nh}, cold {nc})")).into());
    }
    let comp = components(n, &pipes.pairs, &pipes.conductance);
    let mut anchored = vec![false; n];
    for i in 0..n {
        if hot[i] || cold[i] {
            anchored[comp[i] as usize] = true;
        }
    }
    let (t_hot, t_cold) = (delta_t, 0.0);
    let mut temps: Vec<f64> = (0..n)
        .map(|i| {
            if hot[i] {
                t_hot
            } else if cold[i] {
                t_cold
            } else {
                0.5 * delta_t
            }
        })
        .collect();
    let unknown: Vec<bool> = (0..n).map(|i| !hot[i] && !cold[i] && anchored[comp[i] as usize]).collect();
    let floating = (0..n).filter(|&i| !anchored[comp[i] as usize]).count();
    steady(n, &pipes.pairs, &pipes.conductance, &unknown, &mut temps, &vec![0.0; n])?;
    let (mut q_hot, mut q_cold) = (0.0, 0.0);
    for (e, &[i, j]) in pipes.pairs.iter().enumerate() {
        let (i, j) = (i as usize, j as usize);
        let q = pipes.conductance[e] * (temps[i] - temps[j]); // i → j
        if hot[i] && !hot[j] {
            q_hot += q;
        }
        if hot[j] && !hot[i] {
            q_hot -= q;
        }
        if cold[j] && !cold[i] {
            q_cold += q;
        }
        if cold[i] && !cold[j] {
            q_cold -= q;
        }
    }
    if (q_hot - q_cold).abs() > 1e-8 * q_hot.abs().max(1e-300) {
        return Err(SolveError::new(
            "effective conductivity",
            format!("axis {axis}: heat out of the hot layer {q_hot:e} W differs from heat into the cold layer {q_cold:e} W"),
        )
        .into());
    }
    // L_D between the layers' mean centres, without the particles standing proud of a moved face
    // (H17a); with unmoved faces every layer particle counts
    let mean = |sel: &[bool], inside: &dyn Fn(usize) -> bool| {
        let (s, c) = (0..n).filter(|&i| sel[i] && inside(i)).fold((0.0, 0usize), |(s, c), i| (s + p.position[i][axis], c + 1));
        s / c as f64
    };
    let length = mean(&cold, &|i| p.position[i][axis] + p.radius[i] <= fhi[axis]) - mean(&hot, &|i| p.position[i][axis] - p.radius[i] >= flo[axis]);
    let ext = fhi - flo;
    let area = ext[(axis + 1) % 3] * ext[(axis + 2) % 3];
    let kappa = (q_hot / area) / (delta_t / length);
    Ok(AxisResult {
        axis,
        q_hot,
        q_cold,
        area,
        length,
        kappa,
        floating,
        hot_particles: nh,
        cold_particles: nc,
        hot_coverage: cover[axis][0],
        cold_coverage: cover[axis][1],
        hot_face_shift_m: flo[axis] - lo[axis],
        cold_face_shift_m: hi[axis] - fhi[axis],
    })
}

/// Pipes of a periodic box `[0, L)` (positions wrapped into it): contacts found by the
/// minimum-image search with branch vectors `b_ij = x_j + s − x_i`, s the image shift. Each box
/// length must be at least two largest diameters, so that a pair touches through one image only.
pub fn periodic_pipes(p: &Particles, bbox: Vector3<f64>, materials: &[Material], law: &Conductance) -> Result<(Pipes, Vec<Vector3<f64>>), Error> {
    let r_max = p.radius.iter().copied().fold(0.0, f64::max);
    if (0..3).any(|a| !(bbox[a] >= 2.0 * 2.0 * r_max)) {
        return Err(SolveError::new(
            "periodic pipes",
            format!("the periodic box {:?} m must be at least two largest particle diameters ({:e} m) wide along each axis", bbox.as_slice(), 4.0 * r_max),
        )
        .into());
    }
    let wrap = |x: &Vector3<f64>| Vector3::from_fn(|a, _| x[a].rem_euclid(bbox[a]));
    let found = crate::contacts::detect::touching_pairs_periodic(&p.position, &p.radius, bbox, 0.0);
    let mut pairs = Vec::with_capacity(found.len());
    let mut branch = Vec::with_capacity(found.len());
    for c in found {
        let s = Vector3::new(c.shift[0] as f64 * bbox.x, c.shift[1] as f64 * bbox.y, c.shift[2] as f64 * bbox.z);
        pairs.push([c.i, c.j]);
        branch.push((wrap(&p.position[c.j as usize]) + s) - wrap(&p.position[c.i as usize]));
    }
    let phi = pipes::solid_fraction(&p.radius, bbox.x * bbox.y * bbox.z);
    let pipes = pipes::pipes_from_pairs_in(pairs, &branch, p, materials, law, Some(phi))?;
    Ok((pipes, branch))
}

/// The full tensor by the periodic method [W/(m·K)].
pub fn periodic(p: &Particles, pipes: &Pipes, branch: &[Vector3<f64>], bbox: Vector3<f64>) -> Result<Matrix3<f64>, Error> {
    let n = p.len();
    let comp = components(n, &pipes.pairs, &pipes.conductance);
    let volume = bbox.x * bbox.y * bbox.z;
    let mut kappa = Matrix3::zeros();
    let rhs: Vec<Vec<f64>> = (0..3)
        .map(|axis| {
            let g = Vector3::ith(axis, 1.0); // K/m
            let mut rhs = vec![0.0; n];
            for (e, &[i, j]) in pipes.pairs.iter().enumerate() {
                let f = pipes.conductance[e] * g.dot(&branch[e]);
                rhs[i as usize] += f;
                rhs[j as usize] -= f;
            }
            rhs
        })
        .collect();
    // pin the first node of each component (θ = 0); one factorisation for the three gradients
    let unknown: Vec<bool> = (0..n).map(|i| comp[i] as usize != i).collect();
    let mut theta = vec![vec![0.0; n]; 3];
    let extra: Vec<&[f64]> = rhs.iter().map(|r| r.as_slice()).collect();
    steady_many(n, &pipes.pairs, &pipes.conductance, &unknown, &mut theta, &extra)?;
    for (axis, theta) in theta.iter().enumerate() {
        let g = Vector3::ith(axis, 1.0);
        let mut q = Vector3::zeros();
        for (e, &[i, j]) in pipes.pairs.iter().enumerate() {
            let dt_ij = -g.dot(&branch[e]) + theta[i as usize] - theta[j as usize]; // T_i − T_j
            q += pipes.conductance[e] * dt_ij * branch[e];
        }
        q /= volume;
        kappa.set_column(axis, &(-q));
    }
    Ok(kappa)
}

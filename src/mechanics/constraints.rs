//! Kinematic constraints and the removal of rigid-body modes (docs/mechanics.md, "Constraints
//! and constraints"; paper §3.3).
//!
//! - a **rattler** (particle without bonds) is left out of the solve and keeps its position;
//! - **plane constraints**: particles touching the planes x = 0, y = 0, z = 0 of the packing's
//!   frame keep their displacement normal to that plane zero ([`Constraints::principal_planes`]);
//! - any further fixed DOF may be set per particle ([`Constraints::fix`], e.g. a clamped root);
//! - each connected component of the bond graph whose fixed DOF leave a rigid mode free (the
//!   `n_c × 6` matrix of rigid-mode components at its fixed DOF has rank < 6), including every
//!   floating cluster, is **pinned instead**: its own fixed DOF are released and all six DOF of
//!   its particle nearest the centroid are fixed. One full pin is statically determinate, so the
//!   self-equilibrated sintering loads give it no reaction.
//!
//! With these rules the assembled stiffness is SPD (each link has full rank 6, so a connected
//! component held against its six rigid modes has no zero-energy mode left).

use crate::error::{ConfigError, SolveError};
use nalgebra::{Matrix6, SymmetricEigen, Vector3, Vector6};

/// Bits of a per-particle fixed-DOF mask.
pub mod dof {
    /// Displacement along x, y, z.
    pub const UX: u8 = 1;
    pub const UY: u8 = 2;
    pub const UZ: u8 = 4;
    /// Rotation about x, y, z.
    pub const RX: u8 = 8;
    pub const RY: u8 = 16;
    pub const RZ: u8 = 32;
    /// All three displacements.
    pub const U: u8 = 7;
    /// All six DOF (a pin).
    pub const ALL: u8 = 63;
}

/// Fixed degrees of freedom per particle (zero increment in every step).
#[derive(Debug, Clone, PartialEq)]
pub struct Constraints {
    /// Fixed-DOF mask per particle, bits of [`dof`].
    pub fixed: Vec<u8>,
    /// Pin components that the fixed DOF leave free (default); if false, such a component is a
    /// [`SolveError`] (the stiffness would be singular).
    pub pin_floating: bool,
}

impl Constraints {
    /// No fixed DOF on `n` particles; floating components are pinned.
    pub fn none(n: usize) -> Self {
        Constraints { fixed: vec![0; n], pin_floating: true }
    }

    /// The paper's plane constraints: a particle whose sphere lies within `rel_gap·r_i` of the
    /// plane x = x_min (y_min, z_min) of the packing's bounding box (centre within `(1 + rel_gap)·r_i`
    /// of it, overlap counts) gets its x (y, z) displacement fixed. docs/mechanics.md's `rel_gap` is 0.01.
    /// With the packing framed at the origin these are the planes x = 0, y = 0, z = 0. Set once at the
    /// start of a run. `positions` [m], `radii` [m].
    pub fn principal_planes(positions: &[Vector3<f64>], radii: &[f64], rel_gap: f64) -> Result<Self, ConfigError> {
        if positions.len() != radii.len() {
            return Err(ConfigError::invalid(format!("plane constraints: {} positions but {} radii", positions.len(), radii.len())));
        }
        if !(rel_gap.is_finite() && rel_gap >= 0.0) {
            return Err(ConfigError::invalid(format!("plane constraints: relative gap {rel_gap} must be finite and ≥ 0")));
        }
        let mut lo = Vector3::repeat(f64::INFINITY);
        for (x, &r) in positions.iter().zip(radii) {
            if !(r.is_finite() && r > 0.0) || !x.iter().all(|v| v.is_finite()) {
                return Err(ConfigError::invalid(format!("plane constraints: particle at {x:?} with radius {r} m is not finite/positive")));
            }
            lo = lo.inf(&x.add_scalar(-r));
        }
        let mut c = Constraints::none(positions.len());
        for (i, (x, &r)) in positions.iter().zip(radii).enumerate() {
            for a in 0..3 {
                if x[a] - lo[a] <= (1.0 + rel_gap) * r {
                    c.fixed[i] |= 1 << a;
                }
            }
        }
        Ok(c)
    }

    /// Adds the DOF of `mask` (bits of [`dof`]) to particle `i`'s fixed set.
    pub fn fix(&mut self, i: usize, mask: u8) -> Result<(), ConfigError> {
        match self.fixed.get_mut(i) {
            Some(m) => {
                *m |= mask & dof::ALL;
                Ok(())
            }
            None => Err(ConfigError::invalid(format!("constraint on particle {i}, but there are only {} particles", self.fixed.len()))),
        }
    }
}

/// Outcome of the topology analysis: which particles are solved, which DOF are fixed, where each
/// free DOF sits in the equation vector.
#[derive(Debug, Clone, PartialEq)]
pub struct TopologyReport {
    /// Connected components with at least one bond.
    pub components: usize,
    /// Particles without bonds (left out of the solve).
    pub rattlers: Vec<u32>,
    /// Particles pinned (all six DOF fixed) because their component was not held by its constraints.
    pub pinned: Vec<u32>,
    /// Effective fixed-DOF mask per particle (rattlers: all).
    pub fixed: Vec<u8>,
    /// Equation index of each DOF `6i + k`, `u32::MAX` if fixed.
    pub eq: Vec<u32>,
    /// Number of equations.
    pub n_eq: usize,
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[i as usize];
        parent[i as usize] = parent[p as usize];
        i = p;
    }
    i
}

/// Rank of the rigid-mode components at the fixed DOF of one component, `members` with centroid
/// `c` and size `h` (coordinates are centred and scaled by `h` so that the rank test is
/// scale-free).
fn rigid_rank(members: &[u32], fixed: &[u8], pos: &[Vector3<f64>], c: &Vector3<f64>, h: f64) -> usize {
    let mut gram = Matrix6::<f64>::zeros();
    for &i in members {
        let m = fixed[i as usize];
        if m == 0 {
            continue;
        }
        let x = (pos[i as usize] - c) / h;
        for k in 0..6 {
            if m & (1 << k) == 0 {
                continue;
            }
            // row: value of DOF k under the six rigid modes (t_x, t_y, t_z, ω_x, ω_y, ω_z);
            // u = t + ω × x, θ = ω
            let mut g = Vector6::zeros();
            if k < 3 {
                g[k] = 1.0;
                for j in 0..3 {
                    let mut w = Vector3::zeros();
                    w[j] = 1.0;
                    g[3 + j] = w.cross(&x)[k];
                }
            } else {
                g[k] = 1.0;
            }
            gram += g * g.transpose();
        }
    }
    let eig = SymmetricEigen::new(gram).eigenvalues;
    let lmax = eig.iter().copied().fold(0.0, f64::max).max(1.0);
    eig.iter().filter(|&&l| l > 1e-9 * lmax).count()
}

/// Analyses the bond graph `pairs` on `n` particles at positions `pos` [m] under `cons`.
pub fn analyse(n: usize, pairs: &[[u32; 2]], pos: &[Vector3<f64>], cons: &Constraints) -> Result<TopologyReport, SolveError> {
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut degree = vec![0u32; n];
    for &[a, b] in pairs {
        degree[a as usize] += 1;
        degree[b as usize] += 1;
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
    // members per component, in particle order (deterministic)
    let mut root_of = vec![0u32; n];
    for i in 0..n as u32 {
        root_of[i as usize] = find(&mut parent, i);
    }
    let mut comp_index = vec![u32::MAX; n];
    let mut members: Vec<Vec<u32>> = Vec::new();
    let mut rattlers = Vec::new();
    for i in 0..n {
        if degree[i] == 0 {
            rattlers.push(i as u32);
            continue;
        }
        let r = root_of[i] as usize;
        if comp_index[r] == u32::MAX {
            comp_index[r] = members.len() as u32;
            members.push(Vec::new());
        }
        members[comp_index[r] as usize].push(i as u32);
    }
    let mut fixed = cons.fixed.clone();
    for &i in &rattlers {
        fixed[i as usize] = dof::ALL;
    }
    let mut pinned = Vec::new();
    for m in &members {
        let c = m.iter().map(|&i| pos[i as usize]).sum::<Vector3<f64>>() / m.len() as f64;
        let h = m.iter().map(|&i| (pos[i as usize] - c).norm()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let rank = rigid_rank(m, &fixed, pos, &c, h);
        if rank < 6 {
            let nearest =
                m.iter().copied().min_by(|&a, &b| (pos[a as usize] - c).norm_squared().total_cmp(&(pos[b as usize] - c).norm_squared())).unwrap_or(m[0]);
            if !cons.pin_floating {
                return Err(SolveError::new(
                    "mechanics constraints",
                    format!(
                        "the stiffness is singular: a bonded component of {} particles (nearest its centroid: particle {nearest}) \
                         has {} free rigid-body mode(s) that its fixed DOF do not hold; constrain it or enable pinning",
                        m.len(),
                        6 - rank
                    ),
                ));
            }
            for &i in m {
                fixed[i as usize] = 0;
            }
            fixed[nearest as usize] = dof::ALL;
            pinned.push(nearest);
        }
    }
    let mut eq = vec![u32::MAX; 6 * n];
    let mut n_eq = 0usize;
    for i in 0..n {
        for k in 0..6 {
            if fixed[i] & (1 << k) == 0 {
                eq[6 * i + k] = n_eq as u32;
                n_eq += 1;
            }
        }
    }
    Ok(TopologyReport { components: members.len(), rattlers, pinned, fixed, eq, n_eq })
}

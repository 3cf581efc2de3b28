//! The bonded link between two particles (docs/mechanics.md (B1)–(B7), "The link" and
//! (B5); Ivannikov et al. 2022 eqs. 18–40 with the eq. 37 signs corrected).
//!
//! A contact between particles A and B is a 2-node element with 6 DOF per node,
//! `y = [u_A, θ_A, u_B, θ_B]`. With the bond points `l_A0 = y4·e3` (from A's centre) and
//! `l_B0 = −y7·e3` (from B's centre), the link deformation is `y_link = H·y` (eq. 29),
//!
//! ```text
//! ε = u_A − u_B − L_A0·θ_A + L_B0·θ_B,     γ = θ_A − θ_B          (eqs. 25–26)
//! ```
//!
//! and the nodal forces are `P = Hᵀ·K_link·H·y` (eqs. 39–40) with
//! `K_link = diag(GA, GA, EA, EI, EI, GJ)/L_b` in the local frame (eq. 33–36, `L_b = 2R_m`).
//!
//! Every function here works in the **scaled** unknowns of docs/mechanics.md (B10):
//! `ỹ = [u_A, r̄·θ_A, u_B, r̄·θ_B]` [m], so the element matrix `S·K·S` has all entries in N/m and
//! its moments are divided by `r̄` (`r_scale` below). `r_scale = 1` gives the unscaled matrix.

use crate::error::ModelError;
use nalgebra::{Matrix3, Matrix6, SMatrix, Vector3};
use std::f64::consts::PI;

/// 6×12 kinematic matrix (link deformation from the two nodes' DOF).
pub type Kinematics = SMatrix<f64, 6, 12>;
/// 12×12 element stiffness matrix.
pub type ElementMatrix = SMatrix<f64, 12, 12>;

/// Cross-product matrix `skew(l)`, `skew(l)·θ = l × θ`.
pub fn skew(l: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -l.z, l.y, l.z, 0.0, -l.x, -l.y, l.x, 0.0)
}

/// Diagonal of `K_link` (eqs. 33–36): `[G·A, G·A, E·A, E·I, E·I, G·J] / L_b` with
/// `A = πR_m²`, `I = πR_m⁴/4`, `J = πR_m⁴/2`, `G = E/(2(1+ν))`, `L_b = 2R_m`.
/// Units: N/m for the first three (shear, shear, tension), N·m for the last three
/// (bending, bending, torsion). `young` [Pa], `poisson` [1], `r_m` = (R_A + R_B)/2 of the
/// initial radii [m]. Axial entry: `E·A/L_b = (π/2)·E·R_m`, the constant of the load (F5).
pub fn link_stiffness(young: f64, poisson: f64, r_m: f64) -> [f64; 6] {
    let g = young / (2.0 * (1.0 + poisson));
    let a = PI * r_m * r_m;
    let i = 0.25 * PI * r_m.powi(4);
    let j = 0.5 * PI * r_m.powi(4);
    let lb = 2.0 * r_m;
    [g * a / lb, g * a / lb, young * a / lb, young * i / lb, young * i / lb, g * j / lb]
}

/// Elastic constants `(E, ν)` of a link between particles of two materials: the link is two
/// half-links of length R_m in series, so E and G = E/(2(1+ν)) are the harmonic means of the two
/// materials' (docs/mechanics.md, "Mixed-material links"); equal materials give their own (E, ν).
pub fn series_elastic(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    if a == b {
        return a;
    }
    let g = |m: [f64; 2]| m[0] / (2.0 * (1.0 + m[1]));
    let e = 2.0 * a[0] * b[0] / (a[0] + b[0]);
    let gm = 2.0 * g(a) * g(b) / (g(a) + g(b));
    [e, e / (2.0 * gm) - 1.0]
}

/// Local frame `R = [e1 e2 e3]ᵀ` (rows are the unit vectors): e3 given, e1 ⟂ e3 built from the
/// global axis least aligned with e3, e2 = e3 × e1 (right-handed). The link is isotropic in the
/// e1–e2 plane, so the choice of e1 does not change the element matrix.
pub fn frame(e3: &Vector3<f64>) -> Matrix3<f64> {
    let a = if e3.x.abs() <= e3.y.abs() && e3.x.abs() <= e3.z.abs() {
        Vector3::x()
    } else if e3.y.abs() <= e3.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let e1 = a.cross(e3).normalize();
    let e2 = e3.cross(&e1);
    Matrix3::from_rows(&[e1.transpose(), e2.transpose(), e3.transpose()])
}

/// Geometry of one link for one step: the step's frame axis `e3` (unit, A → B) and the two lever
/// arms from the centres to the bond point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BondGeometry {
    /// Unit vector from A's centre to B's centre [1].
    pub e3: Vector3<f64>,
    /// `l_A0 = y4·s·e3` from A's centre to the bond point [m].
    pub l_a: Vector3<f64>,
    /// `l_B0 = −y7·s·e3` from B's centre to the bond point [m].
    pub l_b: Vector3<f64>,
}

impl BondGeometry {
    /// Geometry from the current centres `x_a`, `x_b` [m] and the current corrected `y4`, `y7` [m]
    /// (docs/diffusion7.md (C4)), both scaled by `s = d/(y4 + y7)` with `d = |x_b − x_a|`
    /// (docs/mechanics.md (B2): the bond points then coincide exactly, so the rigid modes of the pair
    /// carry no energy).
    pub fn new(x_a: &Vector3<f64>, x_b: &Vector3<f64>, y4: f64, y7: f64) -> Result<Self, ModelError> {
        let dx = x_b - x_a;
        let d = dx.norm();
        if !(d.is_finite() && d > 0.0) {
            return Err(ModelError::new(format!("bond: centre distance {d} m is not positive and finite")));
        }
        if !(y4.is_finite() && y7.is_finite() && y4 + y7 > 0.0) {
            return Err(ModelError::new(format!("bond: y4 = {y4} m, y7 = {y7} m must be finite with y4 + y7 > 0")));
        }
        let s = d / (y4 + y7);
        let e3 = dx / d;
        Ok(BondGeometry { e3, l_a: e3 * (y4 * s), l_b: -e3 * (y7 * s) })
    }
}

/// `H` of eq. 29 in global axes, unscaled: `[[I, −L_A0, −I, L_B0], [O, I, O, −I]]`.
pub fn h_matrix(l_a: &Vector3<f64>, l_b: &Vector3<f64>) -> Kinematics {
    let mut h = Kinematics::zeros();
    let i3 = Matrix3::identity();
    h.fixed_view_mut::<3, 3>(0, 0).copy_from(&i3);
    h.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(l_a)));
    h.fixed_view_mut::<3, 3>(0, 6).copy_from(&(-i3));
    h.fixed_view_mut::<3, 3>(0, 9).copy_from(&skew(l_b));
    h.fixed_view_mut::<3, 3>(3, 3).copy_from(&i3);
    h.fixed_view_mut::<3, 3>(3, 9).copy_from(&(-i3));
    h
}

/// `B = diag(R, R)·H·S`: the link deformation in the local frame from the scaled nodal unknowns
/// (`S = diag(I, I/r̄, I, I/r̄)`, `r_scale = r̄` [m]).
pub fn kinematics(g: &BondGeometry, r_scale: f64) -> Kinematics {
    let r = frame(&g.e3);
    let mut b = Kinematics::zeros();
    let inv = 1.0 / r_scale;
    b.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    b.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-(r * skew(&g.l_a)) * inv));
    b.fixed_view_mut::<3, 3>(0, 6).copy_from(&(-r));
    b.fixed_view_mut::<3, 3>(0, 9).copy_from(&((r * skew(&g.l_b)) * inv));
    b.fixed_view_mut::<3, 3>(3, 3).copy_from(&(r * inv));
    b.fixed_view_mut::<3, 3>(3, 9).copy_from(&(-r * inv));
    b
}

/// Element matrix `Bᵀ·diag(k)·B` = `S·Hᵀ·diag(Rᵀ,Rᵀ)·K_link·diag(R,R)·H·S` (eq. 40, scaled) [N/m].
pub fn element_matrix(g: &BondGeometry, k: &[f64; 6], r_scale: f64) -> ElementMatrix {
    let b = kinematics(g, r_scale);
    let mut db = b;
    for (row, &kk) in k.iter().enumerate() {
        db.row_mut(row).scale_mut(kk);
    }
    b.transpose() * db
}

/// The blocks `(K_AA, K_AB, K_BB)` of [`element_matrix`] (`K_BA = K_ABᵀ`), from the 3×3 blocks
/// of `B = [[R, T_A, −R, T_B], [O, Q, O, −Q]]` (`T_A = −R·skew(l_A0)/r̄`, `T_B = R·skew(l_B0)/r̄`,
/// `Q = R/r̄`) and `diag(k) = diag(D_t, D_r)`: `K_AA = [[RᵀD_tR, RᵀD_tT_A], [·ᵀ, T_AᵀD_tT_A + QᵀD_rQ]]`,
/// `K_AB = [[−RᵀD_tR, RᵀD_tT_B], [−T_AᵀD_tR, T_AᵀD_tT_B − QᵀD_rQ]]`,
/// `K_BB = [[RᵀD_tR, −RᵀD_tT_B], [·ᵀ, T_BᵀD_tT_B + QᵀD_rQ]]`. A quarter of the 12×12 product's
/// work (its zero blocks and `K_BA` skipped); the same matrix to round-off.
pub fn element_blocks(g: &BondGeometry, k: &[f64; 6], r_scale: f64) -> (Matrix6<f64>, Matrix6<f64>, Matrix6<f64>) {
    let r = frame(&g.e3);
    let inv = 1.0 / r_scale;
    let ta = -(r * skew(&g.l_a)) * inv;
    let tb = (r * skew(&g.l_b)) * inv;
    let scale_rows = |m: &Matrix3<f64>, d: [f64; 3]| Matrix3::from_fn(|i, j| d[i] * m[(i, j)]);
    let dt = [k[0], k[1], k[2]];
    let (dt_r, dt_ta, dt_tb) = (scale_rows(&r, dt), scale_rows(&ta, dt), scale_rows(&tb, dt));
    let rt = r.transpose();
    let rr = rt * dt_r;
    let r_ta = rt * dt_ta;
    let r_tb = rt * dt_tb;
    let qq = rt * scale_rows(&r, [k[3], k[4], k[5]]) * (inv * inv);
    let ta_ta = ta.transpose() * dt_ta + qq;
    let ta_tb = ta.transpose() * dt_tb - qq;
    let tb_tb = tb.transpose() * dt_tb + qq;
    let block = |a: Matrix3<f64>, b: Matrix3<f64>, c: Matrix3<f64>, d: Matrix3<f64>| {
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
        m.fixed_view_mut::<3, 3>(0, 3).copy_from(&b);
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&c);
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&d);
        m
    };
    (block(rr, r_ta, r_ta.transpose(), ta_ta), block(-rr, r_tb, -r_ta.transpose(), ta_tb), block(rr, -r_tb, -r_tb.transpose(), tb_tb))
}

/// Link forces and moments in the local frame, `P_link = K_link·y_link` (eq. 32), from the scaled
/// nodal unknowns `y` (`[u_A, r̄θ_A, u_B, r̄θ_B]` [m]): `[F_1, F_2, F_3]` [N] and `[M_1, M_2, M_3]`
/// [N·m]. `ε_3 = (u_A − u_B)·e3` is the axial approach ξ of (C1), so `F_3 > 0` is compression.
pub fn link_forces(g: &BondGeometry, k: &[f64; 6], r_scale: f64, y: &SMatrix<f64, 12, 1>) -> [f64; 6] {
    let yl = kinematics(g, r_scale) * y;
    std::array::from_fn(|i| k[i] * yl[i])
}

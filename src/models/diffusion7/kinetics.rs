//! Chemical potentials (M2), (M3), the twelve volume fluxes (M4), (M5), the region balances (M7)
//! and the ODE (M8) of the 7-DOF model; conservation and dissipation (M10); the stress term of
//! the GB potentials under a mechanical normal force (M11)–(M13).

use super::geometry::{Side, SideDerivs, sides, violation_error};
use super::material::{Coeffs, ContactParams};
use crate::error::ModelError;
use std::f64::consts::PI;

/// Everything the right-hand side computes at one state (for tests and output).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evaluation {
    /// Per-side geometry (A, B).
    pub sides: [Side; 2],
    /// Per-side derivatives (G7)–(G9).
    pub derivs: [SideDerivs; 2],
    /// ∂V/∂y_i of the pair (M1) [m²].
    pub dv: [f64; 7],
    /// Chemical potentials μ_1..μ_7 (M3), with the stress term (M11) under a normal force [J].
    pub mu: [f64; 7],
    /// Fluxes per side, paths I..VI (M5) [m³/s]; `J > 0` from source to sink as in Table 1.
    pub flux: [[f64; 6]; 2],
    /// Net volume rates Q_1..Q_7 (M7) [m³/s].
    pub q: [f64; 7],
    /// dy/dt (M8) [m/s].
    pub dydt: [f64; 7],
    /// d𝒢/dt = Σ μ_i Q_i / Ω (M10) [W]; under a normal force F_n this is dΨ/dt of the free
    /// energy with the load's potential, Ψ = 𝒢 + F_n·(y4 + y7) (M12).
    pub dg_dt: f64,
}

/// The linear response of the approach rate to a normal force (M13)–(M14) at state `y` [m]
/// with coefficients `k` (their `normal_force` ignored): `(v0, M_c)`, the unloaded approach rate
/// `v0 = −(ẏ4 + ẏ7)` [m/s] and the mobility `M_c = Ω[(k_gb + k_lat,A·a)/(∂V/∂y4)² +
/// (k_gb + k_lat,B·a)/(∂V/∂y7)²]` [m/(N·s)], so that `−(ẏ4 + ẏ7) = v0 + M_c·F_n` and
/// `F_s = v0/M_c` is the (tensile) force that holds the contact at rest.
pub fn load_response(y: &[f64; 7], k: &Coeffs) -> Result<(f64, f64), ModelError> {
    let k0 = Coeffs { normal_force: 0.0, ..*k };
    let e = evaluate(y, &k0)?;
    let a = y[0];
    let m = k.omega * ((k.k_gb + k.k_lat_gb[0] * a) / (e.dv[3] * e.dv[3]) + (k.k_gb + k.k_lat_gb[1] * a) / (e.dv[6] * e.dv[6]));
    Ok((-(e.dydt[3] + e.dydt[6]), m))
}

/// Full evaluation of the model at state `y` [m] with transport coefficients `k` (one temperature).
#[inline]
pub fn evaluate(y: &[f64; 7], k: &Coeffs) -> Result<Evaluation, ModelError> {
    let (sa, sb) = sides(y).map_err(|(s, v)| violation_error(s, v, y))?;
    let da = sa.derivs().map_err(|v| violation_error(0, v, y))?;
    let db = sb.derivs().map_err(|v| violation_error(1, v, y))?;
    let a = y[0];
    let om = k.omega;
    let dv = [da.dv[0] + db.dv[0], da.dv[1], da.dv[2], da.dv[3], db.dv[1], db.dv[2], db.dv[3]];
    // (M3)
    let mu1 = om * (k.gamma_s[0] * da.da[0] + k.gamma_s[1] * db.da[0] + k.gamma_gb * 2.0 * PI * a) / dv[0];
    let side_mu = |g: f64, d: &SideDerivs| [om * g * d.da[1] / d.dv[1], om * g * d.ratio_c, om * g * d.da[3] / d.dv[3]];
    let mut ma = side_mu(k.gamma_s[0], &da);
    let mut mb = side_mu(k.gamma_s[1], &db);
    // (M11): a normal force F_n (compressive > 0) adds the work of the load per volume removed
    // from each GB, Ω·F_n/(∂V/∂y4) and Ω·F_n/(∂V/∂y7); guarded so that F_n = 0 adds nothing at all
    if k.normal_force != 0.0 {
        ma[2] += om * k.normal_force / dv[3];
        mb[2] += om * k.normal_force / dv[6];
    }
    let mu = [mu1, ma[0], ma[1], ma[2], mb[0], mb[1], mb[2]];
    // (M5): paths I..VI for each side
    let fl = |s: usize, sd: &Side, m: &[f64; 3]| {
        let (mu2, mu3, mu4) = (m[0], m[1], m[2]);
        let geo_neck = (a + sd.h) / sd.s;
        let geo_cap = sd.h / sd.s;
        [
            k.k_gb * (mu4 - mu1),
            k.k_lat_gb[s] * a * (mu4 - mu1),
            k.k_s_neck[s] * geo_neck * (mu3 - mu1),
            k.k_b_neck[s] * (a + sd.h) * (mu3 - mu1),
            k.k_s_cap[s] * geo_cap * (mu2 - mu3),
            k.k_b_cap[s] * sd.h * (mu2 - mu3),
        ]
    };
    let ja = fl(0, &sa, &ma);
    let jb = fl(1, &sb, &mb);
    // (M7)
    let q1 = ja[0] + jb[0] + ja[1] + jb[1] + ja[2] + jb[2] + ja[3] + jb[3];
    let q = [q1, -(ja[4] + ja[5]), (ja[4] + ja[5]) - (ja[2] + ja[3]), -(ja[0] + ja[1]), -(jb[4] + jb[5]), (jb[4] + jb[5]) - (jb[2] + jb[3]), -(jb[0] + jb[1])];
    let mut dydt = [0.0; 7];
    let mut dg = 0.0;
    for i in 0..7 {
        dydt[i] = q[i] / dv[i];
        dg += mu[i] * q[i];
    }
    if !dydt.iter().all(|v| v.is_finite()) {
        return Err(ModelError::new("non-finite 7-DOF rate").with_context(format!("y = {y:?} m, dy/dt = {dydt:?} m/s")));
    }
    Ok(Evaluation { sides: [sa, sb], derivs: [da, db], dv, mu, flux: [ja, jb], q, dydt, dg_dt: dg / om })
}

/// The ODE right-hand side dy/dt [m/s] (M8) at state `y` [m] and contact temperature `t` [K].
#[inline]
pub fn rates(y: &[f64; 7], params: &ContactParams, t: f64) -> Result<[f64; 7], ModelError> {
    let k = params.at(t)?;
    rates_with(y, &k)
}

/// dy/dt [m/s] with precomputed coefficients (the integrator's hot path).
#[inline]
pub fn rates_with(y: &[f64; 7], k: &Coeffs) -> Result<[f64; 7], ModelError> {
    evaluate(y, k).map(|e| e.dydt)
}

/// Solid volume V [m³] and interfacial free energy 𝒢 [J] (G10) of a state, with the side
/// surface energies `gamma_s` [J/m²] and GB energy `gamma_gb` [J/m²] (mixed contacts, §3).
pub fn invariants_with(y: &[f64; 7], gamma_s: [f64; 2], gamma_gb: f64) -> Result<(f64, f64), ModelError> {
    let (sa, sb) = sides(y).map_err(|(s, v)| violation_error(s, v, y))?;
    let v = sa.volume() + sb.volume();
    let g = gamma_s[0] * sa.area() + gamma_s[1] * sb.area() + gamma_gb * PI * y[0] * y[0];
    Ok((v, g))
}

/// (V [m³], 𝒢 [J]) of a state for the contact parameters of one phase (docs/diffusion7.md §8).
pub fn invariants(y: &[f64; 7], params: &ContactParams) -> Result<(f64, f64), ModelError> {
    invariants_with(y, [params.sides[0].gamma_s, params.sides[1].gamma_s], params.gamma_gb)
}

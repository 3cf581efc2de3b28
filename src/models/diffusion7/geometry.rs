//! Geometry of the 7-DOF contact (docs/diffusion7.md §2, all derived by the project): per-side
//! lengths (G1)–(G3), (G6), volume and free surface (G4), (G5), their closed-form partial
//! derivatives (G7), (G8) and the regular ratio (G9). Pure functions of the state, SI units (m).

use crate::error::ModelError;
use std::f64::consts::PI;

/// Index names of the seven unknowns `y = [a, R_A, c_A, d_A, R_B, c_B, d_B]` [m] (docs/diffusion7.md §1).
pub const NECK: usize = 0;

/// One side (cap + cone) of the pair, evaluated at a state; all lengths in m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Side {
    /// Neck radius `a = y1` [m].
    pub a: f64,
    /// Cap radius `R` (y2 or y5) [m].
    pub r: f64,
    /// Cone axial length `c` (y3 or y6) [m].
    pub c: f64,
    /// Centre–GB distance `d` (y4 or y7) [m].
    pub d: f64,
    /// (G1) `p = d − c` [m].
    pub p: f64,
    /// (G2) junction radius `h = sqrt(R² − p²)` [m].
    pub h: f64,
    /// (G3) cone slant length `s` [m].
    pub s: f64,
    /// (G6) tangency margin `τ = p·c − h·(h − a)` [m²].
    pub tau: f64,
}

/// Which admissibility condition (docs/diffusion7.md §2) a state violates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Violation {
    /// (A1) a, R or c not positive (or not finite).
    A1,
    /// (A2) |p| ≥ R: the junction plane misses the sphere.
    A2,
    /// (A3) τ ≤ 0: cone tangent to or inside the cap.
    A3,
    /// (A4) ∂V/∂d ≤ 0.
    A4,
}

impl Violation {
    /// A sentence naming the condition (used in `ModelError`s).
    pub fn describe(self) -> &'static str {
        match self {
            Violation::A1 => "(A1) neck radius, cap radius and cone length must be positive and finite",
            Violation::A2 => "(A2) |p| < R: the junction plane must cut the sphere",
            Violation::A3 => "(A3) tau > 0: the cone must not be tangent to the cap",
            Violation::A4 => "(A4) dV/dd > 0",
        }
    }
}

/// Partial derivatives of one side's volume and free surface w.r.t. (a, R, c, d) — (G7), (G8) —
/// plus the regular ratio (G9) `(∂A/∂c)/(∂V/∂c)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideDerivs {
    /// ∂V/∂(a, R, c, d) [m²].
    pub dv: [f64; 4],
    /// ∂A/∂(a, R, c, d) [m].
    pub da: [f64; 4],
    /// (G9) (∂A/∂c)/(∂V/∂c) [1/m].
    pub ratio_c: f64,
}

impl Side {
    /// Evaluates (G1)–(G3), (G6) and checks (A1)–(A3).
    #[inline]
    pub fn new(a: f64, r: f64, c: f64, d: f64) -> Result<Side, Violation> {
        if !(a > 0.0 && r > 0.0 && c > 0.0 && d.is_finite() && a.is_finite() && r.is_finite() && c.is_finite()) {
            return Err(Violation::A1);
        }
        let p = d - c;
        let h2 = r * r - p * p;
        if !(h2 > 0.0) {
            return Err(Violation::A2);
        }
        let h = h2.sqrt();
        let s = ((h - a) * (h - a) + c * c).sqrt();
        let tau = p * c - h * (h - a);
        if !(tau > 0.0) {
            return Err(Violation::A3);
        }
        Ok(Side { a, r, c, d, p, h, s, tau })
    }

    /// (G4) volume of cap + frustum [m³].
    #[inline]
    pub fn volume(&self) -> f64 {
        let (a, r, c, p, h) = (self.a, self.r, self.c, self.p, self.h);
        PI / 3.0 * (r + p) * (r + p) * (2.0 * r - p) + PI / 3.0 * c * (a * a + a * h + h * h)
    }

    /// (G5) free surface: spherical cap + lateral cone [m²].
    #[inline]
    pub fn area(&self) -> f64 {
        2.0 * PI * self.r * (self.r + self.p) + PI * (self.a + self.h) * self.s
    }

    /// θ = h(h − a)/(p c), tangency ratio (monitoring only, docs/diffusion7.md (G6)).
    pub fn theta(&self) -> f64 {
        self.h * (self.h - self.a) / (self.p * self.c)
    }

    /// (G7), (G8), (G9); checks (A4).
    #[inline]
    pub fn derivs(&self) -> Result<SideDerivs, Violation> {
        let (a, r, c, p, h, s, tau) = (self.a, self.r, self.c, self.p, self.h, self.s, self.tau);
        let dv_a = PI / 3.0 * c * (2.0 * a + h);
        let dv_r = 2.0 * PI * r * (r + p) + PI / 3.0 * c * (a + 2.0 * h) * r / h;
        let dv_c = PI / 3.0 * (a + 2.0 * h) * tau / h;
        let dv_d = PI / 3.0 * (a * a + a * h + h * h) - dv_c;
        if !(dv_d > 0.0) {
            return Err(Violation::A4);
        }
        let w = (s * s + h * h - a * a) / s;
        let da_a = PI * (s * s - h * h + a * a) / s;
        let da_r = 2.0 * PI * (2.0 * r + p) + PI * w * r / h;
        let da_c = -2.0 * PI * r + PI * w * p / h + PI * (a + h) * c / s;
        let da_d = 2.0 * PI * r - PI * w * p / h;
        // (G9)
        let x = p * (2.0 * h * (h - a) + c * c) + h * c * (h + a);
        let m = 4.0 * h.powi(4) - 4.0 * h.powi(3) * a + 3.0 * h * h * c * c - 4.0 * h * p * a * c + h * a * c * c + p * c.powi(3);
        let ratio_c = 3.0 * m / (s * (a + 2.0 * h) * (x + 2.0 * h * r * s));
        Ok(SideDerivs { dv: [dv_a, dv_r, dv_c, dv_d], da: [da_a, da_r, da_c, da_d], ratio_c })
    }
}

/// Both sides of a state `y` (A from y1..y4, B from y1, y5..y7).
#[inline]
pub fn sides(y: &[f64; 7]) -> Result<(Side, Side), (usize, Violation)> {
    let a = Side::new(y[0], y[1], y[2], y[3]).map_err(|v| (0, v))?;
    let b = Side::new(y[0], y[4], y[5], y[6]).map_err(|v| (1, v))?;
    Ok((a, b))
}

/// Turns a violation into a `ModelError` naming side and condition.
pub fn violation_error(side: usize, v: Violation, y: &[f64; 7]) -> ModelError {
    ModelError::new(format!("inadmissible 7-DOF state on side {}: {}", if side == 0 { "A" } else { "B" }, v.describe())).with_context(format!("y = {y:?} m"))
}

/// (G10) total solid volume V [m³] and free surface A_s [m²] and GB area A_gb [m²] of a state.
pub fn volume_and_areas(y: &[f64; 7]) -> Result<(f64, f64, f64), ModelError> {
    let (sa, sb) = sides(y).map_err(|(s, v)| violation_error(s, v, y))?;
    Ok((sa.volume() + sb.volume(), sa.area() + sb.area(), PI * y[0] * y[0]))
}

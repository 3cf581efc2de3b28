//! Per-contact state, the initial state of a new contact (docs/diffusion7.md §4, (I1)–(I4)), the virtual
//! sintering force (§5, (F1)–(F5)) and the correction of y4, y7 after the mechanical step
//! (§6, (C1)–(C4)). Pure functions for the coupled simulator.

use super::geometry::{Side, sides};
use crate::error::ModelError;
use std::f64::consts::PI;

/// Defaults of (I4): relative neck excess ε and cone parameter η.
pub const DEFAULT_EPSILON: f64 = 0.01;
pub const DEFAULT_ETA: f64 = 0.1;

/// State of one diffusion contact (docs/design.md: a small `Copy` struct).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Contact7 {
    /// Current state `[a, R_A, c_A, d_A, R_B, c_B, d_B]` [m].
    pub y: [f64; 7],
    /// Last accepted (corrected) state y(t_{i−1}) [m], for rollback and (C2).
    pub y_prev: [f64; 7],
    /// (F1) bar length at creation `L0 = y4(t_c) + y7(t_c)` [m].
    pub l0: f64,
    /// Initial radii (R_A, R_B) [m] (for R_m (F3) and R_min (T1)).
    pub r0: [f64; 2],
    /// Creation time t_c [s].
    pub t_created: f64,
    /// Last accepted substep [s] (0 before the first).
    pub h_last: f64,
    /// Unit vector from A to B of the step (for ξ (C1)).
    pub e3: [f64; 3],
    /// Mechanical normal force on the grain boundary [N], compressive positive: the axial force
    /// of the bond under an applied load (docs/pressure.md (P3)); enters the GB potentials by
    /// (M11). 0 without a load (then the model is exactly the unloaded one).
    #[serde(default)]
    pub normal_force: f64,
    /// The contact's change per second in units of the tolerance in the last sweep of a compact
    /// run, `max_i |Δy_i|/(rtol·max(|y_i|, f·R_min))/Δt` [1/s] (its measure (T2b) over Δt when
    /// it was kept): which contacts the next sweep tests by (T2) (docs/diffusion7.md §7); 0 before
    /// the first sweep.
    #[serde(default)]
    pub change_rate: f64,
}

impl Contact7 {
    /// A new contact between spheres of radii `r_a`, `r_b` [m] at centre distance `d_ab` [m]
    /// created at `t_c` [s], with (I1)–(I4) and the given ε, η.
    pub fn new(r_a: f64, r_b: f64, d_ab: f64, t_c: f64, eps: f64, eta: f64) -> Result<Contact7, ModelError> {
        let y = initial_state(r_a, r_b, d_ab, eps, eta)?;
        Ok(Contact7 { y, y_prev: y, l0: y[3] + y[6], r0: [r_a, r_b], t_created: t_c, h_last: 0.0, e3: [0.0, 0.0, 1.0], normal_force: 0.0, change_rate: 0.0 })
    }

    /// A new contact as [`Contact7::new`] but with the initial neck radius `a0` [m] given instead of
    /// (I2)'s `r_c + ε·min(R_A, R_B)` ((I1), (I3), (I4) unchanged; [`initial_state_with_neck`]).
    pub fn with_neck(r_a: f64, r_b: f64, d_ab: f64, t_c: f64, a0: f64, eta: f64) -> Result<Contact7, ModelError> {
        let y = initial_state_with_neck(r_a, r_b, d_ab, a0, eta)?;
        Ok(Contact7 { y, y_prev: y, l0: y[3] + y[6], r0: [r_a, r_b], t_created: t_c, h_last: 0.0, e3: [0.0, 0.0, 1.0], normal_force: 0.0, change_rate: 0.0 })
    }

    /// Mean radius R_m = (R_A + R_B)/2 of the initial radii (F3) [m].
    pub fn r_mean(&self) -> f64 {
        0.5 * (self.r0[0] + self.r0[1])
    }

    /// Smaller initial radius [m] (tolerance scale (T1)).
    pub fn r_min(&self) -> f64 {
        self.r0[0].min(self.r0[1])
    }

    /// (F2) ΔL = L0 − (y4 + y7) [m] (> 0: closer).
    pub fn approach(&self) -> f64 {
        self.l0 - (self.y[3] + self.y[6])
    }

    /// Shrinkage ΔL/L0 [1].
    pub fn shrinkage(&self) -> f64 {
        self.approach() / self.l0
    }

    /// Neck ratio y1/R_min [1] with the initial smaller radius.
    pub fn neck_ratio(&self) -> f64 {
        self.y[0] / self.r_min()
    }
}

/// (I1)–(I4): the initial state of a contact between spheres of radii `r_a`, `r_b` [m] whose centres
/// are `d_ab` [m] apart (`d_ab ≤ r_a + r_b`), neck excess `eps` (1e-4…0.1) and cone parameter `eta`
/// (0…1). Halves η until (A1)–(A4) hold (at most 60 times).
pub fn initial_state(r_a: f64, r_b: f64, d_ab: f64, eps: f64, eta: f64) -> Result<[f64; 7], ModelError> {
    let ctx = || format!("R_A = {r_a} m, R_B = {r_b} m, d_AB = {d_ab} m, eps = {eps}, eta = {eta}");
    check_pair(r_a, r_b, d_ab, eta, &ctx)?;
    if !((1e-4..=0.1).contains(&eps)) {
        return Err(ModelError::new("initial state: eps must lie in [1e-4, 0.1] (I4)").with_context(ctx()));
    }
    let (d_a, d_b, r_c) = radical_plane(r_a, r_b, d_ab);
    // (I2)
    let a0 = r_c + eps * r_a.min(r_b);
    cone_state(r_a, r_b, d_a, d_b, a0, eta, &ctx)
}

/// (I1), (I3), (I4) with the initial neck radius `a0` [m] given (`r_c ≤ a0 < min(R_A, R_B)`, with
/// `r_c` the radius of the spheres' intersection circle) instead of (I2)'s `r_c + ε·min(R_A, R_B)`:
/// the start of a contact created with the volume-conserving neck of its overlap
/// (`contacts.new_contact_state`, docs/coupled.md "New contacts"). Halves η as [`initial_state`].
pub fn initial_state_with_neck(r_a: f64, r_b: f64, d_ab: f64, a0: f64, eta: f64) -> Result<[f64; 7], ModelError> {
    let ctx = || format!("R_A = {r_a} m, R_B = {r_b} m, d_AB = {d_ab} m, a0 = {a0} m, eta = {eta}");
    check_pair(r_a, r_b, d_ab, eta, &ctx)?;
    let (d_a, d_b, r_c) = radical_plane(r_a, r_b, d_ab);
    if !(a0.is_finite() && a0 > 0.0 && a0 >= r_c * (1.0 - 1e-12) && a0 < r_a.min(r_b)) {
        return Err(ModelError::new(format!(
            "initial state: the neck radius a0 must lie in [r_c, min(R_A, R_B)) = [{r_c:e}, {:e}) m and be positive (r_c: radius of the spheres' intersection circle)",
            r_a.min(r_b)
        ))
        .with_context(ctx()));
    }
    cone_state(r_a, r_b, d_a, d_b, a0.max(r_c), eta, &ctx)
}

/// Radii, centre distance and η of an initial state, checked.
fn check_pair(r_a: f64, r_b: f64, d_ab: f64, eta: f64, ctx: &dyn Fn() -> String) -> Result<(), ModelError> {
    if !(r_a > 0.0 && r_b > 0.0 && r_a.is_finite() && r_b.is_finite()) {
        return Err(ModelError::new("initial state: radii must be positive and finite").with_context(ctx()));
    }
    if !(d_ab > (r_a - r_b).abs() && d_ab <= r_a + r_b) {
        return Err(ModelError::new(
            "initial state: centre distance must satisfy |R_A - R_B| < d_AB <= R_A + R_B (touching or overlapping, neither inside the other)",
        )
        .with_context(ctx()));
    }
    if !(eta > 0.0 && eta < 1.0) {
        return Err(ModelError::new("initial state: eta must lie in (0, 1) (I4)").with_context(ctx()));
    }
    Ok(())
}

/// (I1) and the intersection-circle radius r_c of (I2): `(d_A, d_B, r_c)` [m].
fn radical_plane(r_a: f64, r_b: f64, d_ab: f64) -> (f64, f64, f64) {
    let d_a = (d_ab * d_ab + r_a * r_a - r_b * r_b) / (2.0 * d_ab);
    // the same formula for B (= d_AB − d_A up to round-off) keeps equal pairs exactly symmetric
    let d_b = (d_ab * d_ab + r_b * r_b - r_a * r_a) / (2.0 * d_ab);
    let r_c = (r_a * r_a - d_a * d_a).max(0.0).sqrt();
    (d_a, d_b, r_c)
}

/// (I2)'s cone h0 = (1 + η)·a0 and (I3), halving η until (A1)–(A4) hold (at most 60 times).
fn cone_state(r_a: f64, r_b: f64, d_a: f64, d_b: f64, a0: f64, eta: f64, ctx: &dyn Fn() -> String) -> Result<[f64; 7], ModelError> {
    let mut eta = eta;
    for _ in 0..60 {
        let h0 = (1.0 + eta) * a0;
        if h0 >= r_a.min(r_b) {
            eta *= 0.5;
            continue;
        }
        // (I3)
        let c_a = d_a - (r_a * r_a - h0 * h0).sqrt();
        let c_b = d_b - (r_b * r_b - h0 * h0).sqrt();
        let y = [a0, r_a, c_a, d_a, r_b, c_b, d_b];
        if let Ok((sa, sb)) = sides(&y)
            && sa.derivs().is_ok()
            && sb.derivs().is_ok()
        {
            return Ok(y);
        }
        eta *= 0.5;
    }
    Err(ModelError::new("initial state: no admissible cone found by halving eta (neck too large for the smaller sphere?)").with_context(ctx()))
}

/// A sentence on where a state stands relative to the model's domain (for error messages): neck
/// radius against the smaller cap, how much of each sphere is cut away, tangency.
pub fn diagnose(y: &[f64; 7]) -> String {
    let rmin = y[1].min(y[4]);
    let mut s = format!("y1/min(R_A, R_B) = {:.4}", y[0] / rmin);
    if y[0] >= 0.9 * rmin {
        s.push_str(" (the neck has reached the size of the smaller particle: it is being absorbed, the two-cap geometry no longer applies)");
    }
    for (k, (r, c, d)) in [(y[1], y[2], y[3]), (y[4], y[5], y[6])].into_iter().enumerate() {
        let p = d - c;
        if p < 0.0 {
            s.push_str(&format!("; side {} has more than a hemisphere cut away (p/R = {:.3})", if k == 0 { "A" } else { "B" }, p / r));
        }
    }
    if let Some(th) = tangency(y)
        && th[0].max(th[1]) > 0.9
    {
        s.push_str(&format!("; cone near tangency (theta = {:.3}, {:.3})", th[0], th[1]));
    }
    s
}

/// Tangency ratios θ of both sides (monitoring, §2); `None` if the state is inadmissible.
pub fn tangency(y: &[f64; 7]) -> Option<[f64; 2]> {
    sides(y).ok().map(|(a, b): (Side, Side)| [a.theta(), b.theta()])
}

/// (F4) virtual sintering force F_n = (π/2)·E·R_m·ΔL [N] with ΔL = L0 − (y4 + y7) [m], Young's
/// modulus `e` [Pa], mean initial radius `r_m` [m]. Compressive when positive.
pub fn sintering_force(l0: f64, y4: f64, y7: f64, r_m: f64, e: f64) -> f64 {
    0.5 * PI * e * r_m * (l0 - (y4 + y7))
}

/// (F5) load increment of a step ΔF = (π/2)·E·R_m·(Δy4 + Δy7) [N].
pub fn load_increment(dy4: f64, dy7: f64, r_m: f64, e: f64) -> f64 {
    0.5 * PI * e * r_m * (dy4 + dy7)
}

/// Result of the correction (C3), (C4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correction {
    /// Corrected y4(t_i), y7(t_i) [m].
    pub y4: f64,
    pub y7: f64,
    /// Split weights w4 + w7 = 1 [1].
    pub w4: f64,
    pub w7: f64,
    /// ΔL̄ = (y4 + y7) − (y4* + y7*) [m] (Ivannikov et al. 2022 eq. 44).
    pub dl_bar: f64,
}

/// (C2)–(C4): corrects y4, y7 after the mechanical step.
/// `prev` = (y4, y7) of the previous corrected state, `star` = (y4*, y7*) of this step's 7-DOF result,
/// `rates_star` = (ẏ4, ẏ7) at y* [m/s] (fallback of (C3)), `xi` = axial approach of the centres (C1) [m],
/// `r_sum` = R_A + R_B [m].
pub fn correct_y4_y7(prev: (f64, f64), star: (f64, f64), rates_star: (f64, f64), xi: f64, r_sum: f64) -> Correction {
    let (dy4, dy7) = (prev.0 - star.0, prev.1 - star.1);
    let (v4, v7) = if dy4 + dy7 > 1e-12 * r_sum { (dy4, dy7) } else { (-rates_star.0, -rates_star.1) };
    let w4 = if v4 == 0.0 && v7 == 0.0 {
        0.5
    } else if v4 + v7 == 0.0 {
        if v4 > 0.0 { 1.0 } else { 0.0 }
    } else {
        let w = v4 / (v4 + v7);
        if w.is_finite() { w.clamp(0.0, 1.0) } else { 0.5 }
    };
    let w7 = 1.0 - w4;
    let y4 = prev.0 - w4 * xi;
    let y7 = prev.1 - w7 * xi;
    Correction { y4, y7, w4, w7, dl_bar: (y4 + y7) - (star.0 + star.1) }
}

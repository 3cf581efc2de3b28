//! Pure two-sphere neck geometry (docs/heat-model.md (H9)–(H15), "Volume-conserving cylindrical neck";
//! Rojek et al. 2022 eqs. 11–33).
//!
//! Two spheres of radii `r_i ≤ r_j` overlapping by `h = r_i + r_j − d` are replaced by the two
//! spheres with their facing caps cut off plus a cylinder of radius `a` and height
//! `h_n = h_ci + h_cj − h` (eq. 24) of the same total volume (eq. 27):
//! `Z(a) = 3a²h_n − h_cj²(3r_j − h_cj) − h_ci²(3r_i − h_ci) = 0`.

use crate::error::ModelError;

/// The solved neck and the quantities around it (all lengths in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Neck {
    /// Neck (cylinder) radius a [m].
    pub a: f64,
    /// Coble's estimate √(2 r* h), r* = 2 r_i r_j/(r_i + r_j) (eqs. 11–12) [m].
    pub a_coble: f64,
    /// Cap height cut from the smaller sphere h_ci [m] (eq. 25).
    pub h_ci: f64,
    /// Cap height cut from the larger sphere h_cj [m] (eq. 26).
    pub h_cj: f64,
    /// Cylinder height h_n = h_ci + h_cj − h [m] (eq. 24).
    pub h_n: f64,
    /// Newton iterations used (0 for the equal-radius closed form).
    pub iterations: u32,
    /// First Newton iterate [m] (Coble start for the iteration), for diagnostics.
    pub first_iterate: f64,
}

/// Coble's estimate of the neck radius `√(2 r* h)`, `r* = 2 r_i r_j/(r_i + r_j)` (eqs. 11–12, 33) [m].
pub fn coble(r_i: f64, r_j: f64, h: f64) -> f64 {
    let r_star = 2.0 * r_i * r_j / (r_i + r_j);
    (2.0 * r_star * h.max(0.0)).sqrt()
}

fn cap_height(r: f64, a: f64) -> f64 {
    // r − √(r² − a²), written to avoid cancellation for a ≪ r.
    let d = (r * r - a * a).max(0.0);
    a * a / (r + d.sqrt())
}

/// Largest overlap for which a neck with `a ≤ r_small` exists (Z(r_small) = 0) [m]:
/// `h_max = r_i/3 + h_cj* − h_cj*²(3r_j − h_cj*)/(3 r_i²)`, `h_cj* = r_j − √(r_j² − r_i²)`.
pub fn max_overlap(r1: f64, r2: f64) -> f64 {
    let (ri, rj) = if r1 <= r2 { (r1, r2) } else { (r2, r1) };
    let hcj = cap_height(rj, ri);
    ri / 3.0 + hcj - hcj * hcj * (3.0 * rj - hcj) / (3.0 * ri * ri)
}

/// Solves the volume-conserving neck for radii `r1`, `r2` [m] and overlap `h` [m].
///
/// `h ≤ 0` (no overlap) gives `a = 0`. Equal radii use the closed form (eqs. 18–20); unequal radii
/// Newton's method with `dZ/da = 6 a h_n`, started from Coble's estimate clamped to the smaller
/// radius, stopped at `|Δa| ≤ 1e-12 r_i`. Overlaps beyond [`max_overlap`], non-convergence, or a
/// root outside `[r_c, r_i]` are a [`ModelError`].
pub fn solve(r1: f64, r2: f64, h: f64) -> Result<Neck, ModelError> {
    if !(r1 > 0.0 && r2 > 0.0 && r1.is_finite() && r2.is_finite()) || !h.is_finite() {
        return Err(ModelError::new(format!("neck: radii must be positive and finite (r1 = {r1}, r2 = {r2}, h = {h})")));
    }
    let (ri, rj) = if r1 <= r2 { (r1, r2) } else { (r2, r1) };
    let a_coble = coble(ri, rj, h);
    if h <= 0.0 {
        return Ok(Neck { a: 0.0, a_coble: 0.0, h_ci: 0.0, h_cj: 0.0, h_n: 0.0, iterations: 0, first_iterate: 0.0 });
    }
    let h_max = max_overlap(ri, rj);
    if h > h_max * (1.0 + 1e-12) {
        return Err(ModelError::new(format!(
            "neck: overlap h = {h:.6e} m exceeds the model's limit h_max = {h_max:.6e} m for radii {ri:.6e} m and {rj:.6e} m (the neck would exceed the smaller radius)"
        )));
    }
    let finish = |a: f64, iterations: u32, first: f64| {
        let h_ci = cap_height(ri, a);
        let h_cj = cap_height(rj, a);
        Neck { a, a_coble, h_ci, h_cj, h_n: h_ci + h_cj - h, iterations, first_iterate: first }
    };
    if (rj - ri).abs() <= 1e-14 * rj {
        // eqs. 18–20: h_c = [3(2r + h) − √(9(2r + h)² − 96 r h)]/8
        let r = 0.5 * (ri + rj);
        let s = 2.0 * r + h;
        let disc = (9.0 * s * s - 96.0 * r * h).max(0.0);
        let hc = (3.0 * s - disc.sqrt()) / 8.0;
        let a = (2.0 * r * hc - hc * hc).max(0.0).sqrt();
        return Ok(finish(a, 0, a));
    }
    let z = |a: f64| {
        let hci = cap_height(ri, a);
        let hcj = cap_height(rj, a);
        let hn = hci + hcj - h;
        (3.0 * a * a * hn - hcj * hcj * (3.0 * rj - hcj) - hci * hci * (3.0 * ri - hci), 6.0 * a * hn)
    };
    // radius of the spheres' intersection circle (h_n = 0): the minimum of Z
    let d = ri + rj - h;
    let d_i = (d * d + ri * ri - rj * rj) / (2.0 * d);
    let r_c = (ri * ri - d_i * d_i).max(0.0).sqrt();
    let mut a = a_coble.min(ri);
    let mut first = f64::NAN;
    for it in 1..=50u32 {
        let (zv, dz) = z(a);
        if !(dz > 0.0) {
            return Err(ModelError::new(format!(
                "neck: Newton iterate a = {a:.6e} m left the convex branch (dZ/da = {dz:.3e}) for r_i = {ri:.6e}, r_j = {rj:.6e}, h = {h:.6e}"
            )));
        }
        let step = zv / dz;
        a -= step;
        if it == 1 {
            first = a;
        }
        if step.abs() <= 1e-12 * ri {
            if a < r_c * (1.0 - 1e-9) || a > ri * (1.0 + 1e-12) {
                return Err(ModelError::new(format!("neck: root a = {a:.6e} m lies outside [r_c, r_i] = [{r_c:.6e}, {ri:.6e}] m")));
            }
            return Ok(finish(a.min(ri), it, first));
        }
    }
    Err(ModelError::new(format!("neck: Newton did not converge in 50 iterations (r_i = {ri:.6e}, r_j = {rj:.6e}, h = {h:.6e})")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs()
    }

    #[test]
    fn published_unequal_pair() {
        // test values of docs/heat-model.md (Rojek et al. 2022): r_i = 1 mm, r_j = 3 mm, h = 0.2 mm.
        let n = solve(1e-3, 3e-3, 0.2e-3).unwrap();
        assert!(close(n.a, 0.7414663e-3, 1e-7), "{}", n.a);
        assert!(close(n.a_coble, 0.7745967e-3, 1e-7), "{}", n.a_coble);
        assert!(close(n.first_iterate, 0.7450387e-3, 1e-7), "{}", n.first_iterate);
        // docs/heat-model.md gives these to 6 decimals in mm: half a unit of the last digit is 5e-10 m
        assert!((n.h_ci - 0.329010e-3).abs() <= 5e-10);
        assert!((n.h_cj - 0.093072e-3).abs() <= 5e-10);
        assert!((n.h_n - 0.222082e-3).abs() <= 5e-10);
        assert!(n.iterations <= 6);
        // order of arguments does not matter
        assert_eq!(solve(3e-3, 1e-3, 0.2e-3).unwrap().a, n.a);
    }

    #[test]
    fn clamped_start_and_small_overlap() {
        let n = solve(1e-3, 3e-3, 0.4e-3).unwrap();
        assert!(close(n.a, 0.986013e-3, 1e-6), "{}", n.a);
        assert!(n.iterations <= 6, "{}", n.iterations);
        let n = solve(1e-3, 3e-3, 0.06e-3).unwrap();
        assert!(close(n.a, 0.4191863e-3, 1e-7), "{}", n.a);
    }

    #[test]
    fn equal_spheres_closed_form() {
        let n = solve(1.0, 1.0, 0.2).unwrap();
        assert!(close(n.a, 0.610588, 1e-6), "{}", n.a);
        // the closed form conserves volume: Z(a) = 0
        let z = 3.0 * n.a * n.a * n.h_n - 2.0 * n.h_ci * n.h_ci * (3.0 - n.h_ci);
        assert!(z.abs() < 1e-14);
        // and agrees with Newton on a nearly equal pair
        let m = solve(1.0, 1.0 + 1e-9, 0.2).unwrap();
        assert!(close(m.a, n.a, 1e-8));
    }

    #[test]
    fn validity_limit() {
        let hm = max_overlap(1e-3, 3e-3);
        assert!(close(hm, 0.418278e-3, 2e-6), "{hm}");
        assert!(close(max_overlap(1.0, 1.0), 2.0 / 3.0, 1e-12));
        let n = solve(1e-3, 3e-3, hm).unwrap();
        assert!(close(n.a, 1e-3, 1e-6), "{}", n.a);
        let e = solve(1e-3, 3e-3, 1.01 * hm).unwrap_err();
        assert!(e.message.contains("h_max"), "{e}");
        assert!(solve(1.0, 1.0, 0.7).is_err());
        assert!(solve(-1.0, 1.0, 0.1).is_err());
        assert!(solve(1.0, 1.0, f64::NAN).is_err());
    }

    #[test]
    fn coble_overestimates_and_volume_is_conserved_for_many_ratios() {
        for ratio in [1.5, 2.0, 5.0, 10.0, 50.0] {
            let hm = max_overlap(1.0, ratio);
            for f in [1e-6, 1e-3, 0.05, 0.3, 0.7, 0.99] {
                let h = f * hm;
                let n = solve(1.0, ratio, h).unwrap();
                assert!(n.a_coble >= n.a, "ratio {ratio} f {f}");
                assert!(n.iterations <= 8, "ratio {ratio} f {f}: {} iterations", n.iterations);
                let z = 3.0 * n.a * n.a * n.h_n - n.h_cj * n.h_cj * (3.0 * ratio - n.h_cj) - n.h_ci * n.h_ci * (3.0 - n.h_ci);
                let scale = n.h_ci * n.h_ci * 3.0;
                assert!(z.abs() <= 1e-9 * scale, "ratio {ratio} f {f}: Z = {z}");
            }
        }
    }
}

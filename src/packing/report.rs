//! Packing report: laminae relative density (Ivannikov et al. 2022 eq. 48), and the packing's VTU
//! and laminae plot through the shared writers (`crate::io::vtu`, `crate::plot`).

use crate::error::{Error, IoError};
use nalgebra::Vector3;
use std::path::Path;

/// Volume [m³] of a sphere of radius `r` centred at `c` that lies between the planes `a ≤ s ≤ b`
/// (coordinates along the same axis): `∫ π(r² − (s−c)²) ds` over the clipped interval.
pub fn slab_volume(c: f64, r: f64, a: f64, b: f64) -> f64 {
    let lo = (a - c).max(-r);
    let hi = (b - c).min(r);
    if hi <= lo {
        return 0.0;
    }
    let f = |z: f64| r * r * z - z * z * z / 3.0;
    std::f64::consts::PI * (f(hi) - f(lo))
}

/// Laminae of one axis: centres [m] and relative densities ρ_rel,s = V_particles,s / V_lamina,s (eq. 48).
#[derive(Debug, Clone, PartialEq)]
pub struct Laminae {
    pub axis: usize,
    pub centres: Vec<f64>,
    pub density: Vec<f64>,
    /// Whether the lamina lies at least `interior_margin` from both walls.
    pub interior: Vec<bool>,
}

/// Cuts the box `[lo, hi]` along `axis` into laminae of width ≈ `width` (the extent divided into
/// a whole number of equal laminae) and computes eq. 48 for each.
pub fn laminae(pos: &[Vector3<f64>], rad: &[f64], lo: &Vector3<f64>, hi: &Vector3<f64>, axis: usize, width: f64, interior_margin: f64) -> Laminae {
    let ext = hi[axis] - lo[axis];
    let n = ((ext / width).round() as usize).max(1);
    let w = ext / n as f64;
    let cross: f64 = (0..3).filter(|&a| a != axis).map(|a| hi[a] - lo[a]).product();
    let mut vol = vec![0.0; n];
    for (x, &r) in pos.iter().zip(rad) {
        let c = x[axis];
        let k0 = (((c - r - lo[axis]) / w).floor().max(0.0) as usize).min(n - 1);
        let k1 = (((c + r - lo[axis]) / w).floor().max(0.0) as usize).min(n - 1);
        for (k, v) in vol.iter_mut().enumerate().take(k1 + 1).skip(k0) {
            let a = lo[axis] + k as f64 * w;
            *v += slab_volume(c, r, a, a + w);
        }
    }
    let centres: Vec<f64> = (0..n).map(|k| lo[axis] + (k as f64 + 0.5) * w).collect();
    let interior = (0..n)
        .map(|k| {
            let a = k as f64 * w;
            a >= interior_margin - 1e-12 * ext && ext - (a + w) >= interior_margin - 1e-12 * ext
        })
        .collect();
    Laminae { axis, centres, density: vol.iter().map(|v| v / (w * cross)).collect(), interior }
}

/// Laminae of one axis of a periodic box `[0, l)` (docs/packing.md (G7)): eq. 48 with every
/// sphere's volume counted through its images, so the laminae at the faces see the spheres that
/// stick out of the opposite face; all laminae are interior.
pub fn laminae_periodic(pos: &[Vector3<f64>], rad: &[f64], l: &Vector3<f64>, axis: usize, width: f64) -> Laminae {
    let mut p = Vec::with_capacity(pos.len() + pos.len() / 4);
    let mut r = Vec::with_capacity(p.capacity());
    for (x, &ra) in pos.iter().zip(rad) {
        let mut c = *x;
        c[axis] = x[axis].rem_euclid(l[axis]);
        for k in [-1.0, 0.0, 1.0] {
            let mut ci = c;
            ci[axis] += k * l[axis];
            if ci[axis] + ra > 0.0 && ci[axis] - ra < l[axis] {
                p.push(ci);
                r.push(ra);
            }
        }
    }
    let mut lam = laminae(&p, &r, &Vector3::zeros(), l, axis, width, 0.0);
    lam.interior.iter_mut().for_each(|i| *i = true);
    lam
}

/// Solid fractions of the eight octants `[0, L/2) / [L/2, L)` per axis of a periodic box `[0, l)`
/// (docs/packing.md (G8)), in the order x fastest: the fraction of the points of a regular grid
/// (cell centres, about `r_min/8` apart, at most 256 per axis) that lie in a sphere, images included.
pub fn octant_solid_fractions(pos: &[Vector3<f64>], rad: &[f64], l: &Vector3<f64>) -> [f64; 8] {
    let r_min = rad.iter().copied().fold(f64::INFINITY, f64::min);
    // an even number of points per axis, so that each octant gets the same number
    let m: [usize; 3] = std::array::from_fn(|a| (2 * ((l[a] / (0.125 * r_min) / 2.0).ceil() as usize)).clamp(2, 256));
    let h: [f64; 3] = std::array::from_fn(|a| l[a] / m[a] as f64);
    let mut inside = vec![false; m[0] * m[1] * m[2]];
    for (x, &r) in pos.iter().zip(rad) {
        let c: [f64; 3] = std::array::from_fn(|a| x[a].rem_euclid(l[a]));
        // grid points k with |(k + 1/2) h − c| < r, indices taken modulo m (images)
        let lo: [i64; 3] = std::array::from_fn(|a| ((c[a] - r) / h[a] - 0.5).ceil() as i64);
        let hi: [i64; 3] = std::array::from_fn(|a| ((c[a] + r) / h[a] - 0.5).floor() as i64);
        for kz in lo[2]..=hi[2] {
            let dz = (kz as f64 + 0.5) * h[2] - c[2];
            for ky in lo[1]..=hi[1] {
                let dy = (ky as f64 + 0.5) * h[1] - c[1];
                let rest = r * r - dz * dz - dy * dy;
                if rest <= 0.0 {
                    continue;
                }
                let row = (kz.rem_euclid(m[2] as i64) as usize * m[1] + ky.rem_euclid(m[1] as i64) as usize) * m[0];
                for kx in lo[0]..=hi[0] {
                    let dx = (kx as f64 + 0.5) * h[0] - c[0];
                    if dx * dx < rest {
                        inside[row + kx.rem_euclid(m[0] as i64) as usize] = true;
                    }
                }
            }
        }
    }
    let mut count = [0usize; 8];
    for kz in 0..m[2] {
        for ky in 0..m[1] {
            for kx in 0..m[0] {
                if inside[(kz * m[1] + ky) * m[0] + kx] {
                    count[(kx >= m[0] / 2) as usize + 2 * (ky >= m[1] / 2) as usize + 4 * (kz >= m[2] / 2) as usize] += 1;
                }
            }
        }
    }
    let per = (m[0] * m[1] * m[2] / 8) as f64;
    count.map(|c| c as f64 / per)
}

/// Writes the spheres through the shared VTU writer ([`crate::io::vtu::write_snapshot`]) as
/// `stem.vtu` (points with `radius_m`, `coordination` and, if `temperature` is not empty,
/// `temperature_K`) and `stem_contacts.vtu` (the given contact pairs as lines with their `gap_m`;
/// in a `periodic` box [m] the gap by minimum image, and a pair across a face drawn across the box).
pub fn write_vtu(
    dir: &Path,
    stem: &str,
    pos: &[Vector3<f64>],
    rad: &[f64],
    temperature: &[f64],
    coordination: &[u32],
    contacts: &[[u32; 2]],
    periodic: Option<Vector3<f64>>,
) -> Result<(), Error> {
    // the writer derives `coordination` from the contacts; the caller's count must agree
    debug_assert!(crate::io::vtu::coordination(pos.len(), contacts).iter().zip(coordination).all(|(&a, &b)| a as u32 == b));
    let branch = |c: &[u32; 2]| {
        let d = pos[c[0] as usize] - pos[c[1] as usize];
        periodic.map_or(d, |l| crate::contacts::detect::minimum_image(d, &l))
    };
    let gap: Vec<f64> = contacts.iter().map(|c| branch(c).norm() - rad[c[0] as usize] - rad[c[1] as usize]).collect();
    let snap = crate::io::Snapshot { position: pos, radius: rad, temperature, contacts, contact_data: vec![("gap_m", &gap)], ..Default::default() };
    let (p, c) = crate::io::vtu::write_snapshot(dir, 0, &snap)?;
    for (from, to) in [(p, dir.join(format!("{stem}.vtu"))), (c, dir.join(format!("{stem}_contacts.vtu")))] {
        crate::io::manifest::record(&to)?;
        std::fs::rename(&from, &to).map_err(|e| IoError::new(&to, e))?;
    }
    Ok(())
}

/// The laminae plot (eq. 48) through the shared plot facility: relative density against the
/// normalised position s/L for the three axes, with `mean` ± `band` drawn as two lines.
pub fn write_laminae_plot(path: &Path, title: &str, series: &[(&str, Vec<(f64, f64)>)], mean: f64, band: f64) -> Result<(), Error> {
    let mut plot = crate::plot::Plot::new(title)
        .subtitle(format!("solid fraction of thin layers across the box along each axis; band: interior mean ± {band}"))
        .labels("position across the box / box length", "relative density (solid volume fraction)");
    for (name, pts) in series {
        plot.add(crate::plot::Series::new(format!("along {name}"), pts.clone()).with_markers());
    }
    for (name, y) in [(format!("interior mean ± {band}"), mean + band), (String::new(), mean - band)] {
        plot.add(crate::plot::Series::new(name, vec![(0.0, y), (1.0, y)]).reference());
    }
    plot.save_png(path).map_err(Error::from)
}

/// Writes text to a file, naming the path on failure.
pub fn write_text(path: &Path, text: &str) -> Result<(), Error> {
    Ok(crate::io::write_atomic(path, text)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn slab_volumes_add_up_to_the_sphere() {
        let r = 2.0;
        let full = crate::units::sphere_volume(r);
        assert!((slab_volume(0.3, r, -10.0, 10.0) - full).abs() < 1e-12 * full);
        let parts: f64 = (0..7).map(|k| slab_volume(0.3, r, -3.0 + k as f64, -2.0 + k as f64)).sum();
        assert!((parts - full).abs() < 1e-12 * full);
        // a hemisphere
        assert!((slab_volume(0.0, r, 0.0, 5.0) - 0.5 * full).abs() < 1e-12);
    }

    #[test]
    fn periodic_laminae_and_octants_count_the_images() {
        // one sphere of radius 1 centred on a corner of a 4 × 4 × 4 box: one eighth in each octant
        let l = Vector3::repeat(4.0);
        let (pos, rad) = (vec![Vector3::new(0.0, 4.0, 0.0)], vec![1.0]);
        let full = crate::units::sphere_volume(1.0);
        let oct = octant_solid_fractions(&pos, &rad, &l);
        for o in oct {
            assert!((o - full / 8.0 / 8.0).abs() < 0.03 * full / 64.0, "{oct:?}");
        }
        // laminae along x of width 1: the two at the faces hold half the sphere each
        let lam = laminae_periodic(&pos, &rad, &l, 0, 1.0);
        let slab = slab_volume(0.0, 1.0, 0.0, 1.0) / 16.0;
        assert!((lam.density[0] - slab).abs() < 1e-14 && (lam.density[3] - slab).abs() < 1e-14 && lam.density[1] == 0.0, "{:?}", lam.density);
        assert!(lam.interior.iter().all(|&i| i));
    }
}

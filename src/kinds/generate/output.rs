//! What a generate run reports and writes: coordination, the summary, and the output files.

use super::{GenerateCase, GenerateSummary, Packing, V3, requested_mean_diameter};
use crate::error::{Error, IoError};
use crate::packing::report;
use std::path::Path;

/// Coordination of every particle: neighbours with gap < `gap` [m].
pub fn coordination(pos: &[V3], rad: &[f64], gap: f64) -> (Vec<u32>, usize) {
    let pairs = crate::contacts::detect::touching_pairs(pos, rad, gap);
    let mut z = vec![0u32; pos.len()];
    let mut overl = 0;
    for &(i, j) in &pairs {
        z[i as usize] += 1;
        z[j as usize] += 1;
        if (pos[i as usize] - pos[j as usize]).norm() < rad[i as usize] + rad[j as usize] {
            overl += 1;
        }
    }
    (z, overl)
}

pub(super) fn summarise(
    case: &GenerateCase,
    pos: &[V3],
    rad: &[f64],
    box_si: [f64; 3],
    r_unit: f64,
    ke: f64,
    mu: f64,
    stage: [u64; 3],
    steps: u64,
    wall: f64,
    met: bool,
) -> GenerateSummary {
    let n = pos.len();
    let vp: f64 = rad.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    let vbox = box_si.iter().product::<f64>();
    let (z, overl) = coordination(pos, rad, case.protocol.contact_gap_rel * r_unit);
    let mut ov: f64 = 0.0;
    for &(i, j) in &crate::contacts::detect::touching_pairs(pos, rad, 0.0) {
        ov = ov.max(rad[i as usize] + rad[j as usize] - (pos[i as usize] - pos[j as usize]).norm());
    }
    for (x, &r) in pos.iter().zip(rad) {
        for a in 0..3 {
            ov = ov.max(r - x[a]).max(r - (box_si[a] - x[a]));
        }
    }
    let width = case.lamina_width.unwrap_or(r_unit);
    let lo = V3::zeros();
    let hi = V3::new(box_si[0], box_si[1], box_si[2]);
    let mut dev = [0.0; 3];
    let mut mean = [0.0; 3];
    for a in 0..3 {
        let l = report::laminae(pos, rad, &lo, &hi, a, width, 2.0 * r_unit);
        let inner: Vec<f64> = l.density.iter().zip(&l.interior).filter(|(_, i)| **i).map(|(d, _)| *d).collect();
        if !inner.is_empty() {
            mean[a] = inner.iter().sum::<f64>() / inner.len() as f64;
            dev[a] = inner.iter().map(|d| (d - mean[a]).abs()).fold(0.0, f64::max);
        }
    }
    let mut d: Vec<f64> = rad.iter().map(|r| 2.0 * r).collect();
    d.sort_by(f64::total_cmp);
    let ks = d.iter().enumerate().map(|(k, &x)| (case.size.cdf(x) - (k as f64 + 0.5) / n as f64).abs()).fold(0.0, f64::max);
    let mean_req = 0.5 * requested_mean_diameter(&case.size);
    GenerateSummary {
        particles: n,
        seed: case.seed,
        solid_fraction: vp / vbox,
        target_solid_fraction: case.target_solid_fraction,
        coordination_mean: z.iter().map(|&c| c as f64).sum::<f64>() / n as f64,
        coordination_overlapping: 2.0 * overl as f64 / n as f64,
        rattlers: z.iter().filter(|&&c| c == 0).count(),
        max_overlap_rel: ov.max(0.0) / r_unit,
        kinetic_energy_rel: ke,
        box_size: box_si,
        mean_radius: r_unit,
        mean_radius_requested: mean_req,
        size_ks_distance: ks,
        lamina_width: width,
        laminae_max_deviation: dev,
        laminae_mean: mean,
        final_friction: mu,
        steps,
        stage_steps: stage,
        dt_fraction: case.protocol.dt_fraction,
        wall_time: wall,
        thresholds_met: met,
    }
}

/// Writes `packing.csv`, `packing.vtu`, `laminae.csv`, `laminae.png`, `size_distribution.csv`
/// and `summary.json` into `out_dir`.
pub fn write_outputs(case: &GenerateCase, packing: &Packing, summary: &GenerateSummary, out_dir: &Path) -> Result<(), Error> {
    std::fs::create_dir_all(out_dir).map_err(|e| IoError::new(out_dir, e))?;
    let mut csv = String::from("x_m,y_m,z_m,radius_m\n");
    for (x, r) in packing.positions.iter().zip(&packing.radii) {
        csv.push_str(&format!("{:.10e},{:.10e},{:.10e},{:.10e}\n", x[0], x[1], x[2], r));
    }
    report::write_text(&out_dir.join("packing.csv"), &csv)?;
    let gap = case.protocol.contact_gap_rel * summary.mean_radius;
    let (z, _) = coordination(&packing.positions, &packing.radii, gap);
    let pairs: Vec<[u32; 2]> = crate::contacts::detect::touching_pairs(&packing.positions, &packing.radii, gap).into_iter().map(|(i, j)| [i, j]).collect();
    // the generator is athermal: the VTU carries no temperature
    report::write_vtu(out_dir, "packing", &packing.positions, &packing.radii, &[], &z, &pairs)?;
    // laminae (eq. 48)
    let hi = V3::new(packing.box_size[0], packing.box_size[1], packing.box_size[2]);
    // relative density of laminae (Ivannikov et al. 2022 eq. 48); position_m = lamina centre
    let mut lam = String::from("axis,position_m,relative_density,interior\n");
    let mut series = Vec::new();
    for a in 0..3 {
        let l = report::laminae(&packing.positions, &packing.radii, &V3::zeros(), &hi, a, summary.lamina_width, 2.0 * summary.mean_radius);
        for k in 0..l.centres.len() {
            lam.push_str(&format!("{},{:.6e},{:.6},{}\n", ["x", "y", "z"][a], l.centres[k], l.density[k], l.interior[k]));
        }
        // normalised position s/L so the three axes share the plot
        series.push((["x", "y", "z"][a], l.centres.iter().zip(&l.density).map(|(c, d)| (c / packing.box_size[a], *d)).collect::<Vec<_>>()));
    }
    report::write_text(&out_dir.join("laminae.csv"), &lam)?;
    let title = format!("Laminae (eq. 48), {} particles", packing.radii.len());
    // the band: ± 0.05 around the mean of the interior laminae (the acceptance criterion)
    let interior_mean = summary.laminae_mean.iter().sum::<f64>() / 3.0;
    report::write_laminae_plot(&out_dir.join("laminae.png"), &title, &series, interior_mean, 0.05)?;
    // size distribution achieved vs asked
    let mut d: Vec<f64> = packing.radii.iter().map(|r| 2.0 * r).collect();
    d.sort_by(f64::total_cmp);
    // number-weighted cumulative distribution of diameters: achieved (sample) vs requested
    let mut sd = String::from("diameter_m,cdf_achieved,cdf_requested\n");
    let (lo, hi) = case.size.support();
    for k in 0..=50 {
        let x = lo + (hi - lo) * k as f64 / 50.0;
        let ach = d.partition_point(|&v| v <= x) as f64 / d.len() as f64;
        sd.push_str(&format!("{x:.6e},{ach:.6},{:.6}\n", case.size.cdf(x)));
    }
    report::write_text(&out_dir.join("size_distribution.csv"), &sd)?;
    let json = serde_json::to_string_pretty(summary).map_err(|e| IoError::new(out_dir.join("summary.json"), e))?;
    report::write_text(&out_dir.join("summary.json"), &(json + "\n"))?;
    Ok(())
}

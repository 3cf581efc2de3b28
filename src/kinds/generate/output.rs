//! What a generate run reports and writes: coordination, the summary, and the output files.

use super::{GenerateCase, GenerateSummary, Packing, PeriodicReport, V3, requested_mean_diameter};
use crate::contacts::detect::{PeriodicPair, minimum_image, touching_pairs, touching_pairs_periodic};
use crate::error::{Error, IoError};
use crate::packing::report;
use std::path::Path;

/// Coordination of every particle: neighbours with gap < `gap` [m].
pub fn coordination(pos: &[V3], rad: &[f64], gap: f64) -> (Vec<u32>, usize) {
    coordination_in(pos, rad, gap, None)
}

/// The pairs with gap < `gap` [m]: in open space (`periodic` None, every shift 0) or by minimum
/// image in the periodic box `[0, L)` [m] (docs/packing.md (G1)).
pub fn contact_pairs(pos: &[V3], rad: &[f64], gap: f64, periodic: Option<V3>) -> Vec<PeriodicPair> {
    match periodic {
        None => touching_pairs(pos, rad, gap).into_iter().map(|(i, j)| PeriodicPair { i, j, shift: [0; 3] }).collect(),
        Some(l) => touching_pairs_periodic(pos, rad, l, gap),
    }
}

/// The branch x_i − x_j [m] of a pair (minimum image in a periodic box).
fn branch(pos: &[V3], q: &PeriodicPair, periodic: Option<V3>) -> V3 {
    let d = pos[q.i as usize] - pos[q.j as usize];
    periodic.map_or(d, |l| minimum_image(d, &l))
}

/// Coordination of every particle (neighbours with gap < `gap` [m], minimum image in a `periodic`
/// box) and the number of strictly overlapping pairs.
pub fn coordination_in(pos: &[V3], rad: &[f64], gap: f64, periodic: Option<V3>) -> (Vec<u32>, usize) {
    let mut z = vec![0u32; pos.len()];
    let mut overl = 0;
    for q in &contact_pairs(pos, rad, gap, periodic) {
        let (i, j) = (q.i as usize, q.j as usize);
        z[i] += 1;
        z[j] += 1;
        if branch(pos, q, periodic).norm() < rad[i] + rad[j] {
            overl += 1;
        }
    }
    (z, overl)
}

/// The report of a periodic packing in the box `l` [m] (docs/packing.md (G6)–(G8)): octants,
/// contacts across each pair of faces, the laminae at the faces; `extra` carries the compaction's
/// figures, filled in here.
pub(super) fn periodic_report(pos: &[V3], rad: &[f64], l: V3, gap: f64, width: f64, mut extra: PeriodicReport) -> PeriodicReport {
    extra.octant_solid_fraction = report::octant_solid_fractions(pos, rad, &l);
    extra.contacts_across_faces = [0; 3];
    for q in contact_pairs(pos, rad, gap, Some(l)) {
        for a in 0..3 {
            // wrapped positions more than half a box apart along a: the contact crosses face a
            let d = pos[q.i as usize][a].rem_euclid(l[a]) - pos[q.j as usize][a].rem_euclid(l[a]);
            if d.abs() > 0.5 * l[a] {
                extra.contacts_across_faces[a] += 1;
            }
        }
    }
    let d_mean = 2.0 * rad.iter().sum::<f64>() / rad.len() as f64;
    for a in 0..3 {
        let lam = report::laminae_periodic(pos, rad, &l, a, width);
        let (mut face, mut nf, mut inner, mut ni) = (0.0, 0usize, 0.0, 0usize);
        for (c, d) in lam.centres.iter().zip(&lam.density) {
            if c.min(l[a] - c) < d_mean {
                face += d;
                nf += 1;
            } else {
                inner += d;
                ni += 1;
            }
        }
        extra.face_laminae_mean[a] = face / nf.max(1) as f64;
        extra.interior_laminae_mean[a] = if ni > 0 { inner / ni as f64 } else { extra.face_laminae_mean[a] };
    }
    extra
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
    periodic: Option<V3>,
) -> GenerateSummary {
    let n = pos.len();
    let vp: f64 = rad.iter().map(|&r| crate::units::sphere_volume(r)).sum();
    let vbox = box_si.iter().product::<f64>();
    let (z, overl) = coordination_in(pos, rad, case.protocol.contact_gap_rel * r_unit, periodic);
    let mut ov: f64 = 0.0;
    for q in &contact_pairs(pos, rad, 0.0, periodic) {
        ov = ov.max(rad[q.i as usize] + rad[q.j as usize] - branch(pos, q, periodic).norm());
    }
    if periodic.is_none() {
        for (x, &r) in pos.iter().zip(rad) {
            for a in 0..3 {
                ov = ov.max(r - x[a]).max(r - (box_si[a] - x[a]));
            }
        }
    }
    let width = case.lamina_width.unwrap_or(r_unit);
    let lo = V3::zeros();
    let hi = V3::new(box_si[0], box_si[1], box_si[2]);
    let mut dev = [0.0; 3];
    let mut mean = [0.0; 3];
    for a in 0..3 {
        let l = match periodic {
            None => report::laminae(pos, rad, &lo, &hi, a, width, 2.0 * r_unit),
            Some(b) => report::laminae_periodic(pos, rad, &b, a, width),
        };
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
        boundary: periodic.map(|_| "periodic".to_string()),
        box_size_m: periodic.map(|_| box_si),
        periodic: None,
        completed: None,
        stop_reason: None,
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
    let pbox = case.periodic.then(|| V3::from(packing.box_size));
    let (z, _) = coordination_in(&packing.positions, &packing.radii, gap, pbox);
    let pairs: Vec<[u32; 2]> = contact_pairs(&packing.positions, &packing.radii, gap, pbox).into_iter().map(|q| [q.i, q.j]).collect();
    // the generator is athermal: the VTU carries no temperature
    report::write_vtu(out_dir, "packing", &packing.positions, &packing.radii, &[], &z, &pairs, pbox)?;
    // laminae (eq. 48)
    let hi = V3::new(packing.box_size[0], packing.box_size[1], packing.box_size[2]);
    // relative density of laminae (Ivannikov et al. 2022 eq. 48); position_m = lamina centre
    let mut lam = String::from("axis,position_m,relative_density,interior\n");
    let mut series = Vec::new();
    for a in 0..3 {
        let l = match pbox {
            None => report::laminae(&packing.positions, &packing.radii, &V3::zeros(), &hi, a, summary.lamina_width, 2.0 * summary.mean_radius),
            Some(b) => report::laminae_periodic(&packing.positions, &packing.radii, &b, a, summary.lamina_width),
        };
        for k in 0..l.centres.len() {
            lam.push_str(&format!("{},{:.6e},{:.6},{}\n", ["x", "y", "z"][a], l.centres[k], l.density[k], l.interior[k]));
        }
        // normalised position s/L so the three axes share the plot
        series.push((["x", "y", "z"][a], l.centres.iter().zip(&l.density).map(|(c, d)| (c / packing.box_size[a], *d)).collect::<Vec<_>>()));
    }
    report::write_text(&out_dir.join("laminae.csv"), &lam)?;
    let title = format!("Layer densities across the box, {} particles", packing.radii.len());
    // the band: ± 0.05 around the mean of the interior laminae (the acceptance criterion)
    let interior_mean = summary.laminae_mean.iter().sum::<f64>() / 3.0;
    if let Err(e) = report::write_laminae_plot(&out_dir.join("laminae.png"), &title, &series, interior_mean, 0.05) {
        crate::plot::warn_not_written(&e);
    }
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

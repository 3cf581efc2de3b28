//! Outputs and analyses of a compact run: snapshots, effective conductivity at chosen times,
//! correction histograms and plots.

use crate::coupled::*;
use crate::error::{Error, IoError};
use crate::io::{Snapshot, SnapshotWriter};
use serde_json::json;
use std::path::Path;

/// Output analyses due at given times, and where each list stands (a checkpoint carries it).
pub(crate) struct Due {
    pub(crate) snap_times: Vec<f64>,
    pub(crate) next_snap: usize,
    pub(crate) next_cond: usize,
    pub(crate) cond_results: Vec<serde_json::Value>,
    pub(crate) next_hist: usize,
    pub(crate) hist_results: Vec<serde_json::Value>,
}

impl Due {
    /// The earliest requested output time after `t` [s] (∞ when none is left): the next step is
    /// shortened to land on it.
    pub(crate) fn next_time(&self, sim: &Simulation) -> f64 {
        let after = |list: &[f64], from: usize| list[from.min(list.len())..].iter().copied().find(|&v| v > sim.t * (1.0 + 1e-12)).unwrap_or(f64::INFINITY);
        after(&self.snap_times, self.next_snap).min(after(&sim.settings.conductivity_at, self.next_cond)).min(after(&sim.settings.histogram_at, self.next_hist))
    }

    /// Writes the snapshots, conductivity analyses and correction histograms due at the current time.
    pub(crate) fn write(&mut self, sim: &Simulation, out: &Path, snaps: &mut SnapshotWriter, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let now = sim.t * (1.0 + 1e-12);
        while self.next_snap < self.snap_times.len() && self.snap_times[self.next_snap] <= now + 1e-300 {
            write_snapshot(sim, snaps)?;
            self.next_snap += 1;
        }
        let at = &sim.settings.conductivity_at;
        while self.next_cond < at.len() && at[self.next_cond] <= now {
            if let Some(k) = periodic_conductivity(sim)? {
                let rows: Vec<[f64; 3]> = (0..3).map(|r| [k[(r, 0)], k[(r, 1)], k[(r, 2)]]).collect();
                log(&format!(
                    "t = {:.6e} s: effective conductivity tensor (periodic) diag = [{:.4e}, {:.4e}, {:.4e}] W/(m K)",
                    sim.t,
                    k[(0, 0)],
                    k[(1, 1)],
                    k[(2, 2)]
                ));
                self.cond_results.push(json!({"time_s": sim.t, "method": "periodic", "kappa_eff_W_per_mK": rows}));
            } else {
                let k = compact_conductivity(sim)?;
                log(&format!("t = {}: effective conductivity diag = [{:.4e}, {:.4e}, {:.4e}] W/(m K)", crate::units::fmt_seconds(sim.t), k[0], k[1], k[2]));
                self.cond_results.push(json!({"time_s": sim.t, "kappa_eff_W_per_mK": k}));
            }
            self.next_cond += 1;
        }
        let at = &sim.settings.histogram_at;
        while self.next_hist < at.len() && at[self.next_hist] <= now {
            // the corrections of the step that ended at (or first after) the asked time
            if sim.step > 0 {
                let tag = format!("t{:.0}s", at[self.next_hist]);
                let h = write_correction_histogram(out, sim, &tag)?;
                log(&format!("t = {:.6e} s: correction histogram {tag}: mean ΔL̄/L0 = {:.3e}, std {:.3e} ({} contacts)", sim.t, h.0, h.1, sim.contacts.len()));
                self.hist_results.push(json!({"asked_time_s": at[self.next_hist], "time_s": sim.t, "dl_bar_rel_mean": h.0, "dl_bar_rel_std": h.1, "files": [format!("dl_bar_{tag}.csv"), format!("dl_bar_histogram_{tag}.png")]}));
            }
            self.next_hist += 1;
        }
        Ok(())
    }
}

pub(crate) fn write_snapshot(sim: &Simulation, snaps: &mut SnapshotWriter) -> Result<(), IoError> {
    let p = &sim.prep.scene.particles;
    let neck: Vec<f64> = sim.contacts.state.iter().map(|c| c.y[0]).collect();
    let shrink: Vec<f64> = sim.contacts.state.iter().map(|c| c.shrinkage()).collect();
    let normal: Vec<f64> = sim.contacts.state.iter().map(|c| c.normal_force).collect();
    let disp: Vec<nalgebra::Vector3<f64>> = p.position.iter().zip(&sim.x0).map(|(x, x0)| x - x0).collect();
    let materials_json = serde_json::to_string_pretty(&sim.d7_materials).unwrap_or_default();
    // with thermal expansion: the expanded radii and each particle's thermal strain (X1)
    let eps = sim.thermal_strains();
    let radius: Vec<f64> = match &eps {
        Some(e) => p.radius.iter().zip(e).map(|(r, e)| r * (1.0 + e)).collect(),
        None => p.radius.clone(),
    };
    // particles without a conductive path keep their initial temperature (their true model
    // state): a 0/1 field marks them, so that ParaView's Threshold (isolated = 0) keeps them from
    // pinning the temperature colour map; written only when there are some (docs/outputs.md)
    let isolated_ids = sim.isolated_particles();
    let mut isolated = vec![];
    if !isolated_ids.is_empty() {
        isolated = vec![0.0; p.len()];
        for &i in &isolated_ids {
            isolated[i as usize] = 1.0;
        }
    }
    let mut particle_data = vec![];
    if let Some(e) = &eps {
        particle_data.push(("thermal_strain", e.as_slice()));
    }
    if !isolated.is_empty() {
        particle_data.push(("isolated", isolated.as_slice()));
    }
    snaps.write(&Snapshot {
        time: sim.t,
        step: sim.step,
        position: &p.position,
        radius: &radius,
        temperature: &p.temperature,
        contacts: &sim.contacts.pairs,
        contact_data: vec![("neck_radius_m", &neck), ("contact_shrinkage", &shrink), ("dl_bar_m", &sim.contacts.dl_bar), ("normal_force_N", &normal)],
        particle_data,
        particle_vectors: vec![("displacement_m", &disp), ("velocity_m_per_s", &sim.velocity)],
        parameters: Some(crate::io::Parameters { case_toml: sim.source.0.clone(), materials_json }),
    })
}

/// Effective conductivity (faces method, diagonal) of the compact in its current state [W/(m·K)].
pub fn compact_conductivity(sim: &Simulation) -> Result<[f64; 3], Error> {
    let p = &sim.prep.scene.particles;
    let k = sim.conductances()?;
    let pipes = crate::heat::Pipes { pairs: sim.contacts.pairs.clone(), conductance: k, ..Default::default() };
    let mut out = [0.0; 3];
    for (a, o) in out.iter_mut().enumerate() {
        *o = crate::heat::conductivity::faces(p, &pipes, a, 0.5 * p.mean_radius(), 1.0)?.kappa;
    }
    Ok(out)
}

/// The full effective conductivity tensor of a periodic compact in its current state by periodic
/// homogenisation of its pipe network (`heat::conductivity::periodic`, the branch vectors the
/// minimum images of the cell) [W/(m·K)]; None for a walled compact.
pub fn periodic_conductivity(sim: &Simulation) -> Result<Option<nalgebra::Matrix3<f64>>, Error> {
    let Some(cell) = &sim.cell else { return Ok(None) };
    let p = &sim.prep.scene.particles;
    let k = sim.conductances()?;
    let branch: Vec<nalgebra::Vector3<f64>> = sim.contacts.pairs.iter().map(|&[i, j]| sim.branch(i, j)).collect();
    let pipes = crate::heat::Pipes { pairs: sim.contacts.pairs.clone(), conductance: k, ..Default::default() };
    // the method takes the cell through its volume only: edges whose product is det(L)
    let l = cell.lengths();
    let edges = nalgebra::Vector3::new(l.x, l.y, cell.volume() / (l.x * l.y));
    Ok(Some(crate::heat::conductivity::periodic(p, &pipes, &branch, edges)?))
}

/// The y4/y7 corrections of the last step as data: `dl_bar_TAG.csv` (pair, L0, ΔL̄, ΔL̄/L0),
/// written atomically; returns ΔL̄/L0 per contact. A data file: its failure is the run's error
/// (issue 26, class 10), unlike a plot's.
pub fn write_correction_csv(out: &Path, sim: &Simulation, tag: &str) -> Result<Vec<f64>, IoError> {
    let dl: Vec<f64> = sim.contacts.dl_bar.iter().zip(&sim.contacts.state).map(|(d, c)| d / c.l0).collect();
    let csv_path = out.join(format!("dl_bar_{tag}.csv"));
    let mut text = String::from("particle_a,particle_b,l0_m,dl_bar_m,dl_bar_rel\n");
    for (k, (&[a, b], c)) in sim.contacts.pairs.iter().zip(&sim.contacts.state).enumerate() {
        text.push_str(&format!("{a},{b},{:e},{:e},{:e}\n", c.l0, sim.contacts.dl_bar[k], dl[k]));
    }
    crate::io::write_atomic(&csv_path, &text)?;
    Ok(dl)
}

/// The y4/y7 corrections of the last step, ΔL̄/L0 per contact (Ivannikov et al. 2022 eq. 44,
/// Fig. 20): `dl_bar_TAG.csv` ([`write_correction_csv`]) and `dl_bar_histogram_TAG.png` (30 bins);
/// returns the mean and standard deviation of ΔL̄/L0.
pub fn write_correction_histogram(out: &Path, sim: &Simulation, tag: &str) -> Result<(f64, f64), IoError> {
    let dl = write_correction_csv(out, sim, tag)?;
    plot_correction_histogram(out, sim, tag, &dl)
}

/// The histogram PNG of [`write_correction_histogram`] from ΔL̄/L0 per contact `dl`; returns their
/// mean and standard deviation.
fn plot_correction_histogram(out: &Path, sim: &Simulation, tag: &str, dl: &[f64]) -> Result<(f64, f64), IoError> {
    use crate::plot::{Plot, Series as Line};
    let n = dl.len().max(1) as f64;
    let mean = dl.iter().sum::<f64>() / n;
    let std = (dl.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt();
    if !dl.is_empty() {
        let (lo, hi) = dl.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let bins = 30usize;
        let w = ((hi - lo) / bins as f64).max(f64::MIN_POSITIVE);
        let mut count = vec![0usize; bins];
        for v in dl {
            count[(((v - lo) / w) as usize).min(bins - 1)] += 1;
        }
        let mut pts = Vec::new();
        for (k, &c) in count.iter().enumerate() {
            let (a, b) = (lo + k as f64 * w, lo + (k + 1) as f64 * w);
            pts.push((a, 0.0));
            pts.push((a, c as f64));
            pts.push((b, c as f64));
            pts.push((b, 0.0));
        }
        let mut p = Plot::new(format!("y4/y7 corrections at t = {:.0} s (paper Fig. 20)", sim.t)).labels("dL_bar / L0 [1]", "contacts");
        p.add(Line::new("histogram", pts));
        let name = if tag == "end" { "dl_bar_histogram.png".to_string() } else { format!("dl_bar_histogram_{tag}.png") };
        p.save_png(&out.join(name))?;
    }
    Ok((mean, std))
}

/// PNG plots of a compact run from its series.csv (axis labels from the series columns,
/// [`super::columns`]), the ΔL̄ histogram (Ivannikov et al. 2022 Fig. 20) and the layer profile
/// along z.
pub fn write_plots(out: &Path, sim: &Simulation) -> Result<(), IoError> {
    use super::columns::label;
    use crate::plot::{Plot, Series as Line};
    let path = out.join("series.csv");
    let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect()).collect();
    let col = |name: &str| -> Vec<(f64, f64)> {
        let k = header.iter().position(|h| *h == name).unwrap_or(0);
        rows.iter().filter(|r| r[0] > 0.0).map(|r| (r[0], r[k])).collect()
    };
    let time = label("time_s");
    let mut p = Plot::new("shrinkage along each axis (1 - L/L0)").labels(&time, "shrinkage [1]");
    for (name, key) in [("x", "shrinkage_x"), ("y", "shrinkage_y"), ("z", "shrinkage_z")] {
        p.add(Line::new(name, col(key)));
    }
    if sim.expansion.is_some() {
        // (X11): net of the thermal strain
        for (name, key) in [("x, sintering", "sintering_shrinkage_x"), ("y, sintering", "sintering_shrinkage_y"), ("z, sintering", "sintering_shrinkage_z")] {
            p.add(Line::new(name, col(key)));
        }
    }
    p.save_png(&out.join("shrinkage.png"))?;
    let mut p = Plot::new("relative density (eq. 49)").labels(&time, label("relative_density"));
    p.add(Line::new("relative density", col("relative_density")));
    p.save_png(&out.join("relative_density.png"))?;
    let mut p = Plot::new("mean coordination number").labels(&time, label("coordination_mean"));
    p.add(Line::new("2 contacts / particles", col("coordination_mean")));
    p.save_png(&out.join("coordination.png"))?;
    let mut p = Plot::new("mean neck ratio y1/R_min").labels(&time, label("neck_ratio_mean")).log_x(true);
    p.add(Line::new("neck ratio", col("neck_ratio_mean")));
    p.save_png(&out.join("neck_ratio.png"))?;
    let mut p = Plot::new("particle temperatures").labels(&time, label("mean_temperature_K"));
    for (name, key) in [("mean", "mean_temperature_K"), ("min", "min_temperature_K"), ("max", "max_temperature_K")] {
        p.add(Line::new(name, col(key)));
    }
    p.save_png(&out.join("temperature.png"))?;
    // dl_bar_end.csv itself is data, written before summary.json (driver::finish)
    let dl: Vec<f64> = sim.contacts.dl_bar.iter().zip(&sim.contacts.state).map(|(d, c)| d / c.l0).collect();
    plot_correction_histogram(out, sim, "end", &dl)?;
    let prof = sim.layer_profile(5);
    let mut p = Plot::new("densification through the height").labels("height z [m]", "mean contact shrinkage dL/L0 [1]");
    p.add(Line::new("contacts by layer", prof.iter().map(|l| (l.0, l.1)).collect()).with_markers());
    p.save_png(&out.join("layer_profile.png"))?;
    Ok(())
}

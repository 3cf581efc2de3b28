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
                let hr = mean_overlap_ratio(sim);
                let extrapolated = crate::heat::conductance::beyond_validated(hr);
                self.cond_results.push(
                    json!({"time_s": sim.t, "method": "periodic", "kappa_eff_W_per_mK": rows, "mean_overlap_over_radius": hr, "extrapolated": extrapolated}),
                );
            } else {
                let (k, cut) = compact_conductivity(sim)?;
                let hr = mean_overlap_ratio(sim);
                let extrapolated = crate::heat::conductance::beyond_validated(hr);
                log(&format!("t = {}: effective conductivity diag = [{:.4e}, {:.4e}, {:.4e}] W/(m K)", crate::units::fmt_seconds(sim.t), k[0], k[1], k[2]));
                match cut {
                    Some(w) => {
                        // on the console once per run (also across a resume: the results are
                        // checkpointed); with every result it concerns in summary.json
                        if !self.cond_results.iter().any(|c| c.get("warning").is_some()) {
                            log(&format!("warning: {w}"));
                        }
                        self.cond_results.push(
                            json!({"time_s": sim.t, "kappa_eff_W_per_mK": k, "mean_overlap_over_radius": hr, "extrapolated": extrapolated, "warning": w}),
                        );
                    }
                    None => {
                        self.cond_results.push(json!({"time_s": sim.t, "kappa_eff_W_per_mK": k, "mean_overlap_over_radius": hr, "extrapolated": extrapolated}))
                    }
                }
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

/// Mean over the contacts of the compact of h/min(r_i, r_j), h = r_i + r_j − |b_ij| the overlap of
/// the current centre distance (minimum image in a periodic cell) [1]: the measure of the law's
/// validated range (`heat::conductance::VALIDATED_MEAN_OVERLAP_RATIO`); 0 without contacts.
pub fn mean_overlap_ratio(sim: &Simulation) -> f64 {
    let r = &sim.prep.scene.particles.radius;
    let n = sim.contacts.pairs.len();
    if n == 0 {
        return 0.0;
    }
    sim.contacts
        .pairs
        .iter()
        .map(|&[i, j]| {
            let (ri, rj) = (r[i as usize], r[j as usize]);
            (ri + rj - sim.branch(i, j).norm()) / ri.min(rj)
        })
        .sum::<f64>()
        / n as f64
}

/// Effective conductivity (faces method, diagonal) of the compact in its current state [W/(m·K)],
/// and the cut-face warning (H17b) when a face layer looks cut rather than wall-compacted.
pub fn compact_conductivity(sim: &Simulation) -> Result<([f64; 3], Option<String>), Error> {
    let p = &sim.prep.scene.particles;
    let k = sim.conductances()?;
    let pipes = crate::heat::Pipes { pairs: sim.contacts.pairs.clone(), conductance: k, ..Default::default() };
    let axes = (0..3).map(|a| crate::heat::conductivity::faces(p, &pipes, a, 0.5 * p.mean_radius(), 1.0)).collect::<Result<Vec<_>, _>>()?;
    Ok(([axes[0].kappa, axes[1].kappa, axes[2].kappa], crate::heat::conductivity::cut_face_warning(&axes)))
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
    let n = dl.len().max(1) as f64;
    let mean = dl.iter().sum::<f64>() / n;
    let std = (dl.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt();
    if !dl.is_empty() {
        let name = if tag == "end" { "dl_bar_histogram.png".to_string() } else { format!("dl_bar_histogram_{tag}.png") };
        histogram_plot(&plot_header(sim), sim.t, dl).save_png(&out.join(name))?;
    }
    Ok((mean, std))
}

/// The case title (its `title` key; the case file's stem when run from a file without one,
/// [`crate::kinds::title_from_file`]; else "compact") and the key settings of a compact run, for
/// the title and subtitle of its plots: particles, material, mean radius, temperature span of the
/// particles and the simulated time.
pub(crate) fn plot_header(sim: &Simulation) -> (String, String) {
    let title =
        sim.source.0.parse::<toml::Table>().ok().and_then(|t| t.get("title").and_then(|v| v.as_str()).map(str::to_string)).unwrap_or_else(|| "compact".into());
    let p = &sim.prep.scene.particles;
    let mut names: Vec<&str> = sim.d7_materials.iter().map(|m| m.name.as_str()).collect();
    names.dedup();
    let material = if names.is_empty() { String::new() } else { format!(" of {}", names.join(", ")) };
    let mut sub = format!("{} particles{material}, mean radius {}", p.radius.len(), crate::plot::fmt_length(p.mean_radius()));
    if sim.settings.detect_new {
        sub.push_str(", new contacts detected");
    }
    sub.push_str(&format!(", to t = {}", crate::plot::fmt_time(sim.t)));
    if sim.load.is_some() {
        sub.push_str(", under load");
    }
    (title, sub)
}

/// The histogram plot of the contact length corrections ΔL̄/L0 (Ivannikov et al. 2022 eq. 44,
/// Fig. 20; 30 bins) at time `t` [s]: counts from zero.
pub(crate) fn histogram_plot(header: &(String, String), t: f64, dl: &[f64]) -> crate::plot::Plot {
    use crate::plot::{Plot, Series as Line};
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
    let mut p = Plot::new(format!("{}: contact length corrections at t = {}", header.0, crate::plot::fmt_time(t)))
        .subtitle(header.1.clone())
        .labels("length correction / initial contact length", "number of contacts")
        .y_zero(true);
    p.add(Line::new("contacts", pts).plain());
    p
}

/// The plots of a compact run from its series.csv (`header`, `rows`), with the layer profile
/// `prof` (height [m], mean contact shrinkage): (file name, plot). Plain-language labels, time in
/// the unit its span reads best in ([`crate::plot::time_unit`]), heights in µm; shrinkage and
/// the layer profile from zero, relative density and coordination over their data.
pub(crate) fn series_plots(
    header: &(String, String),
    columns: &[&str],
    rows: &[Vec<f64>],
    expansion: bool,
    prof: &[(f64, f64)],
) -> Vec<(&'static str, crate::plot::Plot)> {
    use crate::plot::{Plot, Series as Line, time_unit};
    let col = |name: &str| -> Option<Vec<(f64, f64)>> {
        let k = columns.iter().position(|h| *h == name)?;
        Some(rows.iter().filter(|r| r[0] > 0.0).map(|r| (r[0], r.get(k).copied().unwrap_or(f64::NAN))).collect())
    };
    let t_end = rows.iter().map(|r| r[0]).fold(0.0, f64::max);
    let tu = time_unit(t_end, false);
    let time = format!("time [{}]", tu.name);
    let (title, sub) = header;
    // a linear time axis starts at the start of the run
    let new = |what: &str, y: &str| Plot::new(format!("{title}: {what}")).subtitle(sub.clone()).labels(&time, y).x_zero(true);
    let mut out = Vec::new();
    let mut p = new("shrinkage along each axis", "shrinkage 1 − L/L0").y_zero(true);
    let mut keys = vec![("x", "shrinkage_x"), ("y", "shrinkage_y"), ("z", "shrinkage_z")];
    if expansion {
        // (X11): net of the thermal strain
        keys.extend([
            ("x, sintering only", "sintering_shrinkage_x"),
            ("y, sintering only", "sintering_shrinkage_y"),
            ("z, sintering only", "sintering_shrinkage_z"),
        ]);
    }
    for (name, key) in keys {
        if let Some(pts) = col(key) {
            p.add(Line::new(name, tu.x(pts)));
        }
    }
    out.push(("shrinkage.png", p));
    let mut p = new("relative density", "relative density (solid volume fraction)");
    if let Some(pts) = col("relative_density") {
        p.add(Line::new("relative density", tu.x(pts)));
    }
    out.push(("relative_density.png", p));
    let mut p = new("contacts per particle", "mean contacts per particle");
    if let Some(pts) = col("coordination_mean") {
        p.add(Line::new("contacts per particle", tu.x(pts)));
    }
    out.push(("coordination.png", p));
    let tl = time_unit(t_end, true);
    let mut p = Plot::new(format!("{title}: neck growth"))
        .subtitle(sub.clone())
        .labels(format!("time [{}] (log scale)", tl.name), "mean neck radius / smaller particle radius")
        .log_x(true);
    if let Some(pts) = col("neck_ratio_mean") {
        p.add(Line::new("neck size", tl.x(pts)));
    }
    out.push(("neck_ratio.png", p));
    let mut p = new("particle temperatures", "temperature [K]");
    for (name, key) in [("hottest particle", "max_temperature_K"), ("mean", "mean_temperature_K"), ("coldest particle", "min_temperature_K")] {
        if let Some(pts) = col(key) {
            p.add(Line::new(name, tu.x(pts)));
        }
    }
    out.push(("temperature.png", p));
    let lu = crate::plot::length_unit(prof.iter().map(|l| l.0.abs()).fold(0.0, f64::max));
    let mut p = Plot::new(format!("{title}: shrinkage through the height"))
        .subtitle(sub.clone())
        .labels(format!("height above the bottom of the compact [{}]", lu.name), "mean contact shrinkage (approach / initial length)")
        .y_zero(true);
    p.add(Line::new("contacts by layer", lu.x(prof.to_vec())).with_markers());
    out.push(("layer_profile.png", p));
    out
}

/// PNG and SVG plots of a compact run from its series.csv ([`series_plots`]), the ΔL̄ histogram
/// (Ivannikov et al. 2022 Fig. 20) and the layer profile along z.
pub fn write_plots(out: &Path, sim: &Simulation) -> Result<(), IoError> {
    let path = out.join("series.csv");
    let text = std::fs::read_to_string(&path).map_err(|e| IoError::new(&path, e))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap_or(f64::NAN)).collect()).collect();
    let head = plot_header(sim);
    let prof: Vec<(f64, f64)> = sim.layer_profile(5).iter().map(|l| (l.0 - sim.planes.z, l.1)).collect();
    for (name, p) in series_plots(&head, &header, &rows, sim.expansion.is_some(), &prof) {
        p.save_png(&out.join(name))?;
    }
    // dl_bar_end.csv itself is data, written before summary.json (driver::finish)
    let dl: Vec<f64> = sim.contacts.dl_bar.iter().zip(&sim.contacts.state).map(|(d, c)| d / c.l0).collect();
    plot_correction_histogram(out, sim, "end", &dl)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows() -> (Vec<&'static str>, Vec<Vec<f64>>) {
        let cols = vec![
            "time_s",
            "shrinkage_x",
            "shrinkage_y",
            "shrinkage_z",
            "relative_density",
            "coordination_mean",
            "neck_ratio_mean",
            "mean_temperature_K",
            "min_temperature_K",
            "max_temperature_K",
        ];
        let rows = (0..=50)
            .map(|k| {
                let t = 100.0 * k as f64;
                let s = 0.01 * (t / 5000.0).sqrt();
                vec![t, s, s, 0.9 * s, 0.6 + s, 6.0 + s, 0.1 + s, 1200.0, 1190.0, 1210.0]
            })
            .collect();
        (cols, rows)
    }

    /// Issue 25 on the compact plots: the case title and settings on each, time in min for a
    /// 5000 s run, no equation numbers or symbols in titles and labels, heights in µm, the layer
    /// profile and shrinkage from zero, x shrinkage and y shrinkage in different styles.
    #[test]
    fn compact_plots_are_titled_plain_and_honest() {
        let (cols, rows) = rows();
        let head = ("copper compact, 1293 K, 5000 s".to_string(), "805 particles of copper, mean radius 25 µm".to_string());
        let prof = vec![(15e-6, 0.0191), (45e-6, 0.0198), (75e-6, 0.0195), (105e-6, 0.0193), (135e-6, 0.0192)];
        let plots = series_plots(&head, &cols, &rows, false, &prof);
        let names: Vec<&str> = plots.iter().map(|p| p.0).collect();
        assert_eq!(names, ["shrinkage.png", "relative_density.png", "coordination.png", "neck_ratio.png", "temperature.png", "layer_profile.png"]);
        for (name, p) in &plots {
            let s = p.spec();
            assert!(s.title.starts_with("copper compact, 1293 K, 5000 s: "), "{name}: {}", s.title);
            assert_eq!(s.subtitle, head.1, "{name}");
            for text in [&s.title, &s.x.label, &s.y.label] {
                for jargon in ["eq.", "y1/R", "R_min", "dL", "Fig.", "_"] {
                    assert!(!text.contains(jargon), "{name}: {text:?} has {jargon:?}");
                }
            }
            if *name != "layer_profile.png" && *name != "neck_ratio.png" {
                assert_eq!(s.x.label, "time [min]", "{name}");
                assert!(s.x.range.0 == 0.0 && (s.x.range.1 - 5000.0 / 60.0).abs() < 1e-9, "{name}: {:?}", s.x.range);
            }
        }
        let spec = |n: &str| plots.iter().find(|p| p.0 == n).unwrap().1.spec();
        let shr = spec("shrinkage.png");
        assert_eq!(shr.y.range.0, 0.0);
        assert_ne!(shr.series[0].line, shr.series[1].line);
        assert_ne!(shr.series[0].marker, shr.series[1].marker);
        let lp = spec("layer_profile.png");
        assert_eq!(lp.y.range.0, 0.0, "the layer spread is not stretched over the axis");
        assert!(lp.x.label.contains("[µm]"), "{}", lp.x.label);
        assert!(lp.series[0].points.iter().all(|p| p.0 >= 15.0 - 1e-9 && p.0 <= 135.0 + 1e-9));
        let temp = spec("temperature.png");
        assert_eq!(temp.y.label, "temperature [K]");
        assert_eq!(temp.series.len(), 3);
        let rd = spec("relative_density.png");
        assert!(rd.title.ends_with("relative density"), "{}", rd.title);
        // a series column another version renamed or dropped: the plot without it, no panic
        let plots = series_plots(&head, &cols[..4], &rows.iter().map(|r| r[..4].to_vec()).collect::<Vec<_>>(), false, &prof);
        assert_eq!(plots[0].1.series.len(), 3);
        assert!(plots[1].1.series.is_empty());
        // the histogram counts from zero, in plain words
        let h = histogram_plot(&head, 1800.0, &[1e-4, 2e-4, 2e-4, 3e-4]).spec();
        assert_eq!(h.y.range.0, 0.0);
        assert!(h.title.ends_with("contact length corrections at t = 30 min"), "{}", h.title);
        assert_eq!(h.series[0].marker, None);
    }
}

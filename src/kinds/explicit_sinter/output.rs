//! Outputs of an `explicit_sinter` run: per branch the history and compression series (one
//! column list, [`columns`]), the contact forces, the plots and `summary.json`.

use super::case::ExplicitSinterCase;
use crate::error::{Error, IoError};
use crate::explicit::sinter::StateColumn;
use crate::io::{Column, Series as Csv};
use crate::plot::{Plot, Series};
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::path::Path;

/// One history row.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct Row {
    pub time: f64,
    pub temperature: f64,
    pub density: f64,
    pub coordination: f64,
    /// Mean normal stress on the x⁺, y⁺, z⁺ walls over the row's interval [Pa].
    pub stress: [f64; 3],
    pub box_size: [f64; 3],
    pub force_min: f64,
    pub force_mean: f64,
    pub force_max: f64,
    pub state_mean: f64,
    pub kinetic: f64,
    /// Vertical strain ε_zz (compression rows; 0 before).
    pub strain: f64,
}

/// The columns of the history and compression series (`history_*.csv`, `compression_*.csv`),
/// with the law's state column; the CSV header and the plots' axis labels come from it.
pub fn columns(state: StateColumn) -> Vec<Column<Row>> {
    vec![
        Column { name: "time_s", unit: "s", get: |r| r.time },
        Column { name: "temperature_K", unit: "K", get: |r| r.temperature },
        Column { name: "density", unit: "1", get: |r| r.density },
        Column { name: "coordination", unit: "1", get: |r| r.coordination },
        Column { name: "sigma_xx_Pa", unit: "Pa", get: |r| r.stress[0] },
        Column { name: "sigma_yy_Pa", unit: "Pa", get: |r| r.stress[1] },
        Column { name: "sigma_zz_Pa", unit: "Pa", get: |r| r.stress[2] },
        Column { name: "lx_m", unit: "m", get: |r| r.box_size[0] },
        Column { name: "ly_m", unit: "m", get: |r| r.box_size[1] },
        Column { name: "lz_m", unit: "m", get: |r| r.box_size[2] },
        Column { name: "force_min_N", unit: "N", get: |r| r.force_min },
        Column { name: "force_mean_N", unit: "N", get: |r| r.force_mean },
        Column { name: "force_max_N", unit: "N", get: |r| r.force_max },
        Column { name: state.name, unit: state.unit, get: |r| r.state_mean },
        Column { name: "kinetic_J", unit: "J", get: |r| r.kinetic },
        Column { name: "strain_zz", unit: "1", get: |r| r.strain },
    ]
}

/// Results of one branch (pressure, sintering time).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Branch {
    pub pressure: f64,
    pub t_sinter: f64,
    pub history: Vec<Row>,
    pub compression: Vec<Row>,
    /// Normal forces of all contacts at the end of sintering and after cool-down and relaxation [N].
    pub forces_sintered: Vec<f64>,
    pub forces_cooled: Vec<f64>,
    pub density_prepared: f64,
    pub density_sintered: f64,
    pub density_final: f64,
    pub coordination_final: f64,
    pub min_force_sintered: f64,
    pub min_force_cooled: f64,
    pub max_force_cooled: f64,
    pub peak_stress: f64,
    pub strain_at_peak: f64,
    /// Secant stiffness dσ_zz/dε_zz over the first 20 % of the strain to the peak [Pa].
    pub stiffness: f64,
    pub heat_solves: u64,
    pub steps: u64,
}

/// Result of a whole case.
#[derive(Debug, Clone, Serialize)]
pub struct ExplicitSinterRun {
    pub title: String,
    pub model: String,
    pub particles: usize,
    pub dt: f64,
    pub branches: Vec<Branch>,
    pub warnings: Vec<String>,
    pub wall_seconds: f64,
    /// Where a run stopped before the end of its protocol (None: completed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped: Option<Stopped>,
}

/// Where a run stopped before the end of its protocol (Ctrl-C, a caller's stop).
#[derive(Debug, Clone, Serialize)]
pub struct Stopped {
    /// `stop_reason` ("interrupted", "stopped by the caller", …).
    pub reason: String,
    /// The stage it was in (`prepare`, `heat`, `sinter`, `cool`, `compress`).
    pub stage: &'static str,
    /// Confining pressure of the sample in progress [Pa].
    pub pressure: f64,
    /// Sintering time of the branch in progress [s] (None before sintering).
    pub t_sinter: Option<f64>,
    /// Time of the sample in progress [s].
    pub time: f64,
    /// Explicit steps taken (all samples).
    pub steps: u64,
    /// The sample in progress was in its compression test (its rows are compression rows).
    pub in_compression: bool,
}

fn tag(b: &Branch) -> String {
    format!("p{:e}_ts{}", b.pressure, b.t_sinter)
}

fn label(b: &Branch, pressures: usize) -> String {
    let ts = crate::plot::fmt_time(b.t_sinter);
    if pressures > 1 { format!("pressure {:.0e} Pa, sintered {ts}", b.pressure) } else { format!("sintered {ts}") }
}

/// Probability density of `f/⟨|f|⟩` in `bins` bins over [−3, 5].
fn force_pdf(forces: &[f64]) -> Vec<(f64, f64)> {
    if forces.is_empty() {
        return Vec::new();
    }
    let mean = forces.iter().map(|f| f.abs()).sum::<f64>() / forces.len() as f64;
    let (lo, hi, bins) = (-3.0, 5.0, 32usize);
    let w = (hi - lo) / bins as f64;
    let mut h = vec![0usize; bins];
    for &f in forces {
        let x = f / mean;
        let k = ((x - lo) / w).floor();
        if k >= 0.0 && (k as usize) < bins {
            h[k as usize] += 1;
        }
    }
    h.iter().enumerate().map(|(k, &c)| (lo + (k as f64 + 0.5) * w, c as f64 / (forces.len() as f64 * w))).collect()
}

/// Writes the series, forces, plots and `summary.json` of a run into `out_dir`; returns the summary.
pub fn write_outputs(case: &ExplicitSinterCase, run: &ExplicitSinterRun, out_dir: &Path) -> Result<serde_json::Value, Error> {
    std::fs::create_dir_all(out_dir).map_err(|e| IoError::new(out_dir, e))?;
    let state = case.law.state();
    let cols = columns(state);
    let header = crate::io::header(&cols);
    for b in &run.branches {
        let t = tag(b);
        let mut csv = Csv::create(&out_dir.join(format!("history_{t}.csv")), &header)?;
        for r in &b.history {
            csv.row(&crate::io::values(&cols, r))?;
        }
        if !b.compression.is_empty() {
            let mut csv = Csv::create(&out_dir.join(format!("compression_{t}.csv")), &header)?;
            for r in &b.compression {
                csv.row(&crate::io::values(&cols, r))?;
            }
        }
        let mut csv = Csv::create(&out_dir.join(format!("forces_{t}.csv")), &["stage", "normal_force_N"])?;
        for &f in &b.forces_sintered {
            csv.row(&[0.0, f])?;
        }
        for &f in &b.forces_cooled {
            csv.row(&[1.0, f])?;
        }
    }
    let summary = summary_json(run);
    crate::io::write_json(&out_dir.join("summary.json"), &summary)?;
    // plots last: one that cannot be written is a warning (docs/outputs.md)
    for (name, pl) in plots(case, run) {
        pl.save_png_or_warn(&out_dir.join(name));
    }
    Ok(summary)
}

/// The plots of a run (file name, plot): one line per branch, the case title and its key settings
/// on each, plain-language labels, time in the unit its span reads best in.
pub fn plots(case: &ExplicitSinterCase, run: &ExplicitSinterRun) -> Vec<(&'static str, Plot)> {
    let np = case.walls.pressures.len();
    let t_end = run.branches.iter().flat_map(|b| b.history.iter().map(|r| r.time)).fold(0.0, f64::max);
    let tu = crate::plot::time_unit(t_end, false);
    let sub = format!(
        "{} particles, {} law, {} branch{}, time step {:.2e} s",
        run.particles,
        run.model,
        run.branches.len(),
        if run.branches.len() == 1 { "" } else { "es" },
        run.dt
    );
    let mk = |what: &str, x: &str, y: &str, zero: bool, f: &dyn Fn(&Branch) -> Vec<(f64, f64)>| {
        let mut pl = Plot::new(format!("{}: {what}", case.title)).subtitle(sub.clone()).labels(x, y).y_zero(zero);
        for b in &run.branches {
            pl.add(Series::new(label(b, np), f(b)));
        }
        pl
    };
    let t = format!("time [{}]", tu.name);
    let history = |f: fn(&Row) -> f64| move |b: &Branch| -> Vec<(f64, f64)> { b.history.iter().map(|r| (tu.of(r.time), f(r))).collect() };
    let state = case.law.state();
    // the state in words with its unit; a length in the unit its values read best in (µm)
    let state_max = run.branches.iter().flat_map(|b| b.history.iter().map(|r| r.state_mean.abs())).fold(0.0, f64::max);
    let su = if state.unit == "m" { crate::plot::length_unit(state_max) } else { crate::plot::Unit { name: state.unit, factor: 1.0 } };
    let state_label = format!("{} [{}]", state.quantity, su.name);
    vec![
        ("density.png", mk("density during the sample history", &t, "density (solid volume fraction)", false, &history(|r| r.density))),
        ("coordination.png", mk("contacts per particle", &t, "mean contacts per particle", false, &history(|r| r.coordination))),
        (
            "wall_stress.png",
            mk("top-wall stress over the confining pressure", &t, "vertical wall stress / confining pressure", true, &|b: &Branch| {
                b.history.iter().map(|r| (tu.of(r.time), r.stress[2] / b.pressure)).collect()
            }),
        ),
        ("temperature.png", mk("mean temperature", &t, "temperature [K]", false, &history(|r| r.temperature))),
        ("state.png", mk(state.title, &t, &state_label, false, &|b: &Branch| b.history.iter().map(|r| (tu.of(r.time), su.of(r.state_mean))).collect())),
        ("force_extremes.png", mk("smallest contact normal force (negative: attractive)", &t, "smallest normal force [N]", true, &history(|r| r.force_min))),
        (
            "force_pdf_sintered.png",
            mk("normal-force distribution after sintering", "normal force / mean |normal force|", "probability density", true, &|b: &Branch| {
                force_pdf(&b.forces_sintered)
            }),
        ),
        (
            "force_pdf_cooled.png",
            mk("normal-force distribution after cool-down and relaxation", "normal force / mean |normal force|", "probability density", true, &|b: &Branch| {
                force_pdf(&b.forces_cooled)
            }),
        ),
        (
            "compression_stress.png",
            mk("compression test: vertical stress", "vertical strain", "vertical stress [Pa]", true, &|b: &Branch| {
                b.compression.iter().map(|r| (r.strain, r.stress[2])).collect()
            }),
        ),
        (
            "compression_density.png",
            mk("compression test: density", "vertical strain", "density (solid volume fraction)", false, &|b: &Branch| {
                b.compression.iter().map(|r| (r.strain, r.density)).collect()
            }),
        ),
    ]
}

/// The `summary.json` value of a run.
pub fn summary_json(run: &ExplicitSinterRun) -> serde_json::Value {
    let branches: Vec<serde_json::Value> = run
        .branches
        .iter()
        .map(|b| {
            json!({
                "pressure_Pa": b.pressure,
                "t_sinter_s": b.t_sinter,
                "density_prepared": b.density_prepared,
                "density_sintered": b.density_sintered,
                "density_final": b.density_final,
                "coordination_final": b.coordination_final,
                "min_force_sintered_N": b.min_force_sintered,
                "min_force_cooled_N": b.min_force_cooled,
                "max_force_cooled_N": b.max_force_cooled,
                "peak_stress_Pa": b.peak_stress,
                "strain_at_peak": b.strain_at_peak,
                "stiffness_Pa": b.stiffness,
                "heat_solves": b.heat_solves,
                "steps": b.steps,
            })
        })
        .collect();
    let mut v = json!({
        "title": run.title,
        "model": run.model,
        "particles": run.particles,
        "dt_s": run.dt,
        "wall_seconds": run.wall_seconds,
        "warnings": run.warnings,
        "branches": branches,
    });
    // a completed run's summary keeps its fields (and checksums): completed = true is implied
    if let (Some(s), Some(o)) = (run.stopped.as_ref(), v.as_object_mut()) {
        o.insert("completed".into(), json!(false));
        o.insert("stop_reason".into(), json!(s.reason));
        let mut at = json!({"stage": s.stage, "pressure_Pa": s.pressure, "time_s": s.time, "steps": s.steps});
        if let (Some(ts), Some(a)) = (s.t_sinter, at.as_object_mut()) {
            a.insert("t_sinter_s".into(), json!(ts));
        }
        o.insert("stopped_at".into(), at);
    }
    v
}

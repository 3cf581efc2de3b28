//! The 28 titanium experiments of [IV22] Table 3 (docs/diffusion7.md §9) as pair runs: each heats linearly to
//! `T_max`, holds, and cools to 313 K; the heating branch is truncated below 793 K by default
//! (`t = 0` when the furnace passes 793 K), or starts at 313 K for the full curve. Each experiment
//! uses its own mean particle diameter. Bundled as `cases/titanium/E1B.toml` … `E28B.toml`.

use crate::error::{Error, IoError};
use crate::kinds::pair::{PairSpec, parse_pair_case, run_pair, summarize};
use crate::plot::{Plot, Series};
use std::io::Write;
use std::path::Path;

/// One row of Table 3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Experiment {
    pub id: &'static str,
    /// Mean particle diameter [m].
    pub mean_diameter: f64,
    /// T_max [K].
    pub peak_temperature: f64,
    /// Heating = cooling rate (magnitude) [K/s].
    pub rate: f64,
    /// Hold time at T_max [s].
    pub hold_time: f64,
}

const R20: f64 = 20.0 / 60.0;
const R50: f64 = 50.0 / 60.0;

const fn ex(id: &'static str, d_um: f64, t: f64, rate: f64, hold_min: f64) -> Experiment {
    Experiment { id, mean_diameter: d_um * 1e-6, peak_temperature: t, rate, hold_time: hold_min * 60.0 }
}

/// [IV22] Table 3 (docs/diffusion7.md §9, compact form).
pub const EXPERIMENTS: [Experiment; 28] = [
    ex("E1B", 67.5, 1203.0, R20, 0.0),
    ex("E2B", 66.2, 1203.0, R20, 30.0),
    ex("E3B", 63.6, 1203.0, R20, 90.0),
    ex("E4B", 66.0, 1203.0, R20, 120.0),
    ex("E5B", 66.3, 1203.0, R20, 180.0),
    ex("E6B", 67.2, 1203.0, R50, 0.0),
    ex("E7B", 65.3, 1203.0, R50, 30.0),
    ex("E8B", 66.3, 1203.0, R50, 60.0),
    ex("E9B", 64.1, 1203.0, R50, 90.0),
    ex("E10B", 64.7, 1203.0, R50, 120.0),
    ex("E11B", 65.4, 1373.0, R20, 0.0),
    ex("E12B", 66.5, 1373.0, R20, 30.0),
    ex("E13B", 66.5, 1373.0, R20, 60.0),
    ex("E14B", 66.6, 1373.0, R20, 90.0),
    ex("E15B", 67.6, 1373.0, R20, 120.0),
    ex("E16B", 65.8, 1373.0, R50, 0.0),
    ex("E17B", 66.4, 1373.0, R50, 30.0),
    ex("E18B", 66.0, 1373.0, R50, 60.0),
    ex("E19B", 65.3, 1373.0, R50, 90.0),
    ex("E20B", 65.0, 1373.0, R50, 120.0),
    ex("E21B", 64.1, 1573.0, R20, 0.0),
    ex("E22B", 66.2, 1573.0, R20, 30.0),
    ex("E23B", 66.2, 1573.0, R20, 60.0),
    ex("E24B", 64.8, 1573.0, R20, 90.0),
    ex("E25B", 73.4, 1573.0, R20, 120.0),
    ex("E26B", 68.9, 1573.0, R50, 0.0),
    ex("E27B", 67.1, 1573.0, R50, 30.0),
    ex("E28B", 66.5, 1573.0, R50, 60.0),
];

/// Start of the truncated heating branch [K] ([IV22]).
pub const TRUNCATED_START: f64 = 793.0;
/// Start of the full curve and end of cooling [K] (docs/diffusion7.md §9).
pub const FULL_START: f64 = 313.0;

impl Experiment {
    /// The experiment by id (`"E14B"`).
    pub fn by_id(id: &str) -> Option<Experiment> {
        EXPERIMENTS.iter().copied().find(|e| e.id.eq_ignore_ascii_case(id))
    }

    /// The case file text (as bundled under `cases/titanium/`).
    pub fn case_toml(&self) -> String {
        let rate_kmin = (self.rate * 60.0).round();
        format!(
            "# Titanium experiment {id} of Ivannikov et al. 2022, Table 3 (docs/diffusion7.md §9), as a pair run:\n\
             # two spheres of the experiment's mean diameter {d:.1} µm, heated at {r} K/min to {tm} K, held {h} min,\n\
             # cooled at {r} K/min to 313 K. Heating branch truncated below 793 K as in [IV22]; for the full\n\
             # curve from 313 K: --set temperature.start_temperature=313. Runs in well under a second.\n\
             #   sinterdem run cases/titanium/{id}.toml --out out/{id}\n\
             kind = \"pair\"\n\
             title = \"titanium {id}\"\n\n\
             [pair]\n\
             material = \"titanium-ivannikov2022\"   # bundled, alpha/beta at 1156 K (docs/diffusion7.md §9)\n\
             radius = {rad:e}        # m, half the mean diameter\n\n\
             [temperature]\n\
             start_temperature = 793.0     # K\n\
             peak_temperature = {tm:.1}    # K\n\
             heating_rate = {rate:?}   # K/s ({r} K/min)\n\
             hold_time = {hs:.1}          # s\n\
             cooling_rate = {rate:?}   # K/s\n\
             end_temperature = 313.0       # K\n\n\
             [solver]\n\
             method = \"dopri5\"\n\
             rtol = 1.0e-6\n",
            id = self.id,
            d = self.mean_diameter * 1e6,
            r = rate_kmin,
            tm = self.peak_temperature,
            h = self.hold_time / 60.0,
            rad = self.mean_diameter / 2.0,
            rate = self.rate,
            hs = self.hold_time,
        )
    }

    /// The pair spec of this experiment; `start_temperature` [K] = 793 (truncated) or 313 (full).
    pub fn spec(&self, start_temperature: f64) -> Result<PairSpec, Error> {
        self.spec_with(start_temperature, None)
    }

    /// As [`Experiment::spec`], with an optional common particle diameter [m] replacing the
    /// experiment's own (the DEM of [IV22] used 64 µm for all).
    pub fn spec_with(&self, start_temperature: f64, diameter: Option<f64>) -> Result<PairSpec, Error> {
        let mut v: toml::Value = toml::Value::Table(self.case_toml().parse::<toml::Table>().map_err(|e| crate::error::ConfigError::invalid(e.to_string()))?);
        crate::config::apply_override(&mut v, &format!("temperature.start_temperature={start_temperature}"))?;
        if let Some(d) = diameter {
            crate::config::apply_override(&mut v, &format!("pair.radius={:e}", d / 2.0))?;
        }
        parse_pair_case(&v)
    }
}

/// Final state of one titanium run.
#[derive(Debug, Clone, PartialEq)]
pub struct TitaniumResult {
    pub experiment: Experiment,
    /// Final y1/R [1] and ΔL/L0 [1].
    pub neck_ratio: f64,
    pub shrinkage: f64,
    pub steps: u64,
    pub rhs_evaluations: u64,
    pub wall_seconds: f64,
    pub volume_drift_rel: f64,
}

/// Runs all 28 experiments (heating branch from `start_temperature` [K]: 793 truncated, 313 full;
/// each with its own mean diameter unless `common_diameter` [m] is given) and writes `titanium.csv` (id, diameter, T_max, rate, hold, final y1/R and ΔL/L0, work) and
/// `titanium_shrinkage.png` (shrinkage against hold time per group) into `out_dir`.
/// CLI: `sinterdem titanium --out DIR [--full]`.
pub fn run_all_titanium(out_dir: &Path, start_temperature: f64, common_diameter: Option<f64>) -> Result<Vec<TitaniumResult>, Error> {
    std::fs::create_dir_all(out_dir).map_err(|e| IoError::new(out_dir, e))?;
    let mut out = Vec::new();
    for e in EXPERIMENTS {
        let spec = e.spec_with(start_temperature, common_diameter)?;
        let run = run_pair(&spec, false, false).map_err(|err| err.with_context(format!("titanium experiment {}", e.id)))?;
        let s = summarize(&spec, &run);
        out.push(TitaniumResult {
            experiment: e,
            neck_ratio: s.neck_ratio,
            shrinkage: s.shrinkage,
            steps: s.steps,
            rhs_evaluations: s.rhs_evaluations,
            wall_seconds: s.wall_seconds,
            volume_drift_rel: s.volume_drift_rel,
        });
    }
    let path = out_dir.join("titanium.csv");
    let io = |err: std::io::Error| IoError::new(&path, err);
    crate::io::manifest::record(&path)?;
    let mut w = std::io::BufWriter::new(std::fs::File::create(&path).map_err(io)?);
    writeln!(w, "id,diameter_m,peak_temperature_K,rate_K_per_min,hold_time_s,start_temperature_K,neck_ratio,shrinkage,steps,rhs_evaluations,wall_seconds,volume_drift_rel").map_err(io)?;
    for r in &out {
        let e = &r.experiment;
        writeln!(
            w,
            "{},{:e},{},{},{},{},{:.8},{:.8e},{},{},{:.6},{:.2e}",
            e.id,
            common_diameter.unwrap_or(e.mean_diameter),
            e.peak_temperature,
            (e.rate * 60.0).round(),
            e.hold_time,
            start_temperature,
            r.neck_ratio,
            r.shrinkage,
            r.steps,
            r.rhs_evaluations,
            r.wall_seconds,
            r.volume_drift_rel
        )
        .map_err(io)?;
    }
    w.flush().map_err(io)?;
    let start = if start_temperature > FULL_START + 1.0 { format!("heating counted from {start_temperature:.0} K") } else { "full heating curve".to_string() };
    let size = common_diameter.map_or("each experiment's own particle diameter".to_string(), |d| format!("all particles {}", crate::plot::fmt_length(d)));
    let mut p = Plot::new("Titanium pairs of Ivannikov et al. 2022 (Table 3): final shrinkage")
        .subtitle(format!("28 two-particle runs, {start}, {size}; one line per peak temperature and heating rate"))
        .labels("hold time at the peak temperature [min]", "final shrinkage: approach / initial centre distance")
        .y_zero(true);
    for (t, r) in [(1203.0, R20), (1203.0, R50), (1373.0, R20), (1373.0, R50), (1573.0, R20), (1573.0, R50)] {
        let pts =
            out.iter().filter(|x| x.experiment.peak_temperature == t && x.experiment.rate == r).map(|x| (x.experiment.hold_time / 60.0, x.shrinkage)).collect();
        p.add(Series::new(format!("{t} K, {} K/min", (r * 60.0).round()), pts).with_markers());
    }
    p.save_png_or_warn(&out_dir.join("titanium_shrinkage.png"));
    Ok(out)
}

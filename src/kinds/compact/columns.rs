//! The columns of a compact run's `series.csv`: one list of (name, unit, getter) read from a
//! [`Row`]; the CSV header, each row and the plots' labels derive from it (docs/outputs.md). A
//! new column is one line here (and, for a new measure, a method in `coupled/observables.rs`).

use crate::coupled::Simulation;
use crate::io::Column;
use nalgebra::Vector3;

/// The state one series row is read from: the simulation after a step, the step's Δt and the
/// measures that give several columns at once, evaluated once per row.
pub(crate) struct Row<'a> {
    pub sim: &'a Simulation,
    /// The Δt of the step that ended at this row [s] (0 for the initial row).
    pub dt: f64,
    /// Total shrinkage per axis [1].
    pub shrinkage: Vector3<f64>,
    /// Mean, min, max particle temperature without the isolated particles [K].
    pub temperature: (f64, f64, f64),
    /// Macroscopic stress `[xx, yy, zz, yz, xz, xy]` [Pa].
    pub stress: [f64; 6],
    /// Sintering shrinkage per axis (net of the thermal strain) [1].
    pub sintering: Vector3<f64>,
}

impl<'a> Row<'a> {
    pub(crate) fn new(sim: &'a Simulation, dt: f64) -> Row<'a> {
        Row {
            sim,
            dt,
            shrinkage: sim.shrinkage(),
            temperature: sim.temperature_stats(&sim.isolated_particles()),
            stress: sim.macroscopic_stress(),
            sintering: sim.sintering_shrinkage(),
        }
    }

    /// The columns of `series.csv`, in order.
    pub(crate) const COLUMNS: &'a [Column<Row<'a>>] = &[
        Column { name: "time_s", unit: "s", get: |r| r.sim.t },
        Column { name: "dt_s", unit: "s", get: |r| r.dt },
        Column { name: "shrinkage_x", unit: "1", get: |r| r.shrinkage.x },
        Column { name: "shrinkage_y", unit: "1", get: |r| r.shrinkage.y },
        Column { name: "shrinkage_z", unit: "1", get: |r| r.shrinkage.z },
        Column { name: "relative_density", unit: "1", get: |r| r.sim.relative_density() },
        Column { name: "coordination_mean", unit: "1", get: |r| r.sim.coordination() },
        Column { name: "neck_ratio_mean", unit: "1", get: |r| r.sim.mean_neck_ratio() },
        Column { name: "contacts", unit: "1", get: |r| r.sim.contacts.len() as f64 },
        Column { name: "mean_temperature_K", unit: "K", get: |r| r.temperature.0 },
        Column { name: "min_temperature_K", unit: "K", get: |r| r.temperature.1 },
        Column { name: "max_temperature_K", unit: "K", get: |r| r.temperature.2 },
        Column { name: "subdivided_fraction", unit: "1", get: |r| r.sim.subdivided_fraction() },
        Column { name: "rhs_evaluations", unit: "1", get: |r| r.sim.ode.rhs as f64 },
        Column { name: "thermal_strain", unit: "1", get: |r| r.sim.thermal_strain().0 },
        Column { name: "sintering_shrinkage_x", unit: "1", get: |r| r.sintering.x },
        Column { name: "sintering_shrinkage_y", unit: "1", get: |r| r.sintering.y },
        Column { name: "sintering_shrinkage_z", unit: "1", get: |r| r.sintering.z },
        Column { name: "applied_stress_Pa", unit: "Pa", get: |r| r.sim.applied_stress() },
        Column { name: "sigma_xx_Pa", unit: "Pa", get: |r| r.stress[0] },
        Column { name: "sigma_yy_Pa", unit: "Pa", get: |r| r.stress[1] },
        Column { name: "sigma_zz_Pa", unit: "Pa", get: |r| r.stress[2] },
        Column { name: "sigma_yz_Pa", unit: "Pa", get: |r| r.stress[3] },
        Column { name: "sigma_xz_Pa", unit: "Pa", get: |r| r.stress[4] },
        Column { name: "sigma_xy_Pa", unit: "Pa", get: |r| r.stress[5] },
        Column { name: "normal_force_mean_N", unit: "N", get: |r| r.sim.mean_normal_force() },
    ];
}

/// Why a column is left out of a run whose physics lacks it (docs/outputs.md "series.csv"): the
/// physics it needs and its absence in words; None for columns every run writes.
fn needs(name: &str) -> Option<(fn(&Simulation) -> bool, &'static str)> {
    let expansion: fn(&Simulation) -> bool = |s| s.expansion.is_some();
    let stress: fn(&Simulation) -> bool = |s| s.load.is_some() || s.cell.is_some();
    match name {
        "thermal_strain" | "sintering_shrinkage_x" | "sintering_shrinkage_y" | "sintering_shrinkage_z" => {
            Some((expansion, "no thermal expansion (thermal_strain is 0 and sintering_shrinkage_* repeats shrinkage_*)"))
        }
        "applied_stress_Pa" | "sigma_xx_Pa" | "sigma_yy_Pa" | "sigma_zz_Pa" | "sigma_yz_Pa" | "sigma_xz_Pa" | "sigma_xy_Pa" | "normal_force_mean_N" => {
            Some((stress, "no applied load and no periodic cell (every stress and contact force is 0)"))
        }
        _ => None,
    }
}

/// The indices into [`Row::COLUMNS`] a run writes: those whose physics is present (the same
/// set for every row and after a resume: it follows from the case alone), and the log lines
/// naming the others with the reason.
pub(crate) fn present(sim: &Simulation) -> (Vec<usize>, Vec<String>) {
    let mut keep = Vec::new();
    let mut dropped: Vec<(&'static str, Vec<&'static str>)> = Vec::new();
    for (k, c) in Row::COLUMNS.iter().enumerate() {
        match needs(c.name) {
            Some((on, why)) if !on(sim) => match dropped.iter_mut().find(|d| d.0 == why) {
                Some(d) => d.1.push(c.name),
                None => dropped.push((why, vec![c.name])),
            },
            _ => keep.push(k),
        }
    }
    let lines = dropped.iter().map(|(why, names)| format!("series.csv without {}: {why}", names.join(", "))).collect();
    (keep, lines)
}

/// The header of the series columns `keep` (indices into [`Row::COLUMNS`]).
pub(crate) fn header(keep: &[usize]) -> Vec<&'static str> {
    keep.iter().map(|&k| Row::COLUMNS[k].name).collect()
}

/// The row of the series columns `keep` of `row`.
pub(crate) fn values(keep: &[usize], row: &Row) -> Vec<f64> {
    keep.iter().map(|&k| (Row::COLUMNS[k].get)(row)).collect()
}

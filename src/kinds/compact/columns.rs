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

/// The names of the series columns, in order (the CSV header).
pub(crate) fn header() -> Vec<&'static str> {
    crate::io::header(Row::COLUMNS)
}

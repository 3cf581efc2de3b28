//! The current state of a stepped run (heat, compact), as plain arrays for callers such as the
//! Python package's `Simulation.particles` / `.contacts`, and the changes a caller may make
//! between steps: the furnace temperature and the applied stress, each rewritten into the run's
//! case text too, so that a checkpoint written afterwards resumes the changed run.

use crate::error::ConfigError;
use crate::profile::Profile;

/// The particles now (SI units).
#[derive(Debug, Clone, Default)]
pub struct ParticleState {
    /// Particle index (the row in the packing, the index in `ContactState::pairs`).
    pub ids: Vec<i64>,
    /// Centres, x y z per particle [m] (row-major N × 3).
    pub positions: Vec<f64>,
    /// Radii [m] (compact runs with thermal expansion: the expanded radius).
    pub radii: Vec<f64>,
    /// Temperatures [K].
    pub temperatures: Vec<f64>,
    /// Position minus initial position [m] (N × 3; zero in heat runs: the packing is static).
    pub displacements: Vec<f64>,
}

/// The contacts now (SI units).
#[derive(Debug, Clone, Default)]
pub struct ContactState {
    /// The two particles of each contact (M × 2).
    pub pairs: Vec<i64>,
    /// Neck radius [m] (compact: the 7-DOF y1).
    pub neck_radii: Vec<f64>,
    /// Normal force of the applied load on the contact, compressive positive [N] (0 without a
    /// load; heat runs: 0).
    pub forces: Vec<f64>,
}

/// Flattens 3-vectors into a row-major N × 3 array.
pub(crate) fn flat3<'a>(v: impl ExactSizeIterator<Item = &'a nalgebra::Vector3<f64>>) -> Vec<f64> {
    let mut out = Vec::with_capacity(3 * v.len());
    for x in v {
        out.extend_from_slice(&[x.x, x.y, x.z]);
    }
    out
}

/// Flattens contact pairs into a row-major M × 2 array.
pub(crate) fn flat_pairs(pairs: &[[u32; 2]]) -> Vec<i64> {
    pairs.iter().flat_map(|p| [p[0] as i64, p[1] as i64]).collect()
}

/// Rewrites `thermal.furnace.profile` (and `wall_profile` when the case has one) of the case text
/// `source` to the table of `profile`.
pub(crate) fn rewrite_furnace(source: &mut String, profile: &Profile) -> Result<(), ConfigError> {
    rewrite(source, |t| {
        let rows = rows_value(&profile.rows());
        let furnace = t
            .get_mut("thermal")
            .and_then(|v| v.get_mut("furnace"))
            .and_then(|v| v.as_table_mut())
            .ok_or_else(|| ConfigError::invalid("set_furnace_temperature: the case has no [thermal.furnace]"))?;
        let table = || toml::Value::Table(toml::Table::from_iter([("table".to_string(), rows.clone())]));
        furnace.insert("profile".into(), table());
        if furnace.contains_key("wall_profile") {
            furnace.insert("wall_profile".into(), table());
        }
        Ok(())
    })
}

/// Rewrites `load.stress` / `load.stress_table` of the case text `source` to the table `rows`.
pub(crate) fn rewrite_stress(source: &mut String, rows: &[[f64; 2]]) -> Result<(), ConfigError> {
    rewrite(source, |t| {
        let load = t.get_mut("load").and_then(|v| v.as_table_mut()).ok_or_else(|| ConfigError::invalid("set_applied_stress: the case has no [load]"))?;
        load.remove("stress");
        load.insert("stress_table".into(), rows_value(rows));
        Ok(())
    })
}

fn rows_value(rows: &[[f64; 2]]) -> toml::Value {
    toml::Value::Array(rows.iter().map(|r| toml::Value::Array(vec![toml::Value::Float(r[0]), toml::Value::Float(r[1])])).collect())
}

fn rewrite(source: &mut String, edit: impl FnOnce(&mut toml::Table) -> Result<(), ConfigError>) -> Result<(), ConfigError> {
    let mut t: toml::Table = source.parse().map_err(|e| ConfigError::invalid(format!("the run's case text cannot be re-read: {e}")))?;
    edit(&mut t)?;
    *source = toml::to_string(&t).map_err(|e| ConfigError::invalid(format!("the run's case text cannot be re-written: {e}")))?;
    Ok(())
}

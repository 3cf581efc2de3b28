//! What a caller of the stepping API reads and changes between the steps of a compact run
//! ([`CompactRun`]): the particle and contact state, the furnace temperature, the applied stress.

use super::CompactRun;
use crate::error::{ConfigError, Error};
use crate::kinds::state::{self, ContactState, ParticleState};

impl CompactRun {
    /// The particles now: positions and displacements [m], radii [m] (expanded with thermal
    /// expansion, as in the snapshots), temperatures [K].
    pub fn particles(&self) -> ParticleState {
        let sim = &self.sim;
        let p = &sim.prep.scene.particles;
        let radii = match sim.thermal_strains() {
            Some(e) => p.radius.iter().zip(&e).map(|(r, e)| r * (1.0 + e)).collect(),
            None => p.radius.clone(),
        };
        let mut displacements = Vec::with_capacity(3 * p.len());
        for (x, x0) in p.position.iter().zip(&sim.x0) {
            let d = x - x0;
            displacements.extend_from_slice(&[d.x, d.y, d.z]);
        }
        ParticleState {
            ids: (0..p.len() as i64).collect(),
            positions: state::flat3(p.position.iter()),
            radii,
            temperatures: p.temperature.clone(),
            displacements,
        }
    }

    /// The contacts now: pairs, neck radii y1 [m], normal forces of the applied load [N].
    pub fn contacts(&self) -> ContactState {
        let c = &self.sim.contacts;
        ContactState {
            pairs: state::flat_pairs(&c.pairs),
            neck_radii: c.state.iter().map(|s| s.y[0]).collect(),
            forces: c.state.iter().map(|s| s.normal_force).collect(),
        }
    }

    /// Holds the furnace at `temperature` [K] from now on (gas and walls; isothermal runs: every
    /// particle). The same as the case's furnace profile rewritten as a table with a jump at the
    /// current time ([`crate::profile::Profile::hold_from`]); the run's case text (checkpoints)
    /// says so too.
    pub fn set_furnace_temperature(&mut self, temperature: f64) -> Result<(), Error> {
        let sim = &mut self.sim;
        let t = sim.t;
        let mut table = None;
        if let Some(p) = sim.prep.isothermal.as_mut() {
            *p = p.hold_from(t, temperature)?;
            table = Some(p.clone());
        }
        if let Some(f) = sim.prep.sources.furnace.as_mut() {
            f.gas = f.gas.hold_from(t, temperature)?;
            f.wall = f.wall.hold_from(t, temperature)?;
            table.get_or_insert_with(|| f.gas.clone());
            let f = f.clone();
            if let Some(net) = sim.heat.as_mut() {
                net.set_furnace(f);
            }
        }
        let Some(profile) = table else {
            return Err(ConfigError::invalid("set_furnace_temperature: this compact case has no furnace (add [thermal.furnace] with a profile)").into());
        };
        state::rewrite_furnace(&mut sim.source.0, &profile)?;
        Ok(())
    }

    /// Holds the applied stress at `stress` [Pa] (compressive positive) from now on: the same
    /// as `load.stress_table` with a jump at the current time; needs a `[load]` section.
    pub fn set_applied_stress(&mut self, stress: f64) -> Result<(), Error> {
        let t = self.sim.t;
        let Some(load) = self.sim.load.as_mut() else {
            return Err(ConfigError::invalid(
                "set_applied_stress: this compact case has no applied load (add [load] with mode = \"uniaxial\" or \"isostatic\")",
            )
            .into());
        };
        load.settings.stress = load.settings.stress.hold_from(t, stress)?;
        let rows = load.settings.stress.rows();
        state::rewrite_stress(&mut self.sim.source.0, &rows)?;
        Ok(())
    }
}

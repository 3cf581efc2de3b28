//! One coupled step ([`Simulation::advance_step`]): topology → heat → diffusion → mechanics →
//! correction → step control (docs/coupled.md "One step"), one call per stage
//! ([`super::stages`]), each stage's wall time counted.

use super::Simulation;
use super::stages::{self, Window};
use crate::error::Error;
use std::time::Instant;

impl Simulation {
    /// One accepted global step (strategy 1 may reject and retry inside).
    pub fn advance_step(&mut self, log: &mut dyn FnMut(&str)) -> Result<(), Error> {
        let end = self.stop_at.min(self.settings.end);
        loop {
            let w = Window::new(self.t, self.dt, end);
            let x_start = self.prep.scene.particles.position.clone();
            // 1. topology
            let tic = Instant::now();
            stages::topology(self, log)?;
            self.timing.detection += tic.elapsed().as_secs_f64();
            // 1b. applied load: the contacts' normal forces at t0 (docs/pressure.md (P3))
            let tic = Instant::now();
            self.update_load_forces(w.t0)?;
            self.timing.mechanics += tic.elapsed().as_secs_f64();
            // 2. heat
            let tic = Instant::now();
            let temps_old = self.prep.scene.particles.temperature.clone();
            let heat_info = stages::heat(self, &w, &temps_old)?;
            self.timing.heat += tic.elapsed().as_secs_f64();
            // 3. diffusion sweep
            let tic = Instant::now();
            let sweep = stages::diffusion(self, &w, &temps_old)?;
            self.timing.diffusion += tic.elapsed().as_secs_f64();
            if stages::reject(self, &w, &sweep, &temps_old) {
                continue;
            }
            stages::keep(self, &sweep, heat_info);
            // 4. mechanics
            let tic = Instant::now();
            let motion = stages::mechanics(self, &w, &temps_old)?;
            self.timing.mechanics += tic.elapsed().as_secs_f64();
            // 5. correction (C1)–(C4)
            let tic = Instant::now();
            stages::correction(self, &w, &motion)?;
            self.timing.correction += tic.elapsed().as_secs_f64();
            // 6. step control
            stages::step_control(self, &w, &x_start, sweep.subdivided);
            let tic = Instant::now();
            self.accumulate_dose(&w, &temps_old);
            self.timing.diffusion += tic.elapsed().as_secs_f64();
            self.check_state(log)?;
            return Ok(());
        }
    }
}

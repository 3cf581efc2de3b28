//! The forward model of a pair calibration: every experiment is one 7-DOF contact between two equal
//! spheres of the experiment's diameter under its own schedule (as a `kind = "pair"` case with
//! `overlap = 0`), integrated in-process and in parallel over experiments (rayon). The outputs are
//! the neck ratio y1/R [1] and the shrinkage ΔL/L0 = (L0 − y4 − y7)/L0 [1] at every series time and
//! at the end of the schedule. A batch of parameter sets runs in parallel over (set, experiment);
//! each run is sequential and the results are collected in order, so an evaluation is
//! bit-identical for any thread count.

use super::data::Experiment;
use super::model::{ForwardModel, Point, Predictions, Problem};
use crate::error::{Error, ModelError};
use crate::models::diffusion7::advance::{PairMaterials, SolverOptions, TemperaturePath, advance};
use crate::models::diffusion7::contact::Contact7;
use crate::models::diffusion7::{Material, PathFactors};
use crate::models::ode::OdeStats;
use rayon::prelude::*;

/// Initial pair geometry (`[pair]` of the calibration file; defaults as in pair cases).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairGeometry {
    /// Centre distance = 2R(1 − overlap) [1].
    pub overlap: f64,
    /// ε, η of (I2) [1].
    pub neck_epsilon: f64,
    pub cone_eta: f64,
}

impl Default for PairGeometry {
    fn default() -> Self {
        PairGeometry {
            overlap: 0.0,
            neck_epsilon: crate::models::diffusion7::contact::DEFAULT_EPSILON,
            cone_eta: crate::models::diffusion7::contact::DEFAULT_ETA,
        }
    }
}

/// Predicted neck ratio and shrinkage [1] at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Predicted {
    pub neck_ratio: f64,
    pub shrinkage: f64,
}

/// Predictions of one experiment: at its series times (same order) and at the end.
#[derive(Debug, Clone, PartialEq)]
pub struct Prediction {
    pub series: Vec<Predicted>,
    pub end: Predicted,
    /// Accepted substeps of the run.
    pub steps: u64,
}

/// The pair forward model: every experiment as one 7-DOF pair run, in-process.
#[derive(Debug)]
pub struct PairModel {
    pub problem: Problem,
    pub solver: SolverOptions,
    pub geometry: PairGeometry,
}

/// Runs one experiment with `material` and `factors`.
pub fn run_experiment(e: &Experiment, material: &Material, factors: PathFactors, solver: &SolverOptions, g: &PairGeometry) -> Result<Prediction, ModelError> {
    if let Some(tm) = material.melting_temperature
        && let Some(t) = e.profile.first_reaching(tm, e.profile.duration())
    {
        return Err(ModelError::new(format!(
            "experiment {}: the temperature history reaches {tm} K, the melting (solidus) temperature of \"{}\", at t = {} s; solid-state sintering no longer applies",
            e.id,
            material.name,
            crate::error::fmt_value(t)
        )));
    }
    let r = 0.5 * e.diameter;
    let mut c = Contact7::new(r, r, 2.0 * r * (1.0 - g.overlap), 0.0, g.neck_epsilon, g.cone_eta)?;
    let mats = PairMaterials { a: material, b: material, factors };
    let path = TemperaturePath::Profile(&e.profile);
    let mut stats = OdeStats::default();
    let mut t = 0.0;
    let mut series = Vec::with_capacity(e.series.len());
    let ctx = |err: ModelError, t: f64| err.with_context(format!("experiment {} at t = {t:.6e} s", e.id));
    for p in &e.series {
        if p.time > t {
            advance(&mut c, &mats, &path, t, p.time, solver, &mut stats, |_, _, _| {}).map_err(|err| ctx(err, p.time))?;
            t = p.time;
        }
        series.push(Predicted { neck_ratio: c.neck_ratio(), shrinkage: c.shrinkage() });
    }
    let end = e.profile.duration();
    if end > t {
        advance(&mut c, &mats, &path, t, end, solver, &mut stats, |_, _, _| {}).map_err(|err| ctx(err, end))?;
    }
    let end = Predicted { neck_ratio: c.neck_ratio(), shrinkage: c.shrinkage() };
    if !(end.neck_ratio.is_finite() && end.shrinkage.is_finite()) {
        return Err(ModelError::new(format!("experiment {}: non-finite result", e.id)));
    }
    Ok(Prediction { series, end, steps: stats.steps })
}

impl ForwardModel for PairModel {
    fn problem(&self) -> &Problem {
        &self.problem
    }

    fn name(&self) -> &'static str {
        "pair"
    }

    /// Every (set, experiment) pair of the batch in parallel (rayon), collected in order: each
    /// run is sequential, so the result is bit-identical for any thread count.
    fn run_batch(&self, _batch: usize, _label: &str, points: &[Point]) -> Result<(Vec<Predictions>, usize), Error> {
        let ne = self.problem.experiments.len();
        let flat: Vec<Result<Prediction, ModelError>> = (0..points.len() * ne)
            .into_par_iter()
            .map(|k| {
                let (p, e) = (&points[k / ne], &self.problem.experiments[k % ne]);
                run_experiment(e, &p.material, p.factors, &self.solver, &self.geometry)
            })
            .collect();
        let mut it = flat.into_iter();
        let out: Vec<Predictions> = points.iter().map(|_| it.by_ref().take(ne).collect()).collect();
        Ok((out, points.len() * ne))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::synthetic::titanium_experiments;
    use crate::kinds::pair::run_pair;
    use crate::kinds::titanium::{Experiment as Table3, TRUNCATED_START};

    /// The calibration's pair run of E14B (schedule string) is the bundled `kind = "pair"` case's run.
    #[test]
    fn experiment_run_matches_the_pair_case() {
        let e = &titanium_experiments(Some(&["E14B"]))[0];
        let spec = Table3::by_id("E14B").unwrap().spec(TRUNCATED_START).unwrap();
        let run = run_pair(&spec, false, false).unwrap();
        let p = run_experiment(e, &spec.material_a, spec.factors, &spec.solver, &PairGeometry::default()).unwrap();
        assert!((p.end.neck_ratio - run.contact.neck_ratio()).abs() < 1e-12, "{} vs {}", p.end.neck_ratio, run.contact.neck_ratio());
        assert!((p.end.shrinkage - run.contact.shrinkage()).abs() < 1e-12);
        assert_eq!(p.steps, run.stats.steps);
    }
}

//! The loss: weighted least squares of the measured values,
//! `χ² = Σ_k r_k²` with `r_k = (model_k − measured_k)/σ_k`, over the neck ratios and shrinkages of
//! every experiment (series points first, in time order, then the end of the schedule). A run that
//! fails (ModelError) gives every residual of its experiment the value [`FAILURE_RESIDUAL`]: a
//! penalty of 10⁶ per value, far above any fit, but finite, so the optimisers carry on.

use super::data::{Experiment, Measured, Observation};
use super::forward::{Predicted, Prediction};
use crate::error::ModelError;

/// Residual of every value of an experiment whose run failed [1].
pub const FAILURE_RESIDUAL: f64 = 1.0e3;

/// Which quantity a residual belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    NeckRatio,
    Shrinkage,
}

impl Quantity {
    pub fn name(&self) -> &'static str {
        match self {
            Quantity::NeckRatio => "neck_ratio",
            Quantity::Shrinkage => "shrinkage",
        }
    }
}

/// One measured value with its fitted counterpart.
#[derive(Debug, Clone, PartialEq)]
pub struct Residual {
    /// Experiment index in the data file.
    pub experiment: usize,
    /// Time of the observation [s] (the schedule's end for end values).
    pub time: f64,
    /// Whether this is the end-of-schedule value (not a series point).
    pub end: bool,
    pub quantity: Quantity,
    pub measured: Measured,
    /// Model value [1] (NaN if the run failed).
    pub fitted: f64,
    /// (fitted − measured)/σ [1], or [`FAILURE_RESIDUAL`].
    pub residual: f64,
}

fn push(out: &mut Vec<Residual>, i: usize, time: f64, end: bool, obs: &Observation, pred: Option<&Predicted>) {
    for (q, m) in [(Quantity::NeckRatio, obs.neck_ratio), (Quantity::Shrinkage, obs.shrinkage)] {
        let Some(m) = m else { continue };
        let (fitted, residual) = match pred {
            Some(p) => {
                let f = if q == Quantity::NeckRatio { p.neck_ratio } else { p.shrinkage };
                (f, (f - m.value) / m.sigma)
            }
            None => (f64::NAN, FAILURE_RESIDUAL),
        };
        out.push(Residual { experiment: i, time, end, quantity: q, measured: m, fitted, residual });
    }
}

/// Residuals of all experiments in the fixed order (experiment, series time, end; neck before shrinkage).
pub fn residuals(experiments: &[Experiment], predictions: &[Result<Prediction, ModelError>]) -> Vec<Residual> {
    let mut out = Vec::new();
    for (i, (e, p)) in experiments.iter().zip(predictions).enumerate() {
        let p = p.as_ref().ok();
        for (k, s) in e.series.iter().enumerate() {
            push(&mut out, i, s.time, false, &s.observation, p.map(|p| &p.series[k]));
        }
        push(&mut out, i, e.profile.duration(), true, &e.end, p.map(|p| &p.end));
    }
    out
}

/// Just the residual vector r [1].
pub fn residual_vector(experiments: &[Experiment], predictions: &[Result<Prediction, ModelError>]) -> Vec<f64> {
    residuals(experiments, predictions).into_iter().map(|r| r.residual).collect()
}

/// χ² = Σ r² [1].
pub fn chi2(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::data::SeriesPoint;
    use crate::profile::Profile;

    #[test]
    fn residuals_are_divided_by_sigma_and_failures_are_penalised() {
        let m = |v, s| Some(Measured { value: v, sigma: s });
        let e = Experiment {
            id: "E".into(),
            diameter: 1e-4,
            schedule: String::new(),
            profile: Profile::constant(1000.0).unwrap(),
            end: Observation { neck_ratio: m(0.5, 0.01), shrinkage: m(0.02, 0.002) },
            series: vec![SeriesPoint { time: 10.0, observation: Observation { neck_ratio: None, shrinkage: m(0.01, 0.001) } }],
        };
        let p = Prediction { series: vec![Predicted { neck_ratio: 0.3, shrinkage: 0.012 }], end: Predicted { neck_ratio: 0.52, shrinkage: 0.02 }, steps: 1 };
        let r = residual_vector(std::slice::from_ref(&e), &[Ok(p)]);
        assert_eq!(r.len(), 3);
        assert!((r[0] - 2.0).abs() < 1e-12 && (r[1] - 2.0).abs() < 1e-9 && r[2].abs() < 1e-12, "{r:?}");
        assert!((chi2(&r) - 8.0).abs() < 1e-9);
        let f = residual_vector(&[e], &[Err(ModelError::new("x"))]);
        assert_eq!(f, vec![FAILURE_RESIDUAL; 3]);
    }
}

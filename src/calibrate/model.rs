//! What the optimisers see of a forward model: a batch of parameter sets in, the predictions of
//! every experiment at each set out.
//!
//! - [`Problem`]: the experiments, the starting material and path factors, the fitted parameters;
//! - [`ForwardModel`]: runs one *batch* (one optimiser generation: the swarm's particles of one
//!   iteration, the perturbed points of a finite-difference Jacobian, …). The pair model
//!   ([`super::forward::PairModel`]) runs a batch in-process in parallel over (set, experiment);
//!   the compact model ([`super::compact::CompactModel`]) sends it to the study engine as one
//!   study (local or SLURM);
//! - [`Evaluator`]: the memo in front of a model. A parameter set is run at most once (the same
//!   point asked for again, e.g. the optimum after the local phase, is answered from memory), a
//!   set the material tables reject is a failure without a run, and every batch actually sent is
//!   logged ([`BatchInfo`]).
//!
//! Sets are keyed by the bits of their values [SI], so a batch's content, its order and therefore
//! the whole fit are deterministic.

use super::data::Experiment;
use super::forward::Prediction;
use super::params::{Parameter, apply};
use crate::error::{Error, ModelError};
use crate::models::diffusion7::{Material, PathFactors};
use serde::Serialize;
use std::collections::HashMap;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

/// Predictions of every experiment (data-file order) at one parameter set; a failed run is `Err`.
pub type Predictions = Vec<Result<Prediction, ModelError>>;

/// The fitted problem, shared by every forward model.
#[derive(Debug, Clone)]
pub struct Problem {
    pub experiments: Vec<Experiment>,
    /// The starting material and path factors (the parameters replace fields of copies).
    pub material: Material,
    pub factors: PathFactors,
    pub params: Vec<Parameter>,
}

impl Problem {
    /// Material and factors at parameter values [SI].
    pub fn configured(&self, values: &[f64]) -> (Material, PathFactors) {
        apply(&self.params, &self.material, &self.factors, values)
    }

    /// Values [SI] at unit coordinates (clamped to [0, 1]).
    pub fn values(&self, u: &[f64]) -> Vec<f64> {
        self.params.iter().zip(u).map(|(p, u)| p.value(*u)).collect()
    }

    /// Measured values in total (residuals of a set).
    pub fn value_count(&self) -> usize {
        self.experiments.iter().map(|e| e.count()).sum()
    }
}

/// One parameter set of a batch: its values [SI] and the material and factors they give.
#[derive(Debug, Clone)]
pub struct Point {
    pub values: Vec<f64>,
    pub material: Material,
    pub factors: PathFactors,
}

/// One batch sent to a forward model.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct BatchInfo {
    /// Sequence number (0, 1, …; the compact model's batch directory `gen-NNNN-LABEL`).
    pub batch: usize,
    /// What the optimiser was doing: `start`, `swarm`, `local`, `simplex`, `jacobian`, `covariance`.
    pub label: String,
    /// Parameter sets in the batch.
    pub points: usize,
    /// Runs in the batch (sets × experiments).
    pub runs: usize,
    /// Runs actually computed (the compact model reuses finished runs of its study store).
    pub executed: usize,
}

/// A forward model: runs every experiment at each parameter set of a batch.
pub trait ForwardModel: Sync {
    /// The problem (experiments, starting material, parameters).
    fn problem(&self) -> &Problem;
    /// `pair` or `compact`.
    fn name(&self) -> &'static str;
    /// Runs batch number `batch` (`label`: what it is for). Returns per set, per experiment, the
    /// prediction or the run's error (a penalty for the loss), plus the number of runs actually
    /// computed; `Err` only when the batch could not be run at all (e.g. no `sbatch` on PATH).
    fn run_batch(&self, batch: usize, label: &str, points: &[Point]) -> Result<(Vec<Predictions>, usize), Error>;
    /// Whether a local-phase cost evaluation should also run the forward-difference points of its
    /// Jacobian in the same batch: worth it when a batch costs latency (a study through a queue)
    /// rather than CPU alone.
    fn speculative_jacobian(&self) -> bool {
        false
    }
}

fn key(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

/// The memo and batch log in front of a forward model (see the module docs).
pub struct Evaluator<'a> {
    pub model: &'a dyn ForwardModel,
    memo: Mutex<HashMap<Vec<u64>, Predictions>>,
    /// Parameter sets evaluated (each runs every experiment once; sets rejected by the material
    /// tables count too).
    evaluations: AtomicU64,
    /// Runs that failed (or sets rejected, one per experiment).
    failures: AtomicU64,
    batches: Mutex<Vec<BatchInfo>>,
}

impl<'a> Evaluator<'a> {
    pub fn new(model: &'a dyn ForwardModel) -> Evaluator<'a> {
        Evaluator { model, memo: Mutex::new(HashMap::new()), evaluations: AtomicU64::new(0), failures: AtomicU64::new(0), batches: Mutex::new(Vec::new()) }
    }

    pub fn problem(&self) -> &Problem {
        self.model.problem()
    }

    /// Predictions at unit coordinates `us` (each clamped to [0, 1]ⁿ), the sets not yet known run
    /// as one batch labelled `label`.
    pub fn predict(&self, us: &[Vec<f64>], label: &str) -> Result<Vec<Predictions>, Error> {
        let pb = self.problem();
        let values: Vec<Vec<f64>> = us.iter().map(|u| pb.values(&u.iter().map(|x| x.clamp(0.0, 1.0)).collect::<Vec<_>>())).collect();
        let mut todo: Vec<Point> = Vec::new();
        {
            let mut memo = self.memo.lock().unwrap_or_else(|e| e.into_inner());
            for v in &values {
                let k = key(v);
                if memo.contains_key(&k) || todo.iter().any(|p| key(&p.values) == k) {
                    continue;
                }
                let (m, f) = pb.configured(v);
                if let Err(e) = m.validate().and(f.validate()) {
                    // a set the material tables reject: every experiment fails, nothing runs
                    let err = ModelError::new(format!("parameter set rejected: {e}"));
                    self.evaluations.fetch_add(1, Ordering::Relaxed);
                    self.failures.fetch_add(pb.experiments.len() as u64, Ordering::Relaxed);
                    memo.insert(k, pb.experiments.iter().map(|_| Err(err.clone())).collect());
                    continue;
                }
                todo.push(Point { values: v.clone(), material: m, factors: f });
            }
        }
        if !todo.is_empty() {
            let batch = self.batches.lock().unwrap_or_else(|e| e.into_inner()).len();
            let (preds, executed) = self.model.run_batch(batch, label, &todo)?;
            // Ctrl-C/SIGTERM: the runs of the batch stopped early, so their results are not
            // predictions; the calibration ends without a fit (the compact model's studies keep
            // their finished runs, so the same command again continues from them)
            if crate::interrupt::requested() {
                return Err(ModelError::new(format!(
                    "calibration interrupted by a signal in batch {batch} ({label}): no fit written; run the same command again"
                ))
                .into());
            }
            let failed: usize = preds.iter().map(|p| p.iter().filter(|r| r.is_err()).count()).sum();
            self.evaluations.fetch_add(todo.len() as u64, Ordering::Relaxed);
            self.failures.fetch_add(failed as u64, Ordering::Relaxed);
            self.batches.lock().unwrap_or_else(|e| e.into_inner()).push(BatchInfo {
                batch,
                label: label.to_string(),
                points: todo.len(),
                runs: todo.len() * pb.experiments.len(),
                executed,
            });
            let mut memo = self.memo.lock().unwrap_or_else(|e| e.into_inner());
            for (p, r) in todo.iter().zip(preds) {
                memo.insert(key(&p.values), r);
            }
        }
        let memo = self.memo.lock().unwrap_or_else(|e| e.into_inner());
        Ok(values.iter().map(|v| memo[&key(v)].clone()).collect())
    }

    /// Residual vectors at unit coordinates `us` (one batch for the unknown sets).
    pub fn residuals(&self, us: &[Vec<f64>], label: &str) -> Result<Vec<Vec<f64>>, Error> {
        let ex = &self.problem().experiments;
        Ok(self.predict(us, label)?.iter().map(|p| super::loss::residual_vector(ex, p)).collect())
    }

    /// Parameter sets evaluated so far.
    pub fn evaluations(&self) -> u64 {
        self.evaluations.load(Ordering::Relaxed)
    }

    /// Failed runs so far.
    pub fn failures(&self) -> u64 {
        self.failures.load(Ordering::Relaxed)
    }

    /// The batches sent so far.
    pub fn batches(&self) -> Vec<BatchInfo> {
        self.batches.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

//! The online predictor: feed it seeks and measurements one at a time; ask for the predicted
//! bias at any candidate next target without changing its state (what a seek scheduler asks).
//!
//! ```
//! # use biasctl::model::{FittedModel, Predictor};
//! # fn demo(model: &FittedModel) -> Result<(), biasctl::model::ModelError> {
//! let mut p = Predictor::new(model, &[])?;
//! p.step(0.0, 100.0, &[], Some(12.0));        // seek to 100, measured 12 counts
//! let guess = p.peek(0.5, 180.0, &[]);         // what would the bias be at 180?
//! assert_eq!(guess, p.step(0.5, 180.0, &[], None));
//! # Ok(()) }
//! ```

use super::term::{Seek, TermState};
use super::{FittedModel, ModelError};
use crate::history::{History, SeekFeatures};

/// Replays a fitted model causally, one seek at a time.
#[derive(Debug, Clone)]
pub struct Predictor {
    history: History,
    states: Vec<Box<dyn TermState>>,
    coefficients: Vec<Vec<f64>>,
    n_covariates: usize,
}

impl Predictor {
    /// A predictor at the start of a log whose covariate columns are named `covariates` (the
    /// values passed to `step`/`peek` follow this order). Fails if a term's covariate is missing.
    pub fn new(model: &FittedModel, covariates: &[String]) -> Result<Self, ModelError> {
        let states = model
            .terms
            .iter()
            .map(|t| t.term.start(covariates))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            history: History::new(),
            states,
            coefficients: model.terms.iter().map(|t| t.coefficients.clone()).collect(),
            n_covariates: covariates.len(),
        })
    }

    /// The seek history so far.
    pub fn history(&self) -> &History {
        &self.history
    }

    fn evaluate(&self, f: &SeekFeatures, covariates: &[f64], contrib: &mut [f64]) -> f64 {
        let seek = Seek {
            features: f,
            covariates,
        };
        let mut stack = [0.0f64; 64];
        let mut heap = Vec::new();
        let mut total = 0.0;
        for (k, (state, coef)) in self.states.iter().zip(&self.coefficients).enumerate() {
            let buf: &mut [f64] = if coef.len() <= stack.len() {
                &mut stack[..coef.len()]
            } else {
                heap.resize(coef.len(), 0.0);
                &mut heap[..]
            };
            state.basis(&seek, buf);
            let c = buf.iter().zip(coef).map(|(b, c)| b * c).sum::<f64>() + state.offset(&seek);
            if let Some(slot) = contrib.get_mut(k) {
                *slot = c;
            }
            total += c;
        }
        total
    }

    /// Predicted bias (counts) if the next seek went to `target` at `time_s` with these covariate
    /// values; the state is unchanged. Missing covariate values count as 0.
    pub fn peek(&self, time_s: f64, target: f64, covariates: &[f64]) -> f64 {
        let f = self.history.peek(time_s, target);
        self.evaluate(&f, &self.pad(covariates), &mut [])
    }

    /// Records a seek to `target` at `time_s` and, if measured, its bias; returns the prediction
    /// made before the measurement was seen.
    pub fn step(&mut self, time_s: f64, target: f64, covariates: &[f64], bias: Option<f64>) -> f64 {
        self.step_detailed(time_s, target, covariates, bias, &mut [])
    }

    /// As [`Predictor::step`], also writing each term's contribution (counts) into `contrib`
    /// (one slot per term; a shorter slice receives only the first ones).
    pub fn step_detailed(
        &mut self,
        time_s: f64,
        target: f64,
        covariates: &[f64],
        bias: Option<f64>,
        contrib: &mut [f64],
    ) -> f64 {
        let cov = self.pad(covariates);
        let f = self.history.step(time_s, target);
        let pred = self.evaluate(&f, &cov, contrib);
        let seek = Seek {
            features: &f,
            covariates: &cov,
        };
        let residual = bias.map(|y| y - pred);
        for s in &mut self.states {
            s.update(&seek, residual);
        }
        pred
    }

    fn pad<'a>(&self, covariates: &'a [f64]) -> std::borrow::Cow<'a, [f64]> {
        if covariates.len() >= self.n_covariates {
            std::borrow::Cow::Borrowed(covariates)
        } else {
            let mut v = covariates.to_vec();
            v.resize(self.n_covariates, 0.0);
            std::borrow::Cow::Owned(v)
        }
    }
}

/// The bias a model predicts for one seek after a replayed log (what `settle --model` feeds to
/// the handoff).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NextPrediction {
    /// The target of the predicted seek, in the log's position unit (tracks).
    pub target: f64,
    /// The time of the predicted seek, s.
    pub time_s: f64,
    /// The predicted bias, counts.
    pub bias: f64,
    /// Rows replayed (with their measurements) before the prediction.
    pub rows_replayed: usize,
}

/// Replays `log` through `model` and predicts the bias of one more seek without using its
/// measurement: with `target = None`, the seek of the log's **last row** (the rows before it are
/// replayed with their measurements; the last row's own bias is not used); with
/// `Some(t)`, a seek to `t` right after the last row (at the last row's time).
pub fn predict_next(
    model: &FittedModel,
    log: &crate::log::Log,
    target: Option<f64>,
) -> Result<NextPrediction, ModelError> {
    model.check_log(log)?;
    let mut p = Predictor::new(model, &log.schema.covariates)?;
    let replay = match target {
        None => log.rows.len().saturating_sub(1),
        Some(_) => log.rows.len(),
    };
    for row in &log.rows[..replay] {
        p.step(row.time_s, row.track, &row.covariates, row.bias);
    }
    let Some(last) = log.rows.last() else {
        return Err(ModelError::EmptyLog {
            file: log.schema.file.clone(),
        });
    };
    let target = target.unwrap_or(last.track);
    Ok(NextPrediction {
        target,
        time_s: last.time_s,
        bias: p.peek(last.time_s, target, &last.covariates),
        rows_replayed: replay,
    })
}

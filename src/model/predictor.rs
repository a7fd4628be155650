//! The online predictor: feed it seeks and measurements one at a time; ask for the predicted
//! bias at any candidate next target without changing its state (what a seek scheduler asks).
//!
//! ```
//! # use biasctl::{FittedModel, Predictor};
//! # fn demo(model: &FittedModel) -> Result<(), biasctl::ModelError> {
//! let mut p = Predictor::new(model, &[])?;    // the log's covariate names (none here)
//! p.step(0.0, 100.0, &[], Some(12.0))?;       // seek to 100, measured 12 counts
//! let guess = p.peek(0.5, 180.0, &[])?;        // what would the bias be at 180?
//! assert_eq!(guess, p.step(0.5, 180.0, &[], None)?);
//! // One value per covariate name given to `new`, no more, no fewer:
//! assert!(p.peek(1.0, 200.0, &[25.0]).is_err());
//! # Ok(()) }
//! ```

use super::term::{Seek, TermState};
use super::{FittedModel, ModelError, RangeWarning};
use crate::history::{History, SeekFeatures};
use crate::log::{LogError, LogReader, Row};
use std::cell::RefCell;
use std::io::Read;

/// Uncrossed rest positions per side of the head the predictor holds without allocating
/// ([`crate::history::RestMemory`]); beyond it the stack grows (Rust) or drops its farthest
/// position (the C export, whose state struct holds this many).
pub(crate) const REST_CAPACITY: usize = 1024;

/// Replays a fitted model causally, one seek at a time.
///
/// [`Predictor::step`] and [`Predictor::peek`] allocate nothing (their buffers are sized in
/// [`Predictor::new`]) while at most `REST_CAPACITY` uncrossed rest positions per side are
/// remembered, so they can run in a real-time loop.
#[derive(Debug, Clone)]
pub struct Predictor {
    history: History,
    /// Index of the velocity column among the covariates when direction comes from it.
    velocity: Option<usize>,
    states: Vec<Box<dyn TermState>>,
    coefficients: Vec<Vec<f64>>,
    /// Scratch: one term's basis values, then the row's covariates.
    scratch: RefCell<(Vec<f64>, Vec<f64>)>,
}

impl Predictor {
    /// A predictor at the start of a log whose covariate columns are named `covariates` (the
    /// values passed to `step`/`peek` follow this order). Fails if a term's covariate is missing,
    /// naming the term and the column.
    pub fn new(model: &FittedModel, covariates: &[String]) -> Result<Self, ModelError> {
        let states = model
            .terms
            .iter()
            .map(|t| t.term.start(covariates))
            .collect::<Result<Vec<_>, _>>()?;
        let widest = model
            .terms
            .iter()
            .map(|t| t.coefficients.len())
            .max()
            .unwrap_or(0);
        let velocity = match &model.direction {
            crate::history::DirectionSource::Velocity { column } => Some(
                super::terms::covariate_position(covariates, column, "direction (--velocity-col)")?,
            ),
            _ => None,
        };
        let mut history = model.direction.history();
        history.reserve(REST_CAPACITY);
        Ok(Self {
            history,
            velocity,
            states,
            coefficients: model.terms.iter().map(|t| t.coefficients.clone()).collect(),
            scratch: RefCell::new((vec![0.0; widest], vec![0.0; covariates.len()])),
        })
    }

    /// The direction a row's velocity column gives, when direction comes from one.
    fn moved(&self, covariates: &[f64]) -> Option<i8> {
        self.velocity
            .map(|k| crate::history::DirectionSource::moved(covariates.get(k).copied()))
    }

    /// The seek history so far.
    pub fn history(&self) -> &History {
        &self.history
    }

    /// Refuses `covariates` unless it holds one value per covariate name given to
    /// [`Predictor::new`].
    fn check_count(&self, covariates: &[f64]) -> Result<(), ModelError> {
        let expected = self.scratch.borrow().1.len();
        if covariates.len() == expected {
            Ok(())
        } else {
            Err(ModelError::CovariateCount {
                expected,
                given: covariates.len(),
            })
        }
    }

    /// Copies `covariates` (one value per name, [`Predictor::check_count`]) into the scratch
    /// buffer and sums the terms' contributions (counts) for the seek `f`, writing each into
    /// `contrib`.
    fn evaluate(&self, f: &SeekFeatures, covariates: &[f64], contrib: &mut [f64]) -> f64 {
        let mut scratch = self.scratch.borrow_mut();
        let (basis, cov) = &mut *scratch;
        cov.copy_from_slice(covariates);
        let seek = Seek {
            features: f,
            covariates: cov,
        };
        let mut total = 0.0;
        for (k, (state, coef)) in self.states.iter().zip(&self.coefficients).enumerate() {
            let buf = &mut basis[..coef.len()];
            state.basis(&seek, buf);
            let c = buf.iter().zip(coef).map(|(b, c)| b * c).sum::<f64>() + state.offset(&seek);
            if let Some(slot) = contrib.get_mut(k) {
                *slot = c;
            }
            total += c;
        }
        total
    }

    /// Predicted bias (counts, or the log's bias unit) if the next seek went to `target`
    /// (tracks) at `time_s` (s) with these covariate values (one per name given to
    /// [`Predictor::new`], else [`ModelError::CovariateCount`]); the state is unchanged.
    pub fn peek(&self, time_s: f64, target: f64, covariates: &[f64]) -> Result<f64, ModelError> {
        self.check_count(covariates)?;
        let f = self
            .history
            .peek_moved(time_s, target, self.moved(covariates));
        Ok(self.evaluate(&f, covariates, &mut []))
    }

    /// Records a seek to `target` at `time_s` and, if measured, its bias; returns the prediction
    /// made before the measurement was seen (it depends on no bias of this row). Adaptive terms
    /// (`drift`) learn from measured rows only and hold their state over unmeasured ones.
    /// `covariates` holds one value per name given to [`Predictor::new`], else the seek is not
    /// recorded and the answer is [`ModelError::CovariateCount`].
    pub fn step(
        &mut self,
        time_s: f64,
        target: f64,
        covariates: &[f64],
        bias: Option<f64>,
    ) -> Result<f64, ModelError> {
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
    ) -> Result<f64, ModelError> {
        self.check_count(covariates)?;
        let f = self
            .history
            .step_moved(time_s, target, self.moved(covariates));
        let pred = self.evaluate(&f, covariates, contrib);
        let residual = bias.map(|y| y - pred);
        let scratch = self.scratch.borrow();
        let seek = Seek {
            features: &f,
            covariates: &scratch.1,
        };
        for s in &mut self.states {
            s.update(&seek, residual);
        }
        Ok(pred)
    }
}

/// What gives a seek's integrator start value from its predicted bias (`predict --handoff`):
/// [`crate::control::StartValues`] implements it for the settle-optimal start values.
pub trait IntegratorStart {
    /// The absolute integrator start value for a seek whose predicted bias is `bias`; `None`
    /// when none exists.
    fn integrator_start(&self, bias: f64) -> Option<f64>;
}

/// One row of a replayed plan or log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowPrediction {
    /// The causal prediction (counts, or the log's bias unit): from earlier rows and this
    /// row's seek, time and covariates, never from this row's bias.
    pub predicted: f64,
    /// measured − predicted, `None` where the row was not measured.
    pub residual: Option<f64>,
    /// The integrator start value for this seek ([`IntegratorStart::integrator_start`]), when
    /// start values were asked for and one settles.
    pub integrator_start: Option<f64>,
}

/// What a streamed replay saw ([`replay_stream`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplaySummary {
    /// Rows predicted.
    pub rows: u64,
    /// Rows with a measured bias (scored: they have a residual).
    pub scored: u64,
    /// Rows without a measured bias (only predicted).
    pub predicted_only: u64,
    /// Rows whose target lies outside the model's fitted position range, if any.
    pub outside_range: Option<RangeWarning>,
}

/// An error while streaming a replay: reading the log, applying the model, or the row sink.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReplayError {
    /// The log could not be read (names file, line and column).
    #[error(transparent)]
    Log(#[from] LogError),
    /// The model cannot be applied to this log (a missing covariate column, …).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The row sink failed (writing the output).
    #[error("writing the predictions: {0}")]
    Sink(#[source] std::io::Error),
}

/// Streams `reader` through `model` in constant memory: every row is predicted (measured or
/// not) and the history advances on every row; `sink` receives each row, its prediction and the
/// terms' contributions (model term order) as soon as the row is read. With `start`, each row
/// also gets its integrator start value from its predicted bias.
pub fn replay_stream<R: Read>(
    model: &FittedModel,
    reader: &mut LogReader<R>,
    start: Option<&dyn IntegratorStart>,
    mut sink: impl FnMut(&Row, &RowPrediction, &[f64]) -> std::io::Result<()>,
) -> Result<ReplaySummary, ReplayError> {
    let schema = reader.schema().clone();
    model.check_schema(&schema)?;
    let mut p = Predictor::new(model, &schema.covariates)?;
    // The covariates the model reads: an empty cell there is an error, elsewhere a missing
    // value.
    let used: Vec<usize> = model
        .covariates_read()
        .iter()
        .filter_map(|(_, c)| schema.covariate_index(c))
        .collect();
    let mut contrib = vec![0.0; model.terms.len()];
    let mut summary = ReplaySummary {
        rows: 0,
        scored: 0,
        predicted_only: 0,
        outside_range: None,
    };
    let fitted = model.fit.position_range;
    let mut outside: Option<RangeWarning> = None;
    reader.try_for_each_row(|row| -> Result<(), ReplayError> {
        schema.require_covariates(row, &used)?;
        let predicted = p.step_detailed(
            row.time_s,
            row.track,
            &row.covariates,
            row.bias,
            &mut contrib,
        )?;
        let out = RowPrediction {
            predicted,
            residual: row.bias.map(|y| y - predicted),
            integrator_start: start.and_then(|s| s.integrator_start(predicted)),
        };
        summary.rows += 1;
        if row.bias.is_some() {
            summary.scored += 1;
        } else {
            summary.predicted_only += 1;
        }
        if let Some([lo, hi]) = fitted
            && (row.track < lo || row.track > hi)
        {
            let w = outside.get_or_insert(RangeWarning {
                outside: 0,
                total: 0,
                fitted: [lo, hi],
                seen: [row.track, row.track],
            });
            w.outside += 1;
            w.seen = [w.seen[0].min(row.track), w.seen[1].max(row.track)];
        }
        sink(row, &out, &contrib).map_err(ReplayError::Sink)
    })?;
    summary.outside_range = outside.map(|mut w| {
        w.total = summary.rows as usize;
        w
    });
    Ok(summary)
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
/// `Some(t)`, a seek to `t` right after the last row (at the last row's time); `t` must be a
/// position a log can hold (finite, within ±1e15), else [`ModelError::BadTarget`].
pub fn predict_next(
    model: &FittedModel,
    log: &crate::log::Log,
    target: Option<f64>,
) -> Result<NextPrediction, ModelError> {
    if let Some(t) = target
        && !(t.is_finite() && t.abs() <= crate::log::MAX_ABS_VALUE)
    {
        return Err(ModelError::BadTarget { target: t });
    }
    model.check_log(log)?;
    let mut p = Predictor::new(model, &log.schema.covariates)?;
    let replay = match target {
        None => log.len().saturating_sub(1),
        Some(_) => log.len(),
    };
    let mut cov = Vec::new();
    for row in log.rows().take(replay) {
        p.step(
            row.time_s,
            row.track,
            row.covariates.gather(&mut cov),
            row.bias,
        )?;
    }
    let Some(last) = log.last() else {
        return Err(ModelError::EmptyLog {
            file: log.schema.file.clone(),
        });
    };
    let target = target.unwrap_or(last.track);
    Ok(NextPrediction {
        target,
        time_s: last.time_s,
        bias: p.peek(last.time_s, target, last.covariates.gather(&mut cov))?,
        rows_replayed: replay,
    })
}

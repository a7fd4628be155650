//! The steps both runs take: progress counting, fitting and scoring a named model, and discover
//! from the report's starting model.

use super::error::{StoryError, error_chain};
use super::options::{Progress, StoryOptions, diagnose_config};
use super::runs::{ScoredModel, Step};
use crate::fit::{CheckedFitOptions, fit};
use crate::log::Log;
use crate::model::{FittedModel, ModelSpec, preset};
use crate::score::score_with_units;
use crate::select::{CheckedVerifyConfig, DiscoverConfig, Discovery, discover};

/// The ladder's terms, added one at a time.
pub(crate) const LADDER_TERMS: [&str; 5] = preset::CALIBRATION_TERMS;

/// The model [`discover`] starts from in a report: position-direction, the industry practice
/// the report's diagnosis also starts from.
pub(crate) const DISCOVER_START: &str = preset::POSITION_DIRECTION;

/// Counts [`Progress`] steps for a progress callback.
pub(crate) struct Steps<'a> {
    done: usize,
    total: usize,
    cb: &'a mut dyn FnMut(Progress<'_>),
}

impl<'a> Steps<'a> {
    /// A counter of `total` steps reporting to `cb`.
    pub(crate) fn new(total: usize, cb: &'a mut dyn FnMut(Progress<'_>)) -> Self {
        Steps { done: 0, total, cb }
    }
    /// Reports that `step` starts.
    pub(crate) fn start(&mut self, step: &str) {
        (self.cb)(Progress {
            step,
            done: self.done,
            total: self.total,
        });
        self.done += 1;
    }
    /// Reports that every step is done.
    pub(crate) fn finish(&mut self) {
        (self.cb)(Progress {
            step: "done",
            done: self.total,
            total: self.total,
        });
    }
}

fn fit_named(spec: &str, label: &str, log: &Log) -> Result<FittedModel, StoryError> {
    let spec = ModelSpec::parse(spec)?;
    fit(&spec, log, &CheckedFitOptions::default()).map_err(|e| StoryError::Fit {
        model: label.to_string(),
        file: log.schema.file.clone(),
        source: Box::new(e),
    })
}

/// Fits `terms` on `train`, replays it over `test` and scores the replay in `test`'s units.
pub(super) fn fit_and_score(
    label: &str,
    terms: &str,
    train: &Log,
    test: &Log,
) -> Result<ScoredModel, StoryError> {
    let model = fit_named(terms, label, train)?;
    let prediction = model.predict_log(test)?;
    let score = score_with_units(
        &prediction.residual,
        &prediction.positions,
        &test.schema.units,
    )?;
    Ok(ScoredModel {
        label: label.to_string(),
        trained_on: train.schema.file.clone(),
        scored_on: test.schema.file.clone(),
        model,
        prediction,
        score,
    })
}
/// [`discover`] from [`DISCOVER_START`] on `train`, scored on `test`, with the report's
/// diagnosis settings.
pub(super) fn discover_run(train: &Log, test: &Log, opts: &StoryOptions) -> Step<Discovery> {
    let config = DiscoverConfig {
        diagnose: diagnose_config(opts).map_err(|e| error_chain(&e))?,
        verify: CheckedVerifyConfig::default(),
        max_steps: DiscoverConfig::default().max_steps,
    }
    .check()
    .map_err(|e| error_chain(&e))?;
    let start = ModelSpec::parse(DISCOVER_START).map_err(|e| error_chain(&e))?;
    discover(&start, train, Some(test), &config)
        .map(|(d, _)| d)
        .map_err(|e| error_chain(&e))
}

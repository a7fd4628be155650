//! Diagnosis of a fitted model on a log: the glue between [`crate::model`] and the
//! model-independent engine of this module.

use super::{CheckedDiagnoseConfig, DiagnoseError, Diagnosis, FeatureTable, diagnose};
use crate::field::Field;
use crate::fit::FitError;
use crate::log::Log;
use crate::model::{FittedModel, ModelError, ModelSpec, Prediction, SpecError};

/// An error diagnosing a model or building a ladder: which stage failed and why.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelDiagnosisError {
    /// The model could not be replayed over the log (for example different column names).
    #[error("replaying the model over {file}")]
    Replay {
        /// The log file.
        file: String,
        /// The model error.
        #[source]
        source: ModelError,
    },
    /// A ladder step's term list is not valid.
    #[error("ladder step {step} (`{terms}`)")]
    Spec {
        /// Step number as in the ladder table (0: the first term alone).
        step: usize,
        /// The step's term list.
        terms: String,
        /// The parse error.
        #[source]
        source: SpecError,
    },
    /// A ladder step could not be fitted on the training log.
    #[error("fitting ladder step {step} (`{terms}`) on {file}")]
    Fit {
        /// Step number as in the ladder table (0: the first term alone).
        step: usize,
        /// The step's term list.
        terms: String,
        /// The training log.
        file: String,
        /// The fit error.
        #[source]
        source: Box<FitError>,
    },
    /// The diagnosis engine rejected the residuals or its settings.
    #[error(transparent)]
    Diagnose(#[from] DiagnoseError),
    /// A ladder's term list has an empty entry (`poly2,,seek`) or no entry at all.
    #[error(
        "{field}: term list `{list}`: term {index} is empty; give a comma-separated list such as poly2,direction,seek"
    )]
    EmptyTerm {
        /// The setting ([`Field::LadderTerms`]).
        field: Field,
        /// The list as given.
        list: String,
        /// 1-based position of the empty entry.
        index: usize,
    },
    /// A ladder step left fewer than two measured test rows, so no std exists.
    #[error("ladder step {step}: fewer than two measured rows in {file}")]
    TooFewTestRows {
        /// Step number as in the ladder table (0: the first term alone).
        step: usize,
        /// The test log.
        file: String,
    },
}

/// The term names of a fitted model, as the diagnosis engine's `existing_terms` expects them.
pub(super) fn model_terms(model: &FittedModel) -> Vec<String> {
    model.terms.iter().map(|t| t.term.name()).collect()
}

/// Replays `model` causally over `log`, and diagnoses its residuals against every candidate
/// feature of the log's seek history and every covariate column. The model's own terms are
/// added to `config.existing_terms`, so nothing the model already has is suggested.
///
/// When the model has adaptive terms (`drift`), it also reports what they absorbed
/// (`super::absorbed`) and warns about a forgetting factor much faster than a slow offset
/// needs (`super::rate_warnings`).
pub fn diagnose_model(
    model: &FittedModel,
    log: &Log,
    config: &CheckedDiagnoseConfig,
) -> Result<Diagnosis, ModelDiagnosisError> {
    let mut prediction = replay_model(model, log)?;
    // Only the residual and the adaptive terms' contributions are read below: the rest of the
    // replay is freed before the diagnosis's peak of memory.
    super::absorbed::keep_needed(model, &mut prediction);
    let table = model_table(model, log);
    let mut d = diagnose_residual(model, &table, &prediction.residual, config)?;
    let mut config = config.clone();
    for t in model_terms(model) {
        config.add_existing_term(t);
    }
    // The shares of the residual alone come from its own diagnosis, `d`.
    let absorbed = super::absorbed(model, &table, &mut prediction, &config, &d.features)?;
    d.absorbed = absorbed;
    d.warnings = super::rate_warnings(model);
    d.summary = super::text::extend_summary(&d);
    Ok(d)
}

/// The feature table of `log` with direction read as `model` reads it
/// ([`FittedModel::direction`]); a velocity column the log lacks (which the model's replay has
/// already refused) falls back to raw steps.
pub(crate) fn model_table(model: &FittedModel, log: &Log) -> FeatureTable {
    crate::history::replay_with(log, &model.direction).map_or_else(
        |_| FeatureTable::from_log(log),
        |r| FeatureTable::from_replay(log, r),
    )
}

/// The model's spec as typed terms (a user's own `TermSpec` included), the base every
/// suggested [`crate::model::ModelEdit`] is applied to.
pub fn model_spec(model: &FittedModel) -> Result<ModelSpec, ModelDiagnosisError> {
    Ok(model.spec.clone())
}

/// [`diagnose_model`] for a caller that has already replayed `model` over the log: `table` is
/// [`FeatureTable::from_log`] of that log and `residual` the replay's residual (counts, one per
/// measured row), so neither is computed again.
pub fn diagnose_residual(
    model: &FittedModel,
    table: &FeatureTable,
    residual: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<Diagnosis, ModelDiagnosisError> {
    let mut config = config.clone();
    for t in model_terms(model) {
        config.add_existing_term(t);
    }
    Ok(diagnose(table, residual, &config)?)
}

/// Replays `model` causally over `log`; a failure is [`ModelDiagnosisError::Replay`] naming
/// the log.
pub fn replay_model(model: &FittedModel, log: &Log) -> Result<Prediction, ModelDiagnosisError> {
    model
        .predict_log(log)
        .map_err(|source| ModelDiagnosisError::Replay {
            file: log.schema.file.clone(),
            source,
        })
}

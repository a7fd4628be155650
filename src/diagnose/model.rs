//! Diagnosis of a fitted model on a log, and the refitting ladder: the glue between
//! [`crate::model`]/[`crate::fit`] and the model-independent engine of this module.

use super::{
    CheckedDiagnoseConfig, DiagnoseError, Diagnosis, FeatureTable, Ladder, LadderInput, diagnose,
    ladder,
};
use crate::field::Field;
use crate::fit::{CheckedFitOptions, FitError, fit};
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
    d.absorbed = super::absorbed(model, &table, &mut prediction, &config)?;
    d.warnings = super::rate_warnings(model);
    d.summary = super::report::extend_summary(&d);
    Ok(d)
}

/// The feature table of `log` with direction read as `model` reads it
/// ([`FittedModel::direction`]); a velocity column the log lacks (which the model's replay has
/// already refused) falls back to raw steps.
fn model_table(model: &FittedModel, log: &Log) -> FeatureTable {
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

/// [`diagnose_model`], then the leading suggestions — the top flagged features' terms and
/// what adaptive terms absorbed — applied as typed edits, refitted on `log` and scored out of
/// sample on folds of consecutive seeks (`super::verify`); the result is in
/// [`Diagnosis::verification`], best verified gain first, and leads the summary.
pub fn diagnose_verified(
    model: &FittedModel,
    log: &Log,
    config: &CheckedDiagnoseConfig,
    verify_config: &super::CheckedVerifyConfig,
) -> Result<Diagnosis, ModelDiagnosisError> {
    let mut d = diagnose_model(model, log, config)?;
    let spec = model_spec(model)?;
    let cands = super::candidates(&d, verify_config.candidates);
    // The second round's re-screen: the residual the best edit leaves against the features
    // it names (the table made again, only those columns and `direction` kept: no table is
    // held through the refits).
    let rescreen = |r: &[f64], with: &ModelSpec, keep: &dyn Fn(&str) -> bool| {
        // The direction column always: the direction-signed analysis reads it.
        let direction = super::FeatureOrigin::BuiltIn(crate::history::Feature::Direction);
        let table = model_table(model, log)
            .without(|c| c.origin != direction && (super::is_time(c.origin) || !keep(&c.name)));
        let mut config = config.clone();
        for t in &with.terms {
            config.add_existing_term(t.name());
        }
        // Only the flags are read (`rescreen_candidates`): no pair screen, no summary.
        (!table.columns().is_empty())
            .then(|| super::flagged_features(&table, r, &config).ok())
            .flatten()
    };
    let v = super::verify_two_rounds(
        &d,
        &spec,
        log,
        &cands,
        config.min_effect,
        verify_config,
        Some(&rescreen),
    )?;
    promote_verified(&mut d, &v);
    d.verification = Some(v);
    d.summary = super::report::extend_summary(&d);
    Ok(d)
}

/// Ranks by verified gain (issue #10, item 4): the feature whose edit is the best verified
/// one moves to the front of [`Diagnosis::features`] and is flagged — also when the
/// one-dimensional screen left it unflagged, since its refit cleared the stricter bar of
/// [`super::STRICT_EXTRA_Z`] — with a note saying so. An edit that came from a pair or
/// from what an adaptive term absorbed names no single feature and changes nothing here.
fn promote_verified(d: &mut Diagnosis, v: &super::Verification) {
    let Some(best) = v.best() else { return };
    let Some(i) = d.features.iter().position(|f| f.name == best.feature) else {
        return;
    };
    let mut f = d.features.remove(i);
    if !f.flagged {
        f.flagged = true;
        let note = format!(
            "flagged by its verified refit: `{}` gains {:.1} % out of sample (z = {:.1}), \
             although the one-dimensional screen alone did not flag it",
            best.edit,
            100.0 * best.gain,
            best.z
        );
        f.note = Some(match f.note.take() {
            Some(n) => format!("{note}; {n}"),
            None => note,
        });
    }
    d.features.insert(0, f);
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

/// Checks a ladder's comma-separated term list (`poly2,direction,seek`) into the
/// [`LadderTerms`] that [`ladder_fit`] requires: trimmed, in order. An empty entry, or an empty
/// list, is an error naming [`Field::LadderTerms`] and the entry's position.
pub fn ladder_terms(list: &str) -> Result<LadderTerms, ModelDiagnosisError> {
    let terms: Vec<String> = list.split(',').map(|t| t.trim().to_string()).collect();
    match terms.iter().position(String::is_empty) {
        Some(i) => Err(ModelDiagnosisError::EmptyTerm {
            field: Field::LadderTerms,
            list: list.to_string(),
            index: i + 1,
        }),
        None => Ok(LadderTerms(terms)),
    }
}

/// A ladder's term list that passed [`ladder_terms`] (no empty entry), in the order the terms are
/// added; read it through `Deref`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LadderTerms(Vec<String>);

impl std::ops::Deref for LadderTerms {
    type Target = [String];
    fn deref(&self) -> &[String] {
        &self.0
    }
}

/// The ladder: for k = 1..=terms.len(), fits the first k terms on `train`, replays on `test`
/// and records the test error std (counts); reductions are relative to the first step. The
/// steps run in parallel (`crate::numeric::parallel`); the result does not depend on the
/// thread count.
pub fn ladder_fit(
    train: &Log,
    test: &Log,
    terms: &LadderTerms,
    opts: &CheckedFitOptions,
) -> Result<Ladder, ModelDiagnosisError> {
    use rayon::prelude::*;
    // Each step is fitted and scored on its own (nothing shared but the logs): in parallel on
    // the process's pool, collected in step order, so the ladder and the error of the first
    // failing step are the same for any thread count.
    let steps: Vec<Result<LadderInput, ModelDiagnosisError>> = (1..=terms.len())
        .into_par_iter()
        .map(|k| -> Result<LadderInput, ModelDiagnosisError> {
            let list = terms[..k].join(",");
            let step = k - 1; // numbered as in the ladder table: step 0 is the first term alone
            let spec = ModelSpec::parse(&list).map_err(|source| ModelDiagnosisError::Spec {
                step,
                terms: list.clone(),
                source,
            })?;
            let model = fit(&spec, train, opts).map_err(|source| ModelDiagnosisError::Fit {
                step,
                terms: list.clone(),
                file: train.schema.file.clone(),
                source: Box::new(source),
            })?;
            let prediction = replay_model(&model, test)?;
            let std = crate::numeric::stats::std_dev(&prediction.residual).ok_or_else(|| {
                ModelDiagnosisError::TooFewTestRows {
                    step,
                    file: test.schema.file.clone(),
                }
            })?;
            let free_run_std = if model.adaptive() {
                model
                    .predict_log_with(test, crate::model::Feedback::Never)
                    .ok()
                    .and_then(|p| crate::numeric::stats::std_dev(&p.residual))
            } else {
                None
            };
            let mut warnings: Vec<String> =
                model.warnings.iter().map(|w| format!("fit: {w}")).collect();
            let mean = crate::numeric::stats::mean(&prediction.residual).unwrap_or(0.0);
            if mean.abs() > crate::score::MEAN_WARNING_RATIO * std {
                warnings.push(format!(
                    "test mean error {mean:.4e} is {:.2}× the error std {std:.4e}: the model is \
                     offset on the test log",
                    mean.abs() / std.max(f64::MIN_POSITIVE)
                ));
            }
            Ok(LadderInput {
                terms: terms[..k].to_vec(),
                std,
                free_run_std,
                warnings,
            })
        })
        .collect();
    let inputs = steps.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(ladder(&inputs)?)
}

/// One step of a [`suggestion_path`]: the feature the residual followed most, the term added
/// for it, and the residual std of the causal replay before and after refitting with it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PathStep {
    /// The top flagged feature before this step.
    pub feature: String,
    /// The term suggested for it and added to the model.
    pub term: String,
    /// Its out-of-sample explained fraction of the residual variance before the step.
    pub explained: f64,
    /// The model's term list after the step.
    pub spec: String,
    /// Residual std before the step (counts, causal replay over the log).
    pub std_before: f64,
    /// Residual std after refitting with the term on the same log (in-sample for the model's
    /// parameters; the diagnosis itself is cross-validated).
    pub std_after: f64,
}

/// Follows the diagnosis's advice automatically, up to `steps` times: take the strongest flagged
/// feature's suggested term, refit the model with it on `log`, diagnose again. Stops early when
/// nothing is flagged or the top feature has no suggested term. This is the loop an engineer runs
/// by hand ("add the suggested term, watch the error fall"), and it separates confounded
/// candidates the way a refit does: a feature that only looked strong through the one before it
/// drops out once that one is in the model.
pub fn suggestion_path(
    model: &FittedModel,
    log: &Log,
    config: &CheckedDiagnoseConfig,
    steps: usize,
    opts: &CheckedFitOptions,
) -> Result<Vec<PathStep>, ModelDiagnosisError> {
    if steps == 0 {
        return Ok(Vec::new());
    }
    let first = diagnose_model(model, log, config)?;
    suggestion_path_from(model, log, first, config, steps, opts)
}

/// [`suggestion_path`] for a caller that already has `first`, the result of
/// [`diagnose_model`]`(model, log, config)`, so the model is not diagnosed twice.
pub fn suggestion_path_from(
    model: &FittedModel,
    log: &Log,
    first: Diagnosis,
    config: &CheckedDiagnoseConfig,
    steps: usize,
    opts: &CheckedFitOptions,
) -> Result<Vec<PathStep>, ModelDiagnosisError> {
    let mut path = Vec::new();
    let mut table = None;
    let mut d = first;
    let mut spec = model_spec(model)?;
    for step in 1..=steps {
        let Some(top) = d.features.first().filter(|f| f.flagged) else {
            break;
        };
        let Some(term) = top.suggested_term.clone() else {
            break;
        };
        let spacing = (top.name == "position")
            .then(|| super::table_spacing(top))
            .flatten();
        let edit = super::edit_for(&term, &spec, spacing).and_then(|e| spec.apply(&e));
        let next_spec = edit.map_err(|source| ModelDiagnosisError::Spec {
            step,
            terms: format!("{spec} + {term}"),
            source,
        })?;
        let spec_text = next_spec.to_string();
        let next = fit(&next_spec, log, opts).map_err(|source| ModelDiagnosisError::Fit {
            step,
            terms: spec_text.clone(),
            file: log.schema.file.clone(),
            source: Box::new(source),
        })?;
        spec = next_spec;
        let after = replay_model(&next, log)?;
        path.push(PathStep {
            feature: top.name.clone(),
            term,
            explained: top.explained,
            spec: spec_text,
            std_before: d.residual_std,
            std_after: crate::numeric::stats::std_dev(&after.residual).unwrap_or(0.0),
        });
        if step < steps {
            let table = table.get_or_insert_with(|| model_table(&next, log));
            d = diagnose_residual(&next, table, &after.residual, config)?;
        }
    }
    Ok(path)
}

//! The suggestion path: follow the diagnosis's advice automatically, one refit per step.

use crate::diagnose::{
    CheckedDiagnoseConfig, Diagnosis, ModelDiagnosisError, diagnose_model, diagnose_residual,
    model_spec, model_table, replay_model,
};
use crate::fit::{CheckedFitOptions, fit};
use crate::log::Log;
use crate::model::FittedModel;

use super::{edit_for, table_spacing};

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
            .then(|| table_spacing(top))
            .flatten();
        let edit = edit_for(&term, &spec, spacing).and_then(|e| spec.apply(&e));
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

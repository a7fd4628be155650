//! `discover`: the whole loop run by the tool — fit, diagnose, apply the best verified edit,
//! repeat — until nothing is flagged or the verified gain is below what noise allows.
//!
//! Each step fits the current spec on the training log, diagnoses its causal residual there
//! ([`super::diagnose_model`], adaptive terms' absorption included), verifies the leading
//! suggestions by refitting on folds of consecutive seeks ([`super::verify`]) and applies the
//! edit with the largest verified gain. The error reported before and after each step is the
//! test log's causal error std when a test log is given, else the out-of-sample (fold) std of
//! the verification.

use std::fmt;

use serde::{Deserialize, Serialize};

use super::model::{ModelDiagnosisError, diagnose_model, replay_model};
use super::{CheckedDiagnoseConfig, VerifyConfig, candidates, verify};
use crate::fit::{FitError, fit};
use crate::log::Log;
use crate::model::{FittedModel, ModelSpec};

/// Settings of [`discover`].
#[derive(Debug, Clone, PartialEq)]
pub struct DiscoverConfig {
    /// The diagnosis at each step (checked by [`super::DiagnoseConfig::check`]).
    pub diagnose: CheckedDiagnoseConfig,
    /// The verification refits at each step (their fit options fit every model).
    pub verify: VerifyConfig,
    /// Most edits applied, 1..=30 (default 8).
    pub max_steps: usize,
}

impl Default for DiscoverConfig {
    fn default() -> Self {
        Self {
            diagnose: CheckedDiagnoseConfig::default(),
            verify: VerifyConfig::default(),
            max_steps: 8,
        }
    }
}

/// An error of [`discover`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiscoverError {
    /// A setting is out of range.
    #[error("invalid discover setting `{field}`: {message}")]
    InvalidConfig {
        /// The setting.
        field: &'static str,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// The starting model could not be fitted on the training log.
    #[error("fitting the starting model `{terms}` on {file}")]
    Start {
        /// The starting terms.
        terms: String,
        /// The training log.
        file: String,
        /// The fit error.
        #[source]
        source: Box<FitError>,
    },
    /// A diagnosis, verification or refit failed.
    #[error(transparent)]
    Diagnosis(#[from] ModelDiagnosisError),
}

/// One rung of the ladder `discover` climbed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiscoverStep {
    /// The edit applied (`add col:temp_c`, `replace poly2 by table:25`).
    pub edit: String,
    /// The feature that led to it (or `drift → temp_c` for an absorbed effect).
    pub feature: String,
    /// Why: the feature's shape and share, and the verified gain.
    pub reason: String,
    /// Error std before the edit (test log if given, else out-of-sample folds; bias unit).
    pub std_before: f64,
    /// Error std after the edit (same basis).
    pub std_after: f64,
    /// The model's terms after the edit.
    pub terms: String,
}

/// What [`discover`] did: the ladder, the final terms and why it stopped. Serialises to
/// `{"steps": [{"edit", "feature", "reason", "std_before", "std_after", "terms"}, …],
/// "final_terms": […], "stopped_because": "…", "basis": "…", "unit": "…"}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Discovery {
    /// The edits applied, in order.
    pub steps: Vec<DiscoverStep>,
    /// The final model's terms.
    pub final_terms: Vec<String>,
    /// Why the loop stopped.
    pub stopped_because: String,
    /// What `std_before`/`std_after` are measured on (`test log …` or `out-of-sample folds …`).
    pub basis: String,
    /// The bias unit of every std.
    pub unit: String,
    /// Error std of the starting model (same basis).
    pub start_std: f64,
}

impl Discovery {
    /// The discovery as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

impl fmt::Display for Discovery {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "discover: error std on {} ({}), starting at {:.4}",
            self.basis, self.unit, self.start_std
        )?;
        for (i, s) in self.steps.iter().enumerate() {
            writeln!(
                f,
                "  {}. {} ({}): {:.4} → {:.4} {}",
                i + 1,
                s.edit,
                s.feature,
                s.std_before,
                s.std_after,
                self.unit
            )?;
            writeln!(f, "     why: {}", s.reason)?;
        }
        writeln!(f, "final terms: {}", self.final_terms.join(","))?;
        writeln!(f, "stopped because {}", self.stopped_because)
    }
}

/// Runs the loop on `train` from `start` (see the module docs); `test`, if given, scores every
/// rung. Returns the ladder and the final model fitted on `train`.
pub fn discover(
    start: &ModelSpec,
    train: &Log,
    test: Option<&Log>,
    config: &DiscoverConfig,
) -> Result<(Discovery, FittedModel), DiscoverError> {
    if !(1..=30).contains(&config.max_steps) {
        return Err(DiscoverError::InvalidConfig {
            field: "max_steps",
            message: format!("{} is not in 1..=30", config.max_steps),
        });
    }
    config
        .verify
        .validate()
        .map_err(ModelDiagnosisError::from)?;
    let opts = &config.verify.fit;
    let mut spec = start.clone();
    let mut model = fit(&spec, train, opts).map_err(|source| DiscoverError::Start {
        terms: spec.to_string(),
        file: train.schema.file.clone(),
        source: Box::new(source),
    })?;
    let test_std = |m: &FittedModel| -> Result<Option<f64>, ModelDiagnosisError> {
        match test {
            Some(t) => Ok(crate::numeric::stats::std_dev(
                &replay_model(m, t)?.residual,
            )),
            None => Ok(None),
        }
    };
    let basis = match test {
        Some(t) => format!("test log {}", t.schema.file),
        None => format!(
            "out-of-sample folds of {} ({} folds of consecutive seeks)",
            train.schema.file, config.verify.folds
        ),
    };
    let mut out = Discovery {
        steps: Vec::new(),
        final_terms: Vec::new(),
        stopped_because: String::new(),
        basis,
        unit: train.schema.units.bias.clone(),
        start_std: 0.0,
    };
    let mut current_test = test_std(&model)?;
    let mut first = true;
    for step in 0..=config.max_steps {
        let d = diagnose_model(&model, train, &config.diagnose)?;
        let cands = candidates(&d, config.verify.candidates);
        if cands.is_empty() {
            if first {
                out.start_std = current_test.unwrap_or(d.residual_std);
            }
            out.stopped_because = "nothing is flagged: no candidate feature explains a practical \
                                   share of the residual beyond noise"
                .to_string();
            break;
        }
        let v = verify(
            &spec,
            train,
            &cands,
            d.null_block_len,
            config.diagnose.min_effect,
            &config.verify,
        )?;
        if first {
            out.start_std = current_test.unwrap_or(v.std_before);
            first = false;
        }
        let Some(best) = v.best().cloned() else {
            out.stopped_because = match v.edits.first() {
                Some(e) => format!(
                    "the best verified edit, `{}` ({}), gains {:.1} % of the error variance \
                     out of sample (z = {:.1}): below what noise allows",
                    e.edit,
                    e.feature,
                    100.0 * e.gain,
                    e.z
                ),
                None => v
                    .not_run
                    .clone()
                    .unwrap_or_else(|| "no suggested edit could be fitted".to_string()),
            };
            break;
        };
        if step == config.max_steps {
            out.stopped_because = format!(
                "the step limit ({}) was reached; `{}` would still gain {:.1} %",
                config.max_steps,
                best.edit,
                100.0 * best.gain
            );
            break;
        }
        let Some(edit) = best.model_edit.clone() else {
            break;
        };
        let next_spec = spec
            .apply(&edit)
            .map_err(|source| ModelDiagnosisError::Spec {
                step: step + 1,
                terms: best.terms.clone(),
                source,
            })?;
        let next = fit(&next_spec, train, opts).map_err(|source| ModelDiagnosisError::Fit {
            step: step + 1,
            terms: best.terms.clone(),
            file: train.schema.file.clone(),
            source: Box::new(source),
        })?;
        let next_test = test_std(&next)?;
        let shape = d
            .feature(&best.feature)
            .map(|f| {
                format!(
                    "the residual{} {} ({:.1} % explained out of sample); ",
                    if f.by_direction { " × direction" } else { "" },
                    f.shape.describe(&f.name, f.shape_at),
                    100.0 * f.explained
                )
            })
            .unwrap_or_default();
        out.steps.push(DiscoverStep {
            edit: best.edit.clone(),
            feature: best.feature.clone(),
            reason: format!(
                "{shape}refitted, the edit gains {:.1} % of the error variance on held-out \
                 seeks (z = {:.1})",
                100.0 * best.gain,
                best.z
            ),
            std_before: current_test.unwrap_or(best.std_before),
            std_after: next_test.unwrap_or(best.std_after),
            terms: next_spec.to_string(),
        });
        spec = next_spec;
        model = next;
        current_test = next_test;
    }
    out.final_terms = spec.terms.iter().map(|t| t.name()).collect();
    Ok((out, model))
}

//! What adaptive terms absorbed. A term that re-estimates itself from past residuals (`drift`)
//! chases any slow effect the model lacks — a coil temperature cycling over seconds, a humidity
//! programme — so the residual looks white and the covariate explains nothing of it, while the
//! physics sits in the adaptive term's contribution. So for every adaptive term the diagnosis is
//! repeated on **residual + that term's contribution** against every candidate except the time
//! features (which trivially follow any adaptive offset), and a candidate that explains a
//! practical share of it becomes advice: "drift is following `temp_c`: add `col:temp_c`".

use serde::{Deserialize, Serialize};

use super::{CheckedDiagnoseConfig, DiagnoseError, FeatureTable, diagnose};
use crate::model::{FittedModel, Prediction};

/// A drift forgetting factor above this (memory shorter than about 10 measurements) is much
/// faster than a slow offset of the driver electronics needs (minutes: a few hundredths at a
/// few seeks per second) and is reported as suspicious.
pub(crate) const FAST_FORGETTING: f64 = 0.1;

/// An effect an adaptive term absorbed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Absorption {
    /// The adaptive term (`drift`).
    pub term: String,
    /// The candidate its contribution follows.
    pub feature: String,
    /// Out-of-sample fraction of (residual + the term's contribution) the feature explains.
    pub explained_with_term: f64,
    /// Out-of-sample fraction of the residual alone it explains (small: the term hid it).
    pub explained_residual: f64,
    /// The term that carries the effect instead (`col:temp_c`), if any.
    pub suggested_term: Option<String>,
    /// Alternatives (as for a feature).
    #[serde(default)]
    pub alternatives: Vec<String>,
}

/// Whether a fitted term is adaptive: it has no linear parameters but contributes (its state
/// follows past residuals, as `drift` does).
fn adaptive(contribution: &[f64], param_names: &[String]) -> bool {
    param_names.is_empty() && contribution.iter().any(|v| v.abs() > 0.0)
}

/// Warnings about the adaptive terms' fitted rates: a forgetting factor above
/// [`FAST_FORGETTING`].
pub(crate) fn rate_warnings(model: &FittedModel) -> Vec<String> {
    model
        .params()
        .filter(|p| p.name.ends_with(".alpha") && p.value > FAST_FORGETTING)
        .map(|p| {
            format!(
                "the fitted forgetting factor {} = {:.3} (memory ≈ {:.0} measurements) is much \
                 faster than a slow offset needs (≤ {FAST_FORGETTING}): the adaptive term is \
                 probably following an effect the model lacks — see what it absorbed",
                p.name,
                p.value,
                1.0 / p.value
            )
        })
        .collect()
}

/// Frees what [`absorbed`] does not read of `prediction`: every vector but the residual and
/// the contributions of `model`'s adaptive terms (the others are left empty, which
/// [`absorbed`] skips as it skips a non-adaptive term).
pub(crate) fn keep_needed(model: &FittedModel, prediction: &mut Prediction) {
    prediction.rows = Vec::new();
    prediction.positions = Vec::new();
    prediction.measured = Vec::new();
    prediction.predicted = Vec::new();
    for (name, contribution) in prediction
        .term_names
        .iter()
        .zip(prediction.contributions.iter_mut())
    {
        let keep = model
            .terms
            .iter()
            .find(|f| f.term.name() == *name)
            .is_some_and(|term| adaptive(contribution, &term.term.param_names()));
        if !keep {
            *contribution = Vec::new();
        }
    }
}

/// For every adaptive term of `model`: diagnose residual + its contribution (replayed in
/// `prediction`, rows aligned with `table`) against every non-time candidate, and report the
/// flagged ones that explain at least `config.min_effect` of it and clearly more than of the
/// residual alone. The sum is made in place of the contribution (taken from `prediction`,
/// which keeps an empty vector there), so no third vector of the log's length is held.
pub(crate) fn absorbed(
    model: &FittedModel,
    table: &FeatureTable,
    prediction: &mut Prediction,
    config: &CheckedDiagnoseConfig,
) -> Result<Vec<Absorption>, DiagnoseError> {
    let mut out = Vec::new();
    let reduced = table.without(|c| super::is_time(c.origin));
    for (t, name) in prediction.term_names.iter().enumerate() {
        let Some(contribution) = prediction.contributions.get_mut(t) else {
            continue;
        };
        let Some(term) = model.terms.iter().find(|f| f.term.name() == *name) else {
            continue;
        };
        if !adaptive(contribution, &term.term.param_names()) {
            continue;
        }
        // residual + contribution (`c + r` is `r + c` bit for bit: IEEE addition commutes).
        let mut y = std::mem::take(contribution);
        y.iter_mut()
            .zip(&prediction.residual)
            .for_each(|(c, r)| *c += r);
        let with = diagnose(&reduced, &y, config)?;
        let plain = diagnose(&reduced, &prediction.residual, config)?;
        for f in with.features.iter().filter(|f| f.flagged) {
            let alone = plain.feature(&f.name).map_or(0.0, |p| p.explained);
            if f.explained >= config.min_effect && f.explained > 2.0 * alone {
                out.push(Absorption {
                    term: name.clone(),
                    feature: f.name.clone(),
                    explained_with_term: f.explained,
                    explained_residual: alone,
                    suggested_term: f.suggested_term.clone(),
                    alternatives: f.alternatives.clone(),
                });
            }
        }
    }
    Ok(out)
}

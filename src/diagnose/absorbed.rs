//! What adaptive terms absorbed. A term that re-estimates itself from past residuals (`drift`)
//! chases any slow effect the model lacks — a coil temperature cycling over seconds, a humidity
//! programme — so the residual looks white and the covariate explains nothing of it, while the
//! physics sits in the adaptive term's contribution. So for every adaptive term the diagnosis is
//! repeated on **residual + that term's contribution** against every candidate except the time
//! features (which trivially follow any adaptive offset), and a candidate that explains a
//! practical share of it becomes advice: "drift is following `temp_c`: add `col:temp_c`".
//!
//! ## Slow columns: the strongest one, on its own null
//! A slow column with a set point (nothing below it, a ramp above: a coolant valve opening, a
//! fan stage) that drift follows makes residual + drift slow too: its null block is a tenth of
//! a 1500-seek log, so the family-wise null has some eight blocks to permute and every slow
//! column (a warm-up, a random walk) matches some permutation — the column with the effect
//! explained 37–48 % of it on every family drive, at a family-wise p above 0.01 (up to 0.80)
//! on 5 of 12 logs. So a second rule ([`slow_column`]) takes the **strongest** non-time
//! candidate of that diagnosis when it is a logged column (or its lag), not flagged, and
//! explains at least `min_effect` of
//! residual + contribution and more than twice what it explains of the residual alone, at a
//! per-feature permutation p (the same block null) of at most [`SLOW_RAW_P`]. Its binned
//! smoother holds any shape (the advice is the shape's term, `bins:COL` for a ramp from a set
//! point), and the edit goes to the verification refit as every absorbed effect's does. On the
//! family drives without such an effect residual + drift holds no slow structure: the
//! strongest column explained 1.4 % at most (`min_effect` is 2 %; docs/diagnosis.md).

use serde::{Deserialize, Serialize};

use super::screen::{Reports, analyse, screen_analysed};
use super::{CheckedDiagnoseConfig, DiagnoseError, FeatureOrigin, FeatureReport, FeatureTable};
use crate::model::{FittedModel, Prediction};

/// A drift forgetting factor above this (memory shorter than about 10 measurements) is much
/// faster than a slow offset of the driver electronics needs (minutes: a few hundredths at a
/// few seeks per second) and is reported as suspicious.
pub(crate) const FAST_FORGETTING: f64 = 0.1;

/// Most per-feature permutation p-value of the slow-column rule ([`slow_column`]).
pub(crate) const SLOW_RAW_P: f64 = 0.01;

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
/// `residual_features`: the features of the diagnosis of `prediction.residual` against
/// `table` with `config` (what the residual alone explains).
pub(crate) fn absorbed(
    model: &FittedModel,
    table: &FeatureTable,
    prediction: &mut Prediction,
    config: &CheckedDiagnoseConfig,
    residual_features: &[FeatureReport],
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
        // Of the residual alone only the explained shares are read: a column's share does not
        // depend on the other columns of the table, so the diagnosis of the residual against
        // the whole table has them (the shares of a diagnosis against `reduced`, tested).
        let alone = |name: &str| {
            (residual_features.iter())
                .find(|p| p.name == name)
                .map_or(0.0, |p| p.explained)
        };
        let absorbs_share = |name: &str, e: f64| e >= config.min_effect && e > 2.0 * alone(name);
        let absorbs = |f: &FeatureReport| absorbs_share(&f.name, f.explained);
        // Every rule below keeps only features that absorb, which their explained shares
        // alone decide (a report's share is its column's analysed share, 0 for a skipped
        // column): when none does, the permutation test and the reports are not needed.
        let analysis = analyse(&reduced, &y, config)?;
        let any = (reduced.columns().iter())
            .zip(&analysis.analysed)
            .any(|(c, a)| absorbs_share(&c.name, a.as_ref().map_or(0.0, |a| a.explained)));
        if !any {
            continue;
        }
        // Only the flagged features and the strongest are read: the screen without the pair
        // screen, the residual's own statistics and the other features' reports (the same
        // reports as `diagnose`'s, in its order, and the same strongest; tested).
        let which = Reports::FlaggedAndStrongest;
        let with = screen_analysed(&reduced, &y, config, which, analysis).reports;
        let reported = with.iter().filter(|f| f.flagged && absorbs(f));
        let slow = slow_column(&with, &reduced).filter(|f| absorbs(f));
        for f in reported.chain(slow) {
            out.push(Absorption {
                term: name.clone(),
                feature: f.name.clone(),
                explained_with_term: f.explained,
                explained_residual: alone(&f.name),
                suggested_term: f.suggested_term.clone(),
                alternatives: with_binned_column(f),
            });
        }
    }
    Ok(out)
}

/// The alternatives of an absorbed effect: the feature's own, and for a lag of a column
/// (`temp@lag4.8s`) the binned column too (`bins:temp`): a lag short beside the column's own
/// course changes it little, and the binned curve holds a set point a lag's straight line
/// cannot (the verification keeps whichever refit gains most).
fn with_binned_column(f: &FeatureReport) -> Vec<String> {
    let mut alternatives = f.alternatives.clone();
    if let Some(column) = super::lagged_column(&f.name) {
        let binned = format!("{}:{column}", crate::model::terms::bins::HEAD);
        if !alternatives.contains(&binned) && f.suggested_term.as_ref() != Some(&binned) {
            alternatives.push(binned);
        }
    }
    alternatives
}

/// The slow-column rule (module docs): the feature of `with` (the diagnosis of residual + an
/// adaptive term's contribution against `table`) that explains most of it, when it is a
/// logged column or a lag of one, not flagged (a flagged one is reported by the family-wise
/// rule), and its per-feature permutation p-value is at most [`SLOW_RAW_P`].
pub(super) fn slow_column<'a>(
    with: &'a [FeatureReport],
    table: &FeatureTable,
) -> Option<&'a FeatureReport> {
    let top = with
        .iter()
        .max_by(|a, b| a.explained.total_cmp(&b.explained))?;
    let logged = table
        .column(&top.name)
        .is_some_and(|c| matches!(c.origin, FeatureOrigin::Covariate | FeatureOrigin::Lagged));
    (logged && !top.flagged && top.p_value_raw <= SLOW_RAW_P).then_some(top)
}

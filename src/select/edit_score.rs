//! One given edit scored on one log the way the verification scores it ([`super::verify`]):
//! the model before and after the edit refitted on the same folds of consecutive seeks, their
//! out-of-sample residuals judged by the same rule, and the parts of the z-score kept, so a
//! caller that pools many logs (the fleet) can add them up.

use rayon::prelude::*;

use crate::diagnose::Reason;
use crate::log::Log;
use crate::model::{ModelEdit, ModelSpec};

use super::CheckedVerifyConfig;
use super::candidates::edit_for;
use super::gain::{Baseline, blown_up};
use super::refit::{cv_residuals_sharing, refits_of};
use super::verify::error_chain;

/// One edit's out-of-sample figures on one log.
#[derive(Debug, Clone)]
pub(crate) struct EditScore {
    /// The typed edit (`add col:load`).
    pub(crate) edit: ModelEdit,
    /// The model's terms after it.
    pub(crate) terms: String,
    /// Held-out rows scored (the log's measured rows).
    pub(crate) rows: usize,
    /// Sum of the squared out-of-sample errors before the edit.
    pub(crate) sse_before: f64,
    /// The same after the edit, on the same rows and folds.
    pub(crate) sse_after: f64,
    /// The verification's gain, `1 − MSE_after / MSE_before`.
    pub(crate) gain: f64,
    /// The verification's gain within folds.
    pub(crate) gain_within_folds: f64,
    /// The summed paired Huber-loss difference: the z-score's numerator.
    pub(crate) loss_gain: f64,
    /// The block standard error of its noise part: the z-score's denominator (0: no spread).
    pub(crate) loss_se: f64,
    /// The verification's z-score (`loss_gain / loss_se`, 0 without spread).
    pub(crate) z: f64,
    /// The verdict of the single-log rule at the plain bar (`min_z`, the bar of a flagged
    /// feature's edit).
    pub(crate) reason: Reason,
}

/// Scores each of `terms` (terms a diagnosis suggests, each turned into an edit of `spec` as
/// the verification turns it, without a `table` spacing) on `log`: `spec` refitted once and
/// each edited model refitted, on `config.folds` folds of consecutive seeks, as
/// [`super::verify`] refits them; `min_effect` is the practical minimum of the single-log
/// rule. One result per term, in order; an error says why the edit does not apply, or the
/// refit (of the model as it is, for every term) failed or blew up.
pub(crate) fn score_edits(
    spec: &ModelSpec,
    terms: &[String],
    log: &Log,
    min_effect: f64,
    config: &CheckedVerifyConfig,
) -> Vec<Result<EditScore, String>> {
    let shared = refits_of(log, &config.fit);
    let edits: Vec<Result<(ModelEdit, ModelSpec), String>> = terms
        .iter()
        .map(|t| {
            let edit = edit_for(t, spec, None).map_err(|e| e.to_string())?;
            let next = spec.apply(&edit).map_err(|e| e.to_string())?;
            Ok((edit, next))
        })
        .collect();
    // The model as it is first: each of its folds' searched values start the edited models'
    // searches on the same fold, as the verification's refits start (`fit_sharing`'s `warm`).
    let (before, warm) =
        match cv_residuals_sharing(spec, log, config.folds, &config.fit, &shared, &[]) {
            Ok(r) => (Ok(r.residuals), r.searched),
            Err(e) => (Err(error_chain(&e)), Vec::new()),
        };
    let score = |s: &ModelSpec| {
        cv_residuals_sharing(s, log, config.folds, &config.fit, &shared, &warm)
            .map(|r| r.residuals)
            .map_err(|e| error_chain(&e))
    };
    let afters = edits
        .par_iter()
        .map(|e| e.as_ref().map_err(Clone::clone).and_then(|(_, n)| score(n)))
        .collect::<Vec<_>>();
    let base = match before {
        Ok(r) => Baseline::new(r, config.folds),
        Err(e) => {
            let why = format!("the model `{spec}` cannot be refitted on this log: {e}");
            return terms.iter().map(|_| Err(why.clone())).collect();
        }
    };
    let std_before = super::verify::std_of(&base.r);
    let sse = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let sse_before = sse(&base.r);
    edits
        .into_iter()
        .zip(afters)
        .map(|(e, after)| {
            let (edit, next) = e?;
            let after = after?;
            if let Some(why) = blown_up(std_before, super::verify::std_of(&after)) {
                return Err(why);
            }
            let judged = base.judge_both(&after, min_effect, config)[0];
            let (loss_gain, loss_se) = base.z_parts(&after);
            Ok(EditScore {
                edit,
                terms: next.to_string(),
                rows: after.len(),
                sse_before,
                sse_after: sse(&after),
                gain: judged.gain,
                gain_within_folds: judged.within,
                loss_gain,
                loss_se,
                z: judged.z,
                reason: judged.reason,
            })
        })
        .collect()
}

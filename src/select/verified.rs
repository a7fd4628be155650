//! A model's diagnosis with its leading suggestions verified by refits: [`diagnose_verified`].

use crate::diagnose::{
    CheckedDiagnoseConfig, Diagnosis, FeatureOrigin, ModelDiagnosisError, Verification,
    diagnose_model, extend_summary, flagged_features, is_time, model_spec, model_table,
};
use crate::log::Log;
use crate::model::{FittedModel, ModelSpec};

use super::{CheckedVerifyConfig, candidates, verify_two_rounds};

/// [`diagnose_model`], then the leading suggestions — the top flagged features' terms and
/// what adaptive terms absorbed — applied as typed edits, refitted on `log` and scored out of
/// sample on folds of consecutive seeks (`super::verify`); the result is in
/// [`Diagnosis::verification`], best verified gain first, and leads the summary.
pub fn diagnose_verified(
    model: &FittedModel,
    log: &Log,
    config: &CheckedDiagnoseConfig,
    verify_config: &CheckedVerifyConfig,
) -> Result<Diagnosis, ModelDiagnosisError> {
    let mut d = diagnose_model(model, log, config)?;
    let spec = model_spec(model)?;
    let cands = candidates(&d, verify_config.candidates);
    // The second round's re-screen: the residual the best edit leaves against the features
    // it names (the table made again, only those columns and `direction` kept: no table is
    // held through the refits).
    let rescreen = |r: &[f64], with: &ModelSpec, keep: &dyn Fn(&str) -> bool| {
        // The direction column always: the direction-signed analysis reads it.
        let direction = FeatureOrigin::BuiltIn(crate::history::Feature::Direction);
        let table = model_table(model, log)
            .without(|c| c.origin != direction && (is_time(c.origin) || !keep(&c.name)));
        let mut config = config.clone();
        for t in &with.terms {
            config.add_existing_term(t.name());
        }
        // Only the flags are read (`rescreen_candidates`): no pair screen, no summary.
        (!table.columns().is_empty())
            .then(|| flagged_features(&table, r, &config).ok())
            .flatten()
    };
    let v = verify_two_rounds(
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
    d.summary = extend_summary(&d);
    Ok(d)
}

/// Ranks by verified gain : the feature whose edit is the best verified
/// one moves to the front of [`Diagnosis::features`] and is flagged — also when the
/// one-dimensional screen left it unflagged, since its refit cleared the stricter bar of
/// [`super::STRICT_EXTRA_Z`] — with a note saying so. An edit that came from a pair or
/// from what an adaptive term absorbed names no single feature and changes nothing here.
fn promote_verified(d: &mut Diagnosis, v: &Verification) {
    let Some(best) = v.best() else { return };
    let Some(i) = d.features.iter().position(|f| f.name == best.feature) else {
        return;
    };
    let mut f = d.features.remove(i);
    if !f.flagged {
        f.flagged = true;
        f.reason = crate::diagnose::Reason::FlaggedByRefit;
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

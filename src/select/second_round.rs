//! The verification's second round: the best verified edit put into the model, and the
//! candidates that can still pay refitted on top of it.

use crate::diagnose::{
    CombinedEdit, Diagnosis, FeatureReport, ModelDiagnosisError, SecondRound, Verification,
    VerifiedEdit,
};
use crate::log::Log;
use crate::model::terms::drift;
use crate::model::{ModelEdit, ModelSpec};

use super::CheckedVerifyConfig;
use super::candidates::{Candidate, feature_candidate, source_of, source_of_name};
use super::verify::{name_verified, verify_round};

/// Share of the best verified edit's gain (of its feature's explained share, for a feature the
/// first round did not score) a promising edit or a feature without a slot must reach for the
/// second round to refit it on top of the best edit ([`second_round_candidates`]): an effect of
/// comparable size, which the best edit alone leaves whole. An edit **verified** in the first
/// round needs not reach it: its own evidence says its effect is there, and [`left_on_top`]
/// says whether the best edit left it (a second effect at 7–20 % of the best gain took the
/// advice from 63–83 % to 100 % of both true terms together on the family drives; README).
pub(crate) const SECOND_ROUND_SHARE: f64 = 0.5;

/// Smallest z-score of a first-round edit that is not verified but *promising* (its gains out
/// of sample and within folds practical): such an edit is refitted on top of the best one too,
/// since an effect the best edit's refit confounded can clear the bar on top of it.
pub(crate) const PROMISING_Z: f64 = 1.0;

/// Most raw permutation p-value of a feature the first round gave no slot for the second round
/// to score it (at the strict bar): looser than [`UNFLAGGED_P`] because a second effect's
/// screen ran on a residual that still held the first (a lagged temperature at p = 0.015 beside
/// a position × direction effect).
pub(crate) const SECOND_ROUND_P: f64 = 0.05;

/// The term an edit puts into the model (`add T`, `replace O by T`: `T`).
pub(super) fn added_term(e: &ModelEdit) -> Option<String> {
    match e {
        ModelEdit::Add(t) | ModelEdit::Replace { new: t, .. } => Some(t.name()),
        _ => None,
    }
}

/// The candidates of the second round, at most `max`, when the first round (`v`, from the
/// candidates `first` of diagnosis `d`) verified an edit: (1) every other first-round edit that
/// is verified or promising ([`PROMISING_Z`]) with at least [`SECOND_ROUND_SHARE`] of the best
/// edit's gain, or verified (at its own bar) with any gain when `left_for` (the share of the
/// residual after the best edit its change can explain, [`left_on_top`]; `None` when the
/// residuals are not at hand) reaches the practical minimum, as scored (its winning term);
/// both gains practical; (2) then the features the first round gave no
/// slot (no candidate of their source): flagged, or at raw p ≤ [`SECOND_ROUND_P`], with at
/// least [`SECOND_ROUND_SHARE`] of the best feature's explained share, largest share first.
/// One per source, none of the best edit's source, no time feature (what `drift` would fit).
/// Empty (the round does not run) when nothing can pay.
pub(crate) fn second_round_candidates(
    d: &Diagnosis,
    first: &[Candidate],
    v: &Verification,
    max: usize,
    left_for: &dyn Fn(&VerifiedEdit) -> Option<f64>,
) -> Vec<Candidate> {
    let Some(best) = v.best() else {
        return Vec::new();
    };
    let src = |name: &str| source_of_name(d, name);
    let mut sources = vec![src(&best.feature)];
    let mut out = Vec::new();
    for e in v.edits.iter().skip(1) {
        let practical = e.gain >= v.min_effect && e.gain_within_folds >= v.min_effect;
        let pays = practical
            && ((e.verified || e.z >= PROMISING_Z) && e.gain >= SECOND_ROUND_SHARE * best.gain
                || e.verified && left_for(e).is_some_and(|g| g >= v.min_effect));
        let Some(term) = e.model_edit.as_ref().and_then(added_term) else {
            continue;
        };
        let s = src(&e.feature);
        if out.len() >= max || !pays || sources.contains(&s) {
            continue;
        }
        sources.push(s);
        out.push(Candidate {
            feature: e.feature.clone(),
            terms: vec![term],
            try_all: false,
            table_spacing: None,
            strict: true,
        });
    }
    let Some(bar) = d
        .feature(&best.feature)
        .map(|f| SECOND_ROUND_SHARE * f.explained)
    else {
        return out;
    };
    sources.extend(first.iter().map(|c| src(&c.feature)));
    let mut pool: Vec<&FeatureReport> = d
        .features
        .iter()
        .filter(|f| f.flagged || f.p_value_raw <= SECOND_ROUND_P)
        .filter(|f| {
            f.suggested_term
                .as_deref()
                .is_some_and(|t| t != drift::HEAD)
        })
        .filter(|f| f.explained >= bar)
        .collect();
    pool.sort_by(|a, b| crate::diagnose::compare(a, b));
    for f in pool {
        let s = source_of(f);
        if out.len() >= max || sources.contains(&s) {
            continue;
        }
        sources.push(s);
        out.push(feature_candidate(f, true));
    }
    out
}

/// The re-screen of the second round ([`verify_two_rounds`]): the flagged features, in the
/// diagnosis's order, of the diagnosis of `residual` (the out-of-sample residual the best
/// verified edit leaves, one per measured row in log order) for the model `spec` (the user's
/// model with that edit: its terms are not suggested again) against the log's feature columns
/// that `keep` admits by name (time features never) — nothing else of that diagnosis is read
/// (`crate::diagnose::flagged_features`); `None` when it cannot run.
pub(crate) type Rescreen<'a> =
    dyn Fn(&[f64], &ModelSpec, &dyn Fn(&str) -> bool) -> Option<Vec<FeatureReport>> + 'a;

/// The features of `d` worth screening again on the residual the best edit leaves (see
/// [`rescreen_candidates`]): raw p ≤ [`SECOND_ROUND_P`] on the first screen (some evidence of
/// an effect even while the first effect hid it), not the best edit's source.
pub(crate) fn rescreen_columns(d: &Diagnosis, best: &VerifiedEdit) -> Vec<String> {
    let best_src = source_of_name(d, &best.feature);
    d.features
        .iter()
        .filter(|f| f.p_value_raw <= SECOND_ROUND_P)
        .filter(|f| source_of(f) != best_src)
        .map(|f| f.name.clone())
        .collect()
}

/// The second round's candidates from the **re-screen** of the residual the best edit leaves
/// (`flagged`, [`Rescreen`]): its flagged features with a suggested term (no time feature), in its
/// order, one per source, none of a source in `taken` (the best edit's and the second round's
/// other candidates), at most `max`. A second effect's screen on the user's residual is
/// diluted by the first effect's variance and confounded with it (a position × direction
/// effect at 2.5–10 % explained beside a slow covariate at 42–49 %, below the pool's share of
/// the best feature; a logged column following the first effect's slow course taking the
/// unflagged slots), and its shape can be read wrong (the effect's direction sign lost in the
/// first effect's spread); on what the best edit leaves it stands alone, and the screen's own
/// rule (family-wise significance, the practical minimum beyond the features before it) says
/// whether it is there. Each is refitted on top of the best edit at the strict bar like the
/// round's other candidates.
pub(crate) fn rescreen_candidates(
    flagged: &[FeatureReport],
    taken: &[String],
    max: usize,
) -> Vec<Candidate> {
    let mut sources = taken.to_vec();
    let mut out = Vec::new();
    for f in flagged.iter().filter(|f| f.flagged) {
        if out.len() >= max {
            break;
        }
        if f.suggested_term.as_deref().is_none_or(|t| t == drift::HEAD) {
            continue;
        }
        let s = source_of(f);
        if sources.contains(&s) {
            continue;
        }
        sources.push(s);
        out.push(feature_candidate(f, true));
    }
    out
}

/// What an edit verified in the first round can still explain of the residual the best edit
/// leaves: with `before`, `best` and `other` the out-of-sample residuals of the model as it is,
/// with the best edit and with the other edit (same folds), the other edit's change of the
/// prediction is `d = before − other`, and the share is the R² of `best` on `d` through the
/// origin, `(Σ best·d)² / (Σ d² · Σ best²)` (0 when either is all zeros). Two edits of one
/// effect change the prediction alike, so what the best leaves is nearly orthogonal to the
/// other's change (share near 0); an edit of a second effect keeps its whole change, which the
/// residual still holds (share ≈ its gain over `1 −` the best's).
pub(crate) fn left_on_top(before: &[f64], best: &[f64], other: &[f64]) -> f64 {
    let (mut rd, mut dd, mut rr) = (0.0, 0.0, 0.0);
    for ((&b, &r), &o) in before.iter().zip(best).zip(other) {
        let d = b - o;
        rd += r * d;
        dd += d * d;
        rr += r * r;
    }
    if dd > 0.0 && rr > 0.0 {
        rd * rd / (dd * rr)
    } else {
        0.0
    }
}

/// [`verify`], then the second round (see the module docs) when [`second_round_candidates`]
/// finds a candidate that can pay: the best verified edit is put into the model, its
/// out-of-sample residual (kept from the first round: no refit) is the new baseline, and the
/// candidates are refitted on top of it on the same folds and judged at the strict bar; what
/// holds on top is reported with both edits together ([`CombinedEdit`]). `d` is the diagnosis
/// the candidates `cands` came from. `rescreen` (when given) diagnoses the best edit's
/// out-of-sample residual against the features [`rescreen_columns`] names; its flagged
/// features join the round's candidates ([`rescreen_candidates`], up to
/// [`VerifyConfig::candidates`] more), and the round runs when one of them can pay too.
pub(crate) fn verify_two_rounds(
    d: &Diagnosis,
    spec: &ModelSpec,
    log: &Log,
    cands: &[Candidate],
    min_effect: f64,
    config: &CheckedVerifyConfig,
    rescreen: Option<&Rescreen<'_>>,
) -> Result<Verification, ModelDiagnosisError> {
    let block_len = d.null_block_len;
    let (mut v, mut keep) = verify_round(spec, log, cands, block_len, min_effect, config, None)?;
    let second = {
        let left = |e: &VerifiedEdit| {
            let best = v.best()?;
            let (r1, _) = keep.verified.get(&best.terms)?;
            let (r2, _) = keep.verified.get(&e.terms)?;
            Some(left_on_top(&keep.before, &r1.residuals, &r2.residuals))
        };
        second_round_candidates(d, cands, &v, config.candidates, &left)
    };
    // The re-screen of what the best edit leaves: features the first effect hid get their
    // own candidates (up to `candidates` more, see `rescreen_candidates`).
    let rescreened = v.best().and_then(|b| {
        let (r1, m) = keep.verified.get(&b.terms)?;
        let columns = rescreen_columns(d, b);
        let r = rescreen?(&r1.residuals, &spec.apply(m).ok()?, &|n: &str| {
            columns.iter().any(|c| c == n)
        })?;
        let mut taken = vec![b.feature.clone()];
        taken.extend(second.iter().map(|c| c.feature.clone()));
        let taken: Vec<String> = taken.iter().map(|n| source_of_name(d, n)).collect();
        Some(rescreen_candidates(&r, &taken, config.candidates))
    });
    let second: Vec<Candidate> = second
        .into_iter()
        .chain(rescreened.into_iter().flatten())
        .collect();
    let base = v
        .best()
        .filter(|_| !second.is_empty())
        .and_then(|b| keep.verified.remove(&b.terms));
    keep.verified.clear();
    name_verified(&mut v, spec, log, config);
    let (Some((after, raw)), Some(best)) = (base, v.best().cloned()) else {
        return Ok(v);
    };
    let Ok(base_spec) = spec.apply(&raw) else {
        return Ok(v);
    };
    let (mut v2, _) = verify_round(
        &base_spec,
        log,
        &second,
        block_len,
        min_effect,
        config,
        Some(after),
    )?;
    name_verified(&mut v2, &base_spec, log, config);
    let combined = v2.best().map(|e2| {
        let terms = best
            .model_edit
            .as_ref()
            .zip(e2.model_edit.as_ref())
            .and_then(|(m1, m2)| spec.apply(m1).and_then(|s| s.apply(m2)).ok())
            .map_or_else(|| e2.terms.clone(), |s| s.to_string());
        CombinedEdit {
            edits: vec![best.edit.clone(), e2.edit.clone()],
            terms,
            std_before: best.std_before,
            std_after: e2.std_after,
            gain: 1.0 - (1.0 - best.gain) * (1.0 - e2.gain),
        }
    });
    v.second_round = Some(SecondRound {
        on_top_of: best.edit.clone(),
        base_terms: best.terms.clone(),
        std_before: best.std_after,
        edits: v2.edits,
        rejected: v2.rejected,
        combined,
    });
    Ok(v)
}

//! Verified advice: every suggestion is a typed [`ModelEdit`], applied to the model's spec,
//! refitted, and scored **out of sample** on folds of consecutive seeks; the edits are ranked by
//! that verified gain, not by what a one-dimensional smoother expected.
//!
//! ## How an edit is scored
//! The log's measured rows are cut into [`VerifyConfig::folds`] contiguous stretches. For each,
//! the stretch's bias cells are blanked (the seeks stay, so the history and every adaptive
//! state are replayed as the drive made them), the model is fitted on the rest, replayed
//! causally over the whole log, and its residuals on the blanked stretch are kept. The model
//! before and after the edit are scored on the same folds, so the per-row squared errors pair
//! up: the verified gain is `1 − MSE_after / MSE_before`, and its noise is judged from the
//! **noise part** of the paired differences (the edit's change of the prediction times the
//! residual after it: what is random once the change is given, `conditional_z`) summed over
//! blocks of consecutive rows (as long as that series' own serial correlation needs: its
//! automatic null block), so serially correlated errors do not make a small gain look sure,
//! and an effect whose gain comes in episodes is not taken for noise. An edit is *verified* when
//! its gain is at least [`crate::diagnose::DiagnoseConfig::min_effect`] and its block z-score at least
//! [`VerifyConfig::min_z`], and its gain **within folds** (each stretch's own mean taken out
//! of both residual series, [`gain_within_folds`]) reaches the same practical minimum: what an
//! edit gains only by moving the few levels the refits miss is not evidence of an effect (a
//! random-walk column with no effect gained 3.2 % out of sample at z = 4.2 under AR(1) noise,
//! 0.3 % within folds). The z-score is taken on Huber losses rather than squared errors
//! (heavy-tailed noise; see `paired_gain` in the module source).
//!
//! ## The strongest unflagged features are verified too
//! The one-dimensional screen's serial-structure null costs power on slow features (a lagged
//! temperature) and its smoother cannot resolve a narrow defect; a refit can. So when fewer
//! than [`VerifyConfig::candidates`] features are flagged, the free slots go to the strongest
//! unflagged ones ([`unflagged_candidates`]: raw p ≤ [`UNFLAGGED_P`], one per source, no time
//! feature). Their edits need z ≥ `min_z` + [`STRICT_EXTRA_Z`] and a lower loss in every fold;
//! [`super::diagnose_verified`] then ranks by verified gain, moving the feature of the best
//! verified edit to the front (flagged, with a note when the screen alone did not flag it).
//!
//! ## The second round: on top of the best edit
//! With two effects of comparable size the first round's best edit holds one of them (on
//! `bw1-sine-tar` with a lag beside a position × direction effect, 54–88 % of the best single
//! true term in 3 of 5 seeds), and the other may not even have had a slot. So, as `discover`
//! does, [`verify_two_rounds`] puts the best verified edit into the model and refits the other
//! candidates that can pay on top of it ([`second_round_candidates`]: edits verified or
//! promising with at least [`SECOND_ROUND_SHARE`] of the best gain, edits verified at any gain
//! whose change of the prediction can still explain the practical minimum of the residual the
//! best edit leaves ([`left_on_top`], from residuals the first round kept: no refit), then
//! features that got no slot; then the features flagged by a **re-screen** of the residual the
//! best edit leaves, [`rescreen_candidates`]: a second effect's own feature, hidden on the
//! user's residual by the first effect, flags there and brings its own term), scored on the
//! same folds against the best edit's out-of-sample residual (kept, not
//! refitted) and judged at the strict bar. What holds on top is reported with the two edits
//! together ([`CombinedEdit`]); the first round's list, its best edit and the features' ranking
//! are left as they were. Where no candidate can pay the round does not run (no cost, no new
//! key in the JSON).

use std::collections::HashMap;

use rayon::prelude::*;

use crate::diagnose::{ModelDiagnosisError, Reason, RejectedEdit, Verification, VerifiedEdit};
use crate::fit::CheckedFitOptions;
use crate::log::Log;
use crate::model::registry::head;
use crate::model::terms::drift;
use crate::model::{ModelEdit, ModelSpec};

use super::candidates::{Candidate, defect_candidate, edit_for, variants};
use super::gain::{Baseline, Judgement, blown_up};
use super::refit::{Refitted, cv_residuals, cv_residuals_sharing, measured_rows, refits_of};

/// Settings of the verification refits.
#[derive(Debug, Clone, PartialEq)]
pub struct VerifyConfig {
    /// Folds of consecutive seeks, 2..=20 (default 3).
    pub folds: usize,
    /// How many of the leading flagged features get a verified edit, 1..=20 (default 3).
    pub candidates: usize,
    /// Smallest block z-score of the gain for an edit to count as verified (default 2.0,
    /// about a one-sided 2 % level).
    pub min_z: f64,
    /// Options of every refit (checked once by [`crate::fit::FitOptions::check`]).
    pub fit: CheckedFitOptions,
}

impl Default for VerifyConfig {
    fn default() -> Self {
        Self {
            folds: 3,
            candidates: 3,
            min_z: 2.0,
            fit: CheckedFitOptions::default(),
        }
    }
}

impl VerifyConfig {
    /// Checks every setting's range once (the error names the setting) into the checked type
    /// `verify` and [`super::diagnose_verified`] accept.
    pub fn check(self) -> Result<CheckedVerifyConfig, crate::diagnose::DiagnoseError> {
        self.validate()?;
        Ok(CheckedVerifyConfig(self))
    }

    /// Checks every setting's range; the error names the setting.
    fn validate(&self) -> Result<(), crate::diagnose::DiagnoseError> {
        let bad = |field, message: String| {
            Err(crate::diagnose::DiagnoseError::InvalidConfig { field, message })
        };
        if !(2..=20).contains(&self.folds) {
            return bad(
                crate::field::Field::VerifyFolds,
                format!("{} is not in 2..=20", self.folds),
            );
        }
        if !(1..=20).contains(&self.candidates) {
            return bad(
                crate::field::Field::VerifyCandidates,
                format!("{} is not in 1..=20", self.candidates),
            );
        }
        if !(self.min_z.is_finite() && self.min_z >= 0.0) {
            return bad(
                crate::field::Field::MinZ,
                format!("{} is not a finite number ≥ 0", self.min_z),
            );
        }
        Ok(())
    }
}

checked_settings! {
    /// Verification settings that passed [`VerifyConfig::check`]; read them through `Deref`.
    /// `Default` is the checked default.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct CheckedVerifyConfig(VerifyConfig);
}

/// What the verification keeps of one refit's out-of-sample residuals: their std and the
/// verdict against the model as it is, for a plain (`judged[0]`) and a strict (`judged[1]`)
/// candidate ([`judge`]); the residuals themselves only for an edit verified at either bar
/// (the second round starts from them).
pub(super) struct Scored {
    std_after: f64,
    judged: [Judgement; 2],
    residual: Option<Refitted>,
}

pub(super) fn std_of(r: &[f64]) -> f64 {
    crate::numeric::stats::std_dev(r).unwrap_or(0.0)
}

/// Verifies `cands` on `log` for the model `spec` (see the module docs): each candidate's
/// first term that applies and fits (every term for `try_all`, keeping the best) is scored;
/// edits are sorted by verified gain, largest first. `block_len` is the z-score's block
/// (use the diagnosis's `null_block_len`), `min_effect` the practical minimum gain.
pub(crate) fn verify(
    spec: &ModelSpec,
    log: &Log,
    cands: &[Candidate],
    block_len: usize,
    min_effect: f64,
    config: &CheckedVerifyConfig,
) -> Result<Verification, ModelDiagnosisError> {
    let (mut v, _) = verify_round(spec, log, cands, block_len, min_effect, config, None)?;
    name_verified(&mut v, spec, log, config);
    Ok(v)
}

/// What a round keeps for the next one: the out-of-sample residuals of the model it started
/// from and of each verified edit (keyed by the edit's terms before [`name_verified`]), with
/// the edit as scored (a `bump`/`step` still searched by every fold's refit) and the values its
/// folds' fits found for the searched parameters (where the next round's refits start).
#[derive(Debug, Default)]
pub(super) struct RoundResiduals {
    pub(super) before: Vec<f64>,
    pub(super) verified: HashMap<String, (Refitted, ModelEdit)>,
}

/// One round of [`verify`] on `spec`, the edits not yet named ([`name_verified`]). `given` is
/// the out-of-sample residual of `spec` when a round before has it (it is not refitted then);
/// with it every edit is judged at the strict bar (the second round). The candidates' refits
/// start their searched parameters where the folds of `spec`'s refit (or of `given`) found them
/// ([`crate::fit::fit_sharing`]'s `warm`).
pub(super) fn verify_round(
    spec: &ModelSpec,
    log: &Log,
    cands: &[Candidate],
    block_len: usize,
    min_effect: f64,
    config: &CheckedVerifyConfig,
    given: Option<Refitted>,
) -> Result<(Verification, RoundResiduals), ModelDiagnosisError> {
    let strict_all = given.is_some();
    let mut keep = RoundResiduals::default();
    let mut v = Verification {
        folds: config.folds,
        block_len,
        min_effect,
        ..Verification::default()
    };
    // The refits the loop below will score (the model as it is; each candidate's first term
    // that applies, every term of a `try_all` candidate) run in parallel first; the loop then
    // reads them, so the result is the same for any number of threads.
    // Every refit of the round reads the log's sampling and replayed features from here.
    let shared = refits_of(log, &config.fit);
    let (wanted, keys) = wanted_refits(spec, cands, given.is_none());
    // The model as it is first (`wanted[0]`, unless a round before gave its residual): every
    // other refit is judged against it as soon as it is made, and only its verdicts are kept —
    // not one residual vector per refit (8 B a row each) until the loop reads it. Its folds'
    // searched values start the other refits' searches.
    let first = usize::from(!strict_all);
    let before = match given.map_or_else(
        || cv_residuals_sharing(spec, log, config.folds, &config.fit, &shared, &[]),
        Ok,
    ) {
        Ok(r) => r,
        Err(e) => {
            v.not_run = Some(format!(
                "the model `{spec}` cannot be refitted on this log, so no suggestion was \
                 verified: {}",
                error_chain(&e)
            ));
            return Ok((v, keep));
        }
    };
    let Refitted {
        residuals: before,
        searched: warm,
    } = before;
    let score = |s: &ModelSpec| {
        cv_residuals_sharing(s, log, config.folds, &config.fit, &shared, &warm)
            .map_err(|e| error_chain(&e))
    };
    let base = Baseline::new(before, config.folds);
    let before = &base.r;
    let std_before = std_of(before);
    let assess = |s: &ModelSpec| {
        score(s).and_then(|after| {
            let std_after = std_of(&after.residuals);
            // A refit whose held-out error blew up failed: it is no verdict on the effect.
            if let Some(why) = blown_up(std_before, std_after) {
                return Err(why);
            }
            let judged = base.judge_both(&after.residuals, min_effect, config);
            Ok(Scored {
                std_after,
                judged,
                residual: judged.iter().any(|j| j.verified).then_some(after),
            })
        })
    };
    let mut cache: HashMap<String, Result<Scored, String>> = keys
        .into_iter()
        .skip(first)
        .zip(wanted[first..].par_iter().map(assess).collect::<Vec<_>>())
        .collect();
    let mut scored = |s: &ModelSpec| cache.remove(&s.to_string()).unwrap_or_else(|| assess(s));
    v.std_before = std_before;
    // The narrow-defect screen on the residual before, on first use: the first round always
    // needs it (its extra `bump` candidate); the second only when a candidate has a `bump`
    // variant (its cost, a scan of the whole log, is not paid for nothing).
    let defect_cell = std::cell::OnceCell::new();
    let defect = || {
        defect_cell.get_or_init(|| {
            // Each measured row's target: its track as logged (what the history's `target`
            // is, without a replay of the history that would hold every row's features).
            let x = log.measured_positions();
            crate::diagnose::advice::defect_screen(&x, before)
        })
    };
    // The step screen, per covariate column a `step:COL` variant is scored for (the clipped
    // residual and the measured rows computed once, on first use).
    let mut step_screen = StepScreen::default();
    let mut step_screened = |variant: &str| step_screen.passes(variant, log, before);
    // The second round scores only the candidates it was given (its cost stays bounded).
    let extra = if strict_all {
        None
    } else {
        defect_candidate(spec, defect().is_some(), cands)
    };
    let mut seen: Vec<String> = Vec::new();
    let mut worth = |variant: &str, c: &Candidate| {
        if variant == crate::diagnose::advice::BUMP_TERM
            && !crate::diagnose::advice::worth_a_bump(defect().as_ref(), c.table_spacing)
        {
            return false;
        }
        !crate::diagnose::advice::is_step(variant) || step_screened(variant)
    };
    for c in cands.iter().chain(&extra) {
        let best = best_edit(
            c,
            spec,
            strict_all,
            v.std_before,
            &mut seen,
            &mut v.rejected,
            &mut worth,
            &mut scored,
        );
        if let Some((e, after)) = best {
            if let (true, Some(m), Some(r)) = (e.verified, &e.model_edit, after.residual) {
                keep.verified.insert(e.terms.clone(), (r, m.clone()));
            }
            v.edits.push(e);
        }
    }
    v.edits
        .sort_by(|a, b| b.verified.cmp(&a.verified).then(b.gain.total_cmp(&a.gain)));
    prefer_physics_to_drift(&mut v.edits);
    keep.before = base.r;
    Ok((v, keep))
}

/// Candidate `c`'s best edit of `spec`: its terms' variants in order, each applied, refitted
/// (`scored`) and judged, skipping the variants `worth` turns down and the models already in
/// `seen`; the first term that fits ends the search unless `c.try_all`. A first variant that
/// cannot be applied or refitted is recorded in `rejected` with its rule.
#[allow(clippy::too_many_arguments)]
fn best_edit(
    c: &Candidate,
    spec: &ModelSpec,
    strict_all: bool,
    std_before: f64,
    seen: &mut Vec<String>,
    rejected_out: &mut Vec<RejectedEdit>,
    worth: &mut dyn FnMut(&str, &Candidate) -> bool,
    scored: &mut dyn FnMut(&ModelSpec) -> Result<Scored, String>,
) -> Option<(VerifiedEdit, Scored)> {
    let mut best: Option<(VerifiedEdit, Scored)> = None;
    for term in &c.terms {
        let mut fitted = false;
        for (k, variant) in variants(term, spec, c.table_spacing).iter().enumerate() {
            if !worth(variant, c) {
                continue;
            }
            let alt = k > 0;
            let attempt = edit_for(variant, spec, c.table_spacing).and_then(|e| {
                let s = spec.apply(&e)?;
                Ok((e, s))
            });
            let (edit, next) = match attempt {
                Ok(x) => x,
                Err(e) => {
                    if !alt {
                        rejected_out.push(rejected(c, term, Reason::NotApplicable, e.to_string()));
                    }
                    continue;
                }
            };
            if seen.contains(&next.to_string()) {
                continue;
            }
            let after = match scored(&next) {
                Ok(r) => r,
                Err(why) => {
                    if !alt {
                        rejected_out.push(rejected(c, term, Reason::FitFailed, why));
                    }
                    continue;
                }
            };
            fitted = true;
            seen.push(next.to_string());
            let j = after.judged[usize::from(c.strict || strict_all)];
            let e = verified_edit(c, edit, &next, std_before, after.std_after, j);
            if best.as_ref().is_none_or(|b| e.gain > b.0.gain) {
                best = Some((e, after));
            }
        }
        if fitted && !c.try_all {
            break;
        }
    }
    best
}

/// Candidate `c`'s `term`, rejected by `reason` for `why`.
fn rejected(c: &Candidate, term: &str, reason: Reason, why: String) -> RejectedEdit {
    RejectedEdit {
        feature: c.feature.clone(),
        term: term.to_string(),
        reason,
        why,
    }
}

/// The refits a round of [`verify_round`] scores up front: the model as it is (`with_spec`),
/// each candidate's first term that applies (every term of a `try_all` candidate), once
/// each; with their texts, in the same order.
fn wanted_refits(
    spec: &ModelSpec,
    cands: &[Candidate],
    with_spec: bool,
) -> (Vec<ModelSpec>, Vec<String>) {
    let mut wanted: Vec<ModelSpec> = Vec::new();
    if with_spec {
        wanted.push(spec.clone());
    }
    for c in cands {
        let mut groups = c.terms.iter().map(|t| {
            variants(t, spec, c.table_spacing)
                .iter()
                // `bump` and `step` wait for their screens on the residual below.
                .filter(|v| {
                    v.as_str() != crate::diagnose::advice::BUMP_TERM
                        && !crate::diagnose::advice::is_step(v)
                })
                .filter_map(|v| {
                    edit_for(v, spec, c.table_spacing)
                        .and_then(|e| spec.apply(&e))
                        .ok()
                })
                .collect::<Vec<_>>()
        });
        if c.try_all {
            wanted.extend(groups.flatten());
        } else if let Some(first) = groups.find(|g| !g.is_empty()) {
            wanted.extend(first);
        }
    }
    let mut keys: Vec<String> = Vec::new();
    wanted.retain(|s| {
        let k = s.to_string();
        let new = !keys.contains(&k);
        if new {
            keys.push(k);
        }
        new
    });
    (wanted, keys)
}

/// The step screen of a round, per covariate column a `step:COL` variant is scored for (the
/// clipped residual and the measured rows computed once, on first use).
#[derive(Default)]
struct StepScreen {
    steps: HashMap<String, bool>,
    clipped: Option<Option<(Vec<f64>, f64)>>,
    rows: Option<Vec<usize>>,
}

impl StepScreen {
    /// Whether the step screen finds a step in `variant`'s column on the residual `before`.
    fn passes(&mut self, variant: &str, log: &Log, before: &[f64]) -> bool {
        let col = variant.split_once(':').map_or("", |(_, c)| c);
        let (clipped, rows) = (&mut self.clipped, &mut self.rows);
        *self.steps.entry(col.to_string()).or_insert_with(|| {
            let Some(k) = log.schema.covariate_index(col) else {
                return false;
            };
            let Some(c) =
                clipped.get_or_insert_with(|| crate::diagnose::advice::clipped_residual(before))
            else {
                return false;
            };
            let column = log.covariate(k);
            let v: Vec<f64> = rows
                .get_or_insert_with(|| measured_rows(log))
                .iter()
                .map(|&i| column[i])
                .collect();
            crate::diagnose::advice::step_screen(&v, c).is_some()
        })
    }
}

/// The verified edit of candidate `c`: `edit`, giving `next`, judged `j`.
fn verified_edit(
    c: &Candidate,
    edit: ModelEdit,
    next: &ModelSpec,
    std_before: f64,
    std_after: f64,
    j: Judgement,
) -> VerifiedEdit {
    VerifiedEdit {
        feature: c.feature.clone(),
        edit: edit.to_string(),
        terms: next.to_string(),
        std_before,
        std_after,
        gain: j.gain,
        gain_within_folds: j.within,
        z: j.z,
        verified: j.verified,
        reason: j.reason,
        z_bar: j.z_bar,
        model_edit: Some(edit),
    }
}

/// A verified `add bump` (`add step:COL`) names the centre and width (the threshold) it finds
/// on the whole log, fitted on `spec`. The named form is kept only where it refits on the
/// folds the bare term was verified on: a threshold found on the whole log can leave a fold's
/// training rows all on one side (a column that steps once in time, its low rows in one
/// stretch), and the next round would then fail to refit the model; the bare term, which
/// places its threshold on each fold's own rows, stays in that case.
pub(super) fn name_verified(
    v: &mut Verification,
    spec: &ModelSpec,
    log: &Log,
    config: &CheckedVerifyConfig,
) {
    for e in v.edits.iter_mut().filter(|e| e.verified) {
        let named = e
            .model_edit
            .as_ref()
            .and_then(|m| crate::diagnose::advice::name_searched(spec, m, log, &config.fit))
            .filter(|(_, next)| cv_residuals(next, log, config.folds, &config.fit).is_ok());
        if let Some((edit, next)) = named {
            e.edit = edit.to_string();
            e.terms = next.to_string();
            e.model_edit = Some(edit);
        }
    }
}

/// Share of an adaptive edit's verified gain a physical edit must reach to be ranked before it.
pub(super) const PHYSICS_OVER_DRIFT: f64 = 0.9;

/// Whether `e` adds an adaptive term (`drift`): a term that follows whatever slow effect the
/// residual carries without naming it.
pub(super) fn adds_adaptive(e: &VerifiedEdit) -> bool {
    matches!(&e.model_edit, Some(ModelEdit::Add(t)) if head(&t.name()) == drift::HEAD)
}

/// "Adaptive terms hide physics", at the ranking: when the leading verified edit
/// adds `drift` and a verified edit that names a physical cause (a logged column, a position
/// shape, a memory law: any non-adaptive edit) reaches [`PHYSICS_OVER_DRIFT`] of its gain,
/// that edit goes first. Drift gains by following the effect (a lagged temperature is slow, so
/// a forgetting factor tracks it nearly as well, e.g. 67.4 % against `lag:temp_lag`'s 65.8 %
/// out of sample on a family log), but only the named effect carries to another log and to a
/// planned seek before it is measured; drift stays in the list as the alternative. The order is
/// otherwise the sort's (verified first, largest gain first).
pub(super) fn prefer_physics_to_drift(edits: &mut [VerifiedEdit]) {
    let Some(first) = edits.first() else { return };
    if !(first.verified && adds_adaptive(first)) {
        return;
    }
    let bar = PHYSICS_OVER_DRIFT * first.gain;
    if let Some(i) = edits
        .iter()
        .position(|e| e.verified && !adds_adaptive(e) && e.gain >= bar)
    {
        edits[..=i].rotate_right(1);
    }
}

/// An error and its sources, joined by ": ".
pub(crate) fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut src = e.source();
    while let Some(x) = src {
        s.push_str(": ");
        s.push_str(&x.to_string());
        src = x.source();
    }
    s
}

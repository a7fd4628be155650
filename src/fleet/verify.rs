//! The pooled suggestion verified across the fleet. The feature is the pooled screen's first
//! flagged one (the features' order: smallest pooled p, then the largest mean explained
//! share) that has a suggested term; its candidates are that term and the alternatives the
//! drives would try ([`super::PooledFeature::alternatives`]), as `diagnose` verifies a
//! feature's terms. Every screened drive is refitted with each candidate and without, on the folds of
//! consecutive seeks the single-drive verification uses
//! ([`VerifyConfig::folds`](crate::select::VerifyConfig::folds)), by the same code (the
//! verification's refits and judgement in `select`), and the drives' out-of-sample figures are
//! pooled per candidate:
//!
//! - **gain** = Σ (SSE_before − SSE_after) / Σ SSE_before over the drives: the share of the
//!   fleet's held-out squared error the edit removes (a drive's own gain is the verification's
//!   `1 − MSE_after / MSE_before`; one drive pooled is that gain);
//! - **z** = Σ Tᵢ / √(Σ sᵢ²): Tᵢ a drive's summed paired Huber-loss difference (its z-score's
//!   numerator) and sᵢ the block standard error of its noise part (the denominator), so that a
//!   drive's own z is Tᵢ / sᵢ and one drive pooled is its own z. The drives are independent, so
//!   the variances add; it is Stouffer's combination of the drives' z-scores weighted by sᵢ,
//!   and an effect of the same size in k drives has a fleet z about √k times a drive's.
//!
//! Which candidate is judged is chosen as `diagnose` chooses among a feature's terms: for a
//! covariate's or lag's terms (or `play`) every candidate is scored and the largest fleet gain
//! kept; otherwise the first candidate that any drive could refit. The rule: verified iff its
//! z ≥ [`VerifyConfig::min_z`](crate::select::VerifyConfig::min_z) (the bar of a flagged
//! feature's edit on one drive) and its gain is positive (`verified_pooled_z`); else
//! `not_significant_pooled_z` or `no_pooled_gain`. The single drive's practical minimum
//! ([`crate::diagnose::DiagnoseConfig::min_effect`]) is not asked of the fleet (an effect
//! below it in every drive is what the pool is for); each drive's own verdict by the
//! single-drive rule is reported beside it (`verified_alone`, `reason_alone`).
//!
//! Each drive's refit pays its estimates' variance out of sample, so an effect verifies
//! across the fleet only where it is larger than that cost on one drive; below it (a linear
//! effect smaller than σ/√n_train per unit of its column) no number of drives verifies it.

use std::path::Path;

use serde::Serialize;

use super::ReadSettings;
use crate::diagnose::Reason;
use crate::log::Log;
use crate::model::ModelSpec;
use crate::select::CheckedVerifyConfig;

/// One drive's refits with the fleet's edit: its out-of-sample figures, as the single-drive
/// verification computes them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DriveEdit {
    /// The drive (its log's path or given name).
    pub source: String,
    /// The edit in words (`add col:load`; the same for every drive of one model).
    #[serde(skip)]
    pub edit: String,
    /// The model's terms with it.
    #[serde(skip)]
    pub terms: String,
    /// Held-out rows scored (the drive's measured rows).
    pub rows: usize,
    /// Sum of squared out-of-sample errors of the model as it is.
    pub sse_before: f64,
    /// The same with the edit, on the same rows and folds.
    pub sse_after: f64,
    /// The drive's gain, `1 − MSE_after / MSE_before`.
    pub gain: f64,
    /// The drive's gain within folds (each fold's mean taken out of both residuals).
    pub gain_within_folds: f64,
    /// The drive's summed paired Huber-loss difference (its z-score's numerator).
    pub loss_gain: f64,
    /// The block standard error of its noise part (the z-score's denominator; 0: no spread).
    pub loss_se: f64,
    /// The drive's own z-score.
    pub z: f64,
    /// Whether the single-drive rule verifies the edit on this drive alone.
    pub verified_alone: bool,
    /// The single-drive rule that decided `verified_alone` (`below_practical_minimum`,
    /// `not_significant`, …).
    pub reason_alone: Reason,
}

/// One drive's refits with one candidate term, or why it has none (the library's message).
#[derive(Debug, Clone, PartialEq)]
pub struct DriveVerification {
    /// The drive.
    pub source: String,
    /// The candidate term.
    pub term: String,
    /// Its figures, or the message.
    pub result: Result<DriveEdit, String>,
}

/// One candidate term's pooled figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TriedEdit {
    /// The term.
    pub term: String,
    /// Drives refitted with it.
    pub drives: usize,
    /// Its fleet gain (none: no drive was refitted).
    pub gain: Option<f64>,
    /// Its fleet z.
    pub z: Option<f64>,
}

/// The pooled suggestion verified across the fleet (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetVerification {
    /// The flagged feature the edit comes from (none: nothing to verify).
    pub feature: Option<String>,
    /// The candidate judged: the pooled suggestion before the refits, then the one chosen
    /// among the candidates (see the module docs).
    pub term: Option<String>,
    /// The terms refitted on every drive: the suggestion, then its alternatives.
    pub candidates: Vec<String>,
    /// Whether every candidate is scored and the largest fleet gain kept (else the first
    /// that any drive could refit).
    pub try_all: bool,
    /// The edit in words (`add col:load`), once a drive was refitted with it.
    pub edit: Option<String>,
    /// The model's terms with it.
    pub terms: Option<String>,
    /// Folds of consecutive seeks of every drive's refits.
    pub folds: usize,
    /// Drives refitted with and without the edit (pooled).
    pub drives: usize,
    /// The fleet's out-of-sample gain: Σ (SSE_before − SSE_after) / Σ SSE_before.
    pub gain: Option<f64>,
    /// The fleet's z: Σ loss_gain / √(Σ loss_se²).
    pub z: Option<f64>,
    /// The bar `z` had to reach (the single drive's `min_z`).
    pub z_bar: f64,
    /// Whether the edit is verified across the fleet.
    pub verified: bool,
    /// The rule that decided: `verified_pooled_z`, `not_significant_pooled_z`,
    /// `no_pooled_gain`, `nothing_flagged`, `no_suggested_term`, `no_drive_refitted` or
    /// `not_run` (the refits were not asked for).
    pub reason: &'static str,
    /// The verdict in words.
    pub why: String,
    /// Drives whose own verification (the single-drive rule) verifies the edit.
    pub drives_verified_alone: usize,
    /// Every candidate's pooled figures, in the order of `candidates`.
    pub tried: Vec<TriedEdit>,
    /// Every pooled drive's figures for the judged term, in the order of the sources.
    pub per_drive: Vec<DriveEdit>,
    /// Drives whose refits with the judged term failed: (source, message).
    pub failed: Vec<(String, String)>,
}

impl FleetVerification {
    /// The verification of a pooled screen before any refit: the edit to verify (reason
    /// `not_run`), or why there is none. `suggestion`: the first flagged feature that has a
    /// suggested term, with its candidates (that term, then the alternatives); `any_flagged`:
    /// whether any feature is flagged.
    pub(super) fn pending(
        suggestion: Option<(String, Vec<String>)>,
        any_flagged: bool,
        z_bar: f64,
        folds: usize,
    ) -> Self {
        let mut v = FleetVerification {
            feature: None,
            term: None,
            candidates: Vec::new(),
            try_all: false,
            edit: None,
            terms: None,
            folds,
            drives: 0,
            gain: None,
            z: None,
            z_bar,
            verified: false,
            reason: "not_run",
            why: String::new(),
            drives_verified_alone: 0,
            tried: Vec::new(),
            per_drive: Vec::new(),
            failed: Vec::new(),
        };
        match suggestion {
            Some((feature, candidates)) => {
                v.feature = Some(feature);
                v.term = candidates.first().cloned();
                v.candidates = candidates;
                v.try_all = crate::select::tries_every_term(&v.candidates);
                v.why = format!(
                    "not_run: the refits with `{}` were not run",
                    v.candidates.join("`, `")
                );
            }
            None if !any_flagged => {
                v.reason = "nothing_flagged";
                v.why = "nothing_flagged: no feature is flagged by the pooled screen, so there \
                         is no edit to verify"
                    .into();
            }
            None => {
                v.reason = "no_suggested_term";
                v.why = "no_suggested_term: no flagged feature has a term the drives suggest, \
                         so there is no edit to verify"
                    .into();
            }
        }
        v
    }
}

/// Refits `spec` without and with each of `terms` on one drive's `log` (see the module
/// docs): one result per term, in order; `min_effect` is the single-drive rule's practical
/// minimum ([`crate::diagnose::DiagnoseConfig::min_effect`]).
pub fn verify_drive(
    source: &str,
    log: &Log,
    spec: &ModelSpec,
    terms: &[String],
    min_effect: f64,
    verify: &CheckedVerifyConfig,
) -> Vec<DriveVerification> {
    let scores = crate::select::score_edits(spec, terms, log, min_effect, verify);
    terms
        .iter()
        .zip(scores)
        .map(|(term, r)| DriveVerification {
            source: source.to_string(),
            term: term.clone(),
            result: r.map(|s| DriveEdit {
                source: source.to_string(),
                edit: s.edit.to_string(),
                terms: s.terms,
                rows: s.rows,
                sse_before: s.sse_before,
                sse_after: s.sse_after,
                gain: s.gain,
                gain_within_folds: s.gain_within_folds,
                loss_gain: s.loss_gain,
                loss_se: s.loss_se,
                z: s.z,
                verified_alone: s.reason == Reason::Verified,
                reason_alone: s.reason,
            }),
        })
        .collect()
}

/// [`verify_drive`] of the log at `path` read with `read`.
pub fn verify_path(
    path: &Path,
    read: &ReadSettings,
    spec: &ModelSpec,
    terms: &[String],
    min_effect: f64,
    verify: &CheckedVerifyConfig,
) -> Vec<DriveVerification> {
    let source = path.display().to_string();
    match read.read(path) {
        Ok(log) => verify_drive(&source, &log, spec, terms, min_effect, verify),
        Err(e) => {
            let m = crate::io::message(&e);
            terms
                .iter()
                .map(|t| DriveVerification {
                    source: source.clone(),
                    term: t.clone(),
                    result: Err(m.clone()),
                })
                .collect()
        }
    }
}

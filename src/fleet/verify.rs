//! The pooled suggestion verified across the fleet. The edit is the pooled screen's: the
//! suggested term of the first flagged feature (the features' order: smallest pooled p, then
//! the largest mean explained share) that has one. Every screened drive is refitted with and
//! without it on the folds of consecutive seeks the single-drive verification uses
//! ([`VerifyConfig::folds`](crate::select::VerifyConfig::folds)), by the same code
//! (`select::score_edit`), and the drives' out-of-sample figures are pooled:
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
//! The rule: verified iff z ≥ [`VerifyConfig::min_z`](crate::select::VerifyConfig::min_z) (the
//! bar of a flagged feature's edit on one drive) and the gain is positive
//! (`verified_pooled_z`); else `not_significant_pooled_z` or `no_pooled_gain`. The single
//! drive's practical minimum is not asked of the fleet (an effect below it in every drive is
//! what the pool is for); each drive's own verdict by the single-drive rule is reported beside
//! it (`verified_alone`, `reason_alone`).

use std::path::Path;

use serde::Serialize;

use super::{FleetDiagnosis, PooledFeature, ReadSettings};
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

/// One drive's refits with the fleet's edit, or why it has none (the library's message).
#[derive(Debug, Clone, PartialEq)]
pub struct DriveVerification {
    /// The drive.
    pub source: String,
    /// Its figures, or the message.
    pub result: Result<DriveEdit, String>,
}

/// The pooled suggestion verified across the fleet (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetVerification {
    /// The flagged feature the edit comes from (none: nothing to verify).
    pub feature: Option<String>,
    /// The suggested term (`col:load`).
    pub term: Option<String>,
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
    /// Every pooled drive's figures, in the order of the sources.
    pub per_drive: Vec<DriveEdit>,
    /// Drives whose refits failed: (source, message).
    pub failed: Vec<(String, String)>,
}

impl FleetVerification {
    /// The verification of a pooled screen before any refit: the edit to verify (reason
    /// `not_run`), or why there is none.
    pub(super) fn pending(features: &[PooledFeature], z_bar: f64, folds: usize) -> Self {
        let mut v = FleetVerification {
            feature: None,
            term: None,
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
            per_drive: Vec::new(),
            failed: Vec::new(),
        };
        let flagged: Vec<_> = features.iter().filter(|f| f.flagged).collect();
        match flagged.iter().find(|f| f.suggested_term.is_some()) {
            Some(f) => {
                v.feature = Some(f.name.clone());
                v.term = f.suggested_term.clone();
                v.why = format!(
                    "not_run: the refits with `{}` were not run",
                    f.suggested_term.as_deref().unwrap_or_default()
                );
            }
            None if flagged.is_empty() => {
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

/// Refits `spec` with and without `term` on one drive's `log` (see the module docs);
/// `min_effect` is the single-drive rule's practical minimum
/// ([`crate::diagnose::DiagnoseConfig::min_effect`]).
pub fn verify_drive(
    source: &str,
    log: &Log,
    spec: &ModelSpec,
    term: &str,
    min_effect: f64,
    verify: &CheckedVerifyConfig,
) -> DriveVerification {
    let result =
        crate::select::score_edit(spec, term, log, min_effect, verify).map(|s| DriveEdit {
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
        });
    DriveVerification {
        source: source.to_string(),
        result,
    }
}

/// [`verify_drive`] of the log at `path` read with `read`.
pub fn verify_path(
    path: &Path,
    read: &ReadSettings,
    spec: &ModelSpec,
    term: &str,
    min_effect: f64,
    verify: &CheckedVerifyConfig,
) -> DriveVerification {
    let source = path.display().to_string();
    match read.read(path) {
        Ok(log) => verify_drive(&source, &log, spec, term, min_effect, verify),
        Err(e) => DriveVerification {
            source,
            result: Err(crate::io::message(&e)),
        },
    }
}

/// Pools the drives' refits with the pooled suggestion ([`FleetDiagnosis::verification`]'s
/// `term`) into the fleet's verdict (see the module docs), sets
/// [`FleetDiagnosis::best_edit`] and the summary. The drives' order does not change it. Does
/// nothing when the pooled screen has no edit to verify.
pub fn pool_verifications(d: &mut FleetDiagnosis, drives: &[DriveVerification]) {
    let v = &mut d.verification;
    let Some(term) = v.term.clone() else { return };
    let mut order: Vec<&DriveVerification> = drives.iter().collect();
    order.sort_by(|a, b| a.source.cmp(&b.source));
    v.per_drive = order
        .iter()
        .filter_map(|r| r.result.as_ref().ok().cloned())
        .collect();
    v.failed = order
        .iter()
        .filter_map(|r| {
            r.result
                .as_ref()
                .err()
                .map(|e| (r.source.clone(), e.clone()))
        })
        .collect();
    v.drives = v.per_drive.len();
    v.drives_verified_alone = v.per_drive.iter().filter(|e| e.verified_alone).count();
    if v.per_drive.is_empty() {
        v.reason = "no_drive_refitted";
        v.why = format!(
            "no_drive_refitted: no drive could be refitted with `{term}` (the failed list \
             names each one's error)"
        );
        d.best_edit = None;
        d.summary = super::pooled::summary(d);
        return;
    }
    let sum = |f: fn(&DriveEdit) -> f64| v.per_drive.iter().map(f).sum::<f64>();
    let (before, after) = (sum(|e| e.sse_before), sum(|e| e.sse_after));
    let gain = if before > 0.0 {
        (before - after) / before
    } else {
        0.0
    };
    let se = sum(|e| e.loss_se * e.loss_se).sqrt();
    let z = if se > 0.0 {
        sum(|e| e.loss_gain) / se
    } else {
        0.0
    };
    (v.gain, v.z) = (Some(gain), Some(z));
    v.edit = v.per_drive.first().map(|e| e.edit.clone());
    v.terms = v.per_drive.first().map(|e| e.terms.clone());
    v.reason = if z.partial_cmp(&v.z_bar).is_none_or(|o| o.is_lt()) {
        "not_significant_pooled_z"
    } else if gain.partial_cmp(&0.0).is_none_or(|o| o.is_le()) {
        "no_pooled_gain"
    } else {
        "verified_pooled_z"
    };
    v.verified = v.reason == "verified_pooled_z";
    let figures = format!(
        "over {} drives it gains {:.2} % of the held-out squared error at z = {:.2} (bar \
         {}); {} of {} drives verify it alone",
        v.drives,
        100.0 * gain,
        z,
        v.z_bar,
        v.drives_verified_alone,
        v.drives
    );
    v.why = match v.reason {
        "verified_pooled_z" => format!("verified_pooled_z: `{term}` {figures}"),
        "no_pooled_gain" => {
            format!("no_pooled_gain: `{term}` {figures}, but the squared error does not fall")
        }
        _ => format!("not_significant_pooled_z: `{term}` {figures}: below the bar"),
    };
    d.best_edit = v.verified.then_some(term);
    d.summary = super::pooled::summary(d);
}

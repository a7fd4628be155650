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
//! paired differences summed over blocks of consecutive rows (the diagnosis's null block), so
//! serially correlated errors do not make a small gain look sure. An edit is *verified* when
//! its gain is at least [`super::DiagnoseConfig::min_effect`] and its block z-score at least
//! [`VerifyConfig::min_z`].

use serde::{Deserialize, Serialize};

use super::model::ModelDiagnosisError;
use super::{Diagnosis, FeatureReport};
use crate::fit::{CheckedFitOptions, fit};
use crate::log::Log;
use crate::model::terms::parse_term;
use crate::model::{ModelEdit, ModelSpec, SpecError};

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
    /// Checks every setting's range; the error names the setting.
    pub fn validate(&self) -> Result<(), super::DiagnoseError> {
        let bad =
            |field, message: String| Err(super::DiagnoseError::InvalidConfig { field, message });
        if !(2..=20).contains(&self.folds) {
            return bad("verify_folds", format!("{} is not in 2..=20", self.folds));
        }
        if !(1..=20).contains(&self.candidates) {
            return bad(
                "verify_candidates",
                format!("{} is not in 1..=20", self.candidates),
            );
        }
        if !(self.min_z.is_finite() && self.min_z >= 0.0) {
            return bad(
                "min_z",
                format!("{} is not a finite number ≥ 0", self.min_z),
            );
        }
        Ok(())
    }
}

/// One suggested edit, refitted and scored out of sample. Equality ignores the typed edit
/// (compared by its text).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct VerifiedEdit {
    /// The feature (or `drift → FEATURE` absorption, or `A × B` pair) that led to the edit.
    pub feature: String,
    /// The edit in words (`add col:temp_c`, `replace poly2 by table:25`).
    pub edit: String,
    /// The model's terms after the edit.
    pub terms: String,
    /// Out-of-sample error std of the model before the edit (bias unit).
    pub std_before: f64,
    /// Out-of-sample error std after the edit (bias unit).
    pub std_after: f64,
    /// Verified gain: 1 − MSE_after / MSE_before (may be negative: the edit made it worse).
    pub gain: f64,
    /// Block z-score of the gain (paired squared-error differences, blocks of consecutive rows).
    pub z: f64,
    /// Whether the gain is both practical and beyond noise (see the module docs).
    pub verified: bool,
    /// The typed edit (not serialised).
    #[serde(skip)]
    pub model_edit: Option<ModelEdit>,
}

impl PartialEq for VerifiedEdit {
    fn eq(&self, o: &Self) -> bool {
        self.feature == o.feature
            && self.edit == o.edit
            && self.terms == o.terms
            && self.std_before.to_bits() == o.std_before.to_bits()
            && self.std_after.to_bits() == o.std_after.to_bits()
            && self.gain.to_bits() == o.gain.to_bits()
            && self.z.to_bits() == o.z.to_bits()
            && self.verified == o.verified
    }
}

/// A suggestion that could not be applied or fitted, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RejectedEdit {
    /// The feature that led to it.
    pub feature: String,
    /// The term tried.
    pub term: String,
    /// Why it failed (the spec or fit error).
    pub why: String,
}

/// The verified edits of one diagnosis.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Verification {
    /// Folds of consecutive seeks.
    pub folds: usize,
    /// Out-of-sample error std of the model as it is (bias unit).
    pub std_before: f64,
    /// Block length (rows) of the z-score.
    pub block_len: usize,
    /// Every edit that fitted, largest verified gain first.
    pub edits: Vec<VerifiedEdit>,
    /// Suggestions that could not be applied or fitted.
    pub rejected: Vec<RejectedEdit>,
    /// Why nothing was verified, when the model as it is cannot be refitted on this log (its
    /// terms need something the log lacks, such as a covariate that varies).
    #[serde(default)]
    pub not_run: Option<String>,
}

impl Verification {
    /// The best verified edit, if any.
    pub fn best(&self) -> Option<&VerifiedEdit> {
        self.edits.first().filter(|e| e.verified)
    }
}

/// A candidate for verification: the feature it comes from and the terms to try, best first
/// (the first that applies and fits is scored; for a covariate every one is scored and the
/// best kept, so a lagged term wins when the lag fits better).
#[derive(Debug, Clone, PartialEq)]
pub struct Candidate {
    /// The feature (or description) the suggestion comes from.
    pub feature: String,
    /// Terms to try, best first.
    pub terms: Vec<String>,
    /// Score every term and keep the best, instead of stopping at the first that fits.
    pub try_all: bool,
    /// Knot spacing for a `table` (from the position smoother's cross-validated bins).
    pub table_spacing: Option<f64>,
}

/// The knot spacing a position smoother chose: the feature's range over its cross-validated
/// number of bins, rounded to two significant digits.
pub fn table_spacing(f: &FeatureReport) -> Option<f64> {
    let lo = f.curve.iter().filter_map(|c| c.lower).reduce(f64::min)?;
    let hi = f.curve.iter().filter_map(|c| c.upper).reduce(f64::max)?;
    let bins = f.bins.max(2) as f64;
    let h = (hi - lo) / bins;
    (h.is_finite() && h > 0.0).then(|| {
        let mag = 10f64.powf(h.log10().floor() - 1.0);
        (h / mag).round() * mag
    })
}

/// The candidates of a diagnosis: its leading flagged features with their suggested term and
/// the alternatives not in the model yet, the screened interactions (`by:A:B`) and what
/// adaptive terms absorbed.
pub fn candidates(d: &Diagnosis, max: usize) -> Vec<Candidate> {
    let mut c = feature_candidates(d, max);
    c.extend(d.interactions.iter().map(|i| Candidate {
        feature: format!("{} × {}", i.a, i.b),
        terms: vec![i.suggested_term.clone()],
        try_all: false,
        table_spacing: None,
    }));
    c.extend(d.absorbed.iter().filter_map(|a| {
        let mut terms: Vec<String> = a.suggested_term.iter().cloned().collect();
        terms.extend(a.alternatives.iter().cloned());
        (!terms.is_empty()).then(|| Candidate {
            feature: format!("{} → {}", a.term, a.feature),
            try_all: true,
            terms,
            table_spacing: None,
        })
    }));
    c
}

fn feature_candidates(d: &Diagnosis, max: usize) -> Vec<Candidate> {
    d.features
        .iter()
        .filter(|f| f.flagged)
        .filter(|f| f.suggested_term.is_some())
        .take(max)
        .map(|f| {
            let mut terms: Vec<String> = f.suggested_term.iter().cloned().collect();
            terms.extend(f.alternatives.iter().cloned());
            Candidate {
                feature: f.name.clone(),
                try_all: terms.iter().any(|t| t.starts_with("col:")),
                terms,
                table_spacing: (f.name == "position").then(|| table_spacing(f)).flatten(),
            }
        })
        .collect()
}

/// The typed edit for suggested `term` on `spec`: a `table` replaces `poly2` (or a coarser
/// table) with the cross-validated spacing, since the two span the same position polynomial
/// and cannot be fitted together; everything else is added.
pub fn edit_for(
    term: &str,
    spec: &ModelSpec,
    table_spacing: Option<f64>,
) -> Result<ModelEdit, SpecError> {
    let has = |name: &str| spec.terms.iter().any(|t| t.name() == name);
    if term == "table" || term.starts_with("table:") {
        let new = match table_spacing {
            Some(h) if term == "table" => {
                parse_term(&format!("table:{}", crate::log::fmt_trimmed(h, 6)))?
            }
            _ => parse_term(term)?,
        };
        if has("poly2") {
            return Ok(ModelEdit::Replace {
                old: "poly2".into(),
                new,
            });
        }
        if let Some(old) = spec
            .terms
            .iter()
            .map(|t| t.name())
            .find(|n| n == "table" || n.starts_with("table:"))
        {
            return Ok(ModelEdit::Replace { old, new });
        }
        return Ok(ModelEdit::Add(new));
    }
    Ok(ModelEdit::Add(parse_term(term)?))
}

/// Out-of-sample residuals of `spec` on `log`, one per measured row in log order: fitted with
/// each of `folds` contiguous stretches of measured rows blanked, replayed over the whole log,
/// scored on the blanked stretch (see the module docs).
pub fn cv_residuals(
    spec: &ModelSpec,
    log: &Log,
    folds: usize,
    opts: &CheckedFitOptions,
) -> Result<Vec<f64>, ModelDiagnosisError> {
    let measured: Vec<usize> = log
        .rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.bias.is_some())
        .map(|(i, _)| i)
        .collect();
    let n = measured.len();
    let mut out = vec![0.0; n];
    let terms = spec.to_string();
    for k in 0..folds {
        let (a, b) = (k * n / folds, (k + 1) * n / folds);
        if a == b {
            continue;
        }
        let mut masked = log.clone();
        for &i in &measured[a..b] {
            masked.rows[i].bias = None;
        }
        let model = fit(spec, &masked, opts).map_err(|source| ModelDiagnosisError::Fit {
            step: k,
            terms: terms.clone(),
            file: log.schema.file.clone(),
            source: Box::new(source),
        })?;
        let p = super::replay_model(&model, log)?;
        out[a..b].copy_from_slice(&p.residual[a..b]);
    }
    Ok(out)
}

/// Verified gain and its block z-score of `after` over `before` (paired residuals).
fn paired_gain(before: &[f64], after: &[f64], block: usize) -> (f64, f64) {
    let n = before.len();
    let mse = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>() / n.max(1) as f64;
    let (mb, ma) = (mse(before), mse(after));
    let gain = if mb > 0.0 { 1.0 - ma / mb } else { 0.0 };
    let block = block.max(1);
    let sums: Vec<f64> = before
        .chunks(block)
        .zip(after.chunks(block))
        .map(|(b, a)| b.iter().zip(a).map(|(b, a)| b * b - a * a).sum())
        .collect();
    let m = sums.len() as f64;
    let z = match crate::numeric::stats::std_dev(&sums) {
        Some(sd) if sd > 0.0 => sums.iter().sum::<f64>() / m / (sd / m.sqrt()),
        _ => 0.0,
    };
    (gain, z)
}

fn std_of(r: &[f64]) -> f64 {
    crate::numeric::stats::std_dev(r).unwrap_or(0.0)
}

/// Verifies `cands` on `log` for the model `spec` (see the module docs): each candidate's
/// first term that applies and fits (every term for `try_all`, keeping the best) is scored;
/// edits are sorted by verified gain, largest first. `block_len` is the z-score's block
/// (use the diagnosis's `null_block_len`), `min_effect` the practical minimum gain.
pub fn verify(
    spec: &ModelSpec,
    log: &Log,
    cands: &[Candidate],
    block_len: usize,
    min_effect: f64,
    config: &VerifyConfig,
) -> Result<Verification, ModelDiagnosisError> {
    config.validate()?;
    let mut v = Verification {
        folds: config.folds,
        block_len,
        ..Verification::default()
    };
    let before = match cv_residuals(spec, log, config.folds, &config.fit) {
        Ok(r) => r,
        Err(e) => {
            v.not_run = Some(format!(
                "the model `{spec}` cannot be refitted on this log, so no suggestion was \
                 verified: {}",
                error_chain(&e)
            ));
            return Ok(v);
        }
    };
    v.std_before = std_of(&before);
    let mut seen: Vec<String> = Vec::new();
    for c in cands {
        let mut best: Option<VerifiedEdit> = None;
        for term in &c.terms {
            let attempt = edit_for(term, spec, c.table_spacing).and_then(|e| {
                let s = spec.apply(&e)?;
                Ok((e, s))
            });
            let (edit, next) = match attempt {
                Ok(x) => x,
                Err(e) => {
                    v.rejected.push(RejectedEdit {
                        feature: c.feature.clone(),
                        term: term.clone(),
                        why: e.to_string(),
                    });
                    continue;
                }
            };
            if seen.contains(&next.to_string()) {
                continue;
            }
            let after = match cv_residuals(&next, log, config.folds, &config.fit) {
                Ok(r) => r,
                Err(e) => {
                    v.rejected.push(RejectedEdit {
                        feature: c.feature.clone(),
                        term: term.clone(),
                        why: error_chain(&e),
                    });
                    continue;
                }
            };
            seen.push(next.to_string());
            let (gain, z) = paired_gain(&before, &after, block_len);
            let e = VerifiedEdit {
                feature: c.feature.clone(),
                edit: edit.to_string(),
                terms: next.to_string(),
                std_before: v.std_before,
                std_after: std_of(&after),
                gain,
                z,
                verified: gain >= min_effect && z >= config.min_z,
                model_edit: Some(edit),
            };
            if best.as_ref().is_none_or(|b| e.gain > b.gain) {
                best = Some(e);
            }
            if !c.try_all {
                break;
            }
        }
        v.edits.extend(best);
    }
    v.edits
        .sort_by(|a, b| b.verified.cmp(&a.verified).then(b.gain.total_cmp(&a.gain)));
    Ok(v)
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

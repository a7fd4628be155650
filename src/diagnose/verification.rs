//! The verification's report: each suggested edit refitted and scored out of sample, as the
//! [`Diagnosis`](super::Diagnosis) carries it (the refits themselves are model-structure
//! selection's, a stage above this one).

use serde::{Deserialize, Serialize};

use super::Reason;
use crate::model::ModelEdit;

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
    /// The same gain within folds: each fold's mean taken out of both residual series first
    /// (`verify::gain_within_folds`); an edit is verified only if this too reaches the practical
    /// minimum.
    #[serde(default)]
    pub gain_within_folds: f64,
    /// z-score of the gain: the paired Huber-loss differences' sum over the block standard
    /// error of their noise part (the change times the residual after the edit).
    pub z: f64,
    /// Whether the gain is both practical and beyond noise (see the module docs).
    pub verified: bool,
    /// The rule that decided `verified` ([`Reason`]): verified, or the first rule it fails —
    /// below the practical minimum (out of sample), only re-levels the folds, not significant,
    /// not a lower loss in every fold.
    pub reason: Reason,
    /// The bar `z` had to reach (the stricter bar of an unflagged feature's edit and of the
    /// second round is one higher).
    pub z_bar: f64,
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
            && self.gain_within_folds.to_bits() == o.gain_within_folds.to_bits()
            && self.z.to_bits() == o.z.to_bits()
            && self.verified == o.verified
            && self.reason == o.reason
            && self.z_bar.to_bits() == o.z_bar.to_bits()
    }
}

/// A suggestion that could not be applied or fitted, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RejectedEdit {
    /// The feature that led to it.
    pub feature: String,
    /// The term tried.
    pub term: String,
    /// The rule: the term cannot be applied to the model, or the fit failed.
    pub reason: Reason,
    /// Why, in words (the spec or fit error, or how the refit blew up).
    pub why: String,
}

/// The verified edits of one diagnosis.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Verification {
    /// Folds of consecutive seeks.
    pub folds: usize,
    /// Out-of-sample error std of the model as it is (bias unit).
    pub std_before: f64,
    /// The diagnosis's null block (rows); each edit's z-score uses the block of the noise part
    /// of its own paired differences (see `conditional_z` in the module source).
    pub block_len: usize,
    /// Every edit that fitted, largest verified gain first.
    pub edits: Vec<VerifiedEdit>,
    /// Suggestions that could not be applied or fitted.
    pub rejected: Vec<RejectedEdit>,
    /// Why nothing was verified, when the model as it is cannot be refitted on this log (its
    /// terms need something the log lacks, such as a covariate that varies).
    #[serde(default)]
    pub not_run: Option<String>,
    /// The practical minimum gain an edit had to reach, out of sample and within folds
    /// ([`super::DiagnoseConfig::min_effect`]).
    #[serde(default)]
    pub min_effect: f64,
    /// The second round: the edits verified **on top of** the best one (see the module docs);
    /// left out of the JSON when the round did not run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_round: Option<SecondRound>,
}

/// The second verification round of a diagnosis (see the module docs): the best verified edit
/// is put into the model, and the other candidates that can pay are refitted and scored out of
/// sample on top of it, on the same folds.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SecondRound {
    /// The best verified edit of the first round, put into the model first.
    pub on_top_of: String,
    /// The model's terms with it: the model every edit below is applied to.
    pub base_terms: String,
    /// Out-of-sample error std of that model (the best edit's `std_after`; bias unit).
    pub std_before: f64,
    /// Every edit scored on top, largest verified gain first; their `std_before`, `gain` and
    /// `z` are against the model with the best edit. All are judged at the stricter bar of the
    /// unflagged features (z ≥ [`VerifyConfig::min_z`](crate::select::VerifyConfig::min_z) + 1, a lower loss in every fold).
    pub edits: Vec<VerifiedEdit>,
    /// Suggestions that could not be applied on top or fitted.
    pub rejected: Vec<RejectedEdit>,
    /// When an edit holds on top: the two edits together, the advice a user applies.
    pub combined: Option<CombinedEdit>,
}

/// Two verified edits applied together (the first round's best and the best that holds on top
/// of it): the model spec to fit (`biasctl fit --terms`, `biasctl discover --start`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CombinedEdit {
    /// The edits, in the order they are applied.
    pub edits: Vec<String>,
    /// The model's terms with both (a `bump`/`step` with the centre or threshold it finds on
    /// the whole log).
    pub terms: String,
    /// Out-of-sample error std of the model as it is (bias unit).
    pub std_before: f64,
    /// Out-of-sample error std with both edits (bias unit).
    pub std_after: f64,
    /// Their gain together: 1 − MSE_after / MSE_before, i.e. `1 − (1 − g₁)(1 − g₂)` of the two
    /// verified gains.
    pub gain: f64,
}

impl Verification {
    /// The best verified edit, if any.
    pub fn best(&self) -> Option<&VerifiedEdit> {
        self.edits.first().filter(|e| e.verified)
    }

    /// Why `e` is (not) verified, in words: its rule ([`VerifiedEdit::reason`]) first, then
    /// the figures that decided it.
    pub fn why_not_verified(&self, e: &VerifiedEdit) -> String {
        let pct = |v: f64| format!("{:.1} %", 100.0 * v);
        let rule = e.reason.words();
        match e.reason {
            Reason::BelowPracticalMinimum => {
                let (g, m) = super::apart(e.gain, self.min_effect, 100.0, 1);
                format!(
                    "{rule}: out of sample it gains {g} % of the error variance, less than the \
                     {m} % that matters"
                )
            }
            Reason::OnlyRelevelsFolds => {
                let (g, m) = super::apart(e.gain_within_folds, self.min_effect, 100.0, 1);
                format!(
                    "{rule}: within folds it gains {g} % of the error variance, below the \
                     practical minimum of {m} %"
                )
            }
            Reason::NotSignificant => {
                let (z, bar) = super::apart(e.z, e.z_bar, 1.0, 1);
                format!(
                    "{rule}: z = {z} is below the bar of {bar}, so the gain is within what \
                     noise allows"
                )
            }
            Reason::NotInEveryFold => format!(
                "{rule}: at the stricter bar an edit must lower the loss in each of the {} \
                 folds, and this one does not",
                self.folds
            ),
            _ => format!(
                "{rule}: it gains {} out of sample and {} within folds (z = {:.1}, bar {:.1})",
                pct(e.gain),
                pct(e.gain_within_folds),
                e.z,
                e.z_bar
            ),
        }
    }
}

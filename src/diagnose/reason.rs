//! The rule that decided a verdict: why a feature is flagged or not, why an edit is verified or
//! not, why `discover` stopped. Every verdict carries one ([`Reason`], JSON key `reason`, in
//! snake case), and the words every text prints for it begin with [`Reason::words`].

use serde::{Deserialize, Serialize};

/// The rule that decided a verdict (JSON: its snake-case name, `"not_significant"`).
///
/// A feature of the diagnosis is [`Reason::Flagged`], [`Reason::FlaggedByRefit`],
/// [`Reason::BelowPracticalMinimum`], [`Reason::NotSignificant`] or [`Reason::NotAnalysed`].
/// A verified edit is [`Reason::Verified`] or, checked in this order, the first rule it fails:
/// [`Reason::BelowPracticalMinimum`] (its gain out of sample), [`Reason::OnlyRelevelsFolds`]
/// (its gain within folds), [`Reason::NotSignificant`] (its z-score), [`Reason::NotInEveryFold`]
/// (the stricter bar's lower loss in every fold). A suggestion that was not scored is
/// [`Reason::NotApplicable`] or [`Reason::FitFailed`]. `discover` stops for the reason of the
/// best scored edit, or [`Reason::NothingFlagged`], [`Reason::StepLimit`],
/// [`Reason::FreeRunWorse`], [`Reason::FitFailed`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum Reason {
    /// A feature: significant (family-wise) and explaining at least the practical minimum,
    /// alone and beyond the features ranked before it.
    Flagged,
    /// A feature the one-dimensional screen did not flag, whose edit was verified by its
    /// refit at the stricter bar.
    FlaggedByRefit,
    /// A feature that could not be analysed (too few distinct values, too few rows).
    NotAnalysed,
    /// An edit: its gain reaches the practical minimum out of sample and within folds, its
    /// z-score the bar (and, at the stricter bar, it lowers the loss in every fold).
    Verified,
    /// Below the practical minimum: a feature explains less than
    /// [`min_effect`](super::DiagnoseConfig::min_effect) of the residual variance (alone or
    /// beyond the features ranked before it), or an edit gains less than it out of sample.
    BelowPracticalMinimum,
    /// Practical out of sample but not within folds: the edit only re-levels the folds.
    OnlyRelevelsFolds,
    /// Not significant: a feature's family-wise p is above `alpha`, or an edit's z-score is
    /// below the bar.
    NotSignificant,
    /// Practical and significant, but at the stricter bar the edit does not lower the loss in
    /// every fold.
    NotInEveryFold,
    /// The suggested term could not be applied to the model.
    NotApplicable,
    /// The refit failed: an error, or an out-of-sample error that blew up.
    FitFailed,
    /// `discover`: no feature is flagged, so nothing is suggested.
    NothingFlagged,
    /// `discover`: the step limit was reached.
    StepLimit,
    /// `discover`: every verified edit gains on the one-step figure only (an adaptive term);
    /// in free run it makes the error worse.
    FreeRunWorse,
}

impl Reason {
    /// The rule in a few words, as every text begins the reason it prints.
    pub fn words(self) -> &'static str {
        match self {
            Reason::Flagged => "flagged",
            Reason::FlaggedByRefit => "flagged by its verified refit",
            Reason::NotAnalysed => "not analysed",
            Reason::Verified => "verified",
            Reason::BelowPracticalMinimum => "below the practical minimum",
            Reason::OnlyRelevelsFolds => "it only re-levels the folds",
            Reason::NotSignificant => "not significant",
            Reason::NotInEveryFold => "not a lower loss in every fold",
            Reason::NotApplicable => "the term cannot be applied",
            Reason::FitFailed => "the fit failed",
            Reason::NothingFlagged => "nothing is flagged",
            Reason::StepLimit => "the step limit was reached",
            Reason::FreeRunWorse => "the free-run error grows",
        }
    }

    /// Its JSON name (`"not_significant"`).
    pub fn key(self) -> String {
        serde_json::to_value(self)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default()
    }
}

impl std::fmt::Display for Reason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.words())
    }
}

//! Model diagnosis: compare a model with the measurements, see where it fails, and learn which
//! physical effect is missing.
//!
//! The engine takes a [`FeatureTable`] (every candidate feature of every measured row) and the
//! model's residuals (measured − predicted, one per measured row) and asks, for each feature,
//! how much of the residual variance a flexible one-dimensional smoother of that feature
//! explains **out of sample**. The strongest feature, the shape of the residual against it and
//! the model term that addresses it become plain-words advice.
//!
//! ```
//! use biasctl::{DiagnoseConfig, diagnose::FeatureTable, diagnose};
//! use biasctl::{ColumnMap, Log};
//! // A log whose residual jumps whenever the seek reverses direction.
//! let mut text = String::from("time_s,track,bias\n");
//! let mut residuals = Vec::new();
//! let mut track = 100i64;
//! for i in 0..400i64 {
//!     track = (track + (i * 37 % 23) - 11).clamp(0, 250);
//!     text.push_str(&format!("{},{track},0\n", i as f64 * 0.5));
//! }
//! let log = Log::from_reader("demo.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
//! let table = FeatureTable::from_log(&log);
//! let change = table.column("direction_change").unwrap();
//! for (i, v) in change.iter().enumerate() {
//!     residuals.push(5.0 * v.unwrap_or(0.0) + ((i * 7919) % 13) as f64 * 0.1);
//! }
//! let config = DiagnoseConfig { permutations: 99, ..DiagnoseConfig::default() }.check().unwrap();
//! let d = diagnose(&table, &residuals, &config).unwrap();
//! assert_eq!(d.features[0].name, "direction_change");
//! assert_eq!(d.features[0].suggested_term.as_deref(), Some("seek"));
//! ```
//!
//! ## How the cross-validation folds are cut, and why
//! Residuals of a drive are serially correlated (drift, slow thermal effects). Purely random
//! folds let a held-out seek be "predicted" by its training neighbours in time through any
//! feature that changes slowly; one contiguous block per fold goes wrong the other way: the
//! held-out stretch of time has no training data at all, so a genuine drift could never be
//! predicted from `elapsed_s`. We use **interleaved blocks**: the seek sequence is cut into
//! contiguous blocks of [`DiagnoseConfig::block_len`] seeks (auto: about n/(25·folds), at most
//! 50) and the blocks are dealt to the folds at random (seeded). Correlation shorter than a
//! block cannot leak across folds, yet every stretch of time keeps training data in the
//! neighbouring blocks, so a slow drift is predictable from `elapsed_s`/`seek_index` — and only
//! from them — and ranks them first instead of smearing onto every feature.
//!
//! ## How significance is tested, and why
//! For every feature the statistic is the smallest one-way-ANOVA F-test p-value over the
//! candidate binnings (an adaptive test: it looks at every number of bins the smoother may pick,
//! so picking the best does not inflate it). It is calibrated by permuting the residuals
//! ([`DiagnoseConfig::permutations`] times, seeded), and the family of features is controlled
//! with the Westfall–Young single-step min-p method: a feature's `p_value` is the fraction of
//! permutations in which *any* feature looked at least as strong. So "no feature flagged at 1 %"
//! fails on pure noise at most 1 % of the time, whatever the number of features and however
//! correlated they are (`seek_length`, `seek_abs` and `direction` are). The uncorrected
//! per-feature value is reported as `p_value_raw`. Plain permutation treats the residuals as
//! exchangeable under the null; for a feature that is independent of time (random targets)
//! that holds whatever the residuals' serial correlation, for a slowly varying feature it does
//! not. So the residuals are permuted in blocks of consecutive seeks (`null_block_len`), and
//! each feature's block is as long as the pair (feature, residual) needs
//! (`feature_null_block`): the residual's block for a feature as slow as the residual,
//! shorter for one that decorrelates sooner (the cross-products decorrelate with the faster of
//! the two), single rows for the time features. Every permutation has its own seeded random
//! streams, so the p-values do not depend on the number of threads they run on.

//!
//! ## Confounded candidates: ranking by what each adds beyond the others
//! Candidates are often strongly related: a slow logged temperature is nearly a function of
//! `elapsed_s`; the per-sample position change is velocity × the sample time. Ranking by the
//! marginal `explained` alone then lets a built-in proxy edge out the physical column by noise.
//! So the **flagged** features (family-wise p ≤ alpha) go through a greedy forward pass of up to
//! `FORWARD_STEPS` steps: at each step every remaining one is cross-validated on what the
//! earlier ones left (the residual minus their **out-of-fold** smooths, so no row's own noise is
//! removed), and the one with the largest gain is taken — except among **near-ties** (gains
//! within `NEAR_TIE` of the best): there, for each tied candidate, the others are
//! re-evaluated after removing it; a candidate "explains another away" when at most
//! `EXPLAINED_AWAY` of the other's gain survives. The taken one is a candidate that explains
//! all the others away — a logged covariate before a built-in feature when several do (twins
//! the data cannot tell apart: the logged physical quantity is the actionable answer, the
//! built-in one its proxy) — or else the one leaving least of the others. Displaced twins get
//! a note. "Strongest first" in [`Diagnosis::features`] is this forward order, then the rest
//! by marginal `explained`; every report carries `explained_beyond_previous` (its gain beyond
//! the features ranked before it, or beyond all taken ones). `explained`, `p_value` and the
//! curve stay marginal. Likewise the direction-signed analysis (below) is chosen only when it
//! beats the plain one by more than `NEAR_TIE`: near a tie the even explanation is simpler.
//!
//! A diagnosis of an out-of-sample model also sees the model's own estimation error: a poly2
//! fitted on 3000 noisy seeks is off by tenths of a count, a true (small) structure in the
//! test residual that the test rightly detects; calibrate "no flag" claims with a long
//! training log.
//!
//! ## Effects that flip with direction, and outliers
//! Friction and lubricant effects of a pivot are hysteretic: P3 (time at track), P4/P5
//! (overshoot) and P6 (rest memory) all enter the bias as `direction × g(feature)`, so the
//! residual's plain mean against the feature is zero when both directions are equally common.
//! Every feature but `direction` is therefore also analysed against **residual × direction of
//! the last move** (its gain counted beyond a constant direction offset, so a missing
//! `direction` term does not leak into every feature); the stronger of the two is reported,
//! with `by_direction` set, and the permutation statistic is the smaller p-value of the two, so
//! the family-wise control still holds. Before the analysis the residuals are clipped at the
//! median ± 4 robust standard deviations: a handful of gross residuals (the start-up transient of
//! a state-space model replayed from rest) must not make the feature that isolates those rows
//! look like an effect. For the same reason a discrete value, or an undefined group, seen in
//! fewer than [`DiagnoseConfig::min_bin_rows`] rows is pooled with its neighbour.

mod absorbed;
pub(crate) mod advice;
mod column;
mod features;
mod forward;
mod ftest;
mod kernels;
mod lanes;
mod model;
mod pairs;
mod permutation;
mod pooled;
mod reason;
mod report;
mod screen;
mod smoother;
mod text;
mod values;
mod verification;

pub use absorbed::Absorption;
#[cfg(test)]
pub(crate) use absorbed::FAST_FORGETTING;
pub(crate) use absorbed::{absorbed, rate_warnings};
#[cfg(test)]
use advice::DAHL_TERM;
pub use advice::Shape;
pub use column::{FeatureColumn, FeatureOrigin};
pub(crate) use features::lagged_column;
pub use features::{DERIVED_VELOCITY, FeatureTable};
pub(crate) use model::model_table;
pub use model::{ModelDiagnosisError, diagnose_model, diagnose_residual, model_spec, replay_model};
pub use pairs::{GlobalCheck, Interaction};
pub use permutation::family_wise_p_values;
pub(crate) use permutation::null_block_len;
pub use pooled::{ScreenStatistics, screen_model, screen_statistics};
pub use reason::Reason;
pub(crate) use report::compare;
pub use report::{CurveBin, Diagnosis, FeatureReport, Whiteness};
pub(crate) use text::extend_summary;
pub(crate) use values::{apart, short};
pub use verification::{CombinedEdit, RejectedEdit, SecondRound, Verification, VerifiedEdit};

use crate::history::Feature;
use crate::io::OutputError;
use crate::numeric::stats;
use forward::{Ctx, gain};
use screen::{Reports, screen};

/// Smallest number of measured rows per cross-validation fold.
pub(crate) const MIN_ROWS_PER_FOLD: usize = 10;
/// Smallest number of measured rows for any diagnosis.
pub(crate) const MIN_ROWS: usize = 30;

/// An error of the diagnosis engine.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiagnoseError {
    /// Too few measured rows to cross-validate.
    #[error(
        "too few measured rows for a diagnosis: {rows}, but {folds}-fold cross-validation needs \
         at least {needed} (max({MIN_ROWS}, {MIN_ROWS_PER_FOLD} per fold)); measure more seeks \
         or use fewer folds"
    )]
    TooFewRows {
        /// Measured rows given.
        rows: usize,
        /// Rows needed.
        needed: usize,
        /// Folds configured.
        folds: usize,
    },
    /// The residuals do not line up with the measured rows.
    #[error(
        "{residuals} residuals for {rows} measured rows: give exactly one residual per row with a \
         measured bias, in log order"
    )]
    LengthMismatch {
        /// Number of residuals given.
        residuals: usize,
        /// Number of measured rows in the feature table.
        rows: usize,
    },
    /// A residual is NaN, infinite or too large to square.
    #[error(
        "residual {index} (log line {line}) is {value}: every residual must be a finite number below 1e100 in magnitude"
    )]
    BadResidual {
        /// 0-based index among the measured rows.
        index: usize,
        /// Log line of that row (0 if unknown).
        line: u64,
        /// The value.
        value: f64,
    },
    /// A configuration value is out of range.
    #[error("invalid diagnosis setting {field}: {message}")]
    InvalidConfig {
        /// The setting.
        field: crate::field::Field,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A column added to a feature table has the wrong length.
    #[error("feature column `{name}` has {values} values but the table has {rows} measured rows")]
    ColumnLength {
        /// Column name.
        name: String,
        /// Values given.
        values: usize,
        /// Rows in the table.
        rows: usize,
    },
    /// A column name is already taken.
    #[error("feature column `{name}` is already in the table")]
    DuplicateColumn {
        /// Column name.
        name: String,
    },
    /// A ladder step's error std is not a finite non-negative number.
    #[error("ladder step {step} ({terms}): error std {std} is not a finite non-negative number")]
    BadLadderStd {
        /// 0-based step.
        step: usize,
        /// The step's terms, comma-separated.
        terms: String,
        /// The value.
        std: f64,
    },
    /// Writing an output file failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// Settings of the diagnosis as given (unchecked). Build with struct-update syntax from
/// [`Default`]; [`DiagnoseConfig::check`] validates them once into the
/// [`CheckedDiagnoseConfig`] that [`diagnose`] and the model entry points accept.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseConfig {
    /// Cross-validation folds, 2..=50 (default 5).
    pub folds: usize,
    /// Length of the contiguous blocks dealt to folds, in seeks; `None` = auto
    /// (clamp(n / (25·folds), 1, 50)). Must leave at least `folds` blocks.
    pub block_len: Option<usize>,
    /// Permutations of the significance test (default 199); at least ⌈1/alpha⌉ − 1 so that a
    /// p-value can reach `alpha`, at most 100 000.
    pub permutations: usize,
    /// Seed of the fold assignment and the permutations.
    pub seed: u64,
    /// Family-wise significance level for flagging a feature, in (0, 0.5] (default 0.01).
    pub alpha: f64,
    /// Most quantile bins a continuous feature is cut into (rounded down to a power of two),
    /// 2..=4096 (default 64).
    pub max_bins: usize,
    /// Fewest defined rows per quantile bin, ≥ 2 (default 10).
    pub min_bin_rows: usize,
    /// A feature with at most this many distinct values is discrete (one bin per value),
    /// 2..=256 (default 12).
    pub max_discrete: usize,
    /// Lags of the Ljung–Box whiteness test, ≥ 1 (default 10).
    pub ljung_box_lags: usize,
    /// Terms the model already has (`seek`, `dahl:2`, `col:temp_c`, …): never suggested again.
    pub existing_terms: Vec<String>,
    /// Block length of the permutation null, in seeks; `None` = auto from the residual's
    /// autocorrelation (`null_block_len`). 1 is the plain (exchangeable) row permutation.
    pub null_block: Option<usize>,
    /// Smallest practical effect: a significant feature is flagged only when it explains at
    /// least this fraction of the residual variance out of sample, beyond the features ranked
    /// before it (default 0.02: the error std falls by about 1 %), in [0, 1).
    pub min_effect: f64,
}

impl Default for DiagnoseConfig {
    fn default() -> Self {
        Self {
            folds: 5,
            block_len: None,
            permutations: 199,
            seed: 1,
            alpha: 0.01,
            max_bins: 64,
            min_bin_rows: 10,
            max_discrete: 12,
            ljung_box_lags: 10,
            existing_terms: Vec::new(),
            null_block: None,
            min_effect: 0.02,
        }
    }
}

impl DiagnoseConfig {
    /// Checks every setting's range; the error names the setting and what is allowed.
    fn validate(&self) -> Result<(), DiagnoseError> {
        let bad = |field, message: String| Err(DiagnoseError::InvalidConfig { field, message });
        if !(2..=50).contains(&self.folds) {
            return bad(
                crate::field::Field::Folds,
                format!("{} is not in 2..=50", self.folds),
            );
        }
        if self.block_len == Some(0) {
            return bad(
                crate::field::Field::BlockLen,
                "0 seeks; use at least 1 (or auto)".into(),
            );
        }
        if !(self.alpha > 0.0 && self.alpha <= 0.5) {
            return bad(
                crate::field::Field::Alpha,
                format!("{} is not in (0, 0.5]", self.alpha),
            );
        }
        let needed = ((1.0 / self.alpha).ceil() as usize).saturating_sub(1);
        if self.permutations < needed || self.permutations > 100_000 {
            return bad(
                crate::field::Field::Permutations,
                format!(
                    "{} is not in {needed}..=100000 (at least 1/alpha − 1 = {needed} so that a \
                     p-value can reach alpha = {})",
                    self.permutations, self.alpha
                ),
            );
        }
        if !(2..=4096).contains(&self.max_bins) {
            return bad(
                crate::field::Field::MaxBins,
                format!("{} is not in 2..=4096", self.max_bins),
            );
        }
        if self.min_bin_rows < 2 {
            return bad(
                crate::field::Field::MinBinRows,
                format!("{} is below 2", self.min_bin_rows),
            );
        }
        if !(2..=256).contains(&self.max_discrete) {
            return bad(
                crate::field::Field::MaxDiscrete,
                format!("{} is not in 2..=256", self.max_discrete),
            );
        }
        if self.ljung_box_lags == 0 {
            return bad(
                crate::field::Field::LjungBoxLags,
                "0; use at least 1".into(),
            );
        }
        if self.null_block == Some(0) {
            return bad(
                crate::field::Field::NullBlock,
                "0 seeks; use at least 1 (or auto)".into(),
            );
        }
        if !(self.min_effect >= 0.0 && self.min_effect < 1.0) {
            return bad(
                crate::field::Field::MinEffect,
                format!("{} is not in [0, 1)", self.min_effect),
            );
        }
        Ok(())
    }

    /// Checks every setting's range once (the error names the setting and what is allowed) into
    /// the checked type the entry points accept.
    pub fn check(self) -> Result<CheckedDiagnoseConfig, DiagnoseError> {
        self.validate()?;
        Ok(CheckedDiagnoseConfig(self))
    }

    /// Fewest measured rows a diagnosis with these settings accepts.
    pub fn min_rows(&self) -> usize {
        MIN_ROWS.max(self.folds * MIN_ROWS_PER_FOLD)
    }

    fn block_len_for(&self, n: usize) -> usize {
        self.block_len
            .unwrap_or_else(|| (n / (25 * self.folds)).clamp(1, 50))
    }
}

checked_settings! {
    /// Diagnosis settings that passed [`DiagnoseConfig::check`]; read them through `Deref`.
    /// `Default` is the checked default.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct CheckedDiagnoseConfig(DiagnoseConfig);
}

impl CheckedDiagnoseConfig {
    /// Adds `term` to [`DiagnoseConfig::existing_terms`] (any text is valid there) unless it
    /// is already listed.
    pub fn add_existing_term(&mut self, term: String) {
        if !self.0.existing_terms.contains(&term) {
            self.0.existing_terms.push(term);
        }
    }
}

/// Diagnoses `residuals` (measured − predicted, one per measured row of `table`, in log order).
///
/// For every feature: the out-of-sample explained fraction of the residual variance by a binned
/// smoother (bins chosen by cross-validation), a family-wise permutation p-value, the curve's
/// shape, the suggested term and the error std expected once it is added; plus whiteness and
/// bimodality of the residuals. Features are sorted strongest first (explained, then p-value);
/// constant or never-defined features are listed last with a note. The residuals are in the
/// table's bias unit ([`FeatureTable::units`]), which labels the summary and the text.
pub fn diagnose(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<Diagnosis, DiagnoseError> {
    let n = table.len();
    let s = screen(table, residuals, config, Reports::All)?;
    let ctx = Ctx {
        direction: s.direction.as_deref(),
        fold: &s.fold,
        folds: config.folds,
        variance: s.variance,
    };
    // The residual's own statistics (one thread each: a sort for the dip test, the
    // Ljung–Box sums) run beside the pair screen instead of after it.
    let ((interactions, global), (whiteness, bimodality, dip)) = rayon::join(
        || pairs::screen(table, &s.left, &ctx, config),
        || {
            (
                Whiteness::of(residuals, config.ljung_box_lags, config.alpha),
                stats::bimodality_coefficient(residuals).filter(|b| b.is_finite()),
                stats::dip_test(residuals),
            )
        },
    );
    let mut d = Diagnosis {
        residual_std: s.residual_std,
        features: s.reports,
        whiteness,
        bimodality,
        dip,
        summary: String::new(),
        units: table.units().clone(),
        null_block_len: s.null_block,
        absorbed: Vec::new(),
        warnings: Vec::new(),
        verification: None,
        rows: n,
        alpha: config.alpha,
        interactions,
        global,
    };
    d.summary = text::summary(&d, n, config.alpha);
    Ok(d)
}

/// The flagged features of [`diagnose`]`(table, residuals, config)`, in its order, each
/// report bit for bit as `diagnose` makes it (tested against it): the same screen, without
/// the pair screen, the residual's own statistics, the summary and the reports of the
/// features that are not flagged — what a caller reading only the flags (the verification's
/// re-screen) would pay for nothing.
pub(crate) fn flagged_features(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<Vec<FeatureReport>, DiagnoseError> {
    Ok(screen(table, residuals, config, Reports::Flagged)?.reports)
}

/// Whether a feature is a time feature (`elapsed_s`, `seek_index`): tested against the plain
/// row permutation, since serial structure of the residual is the effect it stands for.
pub(crate) fn is_time(origin: FeatureOrigin) -> bool {
    matches!(
        origin,
        FeatureOrigin::BuiltIn(Feature::ElapsedS) | FeatureOrigin::BuiltIn(Feature::SeekIndex)
    )
}

#[cfg(test)]
mod tests;

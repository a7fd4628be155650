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
//! use biasctl::{DiagnoseConfig, FeatureTable, diagnose};
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
//! not. So the residuals are permuted in blocks of consecutive seeks ([`null_block_len`]), and
//! each feature's block is as long as the pair (feature, residual) needs
//! ([`feature_null_block`]): the residual's block for a feature as slow as the residual,
//! shorter for one that decorrelates sooner (the cross-products decorrelate with the faster of
//! the two), single rows for the time features. Every permutation has its own seeded random
//! streams, so the p-values do not depend on the number of threads they run on.

//!
//! ## Confounded candidates: ranking by what each adds beyond the others
//! Candidates are often strongly related: a slow logged temperature is nearly a function of
//! `elapsed_s`; the per-sample position change is velocity × the sample time. Ranking by the
//! marginal `explained` alone then lets a built-in proxy edge out the physical column by noise.
//! So the **flagged** features (family-wise p ≤ alpha) go through a greedy forward pass of up to
//! [`FORWARD_STEPS`] steps: at each step every remaining one is cross-validated on what the
//! earlier ones left (the residual minus their **out-of-fold** smooths, so no row's own noise is
//! removed), and the one with the largest gain is taken — except among **near-ties** (gains
//! within [`NEAR_TIE`] of the best): there, for each tied candidate, the others are
//! re-evaluated after removing it; a candidate "explains another away" when at most
//! [`EXPLAINED_AWAY`] of the other's gain survives. The taken one is a candidate that explains
//! all the others away — a logged covariate before a built-in feature when several do (twins
//! the data cannot tell apart: the logged physical quantity is the actionable answer, the
//! built-in one its proxy) — or else the one leaving least of the others. Displaced twins get
//! a note. "Strongest first" in [`Diagnosis::features`] is this forward order, then the rest
//! by marginal `explained`; every report carries `explained_beyond_previous` (its gain beyond
//! the features ranked before it, or beyond all taken ones). `explained`, `p_value` and the
//! curve stay marginal. Likewise the direction-signed analysis (below) is chosen only when it
//! beats the plain one by more than [`NEAR_TIE`]: near a tie the even explanation is simpler.
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
mod features;
mod model;
mod pairs;
mod report;
mod smoother;
mod values;
mod verification;

pub use absorbed::Absorption;
#[cfg(test)]
pub(crate) use absorbed::FAST_FORGETTING;
pub(crate) use absorbed::{absorbed, rate_warnings};
#[cfg(test)]
use advice::DAHL_TERM;
pub use advice::Shape;
pub(crate) use features::lagged_column;
pub use features::{DERIVED_VELOCITY, FeatureColumn, FeatureOrigin, FeatureTable};
pub(crate) use model::model_table;
pub use model::{ModelDiagnosisError, diagnose_model, diagnose_residual, model_spec, replay_model};
pub use pairs::{GlobalCheck, Interaction};
pub use report::{CurveBin, Diagnosis, FeatureReport, Whiteness};
pub(crate) use report::{compare, extend_summary};
pub(crate) use values::short;
pub use verification::{CombinedEdit, RejectedEdit, SecondRound, Verification, VerifiedEdit};

use crate::history::Feature;
use crate::numeric::rng::SimRng;
use crate::numeric::stats;
use crate::render::OutputError;
use rayon::prelude::*;
use smoother::{
    Binned, BlockLane, FTest, LANES, Permuted, SlotTable, Unusable, sst_of_sums, sst_one_pass,
};

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

/// Residuals larger than this in magnitude are rejected (their squares would overflow sums).
const MAX_RESIDUAL: f64 = 1e100;

/// One feature's intermediate results.
struct Analysed {
    binned: Binned,
    shift: u32,
    explained: f64,
    /// ln of the smallest F-test p-value over the plain and (if signable) the signed analysis.
    observed: f64,
    /// Whether the direction-signed analysis explains more than the plain one.
    by_direction: bool,
    /// Whether the signed analysis was run for this feature.
    signable: bool,
    /// Built-in feature or logged covariate.
    origin: FeatureOrigin,
}

/// The residuals multiplied by the direction of the last move (0 before the first move),
/// stored: the reference of the row-by-row products the diagnosis makes instead.
#[cfg(test)]
struct Signed {
    y: Vec<f64>,
    /// Sum of squares of `y` about its mean.
    sst: f64,
}

#[cfg(test)]
impl Signed {
    fn new(y: &[f64], direction: &[i8]) -> Signed {
        let y: Vec<f64> = y
            .iter()
            .zip(direction)
            .map(|(r, &d)| r * f64::from(d))
            .collect();
        Signed {
            sst: stats::sum_sq_about_mean(&y),
            y,
        }
    }
}

/// The direction values `d` (−1, 0, +1) as bytes; `None` (no direction-signed analysis)
/// if a value is not one of those (a built-in `direction` column never has another).
fn direction_bytes(d: impl Iterator<Item = f64>) -> Option<Vec<i8>> {
    let byte = |x: f64| -> Option<i8> {
        [-1i8, 0, 1]
            .into_iter()
            .find(|&b| f64::from(b).to_bits() == x.to_bits())
    };
    d.map(byte).collect()
}

/// Whether the direction-signed analysis applies to `col`: every feature but `direction`
/// itself (whose signed curve is a constant).
fn signable(col: &FeatureColumn) -> bool {
    col.origin != FeatureOrigin::BuiltIn(Feature::Direction)
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
    d.summary = report::summary(&d, n, config.alpha);
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

/// Which feature reports [`screen`] makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reports {
    /// Every column's ([`diagnose`]).
    All,
    /// The flagged columns' only ([`flagged_features`]).
    Flagged,
}

/// What [`screen`] leaves for the rest of [`diagnose`].
struct Screened {
    reports: Vec<FeatureReport>,
    residual_std: f64,
    null_block: usize,
    /// The residual left by the forward pass (the pair screen's input).
    left: Vec<f64>,
    fold: Vec<u8>,
    direction: Option<Vec<i8>>,
    variance: f64,
}

/// The one-dimensional screen of [`diagnose`]: every feature's smoother, the permutation
/// test, the forward pass and the features' reports (`which`), strongest first.
fn screen(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
    which: Reports,
) -> Result<Screened, DiagnoseError> {
    let n = table.len();
    if residuals.len() != n {
        return Err(DiagnoseError::LengthMismatch {
            residuals: residuals.len(),
            rows: n,
        });
    }
    if let Some((index, &value)) = residuals
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && v.abs() <= MAX_RESIDUAL))
    {
        return Err(DiagnoseError::BadResidual {
            index,
            line: table.line(index).unwrap_or(0),
            value,
        });
    }
    let needed = config.min_rows();
    if n < needed {
        return Err(DiagnoseError::TooFewRows {
            rows: n,
            needed,
            folds: config.folds,
        });
    }
    let block_len = config.block_len_for(n);
    let n_blocks = n.div_ceil(block_len);
    if n_blocks < config.folds {
        return Err(DiagnoseError::InvalidConfig {
            field: crate::field::Field::BlockLen,
            message: format!(
                "blocks of {block_len} seeks cut {n} rows into {n_blocks} blocks, fewer than the \
                 {} folds",
                config.folds
            ),
        });
    }

    // Clipped, then centred in place (no second copy of the residual).
    let mut y = winsorize(residuals);
    let mean = stats::mean(&y).unwrap_or(0.0);
    y.iter_mut().for_each(|v| *v -= mean);
    let sst: f64 = y.iter().map(|v| v * v).sum();
    let variance = sst / n as f64;
    let residual_std = stats::std_dev(residuals).unwrap_or(0.0);
    let fold = assign_folds(n, block_len, config.folds, config.seed);

    // The direction of the last move, for the direction-signed analysis (see the module docs):
    // one byte a row (−1, +1; 0 before the first move), read as the same `f64`s.
    let direction: Option<Vec<i8>> = table
        .column(Feature::Direction.name())
        .filter(|c| c.origin == FeatureOrigin::BuiltIn(Feature::Direction))
        .and_then(|c| direction_bytes(c.iter().map(|v| v.unwrap_or(0.0))));
    // The direction-signed residual's sum of squares about its mean; its values are made
    // row by row where they are read (`FTest::min_p_signed`), never stored.
    let signed_sst: Option<f64> = direction
        .as_ref()
        .map(|d| sum_sq_about_mean_rows(|| y.iter().zip(d).map(|(r, &d)| r * f64::from(d))));

    // Bin, cross-validate and compute the observed statistic of every usable feature.
    // Columns are independent (no random draws): in parallel, collected in table order.
    let mut analysed: Vec<Result<Analysed, Unusable>> = table
        .columns()
        .par_iter()
        .map(|col| {
            col.binned(config.max_bins, config.min_bin_rows, config.max_discrete)
                .map(|binned| {
                    let can_sign = signed_sst.is_some() && signable(col);
                    let g = gain(
                        &binned,
                        can_sign,
                        &y,
                        direction.as_deref(),
                        &fold,
                        config.folds,
                        variance,
                    );
                    let mut observed = FTest::new(&binned).min_p(&binned, &y, sst);
                    if let (Some(sst), Some(d)) = (signed_sst.filter(|_| can_sign), &direction) {
                        observed =
                            observed.min(FTest::new(&binned).min_p_signed(&binned, &y, d, sst));
                    }
                    Analysed {
                        binned,
                        shift: g.shift,
                        explained: g.explained,
                        observed,
                        by_direction: g.by_direction,
                        signable: can_sign,
                        origin: col.origin,
                    }
                })
        })
        .collect();

    let null_block = config
        .null_block
        .unwrap_or_else(|| null_block_len(&y))
        .clamp(1, n.max(1));
    // Each feature's null keeps as much serial structure as the pair (feature, residual)
    // has: the residual's block where the feature is as slow as the residual, shorter blocks
    // for a feature that decorrelates sooner (the cross-products decorrelate with the faster
    // of the two), single rows for the time features.
    let blocks: Vec<usize> = analysed
        .par_iter()
        .zip(table.columns())
        .map(|(a, col)| match a {
            Ok(a) if is_time(a.origin) => 1,
            Ok(_) if config.null_block.is_none() => feature_null_block(col.raw(), null_block),
            _ => null_block,
        })
        .collect();
    let (p_raw, p_adj) = permutation_test(
        &mut analysed,
        &y,
        sst,
        direction.as_deref(),
        &blocks,
        config,
        true,
    );

    let ctx = Ctx {
        direction: direction.as_deref(),
        fold: &fold,
        folds: config.folds,
        variance,
    };
    let significant: Vec<usize> = (0..analysed.len())
        .filter(|&j| {
            analysed[j]
                .as_ref()
                .is_ok_and(|a| a.explained > 0.0 && p_adj[j] <= config.alpha)
        })
        .collect();
    let forward = forward_pass(&analysed, &significant, &y, &ctx);
    // The clipped residual served the screen and the forward pass; the reports read the
    // residuals as given (freed before them: the reports' own buffers are the peak there).
    drop(y);

    // A column's flag from the screen alone (as its report sets it below).
    let flagged = |j: usize| {
        analysed[j].as_ref().is_ok_and(|a| {
            significant.contains(&j)
                && a.explained.min(forward.beyond[j].unwrap_or(0.0)) >= config.min_effect
        })
    };
    let wanted: Vec<usize> = (0..analysed.len())
        .filter(|&j| which == Reports::All || flagged(j))
        .collect();
    let signed_residuals: Option<Vec<f64>> = direction
        .as_ref()
        .filter(|_| {
            wanted
                .iter()
                .any(|&j| analysed[j].as_ref().is_ok_and(|a| a.by_direction))
        })
        .map(|d| {
            residuals
                .iter()
                .zip(d)
                .map(|(r, &d)| r * f64::from(d))
                .collect()
        });
    // One report per wanted column, independent of the others: in parallel, in column order.
    let mut reports: Vec<(usize, FeatureReport)> = wanted
        .par_iter()
        .map(|&j| {
            let (col, a) = (&table.columns()[j], &analysed[j]);
            let mut r = match a {
                Ok(a) => report::feature_report(
                    col,
                    a.shift,
                    &a.binned,
                    a.explained,
                    p_raw[j],
                    p_adj[j],
                    match (&signed_residuals, a.by_direction) {
                        (Some(s), true) => s,
                        _ => residuals,
                    },
                    a.by_direction,
                    direction.as_deref(),
                    residual_std,
                    config,
                ),
                Err(why) => report::skipped_report(col, why, residual_std),
            };
            r.explained_beyond_previous = forward.beyond[j];
            r.significant = significant.contains(&j);
            let beyond = forward.beyond[j].unwrap_or(0.0);
            r.flagged = r.significant && r.explained.min(beyond) >= config.min_effect;
            if r.significant && !r.flagged {
                let note = format!(
                    "significant (p = {:.3}) but too small to matter: {:.1} % of the residual \
                     variance alone, {:.1} % beyond the features ranked before it, below the \
                     practical minimum of {:.1} %",
                    r.p_value,
                    100.0 * r.explained,
                    100.0 * beyond,
                    100.0 * config.min_effect
                );
                r.note = Some(match r.note.take() {
                    Some(n) => format!("{note}; {n}"),
                    None => note,
                });
            }
            if let Some(by) = forward.explained_away_by[j] {
                let note = format!(
                    "confounded with `{}`, which explains it away (what `{}` adds beyond it: {:.1} %)",
                    table.columns()[by].name,
                    col.name,
                    100.0 * forward.twin_gain[j]
                );
                r.note = Some(match r.note.take() {
                    Some(n) => format!("{note}; {n}"),
                    None => note,
                });
            }
            let rank = forward
                .order
                .iter()
                .position(|&k| k == j)
                .unwrap_or(usize::MAX);
            (rank, r)
        })
        .collect();
    // Strongest first: the forward order, then the rest by their own (marginal) strength.
    reports.sort_by(|(ra, a), (rb, b)| ra.cmp(rb).then(report::compare(a, b)));
    let reports: Vec<FeatureReport> = reports.into_iter().map(|(_, r)| r).collect();

    // The pair screen reads only the table and what the forward pass left: the binned
    // features and the residual's other copies are freed before it (its cells are the
    // diagnosis's peak of memory otherwise).
    drop(analysed);
    drop(signed_residuals);
    Ok(Screened {
        reports,
        residual_std,
        null_block,
        left: forward.left,
        fold,
        direction,
        variance,
    })
}

/// Two candidates are near-tied when the weaker explains at least `1 − NEAR_TIE` of what the
/// stronger does; the direction-signed analysis must beat the plain one by this margin too.
pub(crate) const NEAR_TIE: f64 = 0.05;
/// A candidate is explained away by another when what it adds beyond the other is at most this
/// fraction of what it explains on its own.
pub(crate) const EXPLAINED_AWAY: f64 = 0.2;
/// Most steps of the forward pass (features ranked by what they add beyond the earlier ones).
pub(crate) const FORWARD_STEPS: usize = 6;
/// Most near-tied candidates compared pairwise at one step.
const MAX_TIED: usize = 4;

/// What is shared by every gain evaluation of one diagnosis.
struct Ctx<'a> {
    direction: Option<&'a [i8]>,
    fold: &'a [u8],
    folds: usize,
    /// Variance of the (clipped, centred) residuals: every gain is a fraction of it.
    variance: f64,
}

/// What one feature explains of a residual, out of sample.
#[derive(Debug, Clone, Copy)]
struct Gain {
    /// Fraction of the original residual variance.
    explained: f64,
    /// Level the cross-validation chose.
    shift: u32,
    /// Whether the direction-signed analysis won.
    by_direction: bool,
}

/// The out-of-sample gain of the binned smoother of `b` on residual `r`: the plain analysis,
/// or — if `signable` and it explains more than `1 + NEAR_TIE` times as much — the analysis of
/// `r` × direction, counted beyond a constant direction offset. Near a tie the plain (even)
/// explanation is kept: it is the simpler one, and a term of the feature alone can fit it.
fn gain(
    b: &Binned,
    signable: bool,
    r: &[f64],
    direction: Option<&[i8]>,
    fold: &[u8],
    folds: usize,
    variance: f64,
) -> Gain {
    let n = r.len() as f64;
    let frac = |base: f64, mse: f64| {
        if variance > 0.0 {
            ((base - mse) / variance).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let cv = smoother::cross_validate(b, r, fold, folds);
    let mut g = Gain {
        explained: frac(stats::sum_sq_about_mean(r) / n, cv.mse),
        shift: cv.shift,
        by_direction: false,
    };
    if let Some(d) = direction.filter(|_| signable) {
        // r × direction row by row, never stored (the values `Signed::new` would hold).
        let signed = || r.iter().zip(d).map(|(v, &d)| v * f64::from(d));
        let cv = smoother::cross_validate_rows(b, signed(), fold, folds);
        let e = frac(sum_sq_about_mean_rows(signed) / n, cv.mse);
        if e > g.explained * (1.0 + NEAR_TIE) {
            g = Gain {
                explained: e,
                shift: cv.shift,
                by_direction: true,
            };
        }
    }
    g
}

/// `r` minus the out-of-fold prediction of `b`'s smoother as chosen by `g`. Only the result
/// is a vector: the signed residual and the predictions are read row by row
/// ([`smoother::cv_fold_means`]; the same values as [`remove_reference`], tested).
fn remove(b: &Binned, g: Gain, r: &[f64], ctx: &Ctx) -> Vec<f64> {
    let cell = |m: usize, i: usize| smoother::cv_cell(b, g.shift, ctx.fold, m, i);
    match ctx.direction.filter(|_| g.by_direction) {
        Some(d) => {
            let s = r.iter().zip(d).map(|(v, &d)| v * f64::from(d));
            let (p, m) = smoother::cv_fold_means(b, g.shift, s, ctx.fold, ctx.folds);
            r.iter()
                .zip(d)
                .enumerate()
                .map(|(i, (v, &d))| v - f64::from(d) * p[cell(m, i)])
                .collect()
        }
        None => {
            let (p, m) =
                smoother::cv_fold_means(b, g.shift, r.iter().copied(), ctx.fold, ctx.folds);
            r.iter()
                .enumerate()
                .map(|(i, v)| v - p[cell(m, i)])
                .collect()
        }
    }
}

/// [`remove`] as it was written with the signed residual and the predictions stored (the
/// plain reference it is tested against).
#[cfg(test)]
fn remove_reference(b: &Binned, g: Gain, r: &[f64], ctx: &Ctx) -> Vec<f64> {
    match ctx.direction.filter(|_| g.by_direction) {
        Some(d) => {
            let d: Vec<f64> = d.iter().map(|&d| f64::from(d)).collect();
            let s: Vec<f64> = r.iter().zip(&d).map(|(v, d)| v * d).collect();
            let p = smoother::cv_predict(b, g.shift, &s, ctx.fold, ctx.folds);
            r.iter()
                .zip(&d)
                .zip(p)
                .map(|((v, d), p)| v - d * p)
                .collect()
        }
        None => {
            let p = smoother::cv_predict(b, g.shift, r, ctx.fold, ctx.folds);
            r.iter().zip(p).map(|(v, p)| v - p).collect()
        }
    }
}

/// [`stats::sum_sq_about_mean`] of the values `rows()` gives (twice: the mean, then the
/// squares), the same sums in the same order, so the same bits, without storing them.
fn sum_sq_about_mean_rows<I: ExactSizeIterator<Item = f64>>(rows: impl Fn() -> I) -> f64 {
    let n = rows().len();
    let m = if n == 0 {
        0.0
    } else {
        rows().sum::<f64>() / n as f64
    };
    rows().map(|v| (v - m) * (v - m)).sum()
}

/// A near-tied candidate, its gain, the largest fraction of another tied candidate's gain
/// that survives its removal, and what each other tied candidate adds beyond it.
type Cover = (usize, Gain, f64, Vec<(usize, f64)>);

/// The result of the forward pass.
struct Forward {
    /// Features (column indices) in the order the pass took them.
    order: Vec<usize>,
    /// Per column: what it explains beyond the features taken before it (for those not taken:
    /// beyond all taken ones); `None` for unusable features.
    beyond: Vec<Option<f64>>,
    /// Per column: the near-tied twin that was taken instead and explains this one away.
    explained_away_by: Vec<Option<usize>>,
    /// Per column with a twin: what it adds beyond that twin.
    twin_gain: Vec<f64>,
    /// The residual left after removing the taken features' out-of-fold smooths.
    left: Vec<f64>,
}

/// Ranks the flagged features by what each explains beyond the ones before it (see the module
/// docs): at each step the candidate with the largest gain on what is left, except that among
/// near-tied candidates the one that explains the others away is taken — and among several
/// that do (twins the data cannot tell apart), a logged covariate before a built-in feature.
fn forward_pass(
    analysed: &[Result<Analysed, Unusable>],
    flagged: &[usize],
    y: &[f64],
    ctx: &Ctx,
) -> Forward {
    let m = analysed.len();
    let mut out = Forward {
        order: Vec::new(),
        beyond: vec![None; m],
        explained_away_by: vec![None; m],
        twin_gain: vec![0.0; m],
        left: Vec::new(),
    };
    let eval = |j: usize, r: &[f64]| -> Option<Gain> {
        analysed[j].as_ref().ok().map(|a| {
            gain(
                &a.binned,
                a.signable,
                r,
                ctx.direction,
                ctx.fold,
                ctx.folds,
                ctx.variance,
            )
        })
    };
    let mut r = y.to_vec();
    for _ in 0..FORWARD_STEPS {
        // Each candidate's gain is independent of the others': in parallel, in order.
        let candidates: Vec<usize> = flagged
            .iter()
            .copied()
            .filter(|j| !out.order.contains(j))
            .collect();
        let mut gains: Vec<(usize, Gain)> = candidates
            .par_iter()
            .filter_map(|&j| eval(j, &r).map(|g| (j, g)))
            .filter(|(_, g)| g.explained > 0.0)
            .collect();
        gains.sort_by(|a, b| b.1.explained.total_cmp(&a.1.explained).then(a.0.cmp(&b.0)));
        let Some(&(_, lead)) = gains.first() else {
            break;
        };
        let tied: Vec<(usize, Gain)> = gains
            .iter()
            .copied()
            .filter(|(_, g)| g.explained >= (1.0 - NEAR_TIE) * lead.explained)
            .take(MAX_TIED)
            .collect();
        let mut chosen = tied[0];
        if tied.len() > 1 {
            // For each tied candidate: what is left of the others once it is removed.
            let covers: Vec<Cover> = tied
                .par_iter()
                .filter_map(|&(c, gc)| {
                    let a = analysed[c].as_ref().ok()?;
                    let rc = remove(&a.binned, gc, &r, ctx);
                    let mut worst = 0.0f64;
                    let mut left = Vec::new();
                    for &(j, gj) in tied.iter().filter(|(j, _)| *j != c) {
                        let after = eval(j, &rc).map_or(0.0, |g| g.explained);
                        worst = worst.max(after / gj.explained);
                        left.push((j, after));
                    }
                    Some((c, gc, worst, left))
                })
                .collect();
            let is_covariate = |j: usize| {
                analysed[j]
                    .as_ref()
                    .is_ok_and(|a| a.origin == FeatureOrigin::Covariate)
            };
            let covering: Vec<&Cover> = covers.iter().filter(|c| c.2 <= EXPLAINED_AWAY).collect();
            let pick = covering
                .iter()
                .find(|c| is_covariate(c.0))
                .or_else(|| covering.first())
                .copied()
                .or_else(|| covers.iter().min_by(|a, b| a.2.total_cmp(&b.2)));
            if let Some((c, gc, _, left)) = pick {
                chosen = (*c, *gc);
                for &(j, after) in left {
                    let gj = tied
                        .iter()
                        .find(|t| t.0 == j)
                        .map_or(0.0, |t| t.1.explained);
                    if after <= EXPLAINED_AWAY * gj {
                        out.explained_away_by[j] = Some(*c);
                        out.twin_gain[j] = after;
                    }
                }
            }
        }
        let (c, gc) = chosen;
        out.beyond[c] = Some(gc.explained);
        out.order.push(c);
        if let Ok(a) = &analysed[c] {
            r = remove(&a.binned, gc, &r, ctx);
        }
    }
    let rest: Vec<Option<f64>> = (0..m)
        .into_par_iter()
        .map(|j| match out.beyond[j] {
            None => eval(j, &r).map(|g| g.explained),
            taken => taken,
        })
        .collect();
    out.beyond = rest;
    out.left = r;
    out
}

/// Residuals farther than this many robust standard deviations (1.4826·MAD) from the median
/// are clipped to that distance before the analysis.
pub(crate) const WINSOR_SIGMAS: f64 = 4.0;

/// The residuals with outliers clipped at the median ± [`WINSOR_SIGMAS`]·1.4826·MAD (unchanged
/// when the MAD is 0). A handful of gross residuals — the start-up transient of a state-space
/// model replayed from rest, a glitch in the log — would otherwise dominate the sums of squares
/// and make whichever feature isolates those rows (an undefined rest distance on the first
/// seeks) look like an effect. A genuine effect moves many rows by a few noise widths and
/// survives the clip; its size is still reported from the raw residuals.
fn winsorize(residuals: &[f64]) -> Vec<f64> {
    // Medians by selection, not sorting: the same bits (`stats::percentile_select`).
    let mut scratch = residuals.to_vec();
    let Some(median) = stats::percentile_select(&mut scratch, 50.0) else {
        return residuals.to_vec();
    };
    for (d, v) in scratch.iter_mut().zip(residuals) {
        *d = (v - median).abs();
    }
    let mad = stats::percentile_select(&mut scratch, 50.0).unwrap_or(0.0);
    let half = WINSOR_SIGMAS * 1.4826 * mad;
    if half > 0.0 {
        residuals
            .iter()
            .map(|v| v.clamp(median - half, median + half))
            .collect()
    } else {
        residuals.to_vec()
    }
}

/// Deals contiguous blocks of `block_len` rows to `folds` folds at random, balanced. One
/// byte a row: `folds` is at most 50 ([`DiagnoseConfig::folds`]).
fn assign_folds(n: usize, block_len: usize, folds: usize, seed: u64) -> Vec<u8> {
    let n_blocks = n.div_ceil(block_len);
    let mut order: Vec<usize> = (0..n_blocks).collect();
    shuffle(&mut order, &mut SimRng::substream(seed, 1));
    let mut block_fold = vec![0u8; n_blocks];
    for (pos, &b) in order.iter().enumerate() {
        block_fold[b] = u8::try_from(pos % folds).unwrap_or(u8::MAX);
    }
    (0..n).map(|i| block_fold[i / block_len]).collect()
}

/// Fisher–Yates shuffle with the seeded generator.
fn shuffle<T>(v: &mut [T], rng: &mut SimRng) {
    for i in (1..v.len()).rev() {
        let j = rng.below(i as u64 + 1) as usize;
        v.swap(i, j);
    }
}

/// [`shuffle`] of a residual, the same swaps in the same order (so the same permutation,
/// tested): the random indices of a chunk are drawn first ([`SimRng::below_descending`],
/// without a division per draw), then each swap prefetches the row it will swap
/// [`SHUFFLE_AHEAD`] swaps later, so the cache misses of a residual larger than the cache
/// overlap instead of following one another (a prefetch, unlike a load, does not hold the
/// swaps behind it while it waits).
fn shuffle_rows<T: Copy>(v: &mut [T], rng: &mut SimRng) {
    const CHUNK: usize = 4096;
    if v.len() < 2 {
        return;
    }
    let mut js: Vec<u64> = Vec::with_capacity(CHUNK);
    let mut i = v.len() - 1;
    while i >= 1 {
        let lo = i.saturating_sub(CHUNK - 1).max(1);
        js.clear();
        rng.below_descending(lo as u64, i as u64, &mut js);
        for (step, &j) in js.iter().enumerate() {
            if let Some(&ahead) = js.get(step + SHUFFLE_AHEAD) {
                smoother::prefetch(&v[ahead as usize..]);
            }
            v.swap(i - step, j as usize);
        }
        i = lo - 1;
    }
}

/// How many swaps ahead [`shuffle_rows`] reads its rows.
const SHUFFLE_AHEAD: usize = 32;

/// Whether a feature is a time feature (`elapsed_s`, `seek_index`): tested against the plain
/// row permutation, since serial structure of the residual is the effect it stands for.
pub(crate) fn is_time(origin: FeatureOrigin) -> bool {
    matches!(
        origin,
        FeatureOrigin::BuiltIn(Feature::ElapsedS) | FeatureOrigin::BuiltIn(Feature::SeekIndex)
    )
}

/// Longest block of the automatic permutation null, in seeks.
pub(crate) const MAX_NULL_BLOCK: usize = 200;
/// The automatic null block is this many times the residual's decorrelation lag.
pub(crate) const NULL_BLOCK_FACTOR: usize = 6;
/// The autocorrelation below which the residual counts as decorrelated (automatic null block).
pub(crate) const NULL_ACF: f64 = 0.1;

/// The block length of the permutation null for residual `y`: [`NULL_BLOCK_FACTOR`] times the
/// first lag at which its autocorrelation falls below [`NULL_ACF`], at most [`MAX_NULL_BLOCK`]
/// and n/8 (so there are at least 8 blocks to permute), at least 1. Serial correlation shorter
/// than a block is kept by the null (a block boundary cuts it, so the block must be several
/// correlation lengths long for the null not to be too narrow), so a slowly varying feature is
/// not flagged for riding on it. Structure slower than the block is what the time features
/// (`elapsed_s`, `seek_index` → `drift`) stand for, and a slow column must add to them to be
/// flagged.
pub(crate) fn null_block_len(y: &[f64]) -> usize {
    let n = y.len();
    let cap = MAX_NULL_BLOCK.min(n / 8).max(1);
    let longest = cap.div_ceil(NULL_BLOCK_FACTOR);
    let k0 = (1..=longest)
        .find(|&lag| stats::autocorrelation(y, lag) < NULL_ACF)
        .unwrap_or(longest);
    (NULL_BLOCK_FACTOR * k0).clamp(1, cap)
}

/// The null block of one feature beside a residual whose own null block is `residual_block`:
/// [`null_block_len`] of the feature's values in seek order (undefined rows at the mean),
/// rounded up to a power of two, at most `residual_block`. A feature that is exchangeable in
/// seek order (random targets) gets short blocks, a slow column the residual's. NaN marks an
/// undefined value.
pub(crate) fn feature_null_block(
    values: std::borrow::Cow<'_, [f64]>,
    residual_block: usize,
) -> usize {
    // The mean of the defined values, summed in row order as `stats::mean` sums them.
    let defined = || values.iter().copied().filter(|x| !x.is_nan());
    let count = defined().count();
    let mean = if count > 0 {
        defined().sum::<f64>() / count as f64
    } else {
        0.0
    };
    // One buffer: the decoded column itself where it was decoded for this call.
    let mut filled = values.into_owned();
    for v in &mut filled {
        *v = values::defined(*v).unwrap_or(mean) - mean;
    }
    null_block_len(&filled)
        .next_power_of_two()
        .min(residual_block)
        .max(1)
}

/// Writes into `out` a block permutation of `y`: `y` rotated by a random offset (so block
/// boundaries are not fixed), cut into consecutive blocks of `block` rows, the blocks
/// concatenated in random order. `block == 1` is a plain row permutation.
fn block_permute(y: &[f64], block: usize, out: &mut [f64], rng: &mut SimRng) {
    let n = y.len();
    if block <= 1 {
        out.copy_from_slice(y);
        shuffle_rows(out, rng);
        return;
    }
    let mut order = Vec::new();
    let offset = draw_blocks(n, block, &mut order, rng);
    Permuted::Blocks {
        y,
        block,
        offset,
        order: &order,
    }
    .for_each_run(|k, run| out[k..k + run.len()].copy_from_slice(run));
}

/// The random part of a block permutation of `n` rows in blocks of `block` (> 1): the
/// rotation offset (returned) and the order of the blocks (written to `order`), drawn as
/// [`block_permute_reference`] draws them.
fn draw_blocks(n: usize, block: usize, order: &mut Vec<usize>, rng: &mut SimRng) -> usize {
    let offset = rng.below(n as u64) as usize;
    order.clear();
    order.extend(0..n.div_ceil(block));
    shuffle_rows(order, rng);
    offset
}

/// [`block_permute`] written row by row with the modulo (the slow, obvious reference it is
/// tested against).
#[cfg(test)]
fn block_permute_reference(y: &[f64], block: usize, out: &mut [f64], rng: &mut SimRng) {
    let n = y.len();
    if block <= 1 {
        out.copy_from_slice(y);
        shuffle(out, rng);
        return;
    }
    let offset = rng.below(n as u64) as usize;
    let n_blocks = n.div_ceil(block);
    let mut order: Vec<usize> = (0..n_blocks).collect();
    shuffle(&mut order, rng);
    let mut k = 0;
    for b in order {
        for i in b * block..((b + 1) * block).min(n) {
            out[k] = y[(i + offset) % n];
            k += 1;
        }
    }
}

/// First random stream of the permutations: permutation `i` draws its permutation for the
/// `b`-th distinct block length from stream `PERM_STREAM + PERM_STRIDE·i + b` of the diagnosis
/// seed (streams 1–3 are the folds' and older uses).
const PERM_STREAM: u64 = 1 << 32;
/// Streams reserved per permutation (more than the distinct block lengths: powers of two up to
/// [`MAX_NULL_BLOCK`], 1 and the residual's own).
const PERM_STRIDE: u64 = 16;

/// The features tested against one block length's permutation, swept in one fused pass
/// ([`SlotTable`]): their indices into the usable features, the signable ones first.
struct PermGroup {
    /// Block length index (into the distinct lengths).
    length: usize,
    /// Usable-feature indices, signable first.
    features: Vec<usize>,
    /// Their fine slots; `None` (a feature with more than 256 slots) tests the group one
    /// feature at a time with [`FTest::min_p`].
    table: Option<SlotTable>,
}

/// The groups of the fused permutation pass: one per distinct block length (`which[k]`: the
/// length of usable feature `k`), signable features first when the residual is signed. Each
/// group's [`SlotTable`] takes its features' one-byte slots from `analysed` (`usable[k]`:
/// the index of usable feature `k` there); [`give_back`] returns them.
fn perm_groups(
    analysed: &mut [Result<Analysed, Unusable>],
    usable: &[usize],
    lengths: usize,
    which: &[usize],
    signed: bool,
    fused: bool,
) -> Vec<PermGroup> {
    let is_signed = |a: &Analysed| signed && a.signable;
    let mut groups: Vec<(PermGroup, Vec<&mut Binned>)> = (0..lengths)
        .map(|length| {
            let group = PermGroup {
                length,
                features: Vec::new(),
                table: None,
            };
            (group, Vec::new())
        })
        .collect();
    // Signable first, each part in usable order (the mutable borrows are handed out in
    // usable order, then each group's are reordered alike).
    let mut usable_at = vec![usize::MAX; analysed.len()];
    for (k, &j) in usable.iter().enumerate() {
        usable_at[j] = k;
    }
    let mut members: Vec<Vec<(bool, usize, &mut Binned)>> =
        (0..lengths).map(|_| Vec::new()).collect();
    for (j, a) in analysed.iter_mut().enumerate() {
        if let (Ok(a), Some(&k)) = (a.as_mut(), usable_at.get(j).filter(|&&k| k != usize::MAX)) {
            let s = is_signed(a);
            members[which[k]].push((!s, k, &mut a.binned));
        }
    }
    for ((g, bins), mut ms) in groups.iter_mut().zip(members) {
        // Stable: signable first, each part in usable order.
        ms.sort_by_key(|&(unsigned, k, _)| (unsigned, k));
        let n_signed = ms.iter().filter(|(unsigned, _, _)| !unsigned).count();
        g.features = ms.iter().map(|&(_, k, _)| k).collect();
        bins.extend(ms.into_iter().map(|(_, _, b)| b));
        g.table = if fused {
            SlotTable::take(bins, n_signed)
        } else {
            None
        };
    }
    groups
        .into_iter()
        .map(|(g, _)| g)
        .filter(|g| !g.features.is_empty())
        .collect()
}

/// Returns the slots the groups' tables took ([`perm_groups`]) to the features of
/// `analysed` (`usable[k]`: the index of usable feature `k` there), freeing the tables.
fn give_back(
    groups: Vec<PermGroup>,
    analysed: &mut [Result<Analysed, Unusable>],
    usable: &[usize],
) {
    let mut bins: Vec<Option<&mut Binned>> = analysed
        .iter_mut()
        .map(|a| a.as_mut().ok().map(|a| &mut a.binned))
        .collect();
    for g in groups {
        if let Some(table) = g.table {
            let mut mine: Vec<&mut Binned> = g
                .features
                .iter()
                .filter_map(|&k| bins[usable[k]].take())
                .collect();
            table.give_back(&mut mine);
        }
    }
}

/// One thread's buffers and hit counts of the permutation test (one slot per usable feature).
struct PermWorker {
    tests: Vec<FTest>,
    /// The row permutation of the residual (block length 1), shuffled in place.
    rows: Vec<f64>,
    /// The block orders of the [`LANES`] block permutations of a batch.
    orders: [Vec<usize>; LANES],
    /// A materialised permutation and its direction-signed copy, for a group without a
    /// [`SlotTable`] only.
    perm: Vec<f64>,
    signed: Vec<f64>,
    /// Per-slot sums of the fused pass (plain and signed residual) of one permutation.
    acc: Vec<f64>,
    acc_signed: Vec<f64>,
    /// The same for the lanes of a batch, and the batch's gathered rows.
    acc_lanes: Vec<[f64; LANES]>,
    acc_signed_lanes: Vec<[f64; LANES]>,
    chunk: Vec<[f64; LANES]>,
    /// `stat[l·m + k]`: feature `k`'s statistic in permutation `l` of the batch.
    stat: Vec<f64>,
    raw: Vec<usize>,
    adj: Vec<usize>,
}

/// What every permutation of one test shares.
struct PermInput<'a, 'b> {
    usable: &'a [(usize, &'b Analysed)],
    y: &'a [f64],
    sst: f64,
    direction: Option<&'a [i8]>,
    lengths: &'a [usize],
    groups: &'a [PermGroup],
    seed: u64,
    permutations: usize,
}

impl PermWorker {
    /// A worker with its own copy of the usable features' F-tests (`tests`: their counts
    /// are counted once, not once per worker).
    fn new(tests: &[FTest]) -> PermWorker {
        let m = tests.len();
        PermWorker {
            tests: tests.to_vec(),
            rows: Vec::new(),
            orders: Default::default(),
            perm: Vec::new(),
            signed: Vec::new(),
            acc: Vec::new(),
            acc_signed: Vec::new(),
            acc_lanes: Vec::new(),
            acc_signed_lanes: Vec::new(),
            chunk: Vec::new(),
            stat: vec![0.0; m * LANES],
            raw: vec![0; m],
            adj: vec![0; m],
        }
    }

    /// The random generator of permutation `i` for block length index `b`.
    fn rng(seed: u64, i: usize, b: usize) -> SimRng {
        SimRng::substream(seed, PERM_STREAM + PERM_STRIDE * i as u64 + b as u64)
    }

    /// Permutations `LANES·batch ..` (at most [`LANES`], fewer at the end): the residual
    /// permuted once per distinct block length, each feature tested against the permutation
    /// of its own block (`groups`, one per length, one fused pass each over the permutation
    /// read in place — the block permutations of the batch side by side in the lanes of one
    /// vector); the family-wise statistic is the smallest over features. Each permutation
    /// draws from its own streams, and each lane's sums are those of its own pass, so the
    /// counts are those of one permutation at a time.
    fn run_batch(&mut self, batch: usize, p: &PermInput) {
        let first = LANES * batch;
        let count = LANES.min(p.permutations - first);
        let m = p.usable.len();
        let n = p.y.len();
        let mut stat = std::mem::take(&mut self.stat);
        for g in p.groups {
            let len = p.lengths[g.length];
            match &g.table {
                Some(table) if len > 1 => {
                    let mut offsets = [0usize; LANES];
                    for (l, offset) in offsets.iter_mut().enumerate().take(count) {
                        let mut rng = Self::rng(p.seed, first + l, g.length);
                        *offset = draw_blocks(n, len, &mut self.orders[l], &mut rng);
                    }
                    // Unused lanes (the last batch) repeat lane 0; their sums are ignored.
                    let lanes: [BlockLane; LANES] = std::array::from_fn(|l| {
                        let l = if l < count { l } else { 0 };
                        BlockLane {
                            offset: offsets[l],
                            order: &self.orders[l],
                        }
                    });
                    let d = p.direction.filter(|_| table.signed() > 0).unwrap_or(&[]);
                    let (sum, sq) = table.accumulate_lanes(
                        p.y,
                        len,
                        &lanes,
                        d,
                        &mut self.chunk,
                        &mut self.acc_lanes,
                        &mut self.acc_signed_lanes,
                    );
                    // The signed sum of squares from the pass's own sums (no second gather).
                    let sst_signed: [f64; LANES] =
                        std::array::from_fn(|l| sst_of_sums(sum[l], sq[l], n));
                    for l in 0..count {
                        self.acc.clear();
                        self.acc.extend(self.acc_lanes.iter().map(|a| a[l]));
                        self.acc_signed.clear();
                        if table.signed() > 0 {
                            self.acc_signed
                                .extend(self.acc_signed_lanes.iter().map(|a| a[l]));
                        }
                        let stat = &mut stat[l * m..(l + 1) * m];
                        for (j, &k) in g.features.iter().enumerate() {
                            let (t, a) = (&mut self.tests[k], p.usable[k].1);
                            stat[k] =
                                t.min_p_of_sums(&a.binned, table.sums(&self.acc, j), n, p.sst);
                            if j < table.signed() {
                                let sums = table.sums(&self.acc_signed, j);
                                stat[k] =
                                    stat[k].min(t.min_p_of_sums(&a.binned, sums, n, sst_signed[l]));
                            }
                        }
                    }
                }
                _ => {
                    for l in 0..count {
                        let mut rng = Self::rng(p.seed, first + l, g.length);
                        self.run_group(g, len, &mut rng, p, &mut stat[l * m..(l + 1) * m]);
                    }
                }
            }
        }
        for l in 0..count {
            let stat = &stat[l * m..(l + 1) * m];
            let min_stat = stat.iter().copied().fold(f64::INFINITY, f64::min);
            for (k, &(_, a)) in p.usable.iter().enumerate() {
                if stat[k] <= a.observed {
                    self.raw[k] += 1;
                }
                if min_stat <= a.observed {
                    self.adj[k] += 1;
                }
            }
        }
        self.stat = stat;
    }

    /// One permutation of group `g` (block length `len`) drawn from `rng`, one at a time: the
    /// row permutation shuffled into a buffer and read by the fused pass, or (no
    /// [`SlotTable`]) materialised and tested feature by feature. Writes the group's
    /// features' statistics into `stat`.
    fn run_group(
        &mut self,
        g: &PermGroup,
        len: usize,
        rng: &mut SimRng,
        p: &PermInput,
        stat: &mut [f64],
    ) {
        let (y, n, sst) = (p.y, p.y.len(), p.sst);
        match &g.table {
            Some(table) => {
                let permuted = if len <= 1 {
                    self.rows.clear();
                    self.rows.extend_from_slice(y);
                    shuffle_rows(&mut self.rows, rng);
                    Permuted::Rows(&self.rows)
                } else {
                    let offset = draw_blocks(n, len, &mut self.orders[0], rng);
                    Permuted::Blocks {
                        y,
                        block: len,
                        offset,
                        order: &self.orders[0],
                    }
                };
                self.acc.resize(table.len(), 0.0);
                self.acc_signed.resize(table.len(), 0.0);
                let d = p.direction.filter(|_| table.signed() > 0).unwrap_or(&[]);
                let (sum, sq) =
                    table.accumulate_permuted(&permuted, d, &mut self.acc, &mut self.acc_signed);
                let sst_signed = sst_of_sums(sum, sq, n);
                for (j, &k) in g.features.iter().enumerate() {
                    let (t, a) = (&mut self.tests[k], p.usable[k].1);
                    stat[k] = t.min_p_of_sums(&a.binned, table.sums(&self.acc, j), n, sst);
                    if j < table.signed() {
                        let sums = table.sums(&self.acc_signed, j);
                        stat[k] = stat[k].min(t.min_p_of_sums(&a.binned, sums, n, sst_signed));
                    }
                }
            }
            None => {
                self.perm.resize(n, 0.0);
                block_permute(y, len, &mut self.perm, rng);
                let mut sst_signed = 0.0;
                if let Some(d) = p.direction {
                    self.signed.clear();
                    self.signed
                        .extend(self.perm.iter().zip(d).map(|(p, &d)| p * f64::from(d)));
                    sst_signed = sst_one_pass(&self.signed);
                }
                for &k in &g.features {
                    let (t, a) = (&mut self.tests[k], p.usable[k].1);
                    stat[k] = t.min_p(&a.binned, &self.perm, sst);
                    if a.signable && p.direction.is_some() {
                        stat[k] = stat[k].min(t.min_p(&a.binned, &self.signed, sst_signed));
                    }
                }
            }
        }
    }
}

/// Raw and Westfall–Young family-wise permutation p-values for every feature (1 for unusable
/// ones); feature `j` is tested against block permutations of `blocks[j]` consecutive
/// residuals (1: rows permuted one by one). `fused`: the statistics of many features from
/// one pass over each permuted residual ([`SlotTable`]); else each feature's own pass
/// ([`FTest::min_p`], the slow reference — the results are bit-identical, tested).
fn permutation_test(
    analysed: &mut [Result<Analysed, Unusable>],
    y: &[f64],
    sst: f64,
    direction: Option<&[i8]>,
    blocks: &[usize],
    config: &DiagnoseConfig,
    fused: bool,
) -> (Vec<f64>, Vec<f64>) {
    let m = analysed.len();
    let mut raw_count = vec![0usize; m];
    let mut adj_count = vec![0usize; m];
    let usable_idx: Vec<usize> = (0..m).filter(|&j| analysed[j].is_ok()).collect();
    if sst > 0.0 && !usable_idx.is_empty() {
        let mut lengths: Vec<usize> = usable_idx.iter().map(|&j| blocks[j]).collect();
        lengths.sort_unstable();
        lengths.dedup();
        let which: Vec<usize> = usable_idx
            .iter()
            .map(|&j| lengths.binary_search(&blocks[j]).unwrap_or(0))
            .collect();
        // The counts before the slot tables take the features' slots.
        let tests: Vec<FTest> = usable_idx
            .par_iter()
            .filter_map(|&j| analysed[j].as_ref().ok())
            .map(|a| FTest::new(&a.binned))
            .collect();
        let groups = perm_groups(
            analysed,
            &usable_idx,
            lengths.len(),
            &which,
            direction.is_some(),
            fused,
        );
        let usable: Vec<(usize, &Analysed)> = analysed
            .iter()
            .enumerate()
            .filter_map(|(j, a)| a.as_ref().ok().map(|a| (j, a)))
            .collect();
        // Every permutation draws from its own seeded streams and the counts are integers, so
        // the p-values are the same for any number of threads.
        let k = usable.len();
        let input = PermInput {
            usable: &usable,
            y,
            sst,
            direction,
            lengths: &lengths,
            groups: &groups,
            seed: config.seed,
            permutations: config.permutations,
        };
        let (raw, adj) = (0..config.permutations.div_ceil(LANES))
            .into_par_iter()
            .fold(
                || PermWorker::new(&tests),
                |mut w, batch| {
                    w.run_batch(batch, &input);
                    w
                },
            )
            .map(|w| (w.raw, w.adj))
            .reduce(
                || (vec![0; k], vec![0; k]),
                |(mut r, mut a), (r2, a2)| {
                    r.iter_mut().zip(r2).for_each(|(x, y)| *x += y);
                    a.iter_mut().zip(a2).for_each(|(x, y)| *x += y);
                    (r, a)
                },
            );
        drop(usable);
        give_back(groups, analysed, &usable_idx);
        for (k, &j) in usable_idx.iter().enumerate() {
            raw_count[j] = raw[k];
            adj_count[j] = adj[k];
        }
    }
    let b = config.permutations as f64 + 1.0;
    let analysed = &*analysed;
    let p = |counts: Vec<usize>| -> Vec<f64> {
        counts
            .iter()
            .zip(analysed)
            .map(|(&c, a)| {
                if a.is_ok() && sst > 0.0 {
                    (c as f64 + 1.0) / b
                } else {
                    1.0
                }
            })
            .collect()
    };
    (p(raw_count), p(adj_count))
}

#[cfg(test)]
mod tests;

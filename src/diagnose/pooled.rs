//! One log's part of a pooled screen over many logs: every feature's observed statistic and its
//! statistic under each of the diagnosis's seeded block permutations, so that a caller can sum
//! them over logs and count a family-wise p-value of the sums (`crate::fleet`), with the same
//! permutation code, seeds and block lengths as [`super::diagnose`].

use super::permutation::{NullStatistics, p_values, permutation_statistics};
use super::screen::{Analysis, Prepared, prepare};
use super::{CheckedDiagnoseConfig, DiagnoseError, FeatureOrigin, FeatureTable};

/// One log's screen statistics: per feature (in the table's order) its observed statistic (ln
/// of the smallest F-test p-value over its binnings, plain and direction-signed), its
/// out-of-sample explained share, this log's own family-wise p-value (as `diagnose` reports
/// it), and its statistic under every permutation.
#[derive(Debug, Clone)]
pub struct ScreenStatistics {
    /// Feature names, in the table's order.
    pub names: Vec<String>,
    /// Built-in feature, covariate, ….
    pub origins: Vec<FeatureOrigin>,
    /// Whether the feature was tested (usable on this log); an untested one has statistic 0
    /// (p = 1) everywhere.
    pub tested: Vec<bool>,
    /// Observed statistic per feature (≤ 0; more negative is stronger).
    pub observed: Vec<f64>,
    /// Out-of-sample share of the residual variance the feature explains (0 if untested).
    pub explained: Vec<f64>,
    /// Whether the direction-signed analysis won for the feature.
    pub by_direction: Vec<bool>,
    /// This log's Westfall–Young family-wise p-value per feature (`diagnose`'s `p_value`).
    pub p_value: Vec<f64>,
    /// Permutations (rows of `null`).
    pub permutations: usize,
    /// Row-major permutations × features: each feature's statistic under each permutation.
    pub null: Vec<f64>,
}

impl ScreenStatistics {
    /// Feature `j`'s statistic under permutation `i`.
    pub fn null_stat(&self, i: usize, j: usize) -> f64 {
        self.null[i * self.names.len() + j]
    }
}

/// The screen statistics of `residuals` (one per measured row of `table`) under `config`: the
/// input checks, clipping, folds, smoothers and block permutations of [`super::diagnose`], the
/// same seeds, without the forward pass, the pair screen and the reports.
pub fn screen_statistics(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<ScreenStatistics, DiagnoseError> {
    let Prepared {
        analysis:
            Analysis {
                y,
                sst,
                direction,
                mut analysed,
                ..
            },
        blocks,
        ..
    } = prepare(table, residuals, config)?;
    let null: NullStatistics = permutation_statistics(
        &mut analysed,
        &y,
        sst,
        direction.as_deref(),
        &blocks,
        config,
        true,
    );
    let (_, p_value) = p_values(&null);
    let cols = table.columns();
    Ok(ScreenStatistics {
        names: cols.iter().map(|c| c.name.clone()).collect(),
        origins: cols.iter().map(|c| c.origin).collect(),
        tested: null.tested,
        observed: null.observed,
        explained: analysed
            .iter()
            .map(|a| a.as_ref().map_or(0.0, |a| a.explained))
            .collect(),
        by_direction: analysed
            .iter()
            .map(|a| a.as_ref().is_ok_and(|a| a.by_direction))
            .collect(),
        p_value,
        permutations: null.permutations,
        null: null.stats,
    })
}

/// [`screen_statistics`] of `model`'s residual on `log`: the model replayed causally over the
/// log and its residual screened against the log's features, as [`super::diagnose_model`]
/// screens it.
pub fn screen_model(
    model: &crate::model::FittedModel,
    log: &crate::log::Log,
    config: &CheckedDiagnoseConfig,
) -> Result<ScreenStatistics, super::ModelDiagnosisError> {
    let prediction = super::replay_model(model, log)?;
    let table = super::model_table(model, log);
    Ok(screen_statistics(&table, &prediction.residual, config)?)
}

//! The one-dimensional screen: every feature's cross-validated smoother, the permutation test
//! and the forward pass, turned into the features' reports, strongest first.

use rayon::prelude::*;

use crate::history::Feature;
use crate::numeric::stats;

use super::forward::{Ctx, Forward, forward_pass};
use super::forward::{gain, sum_sq_about_mean_rows};
use super::ftest::FTest;
use super::is_time;
use super::permutation::{Analysed, feature_null_block, null_block_len, permutation_test, shuffle};
use super::smoother::Unusable;
use super::{
    CheckedDiagnoseConfig, DiagnoseError, FeatureColumn, FeatureOrigin, FeatureReport,
    FeatureTable, report,
};
use crate::numeric::rng::SimRng;

/// Residuals larger than this in magnitude are rejected (their squares would overflow sums).
pub(super) const MAX_RESIDUAL: f64 = 1e100;

/// The residuals multiplied by the direction of the last move (0 before the first move),
/// stored: the reference of the row-by-row products the diagnosis makes instead.
#[cfg(test)]
pub(super) struct Signed {
    pub(super) y: Vec<f64>,
    /// Sum of squares of `y` about its mean.
    pub(super) sst: f64,
}

#[cfg(test)]
impl Signed {
    pub(super) fn new(y: &[f64], direction: &[i8]) -> Signed {
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
pub(super) fn direction_bytes(d: impl Iterator<Item = f64>) -> Option<Vec<i8>> {
    let byte = |x: f64| -> Option<i8> {
        [-1i8, 0, 1]
            .into_iter()
            .find(|&b| f64::from(b).to_bits() == x.to_bits())
    };
    d.map(byte).collect()
}

/// Whether the direction-signed analysis applies to `col`: every feature but `direction`
/// itself (whose signed curve is a constant).
pub(super) fn signable(col: &FeatureColumn) -> bool {
    col.origin != FeatureOrigin::BuiltIn(Feature::Direction)
}

/// Which feature reports [`screen`] makes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Reports {
    /// Every column's ([`diagnose`]).
    All,
    /// The flagged columns' only ([`flagged_features`]).
    Flagged,
    /// The flagged columns' and those whose explained share is the largest (every one of a
    /// tie): what the absorbed-effect rule reads (its flagged features and its strongest).
    FlaggedAndStrongest,
}

/// What [`screen`] leaves for the rest of [`diagnose`].
pub(super) struct Screened {
    pub(super) reports: Vec<FeatureReport>,
    pub(super) residual_std: f64,
    pub(super) null_block: usize,
    /// The residual left by the forward pass (the pair screen's input).
    pub(super) left: Vec<f64>,
    pub(super) fold: Vec<u8>,
    pub(super) direction: Option<Vec<i8>>,
    pub(super) variance: f64,
}

/// The screen's input made ready: the [`Analysis`] (the clipped, centred residual, its folds
/// and direction, every column analysed: binned, cross-validated, its observed statistic) and
/// each column's null block.
pub(super) struct Prepared {
    pub(super) analysis: Analysis,
    pub(super) blocks: Vec<usize>,
    pub(super) null_block: usize,
}

/// The screen's input made ready up to the permutation test's blocks: the clipped, centred
/// residual, its folds and direction, and every column analysed ([`prepare`] without the null
/// blocks).
pub(super) struct Analysis {
    pub(super) y: Vec<f64>,
    pub(super) sst: f64,
    pub(super) variance: f64,
    pub(super) residual_std: f64,
    pub(super) fold: Vec<u8>,
    pub(super) direction: Option<Vec<i8>>,
    pub(super) analysed: Vec<Result<Analysed, Unusable>>,
}

/// Checks the input, clips and centres the residual, and analyses every column: the first
/// part of [`prepare`].
pub(super) fn analyse(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<Analysis, DiagnoseError> {
    let n = table.len();
    let block_len = check_input(table, residuals, config)?;

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
    let analysed = analyse_columns(
        table,
        &Centred {
            y: &y,
            sst,
            signed_sst,
            direction: direction.as_deref(),
            fold: &fold,
            variance,
        },
        config,
    );
    Ok(Analysis {
        y,
        sst,
        variance,
        residual_std,
        fold,
        direction,
        analysed,
    })
}

/// Every column's out-of-sample explained share of `residuals`, in table order, as
/// [`diagnose`]`(table, residuals, config)` reports it (0 for a column it skips): [`analyse`]
/// alone. The tests' reference of the shares the absorbed-effect rule reads.
#[cfg(test)]
pub(super) fn explained_shares(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<Vec<f64>, DiagnoseError> {
    let a = analyse(table, residuals, config)?;
    Ok(a.analysed
        .iter()
        .map(|a| a.as_ref().map_or(0.0, |a| a.explained))
        .collect())
}

/// Checks the input and makes everything the permutation test reads ([`Prepared`]): the first
/// half of [`screen`], shared with the pooled screen of a fleet.
pub(super) fn prepare(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<Prepared, DiagnoseError> {
    Ok(prepare_analysed(
        table,
        analyse(table, residuals, config)?,
        config,
    ))
}

/// [`prepare`] of the [`analyse`]d input (`analysis` of `table`): the null blocks added.
fn prepare_analysed(
    table: &FeatureTable,
    analysis: Analysis,
    config: &CheckedDiagnoseConfig,
) -> Prepared {
    let n = table.len();
    let null_block = config
        .null_block
        .unwrap_or_else(|| null_block_len(&analysis.y))
        .clamp(1, n.max(1));
    // Each feature's null keeps as much serial structure as the pair (feature, residual)
    // has: the residual's block where the feature is as slow as the residual, shorter blocks
    // for a feature that decorrelates sooner (the cross-products decorrelate with the faster
    // of the two), single rows for the time features.
    let blocks: Vec<usize> = analysis
        .analysed
        .par_iter()
        .zip(table.columns())
        .map(|(a, col)| match a {
            Ok(a) if is_time(a.origin) => 1,
            Ok(_) if config.null_block.is_none() => feature_null_block(col.raw(), null_block),
            _ => null_block,
        })
        .collect();
    Prepared {
        analysis,
        blocks,
        null_block,
    }
}

/// The one-dimensional screen of [`diagnose`]: every feature's smoother, the permutation
/// test, the forward pass and the features' reports (`which`), strongest first.
pub(super) fn screen(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
    which: Reports,
) -> Result<Screened, DiagnoseError> {
    let prepared = prepare(table, residuals, config)?;
    Ok(screen_prepared(table, residuals, config, which, prepared))
}

/// [`screen`] of `residuals` already [`analyse`]d (`analysis`, of `table` with `config`): the
/// same result (a caller that read the analysis first, to see whether it needs the rest).
pub(super) fn screen_analysed(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
    which: Reports,
    analysis: Analysis,
) -> Screened {
    let prepared = prepare_analysed(table, analysis, config);
    screen_prepared(table, residuals, config, which, prepared)
}

/// [`screen`] from its [`Prepared`] input.
fn screen_prepared(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
    which: Reports,
    prepared: Prepared,
) -> Screened {
    let Prepared {
        analysis:
            Analysis {
                y,
                sst,
                variance,
                residual_std,
                fold,
                direction,
                mut analysed,
            },
        blocks,
        null_block,
    } = prepared;
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
    // A column's explained share as its report gives it (0 for a skipped column), and the
    // largest, compared as `total_cmp` orders them (as the absorbed-effect rule picks it).
    let share = |j: usize| analysed[j].as_ref().map_or(0.0, |a| a.explained);
    let strongest = (0..analysed.len()).map(share).max_by(|a, b| a.total_cmp(b));
    let wanted: Vec<usize> = (0..analysed.len())
        .filter(|&j| match which {
            Reports::All => true,
            Reports::Flagged => flagged(j),
            Reports::FlaggedAndStrongest => {
                flagged(j) || strongest.is_some_and(|s| share(j).total_cmp(&s).is_eq())
            }
        })
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
    let input = ReportInput {
        table,
        analysed: &analysed,
        p_raw: &p_raw,
        p_adj: &p_adj,
        residuals,
        signed_residuals: signed_residuals.as_deref(),
        direction: direction.as_deref(),
        residual_std,
        significant: &significant,
        forward: &forward,
        config,
    };
    let mut reports: Vec<(usize, FeatureReport)> =
        wanted.par_iter().map(|&j| one_report(&input, j)).collect();
    // Strongest first: the forward order, then the rest by their own (marginal) strength.
    reports.sort_by(|(ra, a), (rb, b)| ra.cmp(rb).then(report::compare(a, b)));
    let reports: Vec<FeatureReport> = reports.into_iter().map(|(_, r)| r).collect();

    // The pair screen reads only the table and what the forward pass left: the binned
    // features and the residual's other copies are freed before it (its cells are the
    // diagnosis's peak of memory otherwise).
    drop(analysed);
    drop(signed_residuals);
    Screened {
        reports,
        residual_std,
        null_block,
        left: forward.left,
        fold,
        direction,
        variance,
    }
}

/// Checks the residuals against `table` and `config` (one finite residual per row, enough rows
/// and blocks for the folds); the block length of the folds.
fn check_input(
    table: &FeatureTable,
    residuals: &[f64],
    config: &CheckedDiagnoseConfig,
) -> Result<usize, DiagnoseError> {
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
    Ok(block_len)
}

/// The clipped, centred residual and what the screen reads with it.
struct Centred<'a> {
    y: &'a [f64],
    /// Sum of squares of `y`.
    sst: f64,
    /// The direction-signed residual's sum of squares about its mean, if there is a direction.
    signed_sst: Option<f64>,
    direction: Option<&'a [i8]>,
    fold: &'a [u8],
    variance: f64,
}

/// Every column binned, cross-validated and its observed statistic computed (or why it is
/// unusable). Columns are independent (no random draws): in parallel, collected in table order.
fn analyse_columns(
    table: &FeatureTable,
    c: &Centred<'_>,
    config: &CheckedDiagnoseConfig,
) -> Vec<Result<Analysed, Unusable>> {
    table
        .columns()
        .par_iter()
        .map(|col| {
            if super::pairs::pair_only(col.origin) {
                return Err(Unusable::PairOnly);
            }
            col.binned(config.max_bins, config.min_bin_rows, config.max_discrete)
                .map(|binned| {
                    let can_sign = c.signed_sst.is_some() && signable(col);
                    let g = gain(
                        &binned,
                        can_sign,
                        c.y,
                        c.direction,
                        c.fold,
                        config.folds,
                        c.variance,
                    );
                    let mut observed = FTest::new(&binned).min_p(&binned, c.y, c.sst);
                    if let (Some(sst), Some(d)) = (c.signed_sst.filter(|_| can_sign), c.direction) {
                        observed =
                            observed.min(FTest::new(&binned).min_p_signed(&binned, c.y, d, sst));
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
        .collect()
}

/// What [`one_report`] reads: the screen's results for every column.
struct ReportInput<'a> {
    table: &'a FeatureTable,
    analysed: &'a [Result<Analysed, Unusable>],
    p_raw: &'a [f64],
    p_adj: &'a [f64],
    residuals: &'a [f64],
    /// The residuals × direction, when a wanted report is direction-signed.
    signed_residuals: Option<&'a [f64]>,
    direction: Option<&'a [i8]>,
    residual_std: f64,
    significant: &'a [usize],
    forward: &'a Forward,
    config: &'a CheckedDiagnoseConfig,
}

/// Column `j`'s report, with its place in the forward order.
fn one_report(inp: &ReportInput<'_>, j: usize) -> (usize, FeatureReport) {
    let (col, a) = (&inp.table.columns()[j], &inp.analysed[j]);
    let mut r = match a {
        Ok(a) => report::feature_report(
            col,
            a.shift,
            &a.binned,
            a.explained,
            inp.p_raw[j],
            inp.p_adj[j],
            match (inp.signed_residuals, a.by_direction) {
                (Some(s), true) => s,
                _ => inp.residuals,
            },
            a.by_direction,
            inp.direction,
            inp.residual_std,
            inp.config,
        ),
        Err(why) => report::skipped_report(col, why, inp.residual_std),
    };
    r.explained_beyond_previous = inp.forward.beyond[j];
    r.significant = inp.significant.contains(&j);
    let beyond = inp.forward.beyond[j].unwrap_or(0.0);
    r.flagged = r.significant && r.explained.min(beyond) >= inp.config.min_effect;
    if a.is_ok() {
        r.reason = match (r.significant, r.flagged) {
            (_, true) => super::Reason::Flagged,
            (true, false) => super::Reason::BelowPracticalMinimum,
            (false, _) => super::Reason::NotSignificant,
        };
    }
    if r.significant && !r.flagged {
        // As many decimals as it takes to tell the failing share from the minimum.
        let min = inp.config.min_effect;
        let (_, m) = super::apart(r.explained.min(beyond), min, 100.0, 1);
        let d = m.len() - m.find('.').map_or(m.len(), |i| i + 1);
        let note = format!(
            "{}: significant (p = {:.3}) but too small to matter: {:.d$} % of the residual \
             variance alone, {:.d$} % beyond the features ranked before it, below the \
             practical minimum of {m} %",
            r.reason,
            r.p_value,
            100.0 * r.explained,
            100.0 * beyond,
        );
        r.note = Some(match r.note.take() {
            Some(n) => format!("{note}; {n}"),
            None => note,
        });
    }
    if let Some(by) = inp.forward.explained_away_by[j] {
        let note = format!(
            "confounded with `{}`, which explains it away (what `{}` adds beyond it: {:.1} %)",
            inp.table.columns()[by].name,
            col.name,
            100.0 * inp.forward.twin_gain[j]
        );
        r.note = Some(match r.note.take() {
            Some(n) => format!("{note}; {n}"),
            None => note,
        });
    }
    let rank = inp
        .forward
        .order
        .iter()
        .position(|&k| k == j)
        .unwrap_or(usize::MAX);
    (rank, r)
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
pub(super) fn winsorize(residuals: &[f64]) -> Vec<f64> {
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
pub(super) fn assign_folds(n: usize, block_len: usize, folds: usize, seed: u64) -> Vec<u8> {
    let n_blocks = n.div_ceil(block_len);
    let mut order: Vec<usize> = (0..n_blocks).collect();
    shuffle(&mut order, &mut SimRng::substream(seed, 1));
    let mut block_fold = vec![0u8; n_blocks];
    for (pos, &b) in order.iter().enumerate() {
        block_fold[b] = u8::try_from(pos % folds).unwrap_or(u8::MAX);
    }
    (0..n).map(|i| block_fold[i / block_len]).collect()
}

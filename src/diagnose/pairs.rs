//! Physics no single feature expresses: pair screening and the global check.
//!
//! Both work on what the forward pass left (the residual minus the out-of-fold smooths of the
//! features it ranked) and use the same cross-validated binned smoother as every single
//! feature, on **cells**: each feature is cut at its quartiles (a discrete feature keeps its
//! values; undefined rows are their own level), and the cell of a row is the combination of its
//! levels. A pair whose cells explain at least [`super::DiagnoseConfig::min_effect`] more than
//! the better of its two features on their own has an interaction without a one-dimensional
//! marginal (a covariate × position); the interaction term `by:A:B` is suggested and left to
//! the verification refit to confirm. The global check does the same for the joint cells of the
//! [`GLOBAL_FEATURES`] strongest candidates: when they explain clearly more than the best single
//! feature, something remains that no single feature explains.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::smoother::Binned;
use super::{Ctx, DiagnoseConfig, FeatureColumn, FeatureOrigin, FeatureTable, gain};
use crate::history::Feature;

/// Levels per feature in a cell (quartiles).
pub(super) const LEVELS: usize = 4;
/// Features in the global check's joint cells.
pub(super) const GLOBAL_FEATURES: usize = 3;
/// Most interactions reported.
pub(super) const MAX_INTERACTIONS: usize = 3;

/// A pair of candidates with an interaction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Interaction {
    /// First feature.
    pub a: String,
    /// Second feature.
    pub b: String,
    /// Out-of-sample fraction of the residual variance the pair's cells explain (of what the
    /// single features left).
    pub explained_pair: f64,
    /// The better of the two features alone, same basis.
    pub best_single: f64,
    /// The interaction term to verify (`by:A:B`).
    pub suggested_term: String,
}

/// The global check.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GlobalCheck {
    /// The candidates whose joint cells were smoothed.
    pub features: Vec<String>,
    /// What the joint cells explain out of sample (of what the single features left).
    pub explained_joint: f64,
    /// The best single feature, same basis.
    pub best_single: f64,
    /// Whether the joint smoother explains at least the practical minimum more.
    pub remains: bool,
}

/// A feature's level per row: quartile (or value) index, `LEVELS` for undefined (one byte a
/// row: `LEVELS` < 256).
fn levels(col: &FeatureColumn) -> Option<Vec<u8>> {
    let mut defined: Vec<f64> = col.iter().flatten().collect();
    if defined.len() < 2 * LEVELS {
        return None;
    }
    defined.sort_by(f64::total_cmp);
    defined.dedup();
    let cuts: Vec<f64> = if defined.len() <= LEVELS {
        defined.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect()
    } else {
        let mut all: Vec<f64> = col.iter().flatten().collect();
        all.sort_by(f64::total_cmp);
        let mut c: Vec<f64> = (1..LEVELS).map(|q| all[q * all.len() / LEVELS]).collect();
        c.dedup_by(|a, b| a.total_cmp(b).is_eq());
        c
    };
    if cuts.is_empty() {
        return None;
    }
    Some(
        col.iter()
            .map(|v| match v {
                Some(x) => cuts.iter().filter(|&&c| x >= c).count() as u8,
                None => LEVELS as u8,
            })
            .collect(),
    )
}

/// The cross-validated gain of the cells made of `parts` on `r`.
fn cells_gain(parts: &[&Vec<u8>], r: &[f64], ctx: &Ctx, config: &DiagnoseConfig) -> f64 {
    let base = LEVELS + 1;
    let cell: Vec<f64> = (0..r.len())
        .map(|i| {
            parts
                .iter()
                .fold(0usize, |acc, p| acc * base + usize::from(p[i])) as f64
        })
        .collect();
    let max_cells = base.pow(parts.len() as u32);
    match Binned::new(
        &cell,
        config.max_bins,
        config.min_bin_rows,
        max_cells.min(256),
    ) {
        Ok(b) => gain(&b, false, r, None, ctx.fold, ctx.folds, ctx.variance).explained,
        Err(_) => 0.0,
    }
}

/// Whether a pair is worth an interaction term: not two time features, not a feature with
/// the direction (the direction-signed single analysis covers `direction × feature`).
/// A summed-memory or lagged feature is no column `by:` can read (its term is `memsum` or
/// `lag:COL`), so it is not paired either.
fn pairable(c: &FeatureColumn) -> bool {
    !super::is_time(c.origin)
        && matches!(
            c.origin,
            FeatureOrigin::BuiltIn(_) | FeatureOrigin::Covariate
        )
        && c.origin != FeatureOrigin::BuiltIn(Feature::Direction)
}

/// Pair screening and the global check on `left`, the residual the forward pass left.
pub(crate) fn screen(
    table: &FeatureTable,
    left: &[f64],
    ctx: &Ctx,
    config: &DiagnoseConfig,
) -> (Vec<Interaction>, Option<GlobalCheck>) {
    // Every level table and every cell smoother below is independent of the others: in
    // parallel, collected in order (the same results for any thread count).
    let cols: Vec<(&FeatureColumn, Vec<u8>)> = table
        .columns()
        .par_iter()
        .filter(|c| !super::is_time(c.origin))
        .filter_map(|c| levels(c).map(|l| (c, l)))
        .collect();
    if cols.is_empty() || left.is_empty() || ctx.variance <= 0.0 {
        return (Vec::new(), None);
    }
    let single: Vec<f64> = cols
        .par_iter()
        .map(|(_, l)| cells_gain(&[l], left, ctx, config))
        .collect();
    let pairs: Vec<(usize, usize)> = (0..cols.len())
        .flat_map(|i| (i + 1..cols.len()).map(move |j| (i, j)))
        .filter(|&(i, j)| pairable(cols[i].0) && pairable(cols[j].0))
        .collect();
    let pair_gains: Vec<f64> = pairs
        .par_iter()
        .map(|&(i, j)| cells_gain(&[&cols[i].1, &cols[j].1], left, ctx, config))
        .collect();
    let mut found = Vec::new();
    // Each feature's strongest showing, alone or in a pair: the global check smooths the
    // joint cells of the strongest, so a feature that matters only jointly is among them.
    let mut score = single.clone();
    for (&(i, j), &pair) in pairs.iter().zip(&pair_gains) {
        score[i] = score[i].max(pair);
        score[j] = score[j].max(pair);
        let best = single[i].max(single[j]);
        if pair - best >= config.min_effect.max(1e-9) {
            found.push(Interaction {
                a: cols[i].0.name.clone(),
                b: cols[j].0.name.clone(),
                explained_pair: pair,
                best_single: best,
                suggested_term: format!("by:{}:{}", cols[i].0.name, cols[j].0.name),
            });
        }
    }
    found.sort_by(|x, y| {
        (y.explained_pair - y.best_single).total_cmp(&(x.explained_pair - x.best_single))
    });
    found.truncate(MAX_INTERACTIONS);
    let mut order: Vec<usize> = (0..cols.len()).collect();
    order.sort_by(|&a, &b| score[b].total_cmp(&score[a]).then(a.cmp(&b)));
    let top: Vec<usize> = order.into_iter().take(GLOBAL_FEATURES).collect();
    let parts: Vec<&Vec<u8>> = top.iter().map(|&k| &cols[k].1).collect();
    let joint = cells_gain(&parts, left, ctx, config);
    let best_single = single.iter().copied().fold(0.0, f64::max);
    let global = GlobalCheck {
        features: top.iter().map(|&k| cols[k].0.name.clone()).collect(),
        explained_joint: joint,
        best_single,
        remains: joint - best_single >= config.min_effect.max(1e-9),
    };
    (found, Some(global))
}

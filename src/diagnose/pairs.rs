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

use super::smoother::{Binned, order_statistics, smallest_distinct};
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
    let cuts = level_cuts(&mut defined);
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

/// The cut points of [`levels`] for the defined values `x` (reordered): midway between
/// consecutive distinct values when there are at most [`LEVELS`] of them, else the quartiles
/// (duplicates dropped). By scanning and selection, without a sort: the same values as
/// sorting `x` by `total_cmp` and deduplicating ([`level_cuts_reference`], tested).
fn level_cuts(x: &mut [f64]) -> Vec<f64> {
    let distinct = smallest_distinct(x, LEVELS + 1);
    if distinct.len() <= LEVELS {
        return distinct.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
    }
    let ranks: Vec<usize> = (1..LEVELS).map(|q| q * x.len() / LEVELS).collect();
    let mut c = order_statistics(x, &ranks);
    c.dedup_by(|a, b| a.total_cmp(b).is_eq());
    c
}

/// [`level_cuts`] by sorting (the slow, obvious reference it is tested against).
#[cfg(test)]
fn level_cuts_reference(x: &[f64]) -> Vec<f64> {
    let mut defined = x.to_vec();
    defined.sort_by(f64::total_cmp);
    defined.dedup();
    if defined.len() <= LEVELS {
        return defined.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
    }
    let mut all = x.to_vec();
    all.sort_by(f64::total_cmp);
    let mut c: Vec<f64> = (1..LEVELS).map(|q| all[q * all.len() / LEVELS]).collect();
    c.dedup_by(|a, b| a.total_cmp(b).is_eq());
    c
}

/// The cells of `parts` (levels `0..=LEVELS` each, at most three parts): the combination of
/// a row's levels in base `LEVELS + 1`, below 125.
fn cells(parts: &[&Vec<u8>], rows: usize) -> Vec<u8> {
    let base = (LEVELS + 1) as u8;
    let mut cell = vec![0u8; rows];
    for p in parts {
        for (c, &l) in cell.iter_mut().zip(p.iter()) {
            *c = *c * base + l;
        }
    }
    cell
}

/// The cross-validated gain of the cells made of `parts` on `r`.
fn cells_gain(parts: &[&Vec<u8>], r: &[f64], ctx: &Ctx, config: &DiagnoseConfig) -> f64 {
    let max_cells = (LEVELS + 1).pow(parts.len() as u32);
    // The cells binned from their codes by counting: the same bins as `Binned::new` of the
    // codes as numbers with `max_cells` discrete values (tested).
    let binned = if max_cells <= 256 {
        Binned::from_codes(&cells(parts, r.len()), config.min_bin_rows)
    } else {
        let base = LEVELS + 1;
        let cell: Vec<f64> = (0..r.len())
            .map(|i| {
                parts
                    .iter()
                    .fold(0usize, |acc, p| acc * base + usize::from(p[i])) as f64
            })
            .collect();
        Binned::new(&cell, config.max_bins, config.min_bin_rows, 256)
    };
    match binned {
        Ok(b) => gain(&b, false, r, None, ctx.fold, ctx.folds, ctx.variance).explained,
        Err(_) => 0.0,
    }
}

/// Whether a pair is worth an interaction term: not two time features, not a feature with
/// the direction (the direction-signed single analysis covers `direction × feature`).
/// A summed-memory or lagged feature is no column `by:` can read (its term is `memsum` or
/// `lag:COL`), so it is not paired either. `reversal_position` is paired with `position`
/// alone ([`reversal_pair`]): that pair is the reversal-memory screen.
fn pairable(a: &FeatureColumn, b: &FeatureColumn) -> bool {
    let one = |c: &FeatureColumn| {
        !super::is_time(c.origin)
            && matches!(
                c.origin,
                FeatureOrigin::BuiltIn(_) | FeatureOrigin::Covariate
            )
            && c.origin != FeatureOrigin::BuiltIn(Feature::Direction)
    };
    let reversal =
        |c: &FeatureColumn| c.origin == FeatureOrigin::BuiltIn(Feature::ReversalPosition);
    one(a) && one(b) && (!(reversal(a) || reversal(b)) || reversal_pair(a, b))
}

/// Whether a feature is read only by the pair screen, not alone: `reversal_position`. Alone
/// it is a proxy of the direction of the next move (a motion turns back away from where it
/// last reversed) and of the seek length, and its single smoother took their place on logs
/// whose effects they name; jointly with `position` it is what no other feature is.
pub(super) fn pair_only(origin: FeatureOrigin) -> bool {
    origin == FeatureOrigin::BuiltIn(Feature::ReversalPosition)
}

/// Whether `(a, b)` is the pair (`position`, `reversal_position`) in either order: the output
/// depends on where the head is and where the motion last turned jointly — hysteresis with
/// reversal memory, whose loops are not congruent (a `play`/`dahl` loop depends on the two
/// only through their difference, `since_reversal`, which the single screen reads). Its term
/// is `preisach` (the relay count chosen by the verification), not `by:`.
fn reversal_pair(a: &FeatureColumn, b: &FeatureColumn) -> bool {
    let is = |c: &FeatureColumn, f| c.origin == FeatureOrigin::BuiltIn(f);
    (is(a, Feature::Position) && is(b, Feature::ReversalPosition))
        || (is(a, Feature::ReversalPosition) && is(b, Feature::Position))
}

/// The term a screened pair suggests: `preisach` for the reversal pair ([`reversal_pair`]),
/// else `by:A:B`. The reversal pair is read only on the residual of a model that already
/// holds a congruent-loop hysteresis term ([`holds_congruent_loops`]) and no `preisach`:
/// where no such term is in the model, a `play`/`dahl` loop left in the residual is a joint
/// function of the two as well (of their difference), and a Preisach grid — which holds every
/// play operator — would be refitted in place of the two-parameter term that answers it
/// (`since_reversal` → `play`/`dahl`, from the single screen). `None`: the pair suggests nothing.
fn pair_term(a: &FeatureColumn, b: &FeatureColumn, existing: &[String]) -> Option<String> {
    use crate::model::terms::preisach;
    if !reversal_pair(a, b) {
        return Some(crate::model::terms::by::spec(&a.name, &b.name));
    }
    let has = existing
        .iter()
        .any(|t| crate::model::registry::head(t.trim()) == preisach::HEAD);
    (!has && holds_congruent_loops(existing)).then(|| preisach::HEAD.to_string())
}

/// Whether the model's terms hold a hysteresis state term with congruent loops (a
/// direction-signed state term other than the plain `direction` offset: `dahl[:N]`,
/// `play[:N]`), whose loops depend on the position and the last reversal only through their
/// difference.
pub(super) fn holds_congruent_loops(existing: &[String]) -> bool {
    existing.iter().map(|t| t.trim()).any(|t| {
        crate::model::registry::is_signed_state(t)
            && crate::model::registry::head(t) != crate::model::terms::direction::HEAD
    })
}

/// The best single gain among the single screen's candidates (a pair-only feature is not one).
fn order_best(single: &[f64], cols: &[(&FeatureColumn, Vec<u8>)]) -> f64 {
    single
        .iter()
        .zip(cols)
        .filter(|(_, (c, _))| !pair_only(c.origin))
        .map(|(&g, _)| g)
        .fold(0.0, f64::max)
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
        .filter(|&(i, j)| pairable(cols[i].0, cols[j].0))
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
        if pair - best >= config.min_effect.max(1e-9)
            && let Some(term) = pair_term(cols[i].0, cols[j].0, &config.existing_terms)
        {
            found.push(Interaction {
                a: cols[i].0.name.clone(),
                b: cols[j].0.name.clone(),
                explained_pair: pair,
                best_single: best,
                suggested_term: term,
            });
        }
    }
    found.sort_by(|x, y| {
        (y.explained_pair - y.best_single).total_cmp(&(x.explained_pair - x.best_single))
    });
    found.truncate(MAX_INTERACTIONS);
    // The global check's candidates are the single screen's (a pair-only feature is not one).
    let mut order: Vec<usize> = (0..cols.len())
        .filter(|&k| !pair_only(cols[k].0.origin))
        .collect();
    order.sort_by(|&a, &b| score[b].total_cmp(&score[a]).then(a.cmp(&b)));
    let top: Vec<usize> = order.into_iter().take(GLOBAL_FEATURES).collect();
    let parts: Vec<&Vec<u8>> = top.iter().map(|&k| &cols[k].1).collect();
    let joint = cells_gain(&parts, left, ctx, config);
    let best_single = order_best(&single, &cols);
    let global = GlobalCheck {
        features: top.iter().map(|&k| cols[k].0.name.clone()).collect(),
        explained_joint: joint,
        best_single,
        remains: joint - best_single >= config.min_effect.max(1e-9),
    };
    (found, Some(global))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// Reference: [`level_cuts_reference`], sorting and deduplicating as `levels` did. The
    /// selection must give the same cut bits: few distinct values (1 to 5), ties, −0 and +0,
    /// many distinct values with heavy ties at the quartiles.
    #[test]
    fn level_cuts_by_selection_equal_the_sorted_ones() {
        let mut rng = SimRng::new(16);
        for n in [8usize, 9, 40, 1001] {
            for distinct in [1u64, 2, 4, 5, 7, 1 << 30] {
                for _ in 0..4 {
                    let x: Vec<f64> = (0..n)
                        .map(|_| match rng.below(distinct) {
                            0 if rng.below(2) == 0 => -0.0,
                            0 => 0.0,
                            k => k as f64 * 0.5 - 3.0,
                        })
                        .collect();
                    let fast = level_cuts(&mut x.clone());
                    let slow = level_cuts_reference(&x);
                    let bits = |v: &[f64]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&fast), bits(&slow), "n {n} distinct {distinct}");
                }
            }
        }
    }

    /// Reference: `Binned::new` of the cell codes as numbers (every row defined, at most
    /// `max_cells` discrete values), as `cells_gain` called it before: the same fine bins,
    /// counts of bins and levels, or the same reason for no bins, for one to three parts
    /// of uneven levels (rare cells pooled, a single populated cell, one dominant cell).
    #[test]
    fn cells_from_codes_bin_as_the_numbers_do() {
        let mut rng = SimRng::new(17);
        for rows in [30usize, 200, 5000] {
            for parts in 1..=3usize {
                for skew in [0u64, 1, 3, 40] {
                    let make = |rng: &mut SimRng| -> Vec<u8> {
                        (0..rows)
                            .map(|_| {
                                let v = rng.below(LEVELS as u64 + 1 + skew);
                                v.min(LEVELS as u64) as u8
                            })
                            .collect()
                    };
                    let cols: Vec<Vec<u8>> = (0..parts).map(|_| make(&mut rng)).collect();
                    let refs: Vec<&Vec<u8>> = cols.iter().collect();
                    let max_cells = (LEVELS + 1).pow(parts as u32);
                    let codes = cells(&refs, rows);
                    let numbers: Vec<f64> = codes.iter().map(|&c| f64::from(c)).collect();
                    for min_bin_rows in [2usize, 10, 60] {
                        let fast = Binned::from_codes(&codes, min_bin_rows);
                        let slow = Binned::new(&numbers, 64, min_bin_rows, max_cells.min(256));
                        match (fast, slow) {
                            (Ok(f), Ok(s)) => {
                                assert_eq!(f.fine, s.fine);
                                assert_eq!(f.n_fine, s.n_fine);
                                assert_eq!(f.kind, s.kind);
                                assert_eq!(f.levels, s.levels);
                            }
                            (f, s) => assert_eq!(f.err(), s.err(), "rows {rows} parts {parts}"),
                        }
                    }
                }
            }
        }
        // A constant cell column.
        let one = vec![3u8; 50];
        let numbers = vec![3.0; 50];
        assert_eq!(
            Binned::from_codes(&one, 10).err(),
            Binned::new(&numbers, 64, 10, 5).err()
        );
    }
}

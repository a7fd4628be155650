//! The one-dimensional smoother: binned means on nested quantile bins, with the number of bins
//! chosen by cross-validation, and missing values in a bin of their own (the F-test on these
//! bins is in `ftest.rs`, the permutation test's fused pass over them in `kernels.rs`).
//!
//! A continuous feature is cut at quantiles into `K_max` (a power of two) fine bins; coarser
//! candidates with `K_max/2, K_max/4, …, 1` bins use every second, fourth, … cut point, so a fine
//! bin index `i` maps to `i >> s` at level `s`. The bins nest exactly, which lets one pass over
//! the rows fill a (fold × fine bin) table of sums from which every candidate's cross-validated
//! error follows without touching the rows again. A discrete feature (few distinct values) has one
//! bin per value and two candidates: all values, or one bin. Missing values always form a bin of
//! their own, also in the one-bin candidate, so "undefined" can itself be an effect.

use super::values::defined;

/// Fine-bin index of a missing value.
pub(crate) const MISSING: u16 = u16::MAX;

/// How a feature's values were binned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum BinKind {
    /// One bin per distinct value.
    Discrete,
    /// Quantile bins.
    Quantile,
}

/// The fine slot of each row of a feature (`0..n_fine` its fine bin, `n_fine` undefined):
/// one byte a row when the feature has at most 255 fine bins (discrete features of up to 255
/// values, quantile bins up to 128), else two (at most 4096 quantile bins and the undefined
/// slot).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum FineSlots {
    /// One byte a row.
    Narrow(Vec<u8>),
    /// Two bytes a row.
    Wide(Vec<u16>),
}

impl FineSlots {
    /// The slots of `fine` (fine bins, [`MISSING`] for an undefined value) of a feature with
    /// `n_fine` fine bins, one byte a row when the `n_fine + 1` slots fit.
    fn of_bins(fine: impl ExactSizeIterator<Item = u16>, n_fine: usize) -> FineSlots {
        let slot = |f: u16| if f == MISSING { n_fine } else { f as usize };
        if n_fine < 256 {
            FineSlots::Narrow(fine.map(|f| slot(f) as u8).collect())
        } else {
            FineSlots::Wide(fine.map(|f| slot(f) as u16).collect())
        }
    }

    /// Rows.
    pub(crate) fn len(&self) -> usize {
        match self {
            FineSlots::Narrow(c) => c.len(),
            FineSlots::Wide(c) => c.len(),
        }
    }

    /// Slot of row `i`.
    #[inline(always)]
    pub(crate) fn get(&self, i: usize) -> usize {
        match self {
            FineSlots::Narrow(c) => c[i] as usize,
            FineSlots::Wide(c) => c[i] as usize,
        }
    }

    /// The one-byte slots, when the feature has them.
    pub(crate) fn narrow(&self) -> Option<&[u8]> {
        match self {
            FineSlots::Narrow(c) => Some(c),
            FineSlots::Wide(_) => None,
        }
    }

    /// Takes the one-byte slots out, leaving none (0 rows) until they are put back.
    pub(super) fn take_narrow(&mut self) -> Option<Vec<u8>> {
        match self {
            FineSlots::Narrow(c) => Some(std::mem::take(c)),
            FineSlots::Wide(_) => None,
        }
    }
}

/// A stored value type of a feature column ([`Binned::of_keys`]): the number it stands for
/// (NaN for an undefined row), and an order that is `total_cmp` of those numbers.
pub(crate) trait Key: Copy + Send + Sync {
    /// The number (bit for bit the column's decoded `f64`; NaN = undefined).
    fn num(self) -> f64;
    /// `self.num().total_cmp(&other.num())`, computed in the stored type where it can be.
    fn order(&self, other: &Self) -> std::cmp::Ordering;
}

/// A feature prepared for smoothing.
#[derive(Debug, Clone)]
pub(crate) struct Binned {
    /// Fine slot of each row (the fine bin; `n_fine` for an undefined value).
    pub fine: FineSlots,
    /// Number of fine (non-missing) bins, ≥ 1.
    pub n_fine: usize,
    /// Discrete or quantile bins.
    pub kind: BinKind,
    /// Candidate levels (shifts), coarsest first.
    pub levels: Vec<u32>,
}

/// Why a feature cannot be smoothed.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Unusable {
    /// Every value is the same (the value is given).
    Constant(f64),
    /// No value is defined.
    AllMissing,
    /// Every value but `others` rows (fewer than the smallest bin) is `value`.
    NearlyConstant {
        /// The common value.
        value: f64,
        /// Rows with another value or undefined.
        others: usize,
    },
    /// A feature the pair screen reads jointly with another and the single screen leaves out
    /// (`reversal_position`, read with `position`).
    PairOnly,
}

/// Shift that maps every fine bin to bin 0.
const ONE_BIN: u32 = 31;

/// Groups consecutive distinct values (`counts[k]` rows of the k-th smallest) into slots of at
/// least `min_bin_rows` rows, in order; a short tail joins the slot before it. Returns each
/// distinct value's slot and the number of slots (at least 1).
fn pool_counts(counts: &[usize], min_bin_rows: usize) -> (Vec<u16>, usize) {
    let mut label = vec![0u16; counts.len()];
    let mut next = 0u16;
    let mut pending = 0usize;
    for (k, &c) in counts.iter().enumerate() {
        label[k] = next;
        pending += c;
        if pending >= min_bin_rows {
            next += 1;
            pending = 0;
        }
    }
    if pending > 0 && next > 0 {
        // The small tail joins the previous group.
        for l in label.iter_mut().filter(|l| **l == next) {
            *l = next - 1;
        }
    } else if pending > 0 {
        next = 1;
    }
    (label, next.max(1) as usize)
}

impl Binned {
    /// Bins `values`: discrete if at most `max_discrete` distinct values, else `k_max` quantile
    /// bins, where `k_max` is the largest power of two ≤ `max_bins` leaving at least
    /// `min_bin_rows` defined values per bin. NaN marks an undefined value.
    pub(super) fn new(
        values: &[f64],
        max_bins: usize,
        min_bin_rows: usize,
        max_discrete: usize,
    ) -> Result<Binned, Unusable> {
        Binned::of_keys(
            || values.iter().copied(),
            max_bins,
            min_bin_rows,
            max_discrete,
        )
    }

    /// [`Binned::new`] of the numbers `rows()` gives as their stored type `T` ([`Key::num`]
    /// each, NaN = undefined): the same bins, with no `f64` copy of a narrow column — the
    /// defined values are gathered in `T` (1–4 bytes a row for a narrow column instead of 8
    /// for its decoded copy and 8 for the defined values) and compared as the `f64`s they
    /// stand for.
    pub(super) fn of_keys<T: Key, I: ExactSizeIterator<Item = T>>(
        rows: impl Fn() -> I,
        max_bins: usize,
        min_bin_rows: usize,
        max_discrete: usize,
    ) -> Result<Binned, Unusable> {
        let len = rows().len();
        // The defined values; no sort: the distinct values and the quantile cuts below are
        // found by scanning and selection (the same values a sort gives, tested). Room for
        // every row at once (no doubling of the buffer as it fills).
        let mut sorted: Vec<T> = Vec::with_capacity(len);
        sorted.extend(rows().filter(|x| !x.num().is_nan()));
        let has_missing = sorted.len() < len;
        if sorted.is_empty() {
            return Err(Unusable::AllMissing);
        }
        let distinct_values = distinct_keys(&sorted, max_discrete + 1);
        if distinct_values.len() == 1 && !has_missing {
            return Err(Unusable::Constant(distinct_values[0]));
        }
        if distinct_values.len() <= max_discrete {
            // A value (or the undefined group) seen in fewer than `min_bin_rows` rows has no
            // reliable mean: one odd row alone in its bin (the first seek, before the head has a
            // direction) would make the F-test's extreme tail. Such a group is pooled with its
            // neighbour: a value with the next larger value (the previous one for the largest),
            // the undefined rows with the largest value (undefined rest distance = no rest
            // position, i.e. farther than any).
            let mut counts = vec![0usize; distinct_values.len()];
            for &v in &sorted {
                let v = v.num();
                counts[distinct_values.partition_point(|&d| d < v)] += 1;
            }
            let missing = len - sorted.len();
            let (label, n_fine) = pool_counts(&counts, min_bin_rows);
            let pool_missing = missing > 0 && missing < min_bin_rows;
            if n_fine == 1 && (missing == 0 || pool_missing) {
                let (k, &most) = counts
                    .iter()
                    .enumerate()
                    .max_by_key(|(_, c)| **c)
                    .unwrap_or((0, &0));
                return Err(Unusable::NearlyConstant {
                    value: distinct_values[k],
                    others: len - most,
                });
            }
            drop(sorted);
            let fine = FineSlots::of_bins(
                rows().map(|v| match defined(v.num()) {
                    Some(x) => label[distinct_values.partition_point(|&d| d < x)],
                    None if pool_missing => n_fine as u16 - 1,
                    None => MISSING,
                }),
                n_fine,
            );
            let levels = if n_fine > 1 {
                vec![ONE_BIN, 0]
            } else {
                vec![0]
            };
            return Ok(Binned {
                fine,
                n_fine,
                kind: BinKind::Discrete,
                levels,
            });
        }
        let cap = max_bins.min(sorted.len() / min_bin_rows.max(1)).max(1);
        let mut k_max = 1usize;
        while k_max * 2 <= cap {
            k_max *= 2;
        }
        let n = sorted.len();
        // A cut between ranks pos−1 and pos: values ≥ the cut go to the upper bin.
        let ranks: Vec<usize> = (1..k_max).map(|k| (k * n / k_max).min(n - 1)).collect();
        let cuts = order_statistics(&mut sorted, &ranks);
        drop(sorted);
        // Too few undefined rows for a bin of their own join the top bin (as above).
        let missing = len - n;
        let pool_missing = missing > 0 && missing < min_bin_rows;
        let fine = FineSlots::of_bins(
            rows().map(|v| match defined(v.num()) {
                Some(x) => cuts.partition_point(|&c| c <= x) as u16,
                None if pool_missing => (k_max - 1) as u16,
                None => MISSING,
            }),
            k_max,
        );
        let top = k_max.trailing_zeros();
        let levels = (0..=top).rev().collect();
        Ok(Binned {
            fine,
            n_fine: k_max,
            kind: BinKind::Quantile,
            levels,
        })
    }

    /// [`Binned::new`] of byte codes, every row defined (the numbers `codes[i] as f64`,
    /// with `max_discrete` at least the number of distinct codes, so the bins are
    /// discrete): the distinct values and their rows counted in one pass over the bytes
    /// instead of scanning for distinct values. The same bins, or the same reason for none,
    /// as [`Binned::new`] of those numbers (tested): each value is its own bin, a value seen
    /// in fewer than `min_bin_rows` rows pooled with the next larger one (the largest with
    /// the one below).
    pub(super) fn from_codes(codes: &[u8], min_bin_rows: usize) -> Result<Binned, Unusable> {
        let mut by_code = [0usize; 256];
        for &c in codes {
            by_code[c as usize] += 1;
        }
        // The distinct values ascending, and their counts.
        let present: Vec<usize> = (0..by_code.len()).filter(|&c| by_code[c] > 0).collect();
        let counts: Vec<usize> = present.iter().map(|&c| by_code[c]).collect();
        match present.len() {
            0 => return Err(Unusable::AllMissing),
            1 => return Err(Unusable::Constant(present[0] as f64)),
            _ => {}
        }
        // As `Binned::new`'s discrete path with no undefined rows.
        let (label, n_fine) = pool_counts(&counts, min_bin_rows);
        if n_fine == 1 {
            let (k, &most) = counts
                .iter()
                .enumerate()
                .max_by_key(|(_, c)| **c)
                .unwrap_or((0, &0));
            return Err(Unusable::NearlyConstant {
                value: present[k] as f64,
                others: codes.len() - most,
            });
        }
        let mut fine_of = [0u16; 256];
        for (&c, &l) in present.iter().zip(&label) {
            fine_of[c] = l;
        }
        Ok(Binned {
            fine: FineSlots::of_bins(codes.iter().map(|&c| fine_of[c as usize]), n_fine),
            n_fine,
            kind: BinKind::Discrete,
            levels: vec![ONE_BIN, 0],
        })
    }

    /// Number of slots (non-missing bins, then the missing bin) at level `shift`.
    pub(super) fn slots(&self, shift: u32) -> usize {
        self.defined_bins(shift) + 1
    }

    /// Number of non-missing bins at level `shift`.
    pub(super) fn defined_bins(&self, shift: u32) -> usize {
        if shift >= ONE_BIN {
            1
        } else {
            ((self.n_fine - 1) >> shift) + 1
        }
    }

    /// Slot of fine slot index `fs` (0..n_fine, n_fine = missing) at level `shift`.
    #[inline]
    pub(super) fn coarse_of_fine_slot(&self, fs: usize, shift: u32) -> usize {
        if fs == self.n_fine {
            self.defined_bins(shift)
        } else if shift >= ONE_BIN {
            0
        } else {
            fs >> shift
        }
    }

    /// Fine slot of row `i` (missing → `n_fine`).
    #[inline]
    pub(super) fn fine_slot(&self, i: usize) -> usize {
        self.fine.get(i)
    }
}

/// Cross-validated error of every candidate level of one feature.
#[derive(Debug, Clone)]
pub(crate) struct CvResult {
    /// The level with the smallest CV error (coarsest on ties).
    pub shift: u32,
    /// Its CV mean squared error.
    pub mse: f64,
}

/// Mean of the rows outside one fold: (`sum` − `fold_sum`) / (`cnt` − `fold_cnt`), or `empty`
/// when no rows remain. With the totals it is the training mean of a fold; with one bin's
/// totals, the out-of-fold prediction for that bin.
#[inline]
fn held_out_mean(sum: f64, cnt: f64, fold_sum: f64, fold_cnt: f64, empty: f64) -> f64 {
    let rest = cnt - fold_cnt;
    if rest > 0.0 {
        (sum - fold_sum) / rest
    } else {
        empty
    }
}

/// Cross-validates the binned-mean smoother of `b` on centred residuals `y` with fold labels
/// `fold` (0..folds). The prediction for a held-out row is the mean of the training rows in its
/// bin, or the training mean when its bin has no training rows.
pub(crate) fn cross_validate(b: &Binned, y: &[f64], fold: &[u8], folds: usize) -> CvResult {
    cross_validate_rows(b, y.iter().copied(), fold, folds)
}

/// [`cross_validate`] of the residual given row by row (`y`: one value per row, in row
/// order), so a derived residual (the direction-signed one) need not be stored: the same
/// sums in the same order, so the same result bit for bit.
pub(crate) fn cross_validate_rows(
    b: &Binned,
    y: impl ExactSizeIterator<Item = f64>,
    fold: &[u8],
    folds: usize,
) -> CvResult {
    let n_slots = b.n_fine + 1;
    let total_cnt = y.len() as f64;
    // (sum, sum of squares, count) per fold and fine slot.
    let mut sum = vec![0.0; folds * n_slots];
    let mut sq = vec![0.0; folds * n_slots];
    let mut cnt = vec![0.0; folds * n_slots];
    for (i, v) in y.enumerate() {
        let k = fold[i] as usize * n_slots + b.fine_slot(i);
        sum[k] += v;
        sq[k] += v * v;
        cnt[k] += 1.0;
    }
    let total_sum: f64 = sum.iter().sum();
    let fold_sum: Vec<f64> = (0..folds)
        .map(|f| sum[f * n_slots..(f + 1) * n_slots].iter().sum())
        .collect();
    let fold_cnt: Vec<f64> = (0..folds)
        .map(|f| cnt[f * n_slots..(f + 1) * n_slots].iter().sum())
        .collect();
    let mut best = CvResult {
        shift: b.levels[0],
        mse: f64::INFINITY,
    };
    for &shift in &b.levels {
        let m = b.slots(shift);
        let mut cs = vec![0.0; folds * m];
        let mut cq = vec![0.0; folds * m];
        let mut cc = vec![0.0; folds * m];
        for f in 0..folds {
            for fs in 0..n_slots {
                let k = f * n_slots + fs;
                let c = f * m + b.coarse_of_fine_slot(fs, shift);
                cs[c] += sum[k];
                cq[c] += sq[k];
                cc[c] += cnt[k];
            }
        }
        let mut bin_sum = vec![0.0; m];
        let mut bin_cnt = vec![0.0; m];
        for f in 0..folds {
            for s in 0..m {
                bin_sum[s] += cs[f * m + s];
                bin_cnt[s] += cc[f * m + s];
            }
        }
        let mut sse = 0.0;
        for f in 0..folds {
            let train_mean = held_out_mean(total_sum, total_cnt, fold_sum[f], fold_cnt[f], 0.0);
            for s in 0..m {
                let k = f * m + s;
                if cc[k] <= 0.0 {
                    continue;
                }
                let p = held_out_mean(bin_sum[s], bin_cnt[s], cs[k], cc[k], train_mean);
                sse += (cq[k] - 2.0 * p * cs[k] + cc[k] * p * p).max(0.0);
            }
        }
        let mse = sse / total_cnt;
        if mse < best.mse {
            best = CvResult { shift, mse };
        }
    }
    best
}

/// Adds `y[i]` into `sums[codes[i]]` for every row, in row order.
#[inline]
pub(super) fn add_by_slot<T: Copy + Into<usize>>(codes: &[T], y: &[f64], sums: &mut [f64]) {
    for (&c, &v) in codes.iter().zip(y) {
        sums[c.into()] += v;
    }
}

/// Adds `y[i] × direction[i]` into `sums[codes[i]]` for every row, in row order.
#[inline]
pub(super) fn add_by_slot_signed<T: Copy + Into<usize>>(
    codes: &[T],
    y: &[f64],
    direction: &[i8],
    sums: &mut [f64],
) {
    for ((&c, &v), &d) in codes.iter().zip(y).zip(direction) {
        sums[c.into()] += v * f64::from(d);
    }
}

/// Counts of rows per fine slot (invariant under permutation of the residuals).
pub(crate) fn fine_counts(b: &Binned) -> Vec<f64> {
    let mut cnt = vec![0.0; b.n_fine + 1];
    for i in 0..b.fine.len() {
        cnt[b.fine_slot(i)] += 1.0;
    }
    cnt
}

/// The up to `limit` smallest distinct values of `x`, ascending — what scanning `x` sorted by
/// `total_cmp` and keeping each value greater than the last kept gives (values equal as
/// numbers, −0 and +0, count once, as the first of them in that order). Found in one pass
/// with a small sorted list for finite values; a sort otherwise (`x` is then left sorted).
pub(super) fn smallest_distinct(x: &mut [f64], limit: usize) -> Vec<f64> {
    if limit == 0 || x.iter().any(|v| v.is_nan()) {
        return sorted_distinct_reference(x, limit);
    }
    distinct_keys(x, limit)
}

/// [`smallest_distinct`] of the numbers of `x` ([`Key::num`], none NaN, `limit` ≥ 1): one
/// pass with a small sorted list.
fn distinct_keys<T: Key>(x: &[T], limit: usize) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(limit + 1);
    for v in x.iter().map(|k| k.num()) {
        if out.len() == limit && out.last().is_some_and(|&l| v > l) {
            continue;
        }
        let pos = out.partition_point(|&d| d < v);
        match out.get_mut(pos) {
            Some(d) if *d <= v => {
                // Equal as numbers: keep the first in total order (−0 before +0).
                if v.total_cmp(d).is_lt() {
                    *d = v;
                }
            }
            _ => {
                out.insert(pos, v);
                out.truncate(limit);
            }
        }
    }
    out
}

/// [`smallest_distinct`] by sorting `x` (the slow, obvious reference, and the path for NaN).
fn sorted_distinct_reference(x: &mut [f64], limit: usize) -> Vec<f64> {
    x.sort_by(f64::total_cmp);
    let mut out: Vec<f64> = Vec::new();
    for &v in x.iter() {
        if out.last().is_none_or(|&last| v > last) {
            if out.len() == limit {
                break;
            }
            out.push(v);
        }
    }
    out
}

/// The values at `ranks` (ascending, each < `x.len()`) of `x` sorted by `total_cmp`, by
/// nested selection (`x` is reordered): O(n·log(ranks)) instead of a sort, the same values.
///
/// Generic over the stored type `T` of a column: the values of its numbers ([`Key::num`]),
/// ranked by `total_cmp` of those numbers (a narrow type's order is its numbers' order).
pub(super) fn order_statistics<T: Key>(x: &mut [T], ranks: &[usize]) -> Vec<f64> {
    /// Fills `out[i]` with the value at rank `ranks[i]` (distinct, ascending) of `x`, whose
    /// first element has rank `base`.
    fn select<T: Key>(x: &mut [T], base: usize, ranks: &[usize], out: &mut [f64]) {
        if ranks.is_empty() {
            return;
        }
        let mid = ranks.len() / 2;
        let r = ranks[mid] - base;
        let (left, &mut v, right) = x.select_nth_unstable_by(r, T::order);
        out[mid] = v.num();
        let (lo_out, hi_out) = out.split_at_mut(mid);
        select(left, base, &ranks[..mid], lo_out);
        select(right, base + r + 1, &ranks[mid + 1..], &mut hi_out[1..]);
    }
    let mut unique = ranks.to_vec();
    unique.dedup();
    let mut values = vec![0.0; unique.len()];
    select(x, 0, &unique, &mut values);
    ranks
        .iter()
        .map(|r| values[unique.partition_point(|u| u < r)])
        .collect()
}

/// Summary of one bin of the smoothed curve.
#[derive(Debug, Clone, Default)]
pub(crate) struct BinAcc {
    pub count: usize,
    pub x_sum: f64,
    pub x_min: f64,
    pub x_max: f64,
    pub y_sum: f64,
    pub y_sq: f64,
}

/// Per-slot accumulators of (x, y) at level `shift`.
pub(crate) fn accumulate(
    b: &Binned,
    shift: u32,
    x: impl Iterator<Item = f64>,
    y: &[f64],
) -> Vec<BinAcc> {
    let mut acc = vec![
        BinAcc {
            x_min: f64::INFINITY,
            x_max: f64::NEG_INFINITY,
            ..BinAcc::default()
        };
        b.slots(shift)
    ];
    for (i, (xv, &yv)) in x.zip(y).enumerate() {
        let a = &mut acc[b.coarse_of_fine_slot(b.fine_slot(i), shift)];
        a.count += 1;
        a.y_sum += yv;
        a.y_sq += yv * yv;
        if let Some(xv) = defined(xv) {
            a.x_sum += xv;
            a.x_min = a.x_min.min(xv);
            a.x_max = a.x_max.max(xv);
        }
    }
    acc
}

/// Out-of-fold predictions of the binned-mean smoother of `b` at level `shift`: for each row,
/// the mean of `y` over the training rows (other folds) in its bin, or the training mean when
/// its bin has none there. Removing these from `y` takes out what the feature explains without
/// letting a row's own noise leak into its prediction.
#[cfg(test)]
pub(crate) fn cv_predict(b: &Binned, shift: u32, y: &[f64], fold: &[u8], folds: usize) -> Vec<f64> {
    let (pred, m) = cv_fold_means(b, shift, y.iter().copied(), fold, folds);
    (0..y.len())
        .map(|i| pred[cv_cell(b, shift, fold, m, i)])
        .collect()
}

/// The cell of row `i` in the table of [`cv_fold_means`] (`m`: slots at level `shift`).
#[inline]
pub(crate) fn cv_cell(b: &Binned, shift: u32, fold: &[u8], m: usize, i: usize) -> usize {
    fold[i] as usize * m + b.coarse_of_fine_slot(b.fine_slot(i), shift)
}

/// The out-of-fold prediction of every (fold, slot) cell of [`cv_predict`] and the number of
/// slots `m`: row `i`'s prediction is `table[cv_cell(b, shift, fold, m, i)]`. The residual is
/// given row by row (`y`, in row order), so neither it nor the predictions need a vector of
/// their own (the same sums in the same order as `cv_predict`'s, so the same bits).
pub(crate) fn cv_fold_means(
    b: &Binned,
    shift: u32,
    y: impl Iterator<Item = f64>,
    fold: &[u8],
    folds: usize,
) -> (Vec<f64>, usize) {
    let m = b.slots(shift);
    let mut cs = vec![0.0; folds * m];
    let mut cc = vec![0.0; folds * m];
    for (i, v) in y.enumerate() {
        let k = fold[i] as usize * m + b.coarse_of_fine_slot(b.fine_slot(i), shift);
        cs[k] += v;
        cc[k] += 1.0;
    }
    let mut bin_sum = vec![0.0; m];
    let mut bin_cnt = vec![0.0; m];
    let mut fold_sum = vec![0.0; folds];
    let mut fold_cnt = vec![0.0; folds];
    for f in 0..folds {
        for s in 0..m {
            bin_sum[s] += cs[f * m + s];
            bin_cnt[s] += cc[f * m + s];
            fold_sum[f] += cs[f * m + s];
            fold_cnt[f] += cc[f * m + s];
        }
    }
    let total_sum: f64 = fold_sum.iter().sum();
    let total_cnt: f64 = fold_cnt.iter().sum();
    // Prediction per (fold, slot).
    let mut pred = vec![0.0; folds * m];
    for f in 0..folds {
        let train_mean = held_out_mean(total_sum, total_cnt, fold_sum[f], fold_cnt[f], 0.0);
        for s in 0..m {
            let k = f * m + s;
            pred[k] = held_out_mean(bin_sum[s], bin_cnt[s], cs[k], cc[k], train_mean);
        }
    }
    (pred, m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::{ftest::FTest, kernels::SlotTable};
    use crate::numeric::rng::SimRng;

    /// Reference: [`FTest::min_p`] of the stored products `y[i] × direction[i]` (the
    /// vector the diagnosis held before). `min_p_signed` makes each product as it adds it:
    /// the same statistic bit for bit, for one-byte and two-byte fine slots and undefined
    /// rows.
    #[test]
    fn signed_statistic_made_row_by_row_equals_the_stored_products() {
        let n = 4001;
        let mut rng = SimRng::new(5);
        let y: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let d: Vec<i8> = (0..n).map(|i| [-1i8, 1, 0][(i * 7 + i / 3) % 3]).collect();
        let stored: Vec<f64> = y.iter().zip(&d).map(|(r, &d)| r * f64::from(d)).collect();
        let sst = crate::numeric::stats::sum_sq_about_mean(&stored);
        let x: Vec<f64> = (0..n)
            .map(|i| {
                if i % 13 == 0 {
                    f64::NAN
                } else {
                    rng.range(0.0, 50.0)
                }
            })
            .collect();
        let levels: Vec<f64> = (0..n).map(|i| (i % 9) as f64).collect();
        for (values, max_bins) in [(&x, 64), (&x, 1024), (&levels, 64)] {
            let b = Binned::new(values, max_bins, 1, 10).expect("usable");
            let want = FTest::new(&b).min_p(&b, &stored, sst);
            let got = FTest::new(&b).min_p_signed(&b, &y, &d, sst);
            assert_eq!(got.to_bits(), want.to_bits());
        }
        let wide = Binned::new(&x, 1024, 1, 10).expect("usable");
        assert!(wide.fine.narrow().is_none());
    }

    /// Reference: [`FTest::min_p`], one feature's own pass over the rows (and, for
    /// [`SlotTable::take`], [`SlotTable::new`]'s copy). The fused pass of
    /// [`SlotTable`] over several features (quantile and discrete bins, missing values in a
    /// slot of their own and pooled, a signed second residual for the first features) must
    /// give the same statistic bit for bit.
    #[test]
    fn fused_pass_is_bit_identical_to_each_features_own_pass() {
        let n = 5003;
        let mut rng = SimRng::new(5);
        let options: Vec<Vec<Option<f64>>> = vec![
            (0..n).map(|_| Some(rng.range(0.0, 250.0))).collect(),
            (0..n).map(|i| (i % 7 != 0).then(|| rng.normal())).collect(),
            (0..n).map(|_| Some(rng.below(3) as f64)).collect(),
            (0..n)
                .map(|i| (i > 3).then(|| (rng.below(2) as f64) * 2.0 - 1.0))
                .collect(),
            (0..n).map(|i| Some((i / 100) as f64)).collect(),
        ];
        // Stored as a feature column stores them: NaN = undefined.
        let columns: Vec<Vec<f64>> = options
            .iter()
            .map(|c| c.iter().map(|v| v.unwrap_or(f64::NAN)).collect())
            .collect();
        let bins: Vec<Binned> = columns
            .iter()
            .map(|c| Binned::new(c, 64, 30, 10).expect("usable"))
            .collect();
        let y: Vec<f64> = (0..n).map(|_| rng.normal() * 3.0 + 0.1).collect();
        let d: Vec<f64> = (0..n).map(|_| (rng.below(2) as f64) * 2.0 - 1.0).collect();
        let ys: Vec<f64> = y.iter().zip(&d).map(|(a, b)| a * b).collect();
        let sst: f64 = y.iter().map(|v| v * v).sum();
        let sst_s: f64 = ys.iter().map(|v| v * v).sum();
        for signed in [0, 2, bins.len()] {
            let refs: Vec<&Binned> = bins.iter().collect();
            let table = SlotTable::new(&refs, signed).expect("few slots");
            let mut acc = vec![f64::NAN; table.len()];
            let mut acc_s = vec![f64::NAN; table.len()];
            table.accumulate(&y, &ys, &mut acc, &mut acc_s);
            for (j, b) in bins.iter().enumerate() {
                let mut t = FTest::new(b);
                let fused = t.min_p_of_sums(b, table.sums(&acc, j), n, sst);
                let own = FTest::new(b).min_p(b, &y, sst);
                assert_eq!(fused.to_bits(), own.to_bits(), "feature {j}");
                if j < signed {
                    let fused = t.min_p_of_sums(b, table.sums(&acc_s, j), n, sst_s);
                    let own = FTest::new(b).min_p(b, &ys, sst_s);
                    assert_eq!(fused.to_bits(), own.to_bits(), "signed feature {j}");
                }
            }
        }
        // `take` (the features' slots moved in, not copied) makes the same table as `new`
        // (the same sums, bit for bit), and `give_back` returns the same slots.
        let refs: Vec<&Binned> = bins.iter().collect();
        let copied = SlotTable::new(&refs, 2).expect("few slots");
        let mut lent = bins.clone();
        let mut muts: Vec<&mut Binned> = lent.iter_mut().collect();
        let taken = SlotTable::take(&mut muts, 2).expect("few slots");
        assert!(muts.iter().all(|b| b.fine.len() == 0));
        let mut sums = [vec![f64::NAN; copied.len()], vec![f64::NAN; copied.len()]];
        let mut sums_taken = sums.clone();
        let [a, b] = &mut sums;
        copied.accumulate(&y, &ys, a, b);
        let [a, b] = &mut sums_taken;
        taken.accumulate(&y, &ys, a, b);
        let bits = |v: &[Vec<f64>; 2]| v.concat().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&sums), bits(&sums_taken));
        assert_eq!(copied.steady(), taken.steady());
        taken.give_back(&mut muts);
        for (l, b) in lent.iter().zip(&bins) {
            assert_eq!(l.fine, b.fine);
        }
        // Too many slots for a byte: no table (the caller falls back to `min_p`), and
        // nothing taken.
        let wide = Binned::new(&columns[0], 512, 1, 10).expect("usable");
        assert!(SlotTable::new(&[&wide], 0).is_none());
        let mut pair = [bins[2].clone(), wide.clone()];
        let [p0, p1] = &mut pair;
        assert!(SlotTable::take(&mut [p0, p1], 0).is_none());
        assert_eq!(pair[0].fine, bins[2].fine);
        assert_eq!(pair[1].fine, wide.fine);
    }

    /// Reference: the plain definition of a row's fine slot, by a full sort — quantile bins:
    /// the number of cuts ≤ the value, the cuts being the sorted defined values at ranks
    /// `k·n/k_max`; discrete bins: the rank of the value among the distinct values; undefined
    /// rows in slot `n_fine`. One byte a row up to 256 slots, two bytes beyond, the same slot
    /// either way (and [`FTest::min_p`]'s per-width loops the same bits as the row-by-row
    /// sum through `fine_slot`).
    #[test]
    fn narrow_and_wide_fine_slots_equal_the_sorted_definition() {
        let n = 12_000;
        let mut rng = SimRng::new(11);
        let column: Vec<f64> = (0..n)
            .map(|i| {
                if i % 97 == 0 {
                    f64::NAN
                } else {
                    rng.range(-5.0, 5.0)
                }
            })
            .collect();
        let y: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let sst: f64 = y.iter().map(|v| v * v).sum();
        let mut defined: Vec<f64> = column.iter().copied().filter(|x| !x.is_nan()).collect();
        defined.sort_by(f64::total_cmp);
        let m = defined.len();
        for (max_bins, wide) in [(64, false), (128, false), (256, true), (4096, true)] {
            let b = Binned::new(&column, max_bins, 1, 10).expect("usable");
            assert_eq!(b.kind, BinKind::Quantile);
            assert_eq!(b.n_fine, max_bins);
            assert_eq!(b.fine.narrow().is_none(), wide, "{max_bins} bins");
            assert_eq!(b.fine.len(), n);
            let cuts: Vec<f64> = (1..max_bins)
                .map(|k| defined[(k * m / max_bins).min(m - 1)])
                .collect();
            for (i, &x) in column.iter().enumerate() {
                let want = if x.is_nan() {
                    max_bins
                } else {
                    cuts.iter().filter(|&&c| c <= x).count()
                };
                assert_eq!(b.fine_slot(i), want, "{max_bins} bins, row {i}");
            }
            let mut by_row = vec![0.0; b.n_fine + 1];
            for (i, &v) in y.iter().enumerate() {
                by_row[b.fine_slot(i)] += v;
            }
            let mut t = FTest::new(&b);
            let reference = t.min_p_of_sums(&b, &by_row, n, sst);
            let own = FTest::new(&b).min_p(&b, &y, sst);
            assert_eq!(own.to_bits(), reference.to_bits(), "{max_bins} bins");
        }
        // Discrete: 255 values and the undefined slot fill a byte; 256 values need two.
        let values: Vec<f64> = (0..n).map(|i| ((i * 37) % 255) as f64).collect();
        let mut holed = values.clone();
        holed[5] = f64::NAN;
        let h = Binned::new(&holed, 64, 1, 256).expect("usable");
        assert_eq!((h.kind, h.n_fine), (BinKind::Discrete, 255));
        assert!(h.fine.narrow().is_some());
        for (i, &v) in values.iter().enumerate() {
            let want = if i == 5 { 255 } else { v as usize };
            assert_eq!(h.fine_slot(i), want);
        }
        let values: Vec<f64> = (0..n).map(|i| ((i * 37) % 256) as f64).collect();
        let b = Binned::new(&values, 64, 1, 256).expect("usable");
        assert_eq!((b.kind, b.n_fine), (BinKind::Discrete, 256));
        assert!(b.fine.narrow().is_none());
        for (i, &v) in values.iter().enumerate() {
            assert_eq!(b.fine_slot(i), v as usize);
        }
        // `from_codes` stores the same slots as `new` of the same numbers.
        let codes: Vec<u8> = values.iter().map(|&v| v as u8).collect();
        assert_eq!(Binned::from_codes(&codes, 1).expect("usable").fine, b.fine);
    }

    /// Reference: a sort by `total_cmp` ([`sorted_distinct_reference`], and indexing the
    /// sorted copy). The scan and the nested selection must give the same bits: distinct
    /// values with ties, −0 and +0, fewer and more distinct values than the limit; order
    /// statistics at quantile ranks, repeated ranks and the ends.
    #[test]
    fn selection_gives_the_sorted_values() {
        let mut rng = SimRng::new(8);
        for n in [1usize, 2, 5, 64, 1000, 4097] {
            for levels in [1u64, 3, 12, 13, 1 << 40] {
                let x: Vec<f64> = (0..n)
                    .map(|_| {
                        let k = rng.below(levels) as i64 - (levels / 2) as i64;
                        if k == 0 && rng.below(2) == 0 {
                            -0.0
                        } else {
                            k as f64 * 0.25
                        }
                    })
                    .collect();
                for limit in [1, 2, 13] {
                    let fast = smallest_distinct(&mut x.clone(), limit);
                    let slow = sorted_distinct_reference(&mut x.clone(), limit);
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(
                        bits(&fast),
                        bits(&slow),
                        "n {n} levels {levels} limit {limit}"
                    );
                }
                let mut sorted = x.clone();
                sorted.sort_by(f64::total_cmp);
                let mut ranks: Vec<usize> = (1..64).map(|k| (k * n / 64).min(n - 1)).collect();
                ranks.push(n - 1);
                let got = order_statistics(&mut x.clone(), &ranks);
                for (r, g) in ranks.iter().zip(&got) {
                    assert_eq!(g.to_bits(), sorted[*r].to_bits(), "n {n} rank {r}");
                }
            }
        }
    }
}

//! The one-dimensional smoother: binned means on nested quantile bins, with the number of bins
//! chosen by cross-validation, missing values in a bin of their own, and the in-sample one-way
//! ANOVA F-test the permutation test is built on.
//!
//! A continuous feature is cut at quantiles into `K_max` (a power of two) fine bins; coarser
//! candidates with `K_max/2, K_max/4, …, 1` bins use every second, fourth, … cut point, so a fine
//! bin index `i` maps to `i >> s` at level `s`. The bins nest exactly, which lets one pass over
//! the rows fill a (fold × fine bin) table of sums from which every candidate's cross-validated
//! error follows without touching the rows again. A discrete feature (few distinct values) has one
//! bin per value and two candidates: all values, or one bin. Missing values always form a bin of
//! their own, also in the one-bin candidate, so "undefined" can itself be an effect.

use super::values::defined;
use crate::numeric::stats::reg_inc_beta;

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
    fn take_narrow(&mut self) -> Option<Vec<u8>> {
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
    fn coarse_of_fine_slot(&self, fs: usize, shift: u32) -> usize {
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
fn add_by_slot<T: Copy + Into<usize>>(codes: &[T], y: &[f64], sums: &mut [f64]) {
    for (&c, &v) in codes.iter().zip(y) {
        sums[c.into()] += v;
    }
}

/// Adds `y[i] × direction[i]` into `sums[codes[i]]` for every row, in row order.
#[inline]
fn add_by_slot_signed<T: Copy + Into<usize>>(
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

/// Scratch space and invariant counts for the in-sample F statistic of one feature.
#[derive(Debug, Clone)]
pub(crate) struct FTest {
    level_cnt: Vec<Vec<f64>>,
    fine_sum: Vec<f64>,
    level_sum: Vec<f64>,
}

impl FTest {
    /// Prepares the counts of `b`.
    pub(super) fn new(b: &Binned) -> FTest {
        let fine_cnt = fine_counts(b);
        let level_cnt = b
            .levels
            .iter()
            .map(|&s| {
                let mut c = vec![0.0; b.slots(s)];
                for (fs, &n) in fine_cnt.iter().enumerate() {
                    c[b.coarse_of_fine_slot(fs, s)] += n;
                }
                c
            })
            .collect();
        FTest {
            fine_sum: vec![0.0; fine_cnt.len()],
            level_cnt,
            level_sum: Vec::new(),
        }
    }

    /// The natural log of the smallest one-way-ANOVA F-test p-value over the candidate levels
    /// of `b` for centred residuals `y` with total sum of squares `sst` (the adaptive statistic
    /// the permutation test calibrates). In log space, so that strong effects on long,
    /// serially correlated logs do not all tie at p = 0 (see [`f_test_ln_p`]). 0 when no level
    /// has two non-empty bins.
    pub(super) fn min_p(&mut self, b: &Binned, y: &[f64], sst: f64) -> f64 {
        // One loop per width (no test of the width per row).
        self.min_p_with(b, y.len(), sst, |fine_sum| match &b.fine {
            FineSlots::Narrow(c) => add_by_slot(c, y, fine_sum),
            FineSlots::Wide(c) => add_by_slot(c, y, fine_sum),
        })
    }

    /// [`FTest::min_p`] of the residuals `y[i] × direction[i]` (their sum of squares about
    /// their mean `sst`), each product made as it is added: the same sums in the same order
    /// as of the stored products, so the same bits, without an 8 B/row copy.
    pub(super) fn min_p_signed(
        &mut self,
        b: &Binned,
        y: &[f64],
        direction: &[i8],
        sst: f64,
    ) -> f64 {
        self.min_p_with(b, y.len(), sst, |fine_sum| match &b.fine {
            FineSlots::Narrow(c) => add_by_slot_signed(c, y, direction, fine_sum),
            FineSlots::Wide(c) => add_by_slot_signed(c, y, direction, fine_sum),
        })
    }

    /// The statistic of `n` rows whose sums per fine slot `fill` adds into zeroed sums.
    fn min_p_with(&mut self, b: &Binned, n: usize, sst: f64, fill: impl FnOnce(&mut [f64])) -> f64 {
        let mut fine_sum = std::mem::take(&mut self.fine_sum);
        fine_sum.iter_mut().for_each(|s| *s = 0.0);
        fill(&mut fine_sum);
        let p = self.min_p_of_sums(b, &fine_sum, n, sst);
        self.fine_sum = fine_sum;
        p
    }

    /// [`FTest::min_p`] from the residuals' sums per fine slot (`fine_sum[s]`: the sum over
    /// the rows of slot `s`, in row order) of `n` rows — the part of the statistic after the
    /// pass over the rows, which [`SlotTable::accumulate`] does for many features at once.
    pub(crate) fn min_p_of_sums(
        &mut self,
        b: &Binned,
        fine_sum: &[f64],
        n: usize,
        sst: f64,
    ) -> f64 {
        let rows = n as f64;
        let total: f64 = fine_sum.iter().sum();
        let mut best = 0.0f64;
        for (li, &shift) in b.levels.iter().enumerate() {
            let cnt = &self.level_cnt[li];
            self.level_sum.clear();
            self.level_sum.resize(cnt.len(), 0.0);
            for (fs, &s) in fine_sum.iter().enumerate() {
                self.level_sum[b.coarse_of_fine_slot(fs, shift)] += s;
            }
            let mut ssb = -total * total / rows;
            let mut groups = 0usize;
            for (s, &c) in self.level_sum.iter().zip(cnt) {
                if c > 0.0 {
                    ssb += s * s / c;
                    groups += 1;
                }
            }
            best = best.min(f_test_ln_p(ssb.max(0.0), sst, groups, n));
        }
        best
    }
}

/// The fine slots of several features, one row after another as bytes, for the permutation
/// test's fused pass: one sweep over a permuted residual adds every row into every feature's
/// per-slot sums (the features' additions are independent, so they overlap in the CPU instead
/// of waiting on each other, and the residual is read once instead of once per feature). Each
/// slot's sum still adds its rows in row order from 0, so the sums — and every statistic from
/// them — are bit-identical to [`FTest::min_p`]'s own pass (tested).
#[derive(Debug, Clone)]
pub(crate) struct SlotTable {
    /// `codes[i·m + j]`: the fine slot of feature `j` at row `i`.
    codes: Vec<u8>,
    /// Features.
    m: usize,
    /// The first `signed` features also sum a second (direction-signed) residual.
    signed: usize,
    /// Start of feature `j`'s slots in the accumulators (`offset[m]`: their length).
    offset: Vec<usize>,
    /// Whether every feature stays in one slot for long runs of rows in seek order (at most
    /// one change of slot per [`STEADY_ROWS`] rows, as the time features' monotone bins do):
    /// then a row-permuted residual is summed with each feature's current slot held in a
    /// register ([`add_rows_held`]).
    steady: bool,
}

/// Rows per change of slot, at least, of a [`SlotTable`] summed with [`add_rows_held`].
const STEADY_ROWS: usize = 64;

impl SlotTable {
    /// The table of `bins` (the first `signed` of them also summed for the signed residual);
    /// `None` when a feature has more than 256 fine slots (then use [`FTest::min_p`]). The
    /// features keep their own slots (a copy): the reference of [`SlotTable::take`].
    #[cfg(test)]
    pub(crate) fn new(bins: &[&Binned], signed: usize) -> Option<SlotTable> {
        if bins.iter().any(|b| b.fine.narrow().is_none()) {
            return None;
        }
        let m = bins.len();
        let n = bins.first().map_or(0, |b| b.fine.len());
        let mut codes = vec![0u8; n * m];
        for (j, b) in bins.iter().enumerate() {
            for (i, row) in codes.chunks_exact_mut(m).enumerate() {
                row[j] = b.fine_slot(i) as u8;
            }
        }
        Some(Self::of_codes(codes, bins, signed))
    }

    /// [`SlotTable::new`] of `bins` that takes their one-byte slots instead of copying them:
    /// each feature's slots are moved into the table column by column (freed as they are
    /// copied in, so the table and the features' slots are not held twice), and the
    /// features hold no slots (0 rows) until [`SlotTable::give_back`] returns them. `None`
    /// (nothing taken) when a feature has more than 256 fine slots.
    pub(crate) fn take(bins: &mut [&mut Binned], signed: usize) -> Option<SlotTable> {
        if bins.iter().any(|b| b.fine.narrow().is_none()) {
            return None;
        }
        let m = bins.len();
        let n = bins.first().map_or(0, |b| b.fine.len());
        let mut codes = vec![0u8; n * m];
        for (j, b) in bins.iter_mut().enumerate() {
            let col = b.fine.take_narrow().unwrap_or_default();
            for (row, &c) in codes.chunks_exact_mut(m).zip(&col) {
                row[j] = c;
            }
        }
        let shared: Vec<&Binned> = bins.iter().map(|b| &**b).collect();
        Some(Self::of_codes(codes, &shared, signed))
    }

    /// Puts the slots [`SlotTable::take`] took back into `bins` (the same features in the
    /// same order), freeing the table.
    pub(crate) fn give_back(self, bins: &mut [&mut Binned]) {
        let m = self.m;
        let mut codes = self.codes;
        for (j, b) in bins.iter_mut().enumerate().take(m) {
            b.fine = FineSlots::Narrow(codes.iter().skip(j).step_by(m).copied().collect());
        }
        codes.clear();
        codes.shrink_to_fit();
    }

    /// The table of the interleaved `codes` of `bins`.
    fn of_codes(codes: Vec<u8>, bins: &[&Binned], signed: usize) -> SlotTable {
        let m = bins.len();
        let n = codes.len() / m.max(1);
        let mut offset = vec![0usize];
        for b in bins {
            offset.push(offset.last().copied().unwrap_or(0) + b.n_fine + 1);
        }
        let changes = (0..m)
            .map(|j| {
                let col = codes.iter().skip(j).step_by(m);
                col.clone().zip(col.skip(1)).filter(|(a, b)| a != b).count()
            })
            .max()
            .unwrap_or(0);
        SlotTable {
            steady: m <= HELD_MAX && changes * STEADY_ROWS <= n,
            codes,
            m,
            signed: signed.min(m),
            offset,
        }
    }

    /// Whether a row-permuted residual is summed by [`add_rows_held`].
    #[cfg(test)]
    pub(crate) fn steady(&self) -> bool {
        self.steady
    }

    /// Length of the accumulators [`SlotTable::accumulate`] fills.
    pub(crate) fn len(&self) -> usize {
        self.offset[self.m]
    }

    /// Feature `j`'s sums in an accumulator filled by [`SlotTable::accumulate`].
    pub(crate) fn sums<'a>(&self, acc: &'a [f64], j: usize) -> &'a [f64] {
        &acc[self.offset[j]..self.offset[j + 1]]
    }

    /// Sets `acc` to every feature's per-slot sums of `y`, and `acc_signed` to the first
    /// `signed` features' sums of `y_signed` (ignored, and may be empty, when there are none):
    /// the fused pass over a materialised residual, the reference of
    /// [`SlotTable::accumulate_permuted`].
    #[cfg(test)]
    pub(crate) fn accumulate(
        &self,
        y: &[f64],
        y_signed: &[f64],
        acc: &mut [f64],
        acc_signed: &mut [f64],
    ) {
        acc.iter_mut().for_each(|a| *a = 0.0);
        let m = self.m;
        if m == 0 {
            return;
        }
        let offset = &self.offset[..m];
        if self.signed == 0 {
            for (row, &v) in self.codes.chunks_exact(m).zip(y) {
                for (&c, &o) in row.iter().zip(offset) {
                    acc[o + c as usize] += v;
                }
            }
        } else {
            acc_signed.iter_mut().for_each(|a| *a = 0.0);
            let ms = self.signed;
            for ((row, &v), &w) in self.codes.chunks_exact(m).zip(y).zip(y_signed) {
                for (&c, &o) in row.iter().zip(offset) {
                    acc[o + c as usize] += v;
                }
                for (&c, &o) in row[..ms].iter().zip(offset) {
                    acc_signed[o + c as usize] += w;
                }
            }
        }
    }
}

/// A permutation of a residual read in place: consecutive runs of rows of a source, so the
/// permutation test's fused pass needs no permuted copy of the residual (and no signed copy:
/// [`SlotTable::accumulate_permuted`] multiplies by the direction as it reads).
pub(crate) enum Permuted<'a> {
    /// The permuted residual itself (a row permutation, shuffled into a buffer).
    Rows(&'a [f64]),
    /// `y` rotated by `offset`, cut into consecutive blocks of `block` rows, the blocks in
    /// `order`: block `b` is rows `(i + offset) mod n` for `i` in `b·block..(b+1)·block`, at
    /// most two runs of `y`.
    Blocks {
        /// The residual.
        y: &'a [f64],
        /// Rows per block (the last block may be shorter).
        block: usize,
        /// Rotation.
        offset: usize,
        /// Block order.
        order: &'a [usize],
    },
}

/// How many blocks ahead [`Permuted::for_each_run`] prefetches a block's rows.
const PREFETCH_BLOCKS: usize = 16;

/// A hint to bring the cache line of `x[0]` into the cache (nothing elsewhere).
#[inline(always)]
pub(crate) fn prefetch<T>(x: &[T]) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch has no effect beyond the cache; SSE is part of x86_64.
    #[allow(unused_unsafe)]
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            x.as_ptr().cast::<i8>(),
        );
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// `i mod n` for `i < 2n` (a block start `b·block < n` plus an offset `< n`): one compare
/// instead of a 64-bit division per block.
#[inline(always)]
fn wrap(i: usize, n: usize) -> usize {
    if i >= n { i - n } else { i }
}

impl Permuted<'_> {
    /// Calls `f(k, run)` for consecutive runs of the permuted residual: `run` is its rows
    /// `k..k + run.len()`, in order from row 0.
    #[inline]
    pub(crate) fn for_each_run(&self, mut f: impl FnMut(usize, &[f64])) {
        match *self {
            Permuted::Rows(v) => f(0, v),
            Permuted::Blocks {
                y,
                block,
                offset,
                order,
            } => {
                let n = y.len();
                let mut k = 0;
                for (idx, &b) in order.iter().enumerate() {
                    // The blocks are scattered over a residual larger than the cache: ask
                    // for a block's rows PREFETCH_BLOCKS blocks before they are read.
                    if let Some(&ahead) = order.get(idx + PREFETCH_BLOCKS) {
                        let start = wrap(ahead * block + offset, n);
                        prefetch(&y[start..]);
                        prefetch(&y[(start + block - 1).min(n - 1)..]);
                    }
                    let len = ((b + 1) * block).min(n) - b * block;
                    let start = wrap(b * block + offset, n);
                    let first = len.min(n - start);
                    f(k, &y[start..start + first]);
                    if len > first {
                        f(k + first, &y[..len - first]);
                    }
                    k += len;
                }
            }
        }
    }
}

/// Σ(w − w̄)² of `n` values from their sum and their sum of squares: Σw² − (Σw)²/n (never
/// below 0). The permutation test's signed sum of squares, from the sums the fused pass
/// takes as it reads the permuted residual ([`SlotTable::accumulate_permuted`],
/// [`SlotTable::accumulate_lanes`]) instead of a second pass for the deviations from the
/// mean: the same value as `stats::sum_sq_about_mean` up to rounding — within 1e-12
/// relative wherever the mean is small against the spread, as it is for a permuted
/// residual (the residual is centred, so the signed mean is a sum of ± terms; tested) — not
/// the same bits.
#[inline]
pub(crate) fn sst_of_sums(sum: f64, sq: f64, n: usize) -> f64 {
    (sq - sum * sum / n as f64).max(0.0)
}

/// [`sst_of_sums`] of `w`, its sums taken in row order as the fused pass takes them (Σw
/// from −0, Σw² from 0): the statistic of a materialised signed residual.
pub(crate) fn sst_one_pass(w: &[f64]) -> f64 {
    let (sum, sq) = w.iter().fold((-0.0, 0.0), |(s, q), &x| (s + x, q + x * x));
    sst_of_sums(sum, sq, w.len())
}

impl SlotTable {
    /// [`SlotTable::accumulate`] of a permuted residual read in place, the signed residual
    /// being the permuted one times `direction` (unused, and may be empty, when no feature is
    /// signed). Returns Σ of the signed residual in row order (−0 when none is signed) and
    /// Σ of its squares (0 when none is signed; for [`sst_of_sums`]). The same additions in
    /// the same order as [`SlotTable::accumulate`] of the materialised permutation and its
    /// product (tested).
    pub(crate) fn accumulate_permuted(
        &self,
        y: &Permuted<'_>,
        direction: &[i8],
        acc: &mut [f64],
        acc_signed: &mut [f64],
    ) -> (f64, f64) {
        acc.iter_mut().for_each(|a| *a = 0.0);
        let m = self.m;
        let mut signed = (-0.0, 0.0);
        if m == 0 {
            return signed;
        }
        let offset = &self.offset[..m];
        let ms = self.signed;
        if ms > 0 {
            acc_signed.iter_mut().for_each(|a| *a = 0.0);
        }
        let codes = &self.codes[..];
        y.for_each_run(|k, run| {
            let rows = &codes[k * m..(k + run.len()) * m];
            if ms == 0 && self.steady {
                add_rows_held(rows, m, offset, run, acc);
            } else if ms == 0 {
                add_rows(rows, m, offset, run, acc);
            } else if self.steady {
                signed = add_rows_signed_held(
                    rows,
                    m,
                    ms,
                    offset,
                    run,
                    &direction[k..k + run.len()],
                    acc,
                    acc_signed,
                    signed,
                );
            } else {
                signed = add_rows_signed(
                    rows,
                    m,
                    ms,
                    offset,
                    run,
                    &direction[k..k + run.len()],
                    acc,
                    acc_signed,
                    signed,
                );
            }
        });
        signed
    }

    /// Features whose sums of the signed residual are taken.
    pub(crate) fn signed(&self) -> usize {
        self.signed
    }
}

/// Permutations summed side by side, one per lane of a vector, by
/// [`SlotTable::accumulate_lanes`] (eight `f64`: one 512-bit register with AVX-512, two
/// 256-bit ones with AVX2).
pub(crate) const LANES: usize = 8;

/// Rows per chunk of [`SlotTable::accumulate_lanes`]: the lanes' permuted rows are gathered
/// into a chunk of `CHUNK × LANES` values (32 KiB, in L1/L2) before they are summed.
const CHUNK: usize = 512;

/// One lane's block permutation, read in place: the residual rotated by `offset`, cut into
/// blocks of `block` rows taken in `order` (as [`Permuted::Blocks`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct BlockLane<'a> {
    /// Rotation.
    pub(crate) offset: usize,
    /// Block order.
    pub(crate) order: &'a [usize],
}

/// Where one lane's gathering stands: the block (index into its order) and the row in it.
#[derive(Debug, Clone, Copy, Default)]
struct Cursor {
    idx: usize,
    pos: usize,
}

/// Copies the next `out.len()` rows of lane `lane`'s block permutation of `y` (blocks of
/// `block` rows) into `out[t][slot]`, advancing `cur`; prefetches the rows of the block
/// [`PREFETCH_BLOCKS`] blocks ahead, as [`Permuted::for_each_run`] does.
#[inline(always)]
fn gather_lane(
    y: &[f64],
    block: usize,
    lane: &BlockLane<'_>,
    slot: usize,
    cur: &mut Cursor,
    out: &mut [[f64; LANES]],
) {
    let n = y.len();
    let mut t = 0;
    while t < out.len() {
        let b = lane.order[cur.idx];
        let len = ((b + 1) * block).min(n) - b * block;
        let take = (len - cur.pos).min(out.len() - t);
        // The block's rows from `cur.pos` on: at most two runs of `y` (it may wrap).
        let start = wrap(b * block + lane.offset + cur.pos, n);
        let first = take.min(n - start);
        for (o, &v) in out[t..t + first].iter_mut().zip(&y[start..start + first]) {
            o[slot] = v;
        }
        for (o, &v) in out[t + first..t + take].iter_mut().zip(&y[..take - first]) {
            o[slot] = v;
        }
        t += take;
        cur.pos += take;
        if cur.pos == len {
            cur.pos = 0;
            cur.idx += 1;
            if let Some(&ahead) = lane.order.get(cur.idx + PREFETCH_BLOCKS) {
                let s = wrap(ahead * block + lane.offset, n);
                prefetch(&y[s..]);
                prefetch(&y[(s + block - 1).min(n - 1)..]);
            }
        }
    }
}

/// The [`LANES`] block permutations of `y`, gathered chunk by chunk in row order from row 0
/// (`next` fills `buf[t][l]` with row `k + t` of lane `l`'s permutation).
struct Chunks<'a, 'b> {
    y: &'a [f64],
    block: usize,
    lanes: &'a [BlockLane<'b>; LANES],
    cur: [Cursor; LANES],
    k: usize,
}

impl<'a, 'b> Chunks<'a, 'b> {
    /// Starts at row 0 (asking for the first blocks' rows).
    #[inline(always)]
    fn new(y: &'a [f64], block: usize, lanes: &'a [BlockLane<'b>; LANES]) -> Self {
        let n = y.len();
        for lane in lanes {
            for &b in lane.order.iter().take(PREFETCH_BLOCKS) {
                prefetch(&y[wrap(b * block + lane.offset, n)..]);
            }
        }
        Chunks {
            y,
            block,
            lanes,
            cur: [Cursor::default(); LANES],
            k: 0,
        }
    }

    /// Gathers the next chunk into `buf` (at most `buf.len()` rows): its first row and its
    /// length, `None` after the last row.
    #[inline(always)]
    fn next(&mut self, buf: &mut [[f64; LANES]]) -> Option<(usize, usize)> {
        let k = self.k;
        let c = buf.len().min(self.y.len() - k);
        if c == 0 {
            return None;
        }
        for (l, lane) in self.lanes.iter().enumerate() {
            gather_lane(self.y, self.block, lane, l, &mut self.cur[l], &mut buf[..c]);
        }
        self.k += c;
        Some((k, c))
    }
}

/// `v[l]·d` for every lane (one vector multiplication).
#[inline(always)]
fn scale_lanes(v: &[f64; LANES], d: f64) -> [f64; LANES] {
    let mut w = [0.0; LANES];
    for l in 0..LANES {
        w[l] = v[l] * d;
    }
    w
}

/// `a[l]·b[l]` for every lane (one vector multiplication).
#[inline(always)]
fn mul_lanes(a: &[f64; LANES], b: &[f64; LANES]) -> [f64; LANES] {
    let mut w = [0.0; LANES];
    for l in 0..LANES {
        w[l] = a[l] * b[l];
    }
    w
}

/// `a[l] += v[l]` for every lane (one vector addition; each lane its own IEEE sum).
#[inline(always)]
fn add_lanes(a: &mut [f64; LANES], v: &[f64; LANES]) {
    for l in 0..LANES {
        a[l] += v[l];
    }
}

impl SlotTable {
    /// [`SlotTable::accumulate_permuted`] of [`LANES`] block permutations (blocks of `block`
    /// rows > 1) at once: `acc[s][l]` is lane `l`'s sum of slot `s`, `acc_signed` the same
    /// for the signed residual (permuted × `direction`; unused, and may be empty, when no
    /// feature is signed). Returns each lane's Σ of the signed residual in row order (−0 when
    /// none is signed) and Σ of its squares (0 when none is signed). Each lane's sums take the same additions in the same order as
    /// [`SlotTable::accumulate_permuted`] of that lane's permutation, so they are the same
    /// bits (tested); the lanes of one row are added by one vector instruction. Runs the
    /// AVX2 copy when the CPU has it (lane-wise additions and products, no fused
    /// multiply-add: the same results).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn accumulate_lanes(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F (checked just above).
            return unsafe {
                self.accumulate_lanes_avx512(y, block, lanes, direction, buf, acc, acc_signed)
            };
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe {
                self.accumulate_lanes_avx2(y, block, lanes, direction, buf, acc, acc_signed)
            };
        }
        self.accumulate_lanes_portable(y, block, lanes, direction, buf, acc, acc_signed)
    }

    /// [`SlotTable::accumulate_lanes`] compiled for AVX-512F (the lanes' sums in one
    /// register; each lane's additions the same, in the same order, as any other build's).
    ///
    /// # Safety
    /// The CPU must support AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn accumulate_lanes_avx512(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        self.accumulate_lanes_portable(y, block, lanes, direction, buf, acc, acc_signed)
    }

    /// [`SlotTable::accumulate_lanes`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn accumulate_lanes_avx2(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        self.accumulate_lanes_portable(y, block, lanes, direction, buf, acc, acc_signed)
    }

    /// [`SlotTable::accumulate_lanes`] for any CPU.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn accumulate_lanes_portable(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        let m = self.m;
        let mut sum = [-0.0; LANES];
        let mut sq = [0.0; LANES];
        acc.clear();
        acc.resize(self.len(), [0.0; LANES]);
        if m == 0 {
            return (sum, sq);
        }
        let ms = self.signed;
        if ms > 0 {
            acc_signed.clear();
            acc_signed.resize(self.len(), [0.0; LANES]);
        }
        let offset = &self.offset[..m];
        let codes = &self.codes[..];
        let (acc, acc_signed) = (&mut acc[..], &mut acc_signed[..]);
        buf.resize(CHUNK, [0.0; LANES]);
        let mut chunks = Chunks::new(y, block, lanes);
        while let Some((k, c)) = chunks.next(buf) {
            let chunk = &buf[..c];
            let rows = &codes[k * m..(k + c) * m];
            if ms == 0 {
                for (row, v) in rows.chunks_exact(m).zip(chunk) {
                    // A local copy: one register, not reloaded after every store to `acc`.
                    let v = *v;
                    for (&c, &o) in row.iter().zip(offset) {
                        add_lanes(&mut acc[o + c as usize], &v);
                    }
                }
            } else {
                let d = &direction[k..k + chunk.len()];
                for ((row, v), &dt) in rows.chunks_exact(m).zip(chunk).zip(d) {
                    let v = *v;
                    let w = scale_lanes(&v, f64::from(dt));
                    add_lanes(&mut sum, &w);
                    add_lanes(&mut sq, &mul_lanes(&w, &w));
                    for (&c, &o) in row.iter().zip(offset) {
                        add_lanes(&mut acc[o + c as usize], &v);
                    }
                    for (&c, &o) in row[..ms].iter().zip(offset) {
                        add_lanes(&mut acc_signed[o + c as usize], &w);
                    }
                }
            }
        }
        (sum, sq)
    }
}

/// Most features [`add_rows_held`] takes.
const HELD_MAX: usize = 4;

/// [`add_rows`] (m ≤ [`HELD_MAX`]) with each feature's current slot held in a register: it is
/// written back, and the next slot read, only when the feature's slot changes. Every slot
/// still receives its rows in row order from the value it had, so the sums are the same bits
/// (tested); what goes is the chain through memory (each add waiting for the previous add's
/// store to the same slot) when a feature keeps its slot for many rows.
fn add_rows_held(codes: &[u8], m: usize, offset: &[usize], run: &[f64], acc: &mut [f64]) {
    match m {
        1 => add_rows_held_m::<1>(codes, offset, run, acc),
        2 => add_rows_held_m::<2>(codes, offset, run, acc),
        3 => add_rows_held_m::<3>(codes, offset, run, acc),
        4 => add_rows_held_m::<4>(codes, offset, run, acc),
        _ => add_rows(codes, m, offset, run, acc),
    }
}

/// [`add_rows_held`] for `M` features.
#[inline]
fn add_rows_held_m<const M: usize>(codes: &[u8], offset: &[usize], run: &[f64], acc: &mut [f64]) {
    if run.is_empty() {
        return;
    }
    let off: [usize; M] = std::array::from_fn(|j| offset[j]);
    let mut slot: [usize; M] = std::array::from_fn(|j| off[j] + codes[j] as usize);
    let mut held: [f64; M] = std::array::from_fn(|j| acc[slot[j]]);
    for (row, &v) in codes.chunks_exact(M).zip(run) {
        for j in 0..M {
            let s = off[j] + row[j] as usize;
            if s != slot[j] {
                acc[slot[j]] = held[j];
                slot[j] = s;
                held[j] = acc[s];
            }
            held[j] += v;
        }
    }
    for j in 0..M {
        acc[slot[j]] = held[j];
    }
}

/// Adds `run[t]` into `acc[offset[j] + codes[t·m + j]]` for every row t and feature j < m.
#[inline]
fn add_rows(codes: &[u8], m: usize, offset: &[usize], run: &[f64], acc: &mut [f64]) {
    for (t, &v) in run.iter().enumerate() {
        let row = &codes[t * m..(t + 1) * m];
        for (&c, &o) in row.iter().zip(offset) {
            acc[o + c as usize] += v;
        }
    }
}

/// [`add_rows`], and `run[t]·d[t]` into `acc_signed` for the first `ms` features; returns
/// `(sum, sq)` plus every `run[t]·d[t]` and its square in row order (local chains, kept in
/// registers).
#[allow(clippy::too_many_arguments)]
#[inline]
fn add_rows_signed(
    codes: &[u8],
    m: usize,
    ms: usize,
    offset: &[usize],
    run: &[f64],
    d: &[i8],
    acc: &mut [f64],
    acc_signed: &mut [f64],
    (mut sum, mut sq): (f64, f64),
) -> (f64, f64) {
    for (t, (&v, &dt)) in run.iter().zip(d).enumerate() {
        let w = v * f64::from(dt);
        sum += w;
        sq += w * w;
        let row = &codes[t * m..(t + 1) * m];
        for (&c, &o) in row.iter().zip(offset) {
            acc[o + c as usize] += v;
        }
        for (&c, &o) in row[..ms].iter().zip(offset) {
            acc_signed[o + c as usize] += w;
        }
    }
    (sum, sq)
}

/// [`add_rows_signed`] (m ≤ [`HELD_MAX`]) with each feature's current slots (plain and
/// signed) held in registers, as [`add_rows_held`]: the same adds per slot in row order.
#[allow(clippy::too_many_arguments)]
fn add_rows_signed_held(
    codes: &[u8],
    m: usize,
    ms: usize,
    offset: &[usize],
    run: &[f64],
    d: &[i8],
    acc: &mut [f64],
    acc_signed: &mut [f64],
    sum: (f64, f64),
) -> (f64, f64) {
    let f = match m {
        1 => add_rows_signed_held_m::<1>,
        2 => add_rows_signed_held_m::<2>,
        3 => add_rows_signed_held_m::<3>,
        4 => add_rows_signed_held_m::<4>,
        _ => return add_rows_signed(codes, m, ms, offset, run, d, acc, acc_signed, sum),
    };
    f(codes, ms, offset, run, d, acc, acc_signed, sum)
}

/// [`add_rows_signed_held`] for `M` features.
#[allow(clippy::too_many_arguments)]
#[inline]
fn add_rows_signed_held_m<const M: usize>(
    codes: &[u8],
    ms: usize,
    offset: &[usize],
    run: &[f64],
    d: &[i8],
    acc: &mut [f64],
    acc_signed: &mut [f64],
    (mut sum, mut sq): (f64, f64),
) -> (f64, f64) {
    if run.is_empty() {
        return (sum, sq);
    }
    let off: [usize; M] = std::array::from_fn(|j| offset[j]);
    let mut slot: [usize; M] = std::array::from_fn(|j| off[j] + codes[j] as usize);
    let mut held: [f64; M] = std::array::from_fn(|j| acc[slot[j]]);
    let mut held_s: [f64; M] =
        std::array::from_fn(|j| if j < ms { acc_signed[slot[j]] } else { 0.0 });
    for ((row, &v), &dt) in codes.chunks_exact(M).zip(run).zip(d) {
        let w = v * f64::from(dt);
        sum += w;
        sq += w * w;
        for j in 0..M {
            let s = off[j] + row[j] as usize;
            if s != slot[j] {
                acc[slot[j]] = held[j];
                held[j] = acc[s];
                if j < ms {
                    acc_signed[slot[j]] = held_s[j];
                    held_s[j] = acc_signed[s];
                }
                slot[j] = s;
            }
            held[j] += v;
            if j < ms {
                held_s[j] += w;
            }
        }
    }
    for j in 0..M {
        acc[slot[j]] = held[j];
        if j < ms {
            acc_signed[slot[j]] = held_s[j];
        }
    }
    (sum, sq)
}

/// p-value of a one-way ANOVA with between-group sum of squares `ssb`, total `sst`, `groups`
/// non-empty groups and `n` rows; 1 when the test is undefined.
pub(crate) fn f_test_p(ssb: f64, sst: f64, groups: usize, n: usize) -> f64 {
    if groups < 2 || n <= groups || sst <= 0.0 {
        return 1.0;
    }
    let df1 = (groups - 1) as f64;
    let df2 = (n - groups) as f64;
    let ssw = (sst - ssb).max(0.0);
    if ssw <= sst * 1e-14 {
        return 0.0;
    }
    let f = (ssb / df1) / (ssw / df2);
    reg_inc_beta(df2 / 2.0, df1 / 2.0, df2 / (df2 + df1 * f)).clamp(0.0, 1.0)
}

/// Natural log of [`f_test_p`], continued below p = 1e-250 (where the p-value underflows) by
/// the large-F tail of the χ² approximation, df1·F ~ χ²(df1): ln Q(k/2, x/2) ≈
/// (k/2 − 1)·ln(x/2) − x/2 − ln Γ(k/2). Monotone in F for fixed degrees of freedom, so
/// strong effects stay comparable instead of tying at p = 0.
pub(crate) fn f_test_ln_p(ssb: f64, sst: f64, groups: usize, n: usize) -> f64 {
    let p = f_test_p(ssb, sst, groups, n);
    if p > 1e-250 {
        return p.ln();
    }
    let df1 = (groups.max(2) - 1) as f64;
    let df2 = (n.saturating_sub(groups)).max(1) as f64;
    let ssw = (sst - ssb).max(sst * 1e-14).max(f64::MIN_POSITIVE);
    let f = (ssb / df1) / (ssw / df2);
    let x = df1 * f;
    let k = df1;
    let ln = (k / 2.0 - 1.0) * (x / 2.0).ln() - x / 2.0 - crate::numeric::stats::ln_gamma(k / 2.0);
    ln.min(1e-250f64.ln())
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

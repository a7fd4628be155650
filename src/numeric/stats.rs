//! Plain statistics shared by scoring and diagnosis: moments, percentiles, histograms,
//! bimodality (Sarle's coefficient and Hartigans' dip test), a trend test, whiteness, and the
//! distribution functions their p-values need.
//!
//! Every function accepts any slice and returns `None` (or a documented neutral value) where the
//! statistic is undefined (too few values, zero spread); none of them panics or returns NaN for
//! finite input.

use serde::{Deserialize, Serialize};

mod acf;
mod dip_table;
#[cfg(test)]
mod dip_tests;

pub(crate) use acf::{autocorrelations, first_lag_below};

/// Arithmetic mean; `None` for an empty slice.
pub fn mean(x: &[f64]) -> Option<f64> {
    (!x.is_empty()).then(|| x.iter().sum::<f64>() / x.len() as f64)
}

/// Sum of squared deviations from the mean, Σ(x − x̄)²; 0 for an empty slice.
pub(crate) fn sum_sq_about_mean(x: &[f64]) -> f64 {
    sum_sq_about(x, mean(x).unwrap_or(0.0))
}

/// The start of every `Iterator::sum` of f64 (−0.0): a running sum begun here and added in
/// the same order ends on the bits `sum()` gives.
#[inline]
pub(crate) fn sum_start() -> f64 {
    std::iter::empty::<f64>().sum::<f64>()
}

/// Σ(x − m)² about a given centre `m`, added in order (a caller that has the mean already).
pub(crate) fn sum_sq_about(x: &[f64], m: f64) -> f64 {
    x.iter().map(|v| (v - m) * (v - m)).sum()
}

/// Sample standard deviation (divisor n − 1); `None` for fewer than two values.
pub fn std_dev(x: &[f64]) -> Option<f64> {
    if x.len() < 2 {
        return None;
    }
    let m = mean(x)?;
    Some((sum_sq_about(x, m) / (x.len() - 1) as f64).sqrt())
}

/// Root mean square; `None` for an empty slice.
pub(crate) fn rms(x: &[f64]) -> Option<f64> {
    (!x.is_empty()).then(|| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt())
}

/// Percentile `p` (0–100) of already **sorted** values, linear interpolation between closest
/// ranks (NumPy's default, "linear"); `None` for an empty slice.
pub(crate) fn percentile_sorted(sorted: &[f64], p: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let pos = (p.clamp(0.0, 100.0) / 100.0) * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let frac = pos - lo as f64;
    Some(sorted[lo] + (sorted[hi] - sorted[lo]) * frac)
}

/// [`percentile_sorted`]`(&sorted(v), p)` without sorting: the two order
/// statistics around the percentile's position found by selection (O(n)); `v` is reordered.
/// Under `total_cmp` equal elements are identical bits, so the result is the same bit for bit.
pub(crate) fn percentile_select(v: &mut [f64], p: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let pos = (p.clamp(0.0, 100.0) / 100.0) * (v.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let frac = pos - lo as f64;
    let (_, &mut a, right) = v.select_nth_unstable_by(lo, f64::total_cmp);
    let b = if hi == lo {
        a
    } else {
        // The next order statistic: the smallest of the elements after `lo`.
        right.iter().copied().min_by(f64::total_cmp).unwrap_or(a)
    };
    Some(a + (b - a) * frac)
}

/// The order statistics of `v` at `ranks` (0-based, non-decreasing, each `< v.len()`), into
/// `out` (one per rank): `out[j]` is `sorted(v)[ranks[j]]` bit for bit (under `total_cmp`
/// equal elements are identical bits). Nested selection: the middle rank over all of `v`,
/// then the lower ranks in the part before it and the higher ones in the part after, so k
/// ranks cost about n·log₂(k + 1) steps instead of the k·n of selecting each over the whole
/// slice. `v` is reordered.
pub(crate) fn order_statistics(v: &mut [f64], ranks: &[usize], out: &mut [f64]) {
    debug_assert_eq!(ranks.len(), out.len());
    nested_select(v, 0, ranks, out);
}

/// [`order_statistics`] of the sub-slice `v` that holds the ranks from `base` on.
fn nested_select(v: &mut [f64], base: usize, ranks: &[usize], out: &mut [f64]) {
    if ranks.is_empty() || v.is_empty() {
        return;
    }
    let mid = ranks.len() / 2;
    let r = ranks[mid];
    let (left, &mut q, right) = v.select_nth_unstable_by(r - base, f64::total_cmp);
    // Ranks equal to `r` (repeats) take its value; those below live in `left`, those above in
    // `right`, which starts at rank r + 1.
    let below = ranks[..mid].partition_point(|&x| x < r);
    let above = mid + 1 + ranks[mid + 1..].partition_point(|&x| x == r);
    out[below..above].fill(q);
    let (out_left, rest) = out.split_at_mut(below);
    let out_right = &mut rest[above - below..];
    // The two sides are disjoint: on two threads where both are long (the same values either
    // way: an order statistic is one value of the slice, whatever the order of the work).
    let both = below > 0 && above < ranks.len() && left.len().min(right.len()) >= PARALLEL_SELECT;
    let mut lower = move || nested_select(left, base, &ranks[..below], out_left);
    let mut upper = move || nested_select(right, r + 1, &ranks[above..], out_right);
    if both {
        rayon::join(lower, upper);
    } else {
        lower();
        upper();
    }
}

/// Values on each side below which [`order_statistics`] selects both sides on one thread.
const PARALLEL_SELECT: usize = 1 << 16;

/// [`percentile_select`] of each of `ps` (0–100, any order) over the same values, each the
/// same bits as `percentile_select` (the same order statistics and interpolation; tested),
/// from one [`order_statistics`] call. `None` for an empty slice. `v` is reordered.
pub(crate) fn percentiles_select(v: &mut [f64], ps: &[f64]) -> Option<Vec<f64>> {
    if v.is_empty() {
        return None;
    }
    let n = v.len();
    let at: Vec<(usize, usize, f64)> = ps
        .iter()
        .map(|p| {
            let pos = (p.clamp(0.0, 100.0) / 100.0) * (n - 1) as f64;
            let lo = pos.floor() as usize;
            (lo, pos.ceil() as usize, pos - lo as f64)
        })
        .collect();
    let mut ranks: Vec<usize> = at.iter().flat_map(|&(lo, hi, _)| [lo, hi]).collect();
    ranks.sort_unstable();
    ranks.dedup();
    let mut os = vec![0.0; ranks.len()];
    order_statistics(v, &ranks, &mut os);
    let stat = |r: usize| os[ranks.partition_point(|&x| x < r)];
    Some(
        at.iter()
            .map(|&(lo, hi, frac)| {
                let (a, b) = (stat(lo), stat(hi));
                a + (b - a) * frac
            })
            .collect(),
    )
}

/// The key of `x` in `f64::total_cmp` order as an unsigned integer (negative values have all
/// bits flipped, the rest their sign bit set): `key(a) < key(b)` exactly when `a` sorts before
/// `b`, and `from_key` inverts it bit for bit.
fn key(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 { !b } else { b | 1 << 63 }
}

/// The value of a [`key`].
fn from_key(k: u64) -> f64 {
    f64::from_bits(if k >> 63 == 1 { k & !(1 << 63) } else { !k })
}

/// Bits of the key fixed per pass of a [`StreamPercentile`] (a histogram of 2^16 counts).
const DIGIT: u32 = 16;
/// A bucket of at most this many values is collected and selected in memory (1 MiB).
const COLLECT_CAP: u64 = 1 << 17;
/// A stream (first pass) or bucket with at most this many distinct values is counted exactly
/// per value (a hash table of 2 × this many slots, 128 KiB).
const DISTINCT_CAP: usize = 4096;

/// Exact counts of up to `cap` distinct keys (open addressing, linear probing); `full` once a
/// key beyond them was seen.
#[derive(Debug, Clone)]
struct Distinct {
    keys: Vec<u64>,
    /// 0 marks an empty slot.
    counts: Vec<u64>,
    len: usize,
    cap: usize,
    full: bool,
}

impl Distinct {
    fn new(cap: usize) -> Self {
        let slots = (2 * cap).next_power_of_two().max(2);
        Self {
            keys: vec![0; slots],
            counts: vec![0; slots],
            len: 0,
            cap,
            full: false,
        }
    }

    #[inline]
    fn add(&mut self, k: u64) {
        self.add_counted(k, 1);
    }

    /// `count` (≥ 1) more of key `k`.
    #[inline]
    fn add_counted(&mut self, k: u64, count: u64) {
        if self.full {
            return;
        }
        let mask = self.keys.len() - 1;
        let mut i = (k.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as usize & mask;
        loop {
            if self.counts[i] == 0 {
                if self.len == self.cap {
                    self.full = true;
                    return;
                }
                (self.keys[i], self.counts[i]) = (k, count);
                self.len += 1;
                return;
            }
            if self.keys[i] == k {
                self.counts[i] += count;
                return;
            }
            i = (i + 1) & mask;
        }
    }

    /// The keys seen with their counts, ascending.
    fn sorted(&self) -> Vec<(u64, u64)> {
        let mut d: Vec<(u64, u64)> = (self.keys.iter().zip(&self.counts))
            .filter(|(_, c)| **c > 0)
            .map(|(k, c)| (*k, *c))
            .collect();
        d.sort_unstable_by_key(|e| e.0);
        d
    }

    fn clear(&mut self) {
        self.counts.iter_mut().for_each(|c| *c = 0);
        self.len = 0;
        self.full = false;
    }
}

/// What the next pass of a [`StreamPercentile`] does with the values in its bucket.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    /// Count the next 16-bit digit of their keys (and their distinct values).
    Histogram,
    /// Keep them (at most [`COLLECT_CAP`]) and select in memory.
    Collect,
}

/// [`percentile_select`] of a stream of values that can be replayed, in memory independent of
/// its length: radix selection over the values' [`key`]s (their bit patterns in `total_cmp`
/// order), 16 bits per pass. The first pass counts the values, histograms the top 16 bits and
/// counts the distinct values (up to [`DISTINCT_CAP`]: then it is exact at once). Each later
/// pass looks only at the values whose key starts with the bucket holding the wanted rank: it
/// keeps them when they are few ([`COLLECT_CAP`]), else histograms their next 16 bits and counts
/// their distinct values; and it tracks the smallest key above the bucket (the next order
/// statistic may lie there). At most five passes (the first and four digits); one or two on
/// the logs tried. The result equals `percentile_select` of the whole stream bit for bit (the
/// same two order statistics under `total_cmp`, the same interpolation).
///
/// Use: [`StreamPercentile::push`] every value of one pass, [`StreamPercentile::end_pass`];
/// repeat the same stream until [`StreamPercentile::result`] is `Some`.
#[derive(Debug, Clone)]
pub(crate) struct StreamPercentile {
    p: f64,
    /// Values seen in the first pass.
    n: u64,
    /// Passes ended.
    passes: u32,
    /// Key bits fixed so far (a multiple of 16) and their value.
    fixed: u32,
    prefix: u64,
    /// Rank of the lower order statistic among the values in the bucket.
    rank: u64,
    /// The interpolation weight of the upper order statistic (rank + 1); 0 with one rank.
    frac: f64,
    two: bool,
    mode: Mode,
    hist: Vec<u64>,
    kept: Vec<f64>,
    distinct: Distinct,
    /// The smallest key above the bucket this pass.
    above: Option<u64>,
    result: Option<Option<f64>>,
    /// [`COLLECT_CAP`] (smaller in tests, to reach every path).
    collect_cap: u64,
}

impl StreamPercentile {
    /// Percentile `p` (0–100, clamped) of the stream, linear interpolation between closest
    /// ranks as [`percentile_sorted`]; `None` for an empty stream.
    pub(crate) fn new(p: f64) -> Self {
        Self::with_caps(p, COLLECT_CAP, DISTINCT_CAP)
    }

    /// [`StreamPercentile::new`] with other caps than [`COLLECT_CAP`] and [`DISTINCT_CAP`].
    pub(crate) fn with_caps(p: f64, collect_cap: u64, distinct_cap: usize) -> Self {
        Self {
            p,
            n: 0,
            passes: 0,
            fixed: 0,
            prefix: 0,
            rank: 0,
            frac: 0.0,
            two: false,
            mode: Mode::Histogram,
            hist: vec![0; 1 << DIGIT],
            kept: Vec::new(),
            distinct: Distinct::new(distinct_cap),
            above: None,
            result: None,
            collect_cap,
        }
    }

    /// Passes ended so far.
    #[cfg(test)]
    pub(crate) fn passes(&self) -> u32 {
        self.passes
    }

    /// The percentile once found: `Some(None)` for an empty stream.
    pub(crate) fn result(&self) -> Option<Option<f64>> {
        self.result
    }

    /// One value of the current pass (ignored once the result is found).
    #[inline]
    pub(crate) fn push(&mut self, x: f64) {
        if self.result.is_some() {
            return;
        }
        let k = key(x);
        if self.passes == 0 {
            self.n += 1;
            self.hist[(k >> (64 - DIGIT)) as usize] += 1;
            self.distinct.add(k);
            return;
        }
        let top = k >> (64 - self.fixed);
        if top == self.prefix {
            match self.mode {
                Mode::Collect => self.kept.push(x),
                Mode::Histogram => {
                    self.hist[((k << self.fixed) >> (64 - DIGIT)) as usize] += 1;
                    self.distinct.add(k);
                }
            }
        } else if top > self.prefix && self.above.is_none_or(|a| k < a) {
            self.above = Some(k);
        }
    }

    /// `count` copies of `x` in the first pass, as many [`StreamPercentile::push`]es of it
    /// (the stream of a value table); ignored after the first pass.
    pub(crate) fn push_counted(&mut self, x: f64, count: u64) {
        if self.passes > 0 || self.result.is_some() || count == 0 {
            return;
        }
        let k = key(x);
        self.n += count;
        self.hist[(k >> (64 - DIGIT)) as usize] += count;
        self.distinct.add_counted(k, count);
    }

    /// In the first pass, before [`StreamPercentile::end_pass`]: percentile `p` of the same
    /// stream, as if it had been pushed every value so far (the first pass only counts the
    /// values, the same for any percentile: two percentiles of one stream count it once).
    pub(crate) fn first_pass_twin(&self, p: f64) -> Self {
        let mut twin = self.clone();
        twin.p = p;
        twin
    }

    /// In the first pass, before [`StreamPercentile::end_pass`]: every distinct value so far
    /// with its count, ascending (`total_cmp`), while there are at most [`DISTINCT_CAP`]; `None`
    /// beyond them or after the first pass.
    pub(crate) fn first_pass_values(&self) -> Option<Vec<(f64, u64)>> {
        (self.passes == 0 && !self.distinct.full).then(|| {
            (self.distinct.sorted().into_iter())
                .map(|(k, c)| (from_key(k), c))
                .collect()
        })
    }

    /// In the first pass, before [`StreamPercentile::end_pass`]: an upper bound on how many
    /// values lie within a factor `1 ± rel` of the percentile, from the first pass's histogram
    /// of the top 16 key bits (values 1/16 of an octave apart): the percentile lies between the
    /// smallest value of the bucket holding its lower rank and the largest of the bucket holding
    /// its upper one, and the bound counts every value in the buckets that meet that span
    /// widened by `rel`. `None` when that span is not wholly above 0, or after the first pass.
    pub(crate) fn first_pass_count_near(&self, rel: f64) -> Option<u64> {
        if self.passes > 0 || self.n == 0 {
            return None;
        }
        let pos = (self.p.clamp(0.0, 100.0) / 100.0) * (self.n - 1) as f64;
        let bucket_of = |rank: u64| {
            let mut below = 0;
            self.hist.iter().position(|&h| {
                below += h;
                rank < below
            })
        };
        let (lo, hi) = (
            bucket_of(pos.floor() as u64)?,
            bucket_of(pos.ceil() as u64)?,
        );
        let edge = |digit: usize, last: bool| {
            let k = (digit as u64) << (64 - DIGIT);
            from_key(if last {
                k | ((1 << (64 - DIGIT)) - 1)
            } else {
                k
            })
        };
        let (a, b) = (edge(lo, false), edge(hi, true));
        if a.is_nan() || b.is_nan() || a <= 0.0 {
            return None;
        }
        let (from, to) = (a * (1.0 - rel), b * (1.0 + rel));
        Some(
            (self.hist.iter().enumerate())
                // A bucket whose edge is NaN counts (it cannot be placed).
                .filter(|&(g, &h)| {
                    let (first, last) = (edge(g, false), edge(g, true));
                    h > 0 && (last >= from || last.is_nan()) && (first <= to || first.is_nan())
                })
                .map(|(_, &h)| h)
                .sum(),
        )
    }

    /// Ends a pass: the result when it is known, else what the next pass looks at.
    pub(crate) fn end_pass(&mut self) {
        if self.result.is_some() {
            return;
        }
        self.passes += 1;
        if self.passes == 1 {
            if self.n == 0 {
                self.result = Some(None);
                return;
            }
            // As percentile_select: the same position, ranks and weight.
            let pos = (self.p.clamp(0.0, 100.0) / 100.0) * (self.n - 1) as f64;
            let (lo, hi) = (pos.floor() as u64, pos.ceil() as u64);
            self.frac = pos - lo as f64;
            self.two = hi != lo;
            self.rank = lo;
        }
        if self.mode == Mode::Collect {
            let mut v = std::mem::take(&mut self.kept);
            let (_, &mut a, right) = v.select_nth_unstable_by(self.rank as usize, f64::total_cmp);
            let b = right.iter().copied().min_by(f64::total_cmp);
            self.finish(a, b);
            return;
        }
        if !self.distinct.full {
            // Every value of the stream (bucket) counted: the order statistics directly.
            let d = self.distinct.sorted();
            let mut below = 0;
            for (i, &(k, c)) in d.iter().enumerate() {
                if self.rank < below + c {
                    let b = if self.rank + 1 < below + c {
                        Some(from_key(k))
                    } else {
                        d.get(i + 1).map(|e| from_key(e.0))
                    };
                    self.finish(from_key(k), b);
                    return;
                }
                below += c;
            }
        }
        self.descend();
    }

    /// The histogram of this pass fixes the next digit: the bucket holding the rank.
    fn descend(&mut self) {
        let mut below = 0;
        let mut digit = 0;
        while digit + 1 < self.hist.len() && self.rank >= below + self.hist[digit] {
            below += self.hist[digit];
            digit += 1;
        }
        let count = self.hist[digit];
        let next = (digit + 1..self.hist.len()).find(|&g| self.hist[g] > 0);
        self.prefix = (self.prefix << DIGIT) | digit as u64;
        self.fixed += DIGIT;
        self.rank -= below;
        if self.fixed == 64 {
            // The whole key: the lower order statistic; the upper one is the same key, the next
            // digit's, or the smallest key above the previous bucket.
            let a = from_key(self.prefix);
            let b = if self.rank + 1 < count {
                Some(a)
            } else {
                next.map(|g| from_key((self.prefix & !0xffff) | g as u64))
            };
            self.finish(a, b);
            return;
        }
        self.hist.iter_mut().for_each(|h| *h = 0);
        self.distinct.clear();
        self.above = None;
        self.mode = if count <= self.collect_cap {
            self.kept = Vec::with_capacity(count as usize);
            Mode::Collect
        } else {
            Mode::Histogram
        };
    }

    /// The lower order statistic `a` and the next one in the bucket `b` (else the smallest
    /// value above the bucket).
    fn finish(&mut self, a: f64, b: Option<f64>) {
        let b = if self.two {
            b.or(self.above.map(from_key)).unwrap_or(a)
        } else {
            a
        };
        self.result = Some(Some(a + (b - a) * self.frac));
        self.hist = Vec::new();
        self.kept = Vec::new();
        self.distinct = Distinct::new(0);
    }
}

/// Sorts a copy of `x` (total order; NaN last).
pub fn sorted(x: &[f64]) -> Vec<f64> {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    v
}

/// A histogram: `edges` has one more entry than `counts`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    /// Bin edges, increasing.
    pub edges: Vec<f64>,
    /// Number of values in each bin (the last bin includes its right edge).
    pub counts: Vec<u64>,
}

/// `[min, max]` of the finite values of `x`; `None` if there are none.
pub(crate) fn range(x: &[f64]) -> Option<[f64; 2]> {
    x.iter()
        .filter(|v| v.is_finite())
        .fold(None, |r, &v| match r {
            None => Some([v, v]),
            Some([lo, hi]) => Some([lo.min(v), hi.max(v)]),
        })
}

/// A histogram of `x` with `bins` equal bins over [min, max]. With zero spread all values go in
/// one bin of width 1 centred on the value. `bins` of 0 is treated as 1.
pub(crate) fn histogram(x: &[f64], bins: usize) -> Histogram {
    let bins = bins.max(1);
    if x.is_empty() {
        return Histogram {
            edges: vec![0.0, 1.0],
            counts: vec![0],
        };
    }
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi, bins) = if hi > lo {
        (lo, hi, bins)
    } else {
        (lo - 0.5, lo + 0.5, 1)
    };
    let width = (hi - lo) / bins as f64;
    let edges = (0..=bins).map(|i| lo + width * i as f64).collect();
    let mut counts = vec![0u64; bins];
    for &v in x {
        let i = (((v - lo) / width) as usize).min(bins - 1);
        counts[i] += 1;
    }
    Histogram { edges, counts }
}

/// Number of histogram bins by the Freedman–Diaconis rule, clamped to 5..=60.
pub(crate) fn fd_bins(x: &[f64]) -> usize {
    fd_bins_sorted(&sorted(x))
}

/// [`fd_bins`] of values already sorted ascending (by `f64::total_cmp`, as [`sorted`] sorts).
pub(crate) fn fd_bins_sorted(s: &[f64]) -> usize {
    let (Some(q1), Some(q3)) = (percentile_sorted(s, 25.0), percentile_sorted(s, 75.0)) else {
        return 5;
    };
    let iqr = q3 - q1;
    let range = s[s.len() - 1] - s[0];
    if iqr <= 0.0 || range <= 0.0 {
        return 5;
    }
    let width = 2.0 * iqr / (s.len() as f64).cbrt();
    ((range / width).ceil() as usize).clamp(5, 60)
}

/// Sample skewness and excess kurtosis (bias-corrected, as SAS/Excel `SKEW`/`KURT`); `None` for
/// fewer than four values or zero spread.
pub(crate) fn skew_kurtosis(x: &[f64]) -> Option<(f64, f64)> {
    let n = x.len() as f64;
    if x.len() < 4 {
        return None;
    }
    // Both are scale-free: computed on x / 2^k so that fourth powers of 1e100 or 1e-100 neither
    // overflow nor underflow (a power of two scales exactly: in-range data give the same bits).
    let k = pow2_scale(x);
    let scaled: Vec<f64> = x.iter().map(|v| v / k).collect();
    let x = &scaled[..];
    let m = mean(x)?;
    let m2 = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n;
    if m2 <= 0.0 {
        return None;
    }
    let m3 = x.iter().map(|v| (v - m).powi(3)).sum::<f64>() / n;
    let m4 = x.iter().map(|v| (v - m).powi(4)).sum::<f64>() / n;
    let g1 = m3 / m2.powf(1.5);
    let g2 = m4 / (m2 * m2) - 3.0;
    let skew = g1 * (n * (n - 1.0)).sqrt() / (n - 2.0);
    let kurt = ((n + 1.0) * g2 + 6.0) * (n - 1.0) / ((n - 2.0) * (n - 3.0));
    Some((skew, kurt))
}

/// The power of two nearest below the largest |value| of `x` (1 when that is 0, not finite,
/// or already between 2^-64 and 2^64): dividing by it is exact and brings the values near 1.
fn pow2_scale(x: &[f64]) -> f64 {
    pow2_of_max(x.iter().fold(0.0f64, |a, v| a.max(v.abs())))
}

/// [`pow2_scale`] of values whose largest magnitude is `m`.
fn pow2_of_max(m: f64) -> f64 {
    if !(m.is_finite() && m > 0.0) {
        return 1.0;
    }
    let e = m.log2().floor();
    if e.abs() <= 64.0 {
        1.0
    } else {
        2f64.powi(e.clamp(-1000.0, 1000.0) as i32)
    }
}

/// Sarle's bimodality coefficient b = (skew² + 1) / (kurt + 3(n−1)²/((n−2)(n−3))) with the
/// bias-corrected skewness and excess kurtosis. The uniform distribution gives 5/9 ≈ 0.555;
/// larger values suggest bimodality, a normal distribution gives ≈ 1/3. `None` as for
/// [`skew_kurtosis`].
pub(crate) fn bimodality_coefficient(x: &[f64]) -> Option<f64> {
    let (skew, kurt) = skew_kurtosis(x)?;
    let n = x.len() as f64;
    let denom = kurt + 3.0 * (n - 1.0).powi(2) / ((n - 2.0) * (n - 3.0));
    (denom > 0.0).then(|| (skew * skew + 1.0) / denom)
}

/// The threshold of [`bimodality_coefficient`] above which a sample is called bimodal (5/9).
pub(crate) const BIMODALITY_THRESHOLD: f64 = 5.0 / 9.0;

/// Level of the dip test at which [`crate::score::Score::bimodal`] calls residuals bimodal: a
/// p-value below 5 % rejects unimodality.
pub(crate) const DIP_SIGNIFICANCE: f64 = 0.05;

/// Hartigans' dip statistic of a sample and its modal interval (see `dip_statistic`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Dip {
    /// The dip D: the largest distance between the empirical distribution function and the
    /// unimodal distribution function closest to it. Between 1/(2n) (as unimodal as n values can
    /// be) and 1/4 (two equal point masses).
    pub statistic: f64,
    /// The modal interval [x_L, x_U] the algorithm ends with (two data values): the unimodal
    /// distribution function it fits is convex below x_L and concave above x_U, so its mode
    /// lies in between.
    pub modal_interval: [f64; 2],
    /// Number of values.
    pub n: usize,
}

/// Hartigans' dip test of unimodality (see [`dip_test`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DipTest {
    /// The dip statistic D ([`Dip::statistic`]).
    pub statistic: f64,
    /// P-value of the null hypothesis "the sample comes from a unimodal distribution",
    /// calibrated against the uniform distribution (Hartigans' conservative null): the chance
    /// that n uniform values have a dip of at least `statistic`. Small values mean two or more
    /// modes.
    pub p_value: f64,
    /// The modal interval [x_L, x_U] ([`Dip::modal_interval`]).
    pub modal_interval: [f64; 2],
    /// Number of values.
    pub n: usize,
}

impl DipTest {
    /// Whether the test rejects unimodality at level `alpha` (p-value below `alpha`).
    pub fn rejects_unimodality(&self, alpha: f64) -> bool {
        self.p_value < alpha
    }
}

/// Hartigans' dip statistic (J. A. Hartigan and P. M. Hartigan, "The dip test of unimodality",
/// Ann. Statist. 13, 1985) of `x` in any order; see [`dip_statistic_sorted`]. `None` for fewer
/// than four values, zero spread or a non-finite value.
pub(crate) fn dip_statistic(x: &[f64]) -> Option<Dip> {
    if x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    dip_statistic_sorted(&sorted(x))
}

/// Hartigans' dip statistic of already **sorted** (ascending) values by the algorithm of
/// P. M. Hartigan, "Computation of the dip statistic to test for unimodality", Appl. Statist.
/// 34, 1985 (AS 217), as corrected and maintained in the `diptst` routine of the R package
/// `diptest` (the lower bound 1/(2n), its default `min.is.0 = FALSE`): the modal interval
/// starts as the whole sample and shrinks to where the greatest convex minorant of the
/// empirical distribution function below it and the least concave majorant above it are
/// furthest apart, until that distance no longer exceeds the dip found so far. Linear time
/// after sorting in practice: the two hulls are built once in O(n), each round scans the values
/// it drops from the modal interval once plus the hull vertices still inside it, and the rounds
/// are few (2 to 24, with at most ~3.4·n vertex visits in all, on the 10⁶-value samples of
/// very different shapes we measured; about 30 ms each in a dev build). Tied values are
/// allowed. `None` for fewer than four values, zero spread, a non-finite value, unsorted
/// input or more than 2³² values.
pub(crate) fn dip_statistic_sorted(x: &[f64]) -> Option<Dip> {
    let n = x.len();
    if n < 4 || x.iter().any(|v| !v.is_finite()) || x.windows(2).any(|w| w[1] < w[0]) {
        return None;
    }
    let last = n - 1;
    if x[last] <= x[0] || u32::try_from(last).is_err() {
        return None;
    }
    // Geometry on the points (x_i, i): heights are counts, so every distance below is n times a
    // distance between distribution functions, and the dip is half the largest such distance.
    let (below, above) = hulls(x);

    // Twice the dip, in counts; 1 is the smallest possible value (a jump of one count).
    let mut two_n_dip = 1.0f64;
    // Distances (in counts) closer than this are equal up to rounding. Where two pieces of the
    // hulls are equally far apart the later one sets the modal interval, as in exact
    // arithmetic; without the tolerance rounding would decide (R's results differ between
    // platforms there, see its tests/ex1.R). The dip value came out the same either way on
    // every sample of the tests.
    let tie = 1e-12 * n as f64;
    let (mut low, mut high) = (0usize, last);
    let mut gcm: Vec<usize> = Vec::new();
    let mut lcm: Vec<usize> = Vec::new();
    while low < high {
        // Vertices of the convex minorant from `high` down to `low`, and of the concave majorant
        // from `low` up to `high`.
        gcm.clear();
        let mut g = high;
        gcm.push(g);
        while g > low {
            g = below[g] as usize;
            gcm.push(g);
        }
        lcm.clear();
        let mut l = low;
        lcm.push(l);
        while l < high {
            l = above[l] as usize;
            lcm.push(l);
        }
        let (lg, ll) = (gcm.len(), lcm.len());
        // Largest vertical distance between the two hulls, walking both vertex lists upwards
        // in step; (ig, ih) index the hull vertices bounding the piece where it occurs.
        let (mut ig, mut ih) = (lg - 1, ll - 1);
        let mut d = 0.0f64;
        if lg != 2 || ll != 2 {
            let mut ix = lg as isize - 2; // next vertex of the minorant
            let mut iv = 1usize; // next vertex of the majorant
            for _ in 0..lg + ll + 2 {
                let gx = gcm[ix as usize];
                let lv = lcm[iv];
                if gx > lv {
                    // A majorant vertex comes first: distance to the minorant's piece below it.
                    let g1 = gcm[ix as usize + 1];
                    iv += 1;
                    // On a vertical piece (tied values) the distance is undefined and skipped.
                    if x[gx] > x[g1] {
                        let dx = (lv as f64 - g1 as f64 + 1.0)
                            - (x[lv] - x[g1]) * (gx - g1) as f64 / (x[gx] - x[g1]);
                        if dx >= d - tie {
                            d = dx;
                            ig = ix as usize + 1;
                            ih = iv - 1;
                        }
                    }
                } else {
                    // A minorant vertex comes first: distance to the majorant's piece above it.
                    let l1 = lcm[iv - 1];
                    ix -= 1;
                    if x[lv] > x[l1] {
                        let dx = (x[gx] - x[l1]) * (lv - l1) as f64 / (x[lv] - x[l1])
                            - (gx as f64 - l1 as f64 - 1.0);
                        if dx >= d - tie {
                            d = dx;
                            ig = (ix + 1) as usize;
                            ih = iv;
                        }
                    }
                }
                ix = ix.max(0);
                iv = iv.min(ll - 1);
                if gcm[ix as usize] == lcm[iv] {
                    break;
                }
            }
        } else {
            d = 1.0;
        }
        if d < two_n_dip {
            break;
        }
        two_n_dip = two_n_dip.max(side_dips(x, &gcm, &lcm, ig, ih));
        let (new_low, new_high) = (gcm[ig], lcm[ih]);
        if new_low == low && new_high == high {
            break;
        }
        low = new_low;
        high = new_high;
    }
    Some(Dip {
        statistic: two_n_dip / (2 * n) as f64,
        // `+ 0.0` turns a −0.0 end into 0.0.
        modal_interval: [x[low] + 0.0, x[high] + 0.0],
        n,
    })
}

/// The two hulls of the points (x_i, i) of sorted `x` ([`dip_statistic_sorted`]), as vertex
/// links: `below[j]`, the vertex before j on the greatest convex minorant (lower hull) of points
/// 0..=j; `above[k]`, the vertex after k on the least concave majorant (upper hull) of points
/// k..=last. Indices are u32 (4 B per point instead of 8; the caller checks n ≤ 2^32).
fn hulls(x: &[f64]) -> (Vec<u32>, Vec<u32>) {
    let (n, last) = (x.len(), x.len() - 1);
    let mut below = vec![0u32; n];
    for j in 1..n {
        let mut a = j - 1;
        while a > 0 {
            let b = below[a] as usize;
            // Keep `a` while the hull turns upwards there: slope b→a below slope a→j.
            if (x[j] - x[a]) * ((a - b) as f64) < (x[a] - x[b]) * ((j - a) as f64) {
                break;
            }
            a = b;
        }
        below[j] = a as u32;
    }
    let mut above = vec![last as u32; n];
    for k in (0..last).rev() {
        let mut a = k + 1;
        while a < last {
            let b = above[a] as usize;
            // Keep `a` while the hull turns downwards there: slope a→b below slope k→a.
            if (x[a] - x[k]) * ((b - a) as f64) < (x[b] - x[a]) * ((a - k) as f64) {
                break;
            }
            a = b;
        }
        above[k] = a as u32;
    }
    (below, above)
}

/// The dip (in counts, at least 1) of the convex minorant `gcm` over the part of the sample
/// left of the modal interval starting at its vertex `ig`, and of the concave majorant `lcm`
/// right of the one ending at its vertex `ih` ([`dip_statistic_sorted`]).
fn side_dips(x: &[f64], gcm: &[usize], lcm: &[usize], ig: usize, ih: usize) -> f64 {
    let (lg, ll) = (gcm.len(), lcm.len());
    let mut dip_l = 0.0f64;
    for j in ig..lg - 1 {
        let (jb, je) = (gcm[j + 1], gcm[j]);
        let mut worst = 1.0f64;
        if je - jb > 1 && x[je] > x[jb] {
            let c = (je - jb) as f64 / (x[je] - x[jb]);
            for (r, &xr) in x.iter().enumerate().take(je + 1).skip(jb) {
                worst = worst.max((r - jb + 1) as f64 - (xr - x[jb]) * c);
            }
        }
        dip_l = dip_l.max(worst);
    }
    let mut dip_u = 0.0f64;
    for k in ih..ll - 1 {
        let (kb, ke) = (lcm[k], lcm[k + 1]);
        let mut worst = 1.0f64;
        if ke - kb > 1 && x[ke] > x[kb] {
            let c = (ke - kb) as f64 / (x[ke] - x[kb]);
            for (r, &xr) in x.iter().enumerate().take(ke + 1).skip(kb) {
                worst = worst.max((xr - x[kb]) * c - (r as f64 - kb as f64 - 1.0));
            }
        }
        dip_u = dip_u.max(worst);
    }
    dip_l.max(dip_u)
}

/// Hartigans' dip test of unimodality of `x` in any order: the dip (`dip_statistic`) and the
/// p-value of "unimodal" (`dip_p_value`). `None` where the dip is.
///
/// ```
/// use biasctl::numeric::dip_test;
/// // Two clusters of 100 values each: two humps.
/// let two: Vec<f64> = (0..200).map(|i| (i % 2) as f64 * 10.0 + (i % 13) as f64 * 0.3).collect();
/// let t = dip_test(&two).unwrap();
/// assert!(t.p_value < 0.01 && t.rejects_unimodality(0.05));
/// // An evenly spread sample: as unimodal as can be.
/// let one: Vec<f64> = (0..200).map(f64::from).collect();
/// assert!(dip_test(&one).unwrap().p_value > 0.5);
/// ```
pub fn dip_test(x: &[f64]) -> Option<DipTest> {
    dip_statistic(x).map(DipTest::from)
}

/// [`dip_test`] of already **sorted** values (as `dip_statistic_sorted`).
pub fn dip_test_sorted(sorted: &[f64]) -> Option<DipTest> {
    dip_statistic_sorted(sorted).map(DipTest::from)
}

impl From<Dip> for DipTest {
    fn from(d: Dip) -> Self {
        Self {
            statistic: d.statistic,
            p_value: dip_p_value(d.statistic, d.n),
            modal_interval: d.modal_interval,
            n: d.n,
        }
    }
}

/// P-value of a dip `statistic` of `n` values under Hartigans' uniform null, as R's
/// `diptest::dip.test` computes it: linear interpolation in the table of dip quantiles of
/// uniform samples (`qDiptab`, 10⁶ simulated samples per n, n = 4 … 72 000), on the √n·D scale
/// (on which the dip has a limit distribution) and linearly in n between the tabulated sample
/// sizes; beyond n = 72 000 the last row is used as the asymptotic one. Below the smallest
/// tabulated quantile the p-value is 1, above the largest 0. One deliberate difference from R: a
/// dip at its minimum 1/(2n) gets p = 1, which is exact (every sample has a dip of at least
/// 1/(2n)); R returns 1 minus the highest level tabulated at that value, 0.4 for n = 4. 1 for
/// n < 4 or a non-finite statistic.
pub(crate) fn dip_p_value(statistic: f64, n: usize) -> f64 {
    use dip_table::{LEVELS, N, Q};
    if n < 4 || !statistic.is_finite() {
        return 1.0;
    }
    let nf = n as f64;
    if statistic <= (1.0 + 1e-9) / (2.0 * nf) {
        return 1.0;
    }
    let Some(i0) = N.iter().rposition(|&m| m <= n) else {
        return 1.0;
    };
    let (i1, frac) = if i0 + 1 < N.len() {
        let (n0, n1) = (N[i0] as f64, N[i0 + 1] as f64);
        (i0 + 1, (nf - n0) / (n1 - n0))
    } else {
        (i0, 0.0)
    };
    let (r0, r1) = ((N[i0] as f64).sqrt(), (N[i1] as f64).sqrt());
    let quantile = |k: usize| {
        let y0 = r0 * Q[i0][k];
        y0 + frac * (r1 * Q[i1][k] - y0)
    };
    let s = nf.sqrt() * statistic;
    match (0..LEVELS.len()).find(|&k| quantile(k) > s) {
        None => 0.0,
        Some(0) => 1.0,
        Some(k) => {
            let (a, b) = (quantile(k - 1), quantile(k));
            let level = LEVELS[k - 1] + (LEVELS[k] - LEVELS[k - 1]) * (s - a) / (b - a);
            (1.0 - level).clamp(0.0, 1.0)
        }
    }
}

/// A least-squares line y = intercept + slope·x with its significance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Trend {
    /// Slope (units of y per unit of x).
    pub slope: f64,
    /// Intercept at x = 0.
    pub intercept: f64,
    /// Standard error of the slope.
    pub slope_se: f64,
    /// t statistic of the slope (slope / se).
    pub t: f64,
    /// Two-sided p-value of "slope = 0" (Student t, n − 2 degrees of freedom).
    pub p_value: f64,
    /// Coefficient of determination of the line.
    pub r2: f64,
    /// Number of points.
    pub n: usize,
}

/// Least-squares trend of `y` against `x` (centred, so large x values lose no precision);
/// `None` for fewer than three points or zero spread in x. A perfect fit gives p = 0.
pub(crate) fn linear_trend(x: &[f64], y: &[f64]) -> Option<Trend> {
    linear_trend_of(x.iter().copied().zip(y.iter().copied()))
}

/// [`linear_trend`] of the points `(x, y)` that `points` gives (it is run through several
/// times instead of copied: the same sums in the same order, so the same bits).
pub(crate) fn linear_trend_of(points: impl Iterator<Item = (f64, f64)> + Clone) -> Option<Trend> {
    let n = points.clone().count();
    if n < 3 {
        return None;
    }
    // Computed on x / 2^a and y / 2^b (exact scalings; in-range data give the same bits) so
    // that squares of 1e-200 or 1e200 neither underflow nor overflow; slope, intercept and
    // slope_se are scaled back, t, p and r² are scale-free.
    let max_abs = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0f64, |a, v| a.max(v.abs()));
    let (kx, ky) = (
        pow2_of_max(max_abs(&mut points.clone().map(|p| p.0))),
        pow2_of_max(max_abs(&mut points.clone().map(|p| p.1))),
    );
    let scaled = points.map(move |(x, y)| (x / kx, y / ky));
    let x = || scaled.clone().map(|p| p.0);
    let y = || scaled.clone().map(|p| p.1);
    let mx = x().sum::<f64>() / n as f64;
    let my = y().sum::<f64>() / n as f64;
    let sxx: f64 = x().map(|v| (v - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let sxy: f64 = scaled.clone().map(|(a, b)| (a - mx) * (b - my)).sum();
    let syy: f64 = y().map(|v| (v - my).powi(2)).sum();
    let slope = sxy / sxx;
    let sse = (syy - slope * sxy).max(0.0);
    let dof = (n - 2) as f64;
    // A slope is known to no better than its own rounding (ε·|slope|): an exact line gives that
    // standard error, not 0, so t stays finite (at most 1/ε ≈ 4.5e15) and the JSON never
    // carries a `null` for it.
    let slope_se = (sse / dof / sxx).sqrt().max(f64::EPSILON * slope.abs());
    let t = if slope_se > 0.0 {
        slope / slope_se
    } else {
        0.0
    };
    let p_value = student_t_two_sided_p(t, dof);
    let r2 = if syy > 0.0 { 1.0 - sse / syy } else { 0.0 };
    Some(Trend {
        slope: slope * (ky / kx),
        intercept: (my - slope * mx) * ky,
        slope_se: slope_se * (ky / kx),
        t,
        p_value,
        r2,
        n,
    })
}

/// Autocorrelation of `x` at `lag` (biased estimator, as in the Ljung–Box test); 0 when the
/// spread is zero or the lag is out of range.
pub(crate) fn autocorrelation(x: &[f64], lag: usize) -> f64 {
    let n = x.len();
    if lag >= n {
        return 0.0;
    }
    let Some(m) = mean(x) else { return 0.0 };
    let c0: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
    if c0 <= 0.0 {
        return 0.0;
    }
    let ck: f64 = (lag..n).map(|i| (x[i] - m) * (x[i - lag] - m)).sum();
    ck / c0
}

/// The Ljung–Box test of whiteness over lags 1..=`lags`: (Q, p-value with `lags` degrees of
/// freedom). `None` when there are not more values than lags + 1.
pub(crate) fn ljung_box(x: &[f64], lags: usize) -> Option<(f64, f64)> {
    let n = x.len();
    if lags == 0 || n <= lags + 1 {
        return None;
    }
    let nf = n as f64;
    // All lags from one pass: the bits of `autocorrelation(x, k)` for each k.
    let acf = autocorrelations(x, lags);
    let q = nf
        * (nf + 2.0)
        * (1..=lags)
            .map(|k| acf[k - 1].powi(2) / (nf - k as f64))
            .sum::<f64>();
    Some((q, chi2_sf(q, lags as f64)))
}

/// Two-sided p-value of a Student t statistic with `dof` degrees of freedom:
/// P(|T| ≥ |t|) = I_{dof/(dof+t²)}(dof/2, 1/2).
pub(crate) fn student_t_two_sided_p(t: f64, dof: f64) -> f64 {
    if dof <= 0.0 {
        return 1.0;
    }
    reg_inc_beta(dof / 2.0, 0.5, dof / (dof + t * t)).clamp(0.0, 1.0)
}

/// Survival function of the chi-square distribution: P(X ≥ q) with `dof` degrees of freedom.
pub(crate) fn chi2_sf(q: f64, dof: f64) -> f64 {
    if q <= 0.0 {
        return 1.0;
    }
    gamma_q(dof / 2.0, q / 2.0).clamp(0.0, 1.0)
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, n = 9; ~1e-15 relative).
pub(crate) fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection formula.
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma function Q(a, x) (series / continued fraction, Numerical
/// Recipes §6.2).
pub(crate) fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        // Series for P, Q = 1 − P.
        let mut ap = a;
        let mut sum = 1.0 / a;
        let mut del = sum;
        for _ in 0..1000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        // Lentz continued fraction for Q.
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / LENTZ_TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            let del = lentz_step(an, b, &mut c, &mut d);
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// Regularised incomplete beta function I_x(a, b) (continued fraction, Numerical Recipes §6.4).
pub(crate) fn reg_inc_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    let front = ln_front.exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_cf(a, b, x) / a
    } else {
        1.0 - front * beta_cf(b, a, 1.0 - x) / b
    }
}

/// Lentz's floor for a vanishing denominator.
const LENTZ_TINY: f64 = 1e-300;

/// `v`, or [`LENTZ_TINY`] where |v| is below it (NaN passes through).
#[inline]
fn guard(v: f64) -> f64 {
    if v.abs() < LENTZ_TINY { LENTZ_TINY } else { v }
}

/// One step of the modified Lentz recurrence for the partial fraction `a / (b + …)`: updates
/// `c` and `d`, returns the factor `d·c` the fraction's value is multiplied by.
#[inline]
fn lentz_step(a: f64, b: f64, c: &mut f64, d: &mut f64) -> f64 {
    *d = 1.0 / guard(b + a * *d);
    *c = guard(b + a / *c);
    *d * *c
}

fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..1000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        h *= lentz_step(aa, 1.0, &mut c, &mut d);
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        let del = lentz_step(aa, 1.0, &mut c, &mut d);
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    /// The slice-copying `linear_trend` as it was before it read its points in place (issue
    /// #16): the reference `linear_trend_of` must match bit for bit.
    fn linear_trend_copying(x: &[f64], y: &[f64]) -> Option<Trend> {
        let n = x.len().min(y.len());
        if n < 3 {
            return None;
        }
        let (kx, ky) = (pow2_scale(&x[..n]), pow2_scale(&y[..n]));
        let xs: Vec<f64> = x[..n].iter().map(|v| v / kx).collect();
        let ys: Vec<f64> = y[..n].iter().map(|v| v / ky).collect();
        let (x, y) = (&xs[..], &ys[..]);
        let mx = mean(x)?;
        let my = mean(y)?;
        let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
        if sxx <= 0.0 {
            return None;
        }
        let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
        let syy: f64 = y.iter().map(|v| (v - my).powi(2)).sum();
        let slope = sxy / sxx;
        let sse = (syy - slope * sxy).max(0.0);
        let dof = (n - 2) as f64;
        let slope_se = (sse / dof / sxx).sqrt().max(f64::EPSILON * slope.abs());
        let t = if slope_se > 0.0 {
            slope / slope_se
        } else {
            0.0
        };
        Some(Trend {
            slope: slope * (ky / kx),
            intercept: (my - slope * mx) * ky,
            slope_se: slope_se * (ky / kx),
            t,
            p_value: student_t_two_sided_p(t, dof),
            r2: if syy > 0.0 { 1.0 - sse / syy } else { 0.0 },
            n,
        })
    }

    #[test]
    fn linear_trend_in_place_matches_the_copying_one_bit_for_bit() {
        let mut rng = crate::numeric::rng::SimRng::new(11);
        let bits = |t: Option<Trend>| {
            t.map(|t| {
                [
                    t.slope,
                    t.intercept,
                    t.slope_se,
                    t.t,
                    t.p_value,
                    t.r2,
                    t.n as f64,
                ]
                .map(f64::to_bits)
            })
        };
        for (sx, sy) in [(1.0, 1.0), (1e3, 1e-3), (1e200, 1e-200), (1e-250, 1e250)] {
            for n in [0usize, 2, 3, 10, 1000] {
                let x: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 3.0) * sx).collect();
                let y: Vec<f64> = x
                    .iter()
                    .map(|v| (0.3 * v / sx + rng.range(-1.0, 1.0)) * sy)
                    .collect();
                assert_eq!(
                    bits(linear_trend(&x, &y)),
                    bits(linear_trend_copying(&x, &y))
                );
                // Unequal lengths: the shorter decides, as before.
                let short = &y[..n.saturating_sub(1)];
                assert_eq!(
                    bits(linear_trend(&x, short)),
                    bits(linear_trend_copying(&x, short))
                );
            }
        }
        assert!(linear_trend(&[2.0; 5], &[1.0, 2.0, 3.0, 4.0, 5.0]).is_none());
    }

    #[test]
    fn distribution_functions_match_scipy_values() {
        // Reference values from scipy.stats (t.sf*2, chi2.sf) and math.lgamma.
        assert!(close(
            student_t_two_sided_p(2.0, 10.0),
            0.073_388_034_770_740_8,
            1e-10
        ));
        // Closed form for 3 degrees of freedom: F(t) = 1/2 + (u/(1+u²) + atan u)/π, u = t/√3.
        let u = 0.5 / 3f64.sqrt();
        let cdf = 0.5 + (u / (1.0 + u * u) + u.atan()) / std::f64::consts::PI;
        assert!(close(
            student_t_two_sided_p(0.5, 3.0),
            2.0 * (1.0 - cdf),
            1e-12
        ));
        assert!(close(chi2_sf(3.841_458_820_694_124, 1.0), 0.05, 1e-10));
        assert!(close(chi2_sf(18.307_038_053_275_146, 10.0), 0.05, 1e-10));
        assert!(close(ln_gamma(10.0), 12.801_827_480_081_469, 1e-12));
        assert!(close(ln_gamma(0.5), 0.572_364_942_924_700_1, 1e-12));
    }

    #[test]
    fn moments_and_percentiles() {
        let x = [1.0, 2.0, 3.0, 4.0];
        assert!(close(mean(&x).unwrap(), 2.5, 1e-15));
        assert!(close(std_dev(&x).unwrap(), (5.0f64 / 3.0).sqrt(), 1e-15));
        assert!(close(percentile_sorted(&x, 50.0).unwrap(), 2.5, 1e-15));
        assert!(close(percentile_sorted(&x, 90.0).unwrap(), 3.7, 1e-12));
        assert_eq!(std_dev(&[1.0]), None);
        assert_eq!(mean(&[]), None);
    }

    #[test]
    fn range_ignores_non_finite_values() {
        assert_eq!(
            range(&[3.0, f64::NAN, -1.0, f64::INFINITY, 2.0]),
            Some([-1.0, 3.0])
        );
        assert_eq!(range(&[5.0]), Some([5.0, 5.0]));
        assert_eq!(range(&[]), None);
        assert_eq!(range(&[f64::NAN]), None);
    }

    #[test]
    fn histogram_counts_every_value_once() {
        let x: Vec<f64> = (0..100).map(f64::from).collect();
        let h = histogram(&x, 10);
        assert_eq!(h.counts, vec![10; 10]);
        assert_eq!(h.edges.len(), 11);
        let one = histogram(&[3.0, 3.0], 10);
        assert_eq!(one.counts, vec![2]);
    }

    #[test]
    fn bimodality_separates_two_clusters_from_one() {
        // Two well separated clusters vs one symmetric lump; the uniform gives 5/9 in the limit.
        let two: Vec<f64> = (0..400)
            .map(|i| if i % 2 == 0 { -10.0 } else { 10.0 } + (i % 7) as f64 * 0.1)
            .collect();
        let one: Vec<f64> = (0..401)
            .map(|i| ((i as f64) - 200.0).powi(3) / 1e6)
            .collect();
        assert!(bimodality_coefficient(&two).unwrap() > 0.9);
        assert!(bimodality_coefficient(&one).unwrap() < BIMODALITY_THRESHOLD);
        let uniform: Vec<f64> = (0..10_000).map(f64::from).collect();
        assert!(close(
            bimodality_coefficient(&uniform).unwrap(),
            5.0 / 9.0,
            1e-3
        ));
    }

    #[test]
    fn trend_of_exact_line_and_of_no_line() {
        let x: Vec<f64> = (0..50).map(|i| 1000.0 + i as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| 2.0 - 0.5 * v).collect();
        let t = linear_trend(&x, &y).unwrap();
        assert!(close(t.slope, -0.5, 1e-12) && close(t.intercept, 2.0, 1e-9));
        assert!(t.p_value < 1e-12 && close(t.r2, 1.0, 1e-12));
        let flat: Vec<f64> = x
            .iter()
            .map(|v| if (*v as i64) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let t0 = linear_trend(&x, &flat).unwrap();
        assert!(t0.p_value > 0.5, "{t0:?}");
        assert!(linear_trend(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).is_none());
        // Reference: an exact line at positions 1e11…1e15 (the fuzz finding that printed
        // `"t": null`): t is finite, |t| = 1/ε, p = 0.
        let big: Vec<f64> = (0..20).map(|i| 1e11 + 5e13 * f64::from(i)).collect();
        let line: Vec<f64> = big.iter().map(|v| 3.0 + 1e-12 * v).collect();
        let tb = linear_trend(&big, &line).unwrap();
        assert!(
            tb.t.is_finite() && tb.slope_se > 0.0 && tb.p_value < 1e-12,
            "{tb:?}"
        );
    }

    #[test]
    fn ljung_box_flags_a_random_walk_not_white_noise() {
        let mut r = crate::numeric::rng::SimRng::new(9);
        let white: Vec<f64> = (0..2000).map(|_| r.normal()).collect();
        let walk: Vec<f64> = white
            .iter()
            .scan(0.0, |s, v| {
                *s += v;
                Some(*s)
            })
            .collect();
        assert!(ljung_box(&white, 10).unwrap().1 > 0.01);
        assert!(ljung_box(&walk, 10).unwrap().1 < 1e-10);
    }

    /// Reference: the moments' ratios and the trend's t, p and r² are scale-free, and the slope
    /// scales as y/x: the same data at 1e±150 must give the in-range figures (scaled) instead
    /// of overflowing or underflowing to `None` (a fuzz finding).
    #[test]
    fn moments_and_trend_survive_extreme_scales() {
        let x: Vec<f64> = (0..200).map(|i| ((i * 37) % 101) as f64 - 40.0).collect();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(i, v)| 0.3 * v + ((i * 13) % 7) as f64)
            .collect();
        let b0 = bimodality_coefficient(&y).unwrap();
        let t0 = linear_trend(&x, &y).unwrap();
        let rel = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
        for (sx, sy) in [
            (1e150, 1e-150),
            (1e-150, 1e150),
            (1e-200, 1e-200),
            (1e200, 1e100),
        ] {
            let xs: Vec<f64> = x.iter().map(|v| v * sx).collect();
            let ys: Vec<f64> = y.iter().map(|v| v * sy).collect();
            assert!(rel(bimodality_coefficient(&ys).unwrap(), b0), "{sy}");
            let t = linear_trend(&xs, &ys).unwrap();
            assert!(rel(t.slope, t0.slope * sy / sx), "{sx} {sy}");
            assert!(rel(t.intercept, t0.intercept * sy), "{sx} {sy}");
            assert!(rel(t.t, t0.t) && rel(t.r2, t0.r2), "{sx} {sy}");
        }
        // The scaling is by powers of two, so data that differ by one give the same bits.
        let ys: Vec<f64> = y.iter().map(|v| v * 2f64.powi(100)).collect();
        let t = linear_trend(&x, &ys).unwrap();
        assert_eq!(t.t.to_bits(), t0.t.to_bits());
    }
}

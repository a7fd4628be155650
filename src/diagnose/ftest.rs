//! The in-sample one-way ANOVA F-test the permutation test is built on: its p-value (and its
//! logarithm, continued where the p-value underflows) over every candidate binning of a
//! feature.

use crate::numeric::stats::reg_inc_beta;

use super::smoother::{Binned, FineSlots, add_by_slot, add_by_slot_signed, fine_counts};

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

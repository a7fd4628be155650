//! Sampling analysis in passes (`SamplingStream`): the exact quantiles of a log read row by
//! row, in memory independent of its length.

use super::sampling::{CLOCK_TOLERANCE, Quantiles, regular_clock, second_difference};
use super::{DirectionTracker, Sampling};
use crate::numeric::stats::StreamPercentile;

/// [`sampling`] of a log read in passes, in memory independent of its length (`biasctl
/// check`): feed every row's time and position with [`SamplingStream::push`], end the pass
/// with [`SamplingStream::end_pass`], and read the log again while it returns `true`; then
/// [`SamplingStream::finish`]. Each quantile is exact ([`StreamPercentile`]), so the result
/// equals [`sampling`] of the whole log bit for bit. Passes: the first counts and
/// histograms; the quantiles of the positions and of Δt usually end with the second; a dense
/// log's reversals with the deadband need one more. Whether the clock is regular (the spread of
/// Δt about its median) costs no pass of its own when the first pass settles it: a Δt of at
/// most 4096 distinct values (a clock) is known value by value, so the spread is
/// computed from that table; else the first pass's histogram bounds how many Δt can lie within
/// 2 % of their median, and when that is fewer than half of them the clock is irregular (the
/// median spread is then above 1 % of the median: a seek log's dwells). Only a clock that is
/// neither (jittered beyond the table, yet within 2 %) reads the log for the spread: one or two
/// passes after the median.
///
/// [`StreamPercentile`]: crate::numeric::stats::StreamPercentile
pub(crate) struct SamplingStream {
    dt: StreamPercentile,
    step: StreamPercentile,
    p95: StreamPercentile,
    p5: StreamPercentile,
    d2: StreamPercentile,
    /// Started in the pass after the median Δt is known (at once, from the first pass's
    /// values, when Δt has few distinct values).
    dt_dev: Option<(f64, StreamPercentile)>,
    /// The first pass settled that the clock is irregular: `dt_dev` is not needed.
    irregular: bool,
    /// Rows in the pass so far, and the last two rows' time and position.
    row: usize,
    prev: (f64, f64),
    prev2_x: f64,
    /// The first pass: rows, first and last time, the raw reversals.
    rows: usize,
    first_last: (f64, f64),
    raw: (DirectionTracker, usize),
    /// The reversals with the deadband the quantiles give a dense log: counted in the pass
    /// after the noise is known; `(deadband, tracker, count, done)`.
    banded: Option<(f64, DirectionTracker, usize, bool)>,
    passes: usize,
}

impl SamplingStream {
    /// Before the first pass.
    pub(crate) fn new() -> Self {
        Self {
            dt: StreamPercentile::new(50.0),
            step: StreamPercentile::new(50.0),
            p95: StreamPercentile::new(95.0),
            p5: StreamPercentile::new(5.0),
            d2: StreamPercentile::new(50.0),
            dt_dev: None,
            irregular: false,
            row: 0,
            prev: (0.0, 0.0),
            prev2_x: 0.0,
            rows: 0,
            first_last: (0.0, 0.0),
            raw: (DirectionTracker::new(0.0), 0),
            banded: None,
            passes: 0,
        }
    }

    /// The next row of the pass: its time (s) and position.
    pub(crate) fn push(&mut self, t: f64, x: f64) {
        let count = |tr: &mut DirectionTracker, n: &mut usize| {
            let s = tr.peek(x, None);
            tr.commit(x, &s);
            *n += usize::from(s.reversal);
        };
        if self.passes == 0 {
            if self.row == 0 {
                self.first_last.0 = t;
            }
            self.first_last.1 = t;
            self.rows += 1;
            let (tr, n) = &mut self.raw;
            count(tr, n);
        }
        if let Some((_, tr, n, false)) = &mut self.banded {
            count(tr, n);
        }
        let (pt, px) = self.prev;
        if self.row >= 1 {
            let dt = t - pt;
            self.dt.push(dt);
            if let Some((median, q)) = &mut self.dt_dev {
                q.push((dt - *median).abs());
            }
            self.step.push((x - px).abs());
        }
        if self.row >= 2 {
            self.d2.push(second_difference(self.prev2_x, px, x));
        }
        if self.passes > 0 {
            self.p95.push(x);
        }
        self.p5.push(x);
        self.prev2_x = px;
        self.prev = (t, x);
        self.row += 1;
    }

    /// Ends a pass; `true` when the log must be read once more.
    pub(crate) fn end_pass(&mut self) -> bool {
        // Read before the first pass's histograms and value tables are dropped.
        let first = self.passes == 0;
        let dt_values = first.then(|| self.dt.first_pass_values()).flatten();
        let dt_near = first
            .then(|| self.dt.first_pass_count_near(2.0 * CLOCK_TOLERANCE))
            .flatten();
        if first {
            // The first pass pushed the positions into `p5` alone.
            self.p95 = self.p5.first_pass_twin(95.0);
        }
        for q in [
            &mut self.dt,
            &mut self.step,
            &mut self.p95,
            &mut self.p5,
            &mut self.d2,
        ] {
            q.end_pass();
        }
        if let Some((_, q)) = &mut self.dt_dev {
            q.end_pass();
        }
        if let Some(b) = &mut self.banded {
            b.3 = true;
        }
        self.passes += 1;
        self.row = 0;
        if let Some(near) = dt_near
            && self.dt.result().is_none()
        {
            // Fewer Δt within 2 % of the median than the lower middle rank of the spreads
            // (`percentile_select`'s position for 50 % of rows − 1 values): the median spread is
            // at least that order statistic, above 1 % of the median.
            let lower_middle = (0.5 * self.rows.saturating_sub(2) as f64).floor() as u64;
            self.irregular = near <= lower_middle;
        }
        if self.dt_dev.is_none()
            && !self.irregular
            && let Some(median) = self.dt.result()
        {
            let median = median.unwrap_or(0.0);
            let mut spread = StreamPercentile::new(50.0);
            if let Some(values) = dt_values {
                // Every Δt of the log, value by value: the spreads' stream is that table.
                for (dt, count) in values {
                    spread.push_counted((dt - median).abs(), count);
                }
                spread.end_pass();
            }
            self.dt_dev = Some((median, spread));
        }
        if self.banded.is_none()
            && let Some(mad) = self.d2.result()
        {
            let q = Quantiles {
                regular_clock: false,
                median_step: 0.0,
                p95: 0.0,
                p5: 0.0,
                mad: mad.unwrap_or(0.0),
            };
            let d = q.dense_deadband(self.rows);
            self.banded = Some((d, DirectionTracker::new(d), 0, false));
        }
        match self.quantiles() {
            None => true,
            Some(q) => {
                let s = q.sampling(self.rows, None, 0, |_| 0);
                s.dense && !self.banded.as_ref().is_some_and(|b| b.3)
            }
        }
    }

    /// Every quantile, once all are known.
    fn quantiles(&self) -> Option<Quantiles> {
        let get = |q: &StreamPercentile| q.result().map(|r| r.unwrap_or(0.0));
        let regular =
            !self.irregular && regular_clock(get(&self.dt)?, get(&self.dt_dev.as_ref()?.1)?);
        Some(Quantiles {
            regular_clock: regular,
            median_step: get(&self.step)?,
            p95: get(&self.p95)?,
            p5: get(&self.p5)?,
            mad: get(&self.d2)?,
        })
    }

    /// The sampling, once [`SamplingStream::end_pass`] has returned `false` (`None` before).
    pub(crate) fn finish(&self) -> Option<Sampling> {
        let q = self.quantiles()?;
        let (a, b) = self.first_last;
        let span = (self.rows > 0 && b > a).then_some(b - a);
        let banded = self.banded.as_ref().map(|b| b.2);
        let s = q.sampling(self.rows, span, self.raw.1, |_| banded.unwrap_or(0));
        (!s.dense || self.banded.as_ref().is_some_and(|b| b.3)).then_some(s)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::float_cmp)] // positions are exact integers here; equality is meant

    use super::*;
    use crate::history::sampling;
    use crate::numeric::rng::SimRng;

    /// Reference: sort a copy and index it (`sorted`, `percentile_sorted`). Nested selection
    /// of several ranks (repeats, neighbours, both ends) and several percentiles from one
    /// selection give the same bits as the sorted copy, on values with ties and signed zeros.
    #[test]
    fn nested_order_statistics_equal_sorted_ones_bit_for_bit() {
        use crate::numeric::stats::{
            order_statistics, percentile_sorted, percentiles_select, sorted,
        };
        let mut rng = SimRng::new(11);
        for case in 0..600 {
            let n = 1 + rng.below(300) as usize;
            let v = awkward_values(&mut rng, case, n);
            let s = sorted(&v);
            let mut ranks: Vec<usize> = (0..rng.below(9) as usize)
                .map(|_| match rng.below(4) {
                    0 => 0,
                    1 => n - 1,
                    _ => rng.below(n as u64) as usize,
                })
                .collect();
            ranks.sort_unstable();
            let mut out = vec![f64::NAN; ranks.len()];
            order_statistics(&mut v.clone(), &ranks, &mut out);
            for (r, o) in ranks.iter().zip(&out) {
                assert_eq!(o.to_bits(), s[*r].to_bits(), "case {case}, rank {r}, n {n}");
            }
            let ps = [95.0, 5.0, 50.0, 37.5, 0.0, 100.0, 99.9];
            let got = percentiles_select(&mut v.clone(), &ps).unwrap();
            for (p, g) in ps.iter().zip(&got) {
                let want = percentile_sorted(&s, *p).unwrap();
                assert_eq!(g.to_bits(), want.to_bits(), "case {case}, p {p}, n {n}");
            }
        }
        assert_eq!(percentiles_select(&mut [], &[50.0]), None);
    }

    /// Values with ties, signed zeros, negatives, near-equal clusters (a clock's Δt differing
    /// in the last bits) and wide spreads, by `case`.
    fn awkward_values(rng: &mut SimRng, case: usize, n: usize) -> Vec<f64> {
        (0..n)
            .map(|_| match case % 6 {
                0 => rng.below(5) as f64 - 2.0,
                1 => [0.0, -0.0, 1.5, -1.5][rng.below(4) as usize],
                2 => rng.normal() * 10f64.powi(rng.below(20) as i32 - 10),
                3 => f64::from_bits(1e-3f64.to_bits() + rng.below(40)) - 1e-3 * rng.below(2) as f64,
                4 => -1e-3 * (1.0 + rng.below(3) as f64 * f64::EPSILON),
                _ => rng.range(-1e6, 1e6).round() + [0.0, 0.25, -0.0][rng.below(3) as usize],
            })
            .collect()
    }

    /// Runs a [`StreamPercentile`] over `v` pass after pass; its result and the passes taken.
    fn streamed(v: &[f64], p: f64, caps: (u64, usize)) -> (Option<f64>, u32) {
        use crate::numeric::stats::StreamPercentile;
        let mut q = StreamPercentile::with_caps(p, caps.0, caps.1);
        loop {
            v.iter().for_each(|&x| q.push(x));
            q.end_pass();
            if let Some(r) = q.result() {
                return (r, q.passes());
            }
            assert!(q.passes() < 5, "more than five passes");
        }
    }

    /// Reference: sort a copy, then `percentile_sorted` (the in-memory definition). The
    /// constant-memory radix selection `check` uses gives the same bits on random streams with
    /// ties, ±0, negatives and near-equal clusters, with the production caps and with caps of
    /// 0 / a few values (every value then goes through all four 16-bit digits, or through the
    /// distinct-value count), at most five passes.
    #[test]
    fn streamed_percentiles_equal_sorted_ones_bit_for_bit() {
        use crate::numeric::stats::{percentile_sorted, sorted};
        let mut rng = SimRng::new(17);
        let caps = [(1 << 17, 4096), (0, 0), (3, 2), (0, 16), (64, 0)];
        for case in 0..240 {
            let n = 1 + rng.below(if case % 10 == 0 { 3000 } else { 150 }) as usize;
            let v = awkward_values(&mut rng, case, n);
            let sorted = sorted(&v);
            for p in [0.0, 5.0, 37.5, 50.0, 95.0, 100.0] {
                let want = percentile_sorted(&sorted, p).unwrap();
                for cap in caps {
                    let (got, _) = streamed(&v, p, cap);
                    assert_eq!(
                        got.map(f64::to_bits),
                        Some(want.to_bits()),
                        "case {case}, p {p}, n {n}, caps {cap:?}: {got:?} vs {want}"
                    );
                }
            }
        }
        assert_eq!(streamed(&[], 50.0, (0, 0)), (None, 1));
        // A long near-constant stream (a regular clock's Δt, differing in the last bits) beyond
        // the collect cap: exact from the distinct count, with the production caps, at once.
        let v: Vec<f64> = (0..300_000)
            .map(|i| ((i + 1) as f64 * 1e-3) - (i as f64 * 1e-3))
            .collect();
        let want = percentile_sorted(&sorted(&v), 50.0).unwrap();
        let (got, passes) = streamed(&v, 50.0, (1 << 17, 4096));
        assert_eq!(got.map(f64::to_bits), Some(want.to_bits()));
        assert_eq!(passes, 1);
        // Without the distinct count: the histogram passes.
        let (got, passes) = streamed(&v, 50.0, (1 << 17, 0));
        assert_eq!(got.map(f64::to_bits), Some(want.to_bits()));
        assert!(passes >= 3, "{passes}");
    }

    /// Runs [`SamplingStream`] over rows `(t, x)` pass after pass; the sampling, the passes and
    /// whether the first pass settled the clock as irregular.
    fn stream_sampling(t: &[f64], x: &[f64]) -> (Sampling, usize, bool) {
        let mut s = SamplingStream::new();
        let mut passes = 0;
        loop {
            t.iter().zip(x).for_each(|(&t, &x)| s.push(t, x));
            passes += 1;
            if !s.end_pass() {
                break;
            }
            assert!(passes < 12, "too many passes");
        }
        (s.finish().expect("finished"), passes, s.irregular)
    }

    /// Reference: [`sampling`] of the rows in memory (its quantiles by selection, themselves
    /// tested against sorting above). The streamed sampling `check` uses is the same bit for
    /// bit (every field) on dense time series (regular clock, noisy sine: the deadband pass),
    /// seek logs (irregular times), logs of a few distinct positions with ±0, negative and
    /// tiny logs, and clocks whose jitter straddles the 1 % a regular clock allows (beyond the
    /// first pass's value table, so only the exact passes can tell) or whose Δt are half
    /// regular, half spread. It also checks the passes: a seek log with irregular times ends
    /// in at most two (the first settles the clock), a clock of few distinct Δt needs no pass for the
    /// spread, and the settling happens on the seek logs (it is not a path never taken).
    #[test]
    fn streamed_sampling_equals_in_memory_sampling() {
        let mut rng = SimRng::new(23);
        let (mut dense, mut seek, mut settled) = (0, 0, 0);
        let mut jittered = [0, 0];
        for case in 0..150 {
            let n = match case % 10 {
                0 => rng.below(4) as usize,
                1 | 4 | 7 => 20_000,
                _ => 1 + rng.below(3000) as usize,
            };
            let dt = [1e-3, 0.01, 0.5][rng.below(3) as usize];
            let jitter = [0.03, 0.034, 0.04][rng.below(3) as usize];
            let mut clock = 0.0;
            let (t, x): (Vec<f64>, Vec<f64>) = (0..n)
                .map(|i| {
                    let ti = i as f64 * dt;
                    match case % 6 {
                        0 | 1 => (ti, 100.0 * (0.002 * i as f64).sin() + 0.05 * rng.normal()),
                        2 => (
                            ti + rng.range(0.0, 0.9) * dt,
                            [0.0, -0.0, -3.0, 7.5][rng.below(4) as usize],
                        ),
                        3 => (ti, rng.range(-500.0, 500.0).round()),
                        // Jitter of ±1.5–2 % of Δt at each row: median spreads of
                        // 0.3·that, 0.88–1.17 % (triangular differences), about the 1 % bar.
                        4 => (
                            ti + rng.range(-jitter, jitter) * dt * 0.5,
                            100.0 * (0.002 * i as f64).sin() + 0.05 * rng.normal(),
                        ),
                        // Every other step on the clock, the rest 1.5–3 Δt: the median Δt at
                        // the edge of the regular half.
                        _ => {
                            clock += if i % 2 == 0 {
                                dt
                            } else {
                                dt * rng.range(1.5, 3.0)
                            };
                            (clock, rng.range(-500.0, 500.0).round())
                        }
                    }
                })
                .unzip();
            let want = sampling(&t, &x);
            let (got, passes, irregular) = stream_sampling(&t, &x);
            assert_eq!(
                format!("{got:?}"),
                format!("{want:?}"),
                "case {case}, n {n}"
            );
            assert!(passes <= 6, "case {case}: {passes} passes");
            if case % 6 == 2 && n > 5000 {
                assert!(passes <= 2 && irregular, "case {case}: {passes} passes");
            }
            if case % 6 == 3 {
                // Integer positions, a clock of one Δt: every quantile from the first pass.
                assert_eq!(passes, 1, "case {case}");
            }
            settled += usize::from(irregular);
            if case % 6 == 4 && n > 1000 {
                jittered[usize::from(want.regular_clock)] += 1;
            }
            if want.dense {
                dense += 1;
            } else {
                seek += 1;
            }
        }
        assert!(dense > 20 && seek > 20, "{dense} dense, {seek} seek logs");
        assert!(settled >= 5, "{settled} logs settled as irregular");
        assert!(
            jittered[0] > 0 && jittered[1] > 0,
            "jittered clocks {jittered:?}"
        );
    }

    /// Reference: the count, in a sorted copy, of the values within `1 ± rel` of the exact
    /// percentile (`percentile_sorted`). The first pass's bound on it
    /// (`first_pass_count_near`) is never below it, on streams of ties, clusters, wide spreads
    /// and signed values, and stays well below the stream's length on wide spreads (it is a
    /// bound that can settle something).
    #[test]
    fn first_pass_count_near_bounds_the_true_count() {
        use crate::numeric::stats::{StreamPercentile, percentile_sorted, sorted};
        let mut rng = SimRng::new(29);
        for case in 0..200 {
            let n = 1 + rng.below(5000) as usize;
            let wide = case % 4 == 3;
            let v: Vec<f64> = if wide {
                (0..n).map(|_| rng.range(0.05, 0.5)).collect()
            } else {
                awkward_values(&mut rng, case, n)
            };
            let p = [5.0, 50.0, 95.0][case % 3];
            let mut q = StreamPercentile::new(p);
            v.iter().for_each(|&x| q.push(x));
            let m = percentile_sorted(&sorted(&v), p).unwrap();
            for rel in [0.0, 0.02, 0.1] {
                let Some(bound) = q.first_pass_count_near(rel) else {
                    assert!(
                        m <= 0.0 || m < 1e-300 || !wide,
                        "case {case}: no bound for {m}"
                    );
                    continue;
                };
                let (lo, hi) = (m * (1.0 - rel), m * (1.0 + rel));
                let truth = v.iter().filter(|&&x| x >= lo && x <= hi).count() as u64;
                assert!(bound >= truth, "case {case}, rel {rel}: {bound} < {truth}");
                if wide && n > 1000 && rel == 0.02 {
                    assert!(bound < n as u64 / 4, "case {case}: {bound} of {n}");
                }
            }
        }
    }
}

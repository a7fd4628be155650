//! Sampling analysis: how a log samples the motion (`Sampling`), dense time series versus
//! seek logs, and the deadband it implies.

use super::DirectionTracker;

/// How a log samples the motion, and how its direction of motion is read (`biasctl check`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampling {
    /// Rows per second (rows − 1 over the time span); `None` for a log without a time span.
    pub rows_per_s: Option<f64>,
    /// Median |position step| between consecutive rows, position unit.
    pub median_step: f64,
    /// The travel: 5–95 % quantile range of the positions, position unit.
    pub travel: f64,
    /// Position noise estimate, position unit: 1.4826·MAD(Δ²x)/√6 (the spread of the second
    /// difference, which removes a smooth motion; white noise of std σ gives σ).
    pub noise: f64,
    /// Whether the rows come on a regular clock: the median |Δt − median Δt| is at most 1 % of
    /// the median Δt (a sampled signal; a seek log's dwells vary).
    pub regular_clock: bool,
    /// Whether the log is a dense time series (on a regular clock, with the median step below
    /// 1 % of the travel) rather than a log of seeks.
    pub dense: bool,
    /// The deadband [`sampling`] estimates: 2·√(2 ln n) × the noise for a dense log of n rows, else 0.
    pub deadband: f64,
    /// Direction reversals from the raw sign of each step.
    pub raw_reversals: usize,
    /// Direction reversals with the deadband.
    pub reversals: usize,
}

/// Describes how `positions` (in row order, position unit) sample the motion; `times_s` are the
/// rows' times. A seek log (each row a seek: irregular times, or a median step ≥ 1 % of the
/// travel) keeps deadband 0.
///
/// The times' quantiles, the median step and the raw reversal count run beside the positions'
/// quantiles (`rayon::join`, each side with its own scratch buffer), and the 5 % and 95 % quantiles of
/// the positions come from one nested selection (`numeric::stats::percentiles_select`): the same bits as
/// the one-buffer, one-quantile-at-a-time `sampling_reference` (tested), on any thread count.
pub fn sampling(times_s: &[f64], positions: &[f64]) -> Sampling {
    use crate::numeric::stats::{percentile_select, percentiles_select};
    // Every quantile is found by selection in a scratch buffer (O(n), no sort); it equals
    // `percentile_sorted(&sorted(v), p)` bit for bit (tested against it).
    let median = |scratch: &mut Vec<f64>, values: &mut dyn Iterator<Item = f64>| {
        scratch.clear();
        scratch.extend(values);
        percentile_select(scratch, 50.0).unwrap_or(0.0)
    };
    // The times' side also finds the median step (three selections and a pass each side,
    // about: the positions' quantiles are two selections nested in one).
    let times_side = || {
        let mut scratch = Vec::with_capacity(times_s.len().max(positions.len()));
        let dt = median(&mut scratch, &mut times_s.windows(2).map(|w| w[1] - w[0]));
        let dt_dev = median(
            &mut scratch,
            &mut times_s.windows(2).map(|w| ((w[1] - w[0]) - dt).abs()),
        );
        let median_step = median(
            &mut scratch,
            &mut positions.windows(2).map(|w| (w[1] - w[0]).abs()),
        );
        (dt, dt_dev, median_step, count_reversals(positions, 0.0))
    };
    let positions_side = || {
        let mut scratch = Vec::with_capacity(positions.len());
        scratch.extend_from_slice(positions);
        let (p95, p5) = match percentiles_select(&mut scratch, &[95.0, 5.0]) {
            Some(q) => (q[0], q[1]),
            None => (0.0, 0.0),
        };
        let mad = median(
            &mut scratch,
            &mut positions
                .windows(3)
                .map(|w| second_difference(w[0], w[1], w[2])),
        );
        (p95, p5, mad)
    };
    let ((dt, dt_dev, median_step, raw), (p95, p5, mad)) = rayon::join(times_side, positions_side);
    let q = Quantiles {
        regular_clock: regular_clock(dt, dt_dev),
        median_step,
        p95,
        p5,
        mad,
    };
    let span = match (times_s.first(), times_s.last()) {
        (Some(a), Some(b)) if b > a => Some(b - a),
        _ => None,
    };
    q.sampling(positions.len(), span, raw, |d| {
        count_reversals(positions, d)
    })
}

/// Direction reversals of `positions` with deadband `d` ([`DirectionTracker`]).
fn count_reversals(positions: &[f64], d: f64) -> usize {
    let mut t = DirectionTracker::new(d);
    positions
        .iter()
        .filter(|&&x| {
            let s = t.peek(x, None);
            t.commit(x, &s);
            s.reversal
        })
        .count()
}

/// The slow, obvious [`sampling`]: one scratch buffer, every quantile selected on its own in
/// turn, on one thread. The reference the parallel, nested one is tested against.
#[cfg(test)]
pub(crate) fn sampling_reference(times_s: &[f64], positions: &[f64]) -> Sampling {
    // Every quantile is found by selection in one reused scratch buffer (O(n), no sort); it
    // equals `percentile_sorted(&sorted(v), p)` bit for bit (tested against it).
    let mut scratch: Vec<f64> = Vec::with_capacity(positions.len().max(times_s.len()));
    let mut quantile = |values: &mut dyn Iterator<Item = f64>, p: f64| {
        scratch.clear();
        scratch.extend(values);
        crate::numeric::stats::percentile_select(&mut scratch, p).unwrap_or(0.0)
    };
    let dt = quantile(&mut times_s.windows(2).map(|w| w[1] - w[0]), 50.0);
    let dt_dev = quantile(
        &mut times_s.windows(2).map(|w| ((w[1] - w[0]) - dt).abs()),
        50.0,
    );
    let q = Quantiles {
        regular_clock: regular_clock(dt, dt_dev),
        median_step: quantile(&mut positions.windows(2).map(|w| (w[1] - w[0]).abs()), 50.0),
        p95: quantile(&mut positions.iter().copied(), 95.0),
        p5: quantile(&mut positions.iter().copied(), 5.0),
        mad: quantile(
            &mut positions
                .windows(3)
                .map(|w| second_difference(w[0], w[1], w[2])),
            50.0,
        ),
    };
    let span = match (times_s.first(), times_s.last()) {
        (Some(a), Some(b)) if b > a => Some(b - a),
        _ => None,
    };
    q.sampling(
        positions.len(),
        span,
        count_reversals(positions, 0.0),
        |d| count_reversals(positions, d),
    )
}

/// |x₂ − 2x₁ + x₀|, the second difference [`Sampling::noise`] is estimated from.
pub(super) fn second_difference(x0: f64, x1: f64, x2: f64) -> f64 {
    (x2 - 2.0 * x1 + x0).abs()
}

/// Whether rows whose median Δt is `dt` and median |Δt − median Δt| is `dt_dev` come on a
/// regular clock ([`Sampling::regular_clock`]).
pub(super) fn regular_clock(dt: f64, dt_dev: f64) -> bool {
    dt > 0.0 && dt_dev <= CLOCK_TOLERANCE * dt
}

/// How far (relative) the median |Δt − median Δt| may stray for a regular clock.
pub(super) const CLOCK_TOLERANCE: f64 = 0.01;

/// The quantiles [`sampling`] is made of: whether the clock is regular (from the median Δt and
/// the median |Δt − median Δt|); the median |position step|; the 95 % and 5 % quantiles of the
/// positions; the median |Δ²x|.
pub(super) struct Quantiles {
    pub(super) regular_clock: bool,
    pub(super) median_step: f64,
    pub(super) p95: f64,
    pub(super) p5: f64,
    pub(super) mad: f64,
}

impl Quantiles {
    /// The position noise estimate (see [`Sampling::noise`]).
    fn noise(&self) -> f64 {
        1.4826 * self.mad / 6f64.sqrt()
    }

    /// The deadband of a dense log of `rows` rows: the range i.i.d. noise spans over n samples
    /// (twice its expected maximum, √(2 ln n)·σ); a smaller band lets two opposite noise
    /// extremes fake a reversal somewhere in a long log.
    pub(super) fn dense_deadband(&self, rows: usize) -> f64 {
        let n = rows.max(2) as f64;
        2.0 * (2.0 * n.ln()).sqrt() * self.noise()
    }

    /// The [`Sampling`] of a log of `rows` rows over time `span` (s) with `raw_reversals`;
    /// `count` counts the reversals with a deadband.
    pub(super) fn sampling(
        &self,
        rows: usize,
        span: Option<f64>,
        raw_reversals: usize,
        count: impl FnOnce(f64) -> usize,
    ) -> Sampling {
        let regular_clock = self.regular_clock;
        let travel = self.p95 - self.p5;
        let dense = regular_clock && travel > 0.0 && self.median_step < 0.01 * travel;
        let deadband = if dense {
            self.dense_deadband(rows)
        } else {
            0.0
        };
        Sampling {
            rows_per_s: span.map(|s| (rows.saturating_sub(1)) as f64 / s),
            median_step: self.median_step,
            travel,
            noise: self.noise(),
            regular_clock,
            dense,
            deadband,
            raw_reversals,
            // With no deadband (every seek log) the count is the raw one: one pass, not two.
            reversals: if deadband == 0.0 {
                raw_reversals
            } else {
                count(deadband)
            },
        }
    }
}

/// [`sampling`] of every row of `log` (its time and position columns, read in place).
pub fn log_sampling(log: &crate::log::Log) -> Sampling {
    sampling(log.times(), log.tracks())
}

impl Sampling {
    /// Plain-language lines for `check`, positions in `unit`.
    pub fn describe(&self, unit: &str) -> Vec<String> {
        let g = |v: f64| format!("{v:.4e}");
        let mut out = vec![match self.rows_per_s {
            Some(r) => format!("sampling: {} rows/s", crate::log::fmt_trimmed(r, 3)),
            None => "sampling: no time span".into(),
        }];
        if self.dense {
            out.push(format!(
                "mode: dense time series (rows on a regular clock; the median step, {} {unit}, is below 1 % of the travel, {} {unit}); \
                 each row is one sample of a continuous motion, and the direction reverses only once the \
                 position has come back more than a deadband of {} {unit} (2·√(2 ln n) × the estimated position noise, {} {unit}) \
                 from its furthest point",
                g(self.median_step), g(self.travel), g(self.deadband), g(self.noise)
            ));
            out.push(format!(
                "reversals: {} with the deadband ({} from the raw sign of each step)",
                self.reversals, self.raw_reversals
            ));
            if self.raw_reversals > 3 * self.reversals.max(1) {
                out.push(format!(
                    "warning: the raw steps reverse {} times, {}× the {} reversals with the deadband: \
                     sensor noise fakes reversals when direction is read from raw steps",
                    self.raw_reversals,
                    self.raw_reversals / self.reversals.max(1),
                    self.reversals
                ));
            }
        } else {
            let why = if self.travel <= 0.0 {
                "every row is at the same position: no motion to read a direction from".to_string()
            } else if self.regular_clock {
                format!(
                    "the median step, {} {unit}, is at least 1 % of the travel, {} {unit}",
                    g(self.median_step),
                    g(self.travel)
                )
            } else {
                "the rows come at irregular times".to_string()
            };
            out.push(format!(
                "mode: seek log ({why}); each row is one seek and its direction is the sign of \
                 the move (no deadband)"
            ));
            out.push(format!("reversals: {}", self.raw_reversals));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::float_cmp)] // positions are exact integers here; equality is meant

    use super::*;
    use crate::numeric::rng::SimRng;

    /// A log whose every row is at one position says so in `check`'s mode line, instead of
    /// comparing a zero median step with a zero travel.
    #[test]
    fn a_constant_position_log_is_described_as_such() {
        let text = "time_s,track,bias\n0,5,1\n1,5,2\n2,5,3\n3,5,2\n";
        let log =
            crate::log::Log::from_reader("c.csv", text.as_bytes(), &Default::default()).unwrap();
        let lines = log_sampling(&log).describe("tracks");
        let mode = lines.iter().find(|l| l.starts_with("mode:")).unwrap();
        assert!(mode.contains("every row is at the same position"), "{mode}");
        assert!(!mode.contains("1 % of the travel"), "{mode}");
    }

    /// Reference: sort a copy, then `percentile_sorted` (what `sampling` did before it selected).
    #[test]
    fn selected_percentiles_equal_sorted_ones_bit_for_bit() {
        use crate::numeric::stats::{percentile_select, percentile_sorted, sorted};
        let mut rng = SimRng::new(7);
        for case in 0..300 {
            let n = 1 + rng.below(200) as usize;
            // Few distinct values (ties), signed zeros, and wide spreads.
            let v: Vec<f64> = (0..n)
                .map(|_| match case % 3 {
                    0 => rng.below(5) as f64 - 2.0,
                    1 => [0.0, -0.0, 1.5, -1.5][rng.below(4) as usize],
                    _ => rng.normal() * 10f64.powi(rng.below(20) as i32 - 10),
                })
                .collect();
            for p in [0.0, 5.0, 37.5, 50.0, 95.0, 100.0] {
                let want = percentile_sorted(&sorted(&v), p).unwrap();
                let got = percentile_select(&mut v.clone(), p).unwrap();
                assert_eq!(got.to_bits(), want.to_bits(), "case {case}, p {p}, n {n}");
            }
        }
        assert_eq!(percentile_select(&mut [], 50.0), None);
    }

    /// Reference: [`sampling_reference`] (one buffer, each quantile selected alone, one
    /// thread). The parallel sampling with the nested 5/95 % selection gives the same
    /// `Sampling`, every float bit for bit, on dense sine logs (the deadband count runs), seek
    /// logs, ties and signed zeros, jittered clocks and logs of 0–3 rows, on 1 and 2 threads.
    #[test]
    fn parallel_sampling_equals_the_reference_bit_for_bit() {
        let mut rng = SimRng::new(29);
        let bits = |s: &Sampling| {
            (
                s.rows_per_s.map(f64::to_bits),
                [s.median_step, s.travel, s.noise, s.deadband].map(f64::to_bits),
                (s.regular_clock, s.dense, s.raw_reversals, s.reversals),
            )
        };
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let mut dense = 0;
        for case in 0..120 {
            let n = match case % 8 {
                0 => rng.below(4) as usize,
                1 => 30_000,
                _ => 1 + rng.below(4000) as usize,
            };
            let dt = [1e-3, 0.01, 0.5][rng.below(3) as usize];
            let (t, x): (Vec<f64>, Vec<f64>) = (0..n)
                .map(|i| {
                    let ti = i as f64 * dt;
                    match case % 5 {
                        0 | 1 => (ti, 100.0 * (0.002 * i as f64).sin() + 0.05 * rng.normal()),
                        2 => (
                            ti + rng.range(0.0, 0.9) * dt,
                            [0.0, -0.0, -3.0, 7.5][rng.below(4) as usize],
                        ),
                        3 => (
                            ti + rng.range(-0.01, 0.01) * dt,
                            rng.range(-500.0, 500.0).round(),
                        ),
                        _ => (ti, rng.below(1001) as f64 * 0.37),
                    }
                })
                .unzip();
            let want = sampling_reference(&t, &x);
            dense += usize::from(want.dense && want.deadband > 0.0);
            assert_eq!(bits(&sampling(&t, &x)), bits(&want), "case {case}, n {n}");
            assert_eq!(bits(&one.install(|| sampling(&t, &x))), bits(&want));
        }
        assert!(dense > 10, "the deadband count ran on {dense} logs");
    }
}

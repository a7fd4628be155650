//! `lag:NAME`: bias linear in a covariate column passed through a first-order lag: a
//! logged temperature often leads its effect (the sensor sits on the case, the effect is
//! in the pivot), so the bias follows `z` with `τ·dz/dt = c(t) − z`.
//!
//! Between two rows the covariate is taken as linear in time (first-order hold), for which the
//! lag has the exact update, with `a = exp(−Δt/τ)`:
//! `z_k = c_k + (z_{k−1} − c_{k−1})·a − (c_k − c_{k−1})·(τ/Δt)·(1 − a)`;
//! `z` starts at the first row's value (the covariate at rest), and a row at the same time as
//! the previous one leaves `z` unchanged. Every row, measured or not, advances the lag.
//!
//! The basis is `(z − centre)/scale` with the column's training mean and std (as `col:`); the
//! reported `slope` is in counts per unit of the column, and `tau` in s. `τ` is the term's
//! nonlinear parameter, searched by variable projection on `ln τ` over
//! `[median Δt / 2, time span]` of the training log (its own sampling and length, never an
//! absolute unit). As τ → 0 the term becomes `col:NAME`.

use super::covariate::ColTerm;
pub use super::lag_filter::{FirstOrderLag, LagStage};
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Term, TermSpec};
use crate::numeric::stats::percentile_select;
use std::sync::Arc;

/// The head of the term's spec text (`lag`).
pub(crate) const HEAD: &str = "lag";

/// Spec of the `lag:NAME` term.
#[derive(Debug, Clone)]
pub struct LagSpec {
    /// The covariate column.
    pub column: String,
}

impl TermSpec for LagSpec {
    fn name(&self) -> String {
        format!("lag:{}", self.column)
    }
    /// The `col:NAME` term with a lag stage whose `ln τ` search interval is
    /// `[ln(median Δt / 2), ln(time span)]` of the training log, starting at its middle.
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let mut term = ColTerm::prepare(data, &self.column, &self.name())?;
        let times = data.log().times();
        let mut steps: Vec<f64> = times
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 0.0)
            .collect();
        let span = times.last().map_or(0.0, |t| *t) - times.first().map_or(0.0, |t| *t);
        // The median by selection (O(n), the same bits as sorting: `percentile_select`).
        let median = percentile_select(&mut steps, 50.0).unwrap_or(0.0);
        if !(median > 0.0 && span > median) {
            return Err(FitError::BadSetting {
                term: self.name(),
                why: "the log's time never advances (or only once), so no lag can be fitted".into(),
            });
        }
        let (lo, hi) = ((0.5 * median).ln(), span.ln());
        term.lag = Some(LagStage {
            tau: (0.5 * (lo + hi)).exp(),
            ln_lo: lo,
            ln_hi: hi,
        });
        Ok(Arc::new(term))
    }
}

/// Restores a saved `lag:NAME` term (a [`ColTerm`] whose settings hold `tau`, `ln_lo` and
/// `ln_hi`); registry entry.
pub(crate) fn restore(
    name: &str,
    settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    let t: ColTerm = serde_json::from_value(settings.clone()).map_err(|e| ModelError::BadTerm {
        term: name.to_string(),
        why: e.to_string(),
    })?;
    if t.lag.is_none() {
        return Err(ModelError::BadTerm {
            term: name.to_string(),
            why: "a `lag` term needs `tau`, `ln_lo` and `ln_hi`".into(),
        });
    }
    Ok(Arc::new(t))
}

/// Parses `lag:NAME`; the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    match t.arg {
        Some(name) if !name.is_empty() => Ok(Arc::new(LagSpec {
            column: name.to_string(),
        })),
        _ => Err(t.bad("`lag` needs a column name: `lag:NAME`".into())),
    }
}

/// The patterns `lag:NAME` answers: a lagged covariate (first), and any even covariate
/// effect last (a logged temperature often leads its effect).
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Covariate(_, false) => Answer::named_if_parses(9),
        Cue::Lagged => Answer::named(0),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the closed form of a first-order lag driven by a ramp from rest,
    /// `z(t) = t − τ·(1 − e^{−t/τ})` for `c(t) = t`, and a step response sampled after it.
    /// The first-order hold is exact for a ramp whatever the (irregular) sampling.
    #[test]
    fn ramp_is_exact_at_irregular_samples() {
        let tau = 2.5;
        let mut lag = FirstOrderLag::new(tau);
        let mut t = 0.0;
        lag.step(0.0, 0.0);
        for k in 1..200 {
            t += 0.01 + 0.37 * ((k * 7919) % 11) as f64 / 11.0;
            let z = lag.step(t, t);
            let exact = t - tau * (1.0 - (-t / tau).exp());
            assert!(
                (z - exact).abs() < 1e-9 * (1.0 + t),
                "t {t}: {z} vs {exact}"
            );
        }
    }

    /// Reference: Euler integration of τ·dz/dt = c − z with 10⁵ sub-steps per sample, for an
    /// input linear between samples (a sine sampled irregularly).
    #[test]
    fn matches_fine_euler_integration() {
        let tau = 0.8;
        let c = |t: f64| (1.3 * t).sin() + 0.2 * t;
        let mut lag = FirstOrderLag::new(tau);
        let (mut t0, mut z) = (0.0, c(0.0));
        lag.step(0.0, c(0.0));
        for k in 1..30 {
            let t1 = t0 + 0.05 + 0.3 * ((k * 31) % 7) as f64 / 7.0;
            let sub = 100_000;
            let h = (t1 - t0) / sub as f64;
            for j in 0..sub {
                let s = t0 + (j as f64 + 0.5) * h;
                let u = c(t0) + (c(t1) - c(t0)) * (s - t0) / (t1 - t0);
                z += h * (u - z) / tau;
            }
            let fast = lag.step(t1, c(t1));
            assert!((fast - z).abs() < 1e-5, "k {k}: {fast} vs {z}");
            t0 = t1;
        }
        // Peek does not change the state; a repeated time leaves the output where it was.
        let before = lag.peek(t0 + 1.0, 3.0);
        assert!((lag.peek(t0 + 1.0, 3.0) - before).abs() <= 0.0);
        assert!((lag.peek(t0, 99.0) - z).abs() < 1e-5);
    }

    /// Reference: [`FirstOrderLag::peek_reference`] (both factors computed at every sample).
    /// The memoised path must give the same bits on a regularly clocked log (times `k·0.3`,
    /// whose steps differ in their last bits), on an irregular one, with repeated times, and
    /// with more distinct steps than memo slots (collisions overwrite, never mix up).
    #[test]
    fn memoised_steps_are_bit_identical_to_the_reference() {
        let clocks: [&dyn Fn(usize) -> f64; 3] = [
            &|k| 0.3 * k as f64,
            &|k| (k as f64).powf(1.3) + 0.001 * ((k * 7919) % 13) as f64,
            &|k| 0.25 * (k / 3) as f64 + 0.07 * ((k * 31) % 29) as f64 * (k % 2) as f64,
        ];
        for (ci, clock) in clocks.iter().enumerate() {
            for tau in [1e-9, 0.05, 2.5, 1e7] {
                let mut fast = FirstOrderLag::new(tau);
                let mut slow = FirstOrderLag::new(tau);
                let mut t_prev = f64::NEG_INFINITY;
                for k in 0..2000 {
                    let t = clock(k).max(t_prev);
                    t_prev = t;
                    let c = (0.37 * k as f64).sin() * 3.0 + 40.0;
                    // A model peeks (basis), then steps (update) the same sample.
                    let p = fast.peek(t, c);
                    let r = slow.peek_reference(t, c);
                    assert_eq!(p.to_bits(), r.to_bits(), "clock {ci} tau {tau} k {k}");
                    let z = fast.step(t, c);
                    assert_eq!(z.to_bits(), r.to_bits(), "clock {ci} tau {tau} k {k}");
                    slow.last = Some((t, c, r));
                }
            }
        }
    }

    /// The `lag:` term's search basis reads the log's columns directly
    /// ([`super::super::lag_filter::LagSearch`]). Reference: the default per-row replay of the
    /// term's state (`PerRowSearch`: `basis` then `update` through the history replay). Every
    /// value bit for bit, at τ across and beyond the search interval, on a log with irregular
    /// and repeated times, unmeasured rows (they advance the lag) and a second covariate
    /// before the lagged one.
    #[test]
    fn lag_search_basis_equals_the_per_row_replay() {
        use crate::model::term::{PerRowSearch, SearchBasis};
        let mut rng = crate::numeric::rng::SimRng::new(9);
        let mut text = String::from("time_s,track,bias,other,temp\n");
        let (mut t, mut temp) = (0.0f64, 40.0f64);
        for k in 0..3000 {
            if k % 7 != 3 {
                t += rng.range(0.01, 3.0);
            }
            temp += 0.1 * rng.normal();
            let x = rng.below(300);
            let bias = 0.5 * temp + rng.normal();
            let other = rng.normal();
            text += &format!("{t:?},{x},{bias:?},{other:?},{temp:?}\n");
        }
        let mut log =
            crate::log::Log::from_reader("lag.csv", text.as_bytes(), &Default::default()).unwrap();
        for i in (5..log.len()).step_by(4) {
            log.set_bias(i, None);
        }
        let data = FitData::new(&log);
        let spec = LagSpec {
            column: "temp".into(),
        };
        let term = spec.prepare(&data).unwrap();
        let nl = term.nonlinear().unwrap();
        let values: Vec<f64> = (0..8)
            .map(|i| nl.lo - 1.0 + (nl.hi - nl.lo + 2.0) * f64::from(i) / 7.0)
            .collect();
        let collect = |basis: &dyn SearchBasis| {
            let mut out = Vec::new();
            let mut rows = 0;
            basis
                .replay(&values, &mut |block, n| {
                    out.extend(block[..n * values.len()].iter().map(|v| v.to_bits()));
                    rows += n;
                })
                .unwrap();
            (rows, out)
        };
        let fast = collect(&*term.search_basis(&data));
        let slow = collect(&PerRowSearch {
            term: &*term,
            data: &data,
        });
        assert_eq!(fast.0, log.measured_count());
        assert_eq!(fast, slow);
    }

    /// Reference: the sorted copy and `percentile_sorted(…, 50)`, bit for bit, on odd and even
    /// lengths, ties and a single value.
    #[test]
    fn median_by_selection_equals_the_sorted_median() {
        let mut rng = crate::numeric::rng::SimRng::new(3);
        for n in [1usize, 2, 3, 10, 11, 1000, 1001] {
            for ties in [false, true] {
                let x: Vec<f64> = (0..n)
                    .map(|_| {
                        let v = rng.range(0.0, 1.0);
                        if ties { (v * 4.0).floor() * 0.3 } else { v }
                    })
                    .collect();
                let sorted = crate::numeric::stats::sorted(&x);
                let want = crate::numeric::stats::percentile_sorted(&sorted, 50.0);
                let got = percentile_select(&mut x.clone(), 50.0);
                assert_eq!(got.map(f64::to_bits), want.map(f64::to_bits), "n {n}");
            }
        }
        assert!(percentile_select(&mut [], 50.0).is_none());
    }
}

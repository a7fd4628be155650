//! The first-order lag `τ·dz/dt = c − z` of a sampled covariate ([`FirstOrderLag`], exact
//! between samples under a first-order hold; the update is derived in `lag.rs`'s docs) and the
//! lag stage a fitted `lag:NAME` term stores ([`LagStage`]). Shared by `col:`/`lag:` terms
//! and the diagnosis's lagged features.

use crate::model::data::FitData;
use crate::model::term::SearchBasis;
use serde::{Deserialize, Serialize};
use std::cell::Cell;

/// The lag stage of a fitted `lag:NAME` term ([`ColTerm::lag`](super::covariate::ColTerm::lag)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LagStage {
    /// Time constant τ of the lag, s.
    pub tau: f64,
    /// Lower end of the `ln τ` search interval.
    pub ln_lo: f64,
    /// Upper end of the `ln τ` search interval.
    pub ln_hi: f64,
}

/// A first-order lag `τ·dz/dt = c − z` of a sampled signal, linear between samples (exact
/// update, see the module docs). Public so diagnosis features and benches can use it.
///
/// The update's two factors `a = exp(−Δt/τ)` and `(1 − a)·τ/Δt` depend only on the step Δt:
/// they are memoised per Δt (a small direct-mapped table keyed by Δt's exact bits), so a
/// regularly clocked log — a few distinct Δt however its times round — evaluates the two
/// transcendentals a handful of times instead of twice per row, and a `peek` followed by the
/// `step` of the same sample (a model's basis, then its update) computes them once. The memo
/// returns the very values it stored, so results are bit-identical to computing every time
/// ([`FirstOrderLag::peek_reference`] is that slow path, tested against it).
#[derive(Debug, Clone)]
pub struct FirstOrderLag {
    pub(super) tau: f64,
    /// `(time, input, output)` at the last sample.
    pub(super) last: Option<(f64, f64, f64)>,
    /// `(Δt bits, a, (1 − a)/r)` per slot; a key of 0 (Δt = 0, never looked up) is empty.
    pub(super) memo: [Cell<(u64, f64, f64)>; MEMO_SLOTS],
}

/// Slots of [`FirstOrderLag`]'s memo of decay factors: `2^MEMO_BITS`, enough for the 18
/// distinct steps the times `k·0.3` s of 100,000 rows round to.
const MEMO_BITS: u32 = 6;
/// See [`MEMO_BITS`].
const MEMO_SLOTS: usize = 1 << MEMO_BITS;

/// The decay factors of one step `dt > 0` with time constant `tau`: `a = exp(−r)` and
/// `(1 − a)/r`, `r = dt/τ` (the latter accurate for small r).
#[inline]
fn decay(dt: f64, tau: f64) -> (f64, f64) {
    let r = dt / tau;
    let a = (-r).exp();
    let g = if r < 1e-6 {
        1.0 - 0.5 * r
    } else {
        -(-r).exp_m1() / r
    };
    (a, g)
}

impl FirstOrderLag {
    /// A lag with time constant `tau` (s, > 0) before its first sample.
    pub fn new(tau: f64) -> Self {
        Self {
            tau,
            last: None,
            memo: std::array::from_fn(|_| Cell::new((0, 0.0, 0.0))),
        }
    }

    /// [`decay`] of `dt > 0`, from the memo or computed and remembered.
    #[inline]
    fn factors(&self, dt: f64) -> (f64, f64) {
        let key = dt.to_bits();
        // Fibonacci hashing: the top bits of key·φ mix in the low mantissa bits, where the steps
        // of one clock differ.
        let slot =
            &self.memo[(key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - MEMO_BITS)) as usize];
        let (k, a, g) = slot.get();
        if k == key {
            return (a, g);
        }
        let (a, g) = decay(dt, self.tau);
        slot.set((key, a, g));
        (a, g)
    }

    /// The output at a sample `(t, c)` following the last one, without changing the state
    /// (only the memo of decay factors).
    #[inline]
    pub fn peek(&self, t: f64, c: f64) -> f64 {
        match self.last {
            None => c,
            Some((t0, c0, z0)) => {
                let dt = t - t0;
                if dt > 0.0 {
                    let (a, g) = self.factors(dt);
                    c + (z0 - c0) * a - (c - c0) * g
                } else {
                    z0
                }
            }
        }
    }

    /// [`FirstOrderLag::peek`] computing both factors every time, without the memo (the slow,
    /// obvious reference the memoised path is tested against, bit for bit).
    pub fn peek_reference(&self, t: f64, c: f64) -> f64 {
        match self.last {
            None => c,
            Some((t0, c0, z0)) => {
                let dt = t - t0;
                if dt > 0.0 {
                    let (a, g) = decay(dt, self.tau);
                    c + (z0 - c0) * a - (c - c0) * g
                } else {
                    z0
                }
            }
        }
    }

    /// Takes the sample `(t, c)` and returns the output.
    #[inline]
    pub fn step(&mut self, t: f64, c: f64) -> f64 {
        let z = self.peek(t, c);
        self.last = Some((t, c, z));
        z
    }
}

/// Measured rows per block [`LagSearch`] hands its sink.
const SEARCH_BLOCK: usize = 256;

/// The search basis of a `lag:NAME` term's τ ([`SearchBasis`]): the column passed through the
/// lag at each searched value, read from the log's time and covariate columns directly — no
/// replay of the history, no dynamic call per row and value. The same values, bit for bit, as
/// the term's state gives row by row (its `basis` peeks the lag, its `update` steps it: one
/// computation from the same state; tested against the per-row replay).
#[derive(Debug)]
pub(crate) struct LagSearch<'d> {
    /// The training data.
    pub(crate) data: &'d FitData<'d>,
    /// The covariate's index among the log's covariates.
    pub(crate) column: usize,
    /// The centre and scale of the basis `(z − centre)/scale`.
    pub(crate) centre: f64,
    pub(crate) scale: f64,
    /// The lag stage whose `ln τ` is searched.
    pub(crate) stage: LagStage,
}

impl SearchBasis for LagSearch<'_> {
    fn replay(&self, values: &[f64], sink: &mut dyn FnMut(&[f64], usize)) -> Option<()> {
        let log = self.data.log();
        let (times, column, bias) = (log.times(), log.covariate(self.column), log.bias_raw());
        let (lo, hi) = (self.stage.ln_lo, self.stage.ln_hi);
        // τ as the term's `with_nonlinear` sets it.
        let mut lags: Vec<FirstOrderLag> = values
            .iter()
            .map(|v| FirstOrderLag::new(v.clamp(lo, hi).exp()))
            .collect();
        let n = values.len();
        let mut block = vec![0.0; SEARCH_BLOCK * n];
        let mut rows = 0;
        for ((&t, &c), &b) in times.iter().zip(column).zip(bias) {
            if b.is_nan() {
                for lag in &mut lags {
                    lag.step(t, c);
                }
                continue;
            }
            let out = &mut block[rows * n..(rows + 1) * n];
            for (o, lag) in out.iter_mut().zip(&mut lags) {
                *o = (lag.step(t, c) - self.centre) / self.scale;
            }
            rows += 1;
            if rows == SEARCH_BLOCK {
                sink(&block, rows);
                rows = 0;
            }
        }
        if rows > 0 {
            sink(&block[..rows * n], rows);
        }
        Some(())
    }
}

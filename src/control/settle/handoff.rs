//! The loop's state at the seek → track-following handoff and what the handoff computation
//! finds: the interval of start values that settles by a sample, and the solution.

use serde::Serialize;

/// The loop's state at handoff (the seek controller's last values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Handoff {
    /// Position error e0 = y − r in µm.
    pub e0_um: f64,
    /// Velocity v0 in µm/s.
    pub v0_um_s: f64,
    /// The control applied during the first τ of the first period, in counts.
    pub u_prev_counts: f64,
    /// The (predicted) bias d in counts.
    pub bias_counts: f64,
}

/// An interval of start values (µm·samples, relative to the converged integrator value) that
/// settles by sample `k`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    /// Settle index reached by every start value in [lo, hi].
    pub k: usize,
    /// Lower bound L*(k) (may be −∞).
    pub lo: f64,
    /// Upper bound U*(k) (may be +∞).
    pub hi: f64,
}

impl Interval {
    /// The start value at least `margin` inside both ends: the midpoint when both ends are
    /// finite, otherwise the value closest to zero feedforward (0) that keeps the margin.
    #[inline]
    pub fn choice(&self, margin: f64) -> f64 {
        if self.lo.is_finite() && self.hi.is_finite() {
            0.5 * (self.lo + self.hi)
        } else {
            let lo = self.lo + margin;
            let hi = self.hi - margin;
            if lo > hi {
                0.5 * (lo + hi)
            } else {
                0.0f64.clamp(lo, hi)
            }
        }
    }
}

/// What the handoff fast path finds (start values relative to the converged value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandoffSolution {
    /// The minimum settle index k* and the optimal interval; `None` if nothing settles.
    pub optimal: Option<Interval>,
    /// The first interval at least 2s wide (s = |∂z/∂d|·Δb); its [`Interval::choice`] with
    /// margin s (the midpoint when both ends are finite) is the robust choice and `k` its
    /// worst-case settle index.
    pub robust: Option<Interval>,
    /// Worst-case settle index of zero feedforward for the true start in [−s, s].
    pub zero_ff_worst: Option<usize>,
    /// s = |∂z/∂d|·Δb in µm·samples.
    pub shift: f64,
}

//! The bounds curves of one handoff (Fig. 15): per-sample bounds, their backward running
//! min/max, and the settle index, optimal interval and paper's robust choice read from them.

use super::Interval;
use super::kernels::suffix_into;

/// The bounds curves of one handoff (Fig. 15), start values in µm·samples relative to the
/// converged value. Make once per horizon with [`Bounds::new`] and refill with
/// [`HandoffTable::bounds_into`](super::HandoffTable::bounds_into).
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    pub(super) upper: Vec<f64>,
    pub(super) lower: Vec<f64>,
    pub(super) upper_min: Vec<f64>,
    pub(super) lower_max: Vec<f64>,
    pub(super) hold: usize,
}

impl Bounds {
    /// Buffers for a horizon of `n` samples.
    pub fn new(n: usize) -> Self {
        Self {
            upper: vec![f64::INFINITY; n],
            lower: vec![f64::NEG_INFINITY; n],
            upper_min: vec![f64::INFINITY; n],
            lower_max: vec![f64::NEG_INFINITY; n],
            hold: 1,
        }
    }
    /// Per-sample upper bounds U_k.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }
    /// Per-sample lower bounds L_k.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    /// Backward running minimum U*(k) = min_{j ≥ k} U_j.
    pub fn upper_min(&self) -> &[f64] {
        &self.upper_min
    }
    /// Backward running maximum L*(k) = max_{j ≥ k} L_j.
    pub fn lower_max(&self) -> &[f64] {
        &self.lower_max
    }

    /// Running bounds of samples `lo .. hi` from their bounds and the running bounds `run` =
    /// (U*, L*) of the samples from `hi` on; returns (U*(lo), L*(lo)).
    #[inline(always)]
    pub(super) fn running_block(&mut self, lo: usize, hi: usize, run: (f64, f64)) -> (f64, f64) {
        suffix_into(
            &self.upper[lo..hi],
            &self.lower[lo..hi],
            &mut self.upper_min[lo..hi],
            &mut self.lower_max[lo..hi],
            run.0,
            run.1,
        );
        (self.upper_min[lo], self.lower_max[lo])
    }

    fn top(&self) -> Option<usize> {
        self.upper.len().checked_sub(self.hold)
    }

    /// The settle index of start value `zeta`: the first k ≤ N − M with L*(k) ≤ ζ ≤ U*(k).
    pub fn settle_index_of(&self, zeta: f64) -> Option<usize> {
        (0..=self.top()?).find(|&k| self.lower_max[k] <= zeta && zeta <= self.upper_min[k])
    }

    /// k* and the optimal interval (eq. 16), from the stored curves.
    ///
    /// U*(k) = min(U_k, U*(k + 1)) ≤ U*(k + 1) and L*(k) ≥ L*(k + 1) (neither is NaN: the
    /// running bounds leave a NaN bound out), so L*(k) ≤ U*(k) implies L*(k + 1) ≤ U*(k + 1):
    /// the condition holds on a suffix of k, and k* is found by bisection (tested against the
    /// sample-by-sample search).
    pub fn optimal(&self) -> Option<Interval> {
        let top = self.top()?;
        let (lo, hi) = (&self.lower_max[..=top], &self.upper_min[..=top]);
        let holds = |k: usize| lo[k] <= hi[k];
        // The last k not holding is in base .. base + size (base itself when none holds below).
        let (mut base, mut size) = (0, top + 1);
        while size > 1 {
            let half = size / 2;
            // Arithmetic, not a branch: which way the search goes is the data's coin flip.
            base += half * usize::from(!holds(base + half));
            size -= half;
        }
        let k = base + usize::from(!holds(base));
        (k <= top).then(|| Interval {
            k,
            lo: lo[k],
            hi: hi[k],
        })
    }

    /// The paper's robust choice: the first local minimum k of the per-sample upper bound U_k
    /// (finite neighbours, U_{k−1} > U_k ≤ U_{k+1}) and the average (U_k + L_k)/2 there.
    /// `None` when the curve has no such minimum.
    pub fn paper_robust(&self) -> Option<(usize, f64)> {
        let u = &self.upper;
        (1..u.len().saturating_sub(1))
            .find(|&k| {
                u[k - 1].is_finite()
                    && u[k].is_finite()
                    && u[k + 1].is_finite()
                    && u[k - 1] > u[k]
                    && u[k] <= u[k + 1]
            })
            .map(|k| (k, 0.5 * (u[k] + self.lower[k])))
    }
}

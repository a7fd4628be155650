//! `play:N`: a Prandtl–Ishlinskii / Maxwell-slip hysteresis model with N elements whose
//! thresholds span the log's reversal amplitudes — the generalised Dahl/Preisach family for
//! actuators whose loops are not one exponential (piezo stacks, magnetic reversal curves, ball
//! screws, seals).
//!
//! Element `i` is a stop operator (an elastic spring in series with a Coulomb slider) with
//! threshold `r_i` (the log's position unit): its play state follows
//! `z_k = clamp(z_{k−1}, x_k − r_i, x_k + r_i)` (`z_0 = x_0`, the log's first position), and its
//! basis value is the normalised spring deflection `(x_k − z_k)/r_i ∈ [−1, 1]`: +1 after a move
//! of at least `2·r_i` in the positive direction, −1 after one in the negative, linear in
//! between. The term's contribution is `Σ w_i·(x − z_i)/r_i` with signed weights `w_i` (the
//! slip force of element `i`, in the bias unit) fitted by the one least-squares solve. One element
//! with threshold r is a Dahl element whose exponential is replaced by a ramp of length 2r.
//!
//! Thresholds: geometric from a quarter of the 5 % quantile (or less, so that they span at least
//! [`MIN_SPAN`]) to half of the 95 % quantile of the training log's reversal amplitudes (`crate::history::reversal_amplitudes`: the distances
//! between consecutive turning points), so the elements cover the loops the log actually makes
//! whatever its position unit. Neighbouring elements are strongly collinear, so the weights are
//! ridge-regularised ([`Term::ridge`], penalty [`RIDGE`] × each column's sum of squares): the
//! fit stays within a fraction of a per cent of plain least squares while weights that would
//! cancel each other stay bounded. State O(N) per step, no allocation.

use crate::model::ModelError;
use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term, TermCaps, TermSpec, TermState};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Relative ridge penalty of the play weights: each weight is pulled towards 0 with a penalty of
/// `RIDGE·‖column‖²·w²` (scale free in both bias and position units).
pub const RIDGE: f64 = 1e-4;

/// Default number of elements of `play`.
pub const DEFAULT_ELEMENTS: usize = 8;

/// Lanes of the fast weighted sum: element `i` is added into accumulator `i mod LANES`, and the
/// lanes are summed as `(a₀ + a₁) + (a₂ + a₃)`. The same order on every CPU (the AVX2 copy runs
/// the four lanes in one register, the portable one in two), so results do not depend on the
/// machine; against the plain left-to-right sum they differ by rounding only (≤ 1e-12 × Σ|wᵢ·dᵢ|,
/// tested).
pub const LANES: usize = 4;

/// `z` clamped to `[lo, hi]` with two selects (vectorises, unlike `f64::clamp`, which checks its
/// bounds); bit-identical to `z.clamp(lo, hi)` for `lo ≤ hi` and no NaN.
#[inline(always)]
fn clamp_to(z: f64, lo: f64, hi: f64) -> f64 {
    let z = if z < lo { lo } else { z };
    if z > hi { hi } else { z }
}

/// Moves every stop to `x` and returns `Σ wᵢ·(x − zᵢ)/rᵢ` summed in [`LANES`] lanes.
#[inline(always)]
fn step_weighted_lanes(z: &mut [f64], r: &[f64], ir: &[f64], w: &[f64], x: f64) -> f64 {
    let mut acc = [0.0f64; LANES];
    let n = z.len().min(r.len()).min(ir.len()).min(w.len());
    let full = n / LANES * LANES;
    let (zh, zt) = z[..n].split_at_mut(full);
    for (((zc, rc), ic), wc) in zh
        .chunks_exact_mut(LANES)
        .zip(r[..full].chunks_exact(LANES))
        .zip(ir[..full].chunks_exact(LANES))
        .zip(w[..full].chunks_exact(LANES))
    {
        for j in 0..LANES {
            let v = clamp_to(zc[j], x - rc[j], x + rc[j]);
            zc[j] = v;
            acc[j] += wc[j] * (x - v) * ic[j];
        }
    }
    for (j, z) in zt.iter_mut().enumerate() {
        let i = full + j;
        let v = clamp_to(*z, x - r[i], x + r[i]);
        *z = v;
        acc[j] += w[i] * (x - v) * ir[i];
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// Moves every stop to `x`.
#[inline(always)]
fn step_lanes(z: &mut [f64], r: &[f64], x: f64) {
    for (z, &r) in z.iter_mut().zip(r) {
        *z = clamp_to(*z, x - r, x + r);
    }
}

/// The deflections `(x − clamp(zᵢ, x − rᵢ, x + rᵢ))/rᵢ` into `out`.
#[inline(always)]
fn peek_lanes(z: &[f64], r: &[f64], ir: &[f64], x: f64, out: &mut [f64]) {
    for (((o, &z), &r), &ir) in out.iter_mut().zip(z).zip(r).zip(ir) {
        *o = (x - clamp_to(z, x - r, x + r)) * ir;
    }
}

/// Whether this CPU runs the AVX2 copies of the play loops (same operations, four elements per
/// instruction).
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// AVX2 copies of the loops above (the same source compiled with AVX2 enabled; no FMA, so the
/// rounding is the portable copy's).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn step_weighted(
        z: &mut [f64],
        r: &[f64],
        ir: &[f64],
        w: &[f64],
        x: f64,
    ) -> f64 {
        super::step_weighted_lanes(z, r, ir, w, x)
    }

    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn step(z: &mut [f64], r: &[f64], x: f64) {
        super::step_lanes(z, r, x)
    }

    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn peek(z: &[f64], r: &[f64], ir: &[f64], x: f64, out: &mut [f64]) {
        super::peek_lanes(z, r, ir, x, out)
    }
}

/// N stop operators with fixed thresholds: the allocation-free state of `play:N`.
#[derive(Debug, Clone)]
pub struct PlayOperator {
    r: Box<[f64]>,
    inv_r: Box<[f64]>,
    z: Box<[f64]>,
    started: bool,
    avx2: bool,
}

impl PlayOperator {
    /// Operators with thresholds `r` (each > 0, position unit), relaxed at the first position.
    pub fn new(r: &[f64]) -> Self {
        Self {
            r: r.into(),
            inv_r: r.iter().map(|v| 1.0 / v).collect(),
            z: vec![0.0; r.len()].into(),
            started: false,
            avx2: has_avx2(),
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.r.len()
    }

    /// Whether there are no elements.
    pub fn is_empty(&self) -> bool {
        self.r.is_empty()
    }

    /// Writes the normalised deflections `(x − z_i)/r_i ∈ [−1, 1]` the operators would have at
    /// position `x` into `out`, without changing them.
    #[inline]
    pub fn peek_into(&self, x: f64, out: &mut [f64]) {
        if !self.started {
            out.fill(0.0);
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2.
            return unsafe { avx2::peek(&self.z, &self.r, &self.inv_r, x, out) };
        }
        peek_lanes(&self.z, &self.r, &self.inv_r, x, out)
    }

    /// Moves the operators to position `x`.
    #[inline]
    pub fn step(&mut self, x: f64) {
        if !self.started {
            self.z.fill(x);
            self.started = true;
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2.
            return unsafe { avx2::step(&mut self.z, &self.r, x) };
        }
        step_lanes(&mut self.z, &self.r, x)
    }

    /// Moves to `x` and returns `Σ w_i·(x − z_i)/r_i` (fused: one pass, no buffer; summed in
    /// [`LANES`] lanes). Elements beyond `w`'s length are not moved.
    #[inline]
    pub fn step_weighted(&mut self, x: f64, w: &[f64]) -> f64 {
        if !self.started {
            self.step(x);
            return 0.0;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2.
            return unsafe { avx2::step_weighted(&mut self.z, &self.r, &self.inv_r, w, x) };
        }
        step_weighted_lanes(&mut self.z, &self.r, &self.inv_r, w, x)
    }
}

/// A fitted `play:N` model as a concrete, allocation-free predictor: `bias = offset + Σ w_i·
/// (x − z_i)/r_i` (bias unit; `x` in the position unit). What firmware would run; the bench
/// `play` measures it.
#[derive(Debug, Clone)]
pub struct PlayPredictor {
    offset: f64,
    weights: Box<[f64]>,
    op: PlayOperator,
}

impl PlayPredictor {
    /// A predictor with thresholds `r` (position unit, each > 0), weights `w` (bias unit, same
    /// length) and a constant `offset` (bias unit); `None` if the lengths differ or a threshold
    /// is not a positive finite number.
    pub fn new(r: &[f64], w: &[f64], offset: f64) -> Option<Self> {
        (r.len() == w.len() && r.iter().all(|v| v.is_finite() && *v > 0.0)).then(|| Self {
            offset,
            weights: w.into(),
            op: PlayOperator::new(r),
        })
    }

    /// Moves to `x` and returns the predicted bias there.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        self.offset + self.op.step_weighted(x, &self.weights)
    }

    /// [`PlayPredictor::step`] over every position of `xs` in turn, the predictions appended to
    /// `out` (bit-identical to calling `step` for each; tested). Allocates nothing when `out`
    /// has room. (A copy of the whole loop compiled for AVX2 was tried and measured slower than
    /// the per-step dispatch, 48.6 vs 62.8 M steps/s of thread CPU time: not kept.)
    pub fn step_many(&mut self, xs: &[f64], out: &mut Vec<f64>) {
        out.reserve(xs.len());
        out.extend(xs.iter().map(|&x| self.step(x)));
    }
}

/// Spec of the `play:N` term.
#[derive(Debug, Clone, Copy)]
pub struct PlaySpec {
    /// Number of elements.
    pub elements: usize,
}

/// Least ratio of the largest to the smallest threshold: a log whose reversals all have about
/// the same amplitude (a damper driven over its full stroke) still gets elements whose loops
/// close within a small fraction of the stroke, as a Dahl or Bouc–Wen loop does.
pub const MIN_SPAN: f64 = 100.0;

/// Thresholds for `n` elements from reversal amplitudes `amps` (position unit): geometric from
/// a quarter of the 5 % quantile (at most the largest threshold / [`MIN_SPAN`]) to half the 95 %
/// quantile; `None` with fewer than two amplitudes.
pub fn thresholds(amps: &[f64], n: usize) -> Option<Vec<f64>> {
    let sorted = crate::numeric::stats::sorted(amps);
    if sorted.len() < 2 || n == 0 {
        return None;
    }
    let q = |p: f64| crate::numeric::stats::percentile_sorted(&sorted, p);
    let hi = 0.5 * q(95.0)?;
    let lo = (0.25 * q(5.0)?).min(hi / MIN_SPAN);
    if !(lo > 0.0 && hi.is_finite()) {
        return None;
    }
    Some(if n == 1 {
        vec![0.5 * q(50.0)?]
    } else {
        (0..n)
            .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
            .collect()
    })
}

impl TermSpec for PlaySpec {
    fn name(&self) -> String {
        format!("play:{}", self.elements)
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let amps = data.reversal_amplitudes();
        let thresholds = thresholds(&amps, self.elements).ok_or_else(|| FitError::BadSetting {
            term: self.name(),
            why: format!(
                "the log has {} direction reversals with a non-zero amplitude; play elements are \
                 placed on the reversal amplitudes and need at least two",
                amps.len()
            ),
        })?;
        Ok(Arc::new(PlayTerm {
            name: self.name(),
            thresholds,
        }))
    }
}

/// The fitted `play:N` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PlayTerm {
    /// Spec string.
    pub name: String,
    /// Thresholds r_i of the elements, increasing, in the log's position unit.
    pub thresholds: Vec<f64>,
}

impl Term for PlayTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // Its state reads `target` / `seek_length` only.
            reads_history: false,
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        self.thresholds
            .iter()
            .map(|&r| format!("w@r={}", crate::log::fmt_trimmed(r, 4)))
            .collect()
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        if !self.thresholds.iter().all(|r| r.is_finite() && *r > 0.0) {
            return Err(ModelError::BadTerm {
                term: self.name.clone(),
                why: "thresholds must be positive finite numbers".into(),
            });
        }
        Ok(Box::new(PlayState(PlayOperator::new(&self.thresholds))))
    }
    fn ridge(&self) -> f64 {
        RIDGE
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
}

#[derive(Debug, Clone)]
struct PlayState(PlayOperator);

impl TermState for PlayState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        self.0.peek_into(seek.features.target, out);
    }
    fn update(&mut self, seek: &Seek<'_>, _residual: Option<f64>) {
        self.0.step(seek.features.target);
    }
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `play` / `play:N` (N from 1 to 256; default [`DEFAULT_ELEMENTS`]).
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    Ok(Arc::new(PlaySpec {
        elements: t
            .arg
            .map(|a| t.count(a, "the number of play elements", 256))
            .transpose()?
            .unwrap_or(DEFAULT_ELEMENTS),
    }))
}

/// The patterns `play` answers: hysteresis whose loop changes with the reversal amplitude,
/// after the Dahl term (the verification scores both and keeps the better).
pub(crate) fn answers(cue: crate::model::cue::Cue) -> Option<crate::model::cue::Answer> {
    use crate::history::Feature::{DirectionChange, SeekAbs, SeekLength, SinceReversal};
    use crate::model::cue::{Answer, Cue};
    match cue {
        Cue::Feature(SinceReversal, false) => Answer::fixed(1),
        Cue::Feature(SeekLength | SeekAbs | SinceReversal | DirectionChange, true) => {
            Answer::fixed(1)
        }
        _ => None,
    }
}

/// The head of the term's spec text, for the diagnosis that suggests it.
pub(crate) const HEAD: &str = "play";

#[cfg(test)]
mod tests {
    use super::*;

    /// Slow, obvious reference of one stop operator: the play output follows the input only
    /// once the input has moved more than r away from it.
    fn reference_stop(xs: &[f64], r: f64) -> Vec<f64> {
        let mut out = Vec::new();
        let mut z = xs[0];
        for &x in xs {
            if x - z > r {
                z = x - r;
            } else if z - x > r {
                z = x + r;
            }
            out.push((x - z) / r);
        }
        out
    }

    #[test]
    fn operator_matches_the_textbook_stop_operator_and_peek_matches_step() {
        let mut rng = crate::numeric::rng::SimRng::new(3);
        let xs: Vec<f64> = (0..500).map(|_| 10.0 * rng.normal()).collect();
        let r = [0.3, 2.0, 7.5];
        let refs: Vec<Vec<f64>> = r.iter().map(|&ri| reference_stop(&xs, ri)).collect();
        let mut op = PlayOperator::new(&r);
        let mut fused = PlayOperator::new(&r);
        let w = [1.0, -2.0, 0.5];
        let mut out = [0.0; 3];
        for (k, &x) in xs.iter().enumerate() {
            op.peek_into(x, &mut out);
            op.step(x);
            let mut after = [0.0; 3];
            op.peek_into(x, &mut after);
            let f = fused.step_weighted(x, &w);
            for i in 0..3 {
                assert!((after[i] - refs[i][k]).abs() < 1e-12, "k {k} i {i}");
                if k > 0 {
                    assert!((out[i] - refs[i][k]).abs() < 1e-12);
                }
            }
            let want: f64 = (0..3).map(|i| w[i] * refs[i][k]).sum();
            assert!((f - want).abs() < 1e-12);
        }
    }

    #[test]
    fn thresholds_scale_with_the_position_unit() {
        // Reference: quantiles are equivariant, so thresholds scale exactly with the amplitudes.
        let amps: Vec<f64> = (1..=100).map(f64::from).collect();
        let a = thresholds(&amps, 6).unwrap();
        let scaled: Vec<f64> = amps.iter().map(|v| v * 1e-6).collect();
        let b = thresholds(&scaled, 6).unwrap();
        for (x, y) in a.iter().zip(&b) {
            assert!((x * 1e-6 - y).abs() <= 1e-12 * y.abs());
        }
        assert!(a.windows(2).all(|w| w[0] < w[1]));
        assert!(thresholds(&[5.0], 4).is_none());
    }

    /// The code before the vectorisation (`f64::clamp`, one element after another, a plain
    /// left-to-right sum): the slow reference of the fast paths.
    struct Slow {
        r: Vec<f64>,
        z: Vec<f64>,
        started: bool,
    }

    impl Slow {
        fn peek(&self, x: f64) -> Vec<f64> {
            self.z
                .iter()
                .zip(&self.r)
                .map(|(&z, &r)| {
                    if self.started {
                        (x - z.clamp(x - r, x + r)) * (1.0 / r)
                    } else {
                        0.0
                    }
                })
                .collect()
        }
        /// Steps and returns Σ wᵢ·dᵢ (left to right) and Σ |wᵢ·dᵢ|.
        fn step(&mut self, x: f64, w: &[f64]) -> (f64, f64) {
            if !self.started {
                self.z.fill(x);
                self.started = true;
                return (0.0, 0.0);
            }
            let (mut s, mut a) = (0.0, 0.0);
            for ((z, &r), &wi) in self.z.iter_mut().zip(&self.r).zip(w) {
                *z = z.clamp(x - r, x + r);
                let t = wi * (x - *z) * (1.0 / r);
                s += t;
                a += t.abs();
            }
            (s, a)
        }
    }

    #[test]
    fn fast_play_paths_match_the_slow_reference() {
        // Reference: `Slow`, the pre-vectorisation arithmetic. Deflections (peek, step) must be
        // bit-identical; the weighted sum (lanes) within 1e-12 × Σ|wᵢ·dᵢ|; `step_many` and the
        // portable copy bit-identical to `step` (AVX2 or not).
        let mut rng = crate::numeric::rng::SimRng::new(11);
        for n in [1usize, 2, 3, 4, 5, 7, 8, 31, 32, 33, 64] {
            let r: Vec<f64> = (0..n).map(|_| 0.01 + 3.0 * rng.uniform()).collect();
            let w: Vec<f64> = (0..n).map(|_| 10.0 * rng.normal()).collect();
            let mut x = 0.0;
            let xs: Vec<f64> = (0..3000)
                .map(|_| {
                    x += 0.3 * rng.normal();
                    x
                })
                .collect();
            let mut slow = Slow {
                r: r.clone(),
                z: vec![0.0; n],
                started: false,
            };
            let mut op = PlayOperator::new(&r);
            let mut pred = PlayPredictor::new(&r, &w, 1.5).unwrap();
            let (mut pz, ir): (Vec<f64>, Vec<f64>) =
                (vec![0.0; n], r.iter().map(|v| 1.0 / v).collect());
            let mut singles = Vec::new();
            let (mut out, mut want) = (vec![0.0; n], Vec::new());
            for (k, &x) in xs.iter().enumerate() {
                op.peek_into(x, &mut out);
                let s_peek = slow.peek(x);
                assert!(
                    out.iter()
                        .zip(&s_peek)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "n {n} k {k}"
                );
                op.step(x);
                let (s, a) = slow.step(x, &w);
                let f = pred.step(x);
                assert!(
                    (f - 1.5 - s).abs() <= 1e-12 * a,
                    "n {n} k {k}: {f} vs {}",
                    s + 1.5
                );
                if k == 0 {
                    pz.fill(x);
                } else {
                    let portable = step_weighted_lanes(&mut pz, &r, &ir, &w, x);
                    assert_eq!(f.to_bits(), (1.5 + portable).to_bits(), "n {n} k {k}");
                }
                assert!(
                    op.z.iter()
                        .zip(&slow.z)
                        .all(|(a, b)| a.to_bits() == b.to_bits())
                );
                singles.push(f);
                want.push(s + 1.5);
            }
            let mut many = PlayPredictor::new(&r, &w, 1.5).unwrap();
            let mut got = Vec::new();
            many.step_many(&xs[..1000], &mut got);
            many.step_many(&xs[1000..], &mut got);
            assert_eq!(got.len(), xs.len());
            assert!(
                got.iter()
                    .zip(&singles)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "n {n}"
            );
        }
    }
}

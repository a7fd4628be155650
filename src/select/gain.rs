//! The verified gain of an edit and its noise: paired Huber losses before and after the edit,
//! the block z-score of their noise part, the gain within folds, and the verdict.

use super::VerifyConfig;
use super::candidates::STRICT_EXTRA_Z;
use crate::diagnose::Reason;

/// Verified gain and its z-score of `after` over `before` (paired residuals): the gain is
/// `1 − MSE_after / MSE_before`; the z-score is the summed paired loss difference over the
/// standard error of its **noise part** ([`noise_part`], [`conditional_z`]).
///
/// The z-score is computed on **Huber losses** (quadratic within [`HUBER_K`] robust standard
/// deviations of the model before the edit, linear beyond), not on squared errors: with
/// heavy-tailed noise (Student-t ν = 4) a handful of squared outliers dominate the block sums'
/// spread and hide a real gain (6.6 % out of sample at z = 1.3 on a threshold run); the Huber
/// loss keeps about 95 % of the squared error's efficiency under Gaussian noise and bounds
/// each outlier's weight.
// The reference of its fast path (used by the tests and by nothing else).
#[cfg_attr(not(test), allow(dead_code))]
pub(super) fn paired_gain(before: &[f64], after: &[f64]) -> (f64, f64) {
    paired_gain_at(before, after, huber_c(before))
}

/// [`paired_gain`] with the Huber constant `c` of `before` given ([`huber_c`]).
pub(super) fn paired_gain_at(before: &[f64], after: &[f64], c: f64) -> (f64, f64) {
    let n = before.len();
    let mse = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>() / n.max(1) as f64;
    let (mb, ma) = (mse(before), mse(after));
    let gain = if mb > 0.0 { 1.0 - ma / mb } else { 0.0 };
    (gain, conditional_z(before, after, c))
}

/// The Huber constant of the verification's loss for the residual `before` the edit:
/// [`HUBER_K`] robust standard deviations.
pub(super) fn huber_c(before: &[f64]) -> f64 {
    HUBER_K * robust_scale(before)
}

/// The z-score of the paired Huber-loss difference `L(b) − L(a)` (`L` = [`huber`] at `c`):
/// its sum over the standard error of the sum of its noise part ([`noise_part`]), taken from
/// block sums, the block being the automatic null block ([`crate::diagnose::null_block_len`]) of the
/// noise part itself.
///
/// Why the noise part: with `d = b − a` the edit's out-of-sample change of the prediction,
/// the squared-error difference is `b² − a² = d² + 2·d·a`. Given the changes `d` (fitted on
/// the *other* folds) and the effect on this log's seeks, `d·(2s − d)` is fixed and only
/// `2·d·e` is noise (`e` the noise, `a ≈ e` when the edit holds the effect `s`). The block
/// sums of the whole difference (the rule before) counted the effect's own unevenness as noise:
/// a lagged temperature's gain comes in episodes at set-point changes, so the difference was
/// slow, got n/8-row blocks, and 8 uneven block sums put a 40–55 % gain at z ≈ 2.5. The noise
/// part is the change times the residual, which decorrelates as fast as the residual does
/// (its autocorrelation is the product of the two), so its blocks are short and many. Under
/// no effect (`a = e − d`) the noise part is `2·d·e − 2·d²`: its spread only grows, and the
/// mean difference `−d²` is a cost, so the score stays honest (tests/it/family.rs: the model
/// holding every effect gets no verified edit in 20 of 20 seeds).
pub(super) fn conditional_z(before: &[f64], after: &[f64], c: f64) -> f64 {
    let (total, se) = conditional_z_parts(before, after, c);
    if se > 0.0 { total / se } else { 0.0 }
}

/// The two parts of [`conditional_z`]: the summed paired Huber-loss difference and the block
/// standard error of its noise part (0 when the block sums have no spread). A caller pooling
/// many logs' edits (the fleet) sums both over the logs.
pub(super) fn conditional_z_parts(before: &[f64], after: &[f64], c: f64) -> (f64, f64) {
    let loss = |r: f64| huber(c, r);
    let total: f64 = before
        .iter()
        .zip(after)
        .map(|(&b, &a)| loss(b) - loss(a))
        .sum();
    let noise = noise_part(before, after, c);
    let block = crate::diagnose::null_block_len(&noise).max(1);
    let sums: Vec<f64> = noise.chunks(block).map(|c| c.iter().sum()).collect();
    let m = sums.len() as f64;
    match crate::numeric::stats::std_dev(&sums) {
        Some(sd) if sd > 0.0 => (total, sd * m.sqrt()),
        _ => (total, 0.0),
    }
}

/// The noise part of the paired Huber-loss difference, per row: the change `d = b − a` times
/// the Huber score `ψ(a)` of the residual after the edit (`2a` within ±c, `2c·sign(a)` beyond;
/// `ψ(a)·d` is `L(a + d) − L(a)` to first order in `d`, and exactly the `2·d·a` of
/// `b² − a² = d² + 2·d·a` where `|a| ≤ c`). See [`conditional_z`].
pub(super) fn noise_part(before: &[f64], after: &[f64], c: f64) -> Vec<f64> {
    let psi = |r: f64| {
        if c > 0.0 && r.abs() > c {
            2.0 * c * r.signum()
        } else {
            2.0 * r
        }
    };
    before
        .iter()
        .zip(after)
        .map(|(&b, &a)| (b - a) * psi(a))
        .collect()
}

/// The verified gain of `after` over `before` **within folds**: `1 − SS_after / SS_before`
/// where SS is the sum of squares about each fold's own mean (the `folds` contiguous
/// stretches [`cv_residuals`] scores).
///
/// Each fold's refit misses the stretch's level by an amount of its own (the low-frequency
/// part of serially correlated noise, an intercept or slow-covariate curve fitted on the other
/// stretches): `folds` numbers, each shared by every row of its stretch. Any slowly varying
/// column whose stretch means happen to line up with them "corrects" them out of sample, and
/// the block z-score of [`paired_gain`] counts that one chance alignment once per block. A
/// random-walk column with **no** effect was verified that way on a held-out `pi-cubic-ar1` log
/// (AR(1) noise, ρ = 0.6): 3.2 % out of sample at z = 4.2, a gain in every fold — and 0.3 %
/// within folds. Evidence with `folds` degrees of freedom cannot be told from chance (nor from
/// a drift), so an edit must also reach the practical minimum within folds; a physical effect
/// varies inside a stretch and keeps most of its gain there (a lagged temperature: 57.8 % →
/// 45.0 %; a slow covariate with 1.5 cycles per log, a threshold, a defect likewise).
// The reference of its fast path (used by the tests and by nothing else).
#[cfg_attr(not(test), allow(dead_code))]
pub(super) fn gain_within_folds(before: &[f64], after: &[f64], folds: usize) -> f64 {
    let ss = |r: &[f64]| -> f64 { within_folds(r, folds).iter().map(|v| v * v).sum() };
    gain_within_folds_of(ss(before), after, folds)
}

/// [`gain_within_folds`] from `before`'s sum of squares within folds (`sb`), `after`'s taken
/// without a copy ([`ss_within_folds`]).
pub(super) fn gain_within_folds_of(sb: f64, after: &[f64], folds: usize) -> f64 {
    if sb > 0.0 {
        1.0 - ss_within_folds(after, folds) / sb
    } else {
        0.0
    }
}

/// The sum of squares of [`within_folds`]`(r, folds)`, row by row in the same order (the same
/// bits, tested) without the copy.
pub(super) fn ss_within_folds(r: &[f64], folds: usize) -> f64 {
    let n = r.len();
    let folds = folds.max(1);
    (0..folds)
        .flat_map(|k| {
            let (a, b) = (k * n / folds, (k + 1) * n / folds);
            let m = crate::numeric::stats::mean(&r[a..b]);
            r[a..b].iter().map(move |&v| {
                let d = m.map_or(v, |m| v - m);
                d * d
            })
        })
        .sum()
}

/// `r` with the mean of each of `folds` contiguous stretches (cut as [`cv_residuals`] cuts
/// them) taken out.
// The reference of its fast path (used by the tests and by nothing else).
#[cfg_attr(not(test), allow(dead_code))]
pub(super) fn within_folds(r: &[f64], folds: usize) -> Vec<f64> {
    let n = r.len();
    let folds = folds.max(1);
    let mut out = r.to_vec();
    for k in 0..folds {
        let (a, b) = (k * n / folds, (k + 1) * n / folds);
        if let Some(m) = crate::numeric::stats::mean(&r[a..b]) {
            out[a..b].iter_mut().for_each(|v| *v -= m);
        }
    }
    out
}

/// Tuning constant of the verification's Huber loss, in robust standard deviations
/// (1.4826·MAD) of the residual before the edit: the classic 95 %-efficiency choice.
pub(crate) const HUBER_K: f64 = 1.345;

/// The Huber loss at `c` on the squared-error scale: `r²` within ±c, `c·(2|r| − c)` beyond
/// (continuous at |r| = c, linear in |r| there); `c = 0` is the squared error.
pub(super) fn huber(c: f64, r: f64) -> f64 {
    let a = r.abs();
    if c > 0.0 && a > c {
        c * (2.0 * a - c)
    } else {
        r * r
    }
}

/// 1.4826 × the median absolute deviation from the median (0 for fewer than two values).
pub(super) fn robust_scale(r: &[f64]) -> f64 {
    let sorted = crate::numeric::stats::sorted(r);
    let Some(m) = crate::numeric::stats::percentile_sorted(&sorted, 50.0) else {
        return 0.0;
    };
    let dev: Vec<f64> = r.iter().map(|v| (v - m).abs()).collect();
    let dev = crate::numeric::stats::sorted(&dev);
    1.4826 * crate::numeric::stats::percentile_sorted(&dev, 50.0).unwrap_or(0.0)
}

/// Whether `after` has a smaller Huber loss (as in [`paired_gain`]) than `before` on every one
/// of the `folds` contiguous stretches [`cv_residuals`] scores. A physical effect the edit
/// captures pays in every stretch of the log; a chance alignment of two slow series (a
/// random-walk column and a slow residual) pays in one stretch and costs in another, yet can
/// reach a high block z-score when the stretches are few. Required of the strict
/// (unflagged-feature) edits only.
// The reference of its fast path (used by the tests and by nothing else).
#[cfg_attr(not(test), allow(dead_code))]
pub(super) fn gains_in_every_fold(before: &[f64], after: &[f64], folds: usize) -> bool {
    gains_in_every_fold_at(before, after, folds, huber_c(before))
}

/// [`gains_in_every_fold`] with `before`'s Huber constant given ([`huber_c`]).
pub(super) fn gains_in_every_fold_at(before: &[f64], after: &[f64], folds: usize, c: f64) -> bool {
    let n = before.len();
    let loss = |r: f64| huber(c, r);
    (0..folds).all(|k| {
        let (a, b) = (k * n / folds, (k + 1) * n / folds);
        let d: f64 = before[a..b]
            .iter()
            .zip(&after[a..b])
            .map(|(&x, &y)| loss(x) - loss(y))
            .sum();
        a == b || d > 0.0
    })
}

/// The verdict on one edit from its paired out-of-sample residuals.
#[derive(Debug, Clone, Copy)]
pub(super) struct Judgement {
    /// [`paired_gain`]'s gain.
    pub gain: f64,
    /// [`gain_within_folds`].
    pub within: f64,
    /// [`paired_gain`]'s block z-score.
    pub z: f64,
    /// The bar `z` had to reach: `min_z`, or `min_z` + [`STRICT_EXTRA_Z`] for a `strict`
    /// candidate.
    pub z_bar: f64,
    /// Both gains at least the practical minimum and z at least the bar (for a `strict`
    /// candidate: `min_z` + [`STRICT_EXTRA_Z`] and a gain in every fold).
    pub verified: bool,
    /// The rule that decided `verified` ([`rule`]).
    pub reason: Reason,
}

/// The rule that decides an edit's verdict: the first it fails, in the order practical out of
/// sample (`gain` ≥ `min_effect`), practical within folds (`within` ≥ `min_effect`),
/// significant (`z` ≥ `z_bar`), a lower loss in every fold (`every_fold`, asked of a strict
/// candidate only: `None` otherwise); [`Reason::Verified`] when it fails none.
pub(super) fn rule(
    gain: f64,
    within: f64,
    min_effect: f64,
    z: f64,
    z_bar: f64,
    every_fold: Option<bool>,
) -> Reason {
    // Below, or not a number: a NaN gain, spread or z fails the rule.
    let below = |a: f64, b: f64| a.partial_cmp(&b).is_none_or(std::cmp::Ordering::is_lt);
    if below(gain, min_effect) {
        Reason::BelowPracticalMinimum
    } else if below(within, min_effect) {
        Reason::OnlyRelevelsFolds
    } else if below(z, z_bar) {
        Reason::NotSignificant
    } else if every_fold == Some(false) {
        Reason::NotInEveryFold
    } else {
        Reason::Verified
    }
}

/// The out-of-sample error std beyond which, as a multiple of the model's before the edit, a
/// refit has blown up: its prediction is a numerical failure (coefficients of nearly equal
/// columns cancelling on the rows it was fitted on and not on the held-out ones), not an edit
/// that noise made look bad.
pub(super) const REFIT_BLOW_UP: f64 = 100.0;

/// Why a refit whose out-of-sample error std is `std_after` against `std_before` (the model
/// before the edit) failed, when it blew up ([`REFIT_BLOW_UP`]) or is not finite.
pub(super) fn blown_up(std_before: f64, std_after: f64) -> Option<String> {
    (!std_after.is_finite() || std_after > REFIT_BLOW_UP * std_before).then(|| {
        format!(
            "the refit blew up: out of sample its error std is more than {REFIT_BLOW_UP:.0} \
             times the model's before the edit ({}): a numerical failure of the fit (its \
             columns nearly a combination of each other on the training folds), not evidence \
             about the effect",
            crate::log::fmt_trimmed(std_before, 4)
        )
    })
}

/// Judges an edit from the residuals before and after it on the same folds (see the module
/// docs): verified when its gain and its gain within folds both reach `min_effect` and its
/// z-score the bar (`strict`: the unflagged-feature bar).
// The reference of its fast path (used by the tests and by nothing else).
#[cfg_attr(not(test), allow(dead_code))]
pub(super) fn judge(
    before: &[f64],
    after: &[f64],
    min_effect: f64,
    strict: bool,
    config: &VerifyConfig,
) -> Judgement {
    let (gain, z) = paired_gain(before, after);
    let within = gain_within_folds(before, after, config.folds);
    let z_bar = config.min_z + if strict { STRICT_EXTRA_Z } else { 0.0 };
    let every_fold = strict.then(|| gains_in_every_fold(before, after, config.folds));
    let reason = rule(gain, within, min_effect, z, z_bar, every_fold);
    Judgement {
        gain,
        within,
        z,
        z_bar,
        verified: reason == Reason::Verified,
        reason,
    }
}

/// What every edit of a round is judged against: the residual before the edits, with its
/// Huber constant ([`huber_c`]) and its sum of squares within folds computed once per round
/// (not once per edit and bar: two sorts of the whole residual each).
pub(super) struct Baseline {
    /// The out-of-sample residual of the model before the edits.
    pub r: Vec<f64>,
    c: f64,
    ss_within: f64,
}

impl Baseline {
    /// The baseline of residual `r`, cut into `folds` as [`cv_residuals`] cuts it.
    pub(super) fn new(r: Vec<f64>, folds: usize) -> Self {
        let c = huber_c(&r);
        let ss_within = ss_within_folds(&r, folds);
        Self { r, c, ss_within }
    }

    /// [`conditional_z_parts`] of `after` against this baseline (its Huber constant): the
    /// parts of [`Self::judge_both`]'s z-score.
    pub(super) fn z_parts(&self, after: &[f64]) -> (f64, f64) {
        conditional_z_parts(&self.r, after, self.c)
    }

    /// [`judge`] of `after` at the plain bar (`[0]`) and the strict one (`[1]`): the same
    /// verdicts bit for bit (tested), the shared parts computed once.
    pub(super) fn judge_both(
        &self,
        after: &[f64],
        min_effect: f64,
        config: &VerifyConfig,
    ) -> [Judgement; 2] {
        let (gain, z) = paired_gain_at(&self.r, after, self.c);
        let within = gain_within_folds_of(self.ss_within, after, config.folds);
        let strict_bar = config.min_z + STRICT_EXTRA_Z;
        // The every-fold check only where the other rules pass at the strict bar (its pass
        // over the residuals is paid only then).
        let every_fold = (rule(gain, within, min_effect, z, strict_bar, None) == Reason::Verified)
            .then(|| gains_in_every_fold_at(&self.r, after, config.folds, self.c));
        [
            (config.min_z, None),
            (strict_bar, Some(every_fold.unwrap_or(true))),
        ]
        .map(|(z_bar, every_fold)| {
            let reason = rule(gain, within, min_effect, z, z_bar, every_fold);
            Judgement {
                gain,
                within,
                z,
                z_bar,
                verified: reason == Reason::Verified,
                reason,
            }
        })
    }
}

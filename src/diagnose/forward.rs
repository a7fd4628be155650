//! The forward pass over the flagged features: each step takes the feature with the largest
//! out-of-fold gain on what the earlier ones left, near-ties settled by which explains the
//! others away.

use rayon::prelude::*;

use crate::numeric::stats;

use super::FeatureOrigin;
use super::permutation::Analysed;
use super::smoother::{self, Binned, Unusable};

/// Two candidates are near-tied when the weaker explains at least `1 − NEAR_TIE` of what the
/// stronger does; the direction-signed analysis must beat the plain one by this margin too.
pub(crate) const NEAR_TIE: f64 = 0.05;

/// A candidate is explained away by another when what it adds beyond the other is at most this
/// fraction of what it explains on its own.
pub(crate) const EXPLAINED_AWAY: f64 = 0.2;

/// Most steps of the forward pass (features ranked by what they add beyond the earlier ones).
pub(crate) const FORWARD_STEPS: usize = 6;

/// Most near-tied candidates compared pairwise at one step.
pub(super) const MAX_TIED: usize = 4;

/// What is shared by every gain evaluation of one diagnosis.
pub(super) struct Ctx<'a> {
    pub(super) direction: Option<&'a [i8]>,
    pub(super) fold: &'a [u8],
    pub(super) folds: usize,
    /// Variance of the (clipped, centred) residuals: every gain is a fraction of it.
    pub(super) variance: f64,
}

/// What one feature explains of a residual, out of sample.
#[derive(Debug, Clone, Copy)]
pub(super) struct Gain {
    /// Fraction of the original residual variance.
    pub(super) explained: f64,
    /// Level the cross-validation chose.
    pub(super) shift: u32,
    /// Whether the direction-signed analysis won.
    pub(super) by_direction: bool,
}

/// The out-of-sample gain of the binned smoother of `b` on residual `r`: the plain analysis,
/// or — if `signable` and it explains more than `1 + NEAR_TIE` times as much — the analysis of
/// `r` × direction, counted beyond a constant direction offset. Near a tie the plain (even)
/// explanation is kept: it is the simpler one, and a term of the feature alone can fit it.
pub(super) fn gain(
    b: &Binned,
    signable: bool,
    r: &[f64],
    direction: Option<&[i8]>,
    fold: &[u8],
    folds: usize,
    variance: f64,
) -> Gain {
    let n = r.len() as f64;
    let frac = |base: f64, mse: f64| {
        if variance > 0.0 {
            ((base - mse) / variance).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let cv = smoother::cross_validate(b, r, fold, folds);
    let mut g = Gain {
        explained: frac(stats::sum_sq_about_mean(r) / n, cv.mse),
        shift: cv.shift,
        by_direction: false,
    };
    if let Some(d) = direction.filter(|_| signable) {
        // r × direction row by row, never stored (the values `Signed::new` would hold).
        let signed = || r.iter().zip(d).map(|(v, &d)| v * f64::from(d));
        let cv = smoother::cross_validate_rows(b, signed(), fold, folds);
        let e = frac(sum_sq_about_mean_rows(signed) / n, cv.mse);
        if e > g.explained * (1.0 + NEAR_TIE) {
            g = Gain {
                explained: e,
                shift: cv.shift,
                by_direction: true,
            };
        }
    }
    g
}

/// `r` minus the out-of-fold prediction of `b`'s smoother as chosen by `g`. Only the result
/// is a vector: the signed residual and the predictions are read row by row
/// ([`smoother::cv_fold_means`]; the same values as [`remove_reference`], tested).
pub(super) fn remove(b: &Binned, g: Gain, r: &[f64], ctx: &Ctx) -> Vec<f64> {
    let cell = |m: usize, i: usize| smoother::cv_cell(b, g.shift, ctx.fold, m, i);
    match ctx.direction.filter(|_| g.by_direction) {
        Some(d) => {
            let s = r.iter().zip(d).map(|(v, &d)| v * f64::from(d));
            let (p, m) = smoother::cv_fold_means(b, g.shift, s, ctx.fold, ctx.folds);
            r.iter()
                .zip(d)
                .enumerate()
                .map(|(i, (v, &d))| v - f64::from(d) * p[cell(m, i)])
                .collect()
        }
        None => {
            let (p, m) =
                smoother::cv_fold_means(b, g.shift, r.iter().copied(), ctx.fold, ctx.folds);
            r.iter()
                .enumerate()
                .map(|(i, v)| v - p[cell(m, i)])
                .collect()
        }
    }
}

/// [`remove`] as it was written with the signed residual and the predictions stored (the
/// plain reference it is tested against).
#[cfg(test)]
pub(super) fn remove_reference(b: &Binned, g: Gain, r: &[f64], ctx: &Ctx) -> Vec<f64> {
    match ctx.direction.filter(|_| g.by_direction) {
        Some(d) => {
            let d: Vec<f64> = d.iter().map(|&d| f64::from(d)).collect();
            let s: Vec<f64> = r.iter().zip(&d).map(|(v, d)| v * d).collect();
            let p = smoother::cv_predict(b, g.shift, &s, ctx.fold, ctx.folds);
            r.iter()
                .zip(&d)
                .zip(p)
                .map(|((v, d), p)| v - d * p)
                .collect()
        }
        None => {
            let p = smoother::cv_predict(b, g.shift, r, ctx.fold, ctx.folds);
            r.iter().zip(p).map(|(v, p)| v - p).collect()
        }
    }
}

/// [`stats::sum_sq_about_mean`] of the values `rows()` gives (twice: the mean, then the
/// squares), the same sums in the same order, so the same bits, without storing them.
pub(super) fn sum_sq_about_mean_rows<I: ExactSizeIterator<Item = f64>>(
    rows: impl Fn() -> I,
) -> f64 {
    let n = rows().len();
    let m = if n == 0 {
        0.0
    } else {
        rows().sum::<f64>() / n as f64
    };
    rows().map(|v| (v - m) * (v - m)).sum()
}

/// A near-tied candidate, its gain, the largest fraction of another tied candidate's gain
/// that survives its removal, and what each other tied candidate adds beyond it.
pub(super) type Cover = (usize, Gain, f64, Vec<(usize, f64)>);

/// The result of the forward pass.
pub(super) struct Forward {
    /// Features (column indices) in the order the pass took them.
    pub(super) order: Vec<usize>,
    /// Per column: what it explains beyond the features taken before it (for those not taken:
    /// beyond all taken ones); `None` for unusable features.
    pub(super) beyond: Vec<Option<f64>>,
    /// Per column: the near-tied twin that was taken instead and explains this one away.
    pub(super) explained_away_by: Vec<Option<usize>>,
    /// Per column with a twin: what it adds beyond that twin.
    pub(super) twin_gain: Vec<f64>,
    /// The residual left after removing the taken features' out-of-fold smooths.
    pub(super) left: Vec<f64>,
}

/// Ranks the flagged features by what each explains beyond the ones before it (see the module
/// docs): at each step the candidate with the largest gain on what is left, except that among
/// near-tied candidates the one that explains the others away is taken — and among several
/// that do (twins the data cannot tell apart), a logged covariate before a built-in feature.
pub(super) fn forward_pass(
    analysed: &[Result<Analysed, Unusable>],
    flagged: &[usize],
    y: &[f64],
    ctx: &Ctx,
) -> Forward {
    let m = analysed.len();
    let mut out = Forward {
        order: Vec::new(),
        beyond: vec![None; m],
        explained_away_by: vec![None; m],
        twin_gain: vec![0.0; m],
        left: Vec::new(),
    };
    let eval = |j: usize, r: &[f64]| -> Option<Gain> {
        analysed[j].as_ref().ok().map(|a| {
            gain(
                &a.binned,
                a.signable,
                r,
                ctx.direction,
                ctx.fold,
                ctx.folds,
                ctx.variance,
            )
        })
    };
    let mut r = y.to_vec();
    for _ in 0..FORWARD_STEPS {
        // Each candidate's gain is independent of the others': in parallel, in order.
        let candidates: Vec<usize> = flagged
            .iter()
            .copied()
            .filter(|j| !out.order.contains(j))
            .collect();
        let mut gains: Vec<(usize, Gain)> = candidates
            .par_iter()
            .filter_map(|&j| eval(j, &r).map(|g| (j, g)))
            .filter(|(_, g)| g.explained > 0.0)
            .collect();
        gains.sort_by(|a, b| b.1.explained.total_cmp(&a.1.explained).then(a.0.cmp(&b.0)));
        let Some(&(_, lead)) = gains.first() else {
            break;
        };
        let tied: Vec<(usize, Gain)> = gains
            .iter()
            .copied()
            .filter(|(_, g)| g.explained >= (1.0 - NEAR_TIE) * lead.explained)
            .take(MAX_TIED)
            .collect();
        let mut chosen = tied[0];
        if tied.len() > 1 {
            // For each tied candidate: what is left of the others once it is removed.
            let covers: Vec<Cover> = tied
                .par_iter()
                .filter_map(|&(c, gc)| {
                    let a = analysed[c].as_ref().ok()?;
                    let rc = remove(&a.binned, gc, &r, ctx);
                    let mut worst = 0.0f64;
                    let mut left = Vec::new();
                    for &(j, gj) in tied.iter().filter(|(j, _)| *j != c) {
                        let after = eval(j, &rc).map_or(0.0, |g| g.explained);
                        worst = worst.max(after / gj.explained);
                        left.push((j, after));
                    }
                    Some((c, gc, worst, left))
                })
                .collect();
            let is_covariate = |j: usize| {
                analysed[j]
                    .as_ref()
                    .is_ok_and(|a| a.origin == FeatureOrigin::Covariate)
            };
            let covering: Vec<&Cover> = covers.iter().filter(|c| c.2 <= EXPLAINED_AWAY).collect();
            let pick = covering
                .iter()
                .find(|c| is_covariate(c.0))
                .or_else(|| covering.first())
                .copied()
                .or_else(|| covers.iter().min_by(|a, b| a.2.total_cmp(&b.2)));
            if let Some((c, gc, _, left)) = pick {
                chosen = (*c, *gc);
                for &(j, after) in left {
                    let gj = tied
                        .iter()
                        .find(|t| t.0 == j)
                        .map_or(0.0, |t| t.1.explained);
                    if after <= EXPLAINED_AWAY * gj {
                        out.explained_away_by[j] = Some(*c);
                        out.twin_gain[j] = after;
                    }
                }
            }
        }
        let (c, gc) = chosen;
        out.beyond[c] = Some(gc.explained);
        out.order.push(c);
        if let Ok(a) = &analysed[c] {
            r = remove(&a.binned, gc, &r, ctx);
        }
    }
    let rest: Vec<Option<f64>> = (0..m)
        .into_par_iter()
        .map(|j| match out.beyond[j] {
            None => eval(j, &r).map(|g| g.explained),
            taken => taken,
        })
        .collect();
    out.beyond = rest;
    out.left = r;
    out
}

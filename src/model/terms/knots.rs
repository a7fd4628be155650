//! Knot placement from data quantiles and the hinge bases the piecewise-linear terms share.

/// Knots strictly inside (min, max) of the finite `values`: the quantiles `j/(k+1)`,
/// j = 1..=k (nearest rank), without repeats, increasing. About `1/(k+1)` of the values lie
/// beyond the last knot. The values are the caller's (the finite ones are kept in place: no
/// copy). The k quantiles come from one nested selection
/// ([`order_statistics`](crate::numeric::stats::order_statistics), about n·log₂(k + 1)
/// steps) instead of k selections over all values: the same knots bit for bit as
/// [`interior_knots_reference`] (tested).
pub(crate) fn interior_knots_owned(mut values: Vec<f64>, k: usize) -> Vec<f64> {
    values.retain(|x| x.is_finite());
    interior_knots_of(values, k)
}

/// [`interior_knots_owned`] of finite `v`.
fn interior_knots_of(mut v: Vec<f64>, k: usize) -> Vec<f64> {
    if v.is_empty() {
        return Vec::new();
    }
    let n = v.len();
    let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
    for &x in &v {
        min = min.min(x);
        max = max.max(x);
    }
    let ranks: Vec<usize> = (1..=k)
        .map(|j| (((j as f64 / (k + 1) as f64) * (n - 1) as f64).round() as usize).min(n - 1))
        .collect();
    let mut qs = vec![0.0; k];
    crate::numeric::stats::order_statistics(&mut v, &ranks, &mut qs);
    let mut knots: Vec<f64> = Vec::new();
    for q in qs {
        if q > min && q < max && !knots.iter().any(|&l| (l - q).abs() <= 0.0) {
            knots.push(q);
        }
    }
    knots.sort_by(f64::total_cmp);
    knots
}

/// The slow, obvious [`interior_knots_owned`]: a filtered copy, each quantile selected over all of
/// it in turn. The reference the nested selection is tested against.
#[cfg(test)]
pub(crate) fn interior_knots_reference(values: &[f64], k: usize) -> Vec<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return Vec::new();
    }
    let n = v.len();
    let min = v.iter().copied().fold(f64::INFINITY, f64::min);
    let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut knots: Vec<f64> = Vec::new();
    for j in 1..=k {
        let idx = ((j as f64 / (k + 1) as f64) * (n - 1) as f64).round() as usize;
        let (_, q, _) = v.select_nth_unstable_by(idx.min(n - 1), f64::total_cmp);
        let q = *q;
        if q > min && q < max && !knots.iter().any(|&l| (l - q).abs() <= 0.0) {
            knots.push(q);
        }
    }
    knots.sort_by(f64::total_cmp);
    knots
}

/// Writes the "decaying hinge" basis `(k_j − a)₊ / k_max` for distance `a ≥ 0` into `out`
/// (one value per knot). The resulting function is continuous, piecewise linear in `a` with
/// breakpoints at the knots, and exactly zero beyond the largest knot.
#[inline]
pub(crate) fn decaying_hinges(knots: &[f64], a: f64, out: &mut [f64]) {
    let scale = knots.last().copied().unwrap_or(1.0);
    for (o, &k) in out.iter_mut().zip(knots) {
        *o = (k - a).max(0.0) / scale;
    }
}

/// Writes the basis of a term with one decaying-hinge curve per slot of `knots.len()` values:
/// all zero, then, for `Some((curve, a))`, the hinges of distance `a` into that curve's slot.
#[inline]
pub(crate) fn curve_hinges(knots: &[f64], at: Option<(usize, f64)>, out: &mut [f64]) {
    out.fill(0.0);
    if let Some((c, a)) = at {
        let k = knots.len();
        decaying_hinges(knots, a, &mut out[c * k..(c + 1) * k]);
    }
}

/// Curve of the approach direction in `[out, in]` order: 0 for −1 (outbound), 1 for +1
/// (inbound), `None` before the first move.
#[inline]
pub(crate) fn direction_side(direction: i8) -> Option<usize> {
    match direction {
        1 => Some(1),
        -1 => Some(0),
        _ => None,
    }
}

/// Spec string of a knotted term: `head`, or `head:K` when `k` is not the default.
pub(crate) fn spec_name(head: &str, k: usize, default: usize) -> String {
    if k == default {
        head.into()
    } else {
        format!("{head}:{k}")
    }
}

/// Short label of a knot position for parameter names (`40`, `12.5`).
pub(crate) fn label(k: f64) -> String {
    crate::log::fmt_trimmed(k, 3)
}

/// Parameter names `curve@knot` of a term with one decaying-hinge curve per entry of `curves`.
pub(crate) fn curve_param_names(curves: &[&str], knots: &[f64]) -> Vec<String> {
    curves
        .iter()
        .flat_map(|c| knots.iter().map(move |&k| format!("{c}@{}", label(k))))
        .collect()
}

/// The fit warning of a hinge term whose data gave it no knots (`seek`, `memory`): the log has
/// no data for it, so it contributes nothing. Empty if `term` has parameters.
pub(crate) fn no_knots_warning(term: &dyn super::super::term::Term) -> Vec<String> {
    if term.param_count() == 0 {
        vec![format!(
            "term `{}` has no knots: the log has no data for it",
            term.name()
        )]
    } else {
        Vec::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// Reference: [`interior_knots_reference`] (each quantile selected over the whole copy in
    /// turn). The nested selection gives the same knots bit for bit for
    /// k = 0..=9 on values with ties, signed zeros, non-finite entries, one or two values and
    /// wide spreads.
    #[test]
    fn nested_knots_equal_the_reference_bit_for_bit() {
        let mut rng = SimRng::new(5);
        for case in 0..400 {
            let n = rng.below(500) as usize;
            let v: Vec<f64> = (0..n)
                .map(|_| match case % 5 {
                    0 => rng.below(4) as f64,
                    1 => [0.0, -0.0, 1.5, f64::NAN, f64::INFINITY][rng.below(5) as usize],
                    2 => rng.normal() * 10f64.powi(rng.below(12) as i32 - 6),
                    3 => rng.below(1000) as f64 * 0.37,
                    _ => rng.range(0.0, 300.0),
                })
                .collect();
            for k in 0..10 {
                let want: Vec<u64> = interior_knots_reference(&v, k)
                    .iter()
                    .map(|x| x.to_bits())
                    .collect();
                let owned: Vec<u64> = interior_knots_owned(v.clone(), k)
                    .iter()
                    .map(|x| x.to_bits())
                    .collect();
                assert_eq!(owned, want, "case {case}, k {k}, n {n}");
            }
        }
    }
}

//! Plain statistics shared by scoring and diagnosis: moments, percentiles, histograms,
//! bimodality, a trend test, whiteness, and the distribution functions their p-values need.
//!
//! Every function accepts any slice and returns `None` (or a documented neutral value) where the
//! statistic is undefined (too few values, zero spread); none of them panics or returns NaN for
//! finite input.

use serde::{Deserialize, Serialize};

/// Arithmetic mean; `None` for an empty slice.
pub fn mean(x: &[f64]) -> Option<f64> {
    (!x.is_empty()).then(|| x.iter().sum::<f64>() / x.len() as f64)
}

/// Sum of squared deviations from the mean, Σ(x − x̄)²; 0 for an empty slice.
pub fn sum_sq_about_mean(x: &[f64]) -> f64 {
    let m = mean(x).unwrap_or(0.0);
    x.iter().map(|v| (v - m) * (v - m)).sum()
}

/// Sample standard deviation (divisor n − 1); `None` for fewer than two values.
pub fn std_dev(x: &[f64]) -> Option<f64> {
    if x.len() < 2 {
        return None;
    }
    let m = mean(x)?;
    let ss: f64 = x.iter().map(|v| (v - m) * (v - m)).sum();
    Some((ss / (x.len() - 1) as f64).sqrt())
}

/// Root mean square; `None` for an empty slice.
pub fn rms(x: &[f64]) -> Option<f64> {
    (!x.is_empty()).then(|| (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt())
}

/// Percentile `p` (0–100) of already **sorted** values, linear interpolation between closest
/// ranks (NumPy's default, "linear"); `None` for an empty slice.
pub fn percentile_sorted(sorted: &[f64], p: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let pos = (p.clamp(0.0, 100.0) / 100.0) * (sorted.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let frac = pos - lo as f64;
    Some(sorted[lo] + (sorted[hi] - sorted[lo]) * frac)
}

/// Sorts a copy of `x` (total order; NaN last).
pub fn sorted(x: &[f64]) -> Vec<f64> {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    v
}

/// A histogram: `edges` has one more entry than `counts`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    /// Bin edges, increasing.
    pub edges: Vec<f64>,
    /// Number of values in each bin (the last bin includes its right edge).
    pub counts: Vec<u64>,
}

/// A histogram of `x` with `bins` equal bins over [min, max]. With zero spread all values go in
/// one bin of width 1 centred on the value. `bins` of 0 is treated as 1.
pub fn histogram(x: &[f64], bins: usize) -> Histogram {
    let bins = bins.max(1);
    if x.is_empty() {
        return Histogram {
            edges: vec![0.0, 1.0],
            counts: vec![0],
        };
    }
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (lo, hi, bins) = if hi > lo {
        (lo, hi, bins)
    } else {
        (lo - 0.5, lo + 0.5, 1)
    };
    let width = (hi - lo) / bins as f64;
    let edges = (0..=bins).map(|i| lo + width * i as f64).collect();
    let mut counts = vec![0u64; bins];
    for &v in x {
        let i = (((v - lo) / width) as usize).min(bins - 1);
        counts[i] += 1;
    }
    Histogram { edges, counts }
}

/// Number of histogram bins by the Freedman–Diaconis rule, clamped to 5..=60.
pub fn fd_bins(x: &[f64]) -> usize {
    let s = sorted(x);
    let (Some(q1), Some(q3)) = (percentile_sorted(&s, 25.0), percentile_sorted(&s, 75.0)) else {
        return 5;
    };
    let iqr = q3 - q1;
    let range = s[s.len() - 1] - s[0];
    if iqr <= 0.0 || range <= 0.0 {
        return 5;
    }
    let width = 2.0 * iqr / (s.len() as f64).cbrt();
    ((range / width).ceil() as usize).clamp(5, 60)
}

/// Sample skewness and excess kurtosis (bias-corrected, as SAS/Excel `SKEW`/`KURT`); `None` for
/// fewer than four values or zero spread.
pub fn skew_kurtosis(x: &[f64]) -> Option<(f64, f64)> {
    let n = x.len() as f64;
    if x.len() < 4 {
        return None;
    }
    let m = mean(x)?;
    let m2 = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n;
    if m2 <= 0.0 {
        return None;
    }
    let m3 = x.iter().map(|v| (v - m).powi(3)).sum::<f64>() / n;
    let m4 = x.iter().map(|v| (v - m).powi(4)).sum::<f64>() / n;
    let g1 = m3 / m2.powf(1.5);
    let g2 = m4 / (m2 * m2) - 3.0;
    let skew = g1 * (n * (n - 1.0)).sqrt() / (n - 2.0);
    let kurt = ((n + 1.0) * g2 + 6.0) * (n - 1.0) / ((n - 2.0) * (n - 3.0));
    Some((skew, kurt))
}

/// Sarle's bimodality coefficient b = (skew² + 1) / (kurt + 3(n−1)²/((n−2)(n−3))) with the
/// bias-corrected skewness and excess kurtosis. The uniform distribution gives 5/9 ≈ 0.555;
/// larger values suggest bimodality, a normal distribution gives ≈ 1/3. `None` as for
/// [`skew_kurtosis`].
pub fn bimodality_coefficient(x: &[f64]) -> Option<f64> {
    let (skew, kurt) = skew_kurtosis(x)?;
    let n = x.len() as f64;
    let denom = kurt + 3.0 * (n - 1.0).powi(2) / ((n - 2.0) * (n - 3.0));
    (denom > 0.0).then(|| (skew * skew + 1.0) / denom)
}

/// The threshold of [`bimodality_coefficient`] above which a sample is called bimodal (5/9).
pub const BIMODALITY_THRESHOLD: f64 = 5.0 / 9.0;

/// A least-squares line y = intercept + slope·x with its significance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Trend {
    /// Slope (units of y per unit of x).
    pub slope: f64,
    /// Intercept at x = 0.
    pub intercept: f64,
    /// Standard error of the slope.
    pub slope_se: f64,
    /// t statistic of the slope (slope / se).
    pub t: f64,
    /// Two-sided p-value of "slope = 0" (Student t, n − 2 degrees of freedom).
    pub p_value: f64,
    /// Coefficient of determination of the line.
    pub r2: f64,
    /// Number of points.
    pub n: usize,
}

/// Least-squares trend of `y` against `x` (centred, so large x values lose no precision);
/// `None` for fewer than three points or zero spread in x. A perfect fit gives p = 0.
pub fn linear_trend(x: &[f64], y: &[f64]) -> Option<Trend> {
    let n = x.len().min(y.len());
    if n < 3 {
        return None;
    }
    let (x, y) = (&x[..n], &y[..n]);
    let mx = mean(x)?;
    let my = mean(y)?;
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let syy: f64 = y.iter().map(|v| (v - my).powi(2)).sum();
    let slope = sxy / sxx;
    let sse = (syy - slope * sxy).max(0.0);
    let dof = (n - 2) as f64;
    let slope_se = (sse / dof / sxx).sqrt();
    let t = if slope_se > 0.0 {
        slope / slope_se
    } else if slope.abs() > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let p_value = if t.is_finite() {
        student_t_two_sided_p(t, dof)
    } else {
        0.0
    };
    let r2 = if syy > 0.0 { 1.0 - sse / syy } else { 0.0 };
    Some(Trend {
        slope,
        intercept: my - slope * mx,
        slope_se,
        t,
        p_value,
        r2,
        n,
    })
}

/// Autocorrelation of `x` at `lag` (biased estimator, as in the Ljung–Box test); 0 when the
/// spread is zero or the lag is out of range.
pub fn autocorrelation(x: &[f64], lag: usize) -> f64 {
    let n = x.len();
    if lag >= n {
        return 0.0;
    }
    let Some(m) = mean(x) else { return 0.0 };
    let c0: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
    if c0 <= 0.0 {
        return 0.0;
    }
    let ck: f64 = (lag..n).map(|i| (x[i] - m) * (x[i - lag] - m)).sum();
    ck / c0
}

/// The Ljung–Box test of whiteness over lags 1..=`lags`: (Q, p-value with `lags` degrees of
/// freedom). `None` when there are not more values than lags + 1.
pub fn ljung_box(x: &[f64], lags: usize) -> Option<(f64, f64)> {
    let n = x.len();
    if lags == 0 || n <= lags + 1 {
        return None;
    }
    let nf = n as f64;
    let q = nf
        * (nf + 2.0)
        * (1..=lags)
            .map(|k| autocorrelation(x, k).powi(2) / (nf - k as f64))
            .sum::<f64>();
    Some((q, chi2_sf(q, lags as f64)))
}

/// Standard normal cumulative distribution function.
pub fn normal_cdf(z: f64) -> f64 {
    0.5 * erfc(-z / std::f64::consts::SQRT_2)
}

/// Complementary error function (W. J. Cody's rational approximations via the incomplete gamma
/// function: erfc(x) = Q(1/2, x²) for x ≥ 0), accurate to ~1e-14 relative.
pub fn erfc(x: f64) -> f64 {
    if x >= 0.0 {
        gamma_q(0.5, x * x)
    } else {
        2.0 - gamma_q(0.5, x * x)
    }
}

/// Two-sided p-value of a Student t statistic with `dof` degrees of freedom:
/// P(|T| ≥ |t|) = I_{dof/(dof+t²)}(dof/2, 1/2).
pub fn student_t_two_sided_p(t: f64, dof: f64) -> f64 {
    if dof <= 0.0 {
        return 1.0;
    }
    reg_inc_beta(dof / 2.0, 0.5, dof / (dof + t * t)).clamp(0.0, 1.0)
}

/// Survival function of the chi-square distribution: P(X ≥ q) with `dof` degrees of freedom.
pub fn chi2_sf(q: f64, dof: f64) -> f64 {
    if q <= 0.0 {
        return 1.0;
    }
    gamma_q(dof / 2.0, q / 2.0).clamp(0.0, 1.0)
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, n = 9; ~1e-15 relative).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection formula.
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma function Q(a, x) (series / continued fraction, Numerical
/// Recipes §6.2).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        // Series for P, Q = 1 − P.
        let mut ap = a;
        let mut sum = 1.0 / a;
        let mut del = sum;
        for _ in 0..1000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        // Lentz continued fraction for Q.
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / LENTZ_TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            let del = lentz_step(an, b, &mut c, &mut d);
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// Regularised incomplete beta function I_x(a, b) (continued fraction, Numerical Recipes §6.4).
pub fn reg_inc_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    let front = ln_front.exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_cf(a, b, x) / a
    } else {
        1.0 - front * beta_cf(b, a, 1.0 - x) / b
    }
}

/// Lentz's floor for a vanishing denominator.
const LENTZ_TINY: f64 = 1e-300;

/// `v`, or [`LENTZ_TINY`] where |v| is below it (NaN passes through).
#[inline]
fn guard(v: f64) -> f64 {
    if v.abs() < LENTZ_TINY { LENTZ_TINY } else { v }
}

/// One step of the modified Lentz recurrence for the partial fraction `a / (b + …)`: updates
/// `c` and `d`, returns the factor `d·c` the fraction's value is multiplied by.
#[inline]
fn lentz_step(a: f64, b: f64, c: &mut f64, d: &mut f64) -> f64 {
    *d = 1.0 / guard(b + a * *d);
    *c = guard(b + a / *c);
    *d * *c
}

fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..1000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        h *= lentz_step(aa, 1.0, &mut c, &mut d);
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        let del = lentz_step(aa, 1.0, &mut c, &mut d);
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn distribution_functions_match_scipy_values() {
        // Reference values from scipy.stats (norm.cdf, t.sf*2, chi2.sf) and math.lgamma.
        assert!(close(normal_cdf(1.96), 0.975_002_104_851_780, 1e-12));
        assert!(close(normal_cdf(-3.0), 0.001_349_898_031_630_095, 1e-13));
        assert!(close(
            student_t_two_sided_p(2.0, 10.0),
            0.073_388_034_770_740_8,
            1e-10
        ));
        // Closed form for 3 degrees of freedom: F(t) = 1/2 + (u/(1+u²) + atan u)/π, u = t/√3.
        let u = 0.5 / 3f64.sqrt();
        let cdf = 0.5 + (u / (1.0 + u * u) + u.atan()) / std::f64::consts::PI;
        assert!(close(
            student_t_two_sided_p(0.5, 3.0),
            2.0 * (1.0 - cdf),
            1e-12
        ));
        assert!(close(chi2_sf(3.841_458_820_694_124, 1.0), 0.05, 1e-10));
        assert!(close(chi2_sf(18.307_038_053_275_146, 10.0), 0.05, 1e-10));
        assert!(close(ln_gamma(10.0), 12.801_827_480_081_469, 1e-12));
        assert!(close(ln_gamma(0.5), 0.572_364_942_924_700_1, 1e-12));
    }

    #[test]
    fn moments_and_percentiles() {
        let x = [1.0, 2.0, 3.0, 4.0];
        assert!(close(mean(&x).unwrap(), 2.5, 1e-15));
        assert!(close(std_dev(&x).unwrap(), (5.0f64 / 3.0).sqrt(), 1e-15));
        assert!(close(percentile_sorted(&x, 50.0).unwrap(), 2.5, 1e-15));
        assert!(close(percentile_sorted(&x, 90.0).unwrap(), 3.7, 1e-12));
        assert_eq!(std_dev(&[1.0]), None);
        assert_eq!(mean(&[]), None);
    }

    #[test]
    fn histogram_counts_every_value_once() {
        let x: Vec<f64> = (0..100).map(f64::from).collect();
        let h = histogram(&x, 10);
        assert_eq!(h.counts, vec![10; 10]);
        assert_eq!(h.edges.len(), 11);
        let one = histogram(&[3.0, 3.0], 10);
        assert_eq!(one.counts, vec![2]);
    }

    #[test]
    fn bimodality_separates_two_clusters_from_one() {
        // Two well separated clusters vs one symmetric lump; the uniform gives 5/9 in the limit.
        let two: Vec<f64> = (0..400)
            .map(|i| if i % 2 == 0 { -10.0 } else { 10.0 } + (i % 7) as f64 * 0.1)
            .collect();
        let one: Vec<f64> = (0..401)
            .map(|i| ((i as f64) - 200.0).powi(3) / 1e6)
            .collect();
        assert!(bimodality_coefficient(&two).unwrap() > 0.9);
        assert!(bimodality_coefficient(&one).unwrap() < BIMODALITY_THRESHOLD);
        let uniform: Vec<f64> = (0..10_000).map(f64::from).collect();
        assert!(close(
            bimodality_coefficient(&uniform).unwrap(),
            5.0 / 9.0,
            1e-3
        ));
    }

    #[test]
    fn trend_of_exact_line_and_of_no_line() {
        let x: Vec<f64> = (0..50).map(|i| 1000.0 + i as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| 2.0 - 0.5 * v).collect();
        let t = linear_trend(&x, &y).unwrap();
        assert!(close(t.slope, -0.5, 1e-12) && close(t.intercept, 2.0, 1e-9));
        assert!(t.p_value < 1e-12 && close(t.r2, 1.0, 1e-12));
        let flat: Vec<f64> = x
            .iter()
            .map(|v| if (*v as i64) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let t0 = linear_trend(&x, &flat).unwrap();
        assert!(t0.p_value > 0.5, "{t0:?}");
        assert!(linear_trend(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).is_none());
    }

    #[test]
    fn ljung_box_flags_a_random_walk_not_white_noise() {
        let mut r = crate::rng::SimRng::new(9);
        let white: Vec<f64> = (0..2000).map(|_| r.normal()).collect();
        let walk: Vec<f64> = white
            .iter()
            .scan(0.0, |s, v| {
                *s += v;
                Some(*s)
            })
            .collect();
        assert!(ljung_box(&white, 10).unwrap().1 > 0.01);
        assert!(ljung_box(&walk, 10).unwrap().1 < 1e-10);
    }
}

//! Tests of Hartigans' dip test ([`dip_statistic`], [`dip_test`], [`dip_p_value`]): against a
//! slow reference dip built from the definition, against published values of the R package
//! `diptest`, the calibration of its p-value table, and its behaviour on normal mixtures.

use super::*;
use crate::numeric::rng::SimRng;

// ----------------------------------------------------------------------------------------------
// Reference: the dip from its definition, D = inf over unimodal distribution functions G of
// sup_x |F(x) − G(x)|, F the empirical distribution function. Nothing of the fast algorithm
// (hull vertex chains, modal-interval iteration) is used. Why the construction is exact:
//
// (a) The mode can be taken at a data value u_q. If G is unimodal with its mode m strictly
//     between two neighbouring data values u_q < m < u_{q+1} (or outside the data), replace G
//     between them by the straight line from G(u_q) to G(u_{q+1}): its slope lies between the
//     slopes of G on [u_q, m] and on [m, u_{q+1}], so the result is convex up to u_{q+1} and
//     concave from u_{q+1} on (if the left slope is the smaller), or convex up to u_q and concave
//     from u_q (otherwise); the values at the data do not change.
// (b) Let u_0 < … < u_{k−1} be the distinct values, F_j = F(u_j), F_{−1} = 0. F is constant
//     between data values and G nondecreasing, so sup|F − G| ≤ d exactly when, for every j,
//     G(u_j−) ≤ F_{j−1} + d and G(u_j) ≥ F_j − d. G can jump only at its mode, so off the mode
//     G(u_j) lies in the box [lo_j, hi_j] = [max(F_j − d, 0), min(F_{j−1} + d, 1)]; at the mode
//     α = G(u_q−) ≤ hi_q and β = G(u_q) ≥ lo_q with α ≤ β (the atom). Only these values matter:
//     linear interpolation between them keeps convexity, concavity and every constraint, and G
//     reaches 0 and 1 beyond the data with slopes as small as needed (closing the constraint set
//     does not change the infimum).
// (c) Left of the mode: a convex nondecreasing sequence within the boxes ending at α ≤ a exists
//     iff the greatest convex minorant of the upper bounds min(hi_i, a) (and a at u_q) stays at
//     or above every lo_i, because that minorant is the largest convex sequence under them.
//     This is monotone in a, so the smallest feasible end α_min follows by bisection. Right of
//     the mode the map x → −x, G → 1 − G turns the concave part into the same problem and gives
//     the largest feasible start β_max. The mode at u_q is feasible iff α_min ≤ β_max.
// (d) Feasibility is monotone in d; D is the smallest feasible d, found by bisection to the last
//     bit. Cost about O(k² · 60²) per sample: fine for the small samples below.
// ----------------------------------------------------------------------------------------------

/// The greatest convex minorant (lower hull) of the points (t_i, h_i), t increasing, evaluated at
/// every t_i (Andrew's monotone chain).
fn minorant_at_knots(t: &[f64], h: &[f64]) -> Vec<f64> {
    let mut hull: Vec<usize> = Vec::new();
    for i in 0..t.len() {
        while let [.., a, b] = hull[..] {
            // Drop b when it lies on or above the segment a→i.
            if (h[b] - h[a]) * (t[i] - t[a]) >= (h[i] - h[a]) * (t[b] - t[a]) {
                hull.pop();
            } else {
                break;
            }
        }
        hull.push(i);
    }
    let mut out = h.to_vec();
    for w in hull.windows(2) {
        let (a, b) = (w[0], w[1]);
        for i in a + 1..b {
            out[i] = h[a] + (h[b] - h[a]) * (t[i] - t[a]) / (t[b] - t[a]);
        }
    }
    out
}

/// The smallest last value of a convex nondecreasing sequence at knots `t` (one more than `lo`)
/// with lo_i ≤ v_i ≤ hi_i before the last knot and v_last ≤ `hi_end`; `None` if there is none.
fn min_end_value(t: &[f64], lo: &[f64], hi: &[f64], hi_end: f64) -> Option<f64> {
    let feasible = |a: f64| {
        let h: Vec<f64> = hi.iter().map(|&v| v.min(a)).chain([a]).collect();
        let g = minorant_at_knots(t, &h);
        lo.iter().zip(&g).all(|(l, g)| g >= l)
    };
    if !feasible(hi_end) {
        return None;
    }
    // The last value is at least every earlier one.
    let mut a = lo.iter().copied().fold(0.0, f64::max);
    if feasible(a) {
        return Some(a);
    }
    let mut b = hi_end;
    loop {
        let mid = 0.5 * (a + b);
        if mid <= a || mid >= b {
            return Some(b);
        }
        if feasible(mid) {
            b = mid;
        } else {
            a = mid;
        }
    }
}

/// The dip of `x` from its definition (see above).
fn reference_dip(x: &[f64]) -> f64 {
    let s = sorted(x);
    let n = s.len() as f64;
    let (mut u, mut f): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for (i, &v) in s.iter().enumerate() {
        let cum = (i + 1) as f64 / n;
        if u.last().is_some_and(|&w: &f64| w >= v) {
            *f.last_mut().unwrap() = cum;
        } else {
            u.push(v);
            f.push(cum);
        }
    }
    let k = u.len();
    let feasible = |d: f64| {
        let lo: Vec<f64> = f.iter().map(|&fj| (fj - d).max(0.0)).collect();
        let hi: Vec<f64> = (0..k)
            .map(|j| (if j == 0 { 0.0 } else { f[j - 1] } + d).min(1.0))
            .collect();
        (0..k).any(|q| {
            let Some(alpha_min) = min_end_value(&u[..=q], &lo[..q], &hi[..q], hi[q]) else {
                return false;
            };
            let t: Vec<f64> = (q..k).rev().map(|j| -u[j]).collect();
            let lo_m: Vec<f64> = (q + 1..k).rev().map(|j| 1.0 - hi[j]).collect();
            let hi_m: Vec<f64> = (q + 1..k).rev().map(|j| 1.0 - lo[j]).collect();
            let Some(w_min) = min_end_value(&t, &lo_m, &hi_m, 1.0 - lo[q]) else {
                return false;
            };
            alpha_min <= 1.0 - w_min
        })
    };
    let (mut a, mut b) = (0.0, 0.5);
    assert!(feasible(b));
    loop {
        let mid = 0.5 * (a + b);
        if mid <= a || mid >= b {
            return b;
        }
        if feasible(mid) {
            b = mid;
        } else {
            a = mid;
        }
    }
}

/// Whether two intervals have the same ends (to 1e-12).
fn same(a: [f64; 2], b: [f64; 2]) -> bool {
    (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12
}

fn dip_of(x: &[f64]) -> f64 {
    dip_statistic(x).expect("dip defined").statistic
}

#[test]
fn reference_dip_of_textbook_cases() {
    // The reference itself, on cases whose dip follows from the definition by hand: two equal
    // point masses are as far from unimodal as possible, 1/4; every sample of distinct values is
    // at least 1/(2n) away (a jump of 1/n off the mode), and equally spaced values reach it.
    assert!((reference_dip(&[1.0, 1.0, 2.0, 2.0]) - 0.25).abs() < 1e-15);
    let even: Vec<f64> = (0..9).map(f64::from).collect();
    assert!((reference_dip(&even) - 1.0 / 18.0).abs() < 1e-15);
}

/// Compares the fast dip with the reference on `count` samples drawn by `draw(rng, n)`.
fn agree_on(
    label: &str,
    seed: u64,
    count: usize,
    sizes: std::ops::RangeInclusive<usize>,
    draw: impl Fn(&mut SimRng, usize) -> Vec<f64>,
) {
    let mut rng = SimRng::new(seed);
    let span = (sizes.end() - sizes.start() + 1) as u64;
    for case in 0..count {
        let n = sizes.start() + rng.below(span) as usize;
        let x = draw(&mut rng, n);
        let Some(fast) = dip_statistic(&x) else {
            continue; // all values tied
        };
        let slow = reference_dip(&x);
        assert!(
            (fast.statistic - slow).abs() <= 1e-12,
            "{label} case {case}: fast {} reference {slow} for {x:?}",
            fast.statistic
        );
        let [lo, hi] = fast.modal_interval;
        assert!(
            lo <= hi && x.contains(&lo) && x.contains(&hi),
            "{label} case {case}"
        );
    }
}

#[test]
fn fast_dip_matches_the_reference_on_uniform_samples() {
    // Reference: `reference_dip` (the definition, see the top of this file).
    agree_on("uniform", 1, 300, 4..=30, |r, n| {
        (0..n).map(|_| r.uniform()).collect()
    });
}

#[test]
fn fast_dip_matches_the_reference_on_normal_mixtures() {
    // Reference: `reference_dip`. Mixtures of N(−μ, 1) and N(μ, 1), μ from 0 to 3.
    agree_on("mixture", 2, 300, 4..=40, |r, n| {
        let mu = 0.5 * r.below(7) as f64;
        (0..n)
            .map(|_| if r.uniform() < 0.5 { -mu } else { mu } + r.normal())
            .collect()
    });
    agree_on("wide mixture", 3, 12, 60..=90, |r, n| {
        let mu = 0.75 * r.below(4) as f64;
        (0..n)
            .map(|_| if r.uniform() < 0.3 { -mu } else { mu } + r.normal())
            .collect()
    });
}

#[test]
fn fast_dip_matches_the_reference_with_ties() {
    // Reference: `reference_dip`. Values rounded to a coarse grid, so most samples have ties.
    agree_on("rounded normal", 4, 300, 4..=25, |r, n| {
        (0..n).map(|_| (1.5 * r.normal()).round()).collect()
    });
    agree_on("few levels", 5, 300, 4..=20, |r, n| {
        (0..n).map(|_| r.below(4) as f64).collect()
    });
    agree_on("bimodal levels", 6, 200, 4..=20, |r, n| {
        (0..n)
            .map(|_| if r.uniform() < 0.5 { 0.0 } else { 6.0 } + r.below(3) as f64)
            .collect()
    });
}

#[test]
fn dip_is_invariant_under_affine_maps_and_mirroring() {
    // Reference: the definition, which only sees the distribution function up to a monotone
    // affine change of variable; a mirror x → −x maps unimodal distributions onto unimodal ones.
    let mut r = SimRng::new(21);
    for _ in 0..50 {
        let x: Vec<f64> = (0..40)
            .map(|_| if r.uniform() < 0.4 { -2.0 } else { 1.0 } + r.normal())
            .collect();
        let d = dip_statistic(&x).unwrap();
        let y: Vec<f64> = x.iter().map(|v| 1e4 + 250.0 * v).collect();
        let m: Vec<f64> = x.iter().map(|v| -v).collect();
        let (dy, dm) = (dip_statistic(&y).unwrap(), dip_statistic(&m).unwrap());
        assert!((dy.statistic - d.statistic).abs() < 1e-12);
        assert!((dm.statistic - d.statistic).abs() < 1e-12);
        assert!((dy.modal_interval[0] - (1e4 + 250.0 * d.modal_interval[0])).abs() < 1e-9);
    }
}

#[test]
fn undefined_cases_give_none_and_never_nan() {
    assert_eq!(dip_statistic(&[1.0, 2.0, 3.0]), None);
    assert_eq!(dip_statistic(&[2.0; 10]), None);
    assert_eq!(dip_statistic(&[1.0, f64::NAN, 2.0, 3.0, 4.0]), None);
    assert_eq!(dip_statistic(&[1.0, f64::INFINITY, 2.0, 3.0, 4.0]), None);
    assert_eq!(dip_statistic_sorted(&[1.0, 3.0, 2.0, 4.0]), None);
    assert_eq!(dip_test(&[]), None);
    // A −0.0 end of the modal interval is reported as 0.0.
    let d = dip_statistic(&[-0.0, -0.0, 0.0, 0.0, 1.0, 1.0, 1.0]).unwrap();
    assert!(
        d.modal_interval.iter().all(|v| !v.is_sign_negative()),
        "{d:?}"
    );
    assert!((dip_p_value(f64::NAN, 100) - 1.0).abs() < 1e-15);
    assert!((dip_p_value(0.3, 3) - 1.0).abs() < 1e-15);
    // Extremes of the scale: tiny and huge spreads, a lone outlier.
    for x in [
        vec![1e-300, 2e-300, 3e-300, 5e-300, 8e-300],
        vec![-1e300, 0.0, 1e300, 1e300, 1e300],
        vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1e9],
    ] {
        let t = dip_test(&x).unwrap();
        assert!(
            t.statistic.is_finite() && t.p_value.is_finite(),
            "{x:?}: {t:?}"
        );
        assert!((1.0 / (2.0 * x.len() as f64) - 1e-15..=0.25 + 1e-15).contains(&t.statistic));
    }
}

// ----------------------------------------------------------------------------------------------
// Published values of the R package diptest (M. Maechler, CRAN; github.com/mmaechler/diptest):
// `tests/ex1.R` with its saved output `tests/ex1.Rout.save-64b` (R 4.5.1, diptest 0.77-2),
// `man/dip.Rd`, `man/dip.test.Rd` and the vignette "Dip Test Distributions, P-values, and other
// Explorations" (`vignettes/diptest-issues.Rnw`). R prints `dip` to 3 digits and the debug
// trace "2n*D" to 5-6; where the trace pins the value exactly, we assert to 1e-12.
// ----------------------------------------------------------------------------------------------

/// `statfaculty` of R diptest (`data/statfaculty.R`): 63 grades of statistics faculty, the
/// example of Hartigan & Hartigan (1985).
const STATFACULTY: [f64; 63] = [
    30.0, 33.0, 35.0, 36.0, 37.0, 37.0, 39.0, 39.0, 39.0, 39.0, 39.0, 40.0, 40.0, 40.0, 40.0, 41.0,
    42.0, 43.0, 43.0, 43.0, 44.0, 44.0, 45.0, 45.0, 46.0, 46.0, 47.0, 47.0, 48.0, 48.0, 48.0, 49.0,
    50.0, 50.0, 51.0, 52.0, 52.0, 53.0, 53.0, 53.0, 53.0, 53.0, 54.0, 54.0, 57.0, 57.0, 59.0, 60.0,
    60.0, 60.0, 61.0, 61.0, 61.0, 61.0, 62.0, 62.0, 62.0, 62.0, 63.0, 66.0, 70.0, 72.0, 72.0,
];

/// R's `datasets::faithful$eruptions` (Old Faithful eruption durations, minutes; Azzalini &
/// Bowman 1990), in R's row order, copied from a public CSV export
/// (github.com/troescherw/datasets, `faithful.csv`).
#[rustfmt::skip]
const FAITHFUL_ERUPTIONS: [f64; 272] = [
    3.6, 1.8, 3.333, 2.283, 4.533, 2.883, 4.7, 3.6, 1.95, 4.35, 1.833, 3.917,
    4.2, 1.75, 4.7, 2.167, 1.75, 4.8, 1.6, 4.25, 1.8, 1.75, 3.45, 3.067,
    4.533, 3.6, 1.967, 4.083, 3.85, 4.433, 4.3, 4.467, 3.367, 4.033, 3.833, 2.017,
    1.867, 4.833, 1.833, 4.783, 4.35, 1.883, 4.567, 1.75, 4.533, 3.317, 3.833, 2.1,
    4.633, 2.0, 4.8, 4.716, 1.833, 4.833, 1.733, 4.883, 3.717, 1.667, 4.567, 4.317,
    2.233, 4.5, 1.75, 4.8, 1.817, 4.4, 4.167, 4.7, 2.067, 4.7, 4.033, 1.967,
    4.5, 4.0, 1.983, 5.067, 2.017, 4.567, 3.883, 3.6, 4.133, 4.333, 4.1, 2.633,
    4.067, 4.933, 3.95, 4.517, 2.167, 4.0, 2.2, 4.333, 1.867, 4.817, 1.833, 4.3,
    4.667, 3.75, 1.867, 4.9, 2.483, 4.367, 2.1, 4.5, 4.05, 1.867, 4.7, 1.783,
    4.85, 3.683, 4.733, 2.3, 4.9, 4.417, 1.7, 4.633, 2.317, 4.6, 1.817, 4.417,
    2.617, 4.067, 4.25, 1.967, 4.6, 3.767, 1.917, 4.5, 2.267, 4.65, 1.867, 4.167,
    2.8, 4.333, 1.833, 4.383, 1.883, 4.933, 2.033, 3.733, 4.233, 2.233, 4.533, 4.817,
    4.333, 1.983, 4.633, 2.017, 5.1, 1.8, 5.033, 4.0, 2.4, 4.6, 3.567, 4.0,
    4.5, 4.083, 1.8, 3.967, 2.2, 4.15, 2.0, 3.833, 3.5, 4.583, 2.367, 5.0,
    1.933, 4.617, 1.917, 2.083, 4.583, 3.333, 4.167, 4.333, 4.5, 2.417, 4.0, 4.167,
    1.883, 4.583, 4.25, 3.767, 2.033, 4.433, 4.083, 1.833, 4.417, 2.183, 4.8, 1.833,
    4.8, 4.1, 3.966, 4.233, 3.5, 4.366, 2.25, 4.667, 2.1, 4.35, 4.133, 1.867,
    4.6, 1.783, 4.367, 3.85, 1.933, 4.5, 2.383, 4.7, 1.867, 3.833, 3.417, 4.233,
    2.4, 4.8, 2.0, 4.15, 1.867, 4.267, 1.75, 4.483, 4.0, 4.117, 4.083, 4.267,
    3.917, 4.55, 4.083, 2.417, 4.183, 2.217, 4.45, 1.883, 1.85, 4.283, 3.95, 2.333,
    4.15, 2.35, 4.933, 2.9, 4.583, 3.833, 2.083, 4.367, 2.133, 4.35, 2.2, 4.45,
    3.567, 4.5, 4.15, 3.817, 3.917, 4.45, 2.0, 4.283, 4.767, 4.533, 1.85, 4.25,
    1.983, 2.25, 4.75, 4.117, 2.15, 4.417, 1.817, 4.467,
];

/// R's `datasets::faithful$waiting` (minutes to the next eruption), same source and order.
#[rustfmt::skip]
const FAITHFUL_WAITING: [f64; 272] = [
    79.0, 54.0, 74.0, 62.0, 85.0, 55.0, 88.0, 85.0, 51.0, 85.0, 54.0, 84.0, 78.0, 47.0, 83.0, 52.0,
    62.0, 84.0, 52.0, 79.0, 51.0, 47.0, 78.0, 69.0, 74.0, 83.0, 55.0, 76.0, 78.0, 79.0, 73.0, 77.0,
    66.0, 80.0, 74.0, 52.0, 48.0, 80.0, 59.0, 90.0, 80.0, 58.0, 84.0, 58.0, 73.0, 83.0, 64.0, 53.0,
    82.0, 59.0, 75.0, 90.0, 54.0, 80.0, 54.0, 83.0, 71.0, 64.0, 77.0, 81.0, 59.0, 84.0, 48.0, 82.0,
    60.0, 92.0, 78.0, 78.0, 65.0, 73.0, 82.0, 56.0, 79.0, 71.0, 62.0, 76.0, 60.0, 78.0, 76.0, 83.0,
    75.0, 82.0, 70.0, 65.0, 73.0, 88.0, 76.0, 80.0, 48.0, 86.0, 60.0, 90.0, 50.0, 78.0, 63.0, 72.0,
    84.0, 75.0, 51.0, 82.0, 62.0, 88.0, 49.0, 83.0, 81.0, 47.0, 84.0, 52.0, 86.0, 81.0, 75.0, 59.0,
    89.0, 79.0, 59.0, 81.0, 50.0, 85.0, 59.0, 87.0, 53.0, 69.0, 77.0, 56.0, 88.0, 81.0, 45.0, 82.0,
    55.0, 90.0, 45.0, 83.0, 56.0, 89.0, 46.0, 82.0, 51.0, 86.0, 53.0, 79.0, 81.0, 60.0, 82.0, 77.0,
    76.0, 59.0, 80.0, 49.0, 96.0, 53.0, 77.0, 77.0, 65.0, 81.0, 71.0, 70.0, 81.0, 93.0, 53.0, 89.0,
    45.0, 86.0, 58.0, 78.0, 66.0, 76.0, 63.0, 88.0, 52.0, 93.0, 49.0, 57.0, 77.0, 68.0, 81.0, 81.0,
    73.0, 50.0, 85.0, 74.0, 55.0, 77.0, 83.0, 83.0, 51.0, 78.0, 84.0, 46.0, 83.0, 55.0, 81.0, 57.0,
    76.0, 84.0, 77.0, 81.0, 87.0, 77.0, 51.0, 78.0, 60.0, 82.0, 91.0, 53.0, 78.0, 46.0, 77.0, 84.0,
    49.0, 83.0, 71.0, 80.0, 49.0, 75.0, 64.0, 76.0, 53.0, 94.0, 55.0, 76.0, 50.0, 82.0, 54.0, 75.0,
    78.0, 79.0, 78.0, 78.0, 70.0, 79.0, 70.0, 54.0, 86.0, 50.0, 90.0, 54.0, 54.0, 77.0, 79.0, 64.0,
    75.0, 47.0, 86.0, 63.0, 85.0, 82.0, 57.0, 82.0, 67.0, 74.0, 54.0, 83.0, 73.0, 73.0, 88.0, 80.0,
    71.0, 83.0, 56.0, 79.0, 78.0, 84.0, 58.0, 83.0, 43.0, 60.0, 75.0, 81.0, 46.0, 90.0, 46.0, 74.0,
];

#[test]
fn faithful_copy_matches_rs_summary() {
    // Reference: R's `summary(faithful)`: eruptions min 1.600, median 4.000, mean 3.488, max
    // 5.100; waiting min 43, median 76, mean 70.9, max 96. Guards the transcription above.
    let e = sorted(&FAITHFUL_ERUPTIONS);
    let w = sorted(&FAITHFUL_WAITING);
    assert!((mean(&e).unwrap() - 3.488).abs() < 5e-4);
    assert!((mean(&w).unwrap() - 70.9).abs() < 5e-2);
    assert!((percentile_sorted(&e, 50.0).unwrap() - 4.0).abs() < 1e-12);
    assert!((percentile_sorted(&w, 50.0).unwrap() - 76.0).abs() < 1e-12);
    assert!((e[0] - 1.6).abs() < 1e-12 && (e[271] - 5.1).abs() < 1e-12);
    assert!((w[0] - 43.0).abs() < 1e-12 && (w[271] - 96.0).abs() < 1e-12);
}

#[test]
fn published_dips_of_r_diptest() {
    // ex1.R: `stopifnot(dip(c(1,1,2,2)) == 1/4)`, "the maximal value possible".
    assert!((dip_of(&[1.0, 1.0, 2.0, 2.0]) - 0.25).abs() < 1e-15);
    // ex1.R: u = cumsum(0:3) = (0, 1, 3, 6): `stopifnot(d == dip(-u), d == 1/(2*n))`.
    let u = [0.0, 1.0, 3.0, 6.0];
    assert!((dip_of(&u) - 0.125).abs() < 1e-15);
    assert!((dip_of(&[-0.0, -1.0, -3.0, -6.0]) - 0.125).abs() < 1e-15);
    // ex1.Rout.save: x = (0, 2, 3, 5, 6): 2n·D = 1.33333, lo.hi = (4, 5), xl = 5, xu = 6; the
    // mirror 6 − x = (0, 1, 3, 4, 6): the same dip, xl = 3, xu = 4.
    let d1 = dip_statistic(&[0.0, 2.0, 3.0, 5.0, 6.0]).unwrap();
    assert!((d1.statistic - 2.0 / 15.0).abs() < 1e-12, "{d1:?}");
    assert!(same(d1.modal_interval, [5.0, 6.0]), "{d1:?}");
    let d2 = dip_statistic(&[6.0, 4.0, 3.0, 1.0, 0.0]).unwrap();
    assert!((d2.statistic - 2.0 / 15.0).abs() < 1e-12, "{d2:?}");
    assert!(same(d2.modal_interval, [3.0, 4.0]), "{d2:?}");
    // ex1.Rout.save, Yong Lu's example x2 = c(1, rep(2, 9)): dip 0.05, xl = xu = 2, and
    // `stopifnot(dip(x2) == dip(3 - x2))`.
    let mut x2 = vec![2.0; 10];
    x2[0] = 1.0;
    let d = dip_statistic(&x2).unwrap();
    assert!(
        (d.statistic - 0.05).abs() < 1e-15 && same(d.modal_interval, [2.0, 2.0]),
        "{d:?}"
    );
    let m: Vec<f64> = x2.iter().map(|v| 3.0 - v).collect();
    assert!((dip_of(&m) - 0.05).abs() < 1e-15);
    // ex1.Rout.save / man/dip.Rd: statfaculty, n = 63: dip 0.0595 with the trace's final
    // 2n·D = 7.5, i.e. D = 7.5/126; lo.hi = (7, 44), xl = 39, xu = 54.
    let d = dip_statistic(&STATFACULTY).unwrap();
    assert!((d.statistic - 7.5 / 126.0).abs() < 1e-12, "{d:?}");
    assert!(same(d.modal_interval, [39.0, 54.0]) && d.n == 63, "{d:?}");
    // ex1.Rout.save: faithful$eruptions, n = 272: 2n·D = 50.2553 (dip 0.0924), lo.hi =
    // (120, 261), xl = 3.83(3), xu = 4.83(3).
    let d = dip_statistic(&FAITHFUL_ERUPTIONS).unwrap();
    assert!((544.0 * d.statistic - 50.2553).abs() < 5e-5, "{d:?}");
    assert!(same(d.modal_interval, [3.833, 4.833]), "{d:?}");
    // And the reference agrees on both real data sets.
    assert!((reference_dip(&STATFACULTY) - 7.5 / 126.0).abs() < 1e-12);
    assert!((reference_dip(&FAITHFUL_ERUPTIONS) - d.statistic).abs() < 1e-12);
}

#[test]
fn published_p_values_of_r_dip_test() {
    // Vignette §5.1: `dip.test(statfaculty)`: D = 0.059524, p-value = 0.08672.
    let t = dip_test(&STATFACULTY).unwrap();
    assert!((t.statistic - 0.059524).abs() < 5e-7);
    assert!((t.p_value - 0.08672).abs() < 5e-6, "{t:?}");
    assert!(!t.rejects_unimodality(DIP_SIGNIFICANCE));
    // Vignette §5.1: faithful$waiting (n = 272, between the rows n = 200 and 500): the
    // interpolated p-value 0.001809527.
    let t = dip_test(&FAITHFUL_WAITING).unwrap();
    assert!((t.p_value - 0.001809527).abs() < 5e-10, "{t:?}");
    assert!(t.rejects_unimodality(DIP_SIGNIFICANCE));
    // man/dip.test.Rd: `dip.test(c(0,0, 1,1))`: "perfect bi-modal for n=4" --> p-value = 0.
    let t = dip_test(&[0.0, 0.0, 1.0, 1.0]).unwrap();
    assert!(
        (t.statistic - 0.25).abs() < 1e-15 && t.p_value.abs() < 1e-15,
        "{t:?}"
    );
}

// ----------------------------------------------------------------------------------------------
// The p-value table.
// ----------------------------------------------------------------------------------------------

#[test]
fn dip_table_is_consistent_and_matches_a_second_copy() {
    use dip_table::{LEVELS, N, Q};
    assert!(N.windows(2).all(|w| w[0] < w[1]));
    assert!(LEVELS.windows(2).all(|w| w[0] < w[1]));
    for (i, row) in Q.iter().enumerate() {
        assert!(row.windows(2).all(|w| w[0] <= w[1]), "row n = {}", N[i]);
        // The smallest possible dip is 1/(2n); the largest 1/4.
        let floor = 1.0 / (2.0 * N[i] as f64);
        assert!(
            row[0] >= floor - 1e-15 && row[25] < 0.25,
            "row n = {}",
            N[i]
        );
        if N[i] <= 10 {
            assert!((row[0] - floor).abs() < 1e-15, "row n = {}", N[i]);
        }
    }
    // Spot checks against the independent reproduction of qDiptab in the Python package diptest
    // (R. Urlus, src/diptest/consts.py, `Consts._CRIT_VALS`, digits as printed there), to the 15
    // significant digits of the copy embedded here.
    let idx = |n: usize| N.iter().position(|&m| m == n).unwrap();
    for (n, k, v) in [
        (4, 10, "0.132559548782689"),
        (8, 2, "0.06569119945032829"),
        (9, 7, "0.09993808978110461"),
        (15, 4, "0.06426571373304441"),
        (30, 12, "0.08147913793901269"),
        (50, 12, "0.06491363240467669"),
        (200, 18, "0.0497198001867437"),
        (1000, 2, "0.007949878346447991"),
        (2000, 25, "0.0213081254074584"),
        (5000, 15, "0.008863578928549141"),
        (10000, 21, "0.008227052458435399"),
        (72000, 8, "0.00141049709228472"),
        (72000, 25, "0.00376331697005859"),
    ] {
        let v: f64 = v.parse().unwrap();
        let q = Q[idx(n)][k];
        assert!(
            (q - v).abs() <= 1e-14 * v,
            "n = {n}, level {}: {q} vs {v}",
            LEVELS[k]
        );
    }
}

#[test]
fn p_value_interpolates_the_table_like_r() {
    use dip_table::{LEVELS, N, Q};
    // On a tabulated row the p-value at a tabulated quantile is 1 − its level, and halfway
    // between two quantiles it is halfway between the levels (linear in √n·D).
    for (i, &n) in N.iter().enumerate().skip(7) {
        for k in [1, 3, 8, 13, 15, 20] {
            let p = dip_p_value(Q[i][k], n);
            assert!((p - (1.0 - LEVELS[k])).abs() < 1e-9, "n {n} k {k}: {p}");
            let mid = 0.5 * (Q[i][k] + Q[i][k + 1]);
            let p = dip_p_value(mid, n);
            assert!((p - (1.0 - 0.5 * (LEVELS[k] + LEVELS[k + 1]))).abs() < 1e-9);
        }
    }
    // Between rows, linear in n on the √n·D scale: n = 300 lies 1/3 of the way from 200 to 500.
    let (i0, i1) = (12, 13);
    assert_eq!((N[i0], N[i1]), (200, 500));
    let s = |i: usize, k: usize| (N[i] as f64).sqrt() * Q[i][k];
    let q300 = (s(i0, 13) + (s(i1, 13) - s(i0, 13)) / 3.0) / 300f64.sqrt();
    assert!((dip_p_value(q300, 300) - 0.05).abs() < 1e-9);
    // Beyond n = 72 000 the last row is the asymptotic one on the √n·D scale.
    let d = s(20, 8) / 1e6f64.sqrt();
    assert!((dip_p_value(d, 1_000_000) - 0.5).abs() < 1e-9);
    // Ends: at the smallest possible dip p = 1 (R gives 0.4 for n = 4, see `dip_p_value`); the
    // largest possible dip 1/4 is beyond every tabulated quantile.
    for n in 4..=12 {
        assert!((dip_p_value(1.0 / (2.0 * n as f64), n) - 1.0).abs() < 1e-15);
        assert!(dip_p_value(0.25, n).abs() < 1e-15);
    }
    // Monotone: a larger dip never has a larger p-value.
    for n in [4, 7, 11, 63, 272, 1234, 50_000, 72_000, 500_000] {
        let mut last = 1.0;
        for j in 0..2000 {
            let d = 1.0 / (2.0 * n as f64) + j as f64 * 1.3e-4;
            let p = dip_p_value(d, n);
            assert!(
                (0.0..=1.0).contains(&p) && p <= last + 1e-15,
                "n {n} D {d}: {p} after {last}"
            );
            last = p;
        }
    }
}

#[test]
fn p_values_of_uniform_samples_are_uniform() {
    // Reference: the table's definition. The p-value is P(D_n(uniform) ≥ d), so on uniform
    // samples P(p ≤ α) = α (up to the table's interpolation in n and its own simulation
    // error). 4000 samples: the binomial standard error of a fraction is ≤ 0.008.
    for (n, seed) in [(50, 31), (300, 32), (1000, 33)] {
        let mut r = SimRng::new(seed);
        let p: Vec<f64> = (0..4000)
            .map(|_| {
                let x: Vec<f64> = (0..n).map(|_| r.uniform()).collect();
                dip_test(&x).unwrap().p_value
            })
            .collect();
        for alpha in [0.01, 0.05, 0.1, 0.3, 0.5, 0.8] {
            let frac = p.iter().filter(|&&v| v <= alpha).count() as f64 / p.len() as f64;
            let se = (alpha * (1.0 - alpha) / p.len() as f64).sqrt();
            assert!(
                (frac - alpha).abs() < 4.0 * se + 0.005,
                "n {n}: P(p <= {alpha}) = {frac}"
            );
        }
    }
}

// ----------------------------------------------------------------------------------------------
// Behaviour.
// ----------------------------------------------------------------------------------------------

/// n draws from the equal mixture of N(−μ, 1) and N(μ, 1).
fn mixture(seed: u64, n: usize, mu: f64) -> Vec<f64> {
    let mut r = SimRng::new(seed);
    (0..n)
        .map(|_| if r.uniform() < 0.5 { -mu } else { mu } + r.normal())
        .collect()
}

#[test]
fn two_humps_are_found_and_one_is_not() {
    // The equal mixture of N(±μ, 1) has two modes iff μ > 1. n = 2000, 40 seeds each.
    let p = |mu: f64| -> Vec<f64> {
        (0..40)
            .map(|seed| dip_test(&mixture(1000 + seed, 2000, mu)).unwrap().p_value)
            .collect()
    };
    let count = |v: &[f64], f: &dyn Fn(f64) -> bool| v.iter().filter(|&&p| f(p)).count();
    // μ = 1.5 (humps 3σ apart): found at 1 % in 35 of the 40 seeds, never missed at 15 %.
    let two = p(1.5);
    assert!(count(&two, &|p| p < 0.01) >= 32, "{two:?}");
    assert!(two.iter().all(|&p| p < 0.15), "{two:?}");
    // μ = 2: always.
    assert!(p(2.0).iter().all(|&p| p < 0.01));
    // μ = 0.5 (one flat-topped hump) and a single normal: never rejected at 5 %.
    for mu in [0.5, 0.0] {
        let one = p(mu);
        assert!(count(&one, &|p| p > 0.05) == one.len(), "μ = {mu}: {one:?}");
    }
}

#[test]
fn dip_test_succeeds_where_sarles_coefficient_fails() {
    // Two overlapping humps (μ = 1.5): Sarle's coefficient stays below 5/9 (its population
    // value is 1/(3 − 0.96) ≈ 0.49), the dip test finds them.
    let x = mixture(7, 2000, 1.5);
    assert!(bimodality_coefficient(&x).unwrap() < BIMODALITY_THRESHOLD);
    assert!(dip_test(&x).unwrap().p_value < 0.01);
    // A skewed single hump (χ² with one degree of freedom, mode at 0): Sarle's coefficient is
    // above 5/9 (population value (8 + 1)/(12 + 3) = 0.6), the dip test sees one mode.
    let mut r = SimRng::new(8);
    let y: Vec<f64> = (0..2000).map(|_| r.normal().powi(2)).collect();
    assert!(bimodality_coefficient(&y).unwrap() > BIMODALITY_THRESHOLD);
    assert!(dip_test(&y).unwrap().p_value > 0.05);
}

#[test]
fn a_million_values_take_linear_time() {
    // The residual vectors of `score` reach ~10⁶ values. A quadratic algorithm would take
    // minutes here; the budget is generous for slow machines (about 30 ms per sample in a dev
    // build). Smooth concave or convex data make every point a hull vertex: the worst shapes
    // measured for the vertex walks.
    let mut r = SimRng::new(9);
    let n = 1_000_000;
    let samples: [(&str, Vec<f64>); 5] = [
        (
            "mixture",
            (0..n)
                .map(|_| if r.uniform() < 0.5 { -1.5 } else { 1.5 } + r.normal())
                .collect(),
        ),
        ("normal", (0..n).map(|_| r.normal()).collect()),
        (
            "rounded",
            (0..n).map(|_| (3.0 * r.normal()).round()).collect(),
        ),
        ("sqrt", (0..n).map(|i| (i as f64).sqrt()).collect()),
        ("exp", (0..n).map(|i| (i as f64 * 1e-5).exp()).collect()),
    ];
    for (name, x) in samples {
        let s = sorted(&x);
        let t = std::time::Instant::now();
        let d = dip_test_sorted(&s).unwrap();
        assert!(t.elapsed().as_secs_f64() < 3.0, "{name}: {:?}", t.elapsed());
        // "rounded" lies on a grid: every repeated value is a point mass, and a unimodal
        // distribution has at most one, so the dip rejects unimodality for quantised data.
        let expect_bimodal = matches!(name, "mixture" | "rounded");
        assert_eq!(d.rejects_unimodality(0.01), expect_bimodal, "{name}: {d:?}");
    }
}
